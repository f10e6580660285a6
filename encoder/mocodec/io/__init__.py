"""File formats: BVH reading and writing."""
from .bvh import BVHError, format_bvh, parse_bvh, read_bvh, write_bvh

__all__ = ["BVHError", "format_bvh", "parse_bvh", "read_bvh", "write_bvh"]

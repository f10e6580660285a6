"""File formats: BVH reading and writing, glTF 2.0 reading."""
from .bvh import BVHError, format_bvh, parse_bvh, read_bvh, write_bvh
from .gltf import GLTFError, read_gltf

__all__ = ["BVHError", "GLTFError", "format_bvh", "parse_bvh", "read_bvh", "read_gltf", "write_bvh"]

"""mocodec: motion-capture animation compression.

The offline encoder reads BVH, encodes clips with a codec into a compact ``.mcd`` asset, and
measures every error through the C runtime that engines use to sample the asset.

>>> import mocodec                                                     # doctest: +SKIP
>>> motion = mocodec.read_bvh("walk.bvh")                              # doctest: +SKIP
>>> units = mocodec.resolve_units(motion.skeleton, "cmu", None)        # doctest: +SKIP
>>> result = mocodec.encode_motions([motion], [units], "spline", mocodec.Tolerance(1.0))  # doctest: +SKIP
"""
__version__ = "0.1.0"

from .motion import Motion, MotionError, Skeleton  # noqa: E402
from .tolerance import Tolerance  # noqa: E402

__all__ = ["Motion", "MotionError", "Skeleton", "Tolerance", "__version__"]

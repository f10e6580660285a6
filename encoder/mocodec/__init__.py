"""mocodec: motion-capture animation compression.

Read animations (BVH, glTF 2.0), encode them with a codec into a compact ``.mcd`` asset whose
every node stays within a tolerance of the original, and sample the asset through the C runtime
that engines use (every error the encoder reports is measured through it).

>>> import mocodec
>>> motions = mocodec.load(mocodec.SAMPLES / "02_01.bvh")        # doctest: +SKIP
>>> data = mocodec.encode(motions, tolerance=1.0)                 # doctest: +SKIP
>>> pose = mocodec.Asset(data).sample("02_01", 0.5, world=True)   # doctest: +SKIP

docs/PYTHON_API.md walks through it; :func:`mocodec.encode_motions` returns the full
report (sizes, errors per clip and node).
"""
from pathlib import Path

__version__ = "0.1.0"

SAMPLES = Path(__file__).resolve().parent / "samples"
"""The sample clips that ship with the package (CMU BVH; glTF in ``SAMPLES / "gltf"``)."""

# The submodule mocodec.encode is loaded first, so that the function below keeps the name.
from . import encode as _encode_module  # noqa: E402,F401
from .api import Asset, Clip, encode  # noqa: E402
from .codecs import UnsupportedMotion  # noqa: E402
from .encode import EncodeError, encode_motions  # noqa: E402
from .io import read_bvh, read_gltf  # noqa: E402
from .load import load, load_all  # noqa: E402
from .units import UnitsError  # noqa: E402
from .motion import Motion, MotionError, Skeleton  # noqa: E402
from .tolerance import Tolerance  # noqa: E402

__all__ = ["Asset", "Clip", "EncodeError", "Motion", "MotionError", "SAMPLES", "Skeleton", "Tolerance",
           "UnitsError", "UnsupportedMotion", "__version__", "encode", "encode_motions", "load", "load_all",
           "read_bvh", "read_gltf"]

"""The Python API: load animations, encode them into an asset, sample an asset.

>>> import mocodec
>>> motions = mocodec.load(mocodec.SAMPLES / "02_01.bvh")            # doctest: +SKIP
>>> data = mocodec.encode(motions, tolerance=1.0)                     # doctest: +SKIP
>>> asset = mocodec.Asset(data)                                        # doctest: +SKIP
>>> pose = asset.sample("02_01", 0.5, world=True)                      # doctest: +SKIP

The defaults are the command line's (codec :data:`mocodec.codecs.DEFAULT_CODEC`, tolerance
:data:`mocodec.tolerance.DEFAULT_TOLERANCE_CM` cm, units as ``mocodec encode`` resolves them).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

from .codecs import DEFAULT_CODEC
from .motion import Motion
from .tolerance import DEFAULT_TOLERANCE_CM, Tolerance


def encode(motions: Motion | Sequence[Motion], tolerance: float = DEFAULT_TOLERANCE_CM,
           codec: str = DEFAULT_CODEC, *, effector_tolerance: float | None = None,
           units: str | None = None, cm_per_unit: float | None = None, strict: bool = False,
           options: dict[str, Any] | None = None, contacts: bool = False,
           warn: Callable[[str], None] | None = None) -> bytes:
    """Encode clips into one ``.mcd`` asset whose every node stays within ``tolerance`` cm of
    the original on every frame, measured through the C runtime.

    Parameters
    ----------
    motions : Motion or sequence of Motion
        Clips, e.g. from :func:`mocodec.load`; names must be unique.
    tolerance : float
        Max world-space position error of any joint, end site or leaf end point, cm.
    codec : str
        One of :func:`mocodec.codecs.available` (only ``rma`` stores animated scale).
    effector_tolerance : float, optional
        A tighter bound for hands, feet, head and end sites, cm.
    units, cm_per_unit : optional
        The BVH clips' length unit (a name of :data:`mocodec.units.UNITS`) or centimetres per
        unit; default: guessed from the animated poses, one unit per skeleton. glTF is metres.
    strict : bool
        A BVH figure under 50 or over 300 cm tall is a :class:`mocodec.units.UnitsError`
        rather than a warning.
    options : dict, optional
        Codec settings (``mocodec --help`` and the codec's settings class list them).
    contacts : bool
        Also store foot contact trajectories (``MCD_SAMPLE_CONTACTS``).
    warn : callable, optional
        Receives the unit warnings (default: :func:`warnings.warn`).

    Returns
    -------
    bytes
        The asset.

    Raises
    ------
    mocodec.encode.EncodeError
        The tolerance cannot be met.
    mocodec.codecs.UnsupportedMotion
        The codec cannot store what a clip holds (animated scale).
    """
    from .encode import encode_motions
    from .units import resolve_library_units

    clips = [motions] if isinstance(motions, Motion) else list(motions)
    choices = resolve_library_units(clips, units, cm_per_unit, strict=strict, warn=warn or _warn)
    result = encode_motions(clips, choices, codec, Tolerance(tolerance, effector_tolerance), options,
                            contacts=contacts)
    return result.asset


def _warn(message: str) -> None:
    import warnings

    warnings.warn(message, stacklevel=3)


@dataclass(frozen=True)
class Clip:
    """One clip of an :class:`Asset`.

    Attributes
    ----------
    index : int
    name : str
    frame_count : int
    frame_rate : float
        Frames per second.
    duration : float
        Seconds, ``(frame_count - 1) / frame_rate``.
    nodes : tuple of str
        Names of the nodes a sample of this clip returns, in order.
    """

    index: int
    name: str
    frame_count: int
    frame_rate: float
    duration: float
    nodes: tuple[str, ...]


class Asset:
    """An ``.mcd`` asset opened with the C runtime (validated first), sampled in place.

    Parameters
    ----------
    data : bytes
        The asset, e.g. from :func:`encode` or a file.

    Attributes
    ----------
    clips : list of Clip
    nodes : list of str
        The node names of the asset's first skeleton (every clip's, when they share one;
        ``clip.nodes`` is each clip's own).
    """

    def __init__(self, data: bytes) -> None:
        from .runtime import Asset as RuntimeAsset

        self.runtime = RuntimeAsset(data)
        names = [tuple(n.name for n in self.runtime.nodes(s)) for s in range(self.runtime.skeleton_count)]
        self.clips = [Clip(c.index, c.name, int(c.frame_count), float(c.frame_rate), float(c.duration),
                           names[c.skeleton]) for c in self.runtime.clips]
        self.nodes = list(names[0])

    def clip(self, clip: int | str) -> Clip:
        """A clip by index or name (``KeyError`` for an unknown name, ``IndexError`` for an index
        outside 0 ... clips - 1: a negative one is refused, not counted from the end, as in the
        runtime's API)."""
        if isinstance(clip, str):
            for c in self.clips:
                if c.name == clip:
                    return c
            raise KeyError(f"no clip named {clip!r}; the asset has {', '.join(c.name for c in self.clips)}")
        if not 0 <= clip < len(self.clips):
            raise IndexError(f"no clip {clip}: the asset has {len(self.clips)} clip(s), 0 ... {len(self.clips) - 1}")
        return self.clips[clip]

    def sample(self, clip: int | str, t: float | np.ndarray, world: bool = False, loop: bool = False,
               nearest: bool = False) -> np.ndarray:
        """The pose of ``clip`` at ``t`` seconds.

        Parameters
        ----------
        clip : int or str
            Index or name.
        t : float or array of float
            Seconds (clamped to the clip unless ``loop``); an array gives one pose per time.
        world : bool
            Model-space transforms instead of parent-relative ones.
        loop : bool
            Wrap time into the clip.
        nearest : bool
            The nearest frame instead of the curve between frames.

        Returns
        -------
        ndarray, float32
            ``(nodes, 10)`` rows ``qx qy qz qw tx ty tz sx sy sz`` (rotation, translation in
            the file's units, scale), or ``(len(t), nodes, 10)`` for an array of times.
        """
        from .runtime import SAMPLE_LOOP, SAMPLE_NEAREST, SAMPLE_WORLD

        index = self.clip(clip).index
        if not np.all(np.isfinite(t)):
            raise ValueError(f"times must be finite seconds, got {t!r}" if np.ndim(t) == 0 else
                             "times must be finite seconds; the array holds nan or inf")
        flags = (SAMPLE_WORLD if world else 0) | (SAMPLE_LOOP if loop else 0) | (SAMPLE_NEAREST if nearest else 0)
        if np.ndim(t) == 0:
            return self.runtime.sample(index, float(t), flags)
        return self.runtime.sample_times(index, np.asarray(t, dtype=np.float64), flags)

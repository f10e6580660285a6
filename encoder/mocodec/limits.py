"""The format's limits (docs/FORMAT.md) as the encoder checks them on what it reads.

A reader checks each limit as soon as it meets the value, before anything large is allocated,
and names the file and line or item; :func:`check_motion` checks a finished :class:`Motion`
(from any reader, or built in code) once more before it is encoded, so the encoder never writes
an asset the runtime would refuse.

>>> frame_time_problem(1e-7, 1)
'1e+07 frames per second; the format allows at most 100,000'
>>> name_problem("Hips")
>>> safe_clip_name("walk:1/2")
'walk_1_2'
"""
from __future__ import annotations

import math
import unicodedata

import numpy as np

from .motion import frame_runs

MAX_NODES = 1024
"""Nodes (joints, end sites, virtual points) of one skeleton."""
MAX_CLIPS = 65535
MAX_FRAMES = 1 << 24
"""Frames of one clip: frame positions are binary32 in the runtime, exact up to 2^24."""
MAX_FRAME_RATE = 100000.0
MAX_ABS_VALUE = 1e7
"""Bound on every stored length and channel value (file units, degrees)."""
MAX_NAME_BYTES = 255
FREE_SAMPLES = 1 << 22
"""Frame x node samples a reader may build whatever the file holds (about 0.35 GB of motion
arrays at 80 bytes a sample, under 1 GB with the reader's temporaries): a channel-less BVH, or a
keyframed glTF animation of an hour at 24 Hz on 48 nodes."""
SAMPLES_PER_VALUE = 8
"""Past :data:`FREE_SAMPLES`, at most this many frame x node samples for each value the file
holds (a BVH frame value, a glTF key), so a tiny file cannot declare gigabytes of frames. A
capture needs about 0.4 (three channels a joint, one node a joint or end site); a glTF capture
keyed every frame about 1, or 4 resampled at four times its key rate."""
_F32_MAX = float(np.finfo(np.float32).max)
_F32_TINY = float(np.finfo(np.float32).tiny)


class LimitError(ValueError):
    """A motion outside the format's limits; the message names the item and the limit."""


def _is_control(ch: str) -> bool:
    """C0 and C1 control characters and DEL (the format's rule for names)."""
    o = ord(ch)
    return o < 0x20 or 0x7F <= o < 0xA0


def printable(text: str) -> str:
    """``text`` with everything a terminal would act on or hide (control and format
    characters, unpaired surrogates) written as ``\\x..`` / ``\\u....`` escapes: names and
    paths from files go through it before they are printed."""
    out = []
    for ch in text:
        if ch.isprintable() or ch == " ":
            out.append(ch)
        else:
            o = ord(ch)
            out.append(f"\\x{o:02x}" if o < 0x100 else f"\\u{o:04x}" if o < 0x10000 else f"\\U{o:08x}")
    return "".join(out)


def name_problem(name: str) -> str | None:
    """Why ``name`` cannot be a node or clip name of an asset, or None when it can: 1 to 255
    bytes of UTF-8 without control characters."""
    if not name:
        return "an empty name"
    try:
        size = len(name.encode("utf-8"))
    except UnicodeEncodeError:
        return f"name '{printable(name)}' is not valid Unicode text"
    if size > MAX_NAME_BYTES:
        return f"name of {size} bytes; the format allows at most {MAX_NAME_BYTES} (UTF-8)"
    bad = next((ch for ch in name if _is_control(ch)), None)
    if bad is not None:
        return f"name '{printable(name)}' holds control character U+{ord(bad):04X}"
    return None


def clip_name_problem(name: str) -> str | None:
    """:func:`name_problem`, and what makes a clip name steer a path when an asset is decoded
    to one file per clip (``/``, ``\\``, ``:``, ``.``, ``..``)."""
    problem = name_problem(name)
    if problem:
        return problem
    if name in (".", "..") or any(c in name for c in "/\\:"):
        return f"clip name '{printable(name)}' holds '/', '\\' or ':' or is '.' or '..'"
    return None


def truncate_utf8(text: str, max_bytes: int) -> str:
    """The longest prefix of ``text`` whose UTF-8 form fits ``max_bytes``."""
    data = text.encode("utf-8", "surrogatepass")
    if len(data) <= max_bytes:
        return text
    return data[:max_bytes].decode("utf-8", "ignore")


def safe_clip_name(stem: str) -> str:
    """A clip name made from a file stem: characters a clip name may not hold (path separators,
    ``:``, control and unpaired surrogate characters) become ``_``, NFC-normalised, cut to 255
    bytes; ``clip`` when nothing is left."""
    cleaned = "".join("_" if (c in "/\\:" or _is_control(c) or 0xD800 <= ord(c) < 0xE000) else c
                      for c in unicodedata.normalize("NFC", stem))
    cleaned = truncate_utf8(cleaned, MAX_NAME_BYTES)
    return "clip" if cleaned in ("", ".", "..") else cleaned


def frame_time_problem(frame_time: float, frames: int) -> str | None:
    """Why ``frame_time`` seconds per frame cannot be stored for a clip of ``frames`` frames,
    or None: the rate, a binary32, must be normal and at most 100,000 per second, and the
    duration finite in binary32."""
    if not (math.isfinite(frame_time) and frame_time > 0):
        return "must be a positive number of seconds"
    rate = 1.0 / frame_time
    problem = frame_rate_problem(rate)
    if problem:
        return problem
    if not (frames - 1) * frame_time < _F32_MAX:
        return f"a clip of {frames:,} frames would last {(frames - 1) * frame_time:.3g} s, past binary32"
    return None


def frame_rate_problem(rate: float) -> str | None:
    """Why ``rate`` frames per second cannot be stored, or None."""
    if not (rate <= MAX_FRAME_RATE):
        return f"{rate:.3g} frames per second; the format allows at most {MAX_FRAME_RATE:,.0f}"
    if not (rate >= _F32_TINY):
        return f"{rate:.3g} frames per second is below what binary32 holds"
    return None


def frames_problem(frames: int) -> str | None:
    if frames < 1:
        return "a clip needs at least one frame"
    if frames > MAX_FRAMES:
        return f"{frames:,} frames; the format allows at most {MAX_FRAMES:,} per clip"
    return None


def samples_allowed(values: int) -> int:
    """The frame x node samples ``values`` values read from a file back."""
    return max(FREE_SAMPLES, SAMPLES_PER_VALUE * values)


def samples_problem(frames: int, nodes: int, values: int, what: str = "values") -> str | None:
    """Why ``frames`` x ``nodes`` samples of motion are more than ``values`` values (``what``:
    their name in the message) read from a file back (:func:`samples_allowed`), or None.
    Checked before the motion arrays exist.

    >>> samples_problem(864_000, 100, 864_000 * 300)
    >>> samples_problem(3_000_000, 2, 0)
    '3,000,000 frames x 2 nodes = 6,000,000 samples (0.447 GiB) backed by 0 values; the limit is 4,194,304 samples or 8 per value'
    """
    samples = frames * nodes
    if samples <= samples_allowed(values):
        return None
    return (f"{frames:,} frames x {nodes:,} nodes = {samples:,} samples ({samples * 80 / 2**30:.3g} GiB) "
            f"backed by {values:,} {what}; the limit is {FREE_SAMPLES:,} samples or "
            f"{SAMPLES_PER_VALUE} per {what.rstrip('s')}")


def value_problem(values: np.ndarray) -> tuple[tuple[int, ...], str] | None:
    """The index of the first value of ``values`` outside +-1e7 (or not finite) and what is
    wrong with it (``"is not finite"``, ``"is outside the format's +-1e7"``), or None."""
    bad = ~(np.abs(values) <= MAX_ABS_VALUE)
    if not bad.any():
        return None
    at = tuple(int(i) for i in np.argwhere(bad)[0])
    return at, "is not finite" if not math.isfinite(float(values[at])) else "is outside the format's +-1e7"


def check_motion(motion, what: str | None = None) -> None:
    """Raise :class:`LimitError` (naming ``what``, default the clip) when ``motion`` is
    outside the format's limits: nodes, names, frames, frame rate, rest offsets and
    translations within +-1e7."""
    sk = motion.skeleton
    where = what or f"clip '{printable(motion.name)}'"
    if sk.node_count > MAX_NODES:
        raise LimitError(f"{where}: {sk.node_count:,} nodes; the format allows at most {MAX_NODES:,}")
    problem = clip_name_problem(motion.name)
    if problem:
        raise LimitError(f"{where}: {problem}")
    for name in sk.names:
        problem = name_problem(name)
        if problem:
            raise LimitError(f"{where}: node {problem}")
    problem = frames_problem(motion.frame_count) or frame_time_problem(motion.frame_time, motion.frame_count)
    if problem:
        raise LimitError(f"{where}: {problem}")
    found = value_problem(sk.offsets)
    if found:
        at, reason = found
        raise LimitError(f"{where}: rest offset of node '{printable(sk.names[at[0]])}': "
                         f"{float(sk.offsets[at]):.6g} {reason}")
    for rows in frame_runs(motion.frame_count):  # a run of frames at a time: no whole-clip temporaries
        run = motion.translations[rows]
        found = value_problem(run)
        if found:
            at, reason = found
            raise LimitError(f"{where}: frame {rows.start + at[0] + 1}, translation of node "
                             f"'{printable(sk.names[at[1]])}': {float(run[at]):.6g} {reason}")


def position_reach(motion) -> float:
    """A bound on every coordinate of every node's world position over the clip (file units):
    the root's largest coordinate plus the longest chain of local translations, each grown by
    its ancestors' largest scale. A run of frames at a time, so a long clip's frames are not
    copied."""
    sk = motion.skeleton
    n = sk.node_count
    coordinate, length, scale = np.zeros(n), np.zeros(n), np.zeros(n)  # per node, largest over frames
    for rows in frame_runs(motion.frame_count):
        tr = motion.translations[rows]
        np.maximum(coordinate, np.abs(tr).max(axis=(0, 2), initial=0.0), out=coordinate)
        np.maximum(length, np.sqrt(np.einsum("fnc,fnc->fn", tr, tr)).max(axis=0, initial=0.0), out=length)
        np.maximum(scale, np.abs(motion.scales[rows]).max(axis=(0, 2), initial=0.0), out=scale)
    reach = np.zeros(n)
    grow = np.ones(n)  # largest |scale| product down to each node
    for i, p in enumerate(sk.parents):
        reach[i] = coordinate[i] if p < 0 else reach[p] + grow[p] * length[i]
        grow[i] = (1.0 if p < 0 else grow[p]) * scale[i]
    return float(reach.max(initial=0.0))


def position_precision_problem(motion, cm_per_unit: float, tolerance_cm: float, share: float) -> str | None:
    """Why the runtime's binary32 positions cannot hold ``tolerance_cm`` on ``motion``, or None:
    a coordinate of magnitude X is held to the binary32 spacing at X (2^(floor(log2 X) - 23)),
    and rounding a key, evaluating its curve and each joint of forward kinematics cost up to half
    a spacing each, so a clip far from the origin (a root 50 km out at 1 cm) has positions no key
    puts within the tolerance. The limit: that spacing at :func:`position_reach` at most
    ``share`` of the tolerance (the codec's, :attr:`mocodec.codecs.Codec.spacing_share`)."""
    reach = position_reach(motion)
    allowed = share * tolerance_cm / cm_per_unit  # units
    spacing = float(np.spacing(np.float32(reach)))
    if spacing <= allowed:
        return None
    # The largest magnitude whose spacing is within `allowed`: 2^(floor(log2 allowed) + 24).
    limit = 2.0 ** (math.floor(math.log2(allowed)) + 24)
    return (f"a position reaches {reach * cm_per_unit:.4g} cm from the origin, where the runtime's binary32 "
            f"positions are {spacing * cm_per_unit:.3g} cm apart, more than {share:g} x the "
            f"{tolerance_cm:g} cm tolerance: move the clip within {limit * cm_per_unit:.4g} cm of the origin, "
            f"or loosen the tolerance to at least {spacing * cm_per_unit / share:.3g} cm")

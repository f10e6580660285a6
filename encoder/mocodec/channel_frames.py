"""A long clip's local rotations and translations held as the BVH channels they come from.

:meth:`mocodec.motion.Motion.from_channels` turns (F, C) channel values into (F, N, 4)
quaternions and (F, N, 3) translations: 7 float64 numbers a node a frame, about 5.5 times the
channels of a CMU skeleton. For a long clip (an hours-long capture, issue 16) it keeps the
channels instead, and a :class:`ChannelFrames` computes the rows asked for, a run of frames or
a node's column at a time, with the same arithmetic: the same numbers, bit for bit. The sign
of each quaternion (made continuous over the whole clip) is worked out once and kept, one
byte a node a frame.
"""
from __future__ import annotations

import operator
from typing import Any

import numpy as np

from . import rotations

SIGN_RUN = 65536
"""Frames whose quaternions are built at a time to find their signs."""


class ChannelFrames:
    """(F, N, 4) local rotations or (F, N, 3) local translations of a clip, computed from its
    channels when indexed: ``a[rows]``, ``a[rows, node]``, ``a[:, node]`` and further indices
    after those give what the held array would (``rows`` an int, a slice, an index or a bool
    array), computing only those rows and nodes; keys numpy would broadcast together (two index
    arrays), ``...`` or ``None``, and ``np.asarray(a)``, build the whole array. Read-only."""

    def __init__(self, channels: np.ndarray, skeleton: Any, part: str) -> None:
        """``part``: ``"rotations"`` or ``"translations"``; ``skeleton`` a
        :class:`mocodec.motion.Skeleton` (its channel layout, and its offsets)."""
        if part not in ("rotations", "translations"):
            raise ValueError(f"part must be 'rotations' or 'translations', not {part!r}")
        self.channels = channels
        self.part = part
        self._nodes = skeleton.node_count
        self._width = 4 if part == "rotations" else 3
        self._offsets = np.asarray(skeleton.offsets, dtype=np.float64)
        # Per node, its channel columns: rotation (columns, order) or position [(axis, column)].
        self._rot: dict[int, tuple[list[int], str]] = {}
        self._pos: dict[int, list[tuple[int, int]]] = {}
        col = 0
        for i, ch in enumerate(skeleton.channels):
            cols = list(range(col, col + len(ch)))
            col += len(ch)
            rot_cols = [c for c, code in zip(cols, ch) if code >= 3]
            if rot_cols:
                self._rot[i] = (rot_cols, skeleton.rotation_order(i))
            pos = [(code, c) for c, code in zip(cols, ch) if code < 3]
            if pos:
                self._pos[i] = pos
        self._column = {i: k for k, i in enumerate(self._rot)}  # node -> its column of signs
        self._negated = self._signs() if part == "rotations" else None

    # ------------------------------------------------------------------ array protocol
    @property
    def shape(self) -> tuple[int, int, int]:
        return (len(self.channels), self._nodes, self._width)

    @property
    def ndim(self) -> int:
        return 3

    @property
    def dtype(self) -> np.dtype:
        return np.dtype(np.float64)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    @property
    def held_bytes(self) -> int:
        """The memory it keeps beside the channels (the signs: one byte a node a frame)."""
        return 0 if self._negated is None else int(self._negated.nbytes)

    def __len__(self) -> int:
        return len(self.channels)

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        if copy is False:
            raise ValueError(f"a long clip's {self.part} are computed from its channels: no array to "
                             "share without building it")
        whole = self[:]
        return whole if dtype is None else whole.astype(dtype, copy=False)

    def __getattr__(self, name: str) -> Any:
        # Any other ndarray attribute (mean, copy, tobytes...) of the whole array, built for it.
        if name.startswith("_") or name in ("channels", "part"):
            raise AttributeError(name)
        return getattr(np.asarray(self), name)

    def __setitem__(self, key: Any, value: Any) -> None:
        raise TypeError(f"a long clip's {self.part} are computed from its channels and cannot be "
                        "changed in place; take a copy (np.array) to change it")

    def __getitem__(self, key: Any) -> np.ndarray:
        key = key if isinstance(key, tuple) else (key,)
        arrays = sum(1 for k in key if not isinstance(k, slice) and np.ndim(k) > 0)
        if any(k is Ellipsis or k is None for k in key) or len(key) > 3 or arrays > 1:
            return np.asarray(self)[key]  # numpy's rules for indices that broadcast together
        rows, node_key, rest = key[0], (key[1] if len(key) > 1 else slice(None)), key[2:]
        # The shape numpy's row indexing gives (int, slice, index or bool array), from an empty
        # array of no columns: nothing copied.
        lead = np.empty((len(self.channels), 0))[rows].shape[:-1]
        if not isinstance(node_key, slice) and np.ndim(node_key) == 0:
            node = operator.index(node_key)
            if not -self._nodes <= node < self._nodes:
                raise IndexError(f"node {node} is out of bounds for {self._nodes} nodes")
            out = self._node(rows, lead, node % self._nodes)
        else:
            nodes = np.arange(self._nodes)[node_key]
            out = np.empty(lead + (len(nodes), self._width))
            for k, i in enumerate(nodes):
                out[..., k, :] = self._node(rows, lead, int(i))
        return out[(Ellipsis,) + rest] if rest else out

    # ------------------------------------------------------------------ the numbers
    def _columns(self, rows: Any, cols: list[int]) -> np.ndarray:
        """The channel values of columns ``cols`` on ``rows`` (index arrays: those columns alone
        copied, not every channel of the rows)."""
        if not isinstance(rows, slice) and np.ndim(rows) == 1:
            at = np.asarray(rows)
            if at.dtype.kind in "iu":
                return self.channels[at[:, None], cols]
        return self.channels[rows][..., cols]

    def _node(self, rows: Any, lead: tuple[int, ...], i: int) -> np.ndarray:
        """Node i's values on ``rows`` (of shape ``lead``), as from_channels holds them."""
        if self.part == "translations":
            out = np.empty(lead + (3,))
            out[...] = self._offsets[i]
            pos = self._pos.get(i, ())
            if pos:
                values = self._columns(rows, [c for _, c in pos])
                for k, (axis, _) in enumerate(pos):
                    out[..., axis] = values[..., k]
            return out
        if i not in self._rot:
            out = np.zeros(lead + (4,))
            out[..., 3] = 1.0
            return out
        cols, order = self._rot[i]
        q = rotations.euler_to_quat(self._columns(rows, cols), order)
        negated = self._negated[rows, self._column[i]]
        q *= np.where(negated, -1.0, 1.0)[..., None]  # x -1: exact, as from_channels flips
        return q

    def _signs(self) -> np.ndarray:
        """(F, R) bool: which quaternions from_channels negates (``quat_make_continuous`` over
        the clip: the parity of the sign changes so far), a run of frames at a time."""
        frames = len(self.channels)
        negated = np.zeros((frames, len(self._rot)), dtype=bool)
        for k, (i, (cols, order)) in enumerate(self._rot.items()):
            last, parity = None, 0
            for start in range(0, frames, SIGN_RUN):
                stop = min(start + SIGN_RUN, frames)
                q = rotations.euler_to_quat(self.channels[start:stop, cols], order)
                # The previous run's last quaternion first, so each dot is the whole clip's.
                both = q if last is None else np.concatenate((last[None], q))
                dots = np.sum(both[1:] * both[:-1], axis=-1)
                flips = (np.cumsum(dots < 0) + parity) % 2
                negated[start + (last is None):stop, k] = flips == 1
                if len(flips):
                    parity = int(flips[-1])
                last = q[-1]
        return negated

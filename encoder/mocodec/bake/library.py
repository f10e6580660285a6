"""A library of clips that is read clip by clip, not held whole (a studio's library outgrows
memory long before it outgrows a disk).

:func:`open_library` reads every file once to list its clips (names made unique as
:func:`mocodec.load.load_all` makes them, sizes, what the units guess needs) and keeps the
motions it read only while they fit in ``resident_bytes``; a clip read again later comes from
that store or from its file. A :class:`Library` is a sequence of :class:`~mocodec.motion.Motion`,
so what takes a list of motions takes it, and a :class:`ClipRef` names one clip of it in a few
bytes: a bake sends refs to its workers, which read the clips themselves.
"""
from __future__ import annotations

import dataclasses
import os
import weakref
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence, overload

from ..channel_frames import ChannelFrames
from ..motion import Motion

RESIDENT_BYTES = 256 << 20
"""Motions a library keeps in memory by default: the dev set (35 clips, 416 s) fits, so a
small library is read once; past it, clips are read again from their files when needed."""


def motion_bytes(motion: Motion) -> int:
    """The memory of a motion's frame arrays: what each holds (a long clip's rotations and
    translations computed from its channels, what they keep beside them; a row broadcast over
    the frames, its row)."""
    def held(a: "np.ndarray | ChannelFrames") -> int:
        if isinstance(a, ChannelFrames):
            return a.held_bytes
        return a[0].nbytes if a.ndim and a.strides[0] == 0 else a.nbytes
    arrays = (motion.rotations, motion.translations, motion.scales, motion.source_channels)
    return sum(held(a) for a in arrays if a is not None)


@dataclass(frozen=True)
class ClipRef:
    """One clip of a file: the ``index``-th clip of ``path``, called ``name`` (pickles small;
    :meth:`load` reads it, ``transform`` applied)."""

    path: str
    index: int
    name: str
    rate: float | None
    frames: int
    nodes: int
    transform: Callable[[Motion], Motion] | None = None

    def load(self) -> Motion:
        """The clip: the copy this process already holds somewhere (a job, the check of the
        same clip, a library's resident clips), else read from its file."""
        from ..load import read_clips

        stamp = _stamp(self.path)
        held = _held(self, stamp)
        if held is not None:
            return held
        clips = read_clips(Path(self.path), self.rate)
        if self.index >= len(clips):
            raise ValueError(f"{self.path}: clip {self.index} is gone (the file changed during the bake)")
        motion = clips[self.index]
        motion.name = self.name
        motion = self.transform(motion) if self.transform is not None else motion
        _hold(self, stamp, motion)
        return motion

    @property
    def weight(self) -> int:
        """A guess of the work: frames times nodes."""
        return self.frames * self.nodes


Stamp = tuple[int, ...]

_LOADED: "weakref.WeakValueDictionary[tuple[ClipRef, Stamp], Motion]" = weakref.WeakValueDictionary()
"""Clips read in this process, by their ref and their file's state (:func:`_stamp`), while
something still holds them: a clip's job, its check and its library share one copy instead of
each reading the file again (a long clip's channels alone are 2x its raw data)."""


def _stamp(path: str) -> Stamp:
    """The file's identity and state: device, inode, size, modification and change times (ns;
    a copy that keeps the modification time is another inode, with a new change time). Empty
    when it cannot be read (the read then says why; nothing is shared)."""
    try:
        st = os.stat(path)
    except OSError:
        return ()
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


def _held(ref: "ClipRef", stamp: Stamp) -> Motion | None:
    """The copy of ``ref``'s clip read from the file in state ``stamp``, if something holds it."""
    try:
        return _LOADED.get((ref, stamp)) if stamp else None
    except TypeError:  # a transform that does not hash: its clips are not shared
        return None


def _hold(ref: "ClipRef", stamp: Stamp, motion: Motion) -> None:
    """Share ``motion``, ``ref``'s clip read from the file in state ``stamp``, while it is held."""
    if stamp:
        try:
            _LOADED[(ref, stamp)] = motion
        except TypeError:
            pass


class Library(Sequence[Motion]):
    """Clips named by :class:`ClipRef`, read when asked for and kept while they fit in
    ``resident_bytes`` (least recently used dropped first). It pickles without the motions."""

    def __init__(self, refs: Sequence[ClipRef], resident_bytes: int = RESIDENT_BYTES) -> None:
        self.refs = list(refs)
        self.resident_bytes = int(resident_bytes)
        self._resident: OrderedDict[int, Motion] = OrderedDict()
        self._held = 0

    def __len__(self) -> int:
        return len(self.refs)

    @overload
    def __getitem__(self, i: int) -> Motion: ...
    @overload
    def __getitem__(self, i: slice) -> "Library": ...

    def __getitem__(self, i: int | slice) -> "Motion | Library":
        if isinstance(i, slice):
            return self.subset(range(len(self))[i])
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(i)
        motion = self._resident.get(i)
        if motion is not None:
            self._resident.move_to_end(i)
            return motion
        motion = self.refs[i].load()
        self.keep(i, motion)
        return motion

    def __iter__(self) -> Iterator[Motion]:
        for i in range(len(self)):
            yield self[i]

    def keep(self, i: int, motion: Motion) -> None:
        """Hold clip ``i`` in memory, dropping the least recently used past the budget."""
        size = motion_bytes(motion)
        if size > self.resident_bytes:
            return
        self._resident[i] = motion
        self._held += size
        while self._held > self.resident_bytes:
            _, old = self._resident.popitem(last=False)
            self._held -= motion_bytes(old)

    def subset(self, indices: Sequence[int]) -> "Library":
        """The clips at ``indices``, as a library of their own (for a worker: no motions)."""
        return Library([self.refs[i] for i in indices], self.resident_bytes)

    def map(self, transform: Callable[[Motion], Motion]) -> "Library":
        """This library with ``transform`` applied to each clip as it is read (``transform``
        must pickle for a bake's workers)."""
        def chain(ref: ClipRef) -> ClipRef:
            return dataclasses.replace(ref, transform=transform if ref.transform is None
                                       else _Chain(ref.transform, transform))
        out = Library([chain(r) for r in self.refs], self.resident_bytes)
        for i, m in self._resident.items():
            mapped = transform(m)
            out.keep(i, mapped)
            stamp = _stamp(self.refs[i].path)
            if _held(self.refs[i], stamp) is m:  # read from the file as it is: the mapped clip too
                _hold(out.refs[i], stamp, mapped)
        return out

    def __getstate__(self) -> dict[str, Any]:
        return {"refs": self.refs, "resident_bytes": self.resident_bytes}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["refs"], state["resident_bytes"])  # type: ignore[misc]


@dataclass(frozen=True)
class _Chain:
    first: Callable[[Motion], Motion]
    then: Callable[[Motion], Motion]

    def __call__(self, motion: Motion) -> Motion:
        return self.then(self.first(motion))


def open_library(paths: Sequence[str | os.PathLike], rate: float | None = None,
                 resident_bytes: int = RESIDENT_BYTES,
                 visit: Callable[[int, Motion], None] | None = None) -> Library:
    """The clips of ``paths`` (files or folders, as :func:`mocodec.load.load_all` reads them and
    with the same names), each file read once here; ``visit(i, motion)`` sees each clip as it is
    read (what a caller needs of every clip, gathered without reading it again)."""
    from ..load import expand, iter_clips

    lib = Library([], resident_bytes)
    before = {str(p): _stamp(str(p)) for p in expand(paths)}  # (a file changed as it is read is not shared)
    for path, index, motion in iter_clips(paths, rate):
        i = len(lib.refs)
        ref = ClipRef(str(path), index, motion.name, rate, motion.frame_count, motion.skeleton.node_count)
        lib.refs.append(ref)
        stamp = _stamp(ref.path)
        if before.get(ref.path) == stamp:
            _hold(ref, stamp, motion)
        if visit is not None:
            visit(i, motion)
        lib.keep(i, motion)
    return lib


def clip_ref(motions: Sequence[Motion], i: int) -> "ClipRef | Motion":
    """What a worker needs to have clip ``i`` of ``motions``: a :class:`ClipRef` for a
    :class:`Library`, the motion itself for a list."""
    return motions.refs[i] if isinstance(motions, Library) else motions[i]

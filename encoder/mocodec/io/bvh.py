"""Reading and writing BVH motion files.

The reader accepts every layout BVH allows (any channel and rotation order, position channels on
any joint, several roots, ``CHANNELS 0``, CRLF, tabs) and turns bad input into a
:class:`BVHError` that names the file, the 1-based line and the fault. The format's limits
(:mod:`mocodec.limits`: nodes, names, frames, frame rate, values) are checked where the value is
read, before anything is allocated for it, and only regular files of bounded size are read
(:mod:`mocodec.io.files`). The ``MOTION`` block is converted in chunks of lines (split, count
per line, one float conversion each), so the text's tokens never all exist at once; lines are
only scanned one by one to locate an error. A file is read a block at a time, twice (its lines
counted, then its frames converted), so that an hours-long capture's text is never held whole.
"""
from __future__ import annotations

import codecs
import itertools
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO, Callable, Iterable, Iterator

import numpy as np

from .. import limits
from ..motion import CHANNEL_CODES, CHANNEL_NAMES, Motion, MotionError, Skeleton, unique_name
from ..output import atomic_open
from .files import MAX_INPUT_BYTES, open_regular_file, too_large

__all__ = ["BVHError", "read_bvh", "parse_bvh", "format_bvh", "write_bvh"]

_FRAMES_RE = re.compile(r"Frames\s*:\s*(.*)")
_FRAME_TIME_RE = re.compile(r"Frame\s+Time\s*:\s*(.*)")
_CHUNK_VALUES = 1 << 16  # frame values split and converted at a time (a few MB of str objects)


def _show(text: str, limit: int = 40) -> str:
    """``text`` quoted for a message: escapes for what a terminal would act on, at most
    ``limit`` characters (a garbage file can hold a line of megabytes)."""
    return repr(text if len(text) <= limit else text[:limit] + "...")


class BVHError(ValueError):
    """A BVH file that cannot be read; ``str(err)`` is ``"{path}:{line}: {message}"``.

    Attributes
    ----------
    path : str or None
        The file, when known.
    line : int or None
        1-based line number of the fault, when it has one.
    message : str
        What is wrong.
    """

    def __init__(self, message: str, path: str | None = None, line: int | None = None) -> None:
        self.message = message
        self.path = path
        self.line = line
        super().__init__(str(self))

    def __str__(self) -> str:
        where = [limits.printable(str(part)) for part in (self.path, self.line) if part is not None]
        return ": ".join([":".join(where), self.message]) if where else self.message

    def __reduce__(self):  # keep pickling (multiprocessing) working with the extra fields
        return (type(self), (self.message, self.path, self.line))


# ------------------------------------------------------------------------------- reading
def read_bvh(path: str | os.PathLike) -> Motion:
    """Read a BVH file (a regular file: a FIFO, a device or a folder is refused before it is
    read); the clip is named after the file stem (:func:`mocodec.limits.safe_clip_name`). The
    file is read a few MB at a time, twice (its lines counted, then its frames converted), so
    its text is never held whole: the same motion, and the same errors, as :func:`parse_bvh`
    of its bytes."""
    path = Path(path)
    with open_regular_file(path, "BVH file", lambda message: BVHError(message, str(path))) as f:
        before = _state(f)
        try:
            scan = _Scan(_FileText(f, str(path)))
            skeleton, channels, frame_time = _parse_lines(scan.head, str(path), scan.frame_lines)
        except BVHError:
            if _state(f) != before:  # the second read saw another file than the first
                raise _changed(str(path)) from None
            raise
        if _state(f) != before:
            raise _changed(str(path))
    motion = Motion.from_channels(skeleton, channels, frame_time, limits.safe_clip_name(path.stem))
    motion.source = {"format": "bvh", "file": str(path)}
    return motion


def parse_bvh(text: str | bytes, path: str | None = None, name: str | None = None) -> Motion:
    """Parse BVH text (or UTF-8 bytes) into a :class:`Motion`.

    Parameters
    ----------
    text : str or bytes
        File contents.
    path : str, optional
        Used in error messages, and for the clip name when ``name`` is not given.
    name : str, optional
        Clip name; defaults to the stem of ``path``, else ``"clip"``.

    Raises
    ------
    BVHError
        With the line number and the fault, for any malformed input.
    """
    if isinstance(text, (bytes, bytearray, memoryview)):
        text = _decode(bytes(text), path)
    if name is None:
        name = limits.safe_clip_name(Path(path).stem) if path else "clip"
    text = _normalized(text, first=True)
    nul = text.find("\x00")
    if nul >= 0:
        raise _nul_error(path, text.count("\n", 0, nul) + 1)
    lines = text.split("\n")
    if len(lines) > 1 and not lines[-1]:
        lines.pop()  # the final newline ends the last line; it does not start another
    skeleton, channels, frame_time = _parse_lines(lines, path, lambda start: _FrameLines.of_list(lines, start))
    del lines, text  # the text is not needed for the motion (memory on long clips)
    return Motion.from_channels(skeleton, channels, frame_time, name)


def _state(f: BinaryIO) -> tuple[int, int, int]:
    """Size, modification and change times (ns) of an open file: what any write changes."""
    st = os.fstat(f.fileno())
    return (st.st_size, st.st_mtime_ns, st.st_ctime_ns)


def _changed(path: str) -> BVHError:
    return BVHError("the file changed while it was read; read it again once it is written", path)


def _normalized(text: str, first: bool) -> str:
    """Line breaks as ``\n``: only \r\n, \r and \n end lines (str.splitlines would also split
    on form feeds and the like, and the line numbers would no longer match an editor's); a
    byte-order mark at the start of the file (``first``) dropped."""
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text.removeprefix("\ufeff") if first else text


def _nul_error(path: str | None, line: int) -> BVHError:
    return BVHError("binary data (NUL character); not a BVH text file", path, line)


def _parse_lines(lines: list[str], path: str | None,
                 frame_lines: "Callable[[int], _FrameLines]") -> tuple[Skeleton, np.ndarray, float]:
    """Skeleton, ``(frames, channels)`` values and frame time from the file's lines up to its
    header (the HIERARCHY, ``MOTION``, ``Frames:`` and ``Frame Time:``; the whole file when it
    has no complete header) and its frame lines (``frame_lines(start)``, those from the line
    index ``start`` on)."""
    hierarchy = _HierarchyParser(lines, path)
    skeleton, motion_line = hierarchy.parse()
    frames, frame_time, data_start, frames_line = _parse_motion_header(lines, motion_line, path)
    channels = _parse_frames(frame_lines(data_start), frames, skeleton, path, frames_line)
    return skeleton, channels, frame_time


def _line_breaks(data: bytes) -> int:
    """How many lines ``data`` ends: \\r\\n, \\r and \\n each end one."""
    return data.count(b"\n") + data.count(b"\r") - data.count(b"\r\n")


def _decode(data: bytes, path: str | None, offset: int = 0, breaks: int = 0) -> str:
    """UTF-8 text of ``data`` (a BOM at the start of the file, ``offset`` 0, is dropped);
    undecodable bytes become a BVHError naming their offset in the file and their line
    (``data`` starts at byte ``offset`` of the file, after ``breaks`` line breaks)."""
    bom = offset == 0 and data.startswith(codecs.BOM_UTF8)
    try:
        return data.decode("utf-8-sig" if offset == 0 else "utf-8")
    except UnicodeDecodeError as exc:
        at = exc.start + (len(codecs.BOM_UTF8) if bom else 0)  # utf-8-sig counts after the BOM
        line = breaks + _line_breaks(data[:at]) + 1
        raise BVHError(
            f"not UTF-8 text (byte 0x{data[at]:02x} at offset {offset + at}); binary or wrongly "
            "encoded file", path, line) from None


@dataclass
class _FrameLines:
    """The lines after a BVH header: the index ``start`` of the first, how many lines the file
    has (``total``), how many of those from ``start`` on are not blank (``rows``), the indices
    of the first and last of them (-1: none), and ``lines()``, those ``(index, line)`` in order."""

    start: int
    total: int
    rows: int
    first_row: int
    last_row: int
    lines: Callable[[], Iterator[tuple[int, str]]]

    @classmethod
    def of_list(cls, lines: list[str], start: int) -> "_FrameLines":
        rows, first, last, _ = _count_rows((k, lines[k]) for k in range(start, len(lines)))
        return cls(start, len(lines), rows, first, last,
                   lambda: ((k, lines[k]) for k in range(start, len(lines)) if _is_row(lines[k])))


def _is_row(line: str) -> bool:
    """Whether a line after the header is a frame line (not blank)."""
    return bool(line) and not line.isspace()


def _count_rows(numbered: Iterable[tuple[int, str]], total: int = 0) -> tuple[int, int, int, int]:
    """How many of ``(index, line)`` pairs are frame lines, the indices of the first and last
    of them (-1: none), and the count of lines up to the last pair (``total`` without any)."""
    rows, first, last = 0, -1, -1
    for k, line in numbered:
        total = k + 1
        if _is_row(line):
            rows += 1
            last = k
            if first < 0:
                first = k
    return rows, first, last, total


_READ_BLOCK = 1 << 22
"""Bytes of a BVH file read at a time (:class:`_FileText`)."""


class _FileText:
    """A BVH file's lines read a block of bytes at a time: each block cut after its last line
    break, decoded and its line breaks normalized, so that the lines (and their numbers, and
    a decoding error's offset) are those :func:`parse_bvh` makes of the whole file. The first
    NUL character's line is kept in :attr:`nul_line`."""

    def __init__(self, f: BinaryIO, path: str) -> None:
        self.f, self.path = f, path
        self.nul_line: int | None = None

    def _pieces(self) -> Iterator[str]:
        """The decoded, normalized text from the start of the file, a piece of whole lines at
        a time (each piece but the last ends with its line break)."""
        self.f.seek(0)
        carry = bytearray()  # the bytes after the last line break so far (appended to: a line
        # of gigabytes costs its length, not its length squared)
        offset, breaks, total = 0, 0, 0
        while True:
            try:
                data = self.f.read(_READ_BLOCK)
            except OSError as exc:
                raise BVHError(f"cannot read: {exc.strerror or exc}", self.path) from None
            total += len(data)
            if total > MAX_INPUT_BYTES:
                raise BVHError(too_large(), self.path)
            if data:
                # After the last \n or \r, but not after a \r that the next block's \n may
                # follow; the carry holds no other break, so only the new bytes (and a held \r)
                # are searched.
                since = max(len(carry) - 1, 0)
                carry += data
                cut = max(carry.rfind(b"\n", since), carry.rfind(b"\r", since, len(carry) - 1)) + 1
                if cut == 0:
                    continue
                piece = bytes(carry[:cut])
                del carry[:cut]
            else:
                piece = bytes(carry)
            yield _normalized(_decode(piece, self.path, offset, breaks), first=offset == 0)
            offset += len(piece)
            breaks += _line_breaks(piece)
            if not data:
                return

    def lines(self) -> Iterator[tuple[int, str]]:
        """``(index, line)`` of every line of the file, from the start, split as parse_bvh
        splits the whole text: a final line break ends the last line rather than starting
        another (a file of one empty line keeps it)."""
        k, tail = 0, ""
        for text in self._pieces():
            if self.nul_line is None:
                nul = text.find("\x00")
                if nul >= 0:
                    self.nul_line = k + text.count("\n", 0, nul) + 1
            parts = text.split("\n")
            for line in parts[:-1]:
                yield k, line
                k += 1
            tail = parts[-1]  # "" but for the last piece: the others end with their break
        if tail or k == 0:
            yield k, tail


class _Scan:
    """The first of :func:`read_bvh`'s two reads: every line decoded (a file that is not UTF-8
    or holds a NUL is refused here, as parse_bvh refuses it before anything else), the lines up
    to the header kept (:attr:`head`: up to the second statement after ``MOTION``, ``Frame
    Time:`` in a good file; the whole file without one), and the frame lines after it counted."""

    def __init__(self, text: _FileText) -> None:
        self.text = text
        self.head: list[str] = []
        self.start = -1
        motion, after, total = False, 0, 0
        numbered = text.lines()
        for k, line in numbered:
            total = k + 1
            self.head.append(line)
            if not motion:
                tokens = line.split()
                motion = bool(tokens) and tokens[0] == "MOTION"
            elif line.strip():
                after += 1
                if after == 2:
                    self.start = k + 1
                    break
        rows, first, last, total = _count_rows(numbered, total)  # the rest of the same read
        if text.nul_line is not None:
            raise _nul_error(text.path, text.nul_line)
        self.total, self.rows, self.first_row, self.last_row = total, rows, first, last

    def frame_lines(self, start: int) -> _FrameLines:
        """The frame lines from ``start`` (the header parser's, the line after ``Frame Time:``:
        where the scan began counting), read again from the file."""
        if start != self.start:
            raise BVHError(f"internal error: frames start at line {start + 1}, counted from "
                           f"{self.start + 1}", self.text.path)
        rows = self.rows

        def lines() -> Iterator[tuple[int, str]]:
            seen = 0
            for k, line in self.text.lines():
                if k >= start and _is_row(line):
                    seen += 1
                    yield k, line
            if seen != rows:
                raise _changed(self.text.path)
        return _FrameLines(start, self.total, rows, self.first_row, self.last_row, lines)
@dataclass
class _Node:
    """A joint or End Site while the hierarchy is being read."""

    name: str
    parent: int
    line: int
    end_site: bool
    offset: tuple[float, float, float] | None = None
    channels: tuple[int, ...] | None = None
    children: int = 0


@dataclass
class _HierarchyParser:
    """Line-oriented reader of the HIERARCHY section.

    Each non-blank line is one statement; ``{`` may also end a ROOT/JOINT/End Site line.
    """

    lines: list[str]
    path: str | None
    nodes: list[_Node] = field(default_factory=list)
    stack: list[int] = field(default_factory=list)  # open nodes (their '{' was read)
    pending: int | None = None  # a node whose header was read but not yet its '{'
    joint_lines: dict[str, int] = field(default_factory=dict)  # joint name -> its line

    def error(self, line: int, message: str) -> BVHError:
        return BVHError(message, self.path, line)

    def parse(self) -> tuple[Skeleton, int]:
        """The skeleton and the index of the MOTION line."""
        k = self._first_statement()
        for k in range(k + 1, len(self.lines)):
            tokens = self.lines[k].split()
            if not tokens:
                continue
            if tokens[0] == "MOTION":
                self._finish_hierarchy(k + 1, tokens)
                return self._skeleton(), k
            self._statement(k + 1, tokens)
        last = len(self.lines)
        open_node = self._innermost()
        if open_node is not None:
            raise self.error(last, f"unexpected end of file inside {self._describe(open_node)} "
                                   f"(opened on line {open_node.line}); unbalanced braces?")
        raise self.error(last, "missing MOTION section (unexpected end of file)")

    def _first_statement(self) -> int:
        for k, line in enumerate(self.lines):
            tokens = line.split()
            if not tokens:
                continue
            if tokens != ["HIERARCHY"]:
                raise self.error(k + 1, f"expected HIERARCHY, found {_show(line.strip())}")
            return k
        raise BVHError("empty file", self.path, 1 if self.lines else None)

    def _statement(self, line: int, tokens: list[str]) -> None:
        if self.pending is not None and tokens[0] != "{":
            node = self.nodes[self.pending]
            raise self.error(line, f"expected '{{' after {self._describe(node)}, "
                                   f"found {_show(tokens[0])}")
        head = tokens[0]
        if all(t in ("{", "}") for t in tokens):
            for t in tokens:
                if t == "{":
                    self._open(line)
                else:
                    self._close(line)
        elif head in ("ROOT", "JOINT"):
            self._joint(line, tokens)
        elif head == "End" and len(tokens) >= 2 and tokens[1].rstrip("{") in ("Site", "site"):
            self._end_site(line, tokens)
        elif head == "OFFSET":
            self._offset(line, tokens)
        elif head == "CHANNELS":
            self._channels(line, tokens)
        else:
            raise self.error(line, f"unexpected {_show(head)} in HIERARCHY")

    def _header_brace(self, tokens: list[str]) -> tuple[list[str], bool]:
        """Split a trailing ``{`` (separate or glued to the name) off a header line."""
        if tokens[-1] == "{":
            return tokens[:-1], True
        if tokens[-1].endswith("{"):
            return tokens[:-1] + [tokens[-1][:-1]], True
        return tokens, False

    def _add(self, node: _Node, brace: bool) -> None:
        if len(self.nodes) >= limits.MAX_NODES:
            raise self.error(node.line, f"more than {limits.MAX_NODES:,} nodes (joints and end sites): "
                                        "the format's limit")
        self.nodes.append(node)
        if node.parent >= 0:
            self.nodes[node.parent].children += 1
        self.pending = len(self.nodes) - 1
        if brace:
            self._open(node.line)

    def _joint(self, line: int, tokens: list[str]) -> None:
        tokens, brace = self._header_brace(tokens)
        keyword = tokens[0]
        if len(tokens) < 2:
            raise self.error(line, f"{keyword} without a name")
        name = " ".join(tokens[1:])
        problem = limits.name_problem(name)
        if problem:
            raise self.error(line, f"{keyword}: {problem}")
        if keyword == "ROOT" and self.stack:
            raise self.error(line, f"ROOT {name!r} inside {self._describe(self._top())}; "
                                   "a '}' is missing?")
        if keyword == "JOINT":
            if not self.stack:
                raise self.error(line, f"JOINT {name!r} outside any ROOT")
            if self._top().end_site:
                raise self.error(line, f"End Site (line {self._top().line}) cannot have "
                                       f"children (JOINT {name!r})")
        if name in self.joint_lines:
            raise self.error(line, f"duplicate joint name {name!r} "
                                   f"(first on line {self.joint_lines[name]})")
        self.joint_lines[name] = line
        parent = self.stack[-1] if self.stack else -1
        self._add(_Node(name, parent, line, end_site=False), brace)

    def _end_site(self, line: int, tokens: list[str]) -> None:
        tokens, brace = self._header_brace(tokens)
        if len(tokens) > 2:
            raise self.error(line, f"unexpected {_show(' '.join(tokens[2:]))} after End Site")
        if not self.stack:
            raise self.error(line, "End Site outside any joint")
        if self._top().end_site:
            raise self.error(line, f"End Site (line {self._top().line}) cannot have children")
        # Named after the hierarchy is complete, so a later joint cannot collide with it.
        self._add(_Node("", self.stack[-1], line, end_site=True), brace)

    def _open(self, line: int) -> None:
        if self.pending is None:
            raise self.error(line, "unexpected '{' (no ROOT, JOINT or End Site before it)")
        self.stack.append(self.pending)
        self.pending = None

    def _close(self, line: int) -> None:
        if not self.stack:
            raise self.error(line, "unmatched '}'")
        node = self.nodes[self.stack.pop()]
        if node.offset is None:
            raise self.error(line, f"{self._describe(node)} (line {node.line}) has no OFFSET")

    def _offset(self, line: int, tokens: list[str]) -> None:
        node = self._current(line, "OFFSET")
        if node.offset is not None:
            raise self.error(line, f"second OFFSET in {self._describe(node)}")
        if len(tokens) != 4:
            raise self.error(line, f"OFFSET needs 3 numbers, got {len(tokens) - 1}")
        for t in tokens[1:]:
            if not _is_number(t):
                raise self.error(line, f"OFFSET value {_show(t)} is not a number")
            found = limits.value_problem(np.array([float(t)]))
            if found:
                raise self.error(line, f"OFFSET value {_show(t)} {found[1]}")
        node.offset = (float(tokens[1]), float(tokens[2]), float(tokens[3]))

    def _channels(self, line: int, tokens: list[str]) -> None:
        node = self._current(line, "CHANNELS")
        if node.end_site:
            raise self.error(line, f"End Site (line {node.line}) cannot have channels")
        if node.channels is not None:
            raise self.error(line, f"second CHANNELS in {self._describe(node)}")
        if node.children:
            raise self.error(line, f"CHANNELS of {self._describe(node)} must come before "
                                   "its child joints")
        if len(tokens) < 2 or not tokens[1].isdigit():
            found = _show(tokens[1]) if len(tokens) > 1 else "nothing"
            raise self.error(line, f"CHANNELS needs a channel count, found {found}")
        count = int(tokens[1])
        names = tokens[2:]
        if count != len(names):
            raise self.error(line, f"CHANNELS count says {count} but {len(names)} channel "
                                   f"names follow")
        codes = []
        for ch in names:
            if ch not in CHANNEL_CODES:
                raise self.error(line, f"unknown channel {_show(ch)} (expected one of "
                                       f"{', '.join(CHANNEL_NAMES)})")
            if CHANNEL_CODES[ch] in codes:
                raise self.error(line, f"duplicate channel {ch!r} in {self._describe(node)}")
            codes.append(CHANNEL_CODES[ch])
        node.channels = tuple(codes)

    def _current(self, line: int, keyword: str) -> _Node:
        if not self.stack:
            raise self.error(line, f"{keyword} outside any joint")
        return self._top()

    def _top(self) -> _Node:
        return self.nodes[self.stack[-1]]

    def _innermost(self) -> _Node | None:
        """The node still waiting for its '{' or '}', if any."""
        if self.pending is not None:
            return self.nodes[self.pending]
        return self.nodes[self.stack[-1]] if self.stack else None

    def _finish_hierarchy(self, line: int, tokens: list[str]) -> None:
        if len(tokens) > 1:
            raise self.error(line, f"unexpected {_show(' '.join(tokens[1:]))} after MOTION")
        node = self._innermost()
        if node is not None:
            raise self.error(line, f"MOTION before the end of {self._describe(node)} "
                                   f"(opened on line {node.line}); unbalanced braces")
        if not self.nodes:
            raise self.error(line, "HIERARCHY has no ROOT")

    @staticmethod
    def _describe(node: _Node) -> str:
        if node.end_site:
            return "End Site"
        return f"{'ROOT' if node.parent < 0 else 'JOINT'} {node.name!r}"

    def _skeleton(self) -> Skeleton:
        names = _end_site_names(self.nodes)
        skeleton = Skeleton(
            names=names,
            parents=np.array([n.parent for n in self.nodes], dtype=np.int64),
            offsets=np.array([n.offset for n in self.nodes], dtype=np.float64).reshape(-1, 3),
            channels=[n.channels or () for n in self.nodes],
            is_end_site=np.array([n.end_site for n in self.nodes], dtype=bool),
        )
        try:
            skeleton.validate()
        except MotionError as exc:  # the parser should make this unreachable
            raise BVHError(f"invalid skeleton: {exc}", self.path) from exc
        return skeleton


def _end_site_names(nodes: list[_Node]) -> list[str]:
    """Node names with End Sites called ``<parent>_End`` (``_End2``... on a collision)."""
    used = {n.name for n in nodes if not n.end_site}
    names = []
    for n in nodes:
        if n.end_site:
            # Cut so the name keeps to the format's 255 bytes with room for a number.
            base = limits.truncate_utf8(nodes[n.parent].name, limits.MAX_NAME_BYTES - 10) + "_End"
            names.append(unique_name(base, used, sep=""))
        else:
            names.append(n.name)
    return names


def _next_statement(lines: list[str], start: int) -> int:
    """Index of the first non-blank line at or after ``start`` (``len(lines)`` if none)."""
    k = start
    while k < len(lines) and not lines[k].strip():
        k += 1
    return k


def _parse_motion_header(lines: list[str], motion_line: int,
                         path: str | None) -> tuple[int, float, int, int]:
    """``Frames:`` and ``Frame Time:`` after the MOTION line: (frames, frame time, index of
    the first frame line, 1-based line of ``Frames:``)."""
    k = _next_statement(lines, motion_line + 1)
    match = _FRAMES_RE.fullmatch(lines[k].strip()) if k < len(lines) else None
    if match is None:
        raise BVHError("missing 'Frames:' line after MOTION", path, min(k + 1, len(lines)))
    text = match.group(1).strip()
    if not re.fullmatch(r"[+-]?\d{1,20}", text):
        raise BVHError(f"'Frames:' needs a whole number, got {_show(match.group(1))}", path,
                       k + 1) from None
    frames = int(text)
    frames_line = k + 1
    problem = limits.frames_problem(frames)
    if problem:
        raise BVHError(f"'Frames: {frames}': {problem}", path, frames_line)
    k = _next_statement(lines, k + 1)
    match = _FRAME_TIME_RE.fullmatch(lines[k].strip()) if k < len(lines) else None
    if match is None:
        raise BVHError("missing 'Frame Time:' line after 'Frames:'", path,
                       min(k + 1, len(lines)))
    if not _is_number(match.group(1)):
        raise BVHError(f"'Frame Time:' needs a number of seconds, got {_show(match.group(1))}",
                       path, k + 1) from None
    frame_time = float(match.group(1))
    problem = limits.frame_time_problem(frame_time, frames)
    if problem:
        raise BVHError(f"'Frame Time: {match.group(1).strip()[:40]}': {problem}", path, k + 1)
    return frames, frame_time, k + 1, frames_line


def _parse_frames(source: _FrameLines, frames: int, skeleton: Skeleton, path: str | None,
                  frames_line: int) -> np.ndarray:
    """The ``(frames, channels)`` values from the frame lines ``source``, each within the
    format's +-1e7. Lines are converted about :data:`_CHUNK_VALUES` values at a time into one
    array no larger than the lines present (``Frames:`` may promise more than the file holds),
    and the motion the values become (frames x nodes) must be backed by them
    (:func:`mocodec.limits.samples_problem`)."""
    width = skeleton.channel_count
    start = source.start
    if width == 0:
        # A hierarchy without channels has one empty line a frame (as write_bvh writes it);
        # anything else on them is an error, and fewer lines than 'Frames:' a truncated file.
        if source.rows:
            raise BVHError("frame line has values but the hierarchy has no channels", path,
                           source.first_row + 1)
        if source.total - start < frames:
            raise BVHError(f"truncated MOTION: 'Frames: {frames}' but only {source.total - start} "
                           "frame lines (empty: the hierarchy has no channels)", path, source.total + 1)
    present = min(frames, source.rows if width else frames)
    problem = limits.samples_problem(present, skeleton.node_count, present * width,
                                     "frame values")
    if problem:
        raise BVHError(f"'Frames: {frames}': {problem}", path, frames_line)
    if width == 0:
        return np.zeros((frames, 0))
    values = np.empty((present, width))
    chunk_lines = max(1, _CHUNK_VALUES // width)
    numbered = source.lines()
    for first in range(0, present, chunk_lines):
        part = list(itertools.islice(numbered, min(chunk_lines, present - first)))
        at = [k for k, _ in part]
        rows = [line.split() for _, line in part]
        counts = np.fromiter(map(len, rows), dtype=np.int64, count=len(rows))
        bad = np.flatnonzero(counts != width)
        if bad.size:
            i = int(bad[0])
            hint = ("; the file may be truncated"
                    if first + i == source.rows - 1 and counts[i] < width else "")
            raise BVHError(f"frame {first + i + 1} of {frames}: expected {width} values, got "
                           f"{counts[i]}{hint}", path, at[i] + 1)
        try:
            # float() also takes '1_000'; no BVH writer emits that, so treat it as garbage.
            if any("_" in line for _, line in part):
                raise ValueError
            chunk = np.fromiter(map(float, itertools.chain.from_iterable(rows)), dtype=np.float64,
                                count=len(rows) * width).reshape(len(rows), width)
        except ValueError:
            # The slow scan runs only to say where the bad value is.
            i, j = next((i, j) for i, row in enumerate(rows)
                        for j, token in enumerate(row) if not _is_number(token))
            raise BVHError(f"frame {first + i + 1} of {frames}, value {j + 1}: {_show(rows[i][j])} is "
                           "not a number", path, at[i] + 1) from None
        found = limits.value_problem(chunk)
        if found:
            (i, j), reason = found
            raise BVHError(f"frame {first + i + 1} of {frames}, value {j + 1}: {_show(rows[i][j])} "
                           f"{reason}", path, at[i] + 1)
        values[first:first + len(rows)] = chunk
    if source.rows < frames:
        after = source.last_row + 2 if source.rows else start + 1
        raise BVHError(f"truncated MOTION: 'Frames: {frames}' but only {source.rows} frame "
                       "lines", path, after)
    if source.rows > frames:
        k, line = next(numbered)
        raise BVHError(f"more frame lines than 'Frames: {frames}' (extra line with "
                       f"{len(line.split())} values)", path, k + 1)
    return values


def _is_number(token: str) -> bool:
    """True if ``token`` reads as a float (NaN and inf included; '1_0' excluded)."""
    if "_" in token:
        return False
    try:
        float(token)
    except ValueError:
        return False
    return True


# ------------------------------------------------------------------------------- writing
def format_bvh(motion: Motion, precision: int = 6, reference: np.ndarray | None = None) -> str:
    """BVH text for ``motion``: its hierarchy and ``motion.to_channels`` values.

    Parameters
    ----------
    motion : Motion
    precision : int
        Decimals of the frame values. OFFSETs and the frame time are written exactly
        (shortest text that reads back as the same float).
    reference : (F, C) array, optional
        Channel values whose 360-degree branches the Euler angles follow; defaults to
        ``motion.source_channels`` when it matches the motion's shape.
    """
    if isinstance(precision, bool) or not isinstance(precision, (int, np.integer)) \
            or not 0 <= precision <= 17:
        raise ValueError(f"precision must be a whole number of decimals in 0..17, got "
                         f"{precision!r}")
    precision = int(precision)
    motion.validate()
    sk = motion.skeleton
    shape = (motion.frame_count, sk.channel_count)
    if reference is None and motion.source_channels is not None:
        if np.shape(motion.source_channels) == shape:
            reference = motion.source_channels
    elif reference is not None and np.shape(reference) != shape:
        raise ValueError(f"reference has shape {np.shape(reference)}, expected {shape}")
    values = motion.to_channels(reference)
    for i, name in enumerate(sk.names):
        if not name.strip() or "\n" in name or "\r" in name:
            raise ValueError(f"node name {name!r} cannot be written to BVH")
        if sk.is_end_site[i] and sk.parents[i] < 0:
            raise ValueError(f"end site {name!r} has no parent joint; BVH cannot hold it")

    order, depth = _preorder(sk)
    out = ["HIERARCHY"]
    open_depths: list[int] = []
    for i, d in zip(order, depth):
        while open_depths and open_depths[-1] >= d:
            out.append("\t" * open_depths.pop() + "}")
        pad = "\t" * d
        if sk.is_end_site[i]:
            out.append(f"{pad}End Site")
        else:
            out.append(f"{pad}{'ROOT' if sk.parents[i] < 0 else 'JOINT'} {sk.names[i]}")
        out.append(f"{pad}{{")
        out.append(f"{pad}\tOFFSET " + " ".join(_exact(v) for v in sk.offsets[i]))
        if not sk.is_end_site[i]:
            names = " ".join(CHANNEL_NAMES[c] for c in sk.channels[i])
            out.append(f"{pad}\tCHANNELS {len(sk.channels[i])}" + (f" {names}" if names else ""))
        open_depths.append(d)
    while open_depths:
        out.append("\t" * open_depths.pop() + "}")
    out += ["MOTION", f"Frames: {motion.frame_count}", f"Frame Time: {_exact(motion.frame_time)}"]

    # Columns follow the order the nodes are written in (the file's own order when the
    # skeleton came from a BVH file, where it is already depth-first).
    starts = np.cumsum([0] + [len(c) for c in sk.channels])
    columns = np.concatenate([np.arange(starts[i], starts[i + 1]) for i in order]
                             ).astype(np.int64)
    out.append(_format_rows(values[:, columns], precision))
    return "\n".join(out) + "\n"


def write_bvh(motion: Motion, path: str | os.PathLike, precision: int = 6,
              reference: np.ndarray | None = None) -> None:
    """Write ``motion`` to a BVH file (see :func:`format_bvh`), atomically: the file at
    ``path`` is replaced only once the whole text is on disk."""
    text = format_bvh(motion, precision, reference)
    with atomic_open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)


def _preorder(sk: Skeleton) -> tuple[list[int], list[int]]:
    """Nodes depth-first (children in index order) and their depths; iterative, so deep
    chains do not hit the recursion limit."""
    children: list[list[int]] = [[] for _ in range(sk.node_count)]
    roots = []
    for i, p in enumerate(sk.parents):
        (children[p] if p >= 0 else roots).append(i)
    order: list[int] = []
    depth: list[int] = []
    stack = [(r, 0) for r in reversed(roots)]
    while stack:
        i, d = stack.pop()
        order.append(i)
        depth.append(d)
        stack.extend((c, d + 1) for c in reversed(children[i]))
    return order, depth


def _exact(x: float) -> str:
    """Shortest positional text that reads back as exactly ``x``."""
    return np.format_float_positional(float(x) + 0.0, trim="-")


def _format_rows(values: np.ndarray, precision: int) -> str:
    """Frame lines: values with ``precision`` decimals, space separated."""
    if values.shape[1] == 0:
        return "\n" * (values.shape[0] - 1)
    # Rounding first turns tiny negatives into 0 rather than '-0.000'; + 0.0 drops -0.0.
    rounded = np.round(values, precision) + 0.0
    row = " ".join([f"%.{precision}f"] * values.shape[1])
    return "\n".join(row % tuple(r) for r in rounded.tolist())

"""read_bvh reads a file a block at a time, twice, and never holds its text whole: for every
good, odd and bad input (the samples, the malformed-input variants, test_bvh's bad inputs with
LF and CRLF, and edge cases of line breaks, byte-order marks, NULs and UTF-8 across blocks) it
gives what parse_bvh of the whole file's bytes gives: the same motion, or the same error, at
block sizes that cut every line, every CRLF and every multi-byte character."""
from __future__ import annotations

import numpy as np
import pytest
from malformed_inputs import variants
from test_bvh import BAD, long_sample_text, traced

import mocodec.io.bvh
from mocodec.io import read_bvh
from mocodec.io.bvh import BVHError, parse_bvh

HEAD = "HIERARCHY\nROOT Hüfte\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xposition Yposition Zposition\n}\nMOTION\n"


def _outcome(read):
    try:
        m = read()
    except BVHError as exc:
        return ("error", str(exc))
    return ("motion", m.skeleton.names, m.frame_count, m.frame_time, m.name,
            np.asarray(m.rotations).tobytes(), np.asarray(m.translations).tobytes(),
            np.asarray(m.source_channels).tobytes())


def _cases() -> list[tuple[str, bytes]]:
    cases = [(name, data) for name, file, data, _ in variants() if file.endswith(".bvh")]
    for name, lines, _, _ in BAD:
        for newline in ("\n", "\r\n"):
            cases.append((f"{name} {newline!r}", (newline.join(lines) + (newline if lines else "")).encode()))
    frames = "Frames: 3\nFrame Time: 0.01\n1 2 3\n4 5 6\n7 8 9\n"
    cases += [
        ("BOM then bad UTF-8 later", b"\xef\xbb\xbf" + (HEAD + "Frames: 1\nFrame Time: 0.01\n1 2 \xff\n").encode("latin-1")),
        ("two BOMs", b"\xef\xbb\xbf" + ("\ufeff" + HEAD + frames).encode()),
        ("NUL in a frame and bad UTF-8 after it", (HEAD + frames).encode() + b"\x00\n\xff\n"),
        ("NUL in the frames", (HEAD + frames + "1 2\x003\n").encode()),
        ("CR line ends", (HEAD + frames).replace("\n", "\r").encode()),
        ("CR then LF across blocks", (HEAD + frames).replace("\n", "\r\n").encode()),
        ("mixed line ends", (HEAD + frames).replace("\n", "\r", 3).encode()),
        ("blank lines and spaces", (HEAD + "Frames: 2\n\n  \nFrame Time: 0.01\n\n1 2 3\n \t\n4 5 6\n\n\n").encode()),
        ("form feed in a frame line", (HEAD + "Frames: 1\nFrame Time: 0.01\n1 2\x0c3\n").encode()),
        ("one empty line", b"\n"),
        ("no line break at all", b"HIERARCHY"),
        ("only the header", (HEAD + "Frames: 0\nFrame Time: 0.01").encode()),
        ("extra frame lines", (HEAD + frames + "1 2\n").encode()),
        ("CR line ends and bad UTF-8", (HEAD + frames).replace("\n", "\r").encode().replace(b"OFFSET", b"OFF\xffSET")),
        ("a line longer than many blocks", (HEAD + "Frames: 1\nFrame Time: 0.01\n" + "1 " * 5000 + "\n").encode()),
        ("non-breaking spaces as blank lines", (HEAD + frames.replace("7 8 9\n", "7 8 9\n\u00a0\u2003\n")).encode()),
    ]
    return cases


@pytest.mark.parametrize("block", [1, 2, 3, 7, 64, 1 << 22])
def test_streamed_read_is_parse_of_the_whole_file(tmp_path, monkeypatch, sample_paths, block) -> None:
    monkeypatch.setattr(mocodec.io.bvh, "_READ_BLOCK", block)
    cases = _cases()
    if block < 7:  # a byte or two at a time: the small cases (the variants run to megabytes)
        cases = [(name, data) for name, data in cases if len(data) < 20_000]
    if block >= 64:
        cases += [(p.name, p.read_bytes()) for p in sample_paths]
    assert len(cases) > 60
    mismatches = []
    for i, (name, data) in enumerate(cases):
        path = tmp_path / f"{i:03d}.bvh"
        path.write_bytes(data)
        want = _outcome(lambda: parse_bvh(data, path=str(path)))
        got = _outcome(lambda: read_bvh(path))
        if got != want:
            mismatches.append(f"{name}: {want[:2] if want[0] == 'error' else want[0]} != {got[:2]}")
    assert not mismatches, "\n".join(mismatches[:10])


@pytest.mark.parametrize("change", ["a frame line gone", "rewritten, same size"])
def test_a_file_that_changes_between_the_two_reads_is_refused(tmp_path, monkeypatch, change) -> None:
    path = tmp_path / "changes.bvh"
    data = (HEAD + "Frames: 2\nFrame Time: 0.01\n1 2 3\n4 5 6\n").encode()
    path.write_bytes(data)
    count = mocodec.io.bvh._Scan.__init__

    def scan_then_change(self, text):
        count(self, text)
        if change == "a frame line gone":
            with open(path, "r+b") as f:
                f.truncate(len(data) - len("4 5 6\n"))
        else:
            path.write_bytes(data.replace(b"Time: 0.01\n1 2 3", b"Time: 0.02\n9 9 9"))
    monkeypatch.setattr(mocodec.io.bvh._Scan, "__init__", scan_then_change)
    with pytest.raises(BVHError, match="changed while it was read"):
        read_bvh(path)


def test_a_bad_byte_in_a_file_of_cr_line_ends_is_on_its_line(tmp_path) -> None:
    data = b"HIERARCHY\rROOT a\rOFF\xffSET 0 0 0\r"
    (tmp_path / "cr.bvh").write_bytes(data)
    for read in (lambda: parse_bvh(data), lambda: read_bvh(tmp_path / "cr.bvh")):
        with pytest.raises(BVHError, match="not UTF-8") as info:
            read()
        assert info.value.line == 3


def test_a_bad_byte_after_a_byte_order_mark_is_named_where_it_is(tmp_path) -> None:
    data = b"\xef\xbb\xbfHIERARCHY\nROOT H\xffips\n"
    at = data.index(b"\xff")
    for read in (lambda: parse_bvh(data, path="x.bvh"), lambda: read_bvh(tmp_path / "x.bvh")):
        (tmp_path / "x.bvh").write_bytes(data)
        with pytest.raises(BVHError, match=f"byte 0xff at offset {at}") as info:
            read()
        assert info.value.line == 2


def test_reading_a_file_holds_a_block_of_its_text_not_all_of_it(tmp_path, monkeypatch, sample_paths) -> None:
    """parse_bvh of a file's bytes holds the text two or three times over at its peak; read_bvh
    holds a block of it (64 KB here) beside the motion it keeps."""
    monkeypatch.setattr(mocodec.io.bvh, "_READ_BLOCK", 1 << 16)
    path = tmp_path / "long.bvh"
    path.write_text(long_sample_text(sample_paths[0], 6000))
    size = path.stat().st_size
    motion, kept, peak = traced(lambda: read_bvh(path))
    assert motion.frame_count == 6000
    assert peak < kept + 0.5 * size, ((peak - kept) / size, size)  # (0.23 measured; whole: 2-3)

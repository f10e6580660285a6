"""Coverage-guided fuzzing of the encoder's input readers (atheris, libFuzzer for Python).

    python tests/fuzz_readers.py bvh  [libFuzzer flags] [corpus dirs]
    python tests/fuzz_readers.py gltf [libFuzzer flags] [corpus dirs]
    python tests/fuzz_readers.py bvh --write-seeds DIR     (write the seeds into DIR and exit)

``make fuzz-readers`` (the Makefile at the root) writes the seeds, then runs both targets for
FUZZ_SECONDS each. The contract held on every input:

- the reader returns motions (``parse_bvh``: one; ``read_gltf``: a list), or raises its own
  error (:class:`~mocodec.io.bvh.BVHError`, :class:`~mocodec.io.gltf.GLTFError`) whose message
  is one non-empty line naming the file; any other exception is a finding;
- a motion it returns passes the format's limits (:func:`mocodec.limits.check_motion`) or is
  refused by that check with a :class:`~mocodec.limits.LimitError` in one line (what
  ``mocodec encode`` does next);
- no input hangs or eats memory: libFuzzer's ``-timeout`` and ``-rss_limit_mb`` (the make
  target passes 10 s and 1,024 MB, the limits of tests/test_malformed_inputs.py) turn one
  into a crash report with the input saved.

Seeds: the bundled samples (BVH cut to their first frames: a seed's size is paid on every
mutation) and every variant of tests/malformed_inputs.py, built from those cut samples.
This lives in tests/ beside malformed_inputs.py, whose variants it starts from, and because it
drives the Python encoder: runtime_c/fuzz/ holds the C runtime's targets.
"""
from __future__ import annotations

import atexit
import contextlib
import io
import shutil
import sys
import tempfile
from pathlib import Path

import atheris

# The readers and what they build motions with (not the codecs, which they never reach); the
# hook's line per module is left out of the output.
with contextlib.redirect_stderr(io.StringIO()), atheris.instrument_imports(include=["mocodec.io", "mocodec.limits", "mocodec.motion", "mocodec.rotations",
                                         "mocodec.kinematics"]):
    from mocodec import limits
    from mocodec.io.bvh import BVHError, parse_bvh
    from mocodec.io.gltf import GLTFError, read_gltf

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import malformed_inputs  # noqa: E402

SEED_FRAMES = 4
"""Frames kept of each sample BVH for its seed."""
MAX_SEED_BYTES = 64 << 10
"""Seeds larger than this are left out (libFuzzer's -max_len: longer inputs cost every run)."""


class ContractBroken(AssertionError):
    """A reader broke its contract (the fuzzer reports it as a crash, with the input)."""


def _cut_bvh(text: str, frames: int) -> str:
    """``text`` with its motion cut to the first ``frames`` frames."""
    lines = text.split("\n")
    at = lines.index("MOTION")
    rows = [ln for ln in lines[at + 3:] if ln.strip()][:frames]
    return "\n".join(lines[:at] + ["MOTION", f"Frames: {len(rows)}", lines[at + 2]] + rows) + "\n"


def seeds(reader: str) -> list[tuple[str, bytes]]:
    """(file name, bytes) of every seed of ``reader`` ("bvh" or "gltf")."""
    samples = malformed_inputs.SAMPLES
    out: list[tuple[str, bytes]] = []
    with tempfile.TemporaryDirectory() as tmp:
        small = Path(tmp)
        for bvh in sorted(samples.glob("*.bvh")):
            (small / bvh.name).write_text(_cut_bvh(bvh.read_text(), SEED_FRAMES))
        shutil.copytree(samples / "gltf", small / "gltf")
        if reader == "bvh":
            out += [(p.name, p.read_bytes()) for p in sorted(small.glob("*.bvh"))]
        else:
            out += [(p.name, p.read_bytes()) for p in sorted((small / "gltf").iterdir()) if p.suffix in (".gltf", ".glb")]
        # The variants from the cut samples: the same faults in a fraction of the bytes.
        saved, malformed_inputs.SAMPLES = malformed_inputs.SAMPLES, small
        try:
            cases = malformed_inputs.variants()
        finally:
            malformed_inputs.SAMPLES = saved
    suffix = ".bvh" if reader == "bvh" else ".gltf"
    out += [(f"variant{i:03d}{suffix}", data) for i, (_, file, data, _) in enumerate(cases) if file.endswith(suffix)]
    return [(name, data) for name, data in out if len(data) <= MAX_SEED_BYTES]


def _check_message(err: Exception, path: str) -> None:
    text = str(err)
    if not text or "\n" in text or path not in text:
        raise ContractBroken(f"{type(err).__name__} message is not one line naming the file: {text[:300]!r}")


def _check_motions(motions) -> None:
    for m in motions:
        try:
            limits.check_motion(m)
        except limits.LimitError as err:
            if not str(err) or "\n" in str(err):
                raise ContractBroken(f"LimitError message is not one line: {str(err)[:300]!r}") from err


class _Target:
    """One reader's fuzz body; glTF inputs are written to a private folder (a glTF names
    buffer files relative to itself: nothing else lies beside it)."""

    def __init__(self, reader: str) -> None:
        self.reader = reader
        self.folder = Path(tempfile.mkdtemp(prefix="mocodec-fuzz-"))
        atexit.register(shutil.rmtree, self.folder, True)

    def path(self, data: bytes) -> str:
        """The file name the reader is given for ``data``."""
        if self.reader == "bvh":
            return "fuzz.bvh"
        return str(self.folder / ("fuzz.glb" if data[:4] == b"glTF" else "fuzz.gltf"))

    def read(self, data: bytes) -> list:
        """The motions of ``data``; raises what the reader raises."""
        if self.reader == "bvh":
            return [parse_bvh(data, path=self.path(data))]
        file = Path(self.path(data))
        file.write_bytes(data)
        try:
            return read_gltf(file)
        finally:
            file.unlink()

    def __call__(self, data: bytes) -> None:
        try:
            motions = self.read(data)
        except (BVHError if self.reader == "bvh" else GLTFError) as err:
            _check_message(err, self.path(data))
            return
        _check_motions(motions)


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[1] not in ("bvh", "gltf"):
        print(__doc__, file=sys.stderr)
        return 2
    reader = argv[1]
    if len(argv) == 4 and argv[2] == "--write-seeds":
        folder = Path(argv[3])
        folder.mkdir(parents=True, exist_ok=True)
        for name, data in seeds(reader):
            (folder / name).write_bytes(data)
        return 0
    target = _Target(reader)
    # The samples must read: a reader that refused everything would keep the contract.
    for name, data in seeds(reader):
        if not name.startswith("variant"):
            _check_motions(target.read(data))
    atheris.Setup([argv[0]] + argv[2:], target)
    atheris.Fuzz()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

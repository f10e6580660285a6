"""The reader fuzz targets (tests/fuzz_readers.py): their seeds keep the contract, the contract
check catches a reader that breaks it, and a short atheris run of each target ends clean.
The long runs are `make fuzz-readers FUZZ_SECONDS=N`."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

atheris = pytest.importorskip("atheris")

import fuzz_readers  # noqa: E402  (needs atheris)

HERE = Path(__file__).resolve().parent


@pytest.mark.parametrize("reader", ["bvh", "gltf"])
def test_every_seed_keeps_the_contract(reader: str) -> None:
    target = fuzz_readers._Target(reader)
    found = fuzz_readers.seeds(reader)
    samples = [name for name, _ in found if not name.startswith("variant")]
    assert samples and len(found) > len(samples) + 15
    for name, data in found:
        target(data)  # raises ContractBroken (or what the reader let through)
        if name in samples:
            assert target.read(data)


def test_the_check_catches_a_foreign_exception_and_a_bad_message(monkeypatch: pytest.MonkeyPatch) -> None:
    target = fuzz_readers._Target("bvh")

    def raises(exc):
        def parse(data, path=None):
            raise exc
        return parse

    monkeypatch.setattr(fuzz_readers, "parse_bvh", raises(KeyError("x")))
    with pytest.raises(KeyError):
        target(b"HIERARCHY\n")
    monkeypatch.setattr(fuzz_readers, "parse_bvh", raises(fuzz_readers.BVHError("two\nlines", "fuzz.bvh", 3)))
    with pytest.raises(fuzz_readers.ContractBroken):
        target(b"HIERARCHY\n")
    monkeypatch.setattr(fuzz_readers, "parse_bvh", raises(fuzz_readers.BVHError("no file named")))
    with pytest.raises(fuzz_readers.ContractBroken):
        target(b"HIERARCHY\n")


@pytest.mark.parametrize("reader", ["bvh", "gltf"])
def test_a_short_fuzz_run_ends_clean(reader: str, tmp_path: Path) -> None:
    corpus = tmp_path / "corpus"
    subprocess.run([sys.executable, str(HERE / "fuzz_readers.py"), reader, "--write-seeds", str(corpus)], check=True)
    r = subprocess.run([sys.executable, str(HERE / "fuzz_readers.py"), reader, "-runs=400", "-timeout=10",
                        "-rss_limit_mb=1024", f"-artifact_prefix={tmp_path}/", str(corpus)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    # libFuzzer can end a little past -runs (a loaded CI run said "Done 421 runs").
    done = re.search(r"Done (\d+) runs", r.stderr)
    assert done and 400 <= int(done.group(1)) < 600, r.stderr[-3000:]

"""bench/engine_bench: the driver reads the clip dump, measures errors as the encoder does, refuses
bad input in one line, and (with ../shared/acl) reproduces ACL_REFERENCE.md's per-clip bytes."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"
sys.path.insert(0, str(BENCH))

import engine_bench  # noqa: E402
from mocodec.encode import encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402

CM_PER_UNIT = 5.644


@pytest.fixture(scope="module")
def clip_and_asset(tmp_path_factory: pytest.TempPathFactory, sample_paths: list[Path]):
    """Sample 09_11 dumped for the driver, and encoded with spline at 1 cm."""
    tmp = tmp_path_factory.mktemp("engine_bench")
    motion = read_bvh(next(p for p in sample_paths if p.stem == "09_11"))
    dump = tmp / "clips.bin"
    engine_bench.write_dump([motion], CM_PER_UNIT, dump)
    result = encode_motions([motion], [resolve_units(motion.skeleton, None, CM_PER_UNIT)], "spline", Tolerance(1.0))
    asset = tmp / "spline.mcd"
    asset.write_bytes(result.asset)
    return dump, asset, result


@pytest.fixture(scope="module")
def driver_without_acl() -> Path:
    return engine_bench.build_driver(engine_bench.RUNTIME_DEFAULT_FLAGS, acl=False)


def test_run_measures_the_encoders_error_and_the_engine_bytes(clip_and_asset, driver_without_acl: Path,
                                                               tmp_path: Path) -> None:
    dump, asset, result = clip_and_asset
    out = tmp_path / "run.json"
    subprocess.run([str(driver_without_acl), "run", str(dump), "--mcd", f"spline:1={asset}", "--rounds", "1",
                    "--open-reps", "1", "--json", str(out)], check=True, capture_output=True)
    run = json.loads(out.read_text())
    assert run["acl"]["available"] is False and run["acl"]["reason"]
    (m,) = run["mcd"]
    encoder_max = result.clips[0].error.max_cm
    assert m["max_cm"] == pytest.approx(encoder_max, abs=1e-4)
    assert m["world_path_max_cm"] == pytest.approx(encoder_max, abs=2e-3)  # float world poses
    assert m["engine_bytes_1"] == m["asset_bytes"] + m["resident_bytes"] + m["scratch_bytes"]
    assert m["engine_bytes_tick"] == m["asset_bytes"] + m["resident_bytes"] + 8 * m["scratch_bytes"]
    assert run["frames"] == result.clips[0].frames
    poses = {md["key"]: md["poses"] for md in run["modes"]}
    assert poses["seq_local"] == poses["random_local"] == result.clips[0].frames
    (speed,) = run["speed"]
    assert all(v["cpu_us"]["median"] > 0 for v in speed["modes"].values())


def test_speed_command_reports_every_mode(clip_and_asset, driver_without_acl: Path) -> None:
    _, asset, _ = clip_and_asset
    sp = engine_bench.mocodec_speed(driver_without_acl, asset, 1)
    assert sp["asset_bytes"] == asset.stat().st_size
    for key in ("local_sequential", "local_random", "world_sequential", "world_random"):
        assert sp[f"us_per_pose_{key}"] > 0


def test_a_truncated_dump_is_refused_in_one_line(clip_and_asset, driver_without_acl: Path, tmp_path: Path) -> None:
    dump, asset, _ = clip_and_asset
    cut = tmp_path / "cut.bin"
    cut.write_bytes(dump.read_bytes()[:1000])
    r = subprocess.run([str(driver_without_acl), "run", str(cut), "--mcd", f"spline:1={asset}", "--json",
                        str(tmp_path / "x.json")], capture_output=True, text=True)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and re.fullmatch(rf"engine_bench: {re.escape(str(cut))}: truncated at byte \d+", lines[0])


def test_acl_tune_reproduces_the_reference_bytes(clip_and_asset, tmp_path: Path) -> None:
    reference = engine_bench.SHARED / "ACL_REFERENCE.md"
    if not all(p.is_dir() for p in engine_bench.ACL_INCLUDES) or not reference.exists():
        pytest.skip(f"ACL 2.1 or its reference is not at {engine_bench.SHARED} (set MOCODEC_SHARED): "
                    "the ACL side of engine_bench is not tested")
    row = re.search(r"^\| 09_11 \| \d+ \| ([0-9,]+) \|", reference.read_text(), re.M)
    assert row, "ACL_REFERENCE.md has no per-clip row for 09_11"
    dump, _, _ = clip_and_asset
    exe = engine_bench.build_driver(acl=True)
    out = tmp_path / "acl.csv"
    subprocess.run([str(exe), "tune", str(dump), "--target-cm", "1", "--out", str(out)], check=True,
                   capture_output=True)
    clip, precision, size, max_cm, met, _ = out.read_text().splitlines()[1].split(",")
    assert clip == "09_11" and met == "1" and float(max_cm) <= 1.0
    assert int(size) == int(row.group(1).replace(",", ""))

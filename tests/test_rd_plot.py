"""bench/rd_plot.py reads every result shape it claims to and skips the rest."""
from __future__ import annotations

import json
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "bench"
sys.path.insert(0, str(BENCH))

import rd_plot  # noqa: E402


def test_reads_rows_lists_and_per_clip_results_and_skips_others(tmp_path: Path) -> None:
    (tmp_path / "spline.json").write_text(json.dumps({
        "codec": "spline", "clips": 35, "frames": 49_980,
        "rows": [{"tolerance_cm": 1, "asset_bytes": 500, "max_cm": 1.0, "mean_cm": 0.3},
                 {"tolerance_cm": 0.1, "asset_bytes": 2000, "max_cm": 0.1, "mean_cm": 0.03}]}))
    (tmp_path / "bare.json").write_text(json.dumps([{"tolerance": 2, "bytes": 90, "max_cm": 3.0}]))
    (tmp_path / "neural.json").write_text(json.dumps({"clips": {
        "a": {"frames": 10, "codecs": [
            {"codec": "n", "tolerance_cm": 1, "met": True, "asset_bytes": 5, "max_error_cm": 0.9, "mean_error_cm": 0.2},
            {"codec": "n", "tolerance_cm": 3, "met": False}]},
        "b": {"frames": 30, "codecs": [
            {"codec": "n", "tolerance_cm": 1, "met": True, "asset_bytes": 7, "max_error_cm": 0.5, "mean_error_cm": 0.4},
            {"codec": "n", "tolerance_cm": 3, "met": True, "asset_bytes": 3, "max_error_cm": 2.0, "mean_error_cm": 1.0}]}}}))
    (tmp_path / "study.json").write_text(json.dumps({"groups": 3, "totals": {}}))
    (tmp_path / "broken.json").write_text("{")

    series = {s.label: s for s in rd_plot.collect(tmp_path)}
    assert set(series) == {"spline", "bare", "n [neural]"}
    assert series["spline"].dev_set and series["spline"].points == [(500.0, 1.0, 0.3), (2000.0, 0.1, 0.03)]
    assert series["bare"].points == [(90.0, 3.0, None)]
    # Per-clip rows add up; a tolerance missed on one clip is left out; the mean is frame-weighted.
    assert series["n [neural]"].points == [(12.0, 0.9, (0.2 * 10 + 0.4 * 30) / 40)]

    out = tmp_path / "rd.png"
    rd_plot.plot(list(series.values()), None, out)
    assert out.stat().st_size > 10_000

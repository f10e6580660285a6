"""Rate-distortion plot of every codec with results in bench/results/, beside ACL 2.1.

    python bench/rd_plot.py                       # bench/results/*.json -> docs/rd_curve.png
    python bench/rd_plot.py --results DIR --out FILE.png

Two panels: size (bytes, log) against max error and against mean error (cm, log). A result
file is read if it has one of these shapes (anything else, e.g. analysis studies, is skipped):

- ``{"codec": name, "clips": n, "frames": f, "rows": [row, ...]}`` (``run_bench.py``,
  ``clip_pca.py``; future ``rma.json``, ``fk_wavelet.json``), or a bare list of rows;
- ``{"clips": {clip: {"frames": f, "codecs": [row + "codec", ...]}}}`` (``bench_neural.py``):
  one point per (codec, tolerance) summed over the clips, only where every clip met it.

A row needs a size (``asset_bytes`` or ``bytes``) and a max error (``max_cm`` or
``max_error_cm``); ``mean_cm`` / ``mean_error_cm`` puts it on the right panel too. Series
measured on another clip set than the CMU dev set (35 clips, 49,980 frames) are drawn hollow
and labelled with their set: their bytes are not comparable with the dev-set ones.
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))

import acl_reference  # noqa: E402

DEV_CLIPS, DEV_FRAMES = 35, 49_980


@dataclass
class Series:
    """One curve: points (bytes, max cm, mean cm or None), sorted by size."""

    label: str
    clips: int | None
    frames: int | None
    points: list[tuple[float, float, float | None]] = field(default_factory=list)

    @property
    def dev_set(self) -> bool:
        return self.clips == DEV_CLIPS and self.frames == DEV_FRAMES


def _first(row: dict, *keys: str) -> float | None:
    for k in keys:
        if row.get(k) is not None:
            return float(row[k])
    return None


def _point(row: dict) -> tuple[float, float, float | None] | None:
    size = _first(row, "asset_bytes", "bytes")
    mx = _first(row, "max_cm", "max_error_cm")
    if size is None or mx is None or row.get("met") is False:
        return None
    return size, mx, _first(row, "mean_cm", "mean_error_cm")


def read_series(path: Path) -> list[Series]:
    """Curves in one result file (empty when the file has no RD rows)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return []
    if isinstance(data, list):
        data = {"rows": data}
    if not isinstance(data, dict) or "tolerance_cm" in data:
        return []  # a sweep of settings at one tolerance (e.g. ik_predict_variants) is no RD curve
    if isinstance(data.get("rows"), list):
        s = Series(str(data.get("label") or data.get("codec") or path.stem), data.get("clips"), data.get("frames"))
        s.points = sorted(p for p in map(_point, data["rows"]) if p is not None)
        return [s] if s.points else []
    clips = data.get("clips")
    if isinstance(clips, dict) and all(isinstance(c, dict) and "codecs" in c for c in clips.values()):
        return _per_clip_series(path.stem, clips)
    return []


def _per_clip_series(stem: str, clips: dict) -> list[Series]:
    """Sum per-clip rows into set-level points: bytes add, max is the max, mean is weighted by
    frames; a (codec, tolerance) that missed on any clip is left out."""
    groups: dict[tuple[str, float], list[tuple[dict, int]]] = {}
    for c in clips.values():
        for row in c["codecs"]:
            groups.setdefault((row.get("codec", "?"), row.get("tolerance_cm")), []).append((row, c["frames"]))
    frames = sum(int(c["frames"]) for c in clips.values())
    out: dict[str, Series] = {}
    for (codec, _), rows in groups.items():
        pts = [_point(r) for r, _ in rows]
        if len(rows) != len(clips) or any(p is None for p in pts):
            continue
        total = sum(p[0] for p in pts)
        means = [p[2] for p in pts]
        mean = (sum(m * f for m, (_, f) in zip(means, rows)) / sum(f for _, f in rows)
                if all(m is not None for m in means) else None)
        s = out.setdefault(codec, Series(f"{codec} [{stem}]", len(clips), frames))
        s.points.append((total, max(p[1] for p in pts), mean))
    for s in out.values():
        s.points.sort()
    return list(out.values())


def collect(results: Path) -> list[Series]:
    series = []
    for path in sorted(results.glob("*.json")):
        series += read_series(path)
    return series


def plot(series: list[Series], acl: acl_reference.AclReference | None, out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")  # files only, no display on the bench machines
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5), sharey=True)
    markers = "osD^v<>pX*h"
    for i, s in enumerate(series):
        style = dict(marker=markers[i % len(markers)], linestyle="-", color=f"C{i % 10}")
        if s.dev_set:
            label = s.label
        elif s.clips is None or s.frames is None:
            label = f"{s.label} (clip set not stated)"
        else:
            label = f"{s.label} ({s.clips} clips, {s.frames:,} frames: other set)"
        if not s.dev_set:
            style.update(markerfacecolor="none", linestyle="--")
        # Lines follow the error axis of each panel (a sweep need not be monotonic in both).
        axes[0].plot(*zip(*sorted((p[1], p[0]) for p in s.points)), label=label, **style)
        mean_pts = sorted((p[2], p[0]) for p in s.points if p[2] is not None)
        if mean_pts:
            axes[1].plot(*zip(*mean_pts), label=label, **style)
    if acl is not None:
        # The sweep's rows past ACL's turning point (0.5u, 0.7u) are drawn too: they are measured.
        sweep = sorted((e, b) for p, b, e in acl.sweep)
        axes[0].plot(*zip(*sweep), color="k", marker="s", linestyle=":", label="ACL 2.1 (precision sweep)")
        if acl.totals:
            axes[1].plot([t[3] for t in acl.totals], [t[1] for t in acl.totals], color="k",
                         marker="s", linestyle=":", label="ACL 2.1 (totals table)")
            for name, b, _, mean in acl.totals:
                axes[1].annotate(name, (mean, b), fontsize=7, xytext=(3, 3), textcoords="offset points")
    # The regime seed 003's ratios are read in: mean <= 2 cm, max <= 6 cm.
    for ax, x in zip(axes, (6.0, 2.0)):
        ax.axvline(x, color="0.5", linestyle="--", linewidth=0.8)
        ax.annotate("seed 003 regime", (x, 1.0), xycoords=("data", "axes fraction"), fontsize=7,
                    xytext=(-3, -12), textcoords="offset points", ha="right", color="0.4")
    for ax, what in zip(axes, ("max", "mean")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"{what} world-position error, every joint and frame (cm)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("size (bytes)")
    axes[0].set_title("size vs max error")
    axes[1].set_title("size vs mean error")
    for ax in axes:
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(f"CMU dev set ({DEV_CLIPS} clips, {DEV_FRAMES:,} frames, 120 Hz) unless marked")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--results", type=Path, default=HERE / "results")
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "rd_curve.png")
    ap.add_argument("--no-acl", action="store_true", help="leave ACL 2.1's reference points out")
    args = ap.parse_args(argv)
    series = collect(args.results)
    acl = None if args.no_acl else acl_reference.load()
    for s in series:
        print(f"{s.label}: {len(s.points)} points, {s.clips} clips, {s.frames} frames", file=sys.stderr)
    if acl is None and not args.no_acl:
        print("ACL reference not found; drawn without it", file=sys.stderr)
    if not series and acl is None:
        print(f"nothing to plot in {args.results}", file=sys.stderr)
        return 1
    plot(series, acl, args.out)
    print(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

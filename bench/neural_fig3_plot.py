"""Seed 001's Figure 3 on our clips, as a picture: max joint error (% of skeleton height)
against compression ratio for SVD, naive and adaptive frequencies, one panel per clip.

    .venv/bin/python bench/neural_fig3_plot.py bench/results/neural_fig3_dev.json docs/neural_fig3.png

Reads the ``figure3`` part of a ``bench_neural.py --figure3`` run.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

STYLE = {"svd": ("SVD (rank 1 ... 32)", "s", "tab:gray"),
         "naive": ("naive frequencies {1..K}", "^", "tab:blue"),
         "adaptive": ("adaptive frequencies (Algorithm 1)", "o", "tab:red")}


def main(src: Path, out: Path) -> int:
    import matplotlib
    matplotlib.use("Agg")  # files only, no display on the bench machines
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    clips = json.loads(src.read_text())["figure3"]
    if not clips:
        print(f"{src}: no Figure 3 curves", file=sys.stderr)
        return 1
    fig, axes = plt.subplots(1, len(clips), figsize=(3.4 * len(clips), 3.6), squeeze=False)
    for ax, (name, c) in zip(axes[0], clips.items()):
        for mode, (label, marker, color) in STYLE.items():
            pts = sorted((r["ratio"], r["max_pct_height"]) for r in c[mode])
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=marker, color=color, ms=3, lw=1, label=label)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{name} ({c['frames']} frames)", fontsize=9)
        ax.set_xlabel("compression ratio (pose numbers / stored numbers)", fontsize=7)
        ax.xaxis.set_minor_formatter(NullFormatter())  # log minor labels collide at this size
        ax.grid(True, which="both", lw=0.3)
        ax.tick_params(labelsize=7)
    axes[0][0].set_ylabel("max joint error, % of height", fontsize=8)
    axes[0][0].legend(fontsize=6, loc="lower right")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(Path(sys.argv[1]), Path(sys.argv[2])))

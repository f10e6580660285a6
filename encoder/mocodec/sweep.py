"""``mocodec eval --sweep``: size against error of one or more codecs over a range of tolerances,
measured through the C runtime, written as a page (inline SVG, no script, no network) or a PNG."""
from __future__ import annotations

import html
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

from .encode import EncodeError, encode_motions
from .output import atomic_open
from .metrics import combine
from .motion import Motion
from .tolerance import Tolerance
from .units import UnitsChoice

if TYPE_CHECKING:
    from .bake import Runner

COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf")


@dataclass
class SweepPoint:
    """One codec at one tolerance (``failed`` says why when it could not be encoded)."""

    codec: str
    tolerance_cm: float
    asset_bytes: int | None = None
    ratio_bvh: float | None = None
    max_cm: float | None = None
    p99_cm: float | None = None
    mean_cm: float | None = None
    encode_seconds: float | None = None
    failed: str | None = None


def run_sweep(motions: list[Motion], units: list[UnitsChoice], codec_names: Sequence[str],
              tolerances: Sequence[float], options: dict | None = None,
              progress: Callable[[str], None] | None = None, runner: "Runner | None" = None) -> list[SweepPoint]:
    """Encode ``motions`` with every codec at every tolerance and measure each asset (the clips
    of each encoded by ``runner``, :mod:`mocodec.bake`; None: in this process)."""
    points = []
    for codec in codec_names:
        for tol in sorted(tolerances):
            try:
                r = encode_motions(motions, units, codec, Tolerance(tol), options, runner=runner)
            except EncodeError as exc:
                points.append(SweepPoint(codec, tol, failed=str(exc).splitlines()[0]))
            else:
                err = combine([c.error for c in r.clips])
                points.append(SweepPoint(codec, tol, r.size.asset_bytes, r.size.ratio_bvh, err["max_cm"],
                                         err["p99_cm"], err["mean_cm"], r.encode_seconds))
            if progress:
                progress(f"{codec} {tol:g} cm")
    return points


def points_json(points: list[SweepPoint]) -> list[dict]:
    return [asdict(p) for p in points]


# ---------------------------------------------------------------------------------- the page
def _log_ticks(lo: float, hi: float) -> list[float]:
    ticks = []
    for e in range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1):
        for m in (1, 2, 5):
            v = m * 10.0 ** e
            if lo <= v <= hi:
                ticks.append(v)
    return ticks


def _fmt(v: float) -> str:
    return f"{v:,.0f}" if v >= 1000 else f"{v:g}"


def _panel(points: list[SweepPoint], codecs: list[str], error: str, title: str) -> str:
    """One SVG chart: asset bytes (log) against an error (log), one line per codec."""
    ok = [p for p in points if p.failed is None and getattr(p, error) and getattr(p, error) > 0]
    w, h, left, right, top, bottom = 520, 360, 70, 16, 30, 44
    if not ok:
        return f'<svg width="{w}" height="{h}"><text x="20" y="40">no point to draw</text></svg>'
    xs = [getattr(p, error) for p in ok]
    ys = [p.asset_bytes for p in ok]
    x0, x1 = min(xs) / 1.3, max(xs) * 1.3
    y0, y1 = min(ys) / 1.3, max(ys) * 1.3
    X = lambda v: left + (math.log(v) - math.log(x0)) / (math.log(x1) - math.log(x0)) * (w - left - right)  # noqa: E731
    Y = lambda v: top + (1 - (math.log(v) - math.log(y0)) / (math.log(y1) - math.log(y0))) * (h - top - bottom)  # noqa: E731
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="11">',
           f'<text x="{left}" y="18" font-size="13" font-weight="bold">{html.escape(title)}</text>']
    for v in _log_ticks(x0, x1):
        out.append(f'<line x1="{X(v):.1f}" y1="{top}" x2="{X(v):.1f}" y2="{h - bottom}" stroke="#e4e4e4"/>'
                   f'<text x="{X(v):.1f}" y="{h - bottom + 14}" text-anchor="middle">{_fmt(v)}</text>')
    for v in _log_ticks(y0, y1):
        out.append(f'<line x1="{left}" y1="{Y(v):.1f}" x2="{w - right}" y2="{Y(v):.1f}" stroke="#e4e4e4"/>'
                   f'<text x="{left - 4}" y="{Y(v) + 4:.1f}" text-anchor="end">{_fmt(v)}</text>')
    out.append(f'<rect x="{left}" y="{top}" width="{w - left - right}" height="{h - top - bottom}" fill="none" stroke="#888"/>'
               f'<text x="{(left + w - right) / 2}" y="{h - 8}" text-anchor="middle">{error.replace("_cm", "")} error (cm, log)</text>'
               f'<text transform="translate(14 {(top + h - bottom) / 2}) rotate(-90)" text-anchor="middle">asset bytes (log)</text>')
    for i, codec in enumerate(codecs):
        colour = COLOURS[i % len(COLOURS)]
        mine = sorted((p for p in ok if p.codec == codec), key=lambda p: p.tolerance_cm)
        if len(mine) > 1:
            path = " ".join(f"{X(getattr(p, error)):.1f},{Y(p.asset_bytes):.1f}" for p in mine)
            out.append(f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="1.8"/>')
        for p in mine:
            x, y = X(getattr(p, error)), Y(p.asset_bytes)
            out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="3.5" fill="{colour}"><title>{html.escape(codec)} at '
                       f'{p.tolerance_cm:g} cm: {p.asset_bytes:,} B, {error.replace("_cm", "")} {getattr(p, error):.4f} cm'
                       f'</title></circle><text x="{x + 5:.1f}" y="{y - 5:.1f}" fill="{colour}" font-size="9">'
                       f'{p.tolerance_cm:g}</text>')
    out.append("</svg>")
    return "".join(out)


def sweep_html(points: list[SweepPoint], description: str) -> str:
    """A page a person can read: the two charts, a legend and every number in a table."""
    codecs = list(dict.fromkeys(p.codec for p in points))
    legend = " ".join(f'<span style="color:{COLOURS[i % len(COLOURS)]}">&#9679; {html.escape(c)}</span>'
                      for i, c in enumerate(codecs))
    rows = []
    for p in points:
        if p.failed:
            rows.append(f"<tr><td>{html.escape(p.codec)}</td><td>{p.tolerance_cm:g}</td>"
                        f'<td colspan="6">not met: {html.escape(p.failed)}</td></tr>')
        else:
            rows.append(f"<tr><td>{html.escape(p.codec)}</td><td>{p.tolerance_cm:g}</td><td>{p.asset_bytes:,}</td>"
                        f"<td>{p.ratio_bvh:.1f}</td><td>{p.max_cm:.4f}</td><td>{p.p99_cm:.4f}</td>"
                        f"<td>{p.mean_cm:.4f}</td><td>{p.encode_seconds:.1f}</td></tr>")
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>mocodec: size against error</title>
<style>body{{font:14px/1.45 sans-serif;margin:24px;color:#222;max-width:1100px}}
table{{border-collapse:collapse;margin-top:12px}}td,th{{padding:3px 10px;text-align:right;border-bottom:1px solid #ddd}}
td:first-child,th:first-child{{text-align:left}}.charts{{display:flex;flex-wrap:wrap;gap:16px}}</style></head>
<body><h1>Size against error</h1><p>{html.escape(description)}</p><p>{legend}</p>
<div class="charts">{_panel(points, codecs, "max_cm", "bytes against max error")}
{_panel(points, codecs, "mean_cm", "bytes against mean error")}</div>
<p>Each point is one asset holding every clip, encoded at the tolerance written beside it (the
promised max world-space error of any joint on any frame); errors are measured through the C
runtime on every frame. Lower and further left is better.</p>
<table><thead><tr><th>codec</th><th>tolerance cm</th><th>bytes</th><th>ratio vs BVH</th><th>max cm</th>
<th>p99 cm</th><th>mean cm</th><th>encode s</th></tr></thead><tbody>{''.join(rows)}</tbody></table>
</body></html>
"""


def sweep_png(points: list[SweepPoint], description: str, path: Path) -> None:
    """The same two charts as a PNG (needs matplotlib)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise EncodeError("a PNG needs matplotlib (pip install matplotlib); or write the page: --plot FILE.html") from None
    codecs = list(dict.fromkeys(p.codec for p in points))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    for ax, error in zip(axes, ("max_cm", "mean_cm")):
        for i, codec in enumerate(codecs):
            mine = sorted((p for p in points if p.codec == codec and p.failed is None), key=lambda p: p.tolerance_cm)
            ax.plot([getattr(p, error) for p in mine], [p.asset_bytes for p in mine], "o-",
                    color=COLOURS[i % len(COLOURS)], label=codec)
            for p in mine:
                ax.annotate(f"{p.tolerance_cm:g}", (getattr(p, error), p.asset_bytes), fontsize=7,
                            xytext=(4, 4), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"{error.replace('_cm', '')} error (cm)")
        ax.set_ylabel("asset bytes")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle(description, fontsize=9)
    fig.tight_layout()
    with atomic_open(path, "wb") as f:
        fig.savefig(f, dpi=120, format="png")
    plt.close(fig)

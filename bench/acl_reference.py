"""ACL 2.1's measured sizes on the CMU dev clips, read from ../shared/ACL_REFERENCE.md, for
comparing at equal max error. Users without ../shared get no ACL column, not a made-up one."""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

DEFAULT_PATH = Path(__file__).resolve().parents[2] / "shared" / "ACL_REFERENCE.md"


@dataclass
class AclReference:
    """Whole-set sweep (bytes vs max error) and per-clip bytes at the fixed precisions."""

    sweep: list[tuple[float, int, float]]       # (precision units or 0 = defaults, bytes, max error cm)
    per_clip: dict[str, dict[str, int]]         # clip -> {"cm-default", "0.01u", "0.1u", "1.0u"}
    per_clip_err_01u: dict[str, float]          # clip -> max error cm at 0.1u
    decode_us: float
    totals: list[tuple[str, int, float, float]] = field(default_factory=list)
    """Rows of the Totals table: (setting, bytes, max err cm, mean err cm); the only ACL rows
    with a mean error, so the mean-error panel of bench/rd_plot.py draws these."""

    def bytes_at_error(self, max_error_cm: float) -> float:
        """Whole-set bytes at a max error, interpolated on a log-log line between the sweep's
        rows (only over the rising part of the curve, below ACL's 0.3u turning point)."""
        rows = sorted((e, b) for _, b, e in self.sweep if e <= 2.2)
        errs = np.log([e for e, _ in rows])
        sizes = np.log([b for _, b in rows])
        x = np.log(max_error_cm)
        if x <= errs[0]:
            slope = (sizes[1] - sizes[0]) / (errs[1] - errs[0])
            return float(np.exp(sizes[0] + slope * (x - errs[0])))
        if x >= errs[-1]:
            return float(np.exp(sizes[-1]))
        return float(np.exp(np.interp(x, errs, sizes)))

    def nearest_row(self, max_error_cm: float) -> tuple[float, int, float]:
        return min(self.sweep, key=lambda r: abs(np.log(r[2] / max_error_cm)))


def load(path: Path = DEFAULT_PATH) -> AclReference | None:
    if not path.exists():
        return None
    text = path.read_text()
    sweep = []
    section = text.split("## Size against max error", 1)[1].split("##", 1)[0]
    for m in re.finditer(r"^\| ([0-9.]+) \| ([0-9,]+) \| ([0-9.]+) \|", section, re.M):
        sweep.append((float(m.group(1)), int(m.group(2).replace(",", "")), float(m.group(3))))
    per_clip, err = {}, {}
    section = text.split("## Per clip", 1)[1]
    for m in re.finditer(r"^\| (\d\d_\d\d) \| (\d+) \| (\d+) \| (\d+) \| (\d+) \| (\d+) \| ([0-9.]+) \|", section, re.M):
        name = m.group(1)
        per_clip[name] = {"cm-default": int(m.group(3)), "0.01u": int(m.group(4)),
                          "0.1u": int(m.group(5)), "1.0u": int(m.group(6))}
        err[name] = float(m.group(7))
    # ACL's own defaults (0.01 cm at a 3 cm shell, 31 joints without end sites) extend the
    # curve to the near-lossless end: the brief's "4.65 MB at 0.02 cm".
    default = re.search(r"^\| cm-default \| 31 \| ([0-9,]+) \| [0-9,]+ \| ([0-9.]+) \|", text, re.M)
    if default:
        sweep.append((0.0, int(default.group(1).replace(",", "")), float(default.group(2))))
    totals = []
    section = text.split("## Totals", 1)[1].split("##", 1)[0]
    for m in re.finditer(r"^\| ([\w.-]+) \| \d+ \| ([0-9,]+) \| [0-9,]+ \| ([0-9.]+) \| ([0-9.]+) \|", section, re.M):
        totals.append((m.group(1), int(m.group(2).replace(",", "")), float(m.group(3)), float(m.group(4))))
    decode = re.search(r"\| 0\.1u \| 38 \| [0-9,]+ \| [0-9,]+ \| [0-9.]+ \| [0-9.]+ \| ([0-9.]+) \|", text)
    return AclReference(sweep, per_clip, err, float(decode.group(1)) if decode else float("nan"), totals)

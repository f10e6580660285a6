"""Where a bench script leaves its figures: <out>.json (the numbers) and <out>.md (the table)."""
from __future__ import annotations

import json
from pathlib import Path


def write_results(out: Path, rows: object, lines: list[str]) -> None:
    """Writes the rows as JSON and the Markdown lines beside them, and prints the table."""
    out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))

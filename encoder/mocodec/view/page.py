"""The page itself: the template, the bundled viewer script, the wasm runtime, the asset and the
originals' world positions in one HTML file that opens with no network."""
from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import Any

from .. import codecs
from ..container import read_summary
from .originals import Original

HERE = Path(__file__).resolve().parent
STATIC = HERE / "static"  # built by `make web`: the bundled viewer script and the wasm runtime
TEMPLATE = HERE / "page.html"  # the markup and style the script fills
DATA_MARK = "/*MOCODEC_DATA*/"
SCRIPT_MARK = "/*MOCODEC_SCRIPT*/"


class ViewerMissing(RuntimeError):
    """The viewer's built files are not in this install."""


def _static(name: str) -> bytes:
    path = STATIC / name
    if not path.exists():
        raise ViewerMissing(f"{path}: the viewer is not built in this install (run `make web`)")
    return path.read_bytes()


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def page_data(asset: bytes, asset_name: str, originals: list[Original]) -> dict[str, Any]:
    """What the page's script reads from its data block."""
    try:
        meta = read_summary(asset).meta
    except ValueError:  # a damaged asset: the page shows the runtime's verdict
        meta = {}
    return {
        "asset": {"name": asset_name, "bytes": _b64(asset)},
        "wasm": _b64(_static("mocodec.wasm")),
        "codecs": {str(c.id): c.name for c in codecs.CODECS},
        "meta": meta,
        "originals": {
            o.clip: {"source": o.source, "frames": int(o.positions.shape[0]), "nodes": int(o.positions.shape[1]),
                     "positions_b64": _b64(o.positions.astype("<f4").tobytes())}
            for o in originals
        },
    }


def build_page(asset: bytes, asset_name: str, originals: list[Original] | None = None) -> str:
    """The HTML text of the page for ``asset`` (and the originals matched to its clips)."""
    template = TEMPLATE.read_text(encoding="utf-8")
    script = _static("viewer.js").decode("utf-8")
    # Inside <script>, "</" could close the element: JSON and JavaScript both read "<\/" as "</".
    data = json.dumps(page_data(asset, asset_name, originals or []), separators=(",", ":")).replace("</", "<\\/")
    script = script.replace("</script", "<\\/script")
    head, rest = template.split(DATA_MARK)
    middle, tail = rest.split(SCRIPT_MARK)
    return head + data + middle + script + tail

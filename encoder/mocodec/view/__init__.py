"""``mocodec view``: one self-contained HTML page that plays an asset, decoded in the page by the
runtime compiled to WebAssembly, beside the original motion, with its errors.

The page is ``page.html``; its script (three.js and the web binding, bundled from ``viewer/``) and
the wasm (``make -C runtime_c wasm``) ship in ``static/``, and ``make web`` rebuilds them.
"""
from .originals import OriginalError, match_originals, read_motions
from .page import build_page
from .serve import serve_page

__all__ = ["OriginalError", "build_page", "match_originals", "read_motions", "serve_page"]

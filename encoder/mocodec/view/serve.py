"""``mocodec view --serve``: the page on a localhost port, until interrupted."""
from __future__ import annotations

import http.server
import sys
from typing import Callable


def serve_page(html: str, port: int = 0, host: str = "127.0.0.1",
               ready: Callable[[str], None] | None = None) -> None:
    """Serve ``html`` at ``http://host:port/`` (port 0: any free one) until Ctrl-C; ``ready``
    gets the address once the socket listens."""
    body = html.encode("utf-8")

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 (the http.server name)
            if self.path not in ("/", "/index.html"):
                self.send_error(404)
                return
            self.send_response(200)
            self.send_header("Content-Type", "text/html; charset=utf-8")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, format: str, *args: object) -> None:  # quiet: one line per start
            pass

    with http.server.ThreadingHTTPServer((host, port), Handler) as server:
        url = f"http://{host}:{server.server_address[1]}/"
        (ready or (lambda u: print(f"serving the viewer at {u} (Ctrl-C stops)", file=sys.stderr, flush=True)))(url)
        try:
            server.serve_forever()
        except KeyboardInterrupt:
            pass

"""A small HTTP server on 127.0.0.1 for one twin folder: ``/`` is the viewer page (this package's ``static/``),
``/twin/...`` the folder's files, ``/vendor/three/...`` three.js from the npm packages installed at set-up
(``make`` runs ``npm ci``; nothing comes from the internet at run time)."""

from __future__ import annotations

import functools
import os
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlparse

from ..errors import TwinregError

STATIC = Path(__file__).resolve().parent / "static"


class ViewerError(TwinregError):
    """The twin folder or the viewer's JavaScript is missing."""


def vendor_folder() -> Path:
    """``node_modules`` holding three.js: ``$TWINREG_NODE_MODULES``, else the nearest one above this package."""
    env = os.environ.get("TWINREG_NODE_MODULES")
    candidates = [Path(env)] if env else [p / "node_modules" for p in Path(__file__).resolve().parents]
    for c in candidates:
        if (c / "three" / "build" / "three.module.js").is_file():
            return c
    raise ViewerError("three.js is not installed: run `make install` in the twinreg folder (npm ci), or set "
                      "TWINREG_NODE_MODULES to a node_modules folder holding the package three")


class _Handler(SimpleHTTPRequestHandler):
    roots: dict = {}

    def translate_path(self, path: str) -> str:
        p = unquote(urlparse(path).path)
        for prefix, root in self.roots.items():
            if p == prefix.rstrip("/") or p.startswith(prefix):
                rel = p[len(prefix):].lstrip("/") or "index.html"
                target = (root / rel).resolve()
                if root.resolve() in target.parents or target == root.resolve():
                    return str(target)
                return str(root / "__forbidden__")
        return str(STATIC / "__missing__")

    def end_headers(self):
        self.send_header("Cache-Control", "no-store")
        super().end_headers()

    def log_message(self, *args):  # quiet: the CLI prints the URL once
        pass


_Handler.extensions_map = {**SimpleHTTPRequestHandler.extensions_map, ".js": "text/javascript",
                           ".mjs": "text/javascript", ".glb": "model/gltf-binary", ".json": "application/json"}


def serve(folder, port: int = 0) -> tuple[ThreadingHTTPServer, str]:
    """Start serving ``folder`` (a twin: twin.json and tiles/) in a background thread; returns the server and the
    viewer's URL. ``port`` 0 takes a free one."""
    folder = Path(folder)
    if not (folder / "twin.json").is_file() or not (folder / "tiles" / "tileset.json").is_file():
        raise ViewerError(f"{folder}: not a twin folder (no twin.json and tiles/tileset.json); pass the OUT folder "
                          "of `twinreg build-twin`")
    roots = {"/twin/": folder, "/vendor/three/": vendor_folder() / "three", "/": STATIC}
    handler = type("Handler", (_Handler,), {"roots": roots})
    try:
        server = ThreadingHTTPServer(("127.0.0.1", port), functools.partial(handler))
    except OSError as exc:
        raise ViewerError(f"port {port}: cannot listen on 127.0.0.1 ({exc.strerror}); pick another --port") from exc
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}/"

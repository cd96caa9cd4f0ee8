"""A small HTTP server on 127.0.0.1 for one twin folder or one comparison: ``/`` is the viewer page (this package's
``static/``: index.html for a twin, epochs.html for the epochs of ``compare``),
``/twin/...`` the folder's files, ``/vendor/three/...`` three.js from the npm packages installed at set-up
(``make`` runs ``npm ci``; nothing comes from the internet at run time).

A twin may come from someone else, so the page treats its text as text (``viewer.js`` never builds HTML from
data) and the server makes that a rule: a Content-Security-Policy allows only this server's own scripts (and the
page's import map, by its hash), no inline script or handler; requests must name 127.0.0.1 or localhost as their
Host (a DNS-rebinding page elsewhere cannot read the folder); no folder is listed; a bad path is a 400 or 404,
never a traceback; an idle connection is closed after :data:`IDLE_TIMEOUT_S`. The folder's files are data, never
pages: only the types the viewer reads are served from it (:data:`DATA_TYPES`; anything else, a planted
``evil.html`` or ``evil.js`` included, is a 404), each with ``Content-Security-Policy: default-src 'none'; sandbox``
and ``nosniff``, so that nothing from a twin can run as this server's script or page."""

from __future__ import annotations

import base64
import functools
import hashlib
import os
import re
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlparse

from ..errors import ViewerError

STATIC = Path(__file__).resolve().parent / "static"
#: seconds an idle connection is kept open
IDLE_TIMEOUT_S = 15
#: the Host names a request may use
LOCAL_HOSTS = ("127.0.0.1", "localhost")
#: the files of a twin or comparison folder the viewer reads, by suffix, with the type they are served as
DATA_TYPES = {".json": "application/json", ".glb": "model/gltf-binary", ".bin": "application/octet-stream"}
#: the policy of every answer from the folder: nothing in it runs, even opened as a page of its own
DATA_POLICY = "default-src 'none'; sandbox"



def content_policy(page: str = "index.html") -> str:
    """The Content-Security-Policy of every answer: scripts from this server only, plus the page's inline import
    map by its sha256 (the one inline script a module page needs)."""
    html = (STATIC / page).read_text(encoding="utf-8")
    hashes = [base64.b64encode(hashlib.sha256(m.encode("utf-8")).digest()).decode("ascii")
              for m in re.findall(r'<script type="importmap">(.*?)</script>', html, re.S)]
    scripts = " ".join(["'self'"] + [f"'sha256-{h}'" for h in hashes])
    return (f"default-src 'self'; script-src {scripts}; style-src 'self'; img-src 'self' data: blob:; "
            "connect-src 'self' data: blob:; worker-src 'self' blob:; object-src 'none'; base-uri 'none'; "
            "form-action 'none'; frame-ancestors 'none'")


def vendor_folder() -> Path:
    """``node_modules`` holding three.js: ``$TWINREG_NODE_MODULES``, else the checkout's own (``npm ci`` beside
    the package: ``twinreg/../node_modules``), never one found further up (anyone may make ``/tmp/node_modules``)."""
    env = os.environ.get("TWINREG_NODE_MODULES")
    candidates = [Path(env)] if env else [Path(__file__).resolve().parents[2] / "node_modules"]
    for c in candidates:
        if (c / "three" / "build" / "three.module.js").is_file():
            return c
    raise ViewerError("three.js is not installed: run `make install` in the twinreg folder (npm ci), or set "
                      "TWINREG_NODE_MODULES to a node_modules folder holding the package three")


class _Handler(SimpleHTTPRequestHandler):
    roots: dict = {}
    page: str = "index.html"
    policy: str = "default-src 'none'"
    timeout = IDLE_TIMEOUT_S

    def _data(self) -> bool:
        """Whether the request is for the twin's folder (data), not for the viewer's own files."""
        return unquote(urlparse(self.path).path).startswith("/twin/")

    def translate_path(self, path: str) -> str:
        p = unquote(urlparse(path).path)
        if "\x00" in p or "\\" in p:
            return str(STATIC / "__forbidden__")
        for prefix, root in self.roots.items():
            if p == prefix.rstrip("/") or p.startswith(prefix):
                rel = p[len(prefix):].lstrip("/") or (self.page if root == STATIC else "")
                try:
                    target = (root / rel).resolve()
                except (OSError, ValueError, RuntimeError):
                    return str(root / "__forbidden__")
                if root.resolve() in target.parents:
                    return str(target)
                return str(root / "__forbidden__")
        return str(STATIC / "__missing__")

    def _host_ok(self) -> bool:
        host = (self.headers.get("Host") or "").strip().lower()
        name = host[1:host.index("]")] if host.startswith("[") and "]" in host else host.rsplit(":", 1)[0]
        return name in LOCAL_HOSTS or name == "::1"

    def send_head(self):
        if not self._host_ok():
            self.send_error(421, "this viewer answers only requests for 127.0.0.1 or localhost")
            return None
        path = self.translate_path(self.path)
        if os.path.isdir(path):  # no folder is listed, whatever it holds
            self.send_error(404, "not found")
            return None
        if self._data() and Path(path).suffix.lower() not in DATA_TYPES:  # never a page, a script or a style
            self.send_error(404, "not found")
            return None
        try:
            return super().send_head()
        except (OSError, ValueError):
            self.send_error(400, "bad request")
            return None

    def guess_type(self, path):
        if self._data():
            return DATA_TYPES.get(Path(str(path)).suffix.lower(), "application/octet-stream")
        return super().guess_type(path)

    def end_headers(self):
        self.send_header("Cache-Control", "no-store")
        self.send_header("Content-Security-Policy", DATA_POLICY if self._data() else self.policy)
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        super().end_headers()

    def log_message(self, *args):  # quiet: the CLI prints the URL once
        pass


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    request_queue_size = 64

    def handle_error(self, request, client_address):  # a broken or timed-out connection: no traceback
        pass


_Handler.extensions_map = {**SimpleHTTPRequestHandler.extensions_map, ".js": "text/javascript",
                           ".mjs": "text/javascript", ".glb": "model/gltf-binary", ".json": "application/json"}


def serve(folder, port: int = 0) -> tuple[ThreadingHTTPServer, str]:
    """Start serving ``folder`` (a twin: twin.json and tiles/; or a comparison: changes.json and view/) in a
    background thread; returns the server and the viewer's URL. ``port`` 0 takes a free one."""
    folder = Path(folder)
    if (folder / "changes.json").is_file() and (folder / "view" / "epochs.json").is_file():
        page = "epochs.html"
    elif (folder / "twin.json").is_file() and (folder / "tiles" / "tileset.json").is_file():
        page = "index.html"
    else:
        raise ViewerError(f"{folder}: neither a twin folder (twin.json and tiles/tileset.json) nor a comparison "
                          "(changes.json and view/); pass the OUT folder of `twinreg build-twin` or `twinreg compare`")
    roots = {"/twin/": folder, "/vendor/three/": vendor_folder() / "three", "/": STATIC}
    handler = type("Handler", (_Handler,), {"roots": roots, "policy": content_policy(page), "page": page})
    if not 0 <= int(port) <= 65535:
        raise ViewerError(f"--port {port}: a port is 0 (any free one) to 65535")
    try:
        server = _Server(("127.0.0.1", port), functools.partial(handler))
    except OSError as exc:
        raise ViewerError(f"port {port}: cannot listen on 127.0.0.1 ({exc.strerror}); pick another --port") from exc
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}/"

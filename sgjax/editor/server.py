"""The editor's local web server: the page and its JSON API (docs/editor.md).

Standard library only (``http.server``): one process, one opened map, threads so that the page
stays responsive while a batch plays. Every answer is JSON or a shipped static file; an error is
``{"error": message}`` with its status, never a traceback page. Every request passes
:class:`sgjax.editor.guard.RequestGuard` first: only the editor's own page, holding this launch's
token, is answered.
"""

from __future__ import annotations

import json
import mimetypes
import sys
import threading
import traceback
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any

from sgjax.editor.guard import RequestGuard, new_token, url_host
from sgjax.editor.session import EditorError, EditorSession
from sgjax.evaluation.policies import BASELINES

STATIC_PACKAGE = "sgjax.editor"
MAX_BODY = 64 * 1024 * 1024  # bytes: the largest request body accepted (GDC3 is ~2 MB)
# One check, routes or save of a map at a time: a burst of requests for a large map waits in
# line instead of holding several copies of its work in memory at once.
_map_work = threading.Lock()
ROUTES_SHOWN = 400


def static_file(name: str) -> bytes:
    """A shipped file of the page (``sgjax/editor/static/<name>``)."""
    folder = resources.files(STATIC_PACKAGE) / "static"
    if "/" in name or "\\" in name or name.startswith("."):
        raise EditorError(404, f"no such file: {name}")
    resource = folder / name
    if not resource.is_file():
        raise EditorError(404, f"no such file: {name}")
    return resource.read_bytes()


def routes(data: Any) -> dict[str, Any]:
    """The shortest path of every allowed (start, goal) pair, at most :data:`ROUTES_SHOWN`,
    with ``tie`` where another, different path is equally short."""
    from sgjax.maps.check import tied_goals
    from sgjax.maps.routing import NO_PATH, all_pairs_shortest_paths, path_nodes
    from sgjax.maps.schema import MapError, parse_map

    try:
        spec = parse_map(data, source="the edited map")
    except MapError as err:
        raise EditorError(422, f"routes: fix the map's errors first ({err.path}: "
                               f"{err.problem.splitlines()[0]})") from None
    length, next_hop = all_pairs_shortest_paths(spec.node_positions, spec.edges)
    found: list[dict[str, Any]] = []
    pairs = 0
    tied: dict[int, Any] = {}
    items = [("group", i, g[0], g[1]) for i, g in enumerate(spec.groups)]
    items += [("route", i, (r[0],), (r[-1],)) for i, r in enumerate(spec.routes)]
    for kind, index, starts, goals in items:
        for s in starts:
            for g in goals:
                if s == g or next_hop[s, g] == NO_PATH:
                    continue
                pairs += 1
                if len(found) >= ROUTES_SHOWN:
                    continue
                if s not in tied:
                    tied[s] = tied_goals(spec, s, length)
                points = spec.node_positions[path_nodes(next_hop, s, g)]
                found.append({"group": index if kind == "group" else None,
                              "route": index if kind == "route" else None,
                              "start": int(spec.node_ids[s]), "goal": int(spec.node_ids[g]),
                              "points": points.round(4).tolist(), "tie": bool(tied[s][g])})
    return {"routes": found, "pairs": pairs, "truncated": pairs > len(found)}


class EditorHandler(BaseHTTPRequestHandler):
    """One request: ``GET /``, ``GET /static/<file>``, ``GET /api/session`` and the ``POST``
    API of docs/editor.md."""

    session: EditorSession  # set on the subclass made by make_server
    guard: RequestGuard  # set by make_server once the port is known
    quiet = True

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 (the base's name)
        if not self.quiet:
            super().log_message(format, *args)

    # --- answers ---------------------------------------------------------------------------

    def send_error(self, code: int, message: str | None = None,
                   explain: str | None = None) -> None:
        """http.server's own errors (an unsupported method such as PUT, a malformed request
        line) as JSON too."""
        body = json.dumps({"error": message or HTTPStatus(code).phrase}).encode()
        self.send_response(code, message)
        self.send_header("Content-Type", "application/json")
        self._safety_headers()
        self.send_header("Connection", "close")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if self.command != "HEAD" and code >= 200 and code not in (204, 304):
            self.wfile.write(body)

    def _safety_headers(self) -> None:
        """No framing by other pages, no content sniffing, no token in a Referer."""
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("X-Frame-Options", "DENY")
        self.send_header("Content-Security-Policy", "frame-ancestors 'none'")
        self.send_header("Referrer-Policy", "no-referrer")

    def _send(self, status: int, body: bytes, content_type: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self._safety_headers()
        self.end_headers()
        self.wfile.write(body)

    def _trusted(self, path: str) -> bool:
        """Whether the guard lets this request through (else the refusal is sent)."""
        try:
            self.guard.check(self.command, path, self.headers)
        except EditorError as err:
            self._json(err.status, {"error": str(err)})
            return False
        return True

    def _json(self, status: int, payload: dict[str, Any]) -> None:
        self._send(status, json.dumps(payload).encode(), "application/json")

    def _guarded(self, answer: Any) -> None:
        try:
            status, payload = answer()
            self._json(status, payload)
        except EditorError as err:
            self._json(err.status, {"error": str(err), **err.extra})
        except Exception as err:  # a bug: a JSON answer and the traceback on the terminal
            traceback.print_exc(file=sys.stderr)
            self._json(500, {"error": f"internal error: {type(err).__name__}: {err}"})

    # --- GET -------------------------------------------------------------------------------

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        path = self.path.split("?", 1)[0]
        if not self._trusted(path):
            return
        if path in ("/", "/index.html"):
            path = "/static/index.html"
        if path.startswith("/static/"):
            name = path[len("/static/"):]
            try:
                body = static_file(name)
            except EditorError as err:
                self._json(err.status, {"error": str(err)})
                return
            kind = mimetypes.guess_type(name)[0] or "application/octet-stream"
            self._send(200, body, kind + ("; charset=utf-8" if kind.startswith("text") or
                                          kind.endswith("javascript") else ""))
        elif path == "/api/session":
            self._guarded(lambda: (200, self._session()))
        else:
            self._json(404, {"error": f"no such page: {path}"})

    def _session(self) -> dict[str, Any]:
        from sgjax.dynamics.limits import PRESETS

        s = self.session
        from sgjax.editor.generate import families

        return {"map": s.data, "file": s.file, "root": str(s.root), "autosave": s.autosaved(),
                "import_report": s.import_report, "policies": list(BASELINES),
                "robot_presets": sorted(PRESETS), "families": families()}

    # --- POST ------------------------------------------------------------------------------

    def _body(self) -> dict[str, Any]:
        size = int(self.headers.get("Content-Length") or 0)
        if size > MAX_BODY:
            raise EditorError(413, f"request body of {size} bytes; at most {MAX_BODY}")
        try:
            body = json.loads(self.rfile.read(size) or b"{}")
        except (json.JSONDecodeError, UnicodeDecodeError) as err:
            raise EditorError(400, f"the request body is not JSON: {err}") from None
        if not isinstance(body, dict):
            raise EditorError(400, "the request body must be a JSON object")
        return body

    def _map(self, body: dict[str, Any]) -> Any:
        if "map" not in body:
            raise EditorError(400, "the request needs a 'map'")
        return body["map"]

    def do_POST(self) -> None:  # noqa: N802 (http.server's name)
        path = self.path.split("?", 1)[0]
        if not self._trusted(path):
            return
        actions = {"/api/check": self._check, "/api/routes": self._routes,
                   "/api/save": self._save, "/api/autosave": self._autosave,
                   "/api/play": self._play, "/api/play/cancel": self._cancel,
                   "/api/generate": self._generate}
        if path not in actions:
            self._json(404, {"error": f"no such API: {path}"})
            return
        self._guarded(lambda: actions[path](self._body()))

    def _check(self, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
        with _map_work:
            problems = self.session.check(self._map(body))
        return 200, {"problems": [p.as_dict() for p in problems]}

    def _routes(self, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
        with _map_work:
            return 200, routes(self._map(body))

    def _save(self, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
        data = self._map(body)
        if not isinstance(data, dict):
            raise EditorError(400, "save: the map must be a JSON object")
        with _map_work:
            path, size = self.session.save(data, body.get("file", self.session.file),
                                           bool(body.get("overwrite", False)))
        return 200, {"saved": str(path), "bytes": size}

    def _autosave(self, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
        data = self._map(body)
        if not isinstance(data, dict):
            raise EditorError(400, "autosave: the map must be a JSON object")
        return 200, {"autosaved": str(self.session.autosave(data))}

    def _play(self, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
        from sgjax.editor.play import play

        return 200, play(body)

    def _generate(self, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
        from sgjax.editor.generate import generate

        with _map_work:
            return 200, generate(body)

    def _cancel(self, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
        from sgjax.editor.play import cancel

        return 200, {"cancelled": cancel()}


class EditorServer(ThreadingHTTPServer):
    """The editor's HTTP server: ``token`` is this launch's secret, ``url`` the page's address
    with it."""

    token: str
    url: str


def make_server(session: EditorSession, host: str = "127.0.0.1", port: int = 8765,
                tries: int = 20, token: str | None = None) -> EditorServer:
    """A server for ``session`` on ``port`` or, if taken, the next free one of ``tries``;
    ``token``: the secret every API call must carry (default: a new random one)."""
    handler = type("Handler", (EditorHandler,), {"session": session})
    for offset in range(tries):
        try:
            server = EditorServer((host, port + offset), handler)
            break
        except OSError:
            if port == 0 or offset == tries - 1:
                raise
    else:  # tries < 1
        raise OSError(f"no free port in {port}..{port + tries - 1}")
    bound = server.server_address[1]
    server.token = token or new_token()
    handler.guard = RequestGuard(host, bound, server.token)
    server.url = f"http://{url_host(host)}:{bound}/?token={server.token}"
    return server


def serve(session: EditorSession, host: str, port: int, browser: bool) -> None:
    """Serve until interrupted, opening the page in the default browser if ``browser``."""
    server = make_server(session, host, port)
    url = server.url
    print(f"sgjax edit: {session.root / session.file} at {url} (Ctrl+C to stop)", flush=True)
    if browser:
        import webbrowser

        threading.Timer(0.5, webbrowser.open, args=(url,)).start()
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        print("sgjax edit: stopped")
    finally:
        server.server_close()

"""The studio's web server: the page, its data as JSON, surfaces as GLB, and the designer's actions.

A standard-library ``ThreadingHTTPServer``; the page and three.js come from this package (nothing is
fetched from the internet). The security rule (docs/studio.md):

- it binds to 127.0.0.1 unless told otherwise; bound to any other address it requires a token, given
  in the URL it prints (``?token=...``) and then kept in a same-site cookie, as Jupyter does;
- on the loopback address it answers only requests whose ``Host`` is a loopback name (a web page
  elsewhere cannot reach it through DNS rebinding), and actions must be JSON ``POST``s carrying the
  ``X-Genr8-Studio`` header, which a cross-site form cannot send;
- it reads only the run directory (through the run store) and its own package files, and writes only
  through ``genr8 edit``'s code (``apply_edit``, the run's queue); ids and formats are checked against
  fixed patterns, file names never come from a request;
- no stored code runs: surfaces grow from the recorded rewrite system; injecting a rewrite system (which
  needs the universe's inverse mapping) is offered only for the universes shipped with genr8_dist.
"""

from __future__ import annotations

import hmac
import ipaddress
import json
import re
import secrets
import sys
import threading
from http import HTTPStatus
from http.cookies import SimpleCookie
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any, TextIO
from urllib.parse import parse_qs, urlsplit

from genr8_dist.errors import ConfigError, Genr8Error, StoreError
from genr8_dist.studio.data import RunView

__all__ = ["Studio", "is_loopback"]

STATIC = Path(__file__).resolve().parent / "static"
_ID = re.compile(r"^\d{1,6}-\d{1,9}-\d{1,9}$")
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
          ".css": "text/css; charset=utf-8", ".svg": "image/svg+xml", ".png": "image/png"}
MAX_BODY = 1 << 20
COOKIE = "genr8_studio_token"


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a name or an address) is this machine's loopback."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


class Studio:
    """The studio over the run in ``run_dir``, served on ``host:port`` (port 0: any free port)."""

    def __init__(self, run_dir: str, *, host: str = "127.0.0.1", port: int = 0, token: str | None = None,
                 log: TextIO | None = None) -> None:
        self.view = RunView(run_dir)
        self.run_dir = run_dir
        self.host = host
        self.loopback = is_loopback(host)
        self.token = token if token else (None if self.loopback else secrets.token_urlsafe(18))
        self.log = log
        handler = type("Handler", (_Handler,), {"studio": self})
        try:
            self.httpd = ThreadingHTTPServer((host, port), handler)
        except OSError as exc:
            raise ConfigError(f"--host {host} --port {port}: cannot listen there "
                              f"({exc.strerror or exc})") from None
        self.httpd.daemon_threads = True
        self.port = int(self.httpd.server_address[1])
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        name = f"[{self.host}]" if ":" in self.host else self.host
        query = f"?token={self.token}" if self.token else ""
        return f"http://{name}:{self.port}/{query}"

    def start(self) -> Studio:
        """Serve in a background thread (``genr8 run --studio``)."""
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="genr8-studio", daemon=True)
        self._thread.start()
        self._warm()
        return self

    def serve_forever(self) -> None:
        self._warm()
        self.httpd.serve_forever()

    def _warm(self) -> None:
        threading.Thread(target=self.view.warm, name="genr8-studio-warm", daemon=True).start()

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()

    # -- actions ------------------------------------------------------------------------------------
    def act(self, body: dict[str, Any]) -> dict[str, Any]:
        """Carry out one action of the page; each is an intervention recorded as ``genr8 edit`` does."""
        from genr8_dist.distributed.intervene import Edit, apply_edit

        action = body.get("action")
        if action in ("pause", "continue"):
            store = self.view.store()
            holder = store.running()
            if holder is None or holder.get("role") != "run":
                raise ConfigError(f"{action}: the run is not running (resume it with genr8 resume)")
            item = store.enqueue({"kind": action, "source": "studio"})
            return {"queued": item.name,
                    "message": f"{action} queued; the run takes it before its next epoch"}
        if action == "favour":
            edit = Edit(favour=[_check_id(i) for i in _list(body.get("ids"), "ids")])
        elif action == "hand_fitness":
            edit = Edit(hand_fitness=[(_check_id(body.get("id")), _number(body.get("fitness"), "fitness"))])
        elif action == "set":
            assignments = [str(a) for a in _list(body.get("assignments"), "assignments")]
            edit = Edit(assignments=assignments)
        elif action == "generations":
            edit = Edit(generations=int(_number(body.get("generations"), "generations")))
        elif action == "inject":
            config = self.view.config()
            from genr8_dist.studio.data import _builtin_universe

            if not _builtin_universe(str(config.universe)):
                raise ConfigError(f"inject: the run's universe {config.universe!r} is a plugin; the studio "
                                  "runs no plugin code (use genr8 edit --inject-text)")
            text = str(body.get("text") or "")
            if not text.strip():
                raise ConfigError("inject: the rewrite system is empty")
            island = body.get("island")
            edit = Edit(inject_systems=[("rewrite system written in the studio", text)],
                        island=None if island in (None, "") else int(_number(island, "island")))
        else:
            raise ConfigError(f"unknown action {action!r}")
        try:
            result = apply_edit(self.run_dir, edit, source="studio")
        except ConfigError as exc:
            if "use --generations N" not in str(exc):
                raise
            raise ConfigError(f"{action}: the run has no generation left to take it; add generations first "
                              "(Steer → Length of the run → Go on)") from None
        if result.queued:
            message = (f"queued ({result.queued}); the run takes it at its next epoch, generation "
                       f"{result.effective_generation} or later")
        else:
            message = (f"recorded: configuration version {result.version} in force from generation "
                       f"{result.effective_generation}")
        return {"queued": result.queued, "version": result.version,
                "effective_generation": result.effective_generation, "message": message}


def _list(value: object, what: str) -> list[Any]:
    if not isinstance(value, list) or not value:
        raise ConfigError(f"{what}: expected a non-empty list")
    return value


def _number(value: Any, what: str) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{what}: expected a number, got {value!r}") from None


def _check_id(value: object) -> str:
    text = str(value or "")
    if not _ID.match(text):
        raise ConfigError(f"{text!r}: an individual id is ISLAND-GENERATION-INDEX, e.g. 0-12-3")
    return text


class _Handler(BaseHTTPRequestHandler):
    studio: Studio
    server_version = "genr8-studio"
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:
        if self.studio.log is not None:
            print(f"studio: {format % args}", file=self.studio.log)

    # -- checks -------------------------------------------------------------------------------------
    def _allowed(self, query: dict[str, list[str]]) -> bool:
        studio = self.studio
        if studio.loopback:
            host = (self.headers.get("Host") or "").rsplit(":", 1)[0]
            if not is_loopback(host):
                return False
        if studio.token is None:
            return True
        given = (query.get("token") or [""])[0]
        if not given:
            cookie = SimpleCookie(self.headers.get("Cookie") or "")
            given = cookie[COOKIE].value if COOKIE in cookie else ""
        if not given:
            given = self.headers.get("X-Genr8-Token") or ""
        return hmac.compare_digest(given.encode(), studio.token.encode())

    def _send(self, status: int, body: bytes, kind: str, extra: dict[str, str] | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        for k, v in (extra or {}).items():
            self.send_header(k, v)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, data: Any, status: int = 200) -> None:
        self._send(status, json.dumps(data, allow_nan=False).encode(), "application/json")

    def _error(self, status: int, message: str) -> None:
        self._json({"error": message}, status)

    # -- GET ----------------------------------------------------------------------------------------
    def do_GET(self) -> None:
        parts = urlsplit(self.path)
        query = parse_qs(parts.query)
        if not self._allowed(query):
            self._error(HTTPStatus.FORBIDDEN, "forbidden: open the URL genr8 studio printed (with its token)")
            return
        try:
            self._get(parts.path, query)
        except (Genr8Error, OSError) as exc:
            status = HTTPStatus.SERVICE_UNAVAILABLE if isinstance(exc, StoreError) else HTTPStatus.BAD_REQUEST
            self._error(status, str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        except (BrokenPipeError, ConnectionResetError):
            return
        except Exception as exc:   # an answer, never a dead connection; the studio keeps serving
            print(f"studio: {self.path}: {type(exc).__name__}: {exc}", file=sys.stderr)
            self._error(HTTPStatus.INTERNAL_SERVER_ERROR, f"{type(exc).__name__}: {exc}")

    do_HEAD = do_GET

    def _get(self, path: str, query: dict[str, list[str]]) -> None:
        view = self.studio.view

        def arg(name: str, default: str | None = None) -> str | None:
            values = query.get(name)
            return values[0] if values else default

        if path in ("/", "/index.html"):
            body = (STATIC / "index.html").read_bytes()
            extra = {}
            if self.studio.token:
                extra["Set-Cookie"] = f"{COOKIE}={self.studio.token}; HttpOnly; SameSite=Strict; Path=/"
            self._send(200, body, _TYPES[".html"], extra)
        elif path.startswith("/static/"):
            self._static(path[len("/static/"):])
        elif path == "/api/state":
            self._json(view.state())
        elif path == "/api/curves":
            self._json(view.curves())
        elif path == "/api/generation":
            g = arg("g")
            self._json(view.generation(None if g in (None, "") else int(_number(g, "g"))))
        elif path == "/api/clusters":
            g, k, island = arg("g"), arg("k"), arg("island")
            self._json(view.clusters(None if g in (None, "") else int(_number(g, "g")),
                                     12 if k in (None, "") else int(_number(k, "k")),
                                     None if island in (None, "") else int(_number(island, "island"))))
        elif path == "/api/archive":
            g = arg("g")
            self._json(view.archive(None if g in (None, "") else int(_number(g, "g"))))
        elif path == "/api/individual":
            self._json(view.individual(_check_id(arg("id"))))
        elif path == "/api/surface":
            self._send(200, view.surface_glb(_check_id(arg("id"))), "model/gltf-binary")
        elif path == "/api/environment":
            v = arg("version")
            self._json(view.environment(None if v in (None, "") else int(_number(v, "version"))))
        elif path == "/api/download":
            ident, kind = _check_id(arg("id")), str(arg("format", ""))
            data, media = view.download(ident, kind)
            name = f"{view.store().run_id}-{ident}.{kind}"
            self._send(200, data, media, {"Content-Disposition": f'attachment; filename="{name}"'})
        else:
            self._error(HTTPStatus.NOT_FOUND, f"no such page: {path}")

    def _static(self, rel: str) -> None:
        target = (STATIC / rel).resolve()
        if STATIC not in target.parents or not target.is_file() or target.suffix not in _TYPES:
            self._error(HTTPStatus.NOT_FOUND, f"no such file: {rel}")
            return
        self._send(200, target.read_bytes(), _TYPES[target.suffix])

    # -- POST ---------------------------------------------------------------------------------------
    def do_POST(self) -> None:
        parts = urlsplit(self.path)
        if not self._allowed(parse_qs(parts.query)):
            self._error(HTTPStatus.FORBIDDEN, "forbidden: open the URL genr8 studio printed (with its token)")
            return
        if parts.path != "/api/act":
            self._error(HTTPStatus.NOT_FOUND, f"no such action endpoint: {parts.path}")
            return
        if self.headers.get("X-Genr8-Studio") != "1" or \
                not (self.headers.get("Content-Type") or "").startswith("application/json"):
            self._error(HTTPStatus.FORBIDDEN, "actions come from the studio page (JSON with X-Genr8-Studio)")
            return
        length = int(self.headers.get("Content-Length") or 0)
        if not 0 < length <= MAX_BODY:
            self._error(HTTPStatus.BAD_REQUEST, f"an action is 1 byte to {MAX_BODY} bytes of JSON")
            return
        try:
            body = json.loads(self.rfile.read(length).decode())
            if not isinstance(body, dict):
                raise ConfigError("an action is a JSON object")
            self._json(self.studio.act(body))
        except (json.JSONDecodeError, UnicodeDecodeError):
            self._error(HTTPStatus.BAD_REQUEST, "an action is a JSON object")
        except (Genr8Error, OSError, ValueError) as exc:
            self._error(HTTPStatus.BAD_REQUEST, str(exc).splitlines()[0] if str(exc) else type(exc).__name__)

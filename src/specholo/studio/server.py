"""The studio's local web server: one page, its preview and the exact design.

The server listens on 127.0.0.1 only and answers only requests addressed to
it by that name (or ``localhost``): the page is for the maker at this machine.
Requests that change anything carry a header of the page's own, so a page from
elsewhere cannot post to it (a browser asks first, and is not answered).

Endpoints (JSON unless said otherwise):

- ``GET /``, ``/studio.js``, ``/studio.css``: the page, from this package.
- ``GET /api/state``: the model, the default settings, the design's status.
- ``POST /api/preview``: ``{"settings": {...}}`` -> :meth:`Preview.as_json`.
- ``POST /api/model``: a model file's bytes (its name in ``X-Specholo-Name``).
- ``POST /api/design``: start the exact design; ``GET /api/design``: its status.
- ``GET /api/design.zip``: the finished design's folder, zipped.
"""

from __future__ import annotations

import json
import re
import shutil
import tempfile
import threading
import urllib.parse
from dataclasses import asdict
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from specholo.errors import SpecholoError
from specholo.pipeline import DesignConfig
from specholo.scene.loading import FORMATS, Model, load_model
from specholo.studio.preview import fast_preview
from specholo.studio.runner import Runner, one_line

#: The only address the studio listens on.
HOST = "127.0.0.1"
#: The header every changing request carries (a page elsewhere cannot add it unasked).
TOKEN_HEADER = "X-Specholo"
#: Largest model upload, bytes.
MAX_UPLOAD = 256 << 20
#: Largest JSON request, bytes.
MAX_JSON = 1 << 20
#: The page's files, served from the package.
ASSETS = {"/": ("page.html", "text/html; charset=utf-8"),
          "/studio.js": ("studio.js", "text/javascript; charset=utf-8"),
          "/studio.css": ("studio.css", "text/css; charset=utf-8")}
#: The settings the page starts from (the design's defaults, a count the preview
#: redraws at once).
START = {"stipples": 1000}
#: Nothing but this server: no script, style, font or connection from elsewhere.
POLICY = ("default-src 'self'; img-src 'self' data: blob:; connect-src 'self'; "
          "frame-ancestors 'none'; base-uri 'none'; form-action 'none'")


def default_model() -> Path | None:
    """The bundled example (``examples/bunny.obj`` of the source tree), if present."""
    for root in (Path(__file__).resolve().parents[3], Path.cwd()):
        p = root / "examples" / "bunny.obj"
        if p.is_file():
            return p
    return None


def safe_name(name: str) -> str:
    """A folder name from a model's file name: letters, digits, '-', '_'."""
    stem = re.sub(r"[^A-Za-z0-9_-]+", "_", Path(name).stem).strip("_")[:40]
    return stem or "model"


def config_of(settings: Any) -> DesignConfig:
    """The design's settings from the page's (the option names of ``specholo design``)."""
    if not isinstance(settings, dict):
        raise SpecholoError("settings must be a table of options")
    return DesignConfig.from_dict(settings)


class Studio:
    """What the page works on: the model, its file, and the design runner.

    Args:
        out_root: where exact designs are written (one folder a model).
    """

    def __init__(self, out_root: Path) -> None:
        self.model: Model | None = None
        self.path: Path | None = None
        self.name = ""
        self.runner = Runner(out_root)
        self.uploads = Path(tempfile.mkdtemp(prefix="specholo-studio-"))
        self._uploaded = 0
        self._lock = threading.Lock()
        # One preview at a time: the page asks again with its latest state.
        self.preview_lock = threading.Lock()

    def open(self, path: Path, name: str | None = None) -> None:
        """Load a model file; the studio keeps its previous model if this one is bad."""
        model = load_model(path)
        with self._lock:
            self.model, self.path, self.name = model, path, safe_name(name or path.name)

    def upload(self, data: bytes, filename: str) -> None:
        """Write an uploaded file to the studio's temporary folder and open it."""
        ext = Path(filename).suffix.lower()
        if ext not in FORMATS:
            raise SpecholoError(f"{filename or 'the file'}: not a model file (use one of "
                                f"{', '.join(FORMATS)})")
        if not data:
            raise SpecholoError(f"{filename}: the file is empty")
        with self._lock:
            self._uploaded += 1
            folder = self.uploads / str(self._uploaded)
        folder.mkdir()
        path = folder / (safe_name(filename) + ext)
        path.write_bytes(data)
        try:
            self.open(path, filename)
        except SpecholoError as exc:
            # The maker knows the file by its own name, not the studio's copy.
            raise SpecholoError(str(exc).replace(str(path), filename)) from exc

    def current(self) -> tuple[Model, Path, str]:
        """The model, its file and its name; refused before any model is open."""
        with self._lock:
            if self.model is None or self.path is None:
                raise SpecholoError("no model open: open a model file first")
            return self.model, self.path, self.name

    def state(self) -> dict[str, Any]:
        """The page's starting point."""
        with self._lock:
            model = self.name if self.model is not None else None
        return {"model": model, "settings": {**asdict(DesignConfig()), **START},
                "formats": list(FORMATS), "design": self.runner.status()}

    def close(self) -> None:
        """Remove the uploaded files."""
        shutil.rmtree(self.uploads, ignore_errors=True)


class StudioServer(ThreadingHTTPServer):
    """The studio's HTTP server (127.0.0.1 only)."""

    daemon_threads = True

    def __init__(self, studio: Studio, port: int) -> None:
        self.studio = studio
        super().__init__((HOST, port), _Handler)

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://{HOST}:{self.server_address[1]}/"

    def server_close(self) -> None:
        super().server_close()
        self.studio.close()


def make_server(model: Path | None, out_root: Path, port: int = 0,
                host: str = HOST) -> StudioServer:
    """A studio server, listening on 127.0.0.1 (port 0: any free port).

    Args:
        model: the model to open, or None to start with the page's prompt.
        out_root: where exact designs are written.
        port: the port.
        host: must be 127.0.0.1: the studio serves this machine only.

    Raises:
        SpecholoError: another host, a bad port, a port in use, or a bad model.
    """
    if host != HOST:
        raise SpecholoError(f"the studio listens on {HOST} only (this machine), not {host}")
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise SpecholoError(f"port must be in 0-65535, got {port!r}")
    studio = Studio(out_root)
    try:
        if model is not None:
            studio.open(Path(model))
        return StudioServer(studio, port)
    except OSError as exc:
        studio.close()
        raise SpecholoError(f"cannot listen on {HOST}:{port}: {exc.strerror or exc}") from exc
    except BaseException:
        studio.close()
        raise


class _Handler(BaseHTTPRequestHandler):
    server: StudioServer
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
        """Quiet: the terminal shows the address and Ctrl-C, not every request."""

    # ------------------------------------------------------------------ replies
    def _send(self, code: int, body: bytes, kind: str, extra: dict[str, str] | None = None
              ) -> None:
        self.send_response(code)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("Content-Security-Policy", POLICY)
        self.send_header("X-Content-Type-Options", "nosniff")
        for k, v in (extra or {}).items():
            self.send_header(k, v)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, code: int, obj: Any) -> None:
        self._send(code, json.dumps(obj, allow_nan=False).encode("utf-8"),
                   "application/json")

    def _error(self, code: int, message: str) -> None:
        self._json(code, {"error": message})

    def _allowed(self) -> bool:
        """Only this machine's names for this server (no other site by DNS rebinding)."""
        port = self.server.server_address[1]
        if self.headers.get("Host", "") not in (f"{HOST}:{port}", f"localhost:{port}"):
            self._error(403, "the studio answers only http://127.0.0.1 requests")
            return False
        return True

    def _body(self, limit: int) -> bytes | None:
        try:
            n = int(self.headers.get("Content-Length", ""))
        except ValueError:
            self._error(411, "the request needs a Content-Length")
            return None
        if n < 0 or n > limit:
            self._error(413, f"the request is too large (at most {limit >> 20} MB)")
            self.close_connection = True
            return None
        return self.rfile.read(n)

    # ------------------------------------------------------------------ routes
    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        if not self._allowed():
            return
        path = urllib.parse.urlsplit(self.path).path
        try:
            if path in ASSETS:
                name, kind = ASSETS[path]
                self._send(200, (Path(__file__).parent / name).read_bytes(), kind)
            elif path == "/api/state":
                self._json(200, self.server.studio.state())
            elif path == "/api/design":
                self._json(200, self.server.studio.runner.status())
            elif path == "/api/design.zip":
                name, data = self.server.studio.runner.zip_bytes()
                self._send(200, data, "application/zip",
                           {"Content-Disposition": f'attachment; filename="{name}"'})
            else:
                self._error(404, f"no such page: {path}")
        except Exception as exc:  # noqa: BLE001 - one line to the page, the server goes on
            self._error(400, one_line(exc))

    do_HEAD = do_GET  # noqa: N815

    def do_POST(self) -> None:  # noqa: N802
        if not self._allowed():
            return
        if self.headers.get(TOKEN_HEADER) != "1":
            self._error(403, f"requests that change the studio carry {TOKEN_HEADER}: 1")
            return
        path = urllib.parse.urlsplit(self.path).path
        studio = self.server.studio
        try:
            if path == "/api/model":
                data = self._body(MAX_UPLOAD)
                if data is None:
                    return
                name = urllib.parse.unquote(self.headers.get("X-Specholo-Name", ""))
                studio.upload(data, Path(name).name)
                self._json(200, studio.state())
                return
            if path not in ("/api/preview", "/api/design"):
                self._error(404, f"no such action: {path}")
                return
            raw = self._body(MAX_JSON)
            if raw is None:
                return
            try:
                request = json.loads(raw.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
                raise SpecholoError(f"the request is not JSON: {exc}") from exc
            if not isinstance(request, dict):
                raise SpecholoError("the request must be a JSON object")
            config = config_of(request.get("settings", {}))
            model, file, name = studio.current()
            if path == "/api/preview":
                with studio.preview_lock:
                    preview = fast_preview(model, config)
                self._json(200, preview.as_json())
            elif studio.runner.start(file, name, config):
                self._json(202, studio.runner.status())
            else:
                self._error(409, "a design is already running; wait for it to finish")
        except Exception as exc:  # noqa: BLE001 - one line to the page, the server goes on
            self._error(400, one_line(exc))

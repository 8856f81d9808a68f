"""The studio's local web server: one page, its preview and the exact design.

The server listens on 127.0.0.1 only and answers only requests addressed to
it by that name (or ``localhost``): the page is for the maker at this machine.
Every run makes a secret of its own, carried by the address it prints
(``?token=...``, as notebook servers do); the page sends it with every API
request in :data:`TOKEN_HEADER`, and an API request without it is refused. A
page from another site cannot read the secret, so it can neither post to the
studio nor read what it answers, even under a name rebound to 127.0.0.1.

Every refusal closes its connection: a body left unread on a kept-alive
connection would otherwise be read as the next request (a request smuggled
inside a refused one). At most :data:`MAX_CONNECTIONS` connections are served
at once, each silent for at most :data:`CLIENT_TIMEOUT` seconds, and a client
that hangs up is no traceback on the terminal.

Endpoints (JSON unless said otherwise):

- ``GET /``, ``/studio.js``, ``/plate_view.js``, ``/studio.css``: the page, from this
  package (no secret in them).
- ``GET /api/state``: the model, the default settings, the command's defaults,
  bounds and choices (:func:`settings_schema`), the design's status.
- ``POST /api/preview``: ``{"settings": {...}}`` -> :meth:`Preview.as_json`.
- ``POST /api/estimate``: ``{"settings": {...}}`` -> the design's figures from a
  sample of it (:func:`specholo.studio.estimate.estimate`), one at a time (a
  second request waits its turn).
- ``POST /api/model``: a model file's bytes (its name in ``X-Specholo-Name``),
  streamed to disk, at most :data:`MAX_UPLOAD` bytes (:data:`MAX_TEXT_UPLOAD` for text).
- ``POST /api/design``: start the exact design; ``GET /api/design``: its status.
- ``GET /api/design.zip``: the finished design's folder, zipped.
- ``GET /api/design/file?name=hologram.gcode``: one of its files (:data:`EXPORTS`:
  the G-code, SVG, DXF, and the PDF pattern, made when first asked for).
- ``GET /api/design/grooves``: what the finished design will cut, for the page's
  plate and 3D views (:func:`specholo.studio.cut.design_grooves`): each path's
  stipple id and its polyline, flat arrays in mm rounded to 0.001 mm (every
  vertex of ``grooves.npz``, arcs cut into chords within
  :data:`~specholo.studio.cut.TOLERANCE` of them); the plate's corners, size
  and registration marks as ``hologram.json`` and the drawings have them; the
  design's settings; ``decimated`` when over :data:`~specholo.studio.cut.MAX_POINTS`
  points only every k-th stipple's grooves are sent. Gzipped when the client
  accepts it (a 2,000-stipple bunny: 8.6 MB of JSON, 3.3 MB sent).
"""

from __future__ import annotations

import contextlib
import gzip
import hmac
import json
import re
import secrets
import shlex
import shutil
import socket
import sys
import tempfile
import threading
import urllib.parse
from collections.abc import Iterable, Iterator
from dataclasses import asdict
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from specholo.errors import SpecholoError
from specholo.fabrication.programs.machines import MACHINES
from specholo.jobs.flat.folder import DesignConfig
from specholo.optics.cutters import KINDS as CUTTER_KINDS
from specholo.scene.loading import FORMATS, Model, load_model
from specholo.scene.pose import UP_AXES
from specholo.setup import HOLDERS, PRELOAD_RANGE, SETTING_BOUNDS
from specholo.studio import cut
from specholo.studio.estimate import estimate
from specholo.studio.preview import NO_RIDGED, fast_preview
from specholo.studio.runner import EXPORTS, STUDIO_FORMATS, Runner, one_line

#: The only address the studio listens on.
HOST = "127.0.0.1"
#: How long an estimate waits for another to finish, s (each takes a second or two).
ESTIMATE_WAIT = 30.0
#: The header every API request carries: the run's secret (:attr:`StudioServer.token`).
TOKEN_HEADER = "X-Specholo-Token"
#: The header an upload names its file in (URL-encoded).
NAME_HEADER = "X-Specholo-Name"
#: Largest model upload, bytes: a binary STL of about 1.3 million faces, or a
#: binary PLY of 5 million points (which loads in about 0.5 GB).
MAX_UPLOAD = 64 << 20
#: Largest upload of a text format (OBJ, OFF, glTF, XYZ, CSV, ASCII STL or PLY),
#: bytes. Loading splits text into Python strings, about 24 bytes of memory a
#: byte of file: a 62 MB XYZ cloud took 1.5 GB and 20 s to load, 16 MB takes
#: about 0.4 GB (an OBJ of some 300,000 faces, a cloud of 600,000 points).
MAX_TEXT_UPLOAD = 16 << 20
#: The formats that are always text; STL and PLY are text when they start so.
TEXT_FORMATS = (".obj", ".off", ".gltf", ".xyz", ".csv")
#: The first bytes of an upload, which tell a text STL or PLY from a binary one.
HEAD_BYTES = 512
#: Bytes read from an upload at a time: the body goes to disk, never whole into memory.
CHUNK = 1 << 20
#: Largest JSON request, bytes.
MAX_JSON = 1 << 20
#: Connections served at once; more are answered 503 and closed at once. A
#: browser opens at most six to one server.
MAX_CONNECTIONS = 16
#: Seconds a connection may stay silent (mid-request, or idle between
#: requests) before it is closed: a half-sent request cannot hold a thread.
CLIENT_TIMEOUT = 30.0
#: The page's files, served from the package.
ASSETS = {"/": ("page.html", "text/html; charset=utf-8"),
          "/studio.js": ("studio.js", "text/javascript; charset=utf-8"),
          "/plate_view.js": ("plate_view.js", "text/javascript; charset=utf-8"),
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
    """The design's settings from the page's (the option names of ``specholo design``;
    a setting the page leaves blank, null, takes the command's default)."""
    if not isinstance(settings, dict):
        raise SpecholoError("settings must be a table of options")
    if settings.get("method") == "ridged":
        # refused as such, before the page's grooved settings would be refused one by one
        raise SpecholoError(NO_RIDGED)
    return DesignConfig.from_dict({k: v for k, v in settings.items() if v is not None})


#: The settings the page offers a choice of, beyond its sliders: each a
#: ``specholo design`` option (a ridged plate is the command's, not the page's).
CHOICES: dict[str, tuple[str, ...]] = {
    "up": tuple(UP_AXES), "method": ("striped", "hyperbola", "arc"), "tool": CUTTER_KINDS,
    "holder": HOLDERS, "machine": tuple(MACHINES)}
#: Flags of ``specholo design`` whose setting is their opposite.
NEGATED = {"order": "--no-order"}


def settings_schema() -> dict[str, Any]:
    """What the page needs to offer every setting as the command does: the
    command's defaults, each number's bounds and unit (:data:`SETTING_BOUNDS`),
    the spring preload's range and each choice's values."""
    lo, hi = PRELOAD_RANGE
    return {"defaults": asdict(DesignConfig()),
            "bounds": {**{k: list(v) for k, v in SETTING_BOUNDS.items()},
                       "preload": [lo, hi, "mm"], "visibility": [0.0, 1.0, "share"]},
            "choices": {k: list(v) for k, v in CHOICES.items()}}


def command_for(model: str, out: Path, settings: dict[str, Any]) -> str:
    """The ``specholo design`` command that designs what the page designs with
    ``settings`` (the page's; a blank, null, is the command's default): each
    setting the page gives away from the command's default, by its option name.

    Raises:
        SpecholoError: settings the design refuses (the same line).
    """
    config_of(settings)  # refused as the design would refuse them
    defaults = asdict(DesignConfig())
    words = ["specholo", "design", model, "--out", str(out), "--formats", ",".join(STUDIO_FORMATS)]
    for key, value in settings.items():
        if value is None or key not in defaults or value == defaults[key]:
            continue
        flag = "--" + key.replace("_", "-")
        if isinstance(value, bool):
            words.append(flag if value else NEGATED.get(key, f"--no-{key}"))
        else:
            words += [flag, str(value)]
    return shlex.join(words)


def looks_like_text(head: bytes) -> bool:
    """Whether an STL or PLY file is text, judged by its first bytes as the loader does."""
    return head.lstrip()[:5].lower() == b"solid" or b"format ascii" in head[:512]


def accepts_gzip(header: str) -> bool:
    """Whether an Accept-Encoding header takes gzip (not refused with q=0)."""
    for part in header.split(","):
        name, _, params = part.strip().partition(";")
        if name.strip().lower() in ("gzip", "*"):
            q = params.strip().lower().removeprefix("q=")
            try:
                return not params.strip() or float(q) > 0
            except ValueError:
                return False
    return False


def upload_limit(filename: str) -> int:
    """The largest upload of this file's format, bytes (text formats load bigger)."""
    return MAX_TEXT_UPLOAD if Path(filename).suffix.lower() in TEXT_FORMATS else MAX_UPLOAD


class TooLarge(SpecholoError):
    """An upload over its format's limit (answered 413)."""


def _mb(n: int) -> str:
    return f"{n >> 20} MB"


class Studio:
    """What the page works on: the model, its file, and the design runner.

    Args:
        out_root: where exact designs are written (one folder a model).
    """

    def __init__(self, out_root: Path) -> None:
        self.model: Model | None = None
        self.path: Path | None = None
        self.name = ""
        # Which model is open: each model opened gets the next number, and a
        # design (its status, its zip) belongs to the model it was made of.
        self.model_id = 0
        self.runner = Runner(out_root)
        self.uploads = Path(tempfile.mkdtemp(prefix="specholo-studio-"))
        self._uploaded = 0
        self._lock = threading.Lock()
        # One preview at a time: the page asks again with its latest state.
        self.preview_lock = threading.Lock()
        # One estimate at a time (each designs a sample: a second or two)
        self.estimate_lock = threading.Lock()
        # The last design's grooves as sent (JSON, gzipped), by folder and
        # grooves.npz's stamp: a reload or a second tab is not another second
        # of encoding.
        self._grooves_lock = threading.Lock()
        self._grooves: tuple[Any, bytes, bytes] | None = None

    def open(self, path: Path, name: str | None = None) -> None:
        """Load a model file; the studio keeps its previous model if this one is bad."""
        model = load_model(path)
        with self._lock:
            self.model, self.path, self.name = model, path, safe_name(name or path.name)
            self.model_id += 1

    @staticmethod
    def check_upload(filename: str, size: int) -> None:
        """Refuse an upload by its name and declared size, before any of it is read.

        Raises:
            TooLarge: over its format's limit.
            SpecholoError: not a model file, or empty.
        """
        ext = Path(filename).suffix.lower()
        if ext not in FORMATS:
            raise SpecholoError(f"{filename or 'the file'}: not a model file (use one of "
                                f"{', '.join(FORMATS)})")
        if size == 0:
            raise SpecholoError(f"{filename}: the file is empty")
        limit = upload_limit(filename)
        if size > limit:
            kind = "a text model file" if limit == MAX_TEXT_UPLOAD else "a model file"
            raise TooLarge(f"{filename}: {size / (1 << 20):.0f} MB is too large for the studio "
                           f"({kind} may be at most {_mb(limit)}; `specholo design` reads "
                           "larger ones)")

    def upload(self, chunks: Iterable[bytes], filename: str, size: int) -> None:
        """Write an uploaded file, chunk by chunk, to the studio's temporary folder and open it.

        Args:
            chunks: the file's bytes, in pieces (never held whole).
            filename: the maker's name for the file (its extension picks the format).
            size: its length, bytes (checked by :meth:`check_upload`).
        """
        self.check_upload(filename, size)
        ext = Path(filename).suffix.lower()
        with self._lock:
            self._uploaded += 1
            folder = self.uploads / str(self._uploaded)
        folder.mkdir()
        path = folder / (safe_name(filename) + ext)
        try:
            with path.open("wb") as fh:
                first = True
                for chunk in chunks:
                    if first and size > MAX_TEXT_UPLOAD and looks_like_text(chunk[:HEAD_BYTES]):
                        # An ASCII STL or PLY loads as text does: judged by its
                        # first bytes, before the rest is read.
                        raise TooLarge(f"{filename}: {size / (1 << 20):.0f} MB is too large "
                                       f"for the studio (a text model file may be at most "
                                       f"{_mb(MAX_TEXT_UPLOAD)}; `specholo design` reads "
                                       "larger ones)")
                    first = False
                    fh.write(chunk)
            self.open(path, filename)
        except SpecholoError as exc:
            shutil.rmtree(folder, ignore_errors=True)
            # The maker knows the file by its own name, not the studio's copy.
            kind = TooLarge if isinstance(exc, TooLarge) else SpecholoError
            raise kind(str(exc).replace(str(path), filename)) from exc
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise

    def current(self) -> tuple[Model, Path, str, int]:
        """The model, its file, its name and its number; refused before any model is open."""
        with self._lock:
            if self.model is None or self.path is None:
                raise SpecholoError("no model open: open a model file first")
            return self.model, self.path, self.name, self.model_id

    def design(self, config: DesignConfig) -> bool:
        """Start the exact design of the open model; False if one is running."""
        _, path, name, model_id = self.current()
        return self.runner.start(path, name, config, model_id=model_id)

    def design_status(self) -> dict[str, Any]:
        """The design's status, for the open model (another model's result is not its)."""
        with self._lock:
            model_id = self.model_id
        return self.runner.status(model_id)

    def command(self, settings: dict[str, Any]) -> str:
        """The command line that designs the open model as the page would
        (:func:`command_for`): the model as it was given (an upload by its
        name), into the folder the studio writes it to."""
        _, path, name, _ = self.current()
        given = path.name if self.uploads in path.parents else str(path)
        return command_for(given, self.runner.out_root / name, settings)

    def export(self, name: str) -> Path:
        """One file of the open model's finished design (see :meth:`Runner.export`)."""
        with self._lock:
            model_id = self.model_id
        return self.runner.export(name, model_id)

    def zip_bytes(self) -> tuple[str, bytes]:
        """The open model's finished design, zipped (see :meth:`Runner.zip_bytes`)."""
        with self._lock:
            model_id = self.model_id
        return self.runner.zip_bytes(model_id)

    def grooves_bytes(self, folder_asked: str | None = None) -> tuple[bytes, bytes]:
        """A finished design's grooves and plate, as JSON and gzipped (see
        :func:`specholo.studio.cut.design_grooves`): of the folder a status named
        (``folder_asked``; still served once the next design has started or
        another model is open, so a page that saw "done" always gets what it
        asked for), else of the open model's finished design.

        Raises:
            SpecholoError: no finished design of this model, or none of this
                studio's in ``folder_asked``, or its folder is gone.
        """
        if folder_asked:
            model_id = self.runner.finished_into(folder_asked)
            folder = Path(folder_asked)
        else:
            with self._lock:
                model_id = self.model_id
            state = self.runner.status(model_id)
            if state["state"] != "done":
                raise SpecholoError("no finished design of this model to draw yet")
            folder = Path(state["folder"])
        npz = folder / "grooves.npz"
        try:
            st = npz.stat()
        except OSError as exc:
            raise SpecholoError(f"the design folder {folder} holds no grooves.npz") from exc
        stamp = (str(folder), model_id, st.st_mtime_ns, st.st_size, cut.MAX_POINTS)
        # one encoding at a time: two tabs asking at once wait for one result
        with self._grooves_lock:
            if self._grooves is None or self._grooves[0] != stamp:
                data = cut.design_grooves(folder)
                data["model_id"] = model_id
                data["folder"] = str(folder)
                raw = json.dumps(data, allow_nan=False, separators=(",", ":")).encode("utf-8")
                self._grooves = (stamp, raw, gzip.compress(raw, compresslevel=1))
            return self._grooves[1], self._grooves[2]

    def state(self) -> dict[str, Any]:
        """The page's starting point."""
        with self._lock:
            model = self.name if self.model is not None else None
            model_id = self.model_id
        return {"model": model, "model_id": model_id,
                "settings": {**asdict(DesignConfig()), **START}, **settings_schema(),
                "formats": list(FORMATS), "design": self.design_status()}

    def close(self) -> None:
        """Remove the uploaded files."""
        shutil.rmtree(self.uploads, ignore_errors=True)


def _client_gone(exc: BaseException | None) -> bool:
    """Whether an error is the client's doing: it hung up, or went silent too long."""
    return isinstance(exc, (ConnectionError, TimeoutError, _ClientGone))


class _ClientGone(Exception):
    """The client hung up, or stopped sending, in the middle of its request."""


class StudioServer(ThreadingHTTPServer):
    """The studio's HTTP server (127.0.0.1 only).

    Attributes:
        token: this run's secret; every API request carries it.
        max_connections: connections served at once (more get 503 and are closed).
        client_timeout: seconds a connection may stay silent.
    """

    daemon_threads = True
    # Connections waiting to be accepted: beyond these the system drops a new
    # one's first packet, and its client waits a second to try again (5, the
    # default, is less than a page's burst of requests).
    request_queue_size = 64
    # server_close() ends the open connections itself rather than waiting for
    # them: a browser keeps its connections open, and Ctrl-C should not wait.
    block_on_close = False

    def __init__(self, studio: Studio, port: int, max_connections: int = MAX_CONNECTIONS,
                 client_timeout: float = CLIENT_TIMEOUT) -> None:
        self.studio = studio
        self.token = secrets.token_urlsafe(32)
        self.max_connections = max_connections
        self.client_timeout = client_timeout
        self._slots = threading.BoundedSemaphore(max_connections)
        self._open: set[socket.socket] = set()
        self._open_lock = threading.Lock()
        super().__init__((HOST, port), _Handler)

    @property
    def origin(self) -> str:
        """The server's address, without the secret: ``http://127.0.0.1:PORT``."""
        return f"http://{HOST}:{self.server_address[1]}"

    @property
    def url(self) -> str:
        """The page's address, with this run's secret."""
        return f"{self.origin}/?token={self.token}"

    def token_ok(self, given: str | None) -> bool:
        """Whether a request's secret is this run's (compared in constant time)."""
        if not given:
            return False
        return hmac.compare_digest(given.encode("utf-8", "surrogateescape"),
                                   self.token.encode("ascii"))

    def process_request(self, request: Any, client_address: Any) -> None:
        """Serve a connection in a thread of its own, if one of the slots is free."""
        if not self._slots.acquire(blocking=False):
            self._busy(request)
            super().shutdown_request(request)
            return
        with self._open_lock:
            self._open.add(request)
        super().process_request(request, client_address)

    def shutdown_request(self, request: Any) -> None:
        """Close a connection, and free its slot."""
        with self._open_lock:
            held = request in self._open
            self._open.discard(request)
        try:
            super().shutdown_request(request)
        finally:
            if held:
                self._slots.release()

    @staticmethod
    def _busy(request: socket.socket) -> None:
        """Answer 503 without a thread: never waiting on the client, which may be gone."""
        body = json.dumps({"error": "the studio is busy (too many connections); "
                                    "try again in a moment"}).encode("utf-8")
        head = ("HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\n"
                f"Content-Length: {len(body)}\r\nRetry-After: 1\r\nCache-Control: no-store\r\n"
                "Connection: close\r\n\r\n").encode("ascii")
        with contextlib.suppress(OSError):
            request.setblocking(False)
            request.send(head + body)  # a few hundred bytes: a new socket's buffer holds them
            # What the client has sent so far is read and dropped: closing a
            # socket with unread bytes resets it, and the client could lose the 503.
            request.recv(1 << 16)

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A client that hung up or went silent: nothing to say. Anything else: one line."""
        exc = sys.exc_info()[1]
        if _client_gone(exc):
            return
        with contextlib.suppress(OSError, ValueError):
            sys.stderr.write(f"specholo studio: a request failed: "
                             f"{one_line(exc) if exc is not None else 'unknown error'}\n")

    def server_close(self) -> None:
        """Stop listening, end the open connections and remove the uploaded files."""
        super().server_close()
        with self._open_lock:
            still = list(self._open)
        for conn in still:
            # Their threads then read the end of the stream and finish.
            with contextlib.suppress(OSError):
                conn.shutdown(socket.SHUT_RDWR)
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
    _unread = False
    # StreamRequestHandler gives the socket this timeout: a client silent for
    # longer (half a request sent, or idle) loses its connection.
    timeout = CLIENT_TIMEOUT

    def setup(self) -> None:
        super().setup()
        self.connection.settimeout(self.server.client_timeout)  # the server's own, if set

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
        """Quiet: the terminal shows the address and Ctrl-C, not every request."""

    def parse_request(self) -> bool:
        ok = super().parse_request()
        # Whether the request has a body this server has not read: if so its
        # connection is closed after the answer, or the body would be read as
        # the next request.
        self._unread = ok and (self.headers.get("Content-Length", "0").strip() not in ("0", "")
                               or "Transfer-Encoding" in self.headers)
        return ok

    def handle_expect_100(self) -> bool:
        # "100 Continue" only once the request is allowed (see _length): a
        # refused upload is answered before its body is sent.
        return True

    # ------------------------------------------------------------------ replies
    def _send(self, code: int, body: bytes, kind: str, extra: dict[str, str] | None = None
              ) -> None:
        try:
            self.send_response(code)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.send_header("Content-Security-Policy", POLICY)
            self.send_header("X-Content-Type-Options", "nosniff")
            # The page's address holds the secret: it is never sent elsewhere.
            self.send_header("Referrer-Policy", "no-referrer")
            for k, v in (extra or {}).items():
                self.send_header(k, v)
            if self._unread or self.close_connection:
                self.send_header("Connection", "close")  # also sets close_connection
            self.end_headers()
            if self.command != "HEAD":
                self.wfile.write(body)
        except OSError:
            # The client hung up (or stopped reading) before the answer was sent.
            self.close_connection = True

    def _json(self, code: int, obj: Any) -> None:
        self._send(code, json.dumps(obj, allow_nan=False).encode("utf-8"),
                   "application/json")

    def _error(self, code: int, message: str) -> None:
        self._json(code, {"error": message})

    def _refuse(self, code: int, message: str) -> None:
        """Refuse the request and close its connection, whatever it carried."""
        self.close_connection = True
        self._error(code, message)

    def _allowed(self, path: str) -> bool:
        """This machine's names for this server only (no other site by DNS
        rebinding); an API request, or any POST, must carry the run's secret."""
        port = self.server.server_address[1]
        if self.headers.get("Host", "") not in (f"{HOST}:{port}", f"localhost:{port}"):
            self._refuse(403, "the studio answers only http://127.0.0.1 requests")
            return False
        if ((path.startswith("/api/") or self.command == "POST")
                and not self.server.token_ok(self.headers.get(TOKEN_HEADER))):
            self._refuse(403, "this request lacks the studio's secret: open the address "
                              "`specholo studio` printed (with its ?token=...)")
            return False
        return True

    def _length(self, limit: int) -> int | None:
        """The body's declared length; None once refused (411, 413)."""
        try:
            n = int(self.headers.get("Content-Length", ""))
        except ValueError:
            self._refuse(411, "the request needs a Content-Length")
            return None
        if n < 0 or n > limit:
            self._refuse(413, f"the request is too large (at most {_mb(limit)})")
            return None
        return n

    def _continue(self) -> None:
        """Ask a client that waits for it ("Expect: 100-continue") to send the body."""
        if self.headers.get("Expect", "").lower() == "100-continue":
            try:
                self.send_response_only(100)
                self.end_headers()
            except OSError as exc:
                raise _ClientGone from exc

    def _chunks(self, n: int, first: int = CHUNK) -> Iterator[bytes]:
        """The body's ``n`` bytes, a chunk at a time (the first ``first`` bytes long)."""
        self._continue()
        left, size = n, first
        while left:
            try:
                chunk = self.rfile.read(min(size, left))
            except OSError as exc:
                raise _ClientGone from exc
            if not chunk:
                raise _ClientGone
            left, size = left - len(chunk), CHUNK
            yield chunk
        self._unread = False

    def _body(self, limit: int) -> bytes | None:
        """The whole (small) body; None once refused."""
        n = self._length(limit)
        if n is None:
            return None
        return b"".join(self._chunks(n))

    # ------------------------------------------------------------------ routes
    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        path = urllib.parse.urlsplit(self.path).path
        if not self._allowed(path):
            return
        studio = self.server.studio
        try:
            if path in ASSETS:
                name, kind = ASSETS[path]
                self._send(200, (Path(__file__).parent / name).read_bytes(), kind)
            elif path == "/api/state":
                self._json(200, studio.state())
            elif path == "/api/design":
                self._json(200, studio.design_status())
            elif path == "/api/design/grooves":
                query = urllib.parse.parse_qs(urllib.parse.urlsplit(self.path).query)
                raw, packed = studio.grooves_bytes((query.get("folder") or [""])[0])
                if accepts_gzip(self.headers.get("Accept-Encoding", "")):
                    self._send(200, packed, "application/json",
                               {"Content-Encoding": "gzip", "Vary": "Accept-Encoding"})
                else:
                    self._send(200, raw, "application/json")
            elif path == "/api/design.zip":
                name, data = studio.zip_bytes()
                self._send(200, data, "application/zip",
                           {"Content-Disposition": f'attachment; filename="{name}"'})
            elif path == "/api/design/file":
                query = urllib.parse.parse_qs(urllib.parse.urlsplit(self.path).query)
                name = (query.get("name") or [""])[0]
                found = studio.export(name)
                self._send(200, found.read_bytes(), EXPORTS[name][1],
                           {"Content-Disposition":
                            f'attachment; filename="{found.parent.name}-{name}"'})
            else:
                self._error(404, f"no such page: {path}")
        except Exception as exc:  # noqa: BLE001 - one line to the page, the server goes on
            self._error(400, one_line(exc))

    do_HEAD = do_GET  # noqa: N815

    def do_POST(self) -> None:  # noqa: N802
        path = urllib.parse.urlsplit(self.path).path
        if not self._allowed(path):
            return
        studio = self.server.studio
        try:
            if path == "/api/model":
                self._upload()
                return
            if path not in ("/api/preview", "/api/design", "/api/estimate"):
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
            if path == "/api/preview":
                model = studio.current()[0]
                with studio.preview_lock:
                    preview = fast_preview(model, config)
                self._json(200, {**preview.as_json(),
                                 "command": studio.command(request["settings"])})
            elif path == "/api/estimate":
                model, model_path = studio.current()[:2]
                # one at a time: another tab's (or a reloaded page's) waits its turn
                if not studio.estimate_lock.acquire(timeout=ESTIMATE_WAIT):
                    self._error(409, "another estimate is still running; ask again after it")
                    return
                try:
                    self._json(200, estimate(model_path, config, model))
                finally:
                    studio.estimate_lock.release()
            elif studio.design(config):
                self._json(202, studio.design_status())
            else:
                self._error(409, "a design is already running; wait for it to finish")
        except _ClientGone:
            self.close_connection = True
        except TooLarge as exc:
            self._refuse(413, one_line(exc))
        except Exception as exc:  # noqa: BLE001 - one line to the page, the server goes on
            self._error(400, one_line(exc))

    def _upload(self) -> None:
        """Stream a model file to disk, then open it (refused before reading, if it must be)."""
        n = self._length(MAX_UPLOAD)
        if n is None:
            return
        name = Path(urllib.parse.unquote(self.headers.get(NAME_HEADER, ""))).name
        # Refused by name and size before a byte of the body is read.
        self.server.studio.check_upload(name, n)
        # The first chunk is what tells an ASCII STL or PLY (see Studio.upload).
        self.server.studio.upload(self._chunks(n, first=HEAD_BYTES), name, n)
        self._json(200, self.server.studio.state())

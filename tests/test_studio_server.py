"""The studio's server under hostile or careless clients, on the socket: a
request hidden in a refused one is never answered, connections are capped and
time out, a client that hangs up is no traceback, uploads stream to disk
within their limits, a design belongs to its model, and the page's settings
pass the same bounds as ``specholo design``."""

from __future__ import annotations

import io
import json
import socket
import struct
import threading
import time
import tracemalloc
import urllib.error
import urllib.request
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from specholo.errors import SpecholoError
from specholo.jobs.flat.settings import SETTING_BOUNDS
from specholo.studio import server as studio_server
from specholo.studio.server import (
    MAX_CONNECTIONS,
    MAX_JSON,
    MAX_TEXT_UPLOAD,
    MAX_UPLOAD,
    StudioServer,
    make_server,
)
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
KNOT = ROOT / "examples" / "knot.obj"


def _serve(s: StudioServer) -> StudioServer:
    threading.Thread(target=s.serve_forever, daemon=True).start()
    return s


@pytest.fixture
def fresh(tmp_path: Path) -> Iterator[StudioServer]:
    """A studio of its own (the bunny open), designs under ``tmp_path/out``."""
    s = _serve(make_server(BUNNY, tmp_path / "out", 0))
    yield s
    s.shutdown()
    s.server_close()
    s.studio.runner.wait(60)


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory) -> Iterator[StudioServer]:
    """One studio for the tests that change nothing."""
    s = _serve(make_server(BUNNY, tmp_path_factory.mktemp("studio-out"), 0))
    yield s
    s.shutdown()
    s.server_close()


def call(server: StudioServer, path: str, body: Any = None,
         headers: dict[str, str] | None = None) -> tuple[int, Any]:
    """(status, JSON or bytes) of one request with the run's secret."""
    data = body if isinstance(body, bytes | None) else json.dumps(body).encode()
    req = urllib.request.Request(server.origin + path, data=data,
                                 headers={"X-Specholo-Token": server.token, **(headers or {})},
                                 method="POST" if data is not None else "GET")
    try:
        with urllib.request.urlopen(req, timeout=60) as reply:
            code, raw, kind = reply.status, reply.read(), reply.headers["Content-Type"]
    except urllib.error.HTTPError as exc:
        code, raw, kind = exc.code, exc.read(), exc.headers["Content-Type"]
    return code, json.loads(raw) if kind == "application/json" else raw


def host(server: StudioServer) -> str:
    return f"127.0.0.1:{server.server_address[1]}"


def connect(server: StudioServer, timeout: float = 10.0) -> socket.socket:
    return socket.create_connection(("127.0.0.1", server.server_address[1]), timeout=timeout)


def read_to_end(sock: socket.socket) -> bytes:
    """Everything the server sends until it closes the connection (a timeout fails)."""
    got = b""
    while True:
        try:
            chunk = sock.recv(1 << 16)
        except ConnectionResetError:  # closed with bytes of ours unread: closed all the same
            return got
        except TimeoutError:
            raise AssertionError(f"the server kept the connection open after {got!r:.300}"
                                 ) from None
        if not chunk:
            return got
        got += chunk


def responses(data: bytes) -> list[tuple[int, dict[str, str], bytes]]:
    """The HTTP responses in a connection's bytes: (status, headers, body) each."""
    out = []
    while data:
        head, _, rest = data.partition(b"\r\n\r\n")
        lines = head.decode("latin-1").split("\r\n")
        headers = {k.strip().lower(): v.strip()
                   for k, v in (line.split(":", 1) for line in lines[1:])}
        n = int(headers.get("content-length", "0"))
        out.append((int(lines[0].split()[1]), headers, rest[:n]))
        data = rest[n:]
    return out


def hang_up(sock: socket.socket) -> None:
    """Close at once with a reset, as a client that crashes or is killed does."""
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    sock.close()


# ---------------------------------------------------------------- A: smuggling
def _hidden_design(server: StudioServer) -> bytes:
    """A whole second request, with everything it needs to start a design."""
    body = json.dumps({"settings": {"stipples": 40, "size": 30}}).encode()
    return (f"POST /api/design HTTP/1.1\r\nHost: {host(server)}\r\n"
            f"X-Specholo-Token: {server.token}\r\nContent-Type: application/json\r\n"
            f"Content-Length: {len(body)}\r\n\r\n").encode() + body


REFUSED = {
    # (method, path, headers besides Content-Length; "{host}" and "{token}" filled in)
    "another site's page (no secret)": ("POST", "/api/design", {"Host": "{host}"}),
    "a wrong secret": ("POST", "/api/preview", {"Host": "{host}", "X-Specholo-Token": "nope"}),
    "a name rebound to 127.0.0.1": ("POST", "/api/design",
                                    {"Host": "evil.example:{port}", "X-Specholo-Token": "{token}"}),
    "a GET from a rebound name": ("GET", "/api/state", {"Host": "evil.example"}),
    "an unknown action": ("POST", "/api/nothing",
                          {"Host": "{host}", "X-Specholo-Token": "{token}"}),
    "a body over the JSON limit": ("POST", "/api/preview", {
        "Host": "{host}", "X-Specholo-Token": "{token}", "Content-Length": str(MAX_JSON + 1)}),
    "a chunked body": ("POST", "/api/preview", {
        "Host": "{host}", "X-Specholo-Token": "{token}", "Transfer-Encoding": "chunked",
        "Content-Length": None}),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_a_request_hidden_in_a_refused_one_is_never_answered(fresh: StudioServer, case: str):
    """The body of a refused request (a text/plain POST from another site, a
    rebound name) is a whole second request: it must not be read as the next
    one on the kept-alive connection. One answer, then the connection closes."""
    method, path, headers = REFUSED[case]
    hidden = _hidden_design(fresh)
    fill = {"host": host(fresh), "port": str(fresh.server_address[1]), "token": fresh.token}
    hdrs = {"Content-Type": "text/plain", "Content-Length": str(len(hidden)), **headers}
    head = f"{method} {path} HTTP/1.1\r\n" + "".join(
        f"{k}: {v.format(**fill)}\r\n" for k, v in hdrs.items() if v is not None)
    with connect(fresh) as sock:
        sock.sendall(head.encode() + b"\r\n" + hidden)
        got = responses(read_to_end(sock))
    assert len(got) == 1, [(code, body) for code, _, body in got]
    code, headers_back, body = got[0]
    assert code in (403, 404, 411, 413), (code, body)
    assert headers_back["connection"] == "close"
    time.sleep(0.3)
    assert fresh.studio.runner.status()["state"] == "idle"  # no design started
    assert not fresh.studio.runner.out_root.exists()


# ---------------------------------------------------------------- C: caps
def test_connections_are_capped_and_silent_ones_time_out(fresh: StudioServer):
    """Idle half-sent requests hold at most the cap's threads; a request beyond
    it gets a 503 at once; each silent connection is closed after the timeout;
    then the studio answers as before."""
    fresh.client_timeout = 2.0
    base = threading.active_count()
    idle = [connect(fresh) for _ in range(3 * MAX_CONNECTIONS)]
    try:
        for sock in idle:
            sock.sendall(f"GET /api/state HTTP/1.1\r\nHost: {host(fresh)}\r\n".encode())
        time.sleep(0.5)
        assert threading.active_count() - base <= MAX_CONNECTIONS
        t0 = time.monotonic()
        with connect(fresh, timeout=5) as sock:
            sock.sendall(f"GET /api/state HTTP/1.1\r\nHost: {host(fresh)}\r\n"
                         f"X-Specholo-Token: {fresh.token}\r\n\r\n".encode())
            (code, headers, body), *rest = responses(read_to_end(sock))
        assert time.monotonic() - t0 < 3
        assert code == 503 and "busy" in json.loads(body)["error"], (code, body)
        assert headers["connection"] == "close" and not rest
        # the silent ones are closed by the server (after the timeout, or at once: 503)
        for sock in idle:
            sock.settimeout(10)
            read_to_end(sock)
        assert time.monotonic() - t0 < 10
    finally:
        for sock in idle:
            sock.close()
    deadline = time.monotonic() + 10
    while threading.active_count() > base and time.monotonic() < deadline:
        time.sleep(0.05)
    assert threading.active_count() <= base
    code, got = call(fresh, "/api/state")
    assert code == 200 and got["model"] == "bunny"


# ---------------------------------------------------------------- D: hang-ups
def test_clients_that_hang_up_print_no_traceback(fresh: StudioServer,
                                                 capfd: pytest.CaptureFixture[str],
                                                 monkeypatch: pytest.MonkeyPatch):
    """Half-sent requests, resets, and a client gone before its large answer:
    nothing on stderr; an unexpected error in the server is one line."""
    base = threading.active_count()
    capfd.readouterr()
    for i in range(40):
        sock = connect(fresh)
        sock.sendall(f"POST /api/preview HTTP/1.1\r\nHost: {host(fresh)}\r\n"
                     f"X-Specholo-Token: {fresh.token}\r\n"
                     "Content-Length: 100\r\n\r\n{\"sett".encode()[: 20 + 3 * i])
        time.sleep(0.01)
        hang_up(sock) if i % 2 else sock.close()
    body = json.dumps({"settings": {"stipples": 5000}}).encode()
    for _ in range(3):  # a preview of 5,000 stipples is some 200 kB of JSON
        sock = connect(fresh)
        sock.sendall(f"POST /api/preview HTTP/1.1\r\nHost: {host(fresh)}\r\n"
                     f"X-Specholo-Token: {fresh.token}\r\nContent-Length: {len(body)}\r\n\r\n"
                     .encode() + body)
        time.sleep(0.05)
        hang_up(sock)
    deadline = time.monotonic() + 30
    while threading.active_count() > base and time.monotonic() < deadline:
        time.sleep(0.05)
    code, got = call(fresh, "/api/state")
    assert code == 200
    err = capfd.readouterr().err
    assert err == "", err[:2000]

    def broken(self: Any) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr(studio_server._Handler, "do_GET", broken)
    with connect(fresh) as sock:
        sock.sendall(f"GET / HTTP/1.1\r\nHost: {host(fresh)}\r\n\r\n".encode())
        read_to_end(sock)
    time.sleep(0.2)
    err = capfd.readouterr().err
    assert err.splitlines() == [
        "specholo studio: a request failed: internal error (RuntimeError: boom)"], err


# ---------------------------------------------------------------- E: uploads
def test_an_upload_streams_to_disk(fresh: StudioServer, monkeypatch: pytest.MonkeyPatch):
    """20 MB uploaded: the server holds a chunk at a time, not the body."""
    size, block = 20 << 20, bytes(range(256)) * 256  # 64 kB, not text
    seen: dict[str, int] = {}

    def stop_before_loading(self: Any, path: Path, name: str | None = None) -> None:
        seen["peak"] = tracemalloc.get_traced_memory()[1]
        seen["size"] = path.stat().st_size
        raise SpecholoError("stopped before loading")

    monkeypatch.setattr(studio_server.Studio, "open", stop_before_loading)
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        with connect(fresh, timeout=60) as sock:
            sock.sendall(f"POST /api/model HTTP/1.1\r\nHost: {host(fresh)}\r\n"
                         f"X-Specholo-Token: {fresh.token}\r\nX-Specholo-Name: cloud.ply\r\n"
                         f"Content-Length: {size}\r\nConnection: close\r\n\r\n".encode())
            for _ in range(size // len(block)):
                sock.sendall(block)
            (code, _, body), = responses(read_to_end(sock))
    finally:
        tracemalloc.stop()
    assert code == 400 and json.loads(body)["error"] == "stopped before loading"
    assert seen["size"] == size
    assert seen["peak"] - base < 4 << 20, f"{(seen['peak'] - base) / (1 << 20):.1f} MB held"
    assert list(fresh.studio.uploads.iterdir()) == []  # a refused file is not kept


@pytest.mark.parametrize("name, size, first, limit", [
    ("cloud.ply", MAX_UPLOAD + 1, b"", MAX_UPLOAD),
    ("cloud.xyz", MAX_TEXT_UPLOAD + 1, b"", MAX_TEXT_UPLOAD),
    ("mesh.obj", MAX_TEXT_UPLOAD + 1, b"", MAX_TEXT_UPLOAD),
    # an ASCII STL loads as text: judged by its first bytes
    ("mesh.stl", MAX_TEXT_UPLOAD + 1, b"solid x\n facet normal 0 0 1\n" * 300, MAX_TEXT_UPLOAD),
])
def test_an_upload_over_its_limit_is_refused_before_it_is_read(
        shared: StudioServer, name: str, size: int, first: bytes, limit: int):
    """413 with the limit in one line, before the body (a client that waits
    for "100 Continue" never gets it), and the connection closed."""
    with connect(shared) as sock:
        sock.sendall(f"POST /api/model HTTP/1.1\r\nHost: {host(shared)}\r\n"
                     f"X-Specholo-Token: {shared.token}\r\nX-Specholo-Name: {name}\r\n"
                     f"Content-Length: {size}\r\nExpect: 100-continue\r\n\r\n".encode() + first)
        got = responses(read_to_end(sock))
    # only a file whose format its first bytes tell is asked for them
    assert [code for code, _, _ in got] == ([100, 413] if first else [413]), got
    _, headers, body = got[-1]
    error = json.loads(body)["error"]
    assert headers["connection"] == "close"
    assert f"at most {limit >> 20} MB" in error and "\n" not in error, error
    assert list(shared.studio.uploads.iterdir()) == []
    code, got_state = call(shared, "/api/state")
    assert code == 200 and got_state["model"] == "bunny"


# ---------------------------------------------------------------- G: a design is its model's
def _zip_names(server: StudioServer) -> list[str]:
    code, data = call(server, "/api/design.zip")
    assert code == 200, data
    return zipfile.ZipFile(io.BytesIO(data)).namelist()


def test_a_new_model_shows_none_of_the_old_ones_design(fresh: StudioServer):
    settings = {"settings": {"stipples": 60, "size": 40, "center_z": -20}}
    code, got = call(fresh, "/api/design", settings)
    assert code == 202, got
    fresh.studio.runner.wait(120)
    assert call(fresh, "/api/design")[1]["state"] == "done"
    assert "bunny/hologram.json" in _zip_names(fresh)

    code, got = call(fresh, "/api/model", KNOT.read_bytes(), {"X-Specholo-Name": "knot.obj"})
    assert code == 200 and got["model"] == "knot" and got["design"]["state"] == "idle", got
    assert call(fresh, "/api/design")[1] == {"state": "idle"}
    code, got = call(fresh, "/api/design.zip")
    assert code == 400 and "no finished design of this model" in got["error"], got

    # a design of the knot still running when the bunny comes back: it is
    # running (one at a time), said to be the previous model's, then none
    code, got = call(fresh, "/api/design", settings)
    assert code == 202 and got["model_id"] == 2, got
    code, got = call(fresh, "/api/model", BUNNY.read_bytes(), {"X-Specholo-Name": "bunny.obj"})
    assert code == 200 and got["model_id"] == 3
    st = got["design"]
    if st["state"] == "running":  # (unless it was that quick)
        assert "previous model" in st["stage"], st
        assert call(fresh, "/api/design", settings)[0] == 409
    fresh.studio.runner.wait(120)
    assert call(fresh, "/api/design")[1] == {"state": "idle"}
    assert call(fresh, "/api/design.zip")[0] == 400

    code, got = call(fresh, "/api/design", settings)
    assert code == 202
    fresh.studio.runner.wait(120)
    st = call(fresh, "/api/design")[1]
    assert st["state"] == "done" and st["model_id"] == 3
    assert "bunny/hologram.json" in _zip_names(fresh)


# ---------------------------------------------------------------- I: the command's bounds
def _refusals(shared: StudioServer, capsys: pytest.CaptureFixture[str], tmp_path: Path,
              name: str, value: Any) -> tuple[str, int, str]:
    """(the studio's error, the command's status, the command's stderr) for one setting."""
    code, got = call(shared, "/api/preview", {"settings": {name: value}})
    assert code == 400, (name, value, got)
    assert "\n" not in got["error"] and got["error"], got
    capsys.readouterr()
    status = main(["design", str(BUNNY), "--out", str(tmp_path / "never"),
                   f"--{name.replace('_', '-')}", str(value)])
    return got["error"], status, capsys.readouterr().err


def test_the_studio_refuses_what_the_command_refuses(shared: StudioServer, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]):
    """Every bound of the design's settings, just past each end, is refused by
    the studio with a one-line 400 and by ``specholo design`` with the same
    line; a value of a choice, by both (click words its own)."""
    checked = 0
    for name, (lo, hi, _) in SETTING_BOUNDS.items():
        for value in (lo - max(1.0, abs(lo)), hi + max(1.0, abs(hi))):
            error, status, err = _refusals(shared, capsys, tmp_path, name, value)
            assert status == 1 and err == f"error: {error}\n", (name, value, error, err)
            checked += 1
    for name, value in (("stipples", 0), ("stipples", -5), ("seed", -1), ("visibility", 1.5),
                        ("raster", 5.0), ("elevation_range", 90.0), ("light_elevation", 200.0),
                        ("size", float("inf"))):
        error, status, err = _refusals(shared, capsys, tmp_path, name, value)
        assert status == 1 and err == f"error: {error}\n", (name, value, error, err)
    for name, value in (("up", "w"), ("tool", "pen"), ("placement", "random"),
                        ("method", "bogus"), ("thin", "maybe"), ("dialect", "fanuc")):
        error, status, err = _refusals(shared, capsys, tmp_path, name, value)
        assert status == 2 and "Invalid value" in err, (name, err)
    assert checked == 2 * len(SETTING_BOUNDS)
    assert not (tmp_path / "never").exists()

"""The studio: its preview puts each glint on the eye's sightline through the
stipple, its pose is the design's, bad input is one line and the server stays
up; in a browser, the page poses, redraws, designs exactly and exports a
folder that verifies."""

from __future__ import annotations

import contextlib
import io
import json
import math
import threading
import urllib.error
import urllib.parse
import urllib.request
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from specholo.errors import SpecholoError
from specholo.jobs.flat.folder import DesignConfig
from specholo.scene.loading import load_model
from specholo.scene.placement import place
from specholo.scene.pose import Pose
from specholo.scene.stippling import stipple
from specholo.studio.preview import fast_preview
from specholo.studio.server import StudioServer, make_server
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"


@contextlib.contextmanager
def running(model: Path | None, out: Path) -> Iterator[StudioServer]:
    """A studio serving ``model`` (None: none yet) on a free port, stopped after."""
    s = make_server(model, out, 0)
    thread = threading.Thread(target=s.serve_forever, daemon=True)
    thread.start()
    try:
        yield s
    finally:
        s.shutdown()
        s.server_close()
        s.studio.runner.wait(120)


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[StudioServer]:
    with running(BUNNY, tmp_path_factory.mktemp("studio-out")) as s:
        yield s


def request(server: StudioServer, path: str, body: Any = None, headers: dict | None = None,
            method: str | None = None) -> tuple[int, Any]:
    """(status, JSON or bytes) of one request to the studio, with its secret."""
    data = None
    hdrs = {"X-Specholo-Token": server.token, **(headers or {})}
    if isinstance(body, bytes):
        data = body
    elif body is not None:
        data = json.dumps(body).encode()
        hdrs["Content-Type"] = "application/json"
    req = urllib.request.Request(server.origin + path, data=data, headers=hdrs,
                                 method=method or ("POST" if data is not None else "GET"))
    try:
        with urllib.request.urlopen(req, timeout=60) as reply:
            code, raw, kind = reply.status, reply.read(), reply.headers["Content-Type"]
    except urllib.error.HTTPError as exc:
        code, raw, kind = exc.code, exc.read(), exc.headers["Content-Type"]
    return code, json.loads(raw) if kind == "application/json" else raw


SETTINGS = {"stipples": 300, "size": 50, "center_z": -30, "rotate_x": 10, "rotate_y": 25}


def test_glints_lie_on_the_sightline_through_their_stipple(server: StudioServer):
    code, got = request(server, "/api/preview", {"settings": SETTINGS})
    assert code == 200, got
    config = DesignConfig.from_dict(SETTINGS)
    pv = fast_preview(load_model(BUNNY), config)
    # the page's data is the library's preview, to the micrometre
    assert got["stipples"] == len(pv.points) == 300
    np.testing.assert_allclose(np.reshape(got["points"], (-1, 3)), pv.points, atol=6e-4)
    assert got["runs"]["stipple"] == pv.stipple.tolist()
    np.testing.assert_allclose(got["runs"]["start"], np.degrees(pv.start), atol=1e-4)
    for az in (-30.0, 0.0, 20.0):
        ids, glints = pv.glints(math.radians(az))
        assert len(ids) > 50
        eye = pv.viewer.eye(np.array([math.radians(az)]))[0]
        np.testing.assert_allclose(eye, [got["eye"]["radius"] * math.sin(math.radians(az)),
                                         got["eye"]["height"],
                                         got["eye"]["radius"] * math.cos(math.radians(az))])
        g = np.column_stack([glints, np.zeros(len(ids))])
        p = pv.points[ids]
        # on the segment from the eye to the stipple, at the plate z = 0
        t = (g - eye)[:, 2] / (p - eye)[:, 2]
        assert ((t > 0) & (t < 1)).all()
        np.testing.assert_allclose(eye + t[:, None] * (p - eye), g, atol=1e-9)
        # and only stipples the design's occlusion says the eye sees
        inside = (pv.start <= math.radians(az)) & (math.radians(az) <= pv.end)
        assert set(ids.tolist()) == set(pv.stipple[inside].tolist())
    # figures labelled as what they are
    e = got["estimates"]
    assert e["as_cut_visibility"] is None and e["as_cut_why"]
    assert e["groove_length_mm"] > 0 and e["cutting_hours_at_least"] > 0


def test_rotate_y_turns_the_stipples_as_place_does(server: StudioServer):
    base = {"stipples": 200, "size": 60, "center_z": -40}
    model = load_model(BUNNY)
    points = {}
    for ry in (0.0, 90.0):
        code, got = request(server, "/api/preview", {"settings": {**base, "rotate_y": ry}})
        assert code == 200, got
        points[ry] = np.reshape(got["points"], (-1, 3))
        placed = place(model, 60, -40, Pose("y", (0.0, ry, 0.0)).rotation())
        want = stipple(placed, np.random.default_rng(0), count=200).points
        np.testing.assert_allclose(points[ry], want, atol=6e-4)
    # a quarter turn about y: the model's depth becomes its width, and the
    # side that faced the viewer (+z) now faces right (+x)
    a = place(model, 60, -40, Pose().rotation()).points
    b = place(model, 60, -40, Pose("y", (0.0, 90.0, 0.0)).rotation()).points
    np.testing.assert_allclose(np.ptp(b, axis=0), np.ptp(a, axis=0)[[2, 1, 0]], rtol=1e-9)
    front = np.argmax(a[:, 2])
    assert b[front, 0] == pytest.approx(b[:, 0].max())
    assert not np.allclose(points[0.0], points[90.0])


def test_bad_input_is_one_line_and_the_server_stays_up(server: StudioServer):
    for name, data in (("broken.stl", b"solid x\nfacet nonsense\n"),
                       ("notes.txt", b"hello"), ("empty.obj", b"")):
        code, got = request(server, "/api/model", data,
                            {"X-Specholo-Name": name, "Content-Type": "application/octet-stream"})
        assert code == 400, got
        assert set(got) == {"error"} and "\n" not in got["error"] and got["error"], got
        assert "specholo-studio" not in got["error"]  # the maker's file name, not the copy
    for settings in ({"stipples": -5}, {"view_range": 95}, {"nonsense": 1}, [1, 2],
                     {"center_z": 500}):
        code, got = request(server, "/api/preview", {"settings": settings})
        assert code == 400 and "\n" not in got["error"], (settings, got)
    code, got = request(server, "/api/preview", b"{not json",
                        {"Content-Type": "application/json"})
    assert code == 400 and got["error"].startswith("the request is not JSON")
    code, got = request(server, "/api/state")
    assert code == 200 and got["model"] == "bunny"


def test_a_good_upload_replaces_the_model(server: StudioServer, tmp_path: Path):
    code, got = request(server, "/api/model", (ROOT / "examples" / "knot.obj").read_bytes(),
                        {"X-Specholo-Name": "my%20knot.obj"})
    assert code == 200 and got["model"] == "my_knot", got
    code, got = request(server, "/api/model", BUNNY.read_bytes(),
                        {"X-Specholo-Name": "bunny.obj"})
    assert code == 200 and got["model"] == "bunny"


def test_the_studio_serves_this_machine_only(server: StudioServer, tmp_path: Path):
    assert server.server_address[0] == "127.0.0.1"
    for host in ("0.0.0.0", "::", "192.168.1.2", "localhost"):
        with pytest.raises(SpecholoError, match="127.0.0.1 only"):
            make_server(BUNNY, tmp_path, 0, host=host)
    code, got = request(server, "/api/state", headers={"Host": "evil.example:80"})
    assert code == 403


def test_every_api_request_needs_the_runs_secret(server: StudioServer, tmp_path: Path):
    """The printed address carries a secret of this run; without it (or with the
    constant header the studio once took) no API request is answered, GET or POST,
    and the connection is closed. The page itself holds no secret."""
    assert server.url == f"{server.origin}/?token={server.token}"
    assert len(server.token) >= 32
    other = make_server(None, tmp_path, 0)
    try:
        assert other.token != server.token  # one secret a run
    finally:
        other.server_close()
    for method, path, body in (("GET", "/api/state", None), ("GET", "/api/design", None),
                               ("GET", "/api/design.zip", None),
                               ("GET", "/api/design/grooves", None),
                               ("POST", "/api/preview", b'{"settings": {}}'),
                               ("POST", "/api/design", b'{"settings": {"stipples": 50}}'),
                               ("POST", "/api/model", b"v 0 0 0\n")):
        for hdrs in ({}, {"X-Specholo": "1"}, {"X-Specholo-Token": ""},
                     {"X-Specholo-Token": server.token[:-1]},
                     {"X-Specholo-Token": server.token + "x"}):
            req = urllib.request.Request(server.origin + path, data=body, method=method,
                                         headers={**hdrs, "X-Specholo-Name": "a.obj"})
            with pytest.raises(urllib.error.HTTPError) as err:
                urllib.request.urlopen(req, timeout=10)
            assert err.value.code == 403, (method, path, hdrs)
            assert err.value.headers["Connection"] == "close"
            assert "secret" in json.loads(err.value.read())["error"]
        # in the address instead of the header: still refused
        req = urllib.request.Request(f"{server.origin}{path}?token={server.token}", data=body,
                                     method=method)
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(req, timeout=10)
        assert err.value.code == 403
    assert server.studio.runner.status()["state"] in ("idle", "done")  # nothing started
    for path in ("/", "/studio.js", "/plate_view.js", "/studio.css"):
        with urllib.request.urlopen(server.origin + path, timeout=10) as reply:
            assert reply.status == 200 and server.token.encode() not in reply.read()
    code, got = request(server, "/api/state")
    assert code == 200 and got["model"] == "bunny"


def test_every_control_has_its_own_label():
    """Each control's label says what it is: no two alike (there were two "up"s,
    the model's up axis and the move up the plate)."""
    from html.parser import HTMLParser

    class Labels(HTMLParser):
        def __init__(self) -> None:
            super().__init__()
            self.labels: dict[str, str] = {}
            self.text: list[str] | None = None
            self.skip = 0
            self.control = ""

        def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
            if tag == "label":
                self.text, self.control = [], ""
            elif tag in ("option", "output") and self.text is not None:
                self.skip += 1
            elif tag in ("input", "select") and self.text is not None:
                self.control = dict(attrs).get("id") or ""

        def handle_endtag(self, tag: str) -> None:
            if tag in ("option", "output") and self.skip:
                self.skip -= 1
            elif tag == "label" and self.text is not None:
                self.labels[self.control] = " ".join("".join(self.text).split())
                self.text = None

        def handle_data(self, data: str) -> None:
            if self.text is not None and not self.skip:
                self.text.append(data)

    parser = Labels()
    parser.feed((ROOT / "src" / "specholo" / "studio" / "page.html").read_text())
    names = [name.removesuffix(" mm").removesuffix("\u00b0").strip()
             for name in parser.labels.values()]
    assert len(names) == len(set(names)), parser.labels
    assert "axis" in parser.labels["up"] and "up" in parser.labels["offset_y"], parser.labels
    assert "axis" not in parser.labels["offset_y"]


def test_one_design_at_a_time(server: StudioServer):
    settings = {"settings": {"stipples": 60, "size": 40, "center_z": -20}}
    code, got = request(server, "/api/design", settings)
    assert code == 202 and got["state"] == "running", got
    code, got = request(server, "/api/design", settings)
    assert code == 409 and "already running" in got["error"]
    server.studio.runner.wait(60)
    code, st = request(server, "/api/design")
    assert st["state"] == "done", st
    f = st["summary"]
    assert f["stipples"] == 60 and 0 < f["machining_hours"] and 0 <= f["as_cut_lowest"] <= 1
    code, data = request(server, "/api/design.zip")
    names = zipfile.ZipFile(io.BytesIO(data)).namelist()
    assert "bunny/hologram.json" in names and "bunny/hologram.gcode" in names


def test_the_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    assert main(["studio", "--help"]) == 0
    assert "127.0.0.1" in capsys.readouterr().out
    assert main(["studio", str(tmp_path / "missing.obj"), "--no-browser"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "does not exist" in err
    bad = tmp_path / "bad.obj"
    bad.write_text("v 1 2\n")
    assert main(["studio", str(bad), "--no-browser", "--port", "0"]) == 1
    assert capsys.readouterr().err.count("\n") == 1


def test_a_port_in_use_is_one_line(server: StudioServer, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]):
    port = server.server_address[1]
    assert main(["studio", "--port", str(port), "--no-browser", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"127.0.0.1:{port}" in err


def test_without_a_model_the_page_asks_for_one(tmp_path: Path):
    s = make_server(None, tmp_path, 0)
    threading.Thread(target=s.serve_forever, daemon=True).start()
    try:
        code, got = request(s, "/api/state")
        assert code == 200 and got["model"] is None
        code, got = request(s, "/api/preview", {"settings": {"stipples": 100}})
        assert code == 400 and got["error"].startswith("no model open")
        code, got = request(s, "/api/design.zip")
        assert code == 400 and "no finished design" in got["error"]
    finally:
        s.shutdown()
        s.server_close()
    assert not s.studio.uploads.exists()


def test_ctrl_c_stops_the_studio_plainly(tmp_path: Path):
    """Ctrl-C is the studio's normal stop: "studio stopped", status 0, nothing on
    stderr, at once even while a browser keeps a connection open."""
    import os
    import signal
    import socket
    import subprocess
    import sys
    import time

    proc = subprocess.Popen(
        [sys.executable, "-c", "import sys; from specholo_cli.cli import main; "
         "sys.argv[0] = 'specholo'; main()", "studio", str(BUNNY), "--port", "0",
         "--no-browser", "--out", str(tmp_path)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        line = proc.stdout.readline()
        assert "http://127.0.0.1:" in line and "/?token=" in line, line
        url = line.split()[2]
        with urllib.request.urlopen(url, timeout=20) as reply:
            assert b"studio.js" in reply.read()
        # a connection kept open, as a browser keeps one between requests
        port = urllib.parse.urlsplit(url).port
        kept = socket.create_connection(("127.0.0.1", port), timeout=10)
        kept.sendall(f"GET /studio.css HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
        assert kept.recv(100).startswith(b"HTTP/1.1 200")
        time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=10)
        kept.close()
    finally:
        proc.kill()
    assert err == "" and proc.returncode == 0, (proc.returncode, err)
    assert out.splitlines() == ["studio stopped"], out


# ---------------------------------------------------------------- in a browser
def _slide(page: Any, key: str, value: float) -> None:
    page.evaluate("([k, v]) => { const e = document.getElementById(k); e.value = v; "
                  "e.dispatchEvent(new Event('input')); }", [key, value])


def _settled(page: Any) -> None:
    page.wait_for_function("window.studio && window.studio.previews() > 0 && "
                           "!window.studio.busy()", timeout=20_000)


def test_the_page_poses_redraws_and_designs_a_plate_that_verifies(
        server: StudioServer, browser: Any, tmp_path: Path):
    from specholo.jobs import VerifyOptions, job_of

    # The page forbids eval; the test's own probes (wait_for_function) need it.
    context = browser.new_context(accept_downloads=True, bypass_csp=True,
                                  viewport={"width": 1400, "height": 900})
    page = context.new_page()
    errors: list[str] = []
    urls: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("request", lambda r: urls.append(r.url))
    page.goto(server.url)
    _settled(page)
    assert page.inner_text("#model-name") == "bunny"
    page.uncheck("#follow")  # designed on the button only (the next test follows)

    # drag on the model: the pose turns about the plate's y and x axes (the
    # canvas brought back into view: unticking "follow" may have scrolled it away)
    page.locator("#model").scroll_into_view_if_needed()
    box = page.locator("#model").bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    asked = page.evaluate("window.studio.previews()")
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + 60, cy + 20, steps=6)
    page.mouse.up()
    _settled(page)
    pose = page.evaluate("window.studio.settings()")
    assert pose["rotate_y"] == pytest.approx(30.0) and pose["rotate_x"] == pytest.approx(10.0)
    assert page.evaluate("window.studio.previews()") > asked

    # the light slider: a new preview, the glint canvas drawn again
    draws = page.evaluate("window.studio.draws()")
    before = page.inner_text("#estimates")
    _slide(page, "light_elevation", 55)
    page.wait_for_function(f"window.studio.draws() > {draws} && !window.studio.busy()")
    _settled(page)
    assert page.inner_text("#estimates") != before  # the groove length follows the light

    # the page's glints are the library's, on each eye's sightline
    _slide(page, "stipples", 150)
    _settled(page)
    _slide(page, "azimuth", 20)
    shown = page.evaluate("window.studio.glints()")
    settings = page.evaluate("window.studio.settings()")
    config = DesignConfig.from_dict({k: settings[k] for k in (
        "size", "center_z", "up", "rotate_x", "rotate_y", "offset_x", "offset_y",
        "light_elevation", "view_range", "view_distance", "stipples", "seed")})
    ids, glints = fast_preview(load_model(BUNNY), config).glints(math.radians(20.0))
    assert [g["id"] for g in shown] == ids.tolist()
    np.testing.assert_allclose([[g["x"], g["y"]] for g in shown], glints, atol=2e-3)

    # design exactly, download the zip, verify what it holds
    page.click("#design")
    page.wait_for_selector("#export:not([hidden])", timeout=60_000)
    result_text = page.inner_text("#result")
    assert "as-cut visibility" in result_text and "of 150" in result_text, result_text
    assert page.inner_text("#folder").endswith("bunny")
    with page.expect_download() as dl:
        page.click("#zip")
    with zipfile.ZipFile(dl.value.path()) as zf:
        zf.extractall(tmp_path)
    folder = tmp_path / "bunny"
    info = json.loads((folder / "hologram.json").read_text())
    assert info["stats"]["stipples"] == 150
    assert info["settings"]["rotate_y"] == pytest.approx(30.0)
    result = job_of(folder).verify(folder, VerifyOptions(step_deg=15.0), print)
    p95 = [float(row[result.table.columns.index("p95 mm")]) for row in result.table.rows]
    assert max(p95) < 0.5, result.lines
    context.close()
    assert errors == []
    # this server only (the zip is saved from memory: a blob: of the page's own)
    assert urls and all(u.startswith((server.origin + "/", f"blob:{server.origin}/"))
                        for u in urls), urls


def test_the_exact_figures_follow_the_settings(server: StudioServer, browser: Any,
                                               tmp_path: Path):
    """Left to follow, the page designs exactly once the settings rest: the
    as-cut visibility and the whole job's machining time stand beside the
    preview's estimates, are the folder's own, and give way when a setting moves."""
    context = browser.new_context(bypass_csp=True, viewport={"width": 1400, "height": 900})
    page = context.new_page()
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(server.url)
    _settled(page)
    # the secret leaves the address bar, and a reload of the bare address in
    # this tab still works; a tab that never had it says what to open
    assert "token" not in page.url
    page.goto(server.origin + "/")
    _settled(page)
    assert page.inner_text("#model-name") == "bunny" and page.inner_text("#error") == ""
    stranger = context.new_page()
    stranger.goto(server.origin + "/")
    stranger.wait_for_function("document.getElementById('error').textContent !== ''")
    assert "?token=" in stranger.inner_text("#error")
    stranger.close()
    assert page.is_checked("#follow")
    _slide(page, "stipples", 100)
    _settled(page)
    current = "window.studio.exact() && window.studio.exact().current"
    page.wait_for_function(current, timeout=120_000)
    exact = page.evaluate("window.studio.exact()")
    assert exact["settings"]["stipples"] == 100
    table = page.inner_text("#estimates")
    summary = exact["summary"]
    assert f"about {summary['machining']}" in table, table
    assert f"{round(100 * summary['as_cut_lowest'])}% lowest" in table, table
    # they are the figures of the folder the design wrote
    info = json.loads((Path(page.inner_text("#folder")) / "hologram.json").read_text())
    assert summary["machining_hours"] == pytest.approx(info["machining"]["estimated_hours"])
    seen = info["expected"]["as_cut_stereo_visibility"]
    assert summary["as_cut_lowest"] == pytest.approx(seen["lowest"])
    # and the light the design names for its sharpest image is the folder's
    lamp = info["light_to_use"]["lamp"]
    assert lamp in summary["light"] and lamp in page.inner_text("#result")
    # a setting moves: the figures wait for the next design, then are its own
    _slide(page, "light_elevation", 50)
    _settled(page)
    # (a quick machine may have the next design done already: then it is its own)
    assert "updating" in page.inner_text("#estimates") or \
        "estimate:" in page.inner_text("#estimates") or \
        page.evaluate("window.studio.exact()")["settings"]["light_elevation"] == 50
    page.wait_for_function(current, timeout=120_000)
    assert page.evaluate("window.studio.exact()")["settings"]["light_elevation"] == 50
    assert "updating" not in page.inner_text("#estimates")
    # another model: the bunny's figures and folder are not its own; its own follow
    page.set_input_files("#file", str(ROOT / "examples" / "knot.obj"))
    page.wait_for_function("document.getElementById('model-name').textContent === 'knot'")
    assert not page.evaluate(current)
    # (or the knot's own estimate, from a sample of its design, labelled so)
    table = page.inner_text("#estimates")
    assert "updating" in table or table.count("\u2014") >= 2 or "estimate:" in table
    assert f"about {summary['machining']}" not in table or "estimate:" in table
    page.wait_for_function(current, timeout=120_000)
    assert page.inner_text("#folder").endswith("knot")
    info = json.loads((Path(page.inner_text("#folder")) / "hologram.json").read_text())
    assert page.evaluate("window.studio.exact()")["summary"]["machining_hours"] == \
        pytest.approx(info["machining"]["estimated_hours"])
    context.close()
    assert errors == []
    server.studio.runner.wait(120)
    code, got = request(server, "/api/model", BUNNY.read_bytes(), {"X-Specholo-Name": "bunny.obj"})
    assert code == 200 and got["model"] == "bunny"


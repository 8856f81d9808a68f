"""The studio offers every setting a maker changes, as ``specholo design`` takes
it: the page's controls are the command's options with its bounds and
choices, the page shows the command that designs what it designs (run, it
gives the same files), each file downloads in one click, and the settings
survive a reload."""

from __future__ import annotations

import json
import re
import shlex
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from test_studio import BUNNY, _settled, request, running

from specholo.studio.server import StudioServer
from specholo_cli.cli import cli, main

PAGE = Path(__file__).resolve().parents[1] / "src" / "specholo" / "studio" / "page.html"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[StudioServer]:
    with running(BUNNY, tmp_path_factory.mktemp("studio-out")) as s:
        yield s


def _design(server: StudioServer, settings: dict[str, Any]) -> dict[str, Any]:
    server.studio.runner.wait(180)  # one a page left running (it follows its settings)
    code, reply = request(server, "/api/design", {"settings": settings})
    assert code == 202, reply
    server.studio.runner.wait(180)
    code, status = request(server, "/api/design")
    assert status["state"] == "done", status
    return status


def test_every_control_of_the_page_is_a_design_option_with_its_choices(server: StudioServer):
    options = {p.name: p for p in cli.commands["design"].params}
    ids = re.findall(r'id="([a-z_]+)" data-setting', PAGE.read_text())
    assert len(ids) >= 15
    assert set(ids) <= set(options), set(ids) - set(options)
    code, state = request(server, "/api/state")
    assert code == 200
    for name, values in state["choices"].items():
        choices = set(options[name].type.choices)  # type: ignore[attr-defined]
        # a ridged plate is `specholo design --method ridged`'s, not the page's
        assert set(values) == choices - {"ridged"}, name
    for name in ids:
        if name in state["bounds"]:
            lo, hi, _ = state["bounds"][name]
            assert lo < hi


def test_the_pages_command_makes_the_same_design(server: StudioServer, tmp_path: Path):
    settings = {"stipples": 120, "size": 50, "center_z": -30, "rotate_x": 10,
                "rotate_y": 25, "rotate_z": 15, "up": "y", "offset_x": 0, "offset_y": 0,
                "light_elevation": 50, "view_range": 40, "view_distance": 600, "seed": 0,
                "tool": "drag", "tool_radius": 0.03, "holder": "rigid", "depth": None,
                "machine": "grbl-router", "method": None, "ipd": None}
    code, preview = request(server, "/api/preview", {"settings": settings})
    assert code == 200, preview
    words = shlex.split(preview["command"])
    assert words[:2] == ["specholo", "design"]
    for flag in ("--tool-radius", "--holder", "--machine", "--rotate-z"):
        assert flag in words, words
    assert "--ipd" not in words and "--method" not in words  # left to their defaults
    status = _design(server, settings)
    assert words[2] == str(BUNNY)  # the model as the studio was given it
    words[words.index("--out") + 1] = str(tmp_path / "cli")
    assert main(words[1:]) == 0
    page, cli_folder = Path(status["folder"]), tmp_path / "cli"
    ours = json.loads((page / "hologram.json").read_text())["settings"]
    theirs = json.loads((cli_folder / "hologram.json").read_text())["settings"]
    assert ours == theirs
    for name in ("grooves.npz", "hologram.gcode", "hologram.svg", "hologram.dxf"):
        assert (page / name).read_bytes() == (cli_folder / name).read_bytes(), name


def test_each_file_downloads_in_one_request(server: StudioServer):
    status = _design(server, {"stipples": 60, "size": 40, "center_z": -20})
    folder = Path(status["folder"])
    code, body = request(server, "/api/design/file?name=hologram.gcode")
    assert code == 200 and body == (folder / "hologram.gcode").read_bytes()
    code, body = request(server, "/api/design/file?name=hologram.dxf")
    assert code == 200 and body == (folder / "hologram.dxf").read_bytes()
    assert not (folder / "pattern.pdf").exists()  # made when first asked for
    code, body = request(server, "/api/design/file?name=pattern.pdf")
    assert code == 200 and body.startswith(b"%PDF") and (folder / "pattern.pdf").exists()
    code, reply = request(server, "/api/design/file?name=..%2Fhologram.json")
    assert code == 400 and "no such file to export" in reply["error"]
    code, _ = request(server, "/api/design/file?name=hologram.gcode",
                      headers={"X-Specholo-Token": "wrong"})
    assert code == 403


def test_the_settings_survive_a_reload(server: StudioServer, browser: Any):
    context = browser.new_context(bypass_csp=True, viewport={"width": 1400, "height": 1000})
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(server.url)
    _settled(page)
    page.uncheck("#follow")
    page.click("#more-box summary")  # the options beyond the sliders, folded away at first
    page.fill("#tool_radius", "0.03")
    page.dispatch_event("#tool_radius", "change")
    page.select_option("#holder", "rigid")
    page.select_option("#up", "z")
    page.dispatch_event("#up", "change")
    page.wait_for_function("window.studio.command().includes('--tool-radius 0.03')")
    _settled(page)
    command = page.evaluate("window.studio.command()")
    assert "--holder rigid" in command and "--up z" in command, command
    # before any exact design, the figures a maker decides on are estimates, so labelled
    page.wait_for_function("window.studio.estimate() !== null", timeout=60_000)
    quick = page.evaluate("window.studio.estimate()")
    table = page.inner_text("#estimates")
    assert f"about {quick['machining']}" in table and "estimate:" in table, table
    # designed, the page sets the design beside the classic arcs of its settings
    page.click("#design")
    page.wait_for_selector("#compare:not([hidden])", timeout=120_000)
    rows = page.locator("#compare tbody tr")
    assert rows.count() == 2
    assert rows.nth(0).inner_text().startswith("exact (striped)")
    assert rows.nth(1).inner_text().startswith("classic arcs")
    page.reload()
    _settled(page)
    assert page.input_value("#tool_radius") == "0.03"
    assert page.input_value("#holder") == "rigid" and page.input_value("#up") == "z"
    page.wait_for_function("window.studio.command().includes('--tool-radius 0.03')")
    assert page.evaluate("window.studio.settings()")["up"] == "z"  # the model stays upright
    context.close()
    assert errors == []


def test_the_design_stands_beside_the_classic_arcs(server: StudioServer, tmp_path: Path):
    """The page sets each design beside the arcs of the same settings: the
    exact grooves' worst error is a fraction of the arcs' (right at every view,
    where the arcs are right only near the straight-on one), and its figures
    are what `specholo verify` finds on the folder."""
    status = _design(server, {"stipples": 200, "size": 50, "center_z": -30})
    exact, arcs = status["summary"]["compared"]
    assert exact["label"] == "exact (striped)" and arcs["label"] == "classic arcs"
    assert exact["strokes"] > 10 * arcs["strokes"]  # what exact costs...
    assert exact["worst_p95_mm"] < 0.05 * arcs["worst_p95_mm"]  # ...and what it buys
    assert exact["as_cut_lowest"] > arcs["as_cut_lowest"]
    folder = Path(status["folder"])
    assert main(["verify", str(folder), "--step", "5"]) == 0
    figures = json.loads((folder / "verify.json").read_text())["figures"]
    assert exact["worst_p95_mm"] == pytest.approx(figures["worst_p95_mm"], rel=1e-9)
    assert exact["lowest_visibility"] == pytest.approx(figures["lowest_visibility"], rel=1e-9)


def test_the_estimate_is_the_exact_design_of_a_strip_at_full_density(server: StudioServer):
    """The page's quick figures come from designing a strip of the plate: a
    design small enough to design whole gives the exact design's figures, and
    a larger one's fall near them (docs/studio.md states the margin)."""
    small = {"stipples": 150, "size": 50, "center_z": -30}
    code, quick = request(server, "/api/estimate", {"settings": small})
    assert code == 200, quick
    assert (quick["sample"], quick["of"]) == (150, 150)  # designed whole
    exact = _design(server, small)["summary"]
    assert quick["strokes"] == exact["paths"]
    assert quick["as_cut_mean"] == pytest.approx(exact["as_cut_mean"], abs=1e-12)
    assert quick["as_cut_lowest"] == pytest.approx(exact["as_cut_lowest"], abs=1e-12)
    assert quick["machining_hours"] == pytest.approx(exact["machining_hours"], rel=1e-9)
    larger = {"stipples": 1000}
    code, quick = request(server, "/api/estimate", {"settings": larger})
    assert code == 200 and quick["sample"] == 200 and quick["of"] == 1000
    exact = _design(server, larger)["summary"]
    assert abs(quick["as_cut_mean"] - exact["as_cut_mean"]) <= 0.04
    assert abs(quick["as_cut_lowest"] - exact["as_cut_lowest"]) <= 0.1
    assert quick["strokes"] == pytest.approx(exact["paths"], rel=0.15)
    assert quick["machining_hours"] == pytest.approx(exact["machining_hours"], rel=0.1)
    code, reply = request(server, "/api/estimate", {"settings": {"visibility": 0.8}})
    assert code == 200 and "chosen by the design" in reply["why"]


def test_a_bad_estimate_request_is_one_line(server: StudioServer):
    for settings, says in (({"tool_radius": -1}, "radius"),
                           ({"method": "ridged"}, "ridged"),
                           ({"stipples": "many"}, "stipples")):
        code, reply = request(server, "/api/estimate", {"settings": settings})
        assert code == 400 and says in reply["error"], reply
        assert "\n" not in reply["error"] and "Traceback" not in reply["error"]
    code, _ = request(server, "/api/estimate", {"settings": {}},
                      headers={"X-Specholo-Token": "wrong"})
    assert code == 403

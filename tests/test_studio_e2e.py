"""The studio end to end, in headless Chromium, as a maker uses it: open a z-up
model, stand it up and pose it, change every control, design, download each
file and check it (the G-code passes `specholo check`, the SVG reads in vpype,
the DXF in ezdxf, the PDF in pypdf), with the page's pictures compared
against stored ones; and posing a 2,000-stipple model keeps every frame
under 100 ms."""

from __future__ import annotations

import io
import json
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_studio import BUNNY, _settled, running

from specholo.studio.server import StudioServer
from specholo_cli.cli import main

GOLDEN = Path(__file__).resolve().parent / "golden"
#: How far a picture may drift from the stored one (the browser's own
#: anti-aliasing may differ a little between versions): the mean difference
#: per channel, of 255, and the share of pixels that differ by more than 48.
MEAN_DRIFT, PIXEL_SHARE = 3.0, 0.01


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[StudioServer]:
    with running(None, tmp_path_factory.mktemp("studio-out")) as s:
        yield s


def z_up_bunny(folder: Path) -> Path:
    """The bundled bunny as a CAD file has it: z up, in binary STL."""
    import trimesh

    mesh = trimesh.load(BUNNY, force="mesh")
    # the model's y (up) becomes z: a turn of +90 degrees about x
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    path = folder / "bunny_zup.stl"
    mesh.export(path)
    return path


def same_picture(png: bytes, name: str, regen: bool) -> None:
    """The picture matches ``tests/golden/<name>`` within the drift above."""
    from PIL import Image

    stored = GOLDEN / name
    if regen:
        stored.write_bytes(png)
        return
    assert stored.exists(), f"missing {stored}; run pytest --regen-golden"
    new = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)
    old = np.asarray(Image.open(stored).convert("RGB"), dtype=float)
    assert new.shape == old.shape, (new.shape, old.shape)
    diff = np.abs(new - old)
    assert diff.mean() <= MEAN_DRIFT and (diff.max(axis=2) > 48).mean() <= PIXEL_SHARE, (
        f"{name}: mean drift {diff.mean():.2f}, "
        f"{100 * (diff.max(axis=2) > 48).mean():.2f}% of pixels differ")


def _set(page: Any, key: str, value: Any, event: str = "change") -> None:
    page.evaluate("([k, v, e]) => { const el = document.getElementById(k); "
                  "if (el.type === 'checkbox') el.checked = v; else el.value = v; "
                  "el.dispatchEvent(new Event(e)); }", [key, value, event])


def _download(page: Any, selector: str, folder: Path) -> Path:
    with page.expect_download(timeout=180_000) as dl:
        page.click(selector)
    path = folder / dl.value.suggested_filename
    dl.value.save_as(path)
    return path


def test_a_maker_designs_a_z_up_model_and_takes_every_file(
        server: StudioServer, browser: Any, tmp_path: Path, request: pytest.FixtureRequest):
    import ezdxf
    import pypdf
    import vpype

    regen = request.config.getoption("--regen-golden")
    context = browser.new_context(accept_downloads=True, bypass_csp=True,
                                  viewport={"width": 1400, "height": 1000})
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.goto(server.url)
    page.wait_for_function("window.studio !== undefined")
    # no model yet: the page asks for one (once its first drawing is done,
    # which a loaded machine may not have reached when the page is up)
    page.wait_for_selector("#prompt", state="visible", timeout=10_000)
    page.set_input_files("#file", str(z_up_bunny(tmp_path)))
    page.wait_for_function("document.getElementById('model-name').textContent === 'bunny_zup'")
    _settled(page)
    page.uncheck("#follow")
    # stand it up, then every control of the page
    _set(page, "up", "z")
    for key, value in {"size": 50, "center_z": -30, "offset_x": 3, "offset_y": -2,
                       "light_elevation": 50, "view_range": 40, "view_distance": 700,
                       "stipples": 300}.items():
        _set(page, key, value, "input")
    page.click("#more-box summary")
    for key, value in {"method": "striped", "rotate_z": 10, "light_distance": 2000,
                       "eye_height": 20, "ipd": 62, "tool": "drag", "tool_radius": 0.03,
                       "depth": 0.012, "holder": "rigid", "machine": "grbl-router",
                       "plate_width": 130, "plate_height": 100}.items():
        _set(page, key, value)
    page.locator("#model").scroll_into_view_if_needed()
    box = page.locator("#model").bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + 40, cy - 20, steps=5)  # a turn about y and x
    page.mouse.up()
    _settled(page)
    settings = page.evaluate("window.studio.settings()")
    assert settings["up"] == "z" and settings["rotate_y"] == pytest.approx(20.0)
    command = page.evaluate("window.studio.command()")
    for flag in ("--up z", "--rotate-y 20", "--tool-radius 0.03", "--machine grbl-router",
                 "--plate-width 130", "--light-distance 2000", "--eye-height 20"):
        assert flag in command, command
    _set(page, "azimuth", 15, "input")
    same_picture(page.locator("#model").screenshot(), "studio_model.png", regen)
    same_picture(page.locator("#glints").screenshot(), "studio_glints.png", regen)

    page.click("#design")
    page.wait_for_function("!document.getElementById('export').hidden || "
                           "document.getElementById('status').textContent.startsWith('failed')",
                           timeout=180_000)
    assert page.is_visible("#export"), page.inner_text("#status")
    files = {name: _download(page, f"button.file[data-file='{name}']", tmp_path)
             for name in ("hologram.gcode", "hologram.svg", "hologram.dxf", "pattern.pdf")}
    assert main(["check", str(files["hologram.gcode"])]) == 0
    lines, _, _ = vpype.read_svg(str(files["hologram.svg"]), quantization=0.1)
    assert len(lines) > 300  # every stipple's strokes, and the plate's marks
    assert len(ezdxf.readfile(files["hologram.dxf"]).modelspace()) > 300
    assert len(pypdf.PdfReader(files["pattern.pdf"]).pages) >= 1
    archive = _download(page, "#zip", tmp_path)
    with zipfile.ZipFile(archive) as zf:
        info = json.loads(zf.read("bunny_zup/hologram.json"))
    saved = info["settings"]
    assert (saved["up"], saved["tool_radius"], saved["holder"], saved["machine"]) == (
        "z", 0.03, "rigid", "grbl-router")
    assert (saved["plate_width"], saved["plate_height"]) == (130, 100)
    context.close()
    assert errors == []


def test_posing_a_2000_stipple_model_keeps_every_frame_under_100_ms(
        server: StudioServer, browser: Any):
    context = browser.new_context(bypass_csp=True, viewport={"width": 1400, "height": 1000})
    page = context.new_page()
    page.goto(server.url)
    page.wait_for_function("window.studio !== undefined")
    if page.inner_text("#model-name") == "no model":
        page.set_input_files("#file", str(BUNNY))
        page.wait_for_function("document.getElementById('model-name').textContent !== "
                               "'no model'")
    _settled(page)
    page.uncheck("#follow")
    _set(page, "stipples", 2000, "input")
    _settled(page)
    # every task the page's main thread runs for longer than 50 ms, from now on
    page.evaluate("window.longTasks = []; new PerformanceObserver((list) => "
                  "list.getEntries().forEach((e) => window.longTasks.push(e.duration)))"
                  ".observe({type: 'longtask', buffered: false});")
    page.locator("#model").scroll_into_view_if_needed()
    box = page.locator("#model").bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(cx, cy)
    page.mouse.down()
    for step in range(30):  # half a second of dragging, a move every frame
        page.mouse.move(cx + 4 * step, cy + 2 * step)
        page.wait_for_timeout(16)
    page.mouse.up()
    _settled(page)
    longest = page.evaluate("Math.max(0, ...window.longTasks)")
    assert longest < 100, page.evaluate("window.longTasks")
    context.close()

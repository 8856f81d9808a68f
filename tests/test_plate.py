"""The plate in the shop files: the SVG's and DXF's PLATE layer (outline and
registration marks) and the G-code's plate block agree with each other, with
the plate the design was made for and with the program's own check line."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import ezdxf
import numpy as np
import pytest
from ezdxf import bbox, recover
from test_gcode import check_canon, needs_rs274, run_rs274

from specholo.errors import SpecholoError
from specholo.fabrication.check import limits_from_header
from specholo.fabrication.drawings.dxf import write_dxf
from specholo.fabrication.drawings.svg import (
    LAYER_COLOURS,
    PLATE_COLOUR,
    PLATE_LAYER,
    PLATE_LAYER_NAME,
    plan_layers,
    write_svg,
)
from specholo.fabrication.plate import (
    MARK_ARM,
    MARK_INSET,
    MARK_RADIUS,
    PLATE_MARGIN,
    Plate,
    fit_plate,
)
from specholo.fabrication.programs.gcode import write_gcode
from specholo.fabrication.programs.program import GcodeOptions
from specholo.setup import Machining, Tool
from specholo.toolpaths.grooves import Grooves

SVG = "{http://www.w3.org/2000/svg}"
INKSCAPE = "{http://www.inkscape.org/namespaces/inkscape}"
ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
# a plate off the grooves' fitted one, with room for the marks beside the grooves
PLATE = Plate(-30.0, -20.0, 30.0, 20.0, thickness=2.0)


def expected_marks(plate: Plate) -> np.ndarray:
    """(5, 2) mark centres: MARK_INSET inside each corner (ccw from lower left), origin."""
    x0, y0, x1, y1 = plate.x0, plate.y0, plate.x1, plate.y1
    i = MARK_INSET * plate.mark_scale
    return np.array([[x0 + i, y0 + i], [x1 - i, y0 + i], [x1 - i, y1 - i], [x0 + i, y1 - i],
                     [0.0, 0.0]])


# ---------------------------------------------------------------------------
# the plate and its marks


def test_fitted_plate_is_the_designs():
    """Without a plate the writers draw the one a design gets without a size:
    centred, whole mm, PLATE_MARGIN beyond the grooves' edges."""
    from specholo.jobs.flat.folder import DesignConfig, plate_rect

    g = Grooves(np.array([[-3.2, 1.0], [17.7, -8.1]]), np.zeros(2), np.array([0, 2]),
                np.array([0]))
    width = 0.4
    fitted = fit_plate(g.extent(), width)
    np.testing.assert_array_equal(fitted, plate_rect(g, width, DesignConfig()))
    # reach 17.7 and 8.1 (+ half a groove): 2 * 17.9 + 10 = 45.8 -> 46, 2 * 8.3 + 10 -> 27
    np.testing.assert_array_equal(fitted, [[-23.0, -13.5], [23.0, 13.5]])
    lo, hi = g.extent()
    assert np.all(lo - 0.5 * width - fitted[0] >= PLATE_MARGIN)
    assert np.all(fitted[1] - hi - 0.5 * width >= PLATE_MARGIN)


def test_corner_marks_lie_in_the_blank_border():
    """On a fitted plate the corner marks, circle and crosshair, stay inside the
    plate and outside the grooves' 5 mm border."""
    plate = Plate.fitted(np.array([[-10.0, -4.0], [10.0, 4.0]]), 0.5)
    reach = MARK_INSET + max(MARK_ARM, MARK_RADIUS)
    assert plate.mark_scale == 1.0 and reach < PLATE_MARGIN
    for (x, y) in plate.marks()[:4]:
        # distance from the nearer vertical and horizontal edge
        dx = min(x - plate.x0, plate.x1 - x)
        dy = min(y - plate.y0, plate.y1 - y)
        assert dx == dy == MARK_INSET
        assert dx - MARK_ARM > 0 and dx + MARK_ARM < PLATE_MARGIN


def test_marks_shrink_on_a_small_plate():
    plate = Plate(-2.0, -1.5, 2.0, 1.5)
    assert plate.mark_scale == pytest.approx(3.0 / (4 * MARK_INSET))
    marks = plate.marks()
    np.testing.assert_allclose(marks, expected_marks(plate))
    arm = plate.mark_arm
    # every corner mark inside the plate, clear of the origin mark
    assert np.all(marks[:4, 0] - arm > plate.x0) and np.all(marks[:4, 0] + arm < plate.x1)
    assert np.all(marks[:4, 1] - arm > plate.y0) and np.all(marks[:4, 1] + arm < plate.y1)
    assert np.all(np.abs(marks[:4]).max(axis=1) > 2 * arm)


@pytest.mark.parametrize("args", [(1.0, 0.0, 0.0, 1.0), (0.0, 0.0, np.nan, 1.0),
                                  (0.0, 0.0, 1.0, 1.0, 0.0), (0.0, 0.0, 1.0, 1.0, np.inf)])
def test_rejects_bad_plates(args):
    with pytest.raises(SpecholoError, match="plate"):
        Plate(*args)


def test_default_plate_of_an_arc_written_straight(tmp_path):
    """A bulge so small that its arc's radius overflows is written as its chord,
    and the default plate is fitted to the chord (it was an infinite plate)."""
    g = Grooves(np.array([[0.0, 0.0], [0.0, 0.0], [0.9, 1.5]]), np.array([0.0, 2.2e-309, 0.0]),
                np.array([0, 1, 3]), np.array([0, 0]))
    assert not np.isfinite(g.extent()).all()
    want = fit_plate(np.array([[0.0, 0.0], [0.9, 1.5]]), Tool().width)
    np.testing.assert_array_equal(want, [[-6.5, -7.0], [6.5, 7.0]])  # ceil(2 * 1.08 + 10)
    write_svg(tmp_path / "s.svg", g, Tool())
    write_dxf(tmp_path / "s.dxf", g, Tool())
    write_gcode(tmp_path / "s.ngc", g, Tool(), Machining())
    np.testing.assert_array_equal(plate_block(tmp_path / "s.ngc")["corners"], want)
    rect = plate_group(ET.parse(tmp_path / "s.svg").getroot()).find(f"{SVG}rect")
    assert rect is not None and float(rect.get("width", "nan")) == 13.0
    doc = ezdxf.readfile(tmp_path / "s.dxf")
    assert tuple(doc.header["$EXTMIN"])[:2] == (-6.5, -7.0)


# ---------------------------------------------------------------------------
# SVG


def plate_group(root: ET.Element) -> ET.Element:
    (group,) = [g for g in root.findall(f"{SVG}g")
                if g.get(f"{INKSCAPE}label", "").endswith(PLATE_LAYER_NAME)]
    return group


def svg_marks(group: ET.Element) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Circle centres (k, 2) and radii (k,), and the crosshairs' lines (2k, 2, 2),
    in the plate frame."""
    circles = group.findall(f"{SVG}circle")
    centres = np.array([[float(c.get("cx", "nan")), -float(c.get("cy", "nan"))]
                        for c in circles])
    radii = np.array([float(c.get("r", "nan")) for c in circles])
    lines = []
    for p in group.findall(f"{SVG}path"):
        nums = [float(v) for v in re.findall(r"-?\d+\.\d+", p.get("d", ""))]
        assert re.fullmatch(r"M [-\d. ]+ L [-\d. ]+ M [-\d. ]+ L [-\d. ]+", p.get("d", ""))
        xy = np.array(nums).reshape(2, 2, 2) * [1.0, -1.0]
        lines.extend(xy)
    return centres, radii, np.array(lines)


@pytest.mark.parametrize("plate", [None, PLATE])
def test_svg_plate_layer(tmp_path, groove_example, plate):
    tool = Tool()
    out = tmp_path / "p.svg"
    write_svg(out, groove_example, tool, plate=plate)
    root = ET.parse(out).getroot()
    want = plate or Plate.fitted(groove_example.extent(), tool.width)
    group = plate_group(root)
    assert group.get("id") == f"layer{PLATE_LAYER}"
    assert group.get(f"{INKSCAPE}label") == f"{PLATE_LAYER} {PLATE_LAYER_NAME}"
    assert group.get(f"{INKSCAPE}groupmode") == "layer"
    assert group.get("fill") == "none" and group.get("stroke") == PLATE_COLOUR[1]
    assert PLATE_COLOUR[1] not in {rgb for _, rgb in LAYER_COLOURS}
    assert float(group.get("stroke-width", "nan")) <= 0.0254  # a laser driver's hairline
    (rect,) = group.findall(f"{SVG}rect")
    x, y, w, h = (float(rect.get(k, "nan")) for k in ("x", "y", "width", "height"))
    # the rectangle is the plate (SVG y = -plate y)
    assert (x, -y - h, x + w, -y) == (want.x0, want.y0, want.x1, want.y1)
    assert (w, h) == (want.width, want.height)
    # every groove point lies on the plate: the drawn paths' end points and dots,
    # and the arcs where they bulge past them, with half a groove round them
    drawn = []
    for g in root.findall(f"{SVG}g"):
        if g is group:
            continue
        for item in g:
            if item.tag == f"{SVG}circle":
                drawn.append([float(item.get("cx", "nan")), float(item.get("cy", "nan"))])
            else:
                for cmd in re.findall(r"[MAL][^MAL]+", item.get("d", "")):
                    drawn.append([float(v) for v in cmd[1:].split()[-2:]])
    points = np.array(drawn) * [1.0, -1.0]
    assert len(points) == len(groove_example.vertices)
    lo, hi = groove_example.extent() + np.array([[-1.0], [1.0]]) * 0.5 * tool.width
    assert np.all(points >= lo) and np.all(points <= hi)
    assert x <= lo[0] and x + w >= hi[0] and -y - h <= lo[1] and -y >= hi[1]
    # the page holds the plate
    vb = [float(v) for v in root.get("viewBox", "").split()]
    assert vb[0] <= x and vb[1] <= y and vb[0] + vb[2] >= x + w and vb[1] + vb[3] >= y + h
    # a crosshair and a circle at each mark
    centres, radii, lines = svg_marks(group)
    np.testing.assert_allclose(centres, expected_marks(want), atol=1e-4)
    np.testing.assert_allclose(radii, want.mark_radius)
    for k, c in enumerate(centres):
        # one line along x, then one along y, each 2 arms long and centred on the circle
        for (s, e), span in zip(lines[2 * k:2 * k + 2], ([2, 0], [0, 2]), strict=True):
            np.testing.assert_allclose(0.5 * (s + e), c, atol=1e-4)
            np.testing.assert_allclose(np.abs(e - s), np.array(span) * want.mark_arm, atol=1e-4)


def test_svg_layer_numbers_do_not_collide(tmp_path, groove_example):
    """The groove and dot layers keep their numbers; the plate's is past them all,
    also with more depth classes than PLATE_LAYER leaves room for."""
    vpype = pytest.importorskip("vpype")
    tool = Tool()
    g = Grooves.concatenate([groove_example] * 30)
    for depths, plate_number in ((None, PLATE_LAYER),
                                 (np.tile([0.08, 0.1, 0.1], 30), PLATE_LAYER),
                                 (0.01 + 0.002 * np.arange(g.n_paths), 2 * g.n_paths + 1)):
        out = tmp_path / "n.svg"
        write_svg(out, g, tool, depths=depths)
        plan = plan_layers(g, tool, depths)
        doc = vpype.read_multilayer_svg(str(out), quantization=0.01)
        numbers = [p.number for p in plan]
        assert sorted(doc.layers) == sorted([*numbers, plate_number])
        assert plate_number > max(numbers)
        for p in plan:
            assert len(doc.layers[p.number]) == len(p.paths)
        # outline, and per mark two crosshair lines and a circle
        assert len(doc.layers[plate_number]) == 1 + 5 * 3
        assert doc.layers[plate_number].property("vp_name") == \
            f"{plate_number} {PLATE_LAYER_NAME}"


# ---------------------------------------------------------------------------
# DXF


@pytest.mark.parametrize("plate", [None, PLATE])
def test_dxf_plate_layer(tmp_path, groove_example, plate):
    tool = Tool()
    out = tmp_path / "p.dxf"
    layers = write_dxf(out, groove_example, tool, plate=plate)
    want = plate or Plate.fitted(groove_example.extent(), tool.width)
    doc = ezdxf.readfile(out)
    auditor = doc.audit()
    assert not auditor.has_errors and not auditor.has_fixes, auditor.errors
    _, recovered = recover.readfile(out)
    assert not recovered.has_errors, recovered.errors
    layer = doc.layers.get(PLATE_LAYER_NAME)
    assert layer.color == PLATE_COLOUR[0]
    assert PLATE_COLOUR[0] not in {aci for aci, _ in LAYER_COLOURS}
    # the groove and dot layers are as before, the plate's entities on their own layer
    assert [p.name for p in layers] == ["GROOVES_D0.080_R0.250", "DOTS_D0.080_R0.250"]
    msp = doc.modelspace()
    assert len(msp.query(f'*[layer!="{PLATE_LAYER_NAME}"]')) == groove_example.n_paths
    (outline,) = msp.query(f'LWPOLYLINE[layer=="{PLATE_LAYER_NAME}"]')
    assert outline.closed and len(outline) == 4
    box = bbox.extents([outline])
    assert (box.extmin.x, box.extmin.y, box.extmax.x, box.extmax.y) == \
        (want.x0, want.y0, want.x1, want.y1)
    # the extents take in the plate, which holds the grooves
    assert tuple(doc.header["$EXTMIN"])[:2] == (want.x0, want.y0)
    assert tuple(doc.header["$EXTMAX"])[:2] == (want.x1, want.y1)
    circles = msp.query(f'CIRCLE[layer=="{PLATE_LAYER_NAME}"]')
    centres = np.array([[c.dxf.center.x, c.dxf.center.y] for c in circles])
    np.testing.assert_allclose(centres, expected_marks(want), atol=1e-12)
    assert {c.dxf.radius for c in circles} == {want.mark_radius}
    # each mark's two lines cross at its centre, one along x and one along y
    lines = msp.query(f'LINE[layer=="{PLATE_LAYER_NAME}"]')
    assert len(lines) == 2 * len(centres)
    for k, c in enumerate(centres):
        for line, axis in zip(lines[2 * k:2 * k + 2], (0, 1), strict=True):
            s, e = np.array(line.dxf.start)[:2], np.array(line.dxf.end)[:2]
            np.testing.assert_allclose(0.5 * (s + e), c, atol=1e-12)
            step = np.zeros(2)
            step[axis] = want.mark_arm
            np.testing.assert_allclose(e - s, 2 * step, atol=1e-12)
    # the corner marks sit in the corners, MARK_INSET from both edges
    corners = want.corners()
    assert np.allclose(np.abs(centres[:4] - corners), MARK_INSET * want.mark_scale)


def test_dxf_is_the_same_on_every_run(tmp_path, groove_example):
    one, two = tmp_path / "1.dxf", tmp_path / "2.dxf"
    write_dxf(one, groove_example, Tool(), plate=PLATE)
    write_dxf(two, groove_example, Tool(), plate=PLATE)
    assert one.read_bytes() == two.read_bytes()


# ---------------------------------------------------------------------------
# G-code

_PLATE_LINE = re.compile(r"plate: (\S+) x (\S+) (mm|in)(?:, (\S+) (?:mm|in) thick)?, "
                         r"corners X(\S+) Y(\S+) to X(\S+) Y(\S+)")
_XY = re.compile(r"X(-?[\d.]+) Y(-?[\d.]+)")


def plate_block(path: Path) -> dict[str, object]:
    """The plate block of a program's header: size, corners, thickness, marks."""
    lines = path.read_text(encoding="ascii").splitlines()
    texts = {}
    for line in lines:
        if line.startswith("("):
            assert line.endswith(")") and "(" not in line[1:-1] and ")" not in line[1:-1]
            text = line[1:-1]
        elif line.startswith(";"):
            text = line[1:].strip()
        else:
            continue
        key = text.partition(":")[0]
        if key.startswith("plate"):
            texts[key] = text
    assert sorted(texts) == ["plate", "plate marks", "plate marks at", "plate zero"]
    m = _PLATE_LINE.fullmatch(texts["plate"])
    assert m, texts["plate"]
    w, h, unit, thick, x0, y0, x1, y1 = m.groups()
    per = 25.4 if unit == "in" else 1.0
    marks = np.array(_XY.findall(texts["plate marks at"]), dtype=float) * per
    return {"size": (float(w) * per, float(h) * per),
            "corners": np.array([[x0, y0], [x1, y1]], dtype=float) * per,
            "thickness": None if thick is None else float(thick) * per,
            "marks": marks, "zero": texts["plate zero"], "unit": unit}


@pytest.mark.parametrize("dialect, units", [("grbl", "mm"), ("linuxcnc", "inch"),
                                            ("marlin", "mm")])
def test_gcode_plate_block(tmp_path, groove_example, dialect, units):
    out = tmp_path / "p.ngc"
    options = GcodeOptions(dialect=dialect, units=units)  # type: ignore[arg-type]
    write_gcode(out, groove_example, Tool(), Machining(), options=options, plate=PLATE)
    block = plate_block(out)
    tol = 1e-6 * 25.4 if units == "inch" else 0.0
    assert block["size"] == pytest.approx((PLATE.width, PLATE.height), abs=2 * tol)
    np.testing.assert_allclose(block["corners"], PLATE.box, atol=tol)
    assert block["thickness"] == pytest.approx(PLATE.thickness, abs=tol)
    np.testing.assert_allclose(block["marks"], expected_marks(PLATE), atol=tol)
    zero = str(block["zero"])
    ll = _XY.findall(zero)[-1]
    np.testing.assert_allclose(np.array(ll, dtype=float) * (25.4 if units == "inch" else 1),
                               PLATE.corners()[0], atol=tol)
    assert ("G10 L20 P1" in zero and "Z0 on the top surface" in zero) if dialect != "marlin" \
        else ("G92" in zero and "focus" in zero)
    # comments only: the lines that do something are those of a program without a plate
    bare = tmp_path / "bare.ngc"
    write_gcode(bare, groove_example, Tool(), Machining(), options=options)

    def words(path: Path) -> list[str]:
        return [ln for ln in path.read_text().splitlines() if not ln.startswith(("(", ";"))]

    assert words(out) == words(bare)


def test_gcode_without_a_plate_names_the_fitted_one(tmp_path, groove_example):
    out = tmp_path / "p.ngc"
    tool = Tool()
    write_gcode(out, groove_example, tool, Machining())
    block = plate_block(out)
    np.testing.assert_array_equal(block["corners"], fit_plate(groove_example.extent(),
                                                              tool.width))
    assert block["thickness"] is None


@needs_rs274
def test_linuxcnc_reads_the_plate_block(tmp_path, groove_example):
    out = tmp_path / "p.ngc"
    tool, machining = Tool(), Machining()
    options = GcodeOptions(dialect="linuxcnc")
    write_gcode(out, groove_example, tool, machining, options=options, plate=PLATE)
    canon = run_rs274(out)
    comments = [args for name, args in canon if name == "COMMENT"]
    assert sum(c.startswith('"plate') for c in comments) == 4
    check_canon(canon, groove_example, tool, machining, options)


# ---------------------------------------------------------------------------
# a design's files


@pytest.fixture(scope="module")
def designed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from specholo_cli.cli import main

    out = tmp_path_factory.mktemp("plate") / "d"
    code = main(["design", str(BUNNY), "--out", str(out), "--stipples", "8", "--size", "30",
                 "--formats", "gcode,svg,dxf", "--plate-width", "120", "--plate-height", "100",
                 "--stock-thickness", "4", "--dialect", "linuxcnc"])
    assert code == 0
    return out


def test_a_designs_files_name_its_plate(designed):
    """The G-code's block, the SVG's rectangle and the DXF's outline are the
    plate of --plate-width/--plate-height, the check line's plate less half a groove
    each side, and the grooves lie on it."""
    import json

    info = json.loads((designed / "hologram.json").read_text())
    plate = np.array(info["plate"]["plate_mm"])
    np.testing.assert_array_equal(plate, [[-60, -50], [60, 50]])
    block = plate_block(designed / "hologram.gcode")
    assert block["size"] == (120.0, 100.0) and block["thickness"] == 4.0
    np.testing.assert_array_equal(block["corners"], plate)
    limits = limits_from_header(designed / "hologram.gcode")
    assert limits is not None and limits.stock.thickness == block["thickness"]
    s = limits.stock
    check = np.array([[s.x0, s.y0], [s.x1, s.y1]])
    # the check's stock is where the tool centre may go: the plate less half a
    # groove each side (corners rounded outward to 0.1 um)
    half = check[0] - plate[0]
    assert np.all(half > 0) and np.all(half < 0.5)
    np.testing.assert_allclose(check[1] + half, plate[1], atol=2e-4)
    assert np.allclose(half, half[0], atol=2e-4)

    rect = plate_group(ET.parse(designed / "hologram.svg").getroot()).find(f"{SVG}rect")
    assert rect is not None
    x, y, w, h = (float(rect.get(k, "nan")) for k in ("x", "y", "width", "height"))
    np.testing.assert_array_equal([[x, -y - h], [x + w, -y]], plate)

    doc = ezdxf.readfile(designed / "hologram.dxf")
    (outline,) = doc.modelspace().query(f'LWPOLYLINE[layer=="{PLATE_LAYER_NAME}"]')
    box = bbox.extents([outline])
    np.testing.assert_array_equal([[box.extmin.x, box.extmin.y], [box.extmax.x, box.extmax.y]],
                                  plate)

    grooves = Grooves.load(designed / "grooves.npz")
    lo, hi = grooves.extent()
    assert np.all(lo > plate[0]) and np.all(hi < plate[1])


@needs_rs274
def test_a_designs_program_runs_in_linuxcnc(designed):
    canon = run_rs274(designed / "hologram.gcode")
    assert sum(args.startswith('"plate') for name, args in canon if name == "COMMENT") == 4

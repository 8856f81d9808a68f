"""DXF export: a valid drawing in mm whose polylines carry the grooves to the written precision."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import ezdxf
import numpy as np
import pytest
from ezdxf.colors import aci2rgb
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from specholo.errors import SpecholoError
from specholo.fabrication.drawings import dxf
from specholo.fabrication.drawings.dxf import write_dxf
from specholo.fabrication.drawings.svg import LAYER_COLOURS, PLATE_LAYER_NAME, plan_layers
from specholo.fabrication.exporting import is_straight
from specholo.setup import Tool
from specholo.toolpaths.grooves import Grooves

GOLDEN = Path(__file__).resolve().parent / "golden"
_SYSTEM_LAYERS = {"0", "Defpoints"}
# half the last written decimal, and the rounding of the text read back
COORD_TOL = 0.5e-9 + 1e-13
BULGE_TOL = 0.5e-12 + 1e-15


def drawing_data(path: Path) -> dict[str, Any]:
    """What a DXF drawing holds, as plain data: the header values that matter,
    the layers and every entity (ezdxf's handles, dates and GUIDs left out)."""
    doc = ezdxf.readfile(path)
    auditor = doc.audit()
    assert not auditor.has_errors and not auditor.has_fixes, auditor.errors
    header = {k: doc.header[k] for k in ("$INSUNITS", "$MEASUREMENT")}
    header.update({k: tuple(map(float, doc.header[k])) for k in ("$EXTMIN", "$EXTMAX")})
    layers = [(layer.dxf.name, layer.color, layer.description) for layer in doc.layers
              if layer.dxf.name not in _SYSTEM_LAYERS | {PLATE_LAYER_NAME}]
    entities: list[tuple[str, str, list[Any]]] = []
    plate: list[tuple[str, list[Any]]] = []
    for e in doc.modelspace():
        if e.dxf.layer == PLATE_LAYER_NAME:
            plate.append(plate_entity(e))
            continue
        if e.dxftype() == "LWPOLYLINE":
            assert not e.closed and e.dxf.const_width == 0
            data = [tuple(map(float, p)) for p in e.get_points("xyb")]
        elif e.dxftype() == "CIRCLE":
            data = [tuple(map(float, e.dxf.center)), float(e.dxf.radius)]
        else:
            raise AssertionError(f"unexpected entity {e.dxftype()}")
        entities.append((e.dxftype(), e.dxf.layer, data))
    (plate_layer,) = [(layer.color, layer.description) for layer in doc.layers
                      if layer.dxf.name == PLATE_LAYER_NAME]
    return {"version": doc.dxfversion, "header": header, "layers": layers,
            "entities": entities, "plate_layer": plate_layer, "plate": plate}


def plate_entity(e: Any) -> tuple[str, list[Any]]:
    """An entity of the plate's layer as plain data: the closed outline's corners,
    a line's ends or a circle's centre and radius."""
    if e.dxftype() == "LWPOLYLINE":
        assert e.closed and e.dxf.const_width == 0
        return "LWPOLYLINE", [tuple(map(float, p)) for p in e.get_points("xyb")]
    if e.dxftype() == "LINE":
        return "LINE", [tuple(map(float, e.dxf.start)), tuple(map(float, e.dxf.end))]
    assert e.dxftype() == "CIRCLE", e.dxftype()
    return "CIRCLE", [tuple(map(float, e.dxf.center)), float(e.dxf.radius)]


def check_drawing(path: Path, g: Grooves, tool: Tool, depths: np.ndarray | None = None) -> None:
    """Every path is in its layer, vertices and bulges as designed to the written precision
    (straight-written arcs as bulge 0), dots as circles of the dimple's size."""
    data = drawing_data(path)
    assert data["header"]["$INSUNITS"] == 4 and data["header"]["$MEASUREMENT"] == 1
    plan = plan_layers(g, tool, depths)
    assert [name for name, _, _ in data["layers"]] == [p.name for p in plan]
    assert [aci for _, aci, _ in data["layers"]] == [p.aci for p in plan]
    bulge = g.bulges.astype(float).copy()
    last = np.zeros(len(bulge), dtype=bool)
    last[g.offsets[1:] - 1] = True
    bulge[~last] = np.where(is_straight(g.segments()), 0.0, bulge[~last])
    bulge[last] = 0.0
    entities = iter(data["entities"])
    for p in plan:
        for j in p.paths:
            kind, layer, got = next(entities)
            assert layer == p.name
            lo, hi = g.offsets[j], g.offsets[j + 1]
            if p.dots:
                assert kind == "CIRCLE"
                (cx, cy, cz), radius = got
                np.testing.assert_array_less(np.abs([cx, cy] - g.vertices[lo]), COORD_TOL)
                assert cz == 0.0 and radius == 0.5 * p.width
            else:
                assert kind == "LWPOLYLINE"
                got = np.array(got)
                assert got.shape == (hi - lo, 3)
                # within the written precision: 9 decimals (mm), 12 for bulges
                np.testing.assert_array_less(np.abs(got[:, :2] - g.vertices[lo:hi]),
                                             COORD_TOL)
                np.testing.assert_array_less(np.abs(got[:, 2] - bulge[lo:hi]), BULGE_TOL)
    assert next(entities, None) is None


def test_golden(tmp_path, groove_example, golden, request, monkeypatch):
    """The example's drawing matches the golden DXF entity for entity.

    The golden file is a real DXF (written with ezdxf's fixed dates and GUIDs so
    regenerating it gives the same bytes), but it is compared by content: the
    bytes also hold ezdxf's version, handles and boilerplate tables, which
    change with ezdxf and say nothing about the grooves.
    """
    monkeypatch.setattr(ezdxf.options, "write_fixed_meta_data_for_testing", True)
    out = tmp_path / "example.dxf"
    write_dxf(out, groove_example, Tool())
    if request.config.getoption("--regen-golden"):
        golden(out, "example.dxf")
        return
    expected = GOLDEN / "example.dxf"
    assert expected.exists(), f"missing golden file {expected}; run pytest --regen-golden"
    assert drawing_data(out) == drawing_data(expected), (
        "example.dxf differs from the golden one; if the change is intended, "
        "run pytest --regen-golden and review the diff")


def test_example(tmp_path, groove_example):
    tool = Tool()
    out = tmp_path / "x.dxf"
    layers = write_dxf(out, groove_example, tool)
    assert [(p.name, p.paths.tolist()) for p in layers] == [
        ("GROOVES_D0.080_R0.250", [0, 2]), ("DOTS_D0.080_R0.250", [1])]
    check_drawing(out, groove_example, tool)
    data = drawing_data(out)
    assert data["version"] == "AC1024"  # R2010
    (_, _, grooves), (_, _, dots) = data["layers"]
    assert "depth 0.0800 mm" in grooves and "ball radius 0.250 mm" in grooves
    assert dots.startswith("specholo dots")
    kinds = [(kind, layer) for kind, layer, _ in data["entities"]]
    assert kinds == [("LWPOLYLINE", "GROOVES_D0.080_R0.250")] * 2 + [
        ("CIRCLE", "DOTS_D0.080_R0.250")]
    # extents: the fitted plate (51 x 31 mm, see test_svg.test_document), which
    # holds the grooves from the dot's rim at (-5, -5) to the segment's end (20, 10)
    assert data["header"]["$EXTMIN"] == (-25.5, -15.5, 0.0)
    assert data["header"]["$EXTMAX"] == (25.5, 15.5, 0.0)
    # the 270-degree arc and the half circle keep their bulges to 12 decimals
    assert [b for _, _, b in data["entities"][1][2]] == [
        round(np.tan(np.radians(270) / 4), 12), -1.0, 0.0]


def test_depth_classes(tmp_path, groove_example):
    tool = Tool()
    depths = np.array([0.1, 0.05, 0.05])
    out = tmp_path / "d.dxf"
    write_dxf(out, groove_example, tool, depths=depths)
    check_drawing(out, groove_example, tool, depths)
    data = drawing_data(out)
    assert [name for name, _, _ in data["layers"]] == [
        "GROOVES_D0.050_R0.250", "GROOVES_D0.100_R0.250", "DOTS_D0.050_R0.250"]
    assert len({aci for _, aci, _ in data["layers"]}) == 3
    # the dot of the shallow class is as wide as a 0.05 mm deep dimple
    (_, _, (_, radius)), = [e for e in data["entities"] if e[0] == "CIRCLE"]
    assert radius == 0.5 * Tool(depth=0.05).width


@settings(max_examples=100, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_round_trip(tmp_path, grooves_strategy, data):
    g = data.draw(grooves_strategy(max_bulge=3.0))
    depths = None
    if data.draw(st.booleans()):
        choices = st.sampled_from([0.02, 0.08, 0.0803, 0.25])
        depths = np.array([data.draw(choices) for _ in range(g.n_paths)])
    out = tmp_path / "r.dxf"
    tool = Tool()
    write_dxf(out, g, tool, depths=depths)
    check_drawing(out, g, tool, depths)


def test_chunks(tmp_path, groove_example, monkeypatch):
    """Written a few paths at a time, the drawing is the same byte for byte."""
    g = Grooves.concatenate([groove_example] * 5)
    depths = np.tile([0.1, 0.05, 0.05], 5)
    whole = tmp_path / "whole.dxf"
    write_dxf(whole, g, Tool(), depths=depths)
    monkeypatch.setattr(dxf, "_CHUNK_ROWS", 3)
    parts = tmp_path / "parts.dxf"
    write_dxf(parts, g, Tool(), depths=depths)
    assert parts.read_bytes() == whole.read_bytes()
    from specholo.fabrication import exporting

    monkeypatch.setattr(exporting, "WRITER_THREADS", 1)  # and made in one thread
    one = tmp_path / "one.dxf"
    write_dxf(one, g, Tool(), depths=depths)
    assert one.read_bytes() == whole.read_bytes()
    check_drawing(parts, g, Tool(), depths)
    # handles are unique and below $HANDSEED
    doc = ezdxf.readfile(parts)
    handles = [int(e.dxf.handle, 16) for e in doc.entitydb.values()]
    assert len(set(handles)) == len(handles)
    assert max(handles) < int(doc.header["$HANDSEED"], 16)


def test_near_full_circle(tmp_path):
    """A bulge too large for 12 decimals keeps its sweep (within 1e-12 rad)."""
    bulge = 3e7
    g = Grooves(np.array([[0.0, 0.0], [1e-3, 0.0]]), np.array([bulge, 0.0]), np.array([0, 2]),
                np.array([0]))
    out = tmp_path / "c.dxf"
    write_dxf(out, g, Tool())
    (_, _, points), = drawing_data(out)["entities"]
    got = points[0][2]
    assert abs(4 * np.arctan(got) - 4 * np.arctan(bulge)) < 1e-12


def test_empty(tmp_path):
    out = tmp_path / "empty.dxf"
    assert write_dxf(out, Grooves.empty(), Tool()) == []
    data = drawing_data(out)
    assert data["layers"] == [] and data["entities"] == []
    assert data["header"]["$INSUNITS"] == 4


def test_layer_colours_are_aci():
    """The SVG colours of the layers are the DXF colours of the same layers."""
    for aci, rgb in LAYER_COLOURS:
        want = (0, 0, 0) if aci == 7 else tuple(aci2rgb(aci))  # ACI 7 prints black
        assert rgb == "#{:02X}{:02X}{:02X}".format(*want)


@pytest.mark.parametrize("vertices, bulges, match", [
    ([[np.nan, 0.0], [1.0, 0.0]], [0.0, 0.0], "non-finite"),
    ([[0.0, 0.0], [1.0, 0.0]], [np.inf, 0.0], "non-finite"),
])
def test_rejects_bad_grooves(tmp_path, vertices, bulges, match):
    bad = Grooves(np.array(vertices), np.array(bulges), np.array([0, 2]), np.array([0]))
    with pytest.raises(SpecholoError, match=match):
        write_dxf(tmp_path / "x.dxf", bad, Tool())
    assert list(tmp_path.iterdir()) == []


def test_rejects_bad_depths(tmp_path, groove_example):
    with pytest.raises(SpecholoError, match="one depth per path"):
        write_dxf(tmp_path / "x.dxf", groove_example, Tool(), depths=np.array([0.08]))
    with pytest.raises(SpecholoError, match=r"depth of path 2 .* got 0.5"):
        write_dxf(tmp_path / "x.dxf", groove_example, Tool(), depths=np.array([0.08, 0.08, 0.5]))
    assert list(tmp_path.iterdir()) == []

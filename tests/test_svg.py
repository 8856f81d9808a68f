"""SVG export: valid XML in mm whose paths draw exactly the grooves, y flipped."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from specholo.errors import SpecholoError
from specholo.fabrication.drawings.svg import (
    LAYER_COLOURS,
    PLATE_LAYER,
    PLATE_LAYER_NAME,
    arc_bounds,
    plan_layers,
    write_svg,
)
from specholo.fabrication.exporting import is_straight
from specholo.setup import Tool
from specholo.toolpaths.grooves import Grooves

SVG = "{http://www.w3.org/2000/svg}"
INKSCAPE = "{http://www.inkscape.org/namespaces/inkscape}"
_TOKEN = re.compile(r"[MAL]|[-+]?(?:\d+\.?\d*|\.\d+)")


def parse_path(d: str) -> list[tuple[str, list[float]]]:
    """Commands of an SVG path made of ``M``, ``A`` and ``L`` with explicit letters."""
    out: list[tuple[str, list[float]]] = []
    assert _TOKEN.sub("", d).strip() == "", d
    for tok in _TOKEN.findall(d):
        if tok in "MAL":
            out.append((tok, []))
        else:
            out[-1][1].append(float(tok))
    arity = {"M": 2, "L": 2, "A": 7}
    assert all(len(args) == arity[c] for c, args in out), d
    return out


def svg_arc_midpoint(p0: np.ndarray, r: float, large: int, sweep: int,
                     p1: np.ndarray) -> np.ndarray:
    """Midpoint of an SVG circular arc, by the endpoint-to-centre conversion of SVG 1.1 F.6.5."""
    h = 0.5 * (p0 - p1)
    d2 = float(h @ h)
    r = max(r, np.sqrt(d2))  # F.6.6: radii too small are scaled up
    coef = np.sqrt(max(0.0, (r * r - d2) / d2))
    if large == sweep:
        coef = -coef
    c = coef * np.array([h[1], -h[0]]) + 0.5 * (p0 + p1)
    a0 = np.arctan2(*(p0 - c)[::-1])
    delta = np.mod(np.arctan2(*(p1 - c)[::-1]) - a0, 2 * np.pi)
    if not sweep and delta > 0:
        delta -= 2 * np.pi
    a = a0 + 0.5 * delta
    return c + r * np.array([np.cos(a), np.sin(a)])


def read(path: Path) -> ET.Element:
    root = ET.parse(path).getroot()
    assert root.tag == f"{SVG}svg"
    return root


def all_layers(root: ET.Element) -> list[ET.Element]:
    """The top-level groups, all of them Inkscape layers."""
    groups = root.findall(f"{SVG}g")
    assert all(g.get(f"{INKSCAPE}groupmode") == "layer" for g in groups)
    assert len(root) == len(groups)  # nothing outside the layers
    return groups


def is_plate(group: ET.Element) -> bool:
    return group.get(f"{INKSCAPE}label", "").endswith(f" {PLATE_LAYER_NAME}")


def layers(root: ET.Element) -> list[ET.Element]:
    """The groove and dot layers, in order; the plate's layer is the last one."""
    groups = all_layers(root)
    assert [is_plate(g) for g in groups] == [False] * (len(groups) - 1) + [True]
    return groups[:-1]


def plate_layer(root: ET.Element) -> ET.Element:
    return all_layers(root)[-1]


def test_golden(tmp_path, groove_example, golden):
    out = tmp_path / "example.svg"
    write_svg(out, groove_example, Tool())
    golden(out, "example.svg")


def test_document(tmp_path, groove_example):
    tool = Tool()
    out = tmp_path / "x.svg"
    write_svg(out, groove_example, tool, margin=5.0)
    root = read(out)
    w, h = root.get("width"), root.get("height")
    assert w is not None and h is not None
    assert w.endswith("mm") and h.endswith("mm")
    vb = [float(v) for v in root.get("viewBox", "").split()]
    # 1 user unit = 1 mm
    assert np.allclose(vb[2:], [float(w[:-2]), float(h[:-2])])
    # grooves span x in [-5, 20] and y in [-5, 10] (the 270-degree arc stays inside
    # that): the fitted plate, centred, whole mm, 5 mm beyond the grooves' edges, is
    # ceil(2 * 20 + width + 10) x ceil(2 * 10 + width + 10) = 51 x 31 mm and holds the
    # grooves' 5 mm border, so the page is the plate
    assert np.allclose(vb, [-25.5, -15.5, 51, 31], atol=1e-4)
    grooves, dots = layers(root)
    assert grooves.get("id") == "layer1" and dots.get("id") == "layer2"
    assert grooves.get(f"{INKSCAPE}label") == "1 GROOVES_D0.080_R0.250"
    assert dots.get(f"{INKSCAPE}label") == "2 DOTS_D0.080_R0.250"
    assert grooves.get("fill") == "none" and grooves.get("stroke") == "#000000"
    assert float(grooves.get("stroke-width", "0")) == round(tool.width, 4)
    assert dots.get("fill") == "#FF0000" and dots.get("stroke") == "none"
    paths = grooves.findall(f"{SVG}path")
    assert len(paths) == 2 and len(grooves) == 2
    assert all(p.get("fill") is None for p in paths)  # inherit fill="none"
    (c,) = dots
    assert c.tag == f"{SVG}circle"
    assert (float(c.get("cx", "nan")), float(c.get("cy", "nan"))) == (-5.0, 5.0)  # y flipped
    assert float(c.get("r", "nan")) == round(0.5 * tool.width, 4)
    assert c.get("fill") is None  # inherits the layer's colour
    assert [cmd for cmd, _ in parse_path(paths[0].get("d", ""))] == ["M", "A", "A", "L"]
    # 270 degrees counter-clockwise on the plate, then a clockwise semicircle
    (_, _), (_, a1), (_, a2) = parse_path(paths[1].get("d", ""))
    assert a1[3:5] == [1, 0] and a2[3:5] == [0, 1]


def test_empty(tmp_path):
    out = tmp_path / "empty.svg"
    write_svg(out, Grooves.empty(), Tool())
    assert layers(read(out)) == []


def check_drawing(path: Path, g: Grooves, depths: np.ndarray | None = None) -> None:
    """Every groove is drawn where it is, y flipped, in its layer: end points, arc
    midpoints, dots."""
    tool = Tool()
    root = read(path)
    plan = plan_layers(g, tool, depths)
    groups = layers(root)
    assert [grp.get("id") for grp in groups] == [f"layer{p.number}" for p in plan]
    segs = g.segments()
    straight = is_straight(segs)
    with np.errstate(all="ignore"):  # subnormal bulges of straight segments overflow
        centre, radius, start, sweep = segs.geometry()
    flip = np.array([1.0, -1.0])
    vb = np.array([float(v) for v in root.get("viewBox", "").split()])
    lo, hi = vb[:2], vb[:2] + vb[2:]
    drawn = np.zeros(g.n_paths, dtype=int)
    for spec, group in zip(plan, groups, strict=True):
        assert group.get(f"{INKSCAPE}label") == f"{spec.number} {spec.name}"
        items = list(group)
        assert len(items) == len(spec.paths)
        if spec.dots:
            assert float(group.get("stroke-width", "0")) == 0.0
        else:
            assert float(group.get("stroke-width", "nan")) == round(spec.width, 4)
        for j, item in zip(spec.paths, items, strict=True):
            drawn[j] += 1
            v = g.vertices[g.offsets[j]:g.offsets[j + 1]] * flip
            if spec.dots:
                assert len(v) == 1 and item.tag == f"{SVG}circle"
                xy = np.array([float(item.get("cx", "nan")), float(item.get("cy", "nan"))])
                assert np.allclose(xy, v[0], atol=1e-4)
                assert float(item.get("r", "nan")) == round(0.5 * spec.width, 4)
                continue
            assert item.tag == f"{SVG}path"
            cmds = parse_path(item.get("d", ""))
            assert len(cmds) == len(v) > 1 and cmds[0][0] == "M"
            pen = np.array(cmds[0][1])
            assert np.allclose(pen, v[0], atol=1e-4)
            s = g.offsets[j] - j  # arcs of the paths before j
            for i, (cmd, args) in enumerate(cmds[1:], start=1):
                end = np.array(args[-2:])
                assert np.allclose(end, v[i], atol=1e-4)
                if straight[s]:
                    assert cmd == "L"
                else:
                    assert cmd == "A" and args[0] == args[1] and args[2] == 0
                    mid = svg_arc_midpoint(pen, args[0], int(args[3]), int(args[4]), end)
                    a = start[s] + 0.5 * sweep[s]
                    want = (centre[s] + radius[s] * np.array([np.cos(a), np.sin(a)])) * flip
                    assert np.allclose(mid, want, atol=1e-3), (mid, want)
                    assert np.all(mid >= lo) and np.all(mid <= hi)
                pen = end
                s += 1
            assert np.all(v >= lo) and np.all(v <= hi)
    assert np.all(drawn == 1)  # every path in exactly one layer


def test_example_drawing(tmp_path, groove_example):
    out = tmp_path / "x.svg"
    write_svg(out, groove_example, Tool())
    check_drawing(out, groove_example)


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_drawing(tmp_path, grooves_strategy, data):
    g = data.draw(grooves_strategy(max_bulge=3.0))
    depths = None
    if data.draw(st.booleans()):
        # a few depth classes, some closer than the 1 um of the layer names
        choices = st.sampled_from([0.05, 0.08, 0.0802, 0.1, 0.25])
        depths = np.array([data.draw(choices) for _ in range(g.n_paths)])
    out = tmp_path / "r.svg"
    write_svg(out, g, Tool(), margin=data.draw(st.floats(0.0, 10.0)), depths=depths)
    check_drawing(out, g, depths)


def test_depth_layers(tmp_path, groove_example):
    tool = Tool()
    depths = np.array([0.1, 0.1, 0.05])  # the dot (path 1) shares the first groove's depth
    out = tmp_path / "d.svg"
    write_svg(out, groove_example, tool, depths=depths)
    check_drawing(out, groove_example, depths)
    plan = plan_layers(groove_example, tool, depths)
    # grooves of classes 0.05 and 0.1 are layers 1 and 2; dots of class 0.1 are 4
    assert [(p.number, p.name, p.paths.tolist()) for p in plan] == [
        (1, "GROOVES_D0.050_R0.250", [2]),
        (2, "GROOVES_D0.100_R0.250", [0]),
        (4, "DOTS_D0.100_R0.250", [1]),
    ]
    assert np.allclose([p.width for p in plan],
                       [Tool(depth=0.05).width, Tool(depth=0.1).width, Tool(depth=0.1).width])
    assert len({p.colour for p in plan}) == len(plan)
    # depths 0.3 um apart share a class; its depth is their mean
    two = Grooves(groove_example.vertices[:4], groove_example.bulges[:4], np.array([0, 2, 4]),
                  np.array([1, 2]))
    (one,) = plan_layers(two, tool, np.array([0.0801, 0.0804]))
    assert one.name == "GROOVES_D0.080_R0.250" and np.isclose(one.depth, 0.08025)


def test_layer_colours_distinct():
    assert len({aci for aci, _ in LAYER_COLOURS}) == len(LAYER_COLOURS)
    assert len({rgb for _, rgb in LAYER_COLOURS}) == len(LAYER_COLOURS)


@pytest.mark.parametrize("depths, match", [
    (np.array([0.08, 0.08]), "one depth per path"),
    (np.array([0.08, 0.0, 0.08]), "depth of path 1"),
    (np.array([0.08, 0.08, 0.3]), "depth of path 2"),
    (np.array([np.nan, 0.08, 0.08]), "depth of path 0"),
])
def test_rejects_bad_depths(tmp_path, groove_example, depths, match):
    with pytest.raises(SpecholoError, match=match):
        write_svg(tmp_path / "x.svg", groove_example, Tool(), depths=depths)
    assert not (tmp_path / "x.svg").exists()


def subset(g: Grooves, paths: np.ndarray) -> Grooves:
    """The given paths of some grooves."""
    return Grooves.concatenate([
        Grooves(g.vertices[g.offsets[j]:g.offsets[j + 1]], g.bulges[g.offsets[j]:g.offsets[j + 1]],
                np.array([0, g.path_sizes[j]]), np.array([g.stipple[j]]))
        for j in paths])


def test_vpype_reads_layers(tmp_path, groove_example):
    """vpype (as plotter pipelines use it) finds the layers by number, with the
    geometry where the grooves are."""
    vpype = pytest.importorskip("vpype")
    tool = Tool()
    depths = np.array([0.08, 0.1, 0.1])
    out = tmp_path / "v.svg"
    write_svg(out, groove_example, tool, depths=depths)
    doc = vpype.read_multilayer_svg(str(out), quantization=0.01)
    plan = plan_layers(groove_example, tool, depths)
    assert sorted(doc.layers) == [p.number for p in plan] + [PLATE_LAYER] == [1, 2, 4, 99]
    assert doc.layers[PLATE_LAYER].property("vp_name") == f"{PLATE_LAYER} {PLATE_LAYER_NAME}"
    root = read(out)
    x0, y0 = (float(v) for v in root.get("viewBox", "").split()[:2])
    px = 96.0 / 25.4  # vpype works in CSS pixels
    for p in plan:
        lc = doc.layers[p.number]
        assert lc.property("vp_name") == f"{p.number} {p.name}"
        assert len(lc) == len(p.paths)
        sub = subset(groove_example, p.paths)
        if p.dots:
            r = 0.5 * p.width
            box = np.stack([sub.vertices.min(axis=0) - r, sub.vertices.max(axis=0) + r])
        else:
            box = arc_bounds(sub.segments())
        # plate (x, y) is SVG (x, -y), offset by the viewBox origin
        want = np.array([box[0, 0] - x0, -box[1, 1] - y0, box[1, 0] - x0, -box[0, 1] - y0])
        assert np.allclose(np.array(lc.bounds()) / px, want, atol=2e-3), (p.name, lc.bounds())


def test_vpype_cli(tmp_path, groove_example):
    """The ``vpype read`` command line sees both layers."""
    pytest.importorskip("vpype")
    cli = pytest.importorskip("vpype_cli")
    out = tmp_path / "v.svg"
    write_svg(out, groove_example, Tool())
    from click.testing import CliRunner

    result = CliRunner().invoke(cli.cli, ["read", str(out), "stat"])
    assert result.exit_code == 0, result.output
    assert "Layer 1" in result.output and "Layer 2" in result.output
    assert "Layer 3" not in result.output


def test_arc_bounds():
    # a counter-clockwise half circle from (1, 0) to (-1, 0) bulges up to y = 1
    g = Grooves(np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([1.0, 0.0]), np.array([0, 2]),
                np.array([0]))
    np.testing.assert_allclose(arc_bounds(g.segments()), [[-1, 0], [1, 1]], atol=1e-12)


def test_rejects_bad_grooves(tmp_path):
    bad = Grooves(np.array([[np.inf, 0.0], [1.0, 0.0]]), np.zeros(2), np.array([0, 2]),
                  np.array([0]))
    with pytest.raises(SpecholoError):
        write_svg(tmp_path / "x.svg", bad, Tool())
    assert not (tmp_path / "x.svg").exists()


def test_chunks_change_nothing(tmp_path, groove_example, monkeypatch):
    """Written a few paths at a time, the drawing is the same byte for byte."""
    from specholo.fabrication.drawings import svg

    g = Grooves.concatenate([groove_example] * 7)
    depths = np.tile([0.1, 0.05, 0.05], 7)
    whole = tmp_path / "whole.svg"
    write_svg(whole, g, Tool(), depths=depths)
    monkeypatch.setattr(svg, "_CHUNK_ROWS", 3)
    parts = tmp_path / "parts.svg"
    write_svg(parts, g, Tool(), depths=depths)
    assert parts.read_bytes() == whole.read_bytes()
    from specholo.fabrication import exporting

    monkeypatch.setattr(exporting, "WRITER_THREADS", 1)  # and made in one thread
    one = tmp_path / "one.svg"
    write_svg(one, g, Tool(), depths=depths)
    assert one.read_bytes() == whole.read_bytes()

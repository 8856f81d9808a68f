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
from specholo.fabrication.gcode import is_straight
from specholo.fabrication.svg import arc_bounds, write_svg
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


def layer(root: ET.Element) -> ET.Element:
    g = root.find(f"{SVG}g")
    assert g is not None
    return g


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
    # grooves span x in [-5, 20] and y in [-5, 10]; the 270-degree arc stays inside that
    pad = 5.0 + 0.5 * tool.width
    assert np.allclose(vb, [-5 - pad, -10 - pad, 25 + 2 * pad, 15 + 2 * pad], atol=1e-4)
    g = layer(root)
    assert g.get("id") == "grooves"
    assert g.get(f"{INKSCAPE}groupmode") == "layer"
    assert g.get(f"{INKSCAPE}label") == "grooves"
    assert g.get("fill") == "none" and g.get("stroke") == "#000000"
    assert float(g.get("stroke-width", "0")) == round(tool.width, 4)
    paths = g.findall(f"{SVG}path")
    circles = g.findall(f"{SVG}circle")
    assert len(paths) == 2 and len(circles) == 1
    assert all(p.get("fill") is None for p in paths)  # inherit fill="none"
    c = circles[0]
    assert (float(c.get("cx", "nan")), float(c.get("cy", "nan"))) == (-5.0, 5.0)  # y flipped
    assert float(c.get("r", "nan")) == round(0.5 * tool.width, 4)
    assert c.get("fill") == "#000000"
    assert [cmd for cmd, _ in parse_path(paths[0].get("d", ""))] == ["M", "A", "A", "L"]
    # 270 degrees counter-clockwise on the plate, then a clockwise semicircle
    (_, _), (_, a1), (_, a2) = parse_path(paths[1].get("d", ""))
    assert a1[3:5] == [1, 0] and a2[3:5] == [0, 1]


def test_empty(tmp_path):
    out = tmp_path / "empty.svg"
    write_svg(out, Grooves.empty(), Tool())
    assert len(list(layer(read(out)))) == 0


def check_drawing(path: Path, g: Grooves) -> None:
    """Every groove is drawn where it is, y flipped: end points, arc midpoints, dots."""
    root = read(path)
    items = list(layer(root))
    assert len(items) == g.n_paths
    segs = g.segments()
    straight = is_straight(segs)
    with np.errstate(all="ignore"):  # subnormal bulges of straight segments overflow
        centre, radius, start, sweep = segs.geometry()
    flip = np.array([1.0, -1.0])
    vb = np.array([float(v) for v in root.get("viewBox", "").split()])
    lo, hi = vb[:2], vb[:2] + vb[2:]
    s = 0
    for j, item in enumerate(items):
        v = g.vertices[g.offsets[j]:g.offsets[j + 1]] * flip
        if len(v) == 1:
            assert item.tag == f"{SVG}circle"
            xy = np.array([float(item.get("cx", "nan")), float(item.get("cy", "nan"))])
            assert np.allclose(xy, v[0], atol=1e-4)
            continue
        assert item.tag == f"{SVG}path"
        cmds = parse_path(item.get("d", ""))
        assert len(cmds) == len(v) and cmds[0][0] == "M"
        pen = np.array(cmds[0][1])
        assert np.allclose(pen, v[0], atol=1e-4)
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


def test_example_drawing(tmp_path, groove_example):
    out = tmp_path / "x.svg"
    write_svg(out, groove_example, Tool())
    check_drawing(out, groove_example)


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_drawing(tmp_path, grooves_strategy, data):
    g = data.draw(grooves_strategy(max_bulge=3.0))
    out = tmp_path / "r.svg"
    write_svg(out, g, Tool(), margin=data.draw(st.floats(0.0, 10.0)))
    check_drawing(out, g)


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

"""G-code export: the file LinuxCNC's own interpreter reads cuts exactly the grooves.

The strongest checks run the program through ``rs274`` (LinuxCNC's RS274/NGC
interpreter, Debian package linuxcnc-uspace) and compare its canonical machine
commands with the grooves: arc end points, centres and directions, cutting depth,
safe height, feeds, and the ``(stipple N)`` comment before each groove.
"""

from __future__ import annotations

import locale
import math
import os
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from specholo.errors import SpecholoError
from specholo.fabrication.exporting import (
    TextRows,
    chunk_bounds,
    format_number,
    is_straight,
    path_chunks,
)
from specholo.fabrication.programs.gcode import GcodeStats, split_wide_arcs, wide_arcs, write_gcode
from specholo.fabrication.programs.gcode_reader import read_gcode
from specholo.fabrication.programs.program import DIALECTS, MAX_ARC_OFFSET_MM, SCALE, GcodeOptions
from specholo.setup import Machining, Tool
from specholo.toolpaths.grooves import Grooves

RS274 = Path("/usr/bin/rs274")
needs_rs274 = pytest.mark.skipif(
    not RS274.exists(),
    reason="LinuxCNC's interpreter /usr/bin/rs274 is missing (apt-get install linuxcnc-uspace)",
)
_CANON = re.compile(r"^\s*\d+ N\.\.\.\.\. ([A-Z][A-Z0-9_]*)\((.*)\)\s*$")
TOL = 1e-3  # rs274 prints 4 decimals


def run_rs274(ngc: Path) -> list[tuple[str, str]]:
    """Interpret a program with rs274; fail on any error, return its canonical commands."""
    # rs274 truncates and maps $HOME/.tool.mmap at start: two at once under one
    # HOME die of SIGBUS, so each runs with the program's own folder as HOME
    proc = subprocess.run([str(RS274), "-g", str(ngc)], capture_output=True, text=True,
                          cwd=ngc.parent, stdin=subprocess.DEVNULL, timeout=600, check=False,
                          env={**os.environ, "HOME": str(ngc.parent)})
    # rs274 exits 0 even on errors: it prints them instead of canonical commands
    # (this version on stderr, others on stdout), so both streams are checked
    bad = [line for line in proc.stdout.splitlines() if not _CANON.match(line)]
    bad += [line for line in proc.stderr.splitlines() if line.strip() not in ("", "executing")]
    assert not bad, "rs274 rejected the program:\n" + "\n".join(bad[:10])
    canon = [(m.group(1), m.group(2)) for m in map(_CANON.match, proc.stdout.splitlines()) if m]
    assert any(name == "PROGRAM_END" for name, _ in canon), (
        f"rs274 stopped before M2 (exit {proc.returncode}):\n"
        + "\n".join(proc.stdout.splitlines()[-3:]))
    return canon


def near(a, b, tol: float = TOL) -> bool:
    """Equal within the interpreter's printed precision (np.allclose is slow per call)."""
    return max(abs(x - y) for x, y in zip(a, b, strict=True)) < tol


def _floats(args: str, n: int) -> np.ndarray:
    return np.array([float(a) for a in args.split(",")[:n]])


def check_canon(canon: list[tuple[str, str]], grooves: Grooves, tool: Tool,
                machining: Machining, options: GcodeOptions | None = None) -> None:
    """Assert that the interpreter's motions cut exactly ``grooves`` (as ``options`` write them)."""
    options = options or GcodeOptions()
    safe, depth = machining.safe_z, -tool.depth
    feed_rate = 0.0
    factor = 1.0  # mm per canonical unit
    events: list[tuple] = []
    spindle_on = spindle_off = -1
    for name, args in canon:
        if name == "USE_LENGTH_UNITS":
            factor = 25.4 if "INCHES" in args else 1.0
        elif name == "SET_FEED_RATE":
            feed_rate = float(args) * factor
        elif name == "COMMENT" and args.startswith('"stipple '):
            events.append(("stipple", int(args.strip('"').split()[1])))
        elif name == "STRAIGHT_TRAVERSE":
            events.append(("rapid", _floats(args, 3) * factor))
        elif name == "STRAIGHT_FEED":
            events.append(("line", _floats(args, 3) * factor, feed_rate))
        elif name == "ARC_FEED":
            a = _floats(args, 6) * factor
            events.append(("arc", a[[0, 1, 5]], feed_rate, a[2:4], int(round(a[4] / factor))))
        elif name == "START_SPINDLE_CLOCKWISE":
            spindle_on = len(events)
        elif name == "STOP_SPINDLE_TURNING" and spindle_off < 0:
            spindle_off = len(events)
    tol = TOL * factor  # rs274 prints 4 decimals of its units

    # every move on its own: rapids at the safe height (XY travel only there)
    # or up to the hop height; feeds at the cutting depth except the vertical
    # plunges, at the plunge rate, and the hops: X/Y at the hop height at the feed
    hop = machining.hop
    pos = None
    for ev in events:
        if ev[0] == "stipple":
            continue
        end = ev[1]
        if ev[0] == "rapid":
            assert abs(end[2] - safe) < tol or abs(end[2] - hop) < tol, f"rapid to z={end[2]}"
            if pos is not None and np.hypot(*(end[:2] - pos[:2])) > tol:
                assert abs(pos[2] - safe) < tol and abs(end[2] - safe) < tol, \
                    "XY rapid below the safe height"
            elif pos is not None:
                assert end[2] >= pos[2] - tol, "rapid down"
        elif ev[0] == "line" and pos is not None and np.hypot(*(end[:2] - pos[:2])) < tol \
                and abs(pos[2] - end[2]) > tol:
            assert abs(end[2] - depth) < tol, "bad plunge"
            assert abs(pos[2] - safe) < tol or abs(pos[2] - hop) < tol, "bad plunge"
            assert abs(ev[2] - machining.plunge) < tol * max(1.0, machining.plunge / 1000)
        elif ev[0] == "line" and pos is not None and abs(pos[2] - hop) < tol \
                and abs(pos[2] - hop) < abs(pos[2] - depth):
            # a hop: never below the hop height, never longer than the longest hop (a
            # shallow groove and a low hop may both lie within rs274's printed
            # precision of inches: the nearer level says which the move is)
            assert abs(end[2] - hop) < tol, "hop leaves the hop height"
            assert np.hypot(*(end[:2] - pos[:2])) <= machining.hop_max + tol, "hop too long"
            assert abs(ev[2] - machining.feed) < tol * max(1.0, machining.feed / 1000)
        else:
            assert pos is not None and abs(pos[2] - depth) < tol and abs(end[2] - depth) < tol
            assert abs(ev[2] - machining.feed) < tol * max(1.0, machining.feed / 1000)
        pos = end

    if machining.spindle > 0:
        first_cut = next((k for k, ev in enumerate(events) if ev[0] in ("line", "arc")),
                         len(events))
        assert 0 <= spindle_on <= first_cut
        assert spindle_off >= len(events) - 1
        assert any(name == "DWELL" for name, _ in canon) == (options.dwell > 0)
    else:
        assert spindle_on < 0

    # the sequence, groove by groove
    k = 0
    while k < len(events) and events[k][0] != "stipple":
        assert events[k][0] == "rapid", "a cut before the first (stipple N) comment"
        k += 1
    segs = grooves.segments()
    straight = is_straight(segs)
    wide = wide_arcs(segs, options.max_arc_offset)
    with np.errstate(all="ignore"):  # subnormal bulges of straight segments overflow
        centre, radius, _, _ = segs.geometry()
    # a groove is hopped onto where it starts within hop_max of the last one's end
    starts = grooves.vertices[grooves.offsets[:-1]]
    ends = grooves.vertices[grooves.offsets[1:] - 1]
    hopped = np.append(False, machining.hops(np.hypot(*(starts[1:] - ends[:-1]).T)))
    s = 0
    for j in range(grooves.n_paths):
        v = grooves.vertices[grooves.offsets[j]:grooves.offsets[j + 1]]
        assert events[k] == ("stipple", grooves.stipple[j]), f"groove {j}: no stipple comment"
        ev = events[k + 1]
        if hopped[j]:
            assert ev[0] == "line" and near(ev[1], [*v[0], hop], tol), f"groove {j}: no hop"
        else:
            assert ev[0] == "rapid" and near(ev[1], [*v[0], safe], tol)
        ev = events[k + 2]
        assert ev[0] == "line" and near(ev[1], [*v[0], depth], tol)
        k += 3
        for i in range(1, len(v)):
            if wide[s]:
                # written as chords: lines whose ends all lie on the arc's circle
                while True:
                    ev = events[k]
                    assert ev[0] == "line", f"groove {j} arc {i - 1}: not chords"
                    assert abs(np.hypot(*(ev[1][:2] - centre[s])) - radius[s]) < tol
                    k += 1
                    if near(ev[1], [*v[i], depth], tol):
                        break
                s += 1
                continue
            ev = events[k]
            assert near(ev[1], [*v[i], depth], tol), f"groove {j} vertex {i}"
            if straight[s]:
                assert ev[0] == "line"
            else:
                assert ev[0] == "arc", f"groove {j} arc {i - 1} is not an arc"
                assert near(ev[3], centre[s], tol), "arc centre"
                assert ev[4] == (1 if segs.bulge[s] > 0 else -1), "arc direction"
            k += 1
            s += 1
        ev = events[k]
        up = hop if j + 1 < grooves.n_paths and hopped[j + 1] else safe
        assert ev[0] == "rapid" and near(ev[1], [*v[-1], up], tol), "retract"
        k += 1
    assert k == len(events), "moves after the last groove"


def lines_of(path: Path) -> list[str]:
    return path.read_text(encoding="ascii").splitlines()


def cut_lines(lines: list[str]) -> list[str]:
    """The XY cutting moves of a written program."""
    return [t for t in lines if re.match(r"G[123] X", t)]


# ---------------------------------------------------------------------------
# the file itself


@pytest.mark.parametrize(("dialect", "units", "name"), [
    ("linuxcnc", "mm", "example.ngc"),
    ("grbl", "mm", "example_grbl.ngc"),
    ("grbl", "inch", "example_grbl_inch.ngc"),
    ("marlin", "mm", "example_marlin.ngc"),
])
def test_golden(tmp_path, groove_example, golden, dialect, units, name):
    out = tmp_path / name
    write_gcode(out, groove_example, Tool(), Machining(), header={"model": "golden example"},
                options=GcodeOptions(dialect=dialect, units=units))
    golden(out, name)


def test_structure(tmp_path, groove_example):
    out = tmp_path / "x.ngc"
    stats = write_gcode(out, groove_example, Tool(), Machining(), header={"job": "a (b)"})
    text = lines_of(out)
    assert "G21 G90 G17 G94 G40" in text
    assert text[-2:] == ["M5", "M2"]
    assert "M3 S12000" in text and "G4 P2" in text
    assert text.index("M3 S12000") < text.index("G0 Z1.00000") < text.index("(stipple 4)")
    assert "(job: a [b])" in text  # parentheses cannot nest in comments
    assert [t for t in text if t.startswith("(stipple")] == [
        "(stipple 4)", "(stipple 4)", "(stipple 9)"]
    # arcs: direction from the sign of the bulge, feed on the first cut of each groove
    cuts = cut_lines(text)
    assert [c.split()[0] for c in cuts] == ["G3", "G2", "G1", "G3", "G2"]
    assert [c.endswith(" F300.00000") for c in cuts] == [True, False, False, True, False]
    # dot: rapid, plunge, retract
    k = text.index("G0 X-5.00000 Y-5.00000")
    assert text[k - 1:k + 3] == ["(stipple 4)", "G0 X-5.00000 Y-5.00000",
                                 "G1 Z-0.08000 F100.00000", "G0 Z1.00000"]
    assert stats == GcodeStats(
        lines=len(text), paths=3,
        cutting_length_mm=pytest.approx(groove_example.total_length() + 3 * 1.08),
        rapid_length_mm=pytest.approx(
            0.0 + math.hypot(25, 10) + math.hypot(6, 6) + 3 * 1.08),
    )


def test_no_spindle(tmp_path, groove_example):
    out = tmp_path / "x.ngc"
    write_gcode(out, groove_example, Tool(), Machining(spindle=0.0))
    text = lines_of(out)
    assert not any(t.startswith(("M3", "M5", "G4")) for t in text)
    assert text[-1] == "M2"


def test_no_negative_zero(tmp_path):
    tiny = 1.0 / SCALE  # the written resolution
    g = Grooves(np.array([[-0.01 * tiny, -0.4 * tiny], [3.0, -0.49 * tiny], [-0.2 * tiny, 1.0]]),
                np.array([0.3, 0, 0]), np.array([0, 2, 3]), np.array([0, 1]))
    out = tmp_path / "x.ngc"
    write_gcode(out, g, Tool(), Machining())
    text = out.read_text()
    assert "X0.00000 Y0.00000" in text
    assert not re.search(r"-0\.0+(?![0-9])", text)


def test_straight_and_degenerate_arcs(tmp_path):
    g = Grooves(
        np.array([[0, 0], [10, 0], [20, 0], [20.004, 0], [30, 0], [40, 0], [40.04, 0]],
                 dtype=float),
        # flat (sagitta 5e-7 mm), radius 2e4 mm (sagitta 6e-4 mm), 2 um half circle,
        # straight, plain arc, short arc turning 8e-4 rad with sagitta 8e-6 mm
        np.array([1e-7, 1.25e-4, 1.0, 0.0, 0.2, 4e-4, 0.0]),
        np.array([0, 7]), np.array([0]))
    out = tmp_path / "x.ngc"
    write_gcode(out, g, Tool(), Machining(), options=GcodeOptions(dialect="linuxcnc"))
    cuts = [t.split()[0] for t in cut_lines(lines_of(out))]
    assert cuts == ["G1", "G3", "G1", "G1", "G3", "G3"]
    # GRBL: the arc centred 2e4 mm away becomes chords within half the grid
    # (sagitta 6.25e-4 mm: ceil(sqrt(6.25e-4 / 5e-6)) = 12 of them)
    write_gcode(out, g, Tool(), Machining(), options=GcodeOptions(dialect="grbl"))
    cuts = [t.split()[0] for t in cut_lines(lines_of(out))]
    assert cuts == ["G1"] + ["G1"] * 12 + ["G1", "G1", "G3", "G3"]
    np.testing.assert_array_equal(is_straight(g.segments()),
                                  [True, False, True, True, False, False])


def test_rejects_bad_grooves(tmp_path):
    bad = Grooves(np.array([[0.0, np.nan]]), np.zeros(1), np.array([0, 1]), np.array([0]))
    with pytest.raises(SpecholoError):
        write_gcode(tmp_path / "x.ngc", bad, Tool(), Machining())
    assert not (tmp_path / "x.ngc").exists()


def wide_example() -> Grooves:
    """Arcs with far-away centres: 0.5 mm of a 20 m radius (one chord), 20 mm of 2 m
    and 1.5 m radii (many chords), and ordinary arcs around them."""
    def bulge(chord: float, radius: float, sign: float) -> float:
        return sign * math.tan(math.asin(chord / (2 * radius)) / 2)

    vertices = np.array([[0.0, 0.0], [5.0, 1.0], [5.5, 1.0], [25.5, 1.0], [26.4, 2.0],
                         [-3.0, -3.0], [-3.0, 17.0]])
    bulges = np.array([0.2, bulge(0.5, 2e4, 1.0), bulge(20.0, 2e3, -1.0), -0.3, 0.0,
                       bulge(20.0, 1500.0, 1.0), 0.0])
    return Grooves(vertices, bulges, np.array([0, 5, 7]), np.array([3, 8]))


GRBL_G = {"G0", "G1", "G2", "G3", "G4", "G17", "G20", "G21", "G40", "G90", "G94"}
GRBL_M = {"M2", "M3", "M5"}


def words(line: str) -> list[str]:
    code = re.sub(r"\(.*?\)|;.*", "", line)
    return re.findall(r"[A-Z][-+]?[0-9.]+", code)


@pytest.mark.parametrize(("dialect", "units"), [
    ("grbl", "mm"), ("grbl", "inch"), ("linuxcnc", "mm"), ("marlin", "mm"), ("marlin", "inch")])
def test_headers_state_the_setup(tmp_path, groove_example, dialect, units):
    out = tmp_path / "x.ngc"
    write_gcode(out, groove_example, Tool(), Machining(),
                options=GcodeOptions(dialect=dialect, units=units))
    head = [t for t in lines_of(out) if t.startswith(("(", ";"))][:9]
    text = " ".join(head).lower()
    unit = "mm" if units == "mm" else "in"
    for needle in ("specholo", "dialect", f"units: {'mm' if units == 'mm' else 'inch'}",
                   "origin: plate centre", "tool:", "depth:", f"{unit}/min"):
        assert needle in text, needle
    if dialect == "marlin":
        assert "arc_support" in text and "laser_feature" in text
        assert ("inch_mode_support" in text) == (units == "inch")
    else:
        radius = format_number(0.25 / (25.4 if units == "inch" else 1), 6 if units == "inch" else 5)
        assert f"radius {radius} {unit}" in text


@pytest.mark.parametrize("units", ["mm", "inch"])
def test_grbl_uses_only_grbl_words(tmp_path, units):
    g = wide_example()
    out = tmp_path / "x.ngc"
    write_gcode(out, Grooves.concatenate([g, Grooves(np.array([[1.0, 2.0]]), np.zeros(1),
                                                      np.array([0, 1]), np.array([5]))]),
                Tool(), Machining(), options=GcodeOptions(dialect="grbl", units=units))
    text = lines_of(out)
    found = [w for t in text for w in words(t)]
    letters = {w[0] for w in found}
    assert letters <= set("GMXYZIJFSP")
    assert {w for w in found if w[0] == "G"} <= GRBL_G
    assert {w for w in found if w[0] == "M"} <= GRBL_M
    assert text[-1] == "M2"
    # GRBL's line buffer holds 79 characters, comments and spaces left out
    assert max(len("".join(words(t))) for t in text) < 80
    # single precision: no arc centre 1000 mm or more from its start
    ij = [abs(float(w[1:])) * (25.4 if units == "inch" else 1.0)
          for w in found if w[0] in "IJ"]
    assert ij and max(ij) <= MAX_ARC_OFFSET_MM


def test_marlin_laser_program(tmp_path, groove_example):
    out = tmp_path / "x.gcode"
    stats = write_gcode(out, groove_example, Tool(), Machining(),
                        options=GcodeOptions(dialect="marlin", laser_on="M4", laser_power=180,
                                             dot_time=0.25, rapid_feed=4000))
    text = lines_of(out)
    code = [t for t in text if not t.startswith(";")]
    # Marlin reads one command per line; nothing moves Z; no M2/M30 (M30 deletes SD files)
    assert all(sum(w[0] in "GM" for w in words(t)) == 1 for t in code)
    assert not any(w[0] == "Z" for t in code for w in words(t))
    assert not any(w in ("M2", "M30") for t in code for w in words(t))
    assert code[:3] == ["G21", "G90", "M5"]
    # each groove: comment, rapid with its feed, laser on, cuts, laser off
    k = text.index("; stipple 9")
    assert text[k:k + 6] == ["; stipple 9", "G0 X1.00000 Y1.00000 F4000.00000", "M4 S180",
                             "G3 X2.00000 Y1.50000 I0.75000 J-0.25000 F300.00000",
                             "G2 X4.00000 Y1.50000 I1.00000 J0.00000", "M5"]
    k = text.index("G0 X-5.00000 Y-5.00000 F4000.00000")
    assert text[k + 1:k + 4] == ["M4 S180", "G4 P250", "M5"]  # a dot: Marlin's P is in ms
    assert text[-1] == "M5"
    assert [t.split()[0] for t in code].count("M4") == 3 == [t for t in code].count("M5") - 1
    assert stats.lines == len(text)
    assert stats.rapid_length_mm == pytest.approx(math.hypot(25, 10) + math.hypot(6, 6))


def test_inch_converts_every_number(tmp_path, groove_example):
    mm, inch = tmp_path / "mm.ngc", tmp_path / "in.ngc"
    machining = Machining(feed=254.0, plunge=127.0, safe_z=2.54)
    write_gcode(mm, groove_example, Tool(), machining, options=GcodeOptions(units="mm"))
    write_gcode(inch, groove_example, Tool(), machining, options=GcodeOptions(units="inch"))
    a, b = lines_of(mm), lines_of(inch)
    assert "G21 G90 G17 G94 G40" in a and "G20 G90 G17 G94 G40" in b
    code_a = [words(t) for t in a if not t.startswith("(")]
    code_b = [words(t) for t in b if not t.startswith("(")]
    assert len(code_a) == len(code_b)
    for wa, wb in zip(code_a, code_b, strict=True):
        assert [w[0] for w in wa] == [w[0] for w in wb]
        for x, y in zip(wa, wb, strict=True):
            if x in ("G20", "G21"):
                continue
            if x[0] in "XYZIJF":
                assert float(y[1:]) * 25.4 == pytest.approx(float(x[1:]), abs=2e-5)
                assert len(y.split(".")[1]) == 6
            else:
                assert x == y
    assert "G1 Z-0.003150 F5.000000" in b and "G0 Z0.100000" in b


def test_inch_round_trip(tmp_path, groove_example):
    out = tmp_path / "in.ngc"
    write_gcode(out, groove_example, Tool(), Machining(), options=GcodeOptions(units="inch"))
    back = read_gcode(out)
    np.testing.assert_allclose(back.vertices, groove_example.vertices, atol=2e-5)
    np.testing.assert_allclose(back.bulges, groove_example.bulges, rtol=1e-4, atol=1e-9)


def test_dwell_and_header_lines(tmp_path, groove_example):
    out = tmp_path / "x.ngc"
    write_gcode(out, groove_example, Tool(), Machining(),
                options=GcodeOptions(dwell=0.5, header_lines=("G54", "M8")))
    text = lines_of(out)
    k = text.index("G21 G90 G17 G94 G40")
    assert text[k:k + 5] == ["G21 G90 G17 G94 G40", "G54", "M8", "M3 S12000", "G4 P0.5"]
    write_gcode(out, groove_example, Tool(), Machining(), options=GcodeOptions(dwell=0.0))
    assert not any(t.startswith("G4") for t in lines_of(out))


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"dialect": "mach3"}, "'mach3'"),
    ({"units": "cm"}, "'cm'"),
    ({"dwell": -1.0}, "dwell must be a finite number >= 0, got -1"),
    ({"laser_power": 0.0}, "laser power must be a finite number > 0, got 0"),
    ({"rapid_feed": math.nan}, "got nan"),
    ({"laser_on": "M5"}, "'M5'"),
    ({"header_lines": ("G54\nG0 Z-5",)}, "header line"),
])
def test_options_reject_bad_values(kwargs, message):
    with pytest.raises(SpecholoError, match=re.escape(message)) as err:
        GcodeOptions(**kwargs)
    assert "\n" not in str(err.value).replace("\\n", "")


def test_split_wide_arcs_keeps_the_arcs():
    g = wide_example()
    segs = g.segments()
    assert list(wide_arcs(segs)) == [False, True, True, False, True]
    assert not wide_arcs(segs, math.inf).any()
    out = split_wide_arcs(g)
    assert out.n_paths == g.n_paths
    np.testing.assert_array_equal(out.stipple, g.stipple)
    # the path ends and the ordinary arcs stay; the wide ones become chords
    np.testing.assert_array_equal(out.vertices[out.offsets[:-1]], g.vertices[g.offsets[:-1]])
    np.testing.assert_array_equal(out.vertices[out.offsets[1:] - 1], g.vertices[g.offsets[1:] - 1])
    with np.errstate(all="ignore"):
        centre, radius, _, _ = segs.geometry()
    sizes = np.diff(out.offsets)
    # 0.5 mm of a 20 m circle bulges 1.6e-6 mm: one chord; 20 mm of a 2 m circle
    # bulges 0.025 mm: chords within half the grid need sqrt(0.025 / 5e-6) ~ 71;
    # of a 1.5 m circle, 0.033 mm: 82
    assert list(sizes) == [4 + 71, 1 + 82]
    new = out.segments()
    # arcs: v0-v1, one chord v1-v2, 71 chords v2-v3 (vertices 2..73), v3-v4
    assert np.all(new.bulge[1:73] == 0.0) and new.bulge[0] == g.bulges[0]
    assert new.bulge[73] == g.bulges[3]
    on_arc = out.vertices[2:74]
    assert np.allclose(np.hypot(*(on_arc - centre[2]).T), radius[2], atol=1e-9, rtol=1e-12)
    chord = np.linalg.norm(np.diff(on_arc, axis=0), axis=1)
    sagitta = radius[2] - np.sqrt(radius[2] ** 2 - chord ** 2 / 4)
    assert sagitta.max() <= 0.5 / SCALE
    assert np.allclose(chord, chord[0])  # equal chords
    assert split_wide_arcs(out) is out


@pytest.mark.parametrize("writer", ["gcode", "svg"])
def test_decimal_point_ignores_locale(tmp_path, groove_example, writer):
    from specholo.fabrication.drawings.svg import write_svg

    def write(out: Path) -> bytes:
        if writer == "gcode":
            write_gcode(out, groove_example, Tool(), Machining())
        else:
            write_svg(out, groove_example, Tool())
        return out.read_bytes()

    reference = write(tmp_path / "c")
    old = locale.setlocale(locale.LC_NUMERIC)
    try:
        try:
            locale.setlocale(locale.LC_NUMERIC, "de_DE.UTF-8")
        except locale.Error:
            pytest.skip("locale de_DE.UTF-8 is not installed")
        assert locale.localeconv()["decimal_point"] == ","
        german = write(tmp_path / "de")
        assert format_number(-1.5) == "-1.50000"
    finally:
        locale.setlocale(locale.LC_NUMERIC, old)
    assert german == reference
    assert not re.search(rb"\d,\d", german)


# ---------------------------------------------------------------------------
# hops


def hopping_example() -> Grooves:
    """A cut; an arc starting 0.5 mm from its end; a dot 10 mm away; a dot 2 mm
    from that one."""
    return Grooves(np.array([[0.0, 0.0], [5.0, 0.0], [5.5, 0.0], [8.0, 2.0], [18.0, 2.0],
                             [20.0, 2.0]]),
                   np.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0]), np.array([0, 2, 4, 5, 6]),
                   np.array([1, 1, 2, 3]))


def test_hops_between_near_grooves(tmp_path):
    g = hopping_example()
    out = tmp_path / "hops.ngc"
    stats = write_gcode(out, g, Tool(), Machining(spindle=0.0))
    text = lines_of(out)
    # onto the arc (0.5 mm) and the last dot (2 mm): up to 0.03 mm, over at the
    # cutting feed, down again; onto the far dot (10 mm): the safe height
    k = text.index("G1 X5.00000 Y0.00000 F300.00000")
    assert text[k + 1:k + 5] == ["G0 Z0.03000", "(stipple 1)", "G1 X5.50000 Y0.00000 F300.00000",
                                 "G1 Z-0.08000 F100.00000"]
    k = text.index("(stipple 2)")
    assert text[k - 1:k + 3] == ["G0 Z1.00000", "(stipple 2)", "G0 X18.00000 Y2.00000",
                                 "G1 Z-0.08000 F100.00000"]
    assert text[k + 3:] == ["G0 Z0.03000", "(stipple 3)", "G1 X20.00000 Y2.00000 F300.00000",
                            "G1 Z-0.08000 F100.00000", "G0 Z1.00000", "M2"]
    # below the surface the tool only plunges straight down and cuts at the depth;
    # in X/Y above it, it rapids at the safe height or hops at the hop height
    z = math.nan
    for line in text:
        if line.startswith("("):  # the header's plate block quotes coordinates
            continue
        words = dict(re.findall(r"([XYZ])(-?[\d.]+)", line))
        if "Z" in words:
            z = float(words["Z"])
            assert z in (1.0, 0.03, -0.08)
        elif "X" in words:
            assert (line.startswith("G0") and z == 1.0) or (line.startswith("G1") and z == 0.03) \
                or (line.startswith(("G1", "G2", "G3")) and z == -0.08), line
    assert stats.hops == 2 and stats.hop_length_mm == pytest.approx(2.5)
    # four plunges and retracts, two of them to and from the hop height only
    vertical = 4 * 1.08 - 2 * (1.0 - 0.03)
    assert stats.cutting_length_mm == pytest.approx(g.total_length() + vertical)
    assert stats.rapid_length_mm == pytest.approx(10.0 + vertical)
    # the hops are no grooves
    back = read_gcode(out)
    np.testing.assert_array_equal(back.offsets, g.offsets)
    np.testing.assert_allclose(back.vertices, g.vertices, atol=1e-5)


def test_no_hops_is_the_program_without_them(tmp_path, groove_example):
    g = hopping_example()
    off = Machining(hop_max=0.0)
    write_gcode(tmp_path / "off.ngc", g, Tool(), off)
    text = lines_of(tmp_path / "off.ngc")
    assert "G0 Z0.03000" not in text
    assert [t for t in text if t.startswith("G1 X")] == ["G1 X5.00000 Y0.00000 F300.00000"]
    assert text.count("G0 Z1.00000") == 1 + 4
    # where no groove is near another, hops change nothing
    for dialect in DIALECTS:
        options = GcodeOptions(dialect=dialect)
        write_gcode(tmp_path / "a.ngc", groove_example, Tool(), off, options=options)
        write_gcode(tmp_path / "b.ngc", groove_example, Tool(), Machining(), options=options)
        assert (tmp_path / "a.ngc").read_bytes() == (tmp_path / "b.ngc").read_bytes()


def test_a_laser_never_hops(tmp_path):
    g = hopping_example()
    options = GcodeOptions(dialect="marlin")
    write_gcode(tmp_path / "a.ngc", g, Tool(), Machining(hop_max=0.0), options=options)
    stats = write_gcode(tmp_path / "b.ngc", g, Tool(), Machining(), options=options)
    assert (tmp_path / "a.ngc").read_bytes() == (tmp_path / "b.ngc").read_bytes()
    assert stats.hops == 0


# ---------------------------------------------------------------------------
# LinuxCNC's interpreter


@needs_rs274
@pytest.mark.parametrize("units", ["mm", "inch"])
@pytest.mark.parametrize("dialect", ["grbl", "linuxcnc"])
def test_rs274_cuts_the_example(tmp_path, groove_example, dialect, units):
    out = tmp_path / "example.ngc"
    options = GcodeOptions(dialect=dialect, units=units)
    write_gcode(out, groove_example, Tool(), Machining(), header={"model": "example"},
                options=options)
    check_canon(run_rs274(out), groove_example, Tool(), Machining(), options)


@needs_rs274
@pytest.mark.parametrize("units", ["mm", "inch"])
@pytest.mark.parametrize("dialect", ["grbl", "linuxcnc"])
def test_rs274_hops(tmp_path, dialect, units):
    g = Grooves.concatenate([hopping_example(), hopping_example()])
    out = tmp_path / "hops.ngc"
    options = GcodeOptions(dialect=dialect, units=units)
    for machining in (Machining(), Machining(hop=0.05, hop_max=10.0), Machining(hop_max=0.0)):
        write_gcode(out, g, Tool(), machining, options=options)
        check_canon(run_rs274(out), g, Tool(), machining, options)


@needs_rs274
@pytest.mark.parametrize("dialect", ["grbl", "linuxcnc"])
def test_rs274_cuts_wide_arcs(tmp_path, dialect):
    g = wide_example()
    out = tmp_path / "wide.ngc"
    options = GcodeOptions(dialect=dialect)
    write_gcode(out, g, Tool(), Machining(), options=options)
    check_canon(run_rs274(out), g, Tool(), Machining(), options)


@needs_rs274
def test_rs274_empty_program(tmp_path):
    out = tmp_path / "empty.ngc"
    write_gcode(out, Grooves.empty(), Tool(), Machining())
    check_canon(run_rs274(out), Grooves.empty(), Tool(), Machining())
    assert read_gcode(out).n_paths == 0


@needs_rs274
@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_rs274_cuts_random_grooves(tmp_path, grooves_strategy, data):
    g = data.draw(grooves_strategy(max_bulge=3.0, chord=(1e-4, 20.0)))
    radius = data.draw(st.floats(0.05, 2.0))
    tool = Tool(radius=radius, depth=data.draw(st.floats(0.01, 1.0)) * radius)
    machining = Machining(
        feed=data.draw(st.floats(1.0, 5000.0)), plunge=data.draw(st.floats(1.0, 1000.0)),
        safe_z=data.draw(st.floats(0.1, 20.0)), spindle=data.draw(st.sampled_from([0.0, 9000.0])),
        hop=data.draw(st.floats(0.01, 0.09)), hop_max=data.draw(st.sampled_from([0.0, 1.0, 10.0])),
    )
    options = GcodeOptions(dialect=data.draw(st.sampled_from(["grbl", "linuxcnc"])),
                           units=data.draw(st.sampled_from(["mm", "inch"])),
                           dwell=data.draw(st.sampled_from([0.0, 0.5, 2.0])))
    out = tmp_path / "random.ngc"
    write_gcode(out, g, tool, machining, header={"note": data.draw(st.text(max_size=30))},
                options=options)
    check_canon(run_rs274(out), g, tool, machining, options)


@needs_rs274
@pytest.mark.parametrize("dialect", ["grbl", "linuxcnc"])
def test_rs274_large_program(tmp_path, dialect):
    # more rows than one formatting chunk, so chunk boundaries fall inside grooves
    rng = np.random.default_rng(7)
    sizes = rng.integers(1, 40, 4000)
    m = int(sizes.sum())
    verts = np.cumsum(rng.uniform(-3, 3, (m, 2)), axis=0)
    bulges = rng.uniform(-1.5, 1.5, m)
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    bulges[offsets[1:] - 1] = 0.0
    g = Grooves(verts, bulges, offsets, np.arange(len(sizes)) // 3)
    out = tmp_path / "large.ngc"
    options = GcodeOptions(dialect=dialect)
    write_gcode(out, g, Tool(), Machining(), options=options)
    check_canon(run_rs274(out), g, Tool(), Machining(), options)
    back = read_gcode(out)
    want = split_wide_arcs(g, options.max_arc_offset)
    np.testing.assert_array_equal(back.offsets, want.offsets)
    np.testing.assert_allclose(back.vertices, want.vertices, atol=1e-4)


# ---------------------------------------------------------------------------
# reading back


def assert_round_trip(back: Grooves, g: Grooves) -> None:
    np.testing.assert_array_equal(back.offsets, g.offsets)
    np.testing.assert_array_equal(back.stipple, g.stipple)
    np.testing.assert_allclose(back.vertices, g.vertices, rtol=0, atol=1e-4)
    segs = g.segments()
    want = np.where(is_straight(segs), 0.0, segs.bulge)
    got = back.segments().bulge
    # rounding moves the end points and the centre by up to e = sqrt(2) / (2 SCALE),
    # which turns the sweep by up to 4 e / radius, i.e. the bulge by |b| 4 e / chord
    # (below 1e-4 |b| for chords over 0.3 mm)
    chord = np.linalg.norm(segs.end - segs.start, axis=1)
    tol = np.abs(want) * np.maximum(1e-4, 4 * np.sqrt(0.5) / SCALE / chord)
    assert np.all(np.abs(got - want) <= tol), np.max(np.abs(got - want) - tol)


def test_round_trip_example(tmp_path, groove_example):
    out = tmp_path / "x.ngc"
    write_gcode(out, groove_example, Tool(), Machining())
    back = read_gcode(out)
    assert_round_trip(back, groove_example)
    np.testing.assert_allclose(back.bulges, groove_example.bulges, rtol=1e-4)


@settings(max_examples=200, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_round_trip(tmp_path, grooves_strategy, data):
    g = data.draw(grooves_strategy())
    out = tmp_path / "rt.ngc"
    write_gcode(out, g, Tool(), Machining(), options=GcodeOptions(dialect="linuxcnc"))
    assert_round_trip(read_gcode(out), g)
    # GRBL writes the same arcs, except far-centred ones as chords
    write_gcode(out, g, Tool(), Machining(), options=GcodeOptions(dialect="grbl"))
    assert_round_trip(read_gcode(out), split_wide_arcs(g))


@pytest.mark.parametrize("dialect", ["linuxcnc", "grbl"])
def test_short_arcs_keep_their_tangents(tmp_path, dialect):
    # glints follow the groove's tangent: the grooves of a design are chains of
    # arcs 0.04-0.3 mm long with radii up to metres, and the written file must
    # not turn them (rounding the ends of a 0.04 mm arc to 0.1 um would turn it
    # by up to 3.5e-3 rad)
    rng = np.random.default_rng(5)
    n = 5000
    chord = rng.uniform(0.04, 0.3, n)
    angle = rng.uniform(-np.pi, np.pi, n)
    radius = np.exp(rng.uniform(np.log(5.0), np.log(1e4), n))
    bulge = np.tan(np.arcsin(chord / (2 * radius)) / 2) * rng.choice([-1, 1], n)
    start = rng.uniform(-100, 100, (n, 2))
    end = start + chord[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    g = Grooves(np.stack([start, end], axis=1).reshape(-1, 2),
                np.stack([bulge, np.zeros(n)], axis=1).ravel(),
                np.arange(0, 2 * n + 1, 2), np.arange(n))
    out = tmp_path / "short.ngc"
    write_gcode(out, g, Tool(), Machining(), options=GcodeOptions(dialect=dialect))
    back = read_gcode(out)
    first = back.offsets[:-1]  # each path's first arc (or chord)
    back_segs = Grooves(back.vertices, back.bulges, back.offsets, back.stipple).segments()
    seg_of_path = np.searchsorted(back_segs.path, np.arange(back.n_paths))

    def start_tangent(segs) -> np.ndarray:
        # an arc of sweep 4 atan(b) leaves its start turned by half its sweep
        # to the right of its chord
        d = segs.end - segs.start
        return np.arctan2(d[:, 1], d[:, 0]) - 2 * np.arctan(segs.bulge)

    got = start_tangent(back_segs)[seg_of_path]
    turn = np.angle(np.exp(1j * (got - start_tangent(g.segments()))))
    # each end moves by up to e across the chord
    e = np.sqrt(0.5) / SCALE
    allowed = 2.2 * e / chord + 1e-6
    if dialect == "grbl":
        # the first of the chords replacing an arc centred over 1000 mm away
        # turns from the tangent by asin(length / 2 radius), below 1e-4 rad
        wide = wide_arcs(g.segments())
        assert wide.any() and len(first) == n
        piece = np.linalg.norm(back_segs.end - back_segs.start, axis=1)[seg_of_path]
        geometric = np.arcsin(piece / (2 * radius))
        assert geometric[wide].max() < 1e-4
        allowed = np.where(wide, 2.2 * e / piece + geometric + 1e-6, allowed)
    assert np.all(np.abs(turn) <= allowed)


def test_read_general_program(tmp_path):
    program = """%
; a hand-written program
g21 g90 (mm, absolute) g17
G0 Z5
(stipple 12)
G0 X1 Y1
G1 Z-0.1 F50   ; plunge
X2             ; modal G1
G3 X3 Y2 I0 J1
G1 Z-0.2       (deeper: no new vertex)
G0 Z1
G20
N10 G0 X0 Y0
G1 Z-.01
Z.1
/G0 X0.5
M30
G1 X99 Z-1
"""
    path = tmp_path / "general.ngc"
    path.write_text(program)
    g = read_gcode(path)
    np.testing.assert_array_equal(g.offsets, [0, 3, 4])
    np.testing.assert_array_equal(g.stipple, [12, 12])
    np.testing.assert_allclose(g.vertices, [[1, 1], [2, 1], [3, 2], [0, 0]])
    np.testing.assert_allclose(g.bulges, [0, math.tan(math.pi / 8), 0, 0])


def test_read_without_stipple_comments(tmp_path):
    path = tmp_path / "plain.ngc"
    path.write_text("G0 X1 Y1 Z1\nG1 Z-1\nG2 X3 Y1 I1 J0\nG0 Z1\n")
    g = read_gcode(path)
    np.testing.assert_array_equal(g.stipple, [-1])
    np.testing.assert_allclose(g.bulges, [-1, 0])


@pytest.mark.parametrize(("program", "message"), [
    ("G1 X1,5 Y2\n", "line 1: cannot parse"),
    ("G0 X0\nG1 X1 Q[#1+2]\n", "line 2: cannot parse"),
    ("G91\nG1 X1\n", "unsupported G91"),
    ("G18\n", "unsupported G18"),
    ("G1 X1 E3\n", "unsupported word E"),
    ("X1 Y1\n", "without a motion mode"),
    ("G1 Z-1\nG2 X1 Y1 Z-1\n", "line 2: arc without I/J"),
    ("G1 Z-1\nG2 X1 Y1\n", "line 2: arc without I/J"),
    ("G1 X1 Y1 I1 J1\n", "line 1: I/J outside an arc"),
    ("G1 Z-1 F1\nG2 X0 Y0 Z-1 I1 J0\n", "line 2: full circles"),
    ("G1 Z-1 F1\nG2 X2 Y0 I1.5 J0\n", "line 2: arc radii"),
    ("G1 X1 (open comment\n", "unbalanced parentheses"),
    ("G1 X1 X2\n", "X given twice"),
])
def test_read_rejects(tmp_path, program, message):
    path = tmp_path / "bad.ngc"
    path.write_text(program)
    with pytest.raises(SpecholoError, match=re.escape(message)) as err:
        read_gcode(path)
    assert "\n" not in str(err.value)


def test_read_missing_file(tmp_path):
    with pytest.raises(SpecholoError, match="cannot read"):
        read_gcode(tmp_path / "nope.ngc")


@settings(max_examples=200, deadline=None)
@given(q=st.lists(st.integers(-(2**63) + 1, 2**63 - 1), min_size=1, max_size=20),
       decimals=st.integers(0, 18), data=st.data())
def test_text_rows_numbers(q, decimals, data):
    """Numbers, trimmed numbers and hexadecimal as Python writes them, masks leave rows out."""
    values = np.array(q, dtype=np.int64)
    mask = np.array(data.draw(st.lists(st.booleans(), min_size=len(q), max_size=len(q))))
    t = TextRows(len(q))
    t.choice(["<", "[", ""], np.arange(len(q)) % 3)
    t.number(values, decimals)
    t.text(" ")
    t.number(values, decimals, mask, trim=True)
    t.text(" ", mask)
    t.hex(np.abs(values), mask)
    t.text("\n")

    def fixed(v: int, trim: bool) -> str:
        sign = "-" if v < 0 else ""
        whole, frac = divmod(abs(v), 10**decimals)
        if not decimals:
            return f"{sign}{whole}"
        text = f"{frac:0{decimals}d}"
        return f"{sign}{whole}.{text.rstrip('0') or '0' if trim else text}"

    want = "".join(
        "<[ "[i % 3].strip() + fixed(v, False) + " "
        + (f"{fixed(v, True)} {abs(v):X}" if keep else "") + "\n"
        for i, (v, keep) in enumerate(zip(q, mask.tolist(), strict=True)))
    assert t.tobytes().decode("ascii") == want


def test_chunk_bounds():
    sizes = np.array([3, 1, 5, 2, 2, 1])
    assert chunk_bounds(sizes, 4).tolist() == [0, 2, 3, 5, 6]  # the 5-vertex path alone
    assert chunk_bounds(sizes, 100).tolist() == [0, 6]
    assert chunk_bounds(np.zeros(0, dtype=np.int64), 4).tolist() == [0]
    with pytest.raises(ValueError, match="got 0"):
        chunk_bounds(sizes, 0)


def test_path_chunks_read_from_the_offsets(monkeypatch):
    """Chunks found from the offsets, a block of paths at a time, are the same
    as from the sizes: whole, for a subset of paths and for a slice whose
    offsets do not start at 0."""
    from specholo.fabrication import exporting

    rng = np.random.default_rng(3)
    sizes = rng.integers(1, 9, 200)
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    g = Grooves(np.zeros((offsets[-1], 2)), np.zeros(offsets[-1]), offsets, np.arange(200))
    paths = rng.permutation(200)[:150]
    tail = Grooves(g.vertices, g.bulges, offsets[50:] - 0, np.arange(150))  # starts at 50's
    for block in (1, 7, 1 << 22):
        monkeypatch.setattr(exporting, "_BLOCK_PATHS", block)
        for rows in (1, 5, 16, 10_000):
            assert path_chunks(g, rows).tolist() == chunk_bounds(sizes, rows).tolist()
            assert path_chunks(g, rows, paths).tolist() == \
                chunk_bounds(sizes[paths], rows).tolist()
            assert path_chunks(tail, rows).tolist() == chunk_bounds(sizes[50:], rows).tolist()
    assert path_chunks(Grooves.empty(), 4).tolist() == [0]


def test_chunks_change_nothing(tmp_path, groove_example, monkeypatch):
    """Written a few paths at a time, the program is the same byte for byte
    (hops onto and off each chunk's paths included)."""
    from specholo.fabrication.programs import gcode

    g = Grooves.concatenate([groove_example, hopping_example()] * 4)
    whole = tmp_path / "whole.ngc"
    stats = write_gcode(whole, g, Tool(), Machining())
    assert stats.hops == 4 * 2
    monkeypatch.setattr(gcode, "_CHUNK_ROWS", 3)
    parts = tmp_path / "parts.ngc"
    again = write_gcode(parts, g, Tool(), Machining())
    assert (again.lines, again.paths, again.hops) == (stats.lines, stats.paths, stats.hops)
    # lengths are summed chunk by chunk: equal to rounding
    assert again.cutting_length_mm == pytest.approx(stats.cutting_length_mm, rel=1e-12)
    assert again.rapid_length_mm == pytest.approx(stats.rapid_length_mm, rel=1e-12)
    assert parts.read_bytes() == whole.read_bytes()
    from specholo.fabrication import exporting

    monkeypatch.setattr(exporting, "WRITER_THREADS", 1)  # and made in one thread
    one = tmp_path / "one.ngc"
    write_gcode(one, g, Tool(), Machining())
    assert one.read_bytes() == whole.read_bytes()


def test_chunks_made_in_threads_come_in_order(monkeypatch):
    """Chunks made by two threads are used in order; an error in one reaches the
    caller; leaving early cancels the rest; where numba's threading layer
    forbids concurrent kernels, the calling thread makes every chunk."""
    import threading
    import time

    from specholo.fabrication import exporting

    rng = np.random.default_rng(0)
    delays = rng.uniform(0, 0.004, 40)
    makers: set[int] = set()

    def make(lo: int, hi: int) -> tuple[int, int]:
        makers.add(threading.get_ident())
        time.sleep(delays[lo])
        return lo, hi

    bounds = np.arange(41)
    assert list(exporting.in_order(make, bounds)) == [(i, i + 1) for i in range(40)]
    assert threading.get_ident() not in makers

    def fail(lo: int, hi: int) -> int:
        if lo == 7:
            raise ValueError("chunk 7")
        return lo

    with pytest.raises(ValueError, match="chunk 7"):
        list(exporting.in_order(fail, bounds))
    made: list[int] = []
    for lo in exporting.in_order(lambda lo, hi: made.append(lo) or lo, bounds, ahead=2):
        if lo == 3:
            break
    assert len(made) <= 3 + 2 + 2  # the chunks in flight, not all 40

    makers.clear()
    monkeypatch.setattr(exporting, "concurrent_kernels_safe", lambda: False)
    assert list(exporting.in_order(make, bounds)) == [(i, i + 1) for i in range(40)]
    assert makers == {threading.get_ident()}


@pytest.mark.parametrize(("drawings", "named"), [
    (("SVG", "DXF"), "layer PLATE of the SVG and DXF, not cut"),
    (("SVG",), "layer PLATE of the SVG, not cut"),
    ((), "in no drawing of this design, not cut")])
def test_plate_marks_name_only_the_drawings_written(tmp_path, groove_example, drawings, named):
    """The header sends a maker to the drawings the design writes, no other."""
    out = tmp_path / "x.ngc"
    write_gcode(out, groove_example, Tool(), Machining(), drawings=drawings)
    marks = [t for t in lines_of(out) if t.startswith("(plate marks:")]
    assert len(marks) == 1 and marks[0].endswith(named + ")")
    for other in {"SVG", "DXF"} - set(drawings):
        assert other not in out.read_text()
    # a flat design's program (the default) names both, as its golden files hold
    default = tmp_path / "flat.ngc"
    write_gcode(default, groove_example, Tool(), Machining())
    assert "layer PLATE of the SVG and DXF, not cut" in default.read_text()


def test_a_v_bit_program_names_the_v_s_groove_width(tmp_path, groove_example):
    """Written through its small round-tip model, a V-bit's program names the
    groove the V cuts: its width at the surface, 2 d tan(angle / 2)."""
    from specholo.optics.cutters import VBit

    vbit, depth = VBit(math.radians(30.0)), 0.4
    out = tmp_path / "v.ngc"
    write_gcode(out, groove_example, vbit.model(depth), Machining(), depth=depth,
                width=vbit.section(depth).width)
    tool = next(t for t in lines_of(out) if t.startswith("(tool:"))
    width = float(re.search(r"groove width ([0-9.]+) mm", tool).group(1))
    assert width == pytest.approx(2 * depth * math.tan(math.radians(15.0)), abs=1e-5)
    assert width == pytest.approx(vbit.section(depth).width, abs=1e-5)
    assert width > 10 * vbit.model(depth).width  # not the round tip's

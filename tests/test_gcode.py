"""G-code export: the file LinuxCNC's own interpreter reads cuts exactly the grooves.

The strongest checks run the program through ``rs274`` (LinuxCNC's RS274/NGC
interpreter, Debian package linuxcnc-uspace) and compare its canonical machine
commands with the grooves: arc end points, centres and directions, cutting depth,
safe height, feeds, and the ``(stipple N)`` comment before each groove.
"""

from __future__ import annotations

import locale
import math
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from specholo.errors import SpecholoError
from specholo.fabrication.gcode import (
    SCALE,
    GcodeStats,
    format_number,
    is_straight,
    read_gcode,
    write_gcode,
)
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
    proc = subprocess.run([str(RS274), "-g", str(ngc)], capture_output=True, text=True,
                          cwd=ngc.parent, stdin=subprocess.DEVNULL, timeout=600, check=False)
    # rs274 exits 0 even on errors: it prints them instead of canonical commands
    # (this version on stderr, others on stdout), so both streams are checked
    bad = [line for line in proc.stdout.splitlines() if not _CANON.match(line)]
    bad += [line for line in proc.stderr.splitlines() if line.strip() not in ("", "executing")]
    assert not bad, "rs274 rejected the program:\n" + "\n".join(bad[:10])
    canon = [(m.group(1), m.group(2)) for m in map(_CANON.match, proc.stdout.splitlines()) if m]
    assert any(name == "PROGRAM_END" for name, _ in canon), "rs274 stopped before M2"
    return canon


def near(a, b) -> bool:
    """Equal within the interpreter's printed precision (np.allclose is slow per call)."""
    return max(abs(x - y) for x, y in zip(a, b, strict=True)) < TOL


def _floats(args: str, n: int) -> np.ndarray:
    return np.array([float(a) for a in args.split(",")[:n]])


def check_canon(canon: list[tuple[str, str]], grooves: Grooves, tool: Tool,
                machining: Machining) -> None:
    """Assert that the interpreter's motions cut exactly ``grooves``."""
    safe, depth = machining.safe_z, -tool.depth
    feed_rate = 0.0
    events: list[tuple] = []
    spindle_on = spindle_off = -1
    for name, args in canon:
        if name == "SET_FEED_RATE":
            feed_rate = float(args)
        elif name == "COMMENT" and args.startswith('"stipple '):
            events.append(("stipple", int(args.strip('"').split()[1])))
        elif name == "STRAIGHT_TRAVERSE":
            events.append(("rapid", _floats(args, 3)))
        elif name == "STRAIGHT_FEED":
            events.append(("line", _floats(args, 3), feed_rate))
        elif name == "ARC_FEED":
            a = _floats(args, 6)
            events.append(("arc", a[[0, 1, 5]], feed_rate, a[2:4], int(a[4])))
        elif name == "START_SPINDLE_CLOCKWISE":
            spindle_on = len(events)
        elif name == "STOP_SPINDLE_TURNING" and spindle_off < 0:
            spindle_off = len(events)

    # every move on its own: rapids at the safe height (XY travel only there),
    # feeds at the cutting depth except the vertical plunges, at the plunge rate
    pos = None
    for ev in events:
        if ev[0] == "stipple":
            continue
        end = ev[1]
        if ev[0] == "rapid":
            assert abs(end[2] - safe) < TOL, f"rapid to z={end[2]}"
            if pos is not None and np.hypot(*(end[:2] - pos[:2])) > TOL:
                assert abs(pos[2] - safe) < TOL, "XY rapid below the safe height"
        elif ev[0] == "line" and pos is not None and np.hypot(*(end[:2] - pos[:2])) < TOL \
                and abs(pos[2] - end[2]) > TOL:
            assert abs(end[2] - depth) < TOL and abs(pos[2] - safe) < TOL, "bad plunge"
            assert abs(ev[2] - machining.plunge) < TOL
        else:
            assert pos is not None and abs(pos[2] - depth) < TOL and abs(end[2] - depth) < TOL
            assert abs(ev[2] - machining.feed) < TOL
        pos = end

    if machining.spindle > 0:
        first_cut = next((k for k, ev in enumerate(events) if ev[0] in ("line", "arc")),
                         len(events))
        assert 0 <= spindle_on <= first_cut
        assert spindle_off >= len(events) - 1
        assert any(name == "DWELL" for name, _ in canon)
    else:
        assert spindle_on < 0

    # the sequence, groove by groove
    k = 0
    while k < len(events) and events[k][0] != "stipple":
        assert events[k][0] == "rapid", "a cut before the first (stipple N) comment"
        k += 1
    segs = grooves.segments()
    straight = is_straight(segs)
    with np.errstate(all="ignore"):  # subnormal bulges of straight segments overflow
        centre, _, _, _ = segs.geometry()
    s = 0
    for j in range(grooves.n_paths):
        v = grooves.vertices[grooves.offsets[j]:grooves.offsets[j + 1]]
        assert events[k] == ("stipple", grooves.stipple[j]), f"groove {j}: no stipple comment"
        ev = events[k + 1]
        assert ev[0] == "rapid" and near(ev[1], [*v[0], safe])
        ev = events[k + 2]
        assert ev[0] == "line" and near(ev[1], [*v[0], depth])
        k += 3
        for i in range(1, len(v)):
            ev = events[k]
            assert near(ev[1], [*v[i], depth]), f"groove {j} vertex {i}"
            if straight[s]:
                assert ev[0] == "line"
            else:
                assert ev[0] == "arc", f"groove {j} arc {i - 1} is not an arc"
                assert near(ev[3], centre[s]), "arc centre"
                assert ev[4] == (1 if segs.bulge[s] > 0 else -1), "arc direction"
            k += 1
            s += 1
        ev = events[k]
        assert ev[0] == "rapid" and near(ev[1], [*v[-1], safe]), "retract"
        k += 1
    assert k == len(events), "moves after the last groove"


def lines_of(path: Path) -> list[str]:
    return path.read_text(encoding="ascii").splitlines()


def cut_lines(lines: list[str]) -> list[str]:
    """The XY cutting moves of a written program."""
    return [t for t in lines if re.match(r"G[123] X", t)]


# ---------------------------------------------------------------------------
# the file itself


def test_golden(tmp_path, groove_example, golden):
    out = tmp_path / "example.ngc"
    write_gcode(out, groove_example, Tool(), Machining(), header={"model": "golden example"})
    golden(out, "example.ngc")


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
    write_gcode(out, g, Tool(), Machining())
    cuts = [t.split()[0] for t in cut_lines(lines_of(out))]
    assert cuts == ["G1", "G3", "G1", "G1", "G3", "G3"]
    np.testing.assert_array_equal(is_straight(g.segments()),
                                  [True, False, True, True, False, False])


def test_rejects_bad_grooves(tmp_path):
    bad = Grooves(np.array([[0.0, np.nan]]), np.zeros(1), np.array([0, 1]), np.array([0]))
    with pytest.raises(SpecholoError):
        write_gcode(tmp_path / "x.ngc", bad, Tool(), Machining())
    assert not (tmp_path / "x.ngc").exists()


@pytest.mark.parametrize("writer", ["gcode", "svg"])
def test_decimal_point_ignores_locale(tmp_path, groove_example, writer):
    from specholo.fabrication.svg import write_svg

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
# LinuxCNC's interpreter


@needs_rs274
def test_rs274_cuts_the_example(tmp_path, groove_example):
    out = tmp_path / "example.ngc"
    write_gcode(out, groove_example, Tool(), Machining(), header={"model": "example"})
    check_canon(run_rs274(out), groove_example, Tool(), Machining())


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
    )
    out = tmp_path / "random.ngc"
    write_gcode(out, g, tool, machining, header={"note": data.draw(st.text(max_size=30))})
    check_canon(run_rs274(out), g, tool, machining)


@needs_rs274
def test_rs274_large_program(tmp_path):
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
    write_gcode(out, g, Tool(), Machining())
    check_canon(run_rs274(out), g, Tool(), Machining())
    back = read_gcode(out)
    np.testing.assert_array_equal(back.offsets, g.offsets)
    np.testing.assert_allclose(back.vertices, g.vertices, atol=1e-4)


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
    write_gcode(out, g, Tool(), Machining())
    assert_round_trip(read_gcode(out), g)


def test_short_arcs_keep_their_tangents(tmp_path):
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
    write_gcode(out, g, Tool(), Machining())
    back = read_gcode(out).segments()

    def start_tangent(segs) -> np.ndarray:
        d = segs.end - segs.start
        return np.arctan2(d[:, 1], d[:, 0]) + 2 * np.arctan(segs.bulge)

    turn = np.angle(np.exp(1j * (start_tangent(back) - start_tangent(g.segments()))))
    # each end moves by up to e across the chord
    e = np.sqrt(0.5) / SCALE
    assert np.all(np.abs(turn) <= 2.2 * e / chord + 1e-6)


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

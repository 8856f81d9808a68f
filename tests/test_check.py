"""The independent G-code safety check: written programs pass, bad ones are caught."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_gcode import check_canon, hopping_example, needs_rs274, run_rs274

from specholo.errors import SpecholoError
from specholo.fabrication.check import CheckReport, Limits, Stock, check_gcode, check_limits
from specholo.fabrication.programs.gcode import write_gcode
from specholo.fabrication.programs.program import DIALECTS, GcodeOptions
from specholo.setup import Machining, Tool
from specholo.toolpaths.grooves import Grooves

PLATE = Stock(-40.0, -30.0, 40.0, 30.0, thickness=3.0)
MACHINING = Machining(feed=300.0, plunge=100.0, safe_z=1.0, spindle=12000.0)
TOOL = Tool()


def check_written(path: Path, options: GcodeOptions, stock: Stock = PLATE,
                  tool: Tool = TOOL, machining: Machining = MACHINING) -> CheckReport:
    """Check a program with the limits it was written for."""
    laser = not options.mill
    rates = (min(machining.feed, machining.plunge), max(machining.feed, machining.plunge))
    power = options.laser_power if laser else machining.spindle
    return check_gcode(path, stock, tool.depth, machining.safe_z, rates, (power, power),
                       laser=laser)


def run(tmp_path: Path, program: str, stock: Stock = PLATE, laser: bool = False,
        **limits) -> CheckReport:
    path = tmp_path / "p.ngc"
    path.write_text(program)
    args = {"max_depth": 0.1, "safe_z": 1.0, "feed_range": (10.0, 1000.0),
            "spindle_range": (1000.0, 24000.0), **limits}
    return check_gcode(path, stock, laser=laser, **args)


def caught(report: CheckReport) -> list[tuple[int, str]]:
    return [(v.line, v.what) for v in report.violations]


START = "G21 G90 G17 G94\nM3 S12000\nG0 Z1\nG0 X0 Y0\nG1 Z-0.08 F100\n"  # 5 lines


# ---------------------------------------------------------------------------
# programs the writer makes


@pytest.mark.parametrize("units", ["mm", "inch"])
@pytest.mark.parametrize("dialect", DIALECTS)
def test_written_programs_pass(tmp_path, groove_example, dialect, units):
    out = tmp_path / "x.ngc"
    options = GcodeOptions(dialect=dialect, units=units)
    write_gcode(out, groove_example, Tool(), MACHINING, options=options)
    report = check_written(out, options)
    assert report.ok, report.summary()
    cuts = {"G1": 1, "G2": 2, "G3": 2}  # the example's cuts by kind
    if options.mill:
        # three plunges, three retracts and XY rapids, the first move to safe Z
        assert report.moves == {"G0": 7, "G1": 1 + 3, "G2": 2, "G3": 2, "dwell": 1,
                                "cutting": 5 + 3}
    else:
        assert report.moves == {"G0": 3, **cuts, "dwell": 1, "cutting": 5 + 1}
    # the first arc dips to y = -2.5 between ends at y = 0; the dot sits at y = -5
    tight = Stock(-6.0, -2.4, 21.0, 11.0, 3.0)
    bad = check_written(out, options, stock=tight)
    lines = out.read_text().splitlines()
    flagged = [lines[v.line - 1].split()[0] for v in bad.violations]
    assert flagged == ["G3", "G1" if options.mill else "G4"], bad.summary()


def test_report_summary(tmp_path):
    report = run(tmp_path, START + "G1 X99 F200\nG0 Z1\nG0 X0 Y0\nG1 Z-5 F100\n")
    text = report.summary()
    assert "2 violation(s)" in text and "line 6:" in text and "line 9:" in text
    assert "[G1 X99 F200]" in text
    limited = run(tmp_path, START + "G1 X99 F200\n" * 5, max_listed=2)
    assert limited.total_violations == 5 and len(limited.violations) == 2
    assert "and 3 more" in limited.summary()


# ---------------------------------------------------------------------------
# hand-made bad programs, each caught on its line


@pytest.mark.parametrize(("body", "line", "what"), [
    # a rapid through the stock: X/Y travel at cutting depth
    ("G0 X5 Y5\n", 6, "rapid in X/Y below the safe height"),
    # rapids that come down below the safe height, straight or sideways
    ("G0 Z1\nG0 Z0.5\n", 7, "rapid down to Z 0.50000, below the safe height 1"),
    ("G0 Z1\nG0 X3 Z-0.08\n", 7, "rapid in X/Y below the safe height"),
    # cuts leaving the stock
    ("G1 X45 Y0 F200\n", 6, "cut leaves the stock"),
    ("G1 Y-31 F200\n", 6, "cut leaves the stock"),
    # a cut too deep
    ("G1 Z-0.2\n", 6, "cut to Z -0.20000, deeper than 0.1"),
    # F0, or no F at all
    ("G1 X1 F0\n", 6, "feed move with zero feed"),
    ("G1 X1 F5000\n", 6, "feed 5000 mm/min outside [10, 1000]"),
    # the spindle stopped, or switched on too fast
    ("M5\nG1 X1 F200\n", 7, "cut with the spindle off"),
    ("S0\nG1 X1 F200\n", 7, "cut with the spindle off"),
    ("M3 S30000\n", 6, "spindle speed S30000 outside [1000, 24000]"),
    # things it cannot vouch for
    ("T2 M6\n", 6, "unsupported word T"),
    ("G18\n", 6, "unsupported G18"),
    ("G93\n", 6, "unsupported G93"),
    ("M98\n", 6, "unsupported M98"),
    ("G1 X1 (open comment\n", 6, "cannot parse: unclosed comment"),
    ("G1 X1,5\n", 6, "cannot parse"),
    ("G1 X1 X2\n", 6, "X given twice"),
    ("G0 G1 X1\n", 6, "two motion codes on one line"),
    ("G1 X2 I1 J0\n", 6, "I/J/R words in a G1 move"),
    ("G2 X2 Y0 I1.5 J0 F200\n", 6, "arc end is off its circle"),
    ("G2 X1 Y0 R0.2 F200\n", 6, "R 0.2 too small"),
    ("G0 Z1\nM2\nG0 X1\n", 8, "move after the program end"),
    ("G80\nX1\n", 7, "axis words without a motion mode"),
])
def test_catches(tmp_path, body, line, what):
    report = run(tmp_path, START + body)
    assert report.total_violations >= 1
    first = report.violations[0]
    assert (first.line, first.what[:len(what)]) == (line, what), report.summary()
    assert first.text == (START + body).splitlines()[line - 1].strip()


def test_catches_an_arc_bulging_out_of_the_stock(tmp_path):
    # both ends inside (|x| = 8, y = 9), the arcs around a centre at (0, 3) of
    # radius 10: clockwise over the top reaches y = 13, anticlockwise round the
    # bottom stays within x = +-10 and y >= -7
    stock = Stock(-11.0, -11.0, 11.0, 11.0, 3.0)
    go = "G21 G90\nM3 S12000\nG0 Z1\nG0 X-8 Y9\nG1 Z-0.05 F100\n"
    assert run(tmp_path, go + "G3 X8 Y9 I8 J-6\n", stock).ok
    report = run(tmp_path, go + "G2 X8 Y9 I8 J-6\n", stock)
    assert caught(report) == [(6, "cut leaves the stock: X -8.00000..8.00000, "
                                  "Y 9.00000..13.00000 outside X -11..11, Y -11..11")]
    # the same by radius: R > 0 the shorter arc (over the top for G2), R < 0 the longer
    assert caught(run(tmp_path, go + "G2 X8 Y9 R10\n", stock))[0][0] == 6
    assert run(tmp_path, go + "G3 X8 Y9 R10\n", stock).ok
    report = run(tmp_path, go + "G3 X8 Y9 R-10\n", stock)  # round the far side, to y = -7...
    assert report.ok
    report = run(tmp_path, go + "G2 X8 Y9 R-10\n", stock)  # ...or round (0, 15) up to y = 25
    assert caught(report)[0] == (6, "cut leaves the stock: X -10.00000..10.00000, "
                                    "Y 9.00000..25.00000 outside X -11..11, Y -11..11")
    # a full circle (I J with the end at the start) is checked whole
    report = run(tmp_path, go + "G2 X-8 Y9 I8 J-6\n", stock)
    assert "Y -7.00000..13.00000" in caught(report)[0][1]


def test_incremental_and_inch_programs(tmp_path):
    program = ("G20 G91\nM3 S12000\nG90 G0 Z0.04\nG0 X1 Y1\nG91 G1 Z-0.042 F4\n"
               "G1 X0.1\nG3 X0.1 Y0 I0.05 J0\nG0 Z0.042\nM5\nM30\n")
    # 1 inch = 25.4 mm: the cut runs from x = 25.4 to 30.48 mm at y = 25.4 mm
    stock = Stock(-26.0, -26.0, 31.0, 27.0, 3.0)
    report = run(tmp_path, program, stock, max_depth=0.1, safe_z=1.0,
                 feed_range=(50.0, 120.0))
    assert report.ok, report.summary()
    assert report.moves["cutting"] == 3
    narrow = Stock(-26.0, -26.0, 30.0, 27.0, 3.0)
    assert caught(run(tmp_path, program, narrow, feed_range=(50.0, 120.0)))[0][0] == 7
    # the feed is in inch/min: 4 in/min = 101.6 mm/min
    report = run(tmp_path, program, stock, feed_range=(10.0, 100.0))
    assert caught(report)[0] == (5, "feed 101.6 mm/min outside [10, 100]")


def test_unknown_start_positions(tmp_path):
    assert caught(run(tmp_path, "M3 S12000\nG0 X1 Y1\n")) == [
        (2, "rapid in X/Y at an unknown height")]
    assert caught(run(tmp_path, "M3 S12000\nG0 Z1\nG1 Z-0.05 F100\n")) == [
        (3, "feed move from an unknown position")]
    assert caught(run(tmp_path, "G91\nG0 Z1\n")) == [(2, "incremental Z from an unknown position")]
    # a rapid straight up from anywhere is fine
    assert run(tmp_path, "G0 Z5\nG0 X1 Y1\n").ok


def test_laser_checks(tmp_path):
    go = "G21\nG90\nM5\nG0 X0 Y0 F3000\nM3 S200\n"  # 5 lines
    limits = {"spindle_range": (100.0, 255.0)}
    assert run(tmp_path, go + "G1 X5 F300\nG4 P100\nM5\nG0 X39 Y29\n", laser=True, **limits).ok
    assert caught(run(tmp_path, go + "G0 X5\n", laser=True, **limits)) == [
        (6, "rapid with the laser on")]
    assert caught(run(tmp_path, go + "G1 X41 F300\n", laser=True, **limits))[0][0] == 6
    assert caught(run(tmp_path, "G0 X50 Y0\nM3 S200\nG4 P100\n", laser=True, **limits))[0] == (
        3, "cut leaves the stock: X 50.00000..50.00000, Y 0.00000..0.00000 outside "
           "X -40..40, Y -30..30")
    assert caught(run(tmp_path, go + "S300\n", laser=True, **limits)) == [
        (6, "laser power S300 outside [100, 255]")]
    # with the laser off, feed moves are travel and may leave the stock
    assert run(tmp_path, go + "M5\nG1 X60 F300\n", laser=True, **limits).ok


def hop_limits(machining: Machining = MACHINING, **change) -> Limits:
    """The limits of a job that hops as ``machining`` says and cuts at TOOL's depth."""
    args = {"hop_max": machining.hop_max, "hop": machining.hop, "groove_depth": TOOL.depth,
            **change}
    return Limits(PLATE, TOOL.depth, machining.safe_z, (machining.plunge, machining.feed),
                  (machining.spindle, machining.spindle), **args)


def test_hops_pass_and_bad_hops_are_refused(tmp_path):
    out = tmp_path / "hops.ngc"
    write_gcode(out, hopping_example(), TOOL, MACHINING)
    report = check_limits(out, hop_limits())
    assert report.ok, report.summary()
    assert report.moves["G1"] == 4 + 1 + 2  # plunges, a straight cut and two hops
    lines = out.read_text().splitlines()
    hops = [i + 1 for i, ln in enumerate(lines) if lines[i - 1].startswith("(stipple")
            and ln.startswith("G1 X")]
    assert len(hops) == 2

    def refused(limits: Limits, program: list[str] = lines) -> list[tuple[int, str]]:
        path = tmp_path / "bad.ngc"
        path.write_text("\n".join(program) + "\n")
        return caught(check_limits(path, limits))

    # longer than the job allows (the first hop is 0.5 mm, the second 2 mm)
    assert refused(hop_limits(hop_max=1.0)) == [(hops[1], (
        "feed move of 2.00000 mm in X/Y between the surface and the safe height 1: longer "
        "than the longest hop 1 mm"))]
    assert [line for line, _ in refused(hop_limits(hop_max=0.0))] == hops
    # too low: at the surface or just above it, the tip would drag over the plate
    for z in ("0.00000", "0.01000"):
        low = [ln.replace("G0 Z0.03000", f"G0 Z{z}") for ln in lines]
        assert refused(hop_limits(), low) == [
            (h, f"feed move in X/Y {float(z):.5f} above the surface: below the hop height "
                "0.03") for h in hops]
    # through the material: a cut, but at no groove's depth
    dip = [ln.replace("G0 Z0.03000", "G0 Z-0.04000") for ln in lines]
    assert refused(hop_limits(), dip) == [
        (h, "cut in X/Y at Z -0.04000, not at the groove depth -0.08") for h in hops]
    # a job that does not hop lets the check say nothing of such moves, as before
    assert refused(hop_limits(hop_max=None, groove_depth=None), low) == []
    # a hop over the edge of the stock (toward the clamps), or round a wide arc
    def go(x: float, hop: str) -> list[str]:
        return (f"G21 G90\nM3 S12000\nG0 Z1\nG0 X{x} Y0\nG1 Z-0.08 F100\nG1 X{x + 0.5} F300\n"
                f"G0 Z0.03\n{hop}\n").splitlines()

    assert refused(hop_limits(), go(39, "G1 X41 F300")) == [(8, (
        "hop leaves the stock: X 39.50000..41.00000, Y 0.00000..0.00000 outside X -40..40, "
        "Y -30..30"))]
    arc = refused(hop_limits(), go(0, "G2 X0.6 Y0 I0.05 J2 F300"))
    assert len(arc) == 1 and arc[0][0] == 8 and "longer than the longest hop" in arc[0][1]
    assert float(arc[0][1].split()[3]) == pytest.approx(2 * math.pi * math.hypot(0.05, 2),
                                                        rel=0.01)


def test_rejects_bad_limits(tmp_path):
    path = tmp_path / "p.ngc"
    path.write_text("G0 Z1\n")
    with pytest.raises(SpecholoError, match=re.escape("feed range must be two finite numbers")):
        check_gcode(path, PLATE, 0.1, 1.0, (500.0, 100.0), (0.0, 1.0))
    with pytest.raises(SpecholoError, match="safe z must be a finite number >= 0, got nan"):
        check_gcode(path, PLATE, 0.1, math.nan, (1.0, 2.0), (0.0, 1.0))
    with pytest.raises(SpecholoError, match="cannot read"):
        check_gcode(tmp_path / "nope.ngc", PLATE, 0.1, 1.0, (1.0, 2.0), (0.0, 1.0))
    with pytest.raises(SpecholoError, match=re.escape("x0 < x1")):
        Stock(1.0, 0.0, -1.0, 1.0, 1.0)
    with pytest.raises(SpecholoError, match="thickness must be positive, got 0"):
        Stock.centred(10.0, 10.0, 0.0)


# ---------------------------------------------------------------------------
# random designs: every dialect passes, the mill dialects cut exactly the arcs


def arc_box(g: Grooves) -> np.ndarray:
    """Bounds of the cuts (2, 2), by dense sampling of every arc (not the checker's method)."""
    pts = [g.vertices]
    segs = g.segments()
    if len(segs):
        t = np.linspace(0.0, 1.0, 2001)
        sweep = 4.0 * np.arctan(segs.bulge)
        d = segs.end - segs.start
        chord = np.linalg.norm(d, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(np.abs(sweep[:, None]) > 1e-9,
                             np.sin(0.5 * t[None] * sweep[:, None]) / np.sin(0.5 * sweep[:, None]),
                             t[None])
        turn = 0.5 * sweep[:, None] * (t[None] - 1.0)
        u = d / np.maximum(chord, 1e-300)[:, None]
        dx = u[:, :1] * np.cos(turn) - u[:, 1:] * np.sin(turn)
        dy = u[:, :1] * np.sin(turn) + u[:, 1:] * np.cos(turn)
        length = chord[:, None] * ratio
        pts.append(np.stack([segs.start[:, :1] + length * dx,
                             segs.start[:, 1:] + length * dy], axis=-1).reshape(-1, 2))
    allp = np.concatenate(pts)
    return np.stack([allp.min(axis=0), allp.max(axis=0)])


@st.composite
def plate_designs(draw: st.DrawFn) -> Grooves:
    """Grooves on an 80 x 60 mm plate: short chains of arcs (some wide), and dots."""
    verts: list[np.ndarray] = []
    bulges: list[float] = []
    sizes: list[int] = []
    for _ in range(draw(st.integers(1, 6))):
        p = np.array([draw(st.floats(-30.0, 30.0)), draw(st.floats(-20.0, 20.0))])
        k = draw(st.integers(0, 4))
        verts.append(p)
        for _ in range(k):
            angle = draw(st.floats(-math.pi, math.pi))
            p = p + draw(st.floats(0.01, 2.0)) * np.array([math.cos(angle), math.sin(angle)])
            verts.append(p)
            bulges.append(draw(st.one_of(st.just(0.0), st.floats(-2.0, 2.0),
                                         st.floats(-3e-4, 3e-4))))
        bulges.append(0.0)
        sizes.append(k + 1)
    return Grooves(np.array(verts), np.array(bulges),
                   np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                   np.arange(len(sizes), dtype=np.int64))


@needs_rs274
@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(g=plate_designs(), units=st.sampled_from(["mm", "inch"]),
       spindle=st.sampled_from([0.0, 10000.0]))
def test_random_designs(tmp_path, g, units, spindle):
    machining = Machining(feed=250.0, plunge=80.0, safe_z=2.0, spindle=spindle)
    tool = Tool(radius=0.2, depth=0.05)
    lo, hi = arc_box(g)
    stock = Stock(lo[0], lo[1], hi[0], hi[1], 1.0) if np.all(hi > lo) else \
        Stock(lo[0] - 1, lo[1] - 1, hi[0] + 1, hi[1] + 1, 1.0)
    for dialect in DIALECTS:
        options = GcodeOptions(dialect=dialect, units=units)
        out = tmp_path / f"{dialect}.ngc"
        write_gcode(out, g, tool, machining, options=options)
        report = check_written(out, options, stock, tool, machining)
        if options.mill and spindle == 0:
            # cutting with the spindle left alone is flagged, and nothing else
            assert report.violations and {v.what for v in report.violations} == {
                "cut with the spindle off"}
        else:
            assert report.ok, report.summary()
        if np.all(hi - lo > 0.05):  # a stock 0.01 mm smaller all round is too small
            smaller = Stock(lo[0] + 0.01, lo[1] + 0.01, hi[0] - 0.01, hi[1] - 0.01, 1.0)
            leaves = [v for v in check_written(out, options, smaller, tool, machining).violations
                      if v.what.startswith("cut leaves the stock")]
            assert leaves
        if options.mill:
            check_canon(run_rs274(out), g, tool, machining, options)


# ---------------------------------------------------------------------------
# the compiled reading of plain lines reads as the line-by-line reader does


def _random_program(rng: np.random.Generator, lines: int) -> str:
    """Plain moves in many spellings among comments, modal changes and bad lines."""
    def num(signed: bool = True) -> str:
        v = rng.normal(0.0, 20.0)
        text = rng.choice([f"{v:.5f}", f"{v:.1f}", f"{v:.0f}.", f"{v:.3f}".replace("0.", "."),
                           f"{abs(v):.4f}", f"+{abs(v):.2f}", f"{v:.17f}", "-0", "0"])
        return text.lstrip("+-") if not signed else text

    odd = ["(stipple 7)", "  (a) (b)  ", "", "   ", "M3 S12000", "M5", "G91", "G90", "G20",
           "G21", "G0 Z1", "G1 Z-0.05 F100", "(nested (comment))", "(unclosed", "G1 X1 (c)",
           "g1 x2 y3", "G1 X 2", "/G1 X3 Y3", "%", "G4 P0.5", "G2 X1 Y1 R5", "G1 I1 J1",
           "G10", "G1.5 X1", "G1 Y1 X2", "G1 X1 X2", "G1 X1 ; note", "M2", "G1 F-5 X1",
           "G3 X\u00e91 Y0", "G1 X1e3", "G1\tX1\tY2", "G00 X1", "G001 Y2", "G03 X1 Y1 I1 J0",
           "G2 X1 Y1 I1 J0 P2", "G3 X2 Y0 I1 J0 P1.5 F200", "G2 X0 Y0 I3 J0 P3", "X1 Y2 I1 P2",
           "(" + "long " * 60 + ")", "G1 X1 Y1 F200 (" + "a" * 300 + ")"]
    out = []
    for _ in range(lines):
        u = rng.random()
        if u < 0.6:
            g = rng.choice(["G0", "G1", "G2", "G3", "G01", "G02", "G03", "G00"])
            words = [f"{w}{num(w != 'F')}" for w in "XYZIJF" if rng.random() < 0.5]
            sep = rng.choice([" ", "", "  ", "\t"])
            out.append(g + sep + sep.join(words) + rng.choice(["", " ", "\t"]))
        else:
            out.append(str(rng.choice(odd)))
    return "\n".join(out)


def _full_report(path) -> dict:
    """Every figure and violation of a check against a tight stock."""
    tight = Stock(-15.0, -15.0, 15.0, 15.0, 3.0)
    r = check_gcode(path, tight, 0.1, 1.0, (10.0, 1000.0), (1000.0, 24000.0), max_listed=10**6)
    return {"lines": r.lines, "moves": r.moves, "total": r.total_violations,
            "violations": r.violations}


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("ending", ["\n", "\r\n"])
def test_compiled_reading_gives_the_line_by_line_report(tmp_path, monkeypatch, seed, ending):
    import specholo.fabrication.check as check

    rng = np.random.default_rng(seed)
    program = START + _random_program(rng, 3000) + ("\n" if seed % 2 else "")
    path = tmp_path / "p.ngc"
    path.write_bytes(program.replace("\n", ending).encode("utf-8"))

    def report() -> dict:
        return _full_report(path)

    # Blocks far smaller than a line's worth of bytes, and of a few lines, so
    # that lines and blocks of moves straddle every boundary.
    monkeypatch.setattr(check, "_READ_BYTES", 97)
    monkeypatch.setattr(check, "_BLOCK_LINES", 7)
    fast = report()
    assert fast["moves"]["G2"] + fast["moves"]["G3"] > 100 and fast["total"] > 100

    def refuse(*args):
        raise check._LoneReturn

    monkeypatch.setattr(check, "_read_bytes", refuse)
    assert report() == fast
    assert fast["lines"] == len(program.splitlines())


@pytest.mark.parametrize("seed", range(3))
def test_moves_checked_in_two_threads_give_the_same_report(tmp_path, monkeypatch, seed):
    """Each block's rows split between two threads beside the reading: the same
    violations in the same order as checked in the reading thread."""
    import specholo.fabrication.check as check

    rng = np.random.default_rng(100 + seed)
    path = tmp_path / "p.ngc"
    path.write_text(START + _random_program(rng, 3000) + "\n")

    def report() -> dict:
        return _full_report(path)

    monkeypatch.setattr(check, "_BLOCK_LINES", 50)
    monkeypatch.setattr(check, "_SPLIT_ROWS", 1)
    split = report()
    assert split["total"] > 100
    monkeypatch.setattr(check, "concurrent_kernels_safe", lambda: False)
    assert report() == split


def test_a_carriage_return_alone_ends_a_line(tmp_path):
    path = tmp_path / "p.ngc"
    path.write_bytes((START.replace("\n", "\r") + "G1 X99 F200\rG0 Z1\r").encode())
    report = check_gcode(path, PLATE, 0.1, 1.0, (10.0, 1000.0), (1000.0, 24000.0))
    assert report.lines == 7
    assert caught(report) == [(6, "cut leaves the stock: X 0.00000..99.00000, Y 0.00000..0.00000 "
                                  "outside X -40..40, Y -30..30")]

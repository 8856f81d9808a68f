"""Holders as they are: a spring holder's tip leaves the plate only above its
lift, a rigid holder's plate is probed and its program levelled to it.

- A spring program (the drag tip's default) cuts at exactly -preload and runs
  no other X/Y move below the lift height; the check flags one edited to hop
  at a rigid holder's 0.03 mm; rs274 reads it.
- The probe program's points cover the grooves at the spacing, and rs274 reads
  it in both dialects.
- A probed plane or a curved (bilinear) map applied to a program puts every
  cut's Z at -depth plus the plate's height under it within 1 um, at its ends,
  along its moves and at the map's nodes; a log that does not cover the
  grooves, too short or unreadable, is refused in one line and nothing is
  written.
- The time estimate of a spring program counts one lift and one lower a stroke.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from test_gcode import needs_rs274, run_rs274

from specholo.errors import SpecholoError
from specholo.fabrication.check import (
    Limits,
    Stock,
    check_limits,
    check_program,
    limits_from_header,
)
from specholo.fabrication.exporting import drawn_extent
from specholo.fabrication.programs.gcode import write_gcode
from specholo.fabrication.programs.leveling import (
    FOLLOW,
    level_program,
    leveled_limits,
    read_probe_log,
)
from specholo.fabrication.programs.program import GcodeOptions
from specholo.fabrication.programs.timing import estimate_time, trapezoid_time
from specholo.jobs.flat.folder import DesignConfig
from specholo.setup import SPRING_LIFT, Holder, Machining, Tool
from specholo.toolpaths.grooves import Grooves
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
#: The written grid's rounding (5 decimals in mm) on top of the levelling's 1 um.
WRITTEN = 1e-5
_WORD = re.compile(r"([A-Z])([-+]?\d*\.?\d+)")


def _run(argv: list[object], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """A command's exit status and output (``check`` exits 1 itself on a fault)."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err.strip()


@pytest.fixture(scope="module")
def designs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A 60-stipple bunny held in a spring holder (the drag tip's default) and
    held rigid."""
    tmp = tmp_path_factory.mktemp("holders")
    out = {}
    for name, extra in (("spring", []), ("rigid", ["--holder", "rigid"])):
        folder = tmp / name
        assert main(["design", str(BUNNY), "--out", str(folder), "--stipples", "60",
                     *extra]) == 0
        out[name] = folder
    return out


def _moves(lines: list[str]) -> list[dict]:
    """Every motion line of a program (mm): kind, start and end (x, y, z), the arc's
    centre, the line's index; a line of its own reading, not the library's."""
    pos = [math.nan, math.nan, math.nan]
    factor, motion = 1.0, -1
    moves = []
    for n, line in enumerate(lines):
        body = re.sub(r"\([^)]*\)", "", line).split(";")[0].upper().replace(" ", "")
        words = dict.fromkeys("XYZIJ", None)
        for k, v in _WORD.findall(body):
            if k == "G" and float(v) in (0, 1, 2, 3):
                motion = int(float(v))
            elif k == "G" and float(v) in (20, 21):
                factor = 25.4 if float(v) == 20 else 1.0
            elif k in words:
                words[k] = float(v) * factor
        if all(words[k] is None for k in "XYZ"):
            continue
        end = [words[k] if words[k] is not None else pos[i] for i, k in enumerate("XYZ")]
        centre = (pos[0] + (words["I"] or 0.0), pos[1] + (words["J"] or 0.0)) \
            if motion >= 2 else None
        moves.append({"kind": motion, "start": tuple(pos), "end": tuple(end),
                      "centre": centre, "line": n})
        pos = end
    return moves


def _moves_xy(m: dict) -> bool:
    (x0, y0, _), (x1, y1, _) = m["start"], m["end"]
    return not math.isnan(x0) and (abs(x1 - x0) > 1e-9 or abs(y1 - y0) > 1e-9)


def _point_along(m: dict, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (x, y, z) at fractions ts along a move as a machine runs it: Z
    linear along a line, linear in the angle along a helix."""
    (x0, y0, z0), (x1, y1, z1) = m["start"], m["end"]
    z = z0 + ts * (z1 - z0)
    if m["centre"] is None:
        return x0 + ts * (x1 - x0), y0 + ts * (y1 - y0), z
    cx, cy = m["centre"]
    a0, a1 = math.atan2(y0 - cy, x0 - cx), math.atan2(y1 - cy, x1 - cx)
    sweep = (a1 - a0) % (2 * math.pi) if m["kind"] == 3 else -((a0 - a1) % (2 * math.pi))
    r0, r1 = math.hypot(x0 - cx, y0 - cy), math.hypot(x1 - cx, y1 - cy)
    th, r = a0 + ts * sweep, r0 + ts * (r1 - r0)
    return cx + r * np.cos(th), cy + r * np.sin(th), z


# ---------------------------------------------------------------- spring holders


def test_a_spring_program_never_drags_its_tip_off_a_cut(designs: dict[str, Path]) -> None:
    """Every G0/G1/G2/G3 moving in X/Y below the lift height is a cut at exactly
    -preload; the lifts are at least SPRING_LIFT; the header says how to touch off."""
    folder = designs["spring"]
    lines = (folder / "hologram.gcode").read_text().splitlines()
    info = json.loads((folder / "hologram.json").read_text())
    preload, lift = info["machining"]["preload_mm"], info["machining"]["spring_lift_mm"]
    assert info["settings"]["holder"] == "spring" and preload == 0.3
    assert lift >= SPRING_LIFT
    cuts = other = 0
    for m in _moves(lines):
        if not _moves_xy(m):
            continue
        z0, z1 = m["start"][2], m["end"][2]
        if min(z0, z1) < lift - 1e-9:
            assert m["kind"] > 0 and z0 == z1 == -preload, lines[m["line"]]
            cuts += 1
        else:
            other += 1
    assert cuts > 1000 and other > 100
    head = "\n".join(lines[:30])
    assert "touch-off:" in head and "paper shim" in head and "preload:" in head
    assert "expected: the spring's force at 0.3 mm of preload sets it" in head
    limits = limits_from_header(folder / "hologram.gcode")
    assert limits is not None and limits.holder == "spring" and limits.lift == lift
    assert limits.groove_depth == preload
    assert check_limits(folder / "hologram.gcode", limits).ok


def test_the_check_flags_a_spring_program_hopping_low(designs: dict[str, Path], tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    """The spring program edited to hop at a rigid holder's 0.03 mm, or to run a
    hop between -preload and the surface: `specholo check` with no options
    flags every such hop as a scratch."""
    text = (designs["spring"] / "hologram.gcode").read_text()
    hops = text.count("G0 Z0.05000\n")
    assert hops > 100
    for low, why in (("0.03000", "0.03000"), ("-0.10000", "-0.10000")):
        bad = tmp_path / f"hop{low}.gcode"
        bad.write_text(text.replace("G0 Z0.05000\n", f"G0 Z{low}\n"))
        code, out, _ = _run(["check", bad], capsys)
        assert code == 1
        assert f"{hops} violation(s)" in out, out[:300]
        assert f"at Z {why}: a spring holder's tip touches the plate below the lift 0.05 " \
               "(a scratch)" in out
    # a cut run at another Z than the preload is one too
    bad = tmp_path / "shallow.gcode"
    bad.write_text(text.replace("G1 Z-0.30000 F100", "G1 Z-0.20000 F100", 1))
    code, out, _ = _run(["check", bad], capsys)
    assert code == 1 and "at Z -0.20000: a spring holder's tip touches" in out


@needs_rs274
@pytest.mark.parametrize("units", ["mm", "inch"])
def test_rs274_runs_a_spring_program(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                     units: str) -> None:
    """LinuxCNC's interpreter reads a spring program: its feed moves in X/Y run
    at -preload or at the lift or above, never between."""
    out = tmp_path / "d"
    code, _, err = _run(["design", BUNNY, "--out", out, "--stipples", "8", "--size", "30",
                         "--dialect", "linuxcnc", "--units", units, "--preload", "0.5"],
                        capsys)
    assert code == 0, err
    factor = 25.4 if units == "inch" else 1.0
    pos = None
    seen = set()
    for name, args in run_rs274(out / "hologram.gcode"):
        if name not in ("STRAIGHT_FEED", "ARC_FEED", "STRAIGHT_TRAVERSE"):
            continue
        a = [float(v) * factor for v in args.split(",")[:6]]
        end = (a[0], a[1], a[5] if name == "ARC_FEED" else a[2])
        if pos is not None and math.hypot(end[0] - pos[0], end[1] - pos[1]) > 1e-3:
            low = min(pos[2], end[2])
            assert abs(low + 0.5) < 2e-3 or low >= SPRING_LIFT - 2e-3, (name, args)
            seen.add("cut" if low < 0 else "air")
        pos = end
    assert seen == {"cut", "air"}


def test_holder_settings_and_their_refusals(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    defaults = {t: DesignConfig(tool=t).holder for t in ("drag", "scriber", "ball", "vbit",
                                                           "laser")}
    assert defaults == {"drag": "spring", "scriber": "spring", "ball": "rigid",
                        "vbit": "rigid", "laser": None}
    assert DesignConfig().preload == 0.3 and DesignConfig(tool="ball").preload is None
    assert DesignConfig(spindle=1000.0).holder == "rigid"  # the spindle holds what it turns
    for values, words in (({"tool": "ball", "holder": "spring"}, "held rigid"),
                          ({"holder": "rigid", "preload": 0.2}, "add --holder spring"),
                          ({"preload": 0.01}, "preload 0.01 mm is out of range"),
                          ({"preload": 3.0}, "preload 3 mm is out of range"),
                          ({"tool": "laser", "holder": "rigid"}, "a laser has no holder"),
                          ({"holder": "spring", "spindle": 1000.0}, "does not spin"),
                          ({"holder": "floating"}, "holder must be one of rigid, spring")):
        with pytest.raises(SpecholoError, match=words) as info:
            DesignConfig.from_dict(values)
        assert "\n" not in str(info.value)
    code, _, err = _run(["design", BUNNY, "--out", tmp_path / "x", "--tool", "vbit",
                         "--holder", "spring"], capsys)
    assert code == 1 and len(err.splitlines()) == 1 and "held rigid" in err
    assert not (tmp_path / "x").exists()


def test_a_rigid_program_names_the_flatness_its_depth_needs(designs: dict[str, Path]) -> None:
    head = (designs["rigid"] / "hologram.gcode").read_text().splitlines()[:30]
    flat = next(line for line in head if line.startswith("(flatness:"))
    assert "known to 0.005 mm over X" in flat and "specholo probe" in flat
    assert any(line.startswith("(holder: rigid; cuts at Z-0.011") for line in head)
    limits = limits_from_header(designs["rigid"] / "hologram.gcode")
    assert limits is not None and limits.holder == "rigid" and limits.lift is None


# ---------------------------------------------------------------- the estimate


def test_the_estimate_counts_one_lift_and_one_lower_a_stroke(designs: dict[str, Path]) -> None:
    """A spring program's estimate against the same grooves held rigid: the
    strokes, the hops and the X/Y moves are the same, and every stroke lowers
    from its lift (or the safe height) to -preload and lifts back, where a
    rigid one plunges to -depth from the hop height: the difference is exactly
    that, stroke by stroke."""
    folder = designs["spring"]
    grooves = Grooves.load(folder / "grooves.npz")
    info = json.loads((folder / "hologram.json").read_text())
    lines = (folder / "hologram.gcode").read_text().splitlines()
    m = Machining(spindle=0.0)  # the design's feeds and heights
    depth = float(info["settings"]["depth"])  # as the design chose it
    spring_depth, spring_m = Holder("spring").program(depth, m)
    rigid = estimate_time(grooves, depth, m)
    spring = estimate_time(grooves, spring_depth, spring_m)
    n, hops = grooves.n_paths, spring.hops
    # the program: one lower a stroke, one lift a stroke (to the lift or the safe height)
    lowers = sum(line.startswith("G1 Z-0.30000") for line in lines)
    lifts = sum(line in ("G0 Z0.05000", "G0 Z1.00000") for line in lines) - 1  # less the start
    assert lowers == lifts == n and hops == rigid.hops == lines.count("G0 Z0.05000")
    assert spring.cutting_s == rigid.cutting_s and spring.hop_s == rigid.hop_s

    def each(rate: float, spring_z: float, rigid_z: float) -> float:
        t = trapezoid_time(np.array([spring_z, rigid_z]), rate / 60.0, 250.0)
        return float(t[0] - t[1])

    lift = spring_m.hop
    plunges = hops * each(m.plunge, lift + 0.3, m.hop + depth) + \
        (n - hops) * each(m.plunge, m.safe_z + 0.3, m.safe_z + depth)
    rises = hops * each(3000.0, lift + 0.3, m.hop + depth) + \
        (n - hops) * each(3000.0, m.safe_z + 0.3, m.safe_z + depth)
    assert spring.plunge_s - rigid.plunge_s == pytest.approx(plunges, rel=1e-9)
    assert spring.rapid_s - rigid.rapid_s == pytest.approx(rises, rel=1e-9)
    # and the design reports the spring program's time
    assert info["machining"]["plunge_hours"] * 3600 == pytest.approx(spring.plunge_s, rel=1e-9)


# ---------------------------------------------------------------- probing


def _probe_points(text: str) -> list[tuple[float, float]]:
    """The X/Y of every G38.2 of a probe program, in order."""
    points, here = [], None
    for line in text.splitlines():
        m = re.match(r"G0 X(\S+) Y(\S+)$", line)
        if m:
            here = (float(m[1]), float(m[2]))
        elif line.startswith("G38.2 Z"):
            assert here is not None
            points.append(here)
    return points


@pytest.mark.parametrize(("spacing", "dialect"), [(10.0, "grbl"), (7.0, "linuxcnc")])
def test_the_probe_grid_covers_the_grooves(designs: dict[str, Path], tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str], spacing: float,
                                           dialect: str) -> None:
    folder = designs["rigid"]
    code, out, err = _run(["probe", folder, "--spacing", spacing, "--dialect", dialect], capsys)
    assert code == 0, err
    text = (folder / "probe.gcode").read_text()
    points = _probe_points(text)
    assert points[0] == (0.0, 0.0)  # the plate zero first
    grid = np.array(points[1:])
    xs, ys = np.unique(grid[:, 0]), np.unique(grid[:, 1])
    assert len(grid) == len(xs) * len(ys)  # a full grid
    (x0, y0), (x1, y1) = drawn_extent(Grooves.load(folder / "grooves.npz"))
    assert xs[0] <= x0 + 1e-4 and xs[-1] >= x1 - 1e-4
    assert ys[0] <= y0 + 1e-4 and ys[-1] >= y1 - 1e-4
    assert np.diff(xs).max() <= spacing + 1e-4 and np.diff(ys).max() <= spacing + 1e-4
    limits = limits_from_header(folder / "hologram.gcode")
    assert limits is not None
    s = limits.stock
    assert (grid[:, 0] >= s.x0).all() and (grid[:, 0] <= s.x1).all()
    assert ("PROBEOPEN" in text) == (dialect == "linuxcnc")
    assert f"{len(points)} points" in out
    if needs_rs274.args[0]:  # rs274 missing: the rest needs it
        return
    canon = run_rs274(folder / "probe.gcode")
    probes = [c for c in canon if c[0] == "STRAIGHT_PROBE"]
    assert len(probes) == len(points)


def test_a_spring_design_is_not_probed_or_levelled(designs: dict[str, Path], tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    for argv in (["probe", designs["spring"]], ["level", designs["spring"], tmp_path / "log"]):
        code, _, err = _run(argv, capsys)
        assert code == 1 and len(err.splitlines()) == 1 and "spring holder" in err
    assert not (designs["spring"] / "probe.gcode").exists()


# ---------------------------------------------------------------- levelling


def _plane(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return 0.001 * np.asarray(x) + 0.0005 * np.asarray(y)


def _grbl_log(path: Path, points: list[tuple[float, float]], height) -> None:
    """A sender's console of a probe run: GRBL's [PRB:...] reports in machine
    coordinates (the work offset X100 Y50 Z-20), among its other lines."""
    with path.open("w") as fh:
        fh.write("Grbl 1.1h ['$' for help]\nok\n")
        for x, y in points:
            z = float(height(x, y))
            fh.write(f"<Idle|MPos:{x + 100:.3f},{y + 50:.3f},{z - 20:.3f}|FS:0,0>\n")
            fh.write(f"[PRB:{x + 100:.3f},{y + 50:.3f},{z - 20:.4f}:1]\nok\n")


def _check_levelled(lines: list[str], depth: float, hop: float, height,
                    nodes: np.ndarray | None = None) -> int:
    """Every cut of a levelled program at -depth + height(x, y) within FOLLOW,
    at its ends and along it (9 points a move), and every hop at hop + height;
    returns the cuts. With ``nodes`` (k, 2), those the cuts pass through are
    vertices of the program at -depth + the node's height."""
    cuts = 0
    at_nodes = set()
    for m in _moves(lines):
        if not _moves_xy(m) or m["kind"] == 0:
            continue
        ts = np.linspace(0.0, 1.0, 9)
        x, y, z = _point_along(m, ts)
        above = z - height(x, y)
        level = -depth if abs(above[0] + depth) < abs(above[0] - hop) else hop
        assert np.abs(above - level).max() <= FOLLOW + WRITTEN, (lines[m["line"]], above)
        if level < 0:
            cuts += 1
            if nodes is not None:
                ex, ey, ez = m["end"]
                near = np.flatnonzero(np.hypot(nodes[:, 0] - ex, nodes[:, 1] - ey) < 2e-5)
                for k in near:
                    assert abs(ez + depth - height(ex, ey)) <= WRITTEN
                    at_nodes.add(int(k))
    if nodes is not None:
        assert at_nodes, "no cut ends on a node of the map"
    return cuts


@pytest.mark.parametrize("units", ["mm", "inch"])
def test_a_probed_plane_levels_every_cut(designs: dict[str, Path], tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str], units: str) -> None:
    """The plate z = 0.001 x + 0.0005 y, probed on the design's own probe grid
    and logged by GRBL in machine coordinates: every cut of the levelled
    program lies at -depth + the plane's height within 1 um, along its moves
    too; it passed the safety check against the probed plate, which the flat
    limits refuse; rs274 reads it."""
    folder = tmp_path / "d"
    code, _, err = _run(["design", BUNNY, "--out", folder, "--stipples", "60", "--holder",
                         "rigid", "--units", units, "--dialect", "linuxcnc"], capsys)
    assert code == 0, err
    assert _run(["probe", folder], capsys)[0] == 0
    log = tmp_path / "console.txt"
    _grbl_log(log, _probe_points((folder / "probe.gcode").read_text()), _plane)
    code, out, err = _run(["level", folder, log], capsys)
    assert code == 0, err
    assert "passed the safety check against the probed plate" in out
    levelled = folder / "hologram_leveled.gcode"
    lines = levelled.read_text().splitlines()
    assert not any(line.startswith("(check") for line in lines)
    assert sum(line.startswith("(levelled:") for line in lines) == 3
    assert _check_levelled(lines, 0.011, 0.03, _plane) > 5000
    flat = limits_from_header(folder / "hologram.gcode")
    assert flat is not None and not check_limits(levelled, flat).ok
    code, _, err = _run(["check", levelled], capsys)
    assert code == 1 and "levelled to a probed plate" in err
    if not needs_rs274.args[0]:
        run_rs274(levelled)


def _long_program(path: Path, dialect: str = "grbl") -> Limits:
    """A program of long moves across the map: straight cuts along its rows and
    columns and a diagonal, wide arcs, hops, written as a rigid holder's."""
    verts, bulges, offsets = [], [], [0]

    def path_of(points: list[tuple[float, float]], bulge: list[float]) -> None:
        verts.extend(points)
        bulges.extend([*bulge, 0.0])
        offsets.append(len(verts))

    path_of([(-60.0, -20.0), (60.0, -20.0)], [0.0])  # along a row of nodes
    path_of([(-40.0, -45.0), (-40.0, 45.0)], [0.0])  # along a column
    path_of([(-58.0, -43.0), (57.0, 41.0)], [0.0])  # across the cells
    path_of([(-50.0, 10.0), (0.0, 30.0), (50.0, 12.0)], [0.3, -0.2])  # wide arcs
    path_of([(-30.0, -30.0), (30.0, -30.0)], [-math.tan(math.radians(160) / 4)])
    path_of([(31.0, -29.0), (33.0, -28.0)], [0.0])  # hopped onto from the last
    grooves = Grooves(np.array(verts), np.array(bulges), np.array(offsets),
                      np.arange(len(offsets) - 1))
    tool, m = Tool(0.025, 0.011), Machining(spindle=0.0)
    limits = Limits(Stock.centred(160.0, 120.0, 3.0), 0.011, m.safe_z, (100.0, 300.0),
                    (0.0, 0.0), "drag", hop_max=m.hop_max, hop=m.hop, groove_depth=0.011)
    write_gcode(path, grooves, tool, m, header=limits.header(), holder=Holder("rigid"),
                options=GcodeOptions(dialect=dialect))  # type: ignore[arg-type]
    return limits


def _linuxcnc_log(path: Path, xs: np.ndarray, ys: np.ndarray, z: np.ndarray) -> None:
    """LinuxCNC's probe file: the plate zero, then the grid, X Y Z A B C U V W a line."""
    rows = [(0.0, 0.0, 0.0)] + [(x, y, z[j, i]) for j, y in enumerate(ys)
                                for i, x in enumerate(xs)]
    path.write_text("".join(f"{x:.6f} {y:.6f} {h:.6f} 0.000000 0.000000 0.000000 0.000000 "
                            "0.000000 0.000000\n" for x, y, h in rows))


def test_a_curved_map_levels_long_moves_at_its_nodes(tmp_path: Path) -> None:
    """A map whose nodes rise and fall (bilinear between them): long moves are
    split where they cross its lines and where it bends, so that every cut's
    Z is -depth + the map's height within 1 um along them and exactly the
    node's height at the nodes they pass."""
    xs, ys = np.linspace(-70.0, 70.0, 8), np.linspace(-50.0, 50.0, 6)
    gx, gy = np.meshgrid(xs, ys)
    z = 0.03 * np.sin(gx / 17.0) * np.cos(gy / 13.0) + 0.02 * (gx / 70.0) ** 2 \
        - 0.015 * (gx * gy) / 3500.0
    z = np.round(z, 6)  # as the log holds them
    log = tmp_path / "probe_results.txt"
    _linuxcnc_log(log, xs, ys, z)
    pmap = read_probe_log(log)
    assert np.allclose(pmap.xs, xs) and np.allclose(pmap.ys, ys) and np.allclose(pmap.z, z)

    def height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        i = np.clip(np.searchsorted(xs, x, side="right") - 1, 0, len(xs) - 2)
        j = np.clip(np.searchsorted(ys, y, side="right") - 1, 0, len(ys) - 2)
        u = (x - xs[i]) / (xs[i + 1] - xs[i])
        v = (y - ys[j]) / (ys[j + 1] - ys[j])
        return (z[j, i] * (1 - u) + z[j, i + 1] * u) * (1 - v) + \
            (z[j + 1, i] * (1 - u) + z[j + 1, i + 1] * u) * v

    src, dst = tmp_path / "long.gcode", tmp_path / "levelled.gcode"
    limits = _long_program(src)
    done = level_program(src, dst, pmap, log.name,
                         check=lambda p: check_program(p, leveled_limits(limits, pmap)))
    assert done.split > 20
    lines = dst.read_text().splitlines()
    nodes = np.stack([gx.ravel(), gy.ravel()], axis=1)
    assert _check_levelled(lines, 0.011, 0.03, height, nodes) > 30


def test_a_log_not_covering_the_grooves_is_refused(designs: dict[str, Path], tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    folder = designs["rigid"]
    assert _run(["probe", folder], capsys)[0] == 0
    points = _probe_points((folder / "probe.gcode").read_text())
    half = [p for p in points if p[0] <= 0.0]  # the left half of the plate
    log = tmp_path / "half.txt"
    _grbl_log(log, half, _plane)
    code, _, err = _run(["level", folder, log], capsys)
    assert code == 1 and len(err.splitlines()) == 1
    assert "half.txt covers X" in err and "not the grooves'" in err
    assert not (folder / "hologram_leveled.gcode").exists()


@pytest.mark.parametrize(("text", "words"), [
    ("[PRB:1.000,2.000,-3.000:1]\n[PRB:2.000,2.000,-3.000:1]\n", "2 probe point(s)"),
    ("0 0 0\n1 1 nan\n2 1 0\n1 2 0\n2 2 0\n", "point 2 holds a non-finite value"),
    ("0 0 0\n1 1 inf\n2 1 0\n1 2 0\n2 2 0\n", "non-finite"),
    ("[PRB:0,0,0:1]\n[PRB:1,1,0:0]\n", "a probe that touched nothing"),
    ("0 0 0\n1 1 0\nprobe failed\n", "line 3: not a point"),
    ("5 5 0\n1 1 0\n2 1 0\n1 2 0\n2 2 0\n", "not the plate zero X0 Y0"),
    ("0 0 0\n1 1 0\n2 1 0\n1 2 0\n2 2 0\n1.04 1 0\n1.08 1 0\n1.12 1 0\n",
     "the point at X1.120 Y1.000 (from the first) lies on no row"),
    ("0 0 0\n1 1 0\n2 1 0\n1 2 0\n2.5 2.5 0\n", "no full grid"),
    ("0 0 0\n1 1 0\n2 1 0\n3 1 0\n1 2 0\n2 2 0\n", "no full grid: none at X3.000 Y2.000"),
])
def test_a_bad_log_is_refused_in_one_line(designs: dict[str, Path], tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str], text: str,
                                          words: str) -> None:
    log = tmp_path / "log.txt"
    log.write_text(text)
    code, _, err = _run(["level", designs["rigid"], log], capsys)
    assert code == 1 and len(err.splitlines()) == 1 and words in err, err
    assert not (designs["rigid"] / "hologram_leveled.gcode").exists()


def test_a_plate_too_far_from_flat_is_refused(designs: dict[str, Path], tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """Heights spanning more than the safe height less the hop: a rapid could
    pass below a hop, so nothing is levelled."""
    folder = designs["rigid"]
    assert _run(["probe", folder], capsys)[0] == 0
    log = tmp_path / "steep.txt"
    _grbl_log(log, _probe_points((folder / "probe.gcode").read_text()),
              lambda x, y: 0.01 * x)
    code, _, err = _run(["level", folder, log], capsys)
    assert code == 1 and len(err.splitlines()) == 1 and "seat the plate flatter" in err
    assert not (folder / "hologram_leveled.gcode").exists()

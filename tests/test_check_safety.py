"""One safety check for every program specholo keeps: each job's own programs
pass it, and the same programs made unsafe are refused.

The programs (small designs, made once for the module) are every job's: flat
designs of each method, tool, dialect and units a design accepts, a ridged
plate, a composition on a cylinder cut with 3 and 4 axes, a turning plate (its
grooves and its relief cut, closed grooves and sliding ones) and a steady
image. Each is checked against the limits its job builds from its settings.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_gcode import check_canon, hopping_example, needs_rs274, run_rs274

from specholo.errors import SpecholoError
from specholo.fabrication.check import Limits, Stock, check_limits, check_program
from specholo.setup import Machining
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
INCH = 25.4
TOOLS = ("drag", "ball", "vbit", "scriber", "laser")
WORD = re.compile(r"([A-Z])([-+]?(?:\d+\.?\d*|\.\d+))")


@dataclass(repr=False)
class Program:
    """A kept program, its job's limits, and where it can be made unsafe.

    Attributes:
        lines: the program's lines.
        limits: the limits its job checks it against.
        per_mm: program units per mm.
        top: height of the surface's highest point, mm (rapids clear it by the
            safe height).
        cuts: lines of feed moves that cut.
        feeds: lines of feed moves with an F word.
        rapids: lines of rapids in X/Y (turning A); for a laser, the lines that
            switch it off before a rapid.
        hops: lines of feed moves in X/Y above the surface, in a job that hops
            between grooves.
    """

    lines: list[str]
    limits: Limits
    per_mm: float
    top: float = 0.0
    cuts: tuple[int, ...] = ()
    feeds: tuple[int, ...] = ()
    rapids: tuple[int, ...] = ()
    hops: tuple[int, ...] = ()

    def __repr__(self) -> str:
        return f"<{len(self.lines)} lines, {self.limits.tool}>"


def _words(line: str) -> list[tuple[str, float]]:
    body = re.sub(r"\([^)]*\)", "", line).split(";")[0].upper().replace(" ", "")
    return [(k, float(v)) for k, v in WORD.findall(body)]


def _program(path: Path, limits: Limits, top: float = 0.0) -> Program:
    """Read a program's lines and find its cuts, its feed lines and its rapids."""
    lines = path.read_text().splitlines()
    motion, z, on, per_mm = -1, math.nan, False, 1.0
    cuts, feeds, rapids, hops = [], [], [], []
    laser = limits.tool == "laser"
    curved = limits.surface is not None and not limits.rotary
    for i, line in enumerate(lines):
        words = _words(line)
        was_on = on
        for k, v in words:
            if k == "G" and v in (0, 1, 2, 3):
                motion = int(v)
            elif k == "G" and v in (20, 21):
                per_mm = 1.0 / INCH if v == 20 else 1.0
            elif k == "M" and v in (3, 4, 5):
                on = v != 5
            elif k == "Z":
                z = v
        moves = any(k in "XYA" for k, _ in words)
        if motion in (1, 2, 3) and moves:
            if (on if laser else (curved or z < 0)):
                cuts.append(i)
            elif limits.hop_max is not None and z >= 0:  # a job that hops
                hops.append(i)
        if motion in (1, 2, 3) and any(k == "F" for k, _ in words):
            feeds.append(i)
        if motion == 0 and moves and not laser:
            rapids.append(i)
        if laser and was_on and line.strip() == "M5":
            after = next((ln for ln in lines[i + 1:] if ln.strip() and ln[0] != ";"), "")
            if after.startswith("G0 X"):
                rapids.append(i)
    return Program(lines, limits, per_mm, top, tuple(cuts), tuple(feeds), tuple(rapids),
                   tuple(hops))


@pytest.fixture(scope="module")
def programs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Program]:
    """Every job's kept programs, made once (each passed its job's check to be kept)."""
    from specholo.fabrication.programs.surface_gcode import host_top, surface_limits
    from specholo.jobs.composition.design import (
        design_composition,
        parse_composition,
        write_composition,
    )
    from specholo.jobs.flat.folder import DesignConfig, design, design_limits, write_design
    from specholo.jobs.ridged.design import design_ridged_model, ridged_limits, write_ridged_design
    from specholo.jobs.ridged.settings import RidgedConfig
    from specholo.jobs.spin.design import SpinConfig, design_spin, spin_limits, write_spin
    from specholo.jobs.steady.design import (
        SteadyConfig,
        design_steady_job,
        steady_limits,
        write_steady,
    )
    from specholo.toolpaths.spinning import relief_grooves

    tmp = tmp_path_factory.mktemp("programs")
    out: dict[str, Program] = {}
    with pytest.MonkeyPatch.context() as patch:
        # the preview, most of a small design's writing time, has no part in its G-code
        patch.setattr("specholo.preview.preview.render_preview", lambda *args, **kwargs: None)
        for method in ("striped", "hyperbola", "arc"):
            for tool in TOOLS:
                # held rigid, as every tip was: a spring holder's program (the
                # drag tip's default) is checked in tests/test_holders.py
                held = {} if tool == "laser" else {"holder": "rigid"}
                d = design(BUNNY, DesignConfig(stipples=6, size=30, method=method, tool=tool,
                                               **held))
                for dialect in ("marlin",) if tool == "laser" else ("grbl", "linuxcnc"):
                    for units in ("mm", "inch"):
                        name = f"{method}-{tool}-{dialect}-{units}"
                        dd = dataclasses.replace(d, config=dataclasses.replace(
                            d.config, dialect=dialect, units=units))
                        write_design(dd, tmp / name, ("gcode",), command=["test"])
                        out[name] = _program(tmp / name / "hologram.gcode", design_limits(dd))
    ridged = design_ridged_model(BUNNY, RidgedConfig.from_dict(
        {"stipples": 6, "size": 10, "raster": 0.1, "view_range": 10,
         "elevation_range": 5, "tool_radius": 0.2}))
    write_ridged_design(ridged, tmp / "ridged", ("gcode",))
    out["ridged"] = _program(tmp / "ridged" / "hologram.gcode", ridged_limits(ridged))

    text = (f'stipples = 10\nseed = 5\n[host]\nkind = "cylinder"\nradius = 35\nheight = 60\n'
            f'[viewer]\nrange = 20\n[[scene]]\nmodel = "{BUNNY}"\nsize = 20\ncenter_z = -20\n')
    composed = design_composition(parse_composition(text, ROOT))
    for axes in (3, 4):
        comp = parse_composition(text.replace("[viewer]", f"[machining]\naxes = {axes}\n"
                                              "[viewer]"), ROOT)
        write_composition(dataclasses.replace(composed, comp=comp), tmp / f"compose{axes}")
        limits = surface_limits(composed.grooves, comp.host, comp.tool, comp.machining, axes)
        out[f"compose-{axes}-axis"] = _program(tmp / f"compose{axes}" / "hologram.gcode",
                                                limits, host_top(comp.host) if axes == 3 else 0.0)

    for turns in (1, 2):
        job = design_spin(BUNNY, SpinConfig(stipples=6, size=20, occlusion=False, turns=turns))
        write_spin(job, tmp / f"spin{turns}", step_deg=45, frames=0)
        cfg = job.config
        out[f"spin-{turns}"] = _program(tmp / f"spin{turns}" / "hologram.gcode",
                                        spin_limits(job.design.grooves, cfg.tool.depth,
                                                    cfg.machining))
        relief, depth = relief_grooves(job.design, cfg.tool)
        out[f"spin-{turns}-relief"] = _program(tmp / f"spin{turns}" / "relief.gcode",
                                               spin_limits(relief, depth, cfg.machining))

    steady = SteadyConfig(stipples=12, size=20)
    sd = design_steady_job(BUNNY, steady)
    write_steady(sd, steady, tmp / "steady", step_deg=5)
    out["steady"] = _program(tmp / "steady" / "hologram.gcode", steady_limits(sd, steady))
    return out


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("mutants")


def test_every_job_and_dialect_is_covered(programs: dict[str, Program]) -> None:
    names = set(programs)
    for method in ("striped", "hyperbola", "arc"):
        for tool in TOOLS:
            for units in ("mm", "inch"):
                dialects = ("marlin",) if tool == "laser" else ("grbl", "linuxcnc")
                assert {f"{method}-{tool}-{d}-{units}" for d in dialects} <= names
    assert {"ridged", "compose-3-axis", "compose-4-axis", "spin-1", "spin-1-relief",
            "spin-2", "spin-2-relief", "steady"} <= names
    kinds = {p.limits.tool for p in programs.values()}
    assert kinds == {"mill", "drag", "laser"}
    # grooves near each other are hopped between, and the check bounds the hops
    hopping = {n for n, p in programs.items() if p.hops}
    assert {"striped-drag-grbl-mm", "striped-ball-linuxcnc-inch"} <= hopping
    assert all(p.limits.hop_max == 3.0 and p.limits.hop == 0.03 for n, p in programs.items()
               if n in hopping)


def test_each_jobs_own_programs_pass(programs: dict[str, Program], scratch: Path) -> None:
    for name, p in programs.items():
        path = scratch / "own.ngc"
        path.write_text("\n".join(p.lines) + "\n")
        report = check_limits(path, p.limits)
        assert report.ok, (name, report.summary())
        assert report.moves["cutting"] > 0 and p.cuts and p.feeds and p.rapids, name
        if p.limits.tool != "laser":
            assert 0 < report.deepest <= p.limits.max_depth + p.limits.tolerance, name


def test_each_flat_program_names_its_own_limits(programs: dict[str, Program],
                                                scratch: Path) -> None:
    """`specholo check FILE` with no options: a program on a flat plate carries the
    limits its job checked it against in its header, read back to the same
    limits (corners rounded outward by at most 0.1 um); curved hosts name none."""
    from specholo.fabrication.check import limits_from_header

    for name, p in programs.items():
        path = scratch / "own.ngc"
        path.write_text("\n".join(p.lines) + "\n")
        own = limits_from_header(path)
        if p.limits.surface is not None or p.limits.rotary:
            assert own is None, name
            continue
        assert own is not None, name
        a, b = own.stock, p.limits.stock
        assert 0 <= b.x0 - a.x0 < 1e-4 and 0 <= a.x1 - b.x1 < 1e-4, name
        assert 0 <= b.y0 - a.y0 < 1e-4 and 0 <= a.y1 - b.y1 < 1e-4, name
        assert (own.tool, own.hop_max, own.groove_depth) == (
            p.limits.tool, p.limits.hop_max, p.limits.groove_depth), name
        assert own.max_depth == pytest.approx(p.limits.max_depth, abs=1e-4), name
        assert check_limits(path, own).ok, name
        # cut deeper than the header allows: refused by the header alone
        i = p.cuts[len(p.cuts) // 2]
        lines, _ = _deeper(p, i, 0.01)
        path.write_text("\n".join(lines) + "\n")
        assert not check_limits(path, own).ok, name


def test_check_with_no_options_reads_the_header(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _design(tmp_path, capsys)
    assert code == 0, err
    program = out / "hologram.gcode"
    assert _run(["check", str(program)]) == 0
    assert "against the limits in its header" in capsys.readouterr().out
    # the same program without its check lines: one line naming the options
    bare = tmp_path / "bare.ngc"
    bare.write_text("".join(ln for ln in program.read_text().splitlines(keepends=True)
                            if not ln.startswith("(check")))
    assert _run(["check", str(bare)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "names no limits" in err[0]


def _number(value: float) -> str:
    return f"{value:.6f}"


def _set(line: str, letter: str, value: str) -> str:
    """The line with its ``letter`` word set to value (added if it has none)."""
    code, _, comment = line.partition(";")
    if re.search(rf"{letter}[-+]?[\d.]", code):
        code = re.sub(rf"{letter}[-+]?(?:\d+\.?\d*|\.\d+)", f"{letter}{value}", code, count=1)
    else:
        code = f"{code.rstrip()} {letter}{value}"
    return code + (f" ;{comment}" if comment else "")


def _modal(lines: list[str], i: int, letter: str) -> float:
    """The value of an axis word in force at line i (after it runs), program units."""
    for line in reversed(lines[:i + 1]):
        for k, v in reversed(_words(line)):
            if k == letter:
                return v
    return 0.0


def _deeper(p: Program, i: int, extra: float) -> tuple[list[str], str]:
    lines = list(p.lines)
    if p.limits.tool == "laser":
        lines[i] = _set(lines[i], "Z", _number(-extra * p.per_mm))
        return lines, "below the surface"
    z = _modal(lines, i, "Z") - (p.limits.max_depth + extra) * p.per_mm
    lines[i] = _set(lines[i], "Z", _number(z))
    return lines, "deeper than"


def _off_plate(p: Program, i: int, extra: float) -> tuple[list[str], str]:
    lines = list(p.lines)
    x = (p.limits.stock.x1 + 1.0 + extra) * p.per_mm
    move = f"G1 X{_number(x)}"
    if not p.limits.rotary:
        move += f" Y{_number(_modal(lines, i, 'Y'))}"
    # a cut in X, Y and Z (a curved host's, a steady scoop's) keeps its own Z: the
    # move before it may end above the surface (a scoop starts at it)
    if (p.limits.surface is not None and not p.limits.rotary) or \
            any(k == "Z" for k, _ in _words(lines[i])):
        move += f" Z{_number(_modal(lines, i, 'Z'))}"
    lines[i] = move
    return lines, "leaves the stock"


def _low_rapid(p: Program, i: int, share: float) -> tuple[list[str], str]:
    lines = list(p.lines)
    if p.limits.tool == "laser":
        del lines[i]  # the laser left on through the rapid after the groove
        return lines, "rapid with the laser on"
    z = p.top + share * (p.limits.safe_z - p.top)
    lines[i] = _set(lines[i], "Z", _number(z * p.per_mm))
    return lines, "below the safe height"


def _long_hop(p: Program, i: int, extra: float) -> tuple[list[str], str]:
    """Hop i sent further than the longest hop, toward the plate's centre."""
    lines = list(p.lines)
    x = _modal(lines, i - 1, "X") / p.per_mm
    most = p.limits.hop_max or 0.0
    x += (most + extra) * (-1.0 if x > 0 else 1.0)
    lines[i] = _set(lines[i], "X", _number(x * p.per_mm))
    return lines, "longer than the longest hop"


def _low_hop(p: Program, i: int, share: float, dip: bool) -> tuple[list[str], str]:
    """The retract before hop i ends lower: nearer the surface than the hop
    height, or below the surface, where the hop cuts through the plate."""
    lines = list(p.lines)
    k = max(j for j in range(i) if lines[j].startswith("G0 Z"))
    z = -share * (p.limits.groove_depth or 0.0) if dip else share * p.limits.hop
    lines[k] = _set(lines[k], "Z", _number(z * p.per_mm))
    return lines, "not at the groove depth" if dip else "below the hop height"


def _bad_feed(p: Program, i: int, how: str, factor: float) -> tuple[list[str], str]:
    lo, hi = p.limits.feed_range
    # absurd, yet short enough a line for a controller to read (see MAX_LINE)
    value = {"zero": "0", "absurd": "1" + "0" * 150,
             "fast": _number(hi * factor * p.per_mm),
             "slow": _number(lo / factor * p.per_mm)}[how]
    lines = list(p.lines)
    lines[i] = _set(lines[i], "F", value)
    return lines, "zero feed" if how == "zero" else "outside"


@settings(max_examples=300, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_programs_made_unsafe_are_refused(programs: dict[str, Program], scratch: Path,
                                          data: st.DataObject) -> None:
    name = data.draw(st.sampled_from(sorted(programs)), label="program")
    p = programs[name]
    how = data.draw(st.sampled_from(["deeper", "off the plate", "low rapid", "bad feed",
                                     "long hop", "low hop"]), label="made unsafe")
    if how in ("long hop", "low hop") and not p.hops:
        how = "deeper"
    if how == "long hop":
        lines, why = _long_hop(p, data.draw(st.sampled_from(p.hops)),
                               data.draw(st.floats(0.01, 5.0)))
    elif how == "low hop":
        dip = data.draw(st.booleans())
        lines, why = _low_hop(p, data.draw(st.sampled_from(p.hops)),
                              data.draw(st.floats(0.1, 0.9) if dip else st.floats(0.0, 0.6)),
                              dip)
    elif how == "deeper":
        lines, why = _deeper(p, data.draw(st.sampled_from(p.cuts)),
                             data.draw(st.floats(0.01, 2.0)))
    elif how == "off the plate":
        lines, why = _off_plate(p, data.draw(st.sampled_from(p.cuts)),
                                data.draw(st.floats(0.0, 100.0)))
    elif how == "low rapid":
        lines, why = _low_rapid(p, data.draw(st.sampled_from(p.rapids)),
                                data.draw(st.floats(0.0, 0.9)))
    else:
        kind = data.draw(st.sampled_from(["zero", "absurd", "fast", "slow"]))
        if kind == "slow" and p.limits.feed_range[0] == 0:
            kind = "fast"
        lines, why = _bad_feed(p, data.draw(st.sampled_from(p.feeds)), kind,
                               data.draw(st.floats(1.5, 1000.0)))
    path = scratch / "mutant.ngc"
    path.write_text("\n".join(lines) + "\n")
    report = check_limits(path, p.limits)
    assert not report.ok, (name, how)
    whats = [v.what for v in report.violations]
    assert any(why in w or "no surface" in w for w in whats), (name, how, whats)
    with pytest.raises(SpecholoError, match="safety check") as info:
        check_program(path, p.limits)
    assert "\n" not in str(info.value)


# ---------------------------------------------------------------------------
# the cases a review reproduced


def _run(args: list[str]) -> int:
    """The exit status of a command (``check`` exits 1 itself when it finds a fault)."""
    try:
        return main(args)
    except SystemExit as exc:
        return int(exc.code or 0)


def _design(tmp_path: Path, capsys: pytest.CaptureFixture[str], *options: str
            ) -> tuple[int, Path, str]:
    out = tmp_path / "d"
    code = main(["design", str(BUNNY), "--out", str(out), "--stipples", "8", "--size", "30",
                 *options])
    return code, out, capsys.readouterr().err.strip()


def test_a_drag_tips_plunge_made_deep_is_refused(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """A drag tip's design, one plunge edited to Z -2.5: its own check and
    ``specholo check --no-spindle`` (or --tool drag) refused nothing before."""
    from specholo.jobs.flat.folder import check_written_gcode, design, design_limits

    code, out, err = _design(tmp_path, capsys)
    assert code == 0, err
    lines = (out / "hologram.gcode").read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("G1 Z-"))
    lines[k] = "G1 Z-2.5 F100.00000"
    bad = tmp_path / "deep.ngc"
    bad.write_text("\n".join(lines) + "\n")
    plate = json.loads((out / "hologram.json").read_text())["plate"]["plate_mm"]
    width, height = (plate[1][i] - plate[0][i] for i in (0, 1))
    for tool in (["--no-spindle"], ["--tool", "drag"], ["--tool", "scriber"]):
        assert _run(["check", str(bad), "--plate-width", str(width), "--plate-height",
                     str(height), "--max-depth", "0.012", "--spindle", "0", "0", *tool]) == 1
        assert f"line {k + 1}: cut to Z -2.50000, deeper than 0.012" in capsys.readouterr().out
    from specholo.jobs.flat.folder import DesignConfig

    d = design(BUNNY, DesignConfig(stipples=8, size=30))
    assert design_limits(d).tool == "drag"
    with pytest.raises(SpecholoError, match="deeper than"):
        check_written_gcode(bad, d)


def test_check_bounds_hops_when_asked(tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    from specholo.fabrication.programs.gcode import write_gcode
    from specholo.setup import Tool

    path = tmp_path / "hops.ngc"
    write_gcode(path, hopping_example(), Tool(), Machining())  # hops of 0.5 and 2 mm
    args = ["check", str(path), "--plate-width", "60", "--plate-height", "60", "--max-depth",
            "0.08", "--feed", "100", "300", "--spindle", "12000", "12000"]
    assert _run(args) == 0
    assert _run([*args, "--hop-max", "3", "--hop", "0.03"]) == 0
    capsys.readouterr()
    assert _run([*args, "--hop-max", "1", "--hop", "0.03"]) == 1
    assert "longer than the longest hop 1 mm" in capsys.readouterr().out
    assert _run([*args, "--hop-max", "3", "--hop", "0.05"]) == 1
    assert "below the hop height 0.05" in capsys.readouterr().out


def test_a_laser_below_the_surface_is_refused(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "laser.ngc"
    path.write_text("G21\nG90\nM5\nG0 X0 Y0 F3000\nG1 Z-50 F300\n")
    for tool in (["--laser"], ["--tool", "laser"]):
        assert _run(["check", str(path), "--plate-width", "100", "--plate-height", "100",
                     "--max-depth", "1", *tool]) == 1
        assert "line 5: move to Z -50.00000, below the surface, on a laser" in \
            capsys.readouterr().out
    assert _run(["check", str(path), "--plate-width", "100", "--plate-height", "100",
                 "--max-depth", "1", "--laser", "--tool", "ball"]) == 1
    assert "give one tool" in capsys.readouterr().err


def test_steady_cuts_no_deeper_than_its_depth_and_is_checked(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``specholo steady --depth 0.02`` cut to Z -0.0815 (a sloping scoop's circle
    dips below its glint point); now its deepest tip is at the depth, and its
    program is read back by the check before the folder is kept."""
    out = tmp_path / "steady"
    assert main(["steady", str(BUNNY), "--out", str(out), "--stipples", "60",
                 "--depth", "0.02"]) == 0
    capsys.readouterr()
    z = [v for ln in (out / "hologram.gcode").read_text().splitlines()
         for k, v in _words(ln) if k == "Z"]
    assert min(z) >= -0.02 - 1e-5
    meta = json.loads((out / "hologram.json").read_text())
    assert meta["safety_check"]["violations"] == 0
    assert meta["safety_check"]["deepest_cut_mm"] <= 0.02 + 1e-5

    # a program that cuts too deep is not kept
    import specholo.jobs.steady.design as steady

    writer = steady.write_path_gcode

    def deeper(path, design, tool, machining, header, **more):  # type: ignore[no-untyped-def]
        deep = dataclasses.replace(design, centres=design.centres - np.array([0, 0, 0.05]))
        return writer(path, deep, tool, machining, header, **more)

    monkeypatch.setattr(steady, "write_path_gcode", deeper)
    bad = tmp_path / "bad"
    assert main(["steady", str(BUNNY), "--out", str(bad), "--stipples", "30"]) == 1
    err = capsys.readouterr().err.strip()
    assert "safety check" in err and "deeper than" in err and len(err.splitlines()) == 1
    assert not bad.exists()


def test_spin_programs_are_checked(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import specholo.fabrication.programs.gcode as gcode
    from specholo.jobs.spin.design import SpinConfig, design_spin, write_spin

    job = design_spin(BUNNY, SpinConfig(stipples=6, size=20, occlusion=False))
    writer = gcode.write_gcode

    def off_plate(path, grooves, *args, **kwargs):  # type: ignore[no-untyped-def]
        moved = dataclasses.replace(grooves, vertices=grooves.vertices + 100.0)
        return writer(path, moved, *args, **kwargs)

    monkeypatch.setattr(gcode, "write_gcode", off_plate)
    with pytest.raises(SpecholoError, match="safety check.*leaves the stock"):
        write_spin(job, tmp_path / "spin", step_deg=45, frames=0)
    assert not (tmp_path / "spin").exists()


def _compose(tmp_path: Path, machining: str) -> tuple[int, Path]:
    comp = tmp_path / "c.toml"
    comp.write_text(f'stipples = 8\n[host]\nkind = "cylinder"\nradius = 35\n[machining]\n'
                    f'{machining}\n[[scene]]\nmodel = "{BUNNY}"\nsize = 20\ncenter_z = -20\n')
    out = tmp_path / "out"
    return main(["compose", str(comp), "--out", str(out), "--step", "15", "--frames", "0"]), out


@pytest.mark.parametrize(("machining", "words"), [
    ("safe_z = 1e-9", "safe z 1e-09 mm is out of range"),
    ("feed = 1e300", "feed 1e+300 mm/min is out of range"),
    ("plunge = 2e5", "plunge 200000 mm/min is out of range"),
])
def test_compose_refuses_absurd_machining(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                          machining: str, words: str) -> None:
    code, out = _compose(tmp_path, machining)
    err = capsys.readouterr().err.strip()
    assert code == 1 and words in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_compose_rapids_clear_the_hosts_top(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    code, out = _compose(tmp_path, "safe_z = 0.5")
    assert code == 0, capsys.readouterr().err
    text = (out / "hologram.gcode").read_text().splitlines()
    rapids = [ln for ln in text if ln.startswith("G0 Z")]
    assert rapids and all(ln == "G0 Z0.50000" for ln in rapids)
    check = json.loads((out / "hologram.json").read_text())["gcode"]["check"]
    assert check["violations"] == 0 and check["safe_z"] == 0.5
    assert 0 < check["deepest_cut_mm"] <= 0.02 + 2e-3


@pytest.mark.parametrize("machining", [dict(safe_z=0.05), dict(safe_z=0.0999),
                                       dict(feed=100_001.0), dict(plunge=1e300),
                                       dict(spindle=2e6), dict(hop=0.005), dict(hop=1.0),
                                       dict(safe_z=0.2, hop=0.25), dict(hop_max=-1.0),
                                       dict(hop_max=10.5)])
def test_machining_refuses_what_no_machine_should_run(machining: dict[str, float]) -> None:
    with pytest.raises(SpecholoError, match="out of range|must be in") as info:
        Machining(**machining)
    assert "\n" not in str(info.value)
    Machining(safe_z=0.1, feed=100_000.0, plunge=100_000.0, spindle=1e6)  # the bounds


def test_hops_are_a_design_setting(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _design(tmp_path, capsys, "--hop", "0.05", "--hop-max", "2")
    assert code == 0, err
    info = json.loads((out / "hologram.json").read_text())
    assert info["settings"]["hop"] == 0.05 and info["machining"]["hops"] > 0
    text = (out / "hologram.gcode").read_text().splitlines()
    assert text.count("G0 Z0.05000") == info["machining"]["hops"]
    code, out, err = _design(tmp_path, capsys, "--hop-max", "0")
    assert code == 0, err
    assert json.loads((out / "hologram.json").read_text())["machining"]["hops"] == 0
    assert not [ln for ln in (out / "hologram.gcode").read_text().splitlines()
                if ln.startswith("G0 Z") and ln != "G0 Z1.00000"]
    code, out, err = _design(tmp_path, capsys, "--hop", "1")
    assert code == 1 and len(err.splitlines()) == 1
    assert "hop 1 mm is out of range: it must be in [0.01, 1] mm and below the safe height" in err


def test_inch_designs_pass_their_check(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                       ) -> None:
    """``--units inch`` was always refused: the check reads G20 in mm, and its
    limits were divided by 25.4 once more."""
    code, out, err = _design(tmp_path, capsys, "--units", "inch", "--tool", "ball")
    assert code == 0, err
    text = (out / "hologram.gcode").read_text()
    assert "G20" in text and "G21" not in text
    info = json.loads((out / "hologram.json").read_text())
    assert info["machining"]["safety_check"]["violations"] == 0
    assert info["machining"]["units"] == "inch"


@needs_rs274
def test_inch_designs_run_in_linuxcnc(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                      ) -> None:
    from specholo.fabrication.programs.program import GcodeOptions
    from specholo.jobs.flat.folder import load_design

    # a rigid holder's program (a spring holder's is read by rs274 in test_holders.py)
    code, out, err = _design(tmp_path, capsys, "--units", "inch", "--dialect", "linuxcnc",
                             "--holder", "rigid")
    assert code == 0, err
    loaded = load_design(out)
    setup = loaded.config.setup()
    check_canon(run_rs274(out / "hologram.gcode"), loaded.grooves, setup.tool, setup.machining,
                GcodeOptions(dialect="linuxcnc", units="inch"))


@pytest.mark.parametrize("tool", ["drag", "ball", "vbit", "scriber"])
def test_marlin_is_refused_for_a_cutter(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                        tool: str) -> None:
    code, out, err = _design(tmp_path, capsys, "--dialect", "marlin", "--tool", tool)
    assert code == 1 and len(err.splitlines()) == 1
    assert f"--dialect marlin drives a laser: --tool {tool} needs --dialect grbl" in err
    assert not out.exists()


def test_a_laser_is_written_for_marlin(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                       ) -> None:
    code, out, err = _design(tmp_path, capsys, "--tool", "laser")
    assert code == 0, err
    text = (out / "hologram.gcode").read_text()
    assert "Marlin, laser" in text
    assert not [ln for ln in text.splitlines() if ln[:1] == "G" and "Z" in ln]
    code, out, err = _design(tmp_path, capsys, "--tool", "laser", "--dialect", "grbl")
    assert code == 1 and "a laser is driven by --dialect marlin" in err


def test_check_help_says_what_is_checked(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for words in ("--tool [ball|vbit|drag|scriber|laser]", "whatever the tool",
                  "a laser never goes below the surface", "only cuts while it spins",
                  "G20 programs are read in mm"):
        assert words in text, words


def test_limits_refuse_nonsense() -> None:
    stock = Stock.centred(10.0, 10.0, 1.0)
    with pytest.raises(SpecholoError, match="tool kind"):
        Limits(stock, 0.1, 1.0, (1.0, 2.0), (0.0, 0.0), "saw")
    with pytest.raises(SpecholoError, match="max depth"):
        Limits(stock, -0.1, 1.0, (1.0, 2.0), (0.0, 0.0))

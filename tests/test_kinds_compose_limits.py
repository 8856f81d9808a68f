"""A composition's machining numbers, stock and program header, as a user and a
machine meet them: a number no machine has is refused in one line naming its
key and range; the stock under the surface bounds the check; a plane host's
program names its own limits, so ``specholo check PROGRAM`` needs no options;
``verify.json`` has no NaN where a position has nothing to measure."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from specholo.errors import SpecholoError
from specholo.fabrication.check import limits_from_header
from specholo.fabrication.programs.surface_gcode import check_surface_program
from specholo.jobs.composition.design import parse_composition
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
SCENE = f'[[scene]]\nmodel = "{BUNNY}"\nsize = 30\ncenter_z = -25\n'


def _toml(tmp_path: Path, host: str = 'kind = "plane"', machining: str = "", tool: str = "",
          stipples: int = 10, scenes: str = SCENE) -> Path:
    path = tmp_path / "c.toml"
    path.write_text(f"stipples = {stipples}\nseed = 3\n[host]\n{host}\n[tool]\n{tool}\n"
                    f"[machining]\n{machining}\n{scenes}")
    return path


def _one_error(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:"), err
    assert "internal error" not in err[0] and "Traceback" not in err[0]
    return err[0]


def _header(path: Path) -> dict[str, str]:
    """The program's header comments, key -> text."""
    out = {}
    for line in path.read_text().splitlines():
        if not line.startswith("("):
            if not line.startswith("G21"):
                continue
            break
        key, _, text = line[1:-1].partition(": ")
        out[key] = text
    return out


@pytest.mark.parametrize("table, setting, key, message", [
    ("machining", "safe_z = 1e300", "machining.safe_z", "[0.1, 100] mm"),
    ("machining", "safe_z = 0.05", "machining.safe_z", "[0.1, 100] mm"),
    ("machining", "safe_z = 150", "machining.safe_z", "[0.1, 100] mm"),
    ("machining", "feed = 1e9", "machining.feed", "[1, 100000] mm/min"),
    ("machining", "feed = 0.001", "machining.feed", "[1, 100000] mm/min"),
    ("machining", "plunge = nan", "machining.plunge", "[1, 100000] mm/min"),
    ("machining", "plunge = inf", "machining.plunge", "[1, 100000] mm/min"),
    ("machining", "spindle = 3", "machining.spindle", "[100, 1e+06] rpm (or 0"),
    ("machining", "spindle = 1e7", "machining.spindle", "[100, 1e+06] rpm (or 0"),
    ("machining", "spindle = false", "machining.spindle", "must be a number"),
    ("machining", "thickness = 0", "machining.thickness", "[0.1, 1000] mm"),
    ("machining", "thickness = 1e300", "machining.thickness", "[0.1, 1000] mm"),
    ("machining", "axes = 4", "4-axis output", "for a cylinder host"),
    ("tool", "radius = 0.05\ndepth = 0.06", "tool.depth", "up to the tool's radius"),
    ("tool", "radius = 25\ndepth = 25", "tool.depth = 25", "machining.thickness"),
    ("tool", "radius = 5\ndepth = 4", "tool.depth = 4", "the 3 mm of material"),
])
def test_a_machining_number_no_machine_has_is_refused_in_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], table: str, setting: str,
        key: str, message: str) -> None:
    comp = _toml(tmp_path, **{table: setting})
    out = tmp_path / "out"
    assert main(["compose", str(comp), "--out", str(out), "--frames", "0"]) == 1
    line = _one_error(capsys)
    assert key in line and message in line, line
    assert not out.exists()


@pytest.mark.parametrize("host, key", [
    ('kind = "cylinder"\nwidth = 40', "host.width"),
    ('kind = "plane"\nradius = 40', "host.radius"),
    ('kind = "plane"\nwidth = 1e300\nheight = 50', "host.width"),
    ('kind = "sphere"\nradius = 1e300', "host.radius"),
])
def test_a_host_size_beyond_any_host_or_for_another_kind_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], host: str, key: str) -> None:
    out = tmp_path / "out"
    assert main(["compose", str(_toml(tmp_path, host=host)), "--out", str(out)]) == 1
    assert key in _one_error(capsys)
    assert not out.exists()


def _check(program: Path) -> int:
    """``specholo check PROGRAM`` with no options: its exit status."""
    try:
        return main(["check", str(program)])
    except SystemExit as exc:  # the check exits 1 on a violation
        return int(exc.code or 0)


def _deeper(program: Path, into: Path, z: float) -> Path:
    """The program with a plunge to Z ``z`` (mm) written into its first groove."""
    lines = program.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("G1 Z"))
    lines.insert(k + 3, f"G1 Z{z:.4f}")
    into.write_text("\n".join(lines) + "\n")
    return into


@pytest.mark.parametrize("host", ['kind = "plane"', 'kind = "cylinder"\nradius = 35'])
def test_the_stock_under_the_surface_bounds_a_composition_s_check(
        tmp_path: Path, host: str) -> None:
    """The stock is a setting (3 mm unless told), the header names it, and a plunge
    of 25 mm written into the program is refused by the composition's own check
    (and, on a plane, by ``specholo check`` reading the header)."""
    comp_file = _toml(tmp_path, host=host, machining="thickness = 2.5")
    out = tmp_path / "out"
    assert main(["compose", str(comp_file), "--out", str(out), "--frames", "0",
                 "--step", "15"]) == 0
    program = out / "hologram.gcode"
    head = _header(program)
    comp = parse_composition(comp_file.read_text(), tmp_path)
    assert comp.thickness == 2.5
    from specholo.jobs.composition.design import load_composition_folder

    d = load_composition_folder(out)
    bad = _deeper(program, tmp_path / "deep.ngc", -25.0)
    with pytest.raises(SpecholoError, match="deeper than 0.02"):
        check_surface_program(bad, d.grooves, comp.host, comp.tool, comp.machining, comp.axes,
                              comp.thickness)
    if "plane" in host:
        assert "2.5 mm thick" in head["plate"]
        limits = limits_from_header(program)
        assert limits is not None and limits.stock.thickness == 2.5
        assert limits.max_depth == pytest.approx(comp.tool.depth)
        assert _check(bad) == 1
    else:
        assert "2.5 mm of material under its surface" in head["host"]


def test_a_plane_composition_s_program_checks_with_no_options(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Its header names the tool, depth, units, plate and limits, and they are what
    the program does: ``specholo check PROGRAM`` passes it as it is."""
    comp_file = _toml(tmp_path, tool="radius = 0.06\ndepth = 0.025",
                      machining="feed = 400\nplunge = 120\nsafe_z = 2\nspindle = 15000")
    out = tmp_path / "out"
    assert main(["compose", str(comp_file), "--out", str(out), "--frames", "0",
                 "--step", "15"]) == 0
    capsys.readouterr()
    program = out / "hologram.gcode"
    assert _check(program) == 0
    assert "0 violation(s) (against the limits in its header)" in capsys.readouterr().out
    head = _header(program)
    assert head["units"].startswith("mm")
    assert head["tool"].startswith("ball end, round tip radius 0.06 mm")
    assert head["depth"] == "0.025 mm below the surface"
    limits = limits_from_header(program)
    assert limits is not None
    assert limits.stock.thickness == 3.0 and limits.safe_z == 2.0
    assert limits.feed_range == (120.0, 400.0) and limits.spindle_range == (15000, 15000)
    assert limits.tool == "mill" and limits.groove_depth == pytest.approx(0.025)
    # what the program does: every cut at the depth named, every move on the plate named
    text = program.read_text()
    cuts = [float(z) for z in re.findall(r"^G1 X\S+ Y\S+ Z(\S+)", text, re.M)]
    assert cuts and all(z == -0.025 for z in cuts)
    xy = [(float(x), float(y)) for x, y in re.findall(r"^G[01] X(\S+) Y(\S+)", text, re.M)]
    corners = re.search(r"corners X(\S+) Y(\S+) to X(\S+) Y(\S+)", head["plate"])
    assert corners
    x0, y0, x1, y1 = (float(v) for v in corners.groups())
    assert all(x0 <= x <= x1 and y0 <= y <= y1 for x, y in xy)
    assert "M3 S15000" in text
    # the files the header talks of are those in the folder: it names no drawing
    assert not any("SVG" in v or "DXF" in v for v in head.values())
    assert not (set(p.name for p in out.iterdir()) & {"hologram.svg", "hologram.dxf"})


def test_a_curved_host_s_program_says_why_its_header_names_no_limits(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["compose", str(_toml(tmp_path, host='kind = "sphere"\nradius = 60')),
                 "--out", str(out), "--frames", "0", "--step", "15"]) == 0
    head = _header(out / "hologram.gcode")
    assert head["host"].startswith("sphere, radius 60 mm, 3 mm of material")
    assert "curved surface, which no header line can name" in head["limits"]
    assert head["depth"] == "0.02 mm below the surface"
    assert limits_from_header(out / "hologram.gcode") is None


def _strict(path: Path) -> object:
    def refuse(constant: str) -> object:
        raise ValueError(f"{path.name} holds {constant}")

    return json.loads(path.read_text(), parse_constant=refuse)


def test_a_hand_over_with_nothing_to_measure_is_an_honest_row(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """At the hand-over between two scenes (0 deg) no stipple is shown to both
    eyes: its row says so, with null figures, in valid JSON, and the table
    prints '-' rather than nan."""
    second = SCENE.replace("center_z = -25\n", "center_z = -25\nfrom = 0\nyaw = 180\n")
    scenes = SCENE.replace("center_z = -25\n", "center_z = -25\nto = 0\n") + second
    out = tmp_path / "out"
    assert main(["compose", str(_toml(tmp_path, scenes=scenes)), "--out", str(out),
                 "--frames", "0", "--step", "15"]) == 0
    capsys.readouterr()
    assert main(["verify", str(out), "--step", "5"]) == 0
    printed = capsys.readouterr().out
    assert "nan" not in printed.lower()
    assert "nothing to measure at +0.0 (no stipple is shown to both eyes)" in printed
    record = _strict(out / "verify.json")
    assert isinstance(record, dict)
    row = next(r for r in record["positions"] if abs(r["position"]) < 1e-9)
    assert row["shown"] == 0 and row["note"] == "no stipple is shown to both eyes"
    assert row["p95_error"] is None and row["visibility"] is None
    others = [r for r in record["positions"] if abs(r["position"]) > 1e-9]
    assert all("note" not in r and r["p95_error"] < 1.0 for r in others)
    assert record["summary"]["worst_p95_error"] < 1.0

"""``specholo spin`` and ``specholo steady`` as a user and a machine meet them:
every number beyond its physical range is refused in one line with no folder
(never "internal error"); ``verify.json`` holds no NaN; each program's header
names the one tool that cuts it, the files the folder holds and the real plate
thickness, and ``specholo check PROGRAM`` passes it with no options."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from specholo.fabrication.check import limits_from_header
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
#: Small designs: each run takes a fraction of a second.
FAST = {"spin": ["--stipples", "8", "--frames", "0", "--step", "45"],
        "steady": ["--stipples", "8", "--step", "5"]}
#: Numbers no option takes: beyond any float's reach, not numbers, nothing.
ABSURD = ["1e308", "-1e308", "nan", "inf", "-inf"]
#: Each command's float options, with the values beyond their range besides
#: :data:`ABSURD` (0 where 0 is no value the option takes).
OPTIONS = {
    "spin": {"size": ["0", "1e5"], "center-z": ["2e4"], "view-distance": ["0", "5"],
             "view-elevation": ["0", "90"], "ipd": ["0", "0.1"], "light-height": ["0", "1e8"],
             "tool-radius": ["0", "30"], "depth": ["0"], "stock-thickness": ["0", "2000"],
             "rotate-x": ["400"], "offset-x": ["2e4"]},
    "steady": {"size": ["0", "1e5"], "center-z": ["2e4"], "view-distance": ["0", "5"],
               "ipd": ["0", "0.1"], "light-elevation": ["0", "180"],
               "light-sweep": ["0", "20"], "tool-radius": ["0", "30"], "depth": ["0"],
               "stock-thickness": ["0", "2000"], "rotate-x": ["400"], "offset-x": ["2e4"]},
}
CASES = [(command, f"--{option}", value) for command, options in OPTIONS.items()
         for option, beyond in options.items() for value in [*ABSURD, *beyond]]
CASES += [(command, option, value) for command in OPTIONS
          for option, value in (("--seed", "-1"), ("--plate-width", "1e308"))]


@pytest.mark.parametrize("command, option, value", CASES)
def test_a_number_beyond_its_range_is_one_line_and_no_folder(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, option: str,
        value: str) -> None:
    out = tmp_path / "out"
    extra = ["--plate-height", "50"] if option == "--plate-width" else []
    code = main([command, str(BUNNY), "--out", str(out), *FAST[command], option, value,
                 *extra])
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert code != 0, (option, value, captured.out[-300:])
    assert len(err) == 1 and err[0].startswith("error:"), err
    assert "internal error" not in err[0]
    assert not out.exists()


@pytest.mark.parametrize("command, option, value, words", [
    ("spin", "--center-z", "1e308", "center-z 1e+308 mm is out of range: it must be in "
                                    "[-10000, 10000] mm"),
    ("spin", "--tool-radius", "1e308", "tool-radius 1e+308 mm is out of range"),
    ("spin", "--view-distance", "1e308", "view-distance 1e+308 mm is out of range: it "
                                         "must be in [10, 1e+07] mm"),
    ("spin", "--size", "1e308", "size 1e+308 mm is out of range: it must be in "
                                "[0.01, 10000] mm"),
    ("steady", "--center-z", "-1e308", "center-z -1e+308 mm is out of range"),
    ("steady", "--view-distance", "1e308", "view-distance 1e+308 mm is out of range"),
    ("steady", "--ipd", "0.5", "ipd 0.5 mm is out of range: it must be in [1, 1000] mm"),
    ("steady", "--ipd", "1e308", "ipd 1e+308 mm must be below the viewer distance 600 mm"),
    ("steady", "--tool-radius", "1e308", "tool-radius 1e+308 mm is out of range"),
    ("steady", "--seed", "-1", "seed -1 is out of range"),
])
def test_the_line_names_the_option_and_its_range(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, option: str,
        value: str, words: str) -> None:
    out = tmp_path / "out"
    assert main([command, str(BUNNY), "--out", str(out), *FAST[command], option, value]) == 1
    assert words in capsys.readouterr().err


def _strict(path: Path) -> object:
    def refuse(constant: str) -> object:
        raise ValueError(f"{path.name} holds {constant}")

    return json.loads(path.read_text(), parse_constant=refuse)


def test_a_turn_nobody_sees_is_written_as_nothing_measured_not_nan(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A 3 m model round a turning plate: no stipple glints for both eyes at any
    angle. The folder's JSON is valid (null, with a note), the lines say '-'."""
    out = tmp_path / "out"
    assert main(["spin", str(BUNNY), "--out", str(out), *FAST["spin"], "--size", "3000"]) == 0
    printed = capsys.readouterr().out
    assert "nan" not in printed.lower() and "worst p95 - mm" in printed
    record = _strict(out / "verify.json")
    assert isinstance(record, dict)
    assert record["summary"]["worst_p95_mm"] is None
    assert all(r["p95_mm"] is None and "nothing to measure" in r["note"]
               for r in record["angles"])
    meta = _strict(out / "hologram.json")
    assert isinstance(meta, dict) and meta["verify"]["worst_p95_mm"] is None


def _head(path: Path) -> list[str]:
    """The header comments' texts, up to the first command."""
    out = []
    for line in path.read_text().splitlines():
        if not line.startswith("("):
            break
        out.append(line[1:-1])
    return out


def _value(head: list[str], key: str) -> str:
    found = [t.partition(": ")[2] for t in head if t.partition(": ")[0] == key]
    assert len(found) == 1, (key, head)
    return found[0]


def _check(program: Path) -> int:
    """``specholo check PROGRAM`` with no options: its exit status."""
    try:
        return main(["check", str(program)])
    except SystemExit as exc:  # the check exits 1 on a violation
        return int(exc.code or 0)


def _cut_depths(program: Path) -> list[float]:
    """The depths (mm) the feed moves cut to below the surface, each once, in order."""
    text = program.read_text()
    zs = re.findall(r"^G1 X\S+ Y\S+ Z(-\S+)", text, re.M) + re.findall(r"^G1 Z(-\S+)", text,
                                                                          re.M)
    return sorted({-float(z) for z in zs})


def test_spin_programs_name_their_one_tool_and_the_plate_they_cut(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["spin", str(BUNNY), "--out", str(out), *FAST["spin"],
                 "--stock-thickness", "4"]) == 0
    capsys.readouterr()
    for name in ("hologram.gcode", "relief.gcode"):
        assert _check(out / name) == 0, capsys.readouterr()
        assert "0 violation(s) (against the limits in its header)" in capsys.readouterr().out
    # the relief is cut by the V-bit alone: one tool named, and it is the V-bit
    relief = _head(out / "relief.gcode")
    tool = _value(relief, "tool")
    assert tool.startswith("V-bit, 30 degrees") and "ball" not in tool
    depth = float(_value(relief, "depth").split()[0])
    assert _cut_depths(out / "relief.gcode") == pytest.approx([depth], abs=1e-4)
    meta = json.loads((out / "hologram.json").read_text())
    assert meta["relief"]["depth_mm"] == pytest.approx(depth, abs=1e-4)
    # the grooves by the ball
    groove = _head(out / "hologram.gcode")
    assert _value(groove, "tool").startswith("ball end, round tip radius 0.25000 mm")
    assert _cut_depths(out / "hologram.gcode") == pytest.approx([0.08], abs=1e-9)
    for name in ("hologram.gcode", "relief.gcode"):
        limits = limits_from_header(out / name)
        assert limits is not None and limits.stock.thickness == 4.0
        assert _value(_head(out / name), "stock").startswith("4 mm thick plate")


def test_spin_refuses_a_relief_through_the_plate(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The relief cut reaches 0.45 mm with the default tool: a 0.3 mm plate is
    refused in one line; with both walls (no relief) it is cut."""
    out = tmp_path / "out"
    assert main(["spin", str(BUNNY), "--out", str(out), *FAST["spin"],
                 "--stock-thickness", "0.3"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "relief cut goes" in err[0] and "0.3 mm plate" in err[0]
    assert not out.exists()
    assert main(["spin", str(BUNNY), "--out", str(out), *FAST["spin"],
                 "--stock-thickness", "0.3", "--walls", "both"]) == 0


def test_steady_header_names_what_it_writes_and_the_plate_s_thickness(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["steady", str(BUNNY), "--out", str(out), *FAST["steady"],
                 "--stock-thickness", "2", "--tool-radius", "0.06", "--depth", "0.025"]) == 0
    capsys.readouterr()
    program = out / "hologram.gcode"
    assert _check(program) == 0
    assert "0 violation(s) (against the limits in its header)" in capsys.readouterr().out
    head = _head(program)
    # it writes no drawing: the header names none
    assert not any("SVG" in t or "DXF" in t for t in head)
    assert not {"hologram.svg", "hologram.dxf"} & {p.name for p in out.iterdir()}
    assert _value(head, "stock").startswith("2 mm thick plate")
    limits = limits_from_header(program)
    assert limits is not None and limits.stock.thickness == 2.0
    assert limits.max_depth == pytest.approx(0.025)
    assert _value(head, "tool") == "ball end, round tip radius 0.06 mm"
    assert _value(head, "depth").startswith("0.025 mm at most")
    assert max(_cut_depths(program)) <= 0.025 + 1e-5

"""``specholo spin``, ``specholo steady`` and ``specholo compose`` write their
programs for the dialect and in the units asked for (``--dialect``/``--units``,
a composition's ``[machining] dialect``/``units``): an inch LinuxCNC program is
the GRBL mm program of the same design with every length and feed divided by
25.4 (a rotary A axis still in degrees), says so in its header, passes the
safety check that reads it in mm, parses in LinuxCNC's interpreter to the same
cuts, and is recorded in hologram.json; a laser dialect is refused in one line
with no folder."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from legacy import old_settings
from test_gcode import needs_rs274, run_rs274
from test_kinds_spin_steady_bounds import _head

from specholo.errors import SpecholoError
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
INCH = 25.4
KINDS = ("spin", "steady", "compose")
#: The programs each kind writes.
PROGRAMS = {"spin": ("hologram.gcode", "relief.gcode"), "steady": ("hologram.gcode",),
            "compose": ("hologram.gcode",)}
#: Small designs, as tests/test_kinds_spin_steady_bounds.py runs them.
FAST = {"spin": ["--stipples", "8", "--frames", "0", "--step", "45"],
        "steady": ["--stipples", "20", "--step", "5"],
        "compose": ["--frames", "0", "--step", "15"]}
#: A cylinder on a rotary axis: X, Z and feeds in the program's units, A in degrees.
COMPOSITION = f"""stipples = 20
seed = 1
[host]
kind = "cylinder"
radius = 35
[viewer]
range = 20
[machining]
axes = 4
{{machining}}
[[scene]]
model = "{BUNNY.as_posix()}"
size = 30
center_z = -25
"""
#: Words whose values are lengths (scaled by the units) or angles (never).
LENGTHS, ANGLES = "XYZIJF", "A"


def _argv(kind: str, out: Path, inch: bool, folder: Path) -> list[str]:
    """The command writing ``kind`` into ``out``, in inches for LinuxCNC or as by default."""
    if kind == "compose":
        toml = folder / f"{out.name}.toml"
        toml.write_text(COMPOSITION.format(
            machining='dialect = "linuxcnc"\nunits = "inch"' if inch else ""))
        return ["compose", str(toml), "--out", str(out), *FAST[kind]]
    extra = ["--units", "inch", "--dialect", "linuxcnc"] if inch else []
    return [kind, str(BUNNY), "--out", str(out), *FAST[kind], *extra]


@pytest.fixture(scope="module", params=KINDS)
def written(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
            ) -> tuple[str, Path, Path]:
    """A kind's design written twice: by default (GRBL, mm) and in inches for LinuxCNC."""
    kind = request.param
    folder = tmp_path_factory.mktemp(kind)
    mm, inch = folder / "mm", folder / "inch"
    for out, in_inches in ((mm, False), (inch, True)):
        assert main(_argv(kind, out, in_inches, folder)) == 0
    return kind, mm, inch


def _commands(path: Path) -> list[str]:
    """The program's lines without their comments."""
    lines = (re.sub(r"\([^)]*\)", "", ln).strip() for ln in path.read_text().splitlines())
    return [ln for ln in lines if ln]


def _moves(path: Path) -> list[dict[str, float]]:
    """Each motion line's words (G0 to G3): letter -> value as written."""
    return [{w[0]: float(w[1:]) for w in ln.split()[1:]} for ln in _commands(path)
            if re.match(r"G[0-3]\b", ln)]


def _feed_ends(path: Path) -> np.ndarray:
    """(n, 4) X, Y, Z, A at the end of each feed move (G1, G2, G3), modal words carried."""
    pos = dict.fromkeys("XYZA", 0.0)
    ends = []
    for ln in _commands(path):
        words = ln.split()
        pos.update({w[0]: float(w[1:]) for w in words if w[0] in "XYZA"})
        if words[0] in ("G1", "G2", "G3") and any(w[0] in "XYZA" for w in words[1:]):
            ends.append([pos[k] for k in "XYZA"])
    return np.array(ends)


def _check(program: Path) -> int:
    """``specholo check PROGRAM`` with no options: its exit status."""
    try:
        return main(["check", str(program)])
    except SystemExit as exc:
        return int(exc.code or 0)


def test_the_inch_linuxcnc_program_is_the_mm_program_over_25_4(
        written: tuple[str, Path, Path]) -> None:
    kind, mm, inch = written
    for name in PROGRAMS[kind]:
        a, b = mm / name, inch / name
        head = _head(b)
        assert "dialect: LinuxCNC RS274/NGC" in head
        assert any(t.startswith("units: inch,") for t in head), head
        assert "dialect: GRBL 1.1" in _head(a)
        assert any(t.startswith("units: mm,") for t in _head(a))
        words = [set(ln.split()) for ln in _commands(b)]
        assert any("G20" in w for w in words) and not any("G21" in w for w in words)
        assert any("G21" in ln.split() for ln in _commands(a))
        ma, mb = _moves(a), _moves(b)
        assert len(ma) == len(mb) > 20, name
        for x, y in zip(ma, mb, strict=True):
            assert x.keys() == y.keys(), (x, y)
            for letter, v in y.items():
                want = x[letter] / INCH if letter in LENGTHS else x[letter]
                assert abs(v - want) <= 1e-5, (name, letter, v, want)
        # a few cut points, and the extents, as lengths
        ea, eb = _feed_ends(a), _feed_ends(b)
        np.testing.assert_allclose(eb[:, :3] * INCH, ea[:, :3], atol=1e-5 * INCH)
        np.testing.assert_allclose(eb[:, 3], ea[:, 3], atol=1e-5)
        np.testing.assert_allclose(np.ptp(eb[:, :3], axis=0) * INCH, np.ptp(ea[:, :3], axis=0),
                                   atol=2e-5 * INCH)
        assert np.ptp(eb[:, :2]) > 0.1  # inches: the grooves span the plate


def test_the_inch_program_passes_its_safety_check_in_mm_and_the_folder_says_so(
        written: tuple[str, Path, Path]) -> None:
    """The folder is published only once its programs passed the check, which
    reads G20 programs in mm: the deepest cut it finds in inches is the mm
    program's, and hologram.json records the dialect and units chosen (and
    the defaults for the mm design)."""
    kind, mm, inch = written
    meta = {k: json.loads((f / "hologram.json").read_text()) for k, f in (("mm", mm),
                                                                          ("inch", inch))}
    where = {"spin": ("settings", ("gcode", "safety_check")),
             "steady": ("settings", ("safety_check",)),
             "compose": ("gcode", ("gcode", "check"))}[kind]
    said = {k: (m[where[0]]["dialect"], m[where[0]]["units"]) for k, m in meta.items()}
    checks = {}
    for k, m in meta.items():
        for key in where[1]:
            m = m[key]
        checks[k] = m
    if kind != "compose":  # `specholo check` reads the limits in the header, in mm
        for name in PROGRAMS[kind]:
            assert _check(inch / name) == 0
    assert said == {"mm": ("grbl", "mm"), "inch": ("linuxcnc", "inch")}
    assert checks["inch"]["violations"] == 0
    assert checks["inch"]["moves"] == checks["mm"]["moves"]
    if "deepest_cut_mm" in checks["mm"]:
        # the same depth in mm, within the inch program's 6 decimals
        assert checks["mm"]["deepest_cut_mm"] > 0.01
        assert checks["inch"]["deepest_cut_mm"] == pytest.approx(checks["mm"]["deepest_cut_mm"],
                                                                 abs=1e-6 * INCH)


def test_the_folder_reads_back_its_dialect_and_units_and_an_old_one_grbl_in_mm(
        written: tuple[str, Path, Path], tmp_path: Path) -> None:
    from specholo.jobs import job_of

    kind, _, inch = written
    job = job_of(inch)
    loaded = job.load(inch)
    config = {"spin": lambda j: j.config, "steady": lambda j: j[1],
              "compose": lambda d: d.comp}[kind](loaded)
    assert (config.dialect, config.units) == ("linuxcnc", "inch")
    if kind == "compose":
        return  # its settings are its TOML, read again
    old = tmp_path / "old"
    shutil.copytree(inch, old)
    meta = old_settings(old)  # as written before every kind's settings had option names
    del meta["config"]["dialect"], meta["config"]["units"]
    (old / "hologram.json").write_text(json.dumps(meta))
    before = job.load(old)
    config = before.config if kind == "spin" else before[1]
    assert (config.dialect, config.units) == ("grbl", "mm")


@needs_rs274
def test_linuxcnc_reads_the_inch_program_as_cutting_the_mm_program(
        written: tuple[str, Path, Path]) -> None:
    kind, mm, inch = written
    for name in PROGRAMS[kind]:
        canon = run_rs274(inch / name)
        units = [args for n, args in canon if n == "USE_LENGTH_UNITS"]
        assert units[-1] == "CANON_UNITS_INCHES"
        cut = []
        for n, args in canon:
            if n in ("STRAIGHT_FEED", "ARC_FEED"):
                v = [float(x) for x in args.split(",")]
                # a line: x, y, z, a; an arc: x and y ends, centre, turn, z end, a
                cut.append(v[:4] if n == "STRAIGHT_FEED" else [v[0], v[1], v[5], v[6]])
        cut_mm = np.array(cut)
        cut_mm[:, :3] *= INCH
        want = _feed_ends(mm / name)
        assert cut_mm.shape == want.shape
        # rs274 prints 4 decimals of its units
        np.testing.assert_allclose(cut_mm[:, :3], want[:, :3], atol=6e-5 * INCH)
        np.testing.assert_allclose(cut_mm[:, 3], want[:, 3], atol=6e-5)


@pytest.mark.parametrize("kind, setting, words", [
    ("spin", ("--dialect", "marlin"), "'--dialect': 'marlin' is not one of 'grbl', 'linuxcnc'"),
    ("steady", ("--dialect", "marlin"), "'--dialect': 'marlin' is not one of 'grbl', 'linuxcnc'"),
    ("spin", ("--units", "cm"), "'--units': 'cm' is not one of 'mm', 'inch'"),
    ("compose", 'dialect = "marlin"', "composition: machining.dialect must be grbl or linuxcnc "
                                      "(a laser cannot cut these programs), got 'marlin'"),
    ("compose", 'units = "cm"', "composition: machining.units must be mm or inch, got 'cm'"),
    ("compose", "units = 25.4", "composition: machining.units must be mm or inch, got 25.4"),
])
def test_a_laser_or_unknown_units_are_refused_in_one_line_and_no_folder(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str,
        setting: tuple[str, str] | str, words: str) -> None:
    out = tmp_path / "out"
    if kind == "compose":
        toml = tmp_path / "c.toml"
        toml.write_text(COMPOSITION.format(machining=setting))
        argv = ["compose", str(toml), "--out", str(out), *FAST[kind]]
    else:
        argv = [kind, str(BUNNY), "--out", str(out), *FAST[kind], *setting]
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0
    assert len(err) == 1 and err[0].startswith("error:") and words in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("make", ["spin", "steady"])
def test_the_settings_refuse_a_laser_naming_the_option_and_why(make: str) -> None:
    from specholo.jobs.spin.design import SpinConfig
    from specholo.jobs.steady.design import SteadyConfig

    config = {"spin": SpinConfig, "steady": SteadyConfig}[make]
    with pytest.raises(SpecholoError) as laser:
        config(dialect="marlin")
    assert str(laser.value) == ("--dialect must be grbl or linuxcnc (a laser cannot cut these "
                                "programs), got 'marlin'")
    with pytest.raises(SpecholoError, match="^--units must be mm or inch, got 'mm '$"):
        config(units="mm ")
    assert config(dialect="linuxcnc", units="inch").settings()["units"] == "inch"

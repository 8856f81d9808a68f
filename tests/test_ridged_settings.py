"""A ridged plate's settings are its own (``RidgedConfig``) and a grooved design's
its own (``DesignConfig``): each refuses the other's options in one line naming
the option, and folders written when one set of settings held both still read."""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict, fields
from pathlib import Path

import pytest

from specholo.errors import SpecholoError
from specholo.jobs.flat.folder import load_design
from specholo.jobs.flat.settings import DesignConfig
from specholo.jobs.ridged.design import load_ridged_design
from specholo.jobs.ridged.settings import RidgedConfig
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
TINY_RIDGED = ["--method", "ridged", "--stipples", "40", "--view-range", "8",
               "--elevation-range", "4", "--raster", "0.05", "--formats", "png"]
TINY_FLAT = ["--stipples", "40", "--formats", "gcode"]

#: A grooved design's options on a ridged plate, and what the refusal names.
GROOVED_ONLY = [
    (["--band", "0.3"], "--band"), (["--band-share", "0.5"], "--band-share"),
    (["--placement", "phase"], "--placement"), (["--thin", "off"], "--thin"),
    (["--tool-angle", "60"], "--tool-angle"), (["--tip-flat", "0.01"], "--tip-flat"),
    (["--spot", "0.1"], "--spot"), (["--strict"], "--strict"), (["--no-order"], "--no-order"),
    (["--hop", "0.05"], "--hop"), (["--hop-max", "2"], "--hop-max"),
    (["--holder", "rigid"], "--holder"), (["--preload", "0.3"], "--preload"),
    (["--machine", "grbl-router"], "--machine times a grooved design"),
    (["--depth", "0.1"], "depth is a groove's"),
    (["--visibility", "0.8"], "visibility needs a grooved design"),
]
#: A ridged plate's options on a grooved design, and what the refusal names.
RIDGED_ONLY = [
    (["--shell", "0.1"], "--shell"), (["--raster", "0.05"], "--raster"),
    (["--elevation-range", "10"], "--elevation-range"), (["--optic", "reflect"], "--optic"),
    (["--optic", "refract"], "a refraction plate is a ridged design: use --method ridged"),
    (["--refraction", "single"], "--refraction"), (["--index", "1.6"], "--index"),
]
#: The grooved designs' settings a ridged folder recorded, with the values a
#: ridged design held, when one set of settings held both kinds'.
OLD_GROOVED = {"visibility": None, "band": 0.2, "band_share": None, "placement": "auto",
               "thin": "auto", "tool_angle": None, "tip_flat": 0.0, "spot": None,
               "depth": None, "strict": False, "order": True, "hop": 0.03, "hop_max": 3.0,
               "holder": "rigid", "preload": None, "machine": None}
#: The ridged plate's settings a grooved folder recorded then, at their defaults.
OLD_RIDGED = {"elevation_range": 15.0, "shell": 0.1, "raster": 0.02, "optic": "reflect",
              "refraction": "exact", "index": 1.49}


def refused(argv: list[object], capsys: pytest.CaptureFixture[str]) -> str:
    """Run a command that must be refused: non-zero, one line, no traceback."""
    code = main([str(a) for a in argv])
    _, err = capsys.readouterr()
    assert code != 0, argv
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), (argv, err)
    assert "Traceback" not in err and "internal error" not in err, (argv, err)
    return lines[0]


@pytest.mark.parametrize(("extra", "names"), GROOVED_ONLY, ids=lambda v: str(v))
def test_a_grooved_option_on_a_ridged_plate_is_refused_in_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], names: str):
    out = tmp_path / "out"
    line = refused(["design", BUNNY, "--out", out, "--method", "ridged", *extra], capsys)
    assert names in line, line
    assert not out.exists()


@pytest.mark.parametrize(("extra", "names"), RIDGED_ONLY, ids=lambda v: str(v))
@pytest.mark.parametrize("method", [None, "striped", "arc"])
def test_a_ridged_option_on_a_grooved_design_is_refused_in_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], names: str,
        method: str | None):
    out = tmp_path / "out"
    chosen = [] if method is None else ["--method", method]
    line = refused(["design", BUNNY, "--out", out, *chosen, *extra], capsys)
    assert names in line, line
    assert "--method ridged" in line, line
    assert not out.exists()


def test_a_config_file_is_held_to_the_same(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    toml = tmp_path / "ridged.toml"
    toml.write_text('method = "ridged"\nplacement = "phase"\n')
    assert "--placement" in refused(["design", BUNNY, "--out", tmp_path / "a", "--config",
                                     toml], capsys)
    toml.write_text("shell = 0.2\n")
    assert "--shell" in refused(["design", BUNNY, "--out", tmp_path / "b", "--config", toml],
                                capsys)


def test_the_library_refuses_the_other_kinds_settings():
    for name in ("band", "hop", "holder", "tool-angle"):
        with pytest.raises(SpecholoError, match=f"--{name} is a grooved design's") as err:
            RidgedConfig.from_dict({name: None})
        assert "\n" not in str(err.value)
    for name in ("shell", "raster", "elevation_range"):
        with pytest.raises(SpecholoError, match=f"--{name.replace('_', '-')} is a ridged"):
            DesignConfig.from_dict({name: 1.0})
    for config in (RidgedConfig, DesignConfig):
        with pytest.raises(SpecholoError, match="unknown setting 'frobnicate'"):
            config.from_dict({"frobnicate": 1})
    with pytest.raises(SpecholoError, match="RidgedConfig"):
        DesignConfig(method="ridged")
    with pytest.raises(SpecholoError, match="method is ridged"):
        RidgedConfig(method="striped")
    # the ridged defaults are the config's own
    config = RidgedConfig.from_dict({})
    assert (config.size, config.center_z, config.view_range, config.elevation_range,
            config.tool, config.method) == (50.0, -20.0, 20.0, 8.0, "ball", "ridged")
    assert RidgedConfig.from_dict({"optic": "refract"}).light_elevation == -90.0


@pytest.fixture(scope="module")
def ridged(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ridged") / "plate"
    assert main(["design", str(BUNNY), "--out", str(out), *TINY_RIDGED]) == 0
    return out


@pytest.fixture(scope="module")
def flat(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("flat") / "plate"
    assert main(["design", str(BUNNY), "--out", str(out), *TINY_FLAT]) == 0
    return out


def _as_written_before(folder: Path, into: Path, extra: dict[str, object]) -> Path:
    """A copy of a folder whose hologram.json settings hold every key the one set
    of settings both kinds shared recorded."""
    shutil.copytree(folder, into)
    meta = json.loads((into / "hologram.json").read_text())
    meta["settings"] = {**meta["settings"], **extra}
    (into / "hologram.json").write_text(json.dumps(meta, indent=1))
    return into


def test_a_ridged_folder_holds_only_the_ridged_settings(ridged: Path):
    settings = json.loads((ridged / "hologram.json").read_text())["settings"]
    assert set(settings) == {f.name for f in fields(RidgedConfig)}
    assert settings["method"] == "ridged" and not set(settings) & set(OLD_GROOVED)


def test_an_old_ridged_folder_still_verifies(ridged: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]):
    old = _as_written_before(ridged, tmp_path / "old", OLD_GROOVED)
    assert main(["verify", str(old), "--step", "4"]) == 0, capsys.readouterr().err
    assert (old / "verify.json").is_file()
    assert load_ridged_design(old).config == load_ridged_design(ridged).config
    # whatever the grooved settings held: the ridged design never used them
    odd = _as_written_before(ridged, tmp_path / "odd", {**OLD_GROOVED, "band": 0.5,
                                                         "strict": True, "order": False})
    assert load_ridged_design(odd).config == load_ridged_design(ridged).config


def test_an_old_flat_folder_still_verifies(flat: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]):
    settings = json.loads((flat / "hologram.json").read_text())["settings"]
    assert not set(settings) & set(OLD_RIDGED)
    old = _as_written_before(flat, tmp_path / "old", OLD_RIDGED)
    assert main(["verify", str(old)]) == 0, capsys.readouterr().err
    assert load_design(old).config == load_design(flat).config


def test_an_old_coupons_design_settings_still_read():
    from specholo.jobs.flat.coupon import CouponConfig

    config = CouponConfig.from_options({})
    saved = config.saved()
    saved["design"] = {**saved["design"], **OLD_RIDGED}
    assert CouponConfig.from_saved(saved) == config
    assert asdict(config.design).keys().isdisjoint(OLD_RIDGED)

"""Every kind records its settings in hologram.json the same way: under
``settings``, by its command's option names and in the command's units (mm,
degrees), and reads them back to the same configuration."""

from __future__ import annotations

import json
import math

import pytest

from specholo.jobs.spin.design import SpinConfig
from specholo.jobs.steady.design import SteadyConfig
from specholo.scene.pose import Pose
from specholo.setup import Machining
from specholo_cli.cli import cli

#: Settings that are not the command's options: the feeds and heights a library
#: user may change (a flat design's options of the same names), and the fits'
#: own sampling.
NOT_OPTIONS = {"feed", "plunge", "safe_z", "spindle", "hop", "hop_max", "harmonics",
               "angles", "samples", "eye_height"}


def configs() -> dict[str, object]:
    pose = Pose("z", (10.0, -20.0, 30.0), (1.5, -2.5))
    machining = Machining(450.0, 90.0, 2.0, 0.0, 0.05, 2.0)
    return {
        "spin": _replace(SpinConfig.from_options(
            size=35.0, center_z=-5.0, turns=2, stipples=120, seed=7, view_distance=500.0,
            view_elevation=40.0, ipd=60.0, light_height=300.0, walls="both",
            occlusion=False, tool_radius=0.2, depth=0.07, pose=pose, plate_width=80.0,
            plate_height=70.0, fit=True, stock_thickness=4.0, dialect="linuxcnc",
            units="inch"), machining),
        "steady": _replace(SteadyConfig.from_options(
            size=30.0, center_z=-15.0, stipples=90, seed=3, view_distance=700.0, ipd=62.0,
            light_elevation=50.0, light_sweep=7.0, shape="flat", tool_radius=0.06,
            depth=0.025, pose=pose, plate_width=60.0, plate_height=50.0,
            stock_thickness=2.5, dialect="linuxcnc", units="inch"), machining),
    }


def _replace(config: object, machining: Machining) -> object:
    import dataclasses

    return dataclasses.replace(config, machining=machining)  # type: ignore[type-var]


@pytest.mark.parametrize("kind", ["spin", "steady"])
def test_the_settings_read_back_to_the_same_configuration(kind: str) -> None:
    config = configs()[kind]
    saved = json.loads(json.dumps(config.settings()))  # type: ignore[attr-defined]
    again = type(config).from_settings(saved)  # type: ignore[attr-defined]
    assert again == config
    # in the command's units: the angles in degrees
    if kind == "spin":
        assert saved["view_elevation"] == pytest.approx(40.0)
        assert again.setup.elevation == pytest.approx(math.radians(40.0))
    else:
        assert (saved["light_elevation"], saved["light_sweep"]) == pytest.approx((50.0, 7.0))


@pytest.mark.parametrize("kind", ["spin", "steady"])
def test_the_settings_are_named_as_the_command_names_its_options(kind: str) -> None:
    command = cli.commands[kind]
    # a flag --no-X records X: true without it
    options = {str(p.name).removeprefix("no_") for p in command.params}
    saved = configs()[kind].settings()  # type: ignore[attr-defined]
    assert set(saved) - NOT_OPTIONS <= options


@pytest.mark.parametrize(("kind", "key", "value", "says"), [
    ("spin", "view_elevation", None, "view_elevation must be given"),
    ("spin", "elevation_deg", 45.0, "unknown setting 'elevation_deg'"),
    ("steady", "light_sweep", "wide", "light_sweep must be a number"),
])
def test_a_bad_setting_is_refused_naming_it(kind: str, key: str, value: object,
                                            says: str) -> None:
    from specholo.errors import SpecholoError

    saved = {**configs()[kind].settings(), key: value}  # type: ignore[attr-defined]
    with pytest.raises(SpecholoError, match=says):
        type(configs()[kind]).from_settings(saved)  # type: ignore[attr-defined]

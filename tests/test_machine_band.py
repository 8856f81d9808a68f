"""A machine whose strokes lift the tool gets a band chosen from the stipples' spacing.

On a router (or mill, or plotter) every stroke costs a lift and a lowering,
about as much as its cut, and the striping's band sets how many strokes a
stipple takes. With such a ``--machine`` and no ``--band``, the design widens the
band to a share of the neighbouring stipples' spacing as the eye sees it: fewer
strokes, and an image error still within the band.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from specholo.jobs.flat.design import design, stipple_spacing
from specholo.jobs.flat.settings import BAND, MACHINE_BAND_SHARE, DesignConfig
from specholo.simulation.verify import summarise, verify
from specholo_cli.cli import main

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
SCENE = dict(stipples=300, size=60, center_z=-40, light_elevation=45, view_distance=600,
             view_range=45)


def test_a_router_widens_the_band_to_a_share_of_the_stipple_spacing() -> None:
    chosen = design(BUNNY, DesignConfig.from_dict({**SCENE, "machine": "grbl-router"}),
                    expect_as_cut=False)
    fixed = design(BUNNY, DesignConfig.from_dict({**SCENE, "machine": "grbl-router",
                                                  "band": BAND}), expect_as_cut=False)
    band = float(chosen.config.band or 0.0)
    assert chosen.config.band_share is None  # applied once, recorded as the band
    distance = chosen.config.setup().viewer.distance
    spacing = stipple_spacing(chosen.points, distance)
    assert spacing is not None
    seen = math.degrees(band / distance) * 60.0  # arcmin
    assert band > BAND and seen == pytest.approx(MACHINE_BAND_SHARE * spacing, abs=0.05)
    # the same stipples, in fewer strokes
    assert np.array_equal(chosen.points, fixed.points)
    assert chosen.grooves.n_paths < 0.9 * fixed.grooves.n_paths
    # and each point still appears within the band of its place (p95, both eyes)
    az = np.radians([-40.0, -20.0, 0.0, 20.0, 40.0])
    worst = summarise(verify(chosen.grooves, chosen.points, chosen.config.setup(),
                             azimuths=az))["worst_p95_error"]
    assert worst <= band
    assert chosen.band_note.startswith("chosen for grbl-router")


@pytest.mark.parametrize("settings", [{"machine": "galvo-fiber"},
                                      {"machine": "grbl-router", "band": 0.25},
                                      {"machine": "grbl-router", "method": "arc"},
                                      {}])
def test_a_laser_a_given_band_or_no_machine_keeps_it(settings: dict[str, object]) -> None:
    cfg = DesignConfig.from_dict({**SCENE, **settings})
    assert cfg.band_share is None
    assert cfg.band == settings.get("band", BAND)


def test_the_summary_says_why_the_band_is_wide(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["design", str(BUNNY), "--out", str(tmp_path / "d"), "--stipples", "60",
                 "--machine", "pen-plotter"]) == 0
    out = capsys.readouterr().out
    assert "chosen for pen-plotter, whose strokes each lift the tool" in out


def test_the_setup_and_cutter_are_built_once_per_settings() -> None:
    """Every layer asks the settings for the setup and the cutter: it gets the
    same objects, and settings that differ get their own."""
    cfg = DesignConfig.from_dict(dict(SCENE))
    assert cfg.setup() is cfg.setup() and cfg.cutter() is cfg.cutter()
    assert cfg.setup().tool == cfg.cutter().model(cfg.depth_mm)
    other = DesignConfig.from_dict({**SCENE, "light_elevation": 30})
    assert other.setup() is not cfg.setup()
    assert other.setup().light.elevation == pytest.approx(math.radians(30.0))
    assert other == DesignConfig.from_dict({**SCENE, "light_elevation": 30})  # eq ignores it

"""A laser's program reads back into the grooves it marks, so the plate as cut is
verified from the file a galvo or gantry laser will run.

A Marlin program has no Z: a groove is the feed moves made while the beam is on
(``M3``/``M4`` to ``M5``), a dot the beam switched on and off where it stands, and
each names its stipple in a ``; stipple N`` comment.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from specholo.fabrication.programs.gcode import write_gcode
from specholo.fabrication.programs.gcode_reader import read_gcode
from specholo.fabrication.programs.program import GcodeOptions
from specholo.setup import Machining, Tool
from specholo.toolpaths.grooves import Grooves
from specholo_cli.cli import main

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


def _grooves() -> Grooves:
    """Two arcs turning both ways, a dot, a straight pair and another dot."""
    vertices = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0],   # stipple 4: two arcs
                         [3.0, -2.0],                               # stipple 7: a dot
                         [-5.0, -5.0], [-1.0, -6.0], [2.0, -9.0],  # stipple 2: lines
                         [-8.0, 4.0]])                              # stipple 0: a dot
    bulges = np.array([0.3, -0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    return Grooves(vertices, bulges, np.array([0, 3, 4, 7, 8]), np.array([4, 7, 2, 0]))


@pytest.mark.parametrize("units", ["mm", "inch"])
def test_a_laser_program_reads_back_into_its_grooves(tmp_path: Path, units: str) -> None:
    grooves = _grooves()
    path = tmp_path / "laser.gcode"
    write_gcode(path, grooves, Tool(), Machining(),
                options=GcodeOptions(dialect="marlin", units=units))  # type: ignore[arg-type]
    back = read_gcode(path)
    assert back.n_paths == grooves.n_paths
    assert np.array_equal(back.offsets, grooves.offsets)
    assert np.array_equal(back.stipple, grooves.stipple)
    grid = 1e-5 if units == "mm" else 25.4e-6  # half the written grid, and a margin
    assert np.abs(back.vertices - grooves.vertices).max() <= grid
    # the arcs keep their sweep (a bulge is tan(sweep / 4))
    assert np.allclose(back.bulges, grooves.bulges, atol=1e-6)
    assert back.is_dot.tolist() == [False, True, False, True]


def test_a_lasers_plate_as_cut_is_verified_from_its_program(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "d"
    assert main(["design", str(BUNNY), "--out", str(out), "--stipples", "80", "--size", "40",
                 "--center-z", "-30", "--tool", "laser"]) == 0
    capsys.readouterr()
    assert main(["verify", str(out), "--cut"]) == 0
    cut = json.loads((out / "verify_cut.json").read_text())
    assert cut["source"] == "hologram.gcode"
    # the plate as cut from the laser's program shows the image
    lowest = cut["summary"]["min_visibility"]
    assert 0.5 < lowest <= 1.0 and cut["summary"]["worst_p95_error"] < 1.0
    # as the design estimated it from its own grooves, within a few stipples
    expected = json.loads((out / "hologram.json").read_text())["expected"]
    low = expected["as_cut_stereo_visibility"]["lowest"]
    assert lowest == pytest.approx(low, abs=0.1)

"""The most stipples that reach a visibility as cut: the plate found is checked
again by the survival test itself, and what cannot be reached is refused."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from specholo.errors import SpecholoError
from specholo.jobs.flat.density import design_for_visibility
from specholo.jobs.flat.folder import DesignConfig
from specholo.simulation.survival import verify_as_cut
from specholo.simulation.verify import view_azimuths
from specholo.visibility.occlusion import visible

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
#: A small, crowded plate: a few hundred stipples already cut each other away.
CROWDED = {"size": 15.0, "center_z": -10.0, "stipples": 300, "placement": "phase"}


def test_the_count_found_reaches_the_visibility_and_more_do_not():
    tries: list[tuple[int, float]] = []
    config = DesignConfig.from_dict({**CROWDED, "visibility": 0.7})
    d = design_for_visibility(BUNNY, config, lambda n, v: tries.append((n, v)))
    n = len(d.points)
    # the first try (300 stipples) falls short: the search came down from it
    assert tries[0] == (300, pytest.approx(tries[0][1])) and tries[0][1] < 0.7
    assert n < 300 and d.config.stipples == n
    # the plate as cut, measured again from its grooves: every view keeps 70%
    setup = d.config.setup()
    az = view_azimuths(setup.viewer.half_range, math.radians(5.0))
    as_cut = verify_as_cut(d.grooves, d.points, setup, d.config.cutter(), d.config.depth_mm,
                           lambda p, e: visible(d.model.mesh, p, d.normals, e), az)
    lowest = min(r.visibility for r in as_cut.reports if r.stipples_seen)
    assert lowest >= 0.7
    # every larger count tried fell short of it
    assert all(v < 0.7 for m, v in tries if m > n)
    assert any(m > n for m, _ in tries)


def test_an_unreachable_visibility_is_refused():
    # a 150 degree cone offers walls tilted up to 15 degrees: the views need
    # more, so no count keeps 99% of the stipples
    config = DesignConfig.from_dict({**CROWDED, "stipples": 60, "visibility": 0.99,
                                     "tool_angle": 150.0})
    with pytest.raises(SpecholoError, match="no stipple count reaches 99%"):
        design_for_visibility(BUNNY, config)

"""Stripes joined into strokes (toolpaths.joining): the hand-overs it joins are
the striping's own (same stipple, same x, one band apart), the strokes keep
every stripe and add only the connectors, and a connector is made only where
no eye of the range can see its walls glint."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from specholo.jobs.flat.folder import DesignConfig, design
from specholo.simulation.glints import Engraved, find_glints
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.joining import SAME_X, dark, join_stripes

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


@pytest.fixture(scope="module")
def designed():
    cfg = DesignConfig(stipples=80, size=60, center_z=-40, light_elevation=45,
                       view_distance=600, view_range=45)
    return design(BUNNY, cfg, expect_as_cut=False)


def test_strokes_keep_every_stripe_and_add_only_connectors(designed):
    g = designed.grooves
    j = join_stripes(g, designed.config.setup())
    j.grooves.validate(len(designed.points))
    # Far fewer strokes: about one a stipple where dozens of stripes were.
    assert j.grooves.n_paths < 0.05 * g.n_paths
    assert j.grooves.n_paths >= len(np.unique(g.stipple))
    assert j.joined == g.n_paths - j.grooves.n_paths
    assert j.grooves.total_length() == pytest.approx(g.total_length() + j.connector_length,
                                                     rel=1e-9)
    # Every stripe vertex is still there, with its stipple.
    before = {(s, round(x, 9), round(y, 9)) for s, (x, y) in
              zip(np.repeat(g.stipple, g.path_sizes), g.vertices, strict=True)}
    after = {(s, round(x, 9), round(y, 9)) for s, (x, y) in
             zip(np.repeat(j.grooves.stipple, j.grooves.path_sizes), j.grooves.vertices,
                 strict=True)}
    assert before == after
    # A connector is a hand-over: the same x, one band or so apart in y.
    d = j.connectors[:, 1] - j.connectors[:, 0]
    assert np.all(np.abs(d[:, 0]) <= SAME_X) and np.all(np.abs(d[:, 1]) <= 1.0)


def test_connectors_send_no_glint_to_any_eye(designed):
    """The connectors alone, as grooves, glint for no eye of the range."""
    setup = designed.config.setup()
    j = join_stripes(designed.grooves, setup)
    c = j.connectors
    k = len(c)
    alone = Grooves(c.reshape(-1, 2), np.zeros(2 * k), np.arange(0, 2 * k + 1, 2),
                    np.zeros(k, dtype=np.int64))
    eng = Engraved.from_grooves(alone, setup.tool)
    r = setup.viewer.design_range
    for eye in setup.viewer.eye(np.linspace(-r, r, 13)):
        assert len(find_glints(eng, eye, setup.light).stipple) == 0


def test_a_connector_across_the_light_is_not_dark(designed):
    """Vertical connectors are dark under a light above the plate; horizontal
    ones are seen from some azimuth (h's x component changes sign over the
    range), so they are never made."""
    setup = designed.config.setup()
    a = np.array([[0.0, 0.0], [0.0, 0.0]])
    b = np.array([[0.0, 0.3], [0.3, 0.0]])
    assert dark(a, b, setup).tolist() == [True, False]

"""Stripes that end together ("lock" placement): both eyes meet stripe ends alike."""

from __future__ import annotations

import numpy as np
import pytest
from test_avoid import _design, _runs, _setup

from specholo.optics.spread import GLOSS, SUN, Spread
from specholo.simulation.glints import Engraved, find_glints
from specholo.simulation.streak_verify import verify_streaks
from specholo.simulation.verify import verify
from specholo.toolpaths import striped
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.striped import StripeOptions

# The setup (the README's drag tip, eyes 600 mm away over +-45 deg), the runs
# (every stipple over the whole design range) and the design are test_avoid's.


def _scene(n: int = 24, seed: int = 5) -> np.ndarray:
    """Stipples spread over a plate, in front of it and behind, a few mm apart."""
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-15, 15, n), rng.uniform(-10, 10, n),
                            rng.uniform(-30, 20, n)])


@pytest.fixture(scope="module")
def designs() -> dict[str, Grooves]:
    """"phase", "auto" (the avoiding plan here), "lock" (the plan, on the grid)
    and "lock walk" (the phase walk on the grid, as where the plan would not
    fit)."""
    setup, pts = _setup(), _scene()
    out = {p: _design(pts, p, setup) for p in ("phase", "auto")}
    info: dict[str, str] = {}
    out["lock"] = _design(pts, "lock", setup, info)
    assert info == {"placement": "lock"}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(striped, "AUTO_MAX_PLAN_SAMPLES", 0)
        info = {}
        out["lock walk"] = _design(pts, "lock", setup, info)
        assert info["placement"] == "lock" and "plan samples" in info["fallback"]
    return out


LOCKED = ("lock", "lock walk")


def test_lock_periods_divide_the_eyes_separation() -> None:
    """Each run's period is the eyes' separation over a whole number, the fewest
    parts in which the run's mean drift fits the band; a run drifting less
    than a band's height over the eyes' separation has no grid."""
    setup, pts = _setup(), _scene()
    runs = _runs(pts, setup)
    params = striped._params(setup, StripeOptions())
    period = striped.lock_periods(runs, params, setup, 0.2)
    lock = 2.0 * setup.viewer.eye_half_angle
    drift = striped.kernel.drifts(runs.start, runs.end, np.ascontiguousarray(runs.point),
                                  params, 0.2)
    gridded = period > 0
    # runs whose stripes outlast the eyes' separation anyway keep no grid
    assert np.array_equal(gridded, drift * lock > 2 * 0.2)
    assert 0 < gridded.sum() < len(period)
    parts = lock / period[gridded]
    assert np.allclose(parts, np.round(parts)) and parts.min() >= 2
    assert np.all(drift[gridded] * period[gridded] <= 2 * 0.2 + 1e-9)
    assert np.all(drift[gridded] * lock / (parts - 1) > 2 * 0.2)


def test_an_eye_on_the_azimuth_where_every_stripe_ends_sees_every_stipple(
        designs: dict[str, Grooves]) -> None:
    """Every stipple hands over from one stripe to the next at the same azimuths
    (a + (j + 1/2) periods, a the eye half-angle): an eye exactly there (both
    eyes of a head at an odd multiple of half a period) still sees each
    stipple's glint."""
    setup, pts = _setup(), _scene()
    runs = _runs(pts, setup)
    period = striped.lock_periods(runs, striped._params(setup, StripeOptions()), setup, 0.2)
    for name in LOCKED:
        eng = Engraved.from_grooves(designs[name], setup.tool)
        checked = 0
        for s in np.flatnonzero(period > 0):
            grid = setup.viewer.eye_half_angle + (np.arange(-40, 40) + 0.5) * period[s]
            for theta in grid[np.abs(grid) < setup.viewer.half_range][::3]:
                eye = setup.viewer.eye(np.array([theta]))[0]
                assert s in find_glints(eng, eye, setup.light).image().stipple, name
                checked += 1
        assert checked > 100


def test_a_head_a_whole_eye_separation_over_sees_every_stipple_mid_stripe(
        designs: dict[str, Grooves]) -> None:
    """A head turned a whole number of eye separations (2a, 6.1 deg here) from
    straight on has both eyes half a period from every grid azimuth: each
    gridded stipple's glint lies in the middle of its stripe, where "phase"
    puts some next to an end."""
    setup, pts = _setup(), _scene()
    runs = _runs(pts, setup)
    period = striped.lock_periods(runs, striped._params(setup, StripeOptions()), setup, 0.2)

    def inside(grooves: Grooves, head: float) -> np.ndarray:
        """Each glint's distance to its stripe's nearer end over the stripe's
        end-to-end length, both eyes, gridded stipples only."""
        eng = Engraved.from_grooves(grooves, setup.tool)
        v = grooves.vertices
        first, last = v[grooves.offsets[:-1], :2], v[grooves.offsets[1:] - 1, :2]
        out = []
        for eye in setup.viewer.stereo(np.array([head]))[0]:
            g = find_glints(eng, eye, setup.light).image()
            keep = period[g.stipple] > 0
            p, xy = g.path[keep], g.point[keep, :2]
            near = np.minimum(np.linalg.norm(xy - first[p], axis=1),
                              np.linalg.norm(xy - last[p], axis=1))
            out.append(near / np.linalg.norm(last[p] - first[p], axis=1))
        return np.concatenate(out)

    separation = 2.0 * setup.viewer.eye_half_angle
    for k in (-4, -2, 2, 4):
        for free in ("phase", "auto"):
            assert inside(designs[free], k * separation).min() < 0.1
        for name in LOCKED:
            locked = inside(designs[name], k * separation)
            assert len(locked) > 10
            assert locked.min() > 0.4, name


def test_lock_keeps_the_ideal_glints_on_the_sightline(designs: dict[str, Grooves]) -> None:
    """Every stipple glints for both eyes at every azimuth, within the bands the
    stripes may drift over (3 bands at most)."""
    setup, pts = _setup(), _scene()
    for name in LOCKED:
        reports = verify(designs[name], pts, setup,
                         azimuths=np.radians(np.arange(-45, 46, 3.0)))
        assert all(r.visibility == 1.0 for r in reports)
        # the apparent point moves about as far as the glint strays vertically
        assert max(r.max_error for r in reports) < 1.1 * striped.LOCK_SLACK * 0.2


def test_under_the_sun_locked_ends_blur_the_image_less(designs: dict[str, Grooves]) -> None:
    """The sun on a mirror finish, every degree: the stipples' worst p95 error is
    well under that of stripes ending wherever their band does (one family,
    or placed out of each other's way), and fewer stripe ends spill light far
    from a designed glint."""
    setup, pts = _setup(), _scene()
    spread = Spread(SUN, GLOSS["mirror"])
    az = np.radians(np.arange(-45.0, 45.5, 1.0))
    figures = {}
    for placement, grooves in designs.items():
        reports = verify_streaks(grooves, pts, setup, spread, azimuths=az)
        figures[placement] = (max(r.p95_error for r in reports),
                              float(np.mean([r.end_spills for r in reports])))
    for free in ("phase", "auto"):
        for name in LOCKED:
            assert figures[name][0] < 0.7 * figures[free][0], figures
            assert figures[name][1] < figures[free][1], figures


def test_lock_costs_few_more_strokes(designs: dict[str, Grooves]) -> None:
    """The grid ends a stripe where the band would not have yet, and the band's
    edge ends fewer: about as many strokes, no more groove."""
    for name, free in (("lock", "auto"), ("lock walk", "phase")):
        lock, other = designs[name], designs[free]
        assert lock.n_paths < 1.3 * other.n_paths
        assert lock.total_length() == pytest.approx(other.total_length(), rel=0.02)


def test_only_the_gridded_stipples_drift_past_the_band(designs: dict[str, Grooves]) -> None:
    """A stipple the grid ends the stripes of may drift 3 bands from its
    sightline before the band's edge ends one; a stipple without a grid (its
    stripes outlast the eyes' separation anyway) keeps to the band."""
    setup, pts = _setup(), _scene()
    runs = _runs(pts, setup)
    period = striped.lock_periods(runs, striped._params(setup, StripeOptions()), setup, 0.2)
    for name in LOCKED:
        eng = Engraved.from_grooves(designs[name], setup.tool)
        drift: dict[bool, list[float]] = {True: [], False: []}
        for theta in np.radians(np.arange(-45.0, 46.0, 1.5)):
            eye = setup.viewer.eye(np.array([theta]))[0]
            g = find_glints(eng, eye, setup.light).image()
            p = pts[g.stipple]
            # where the eye's sightline through the stipple is at the glint's depth
            t = (g.point[:, 2] - eye[2]) / (p[:, 2] - eye[2])
            cross = eye + t[:, None] * (p - eye)
            for gridded, u in zip(period[g.stipple] > 0, g.point[:, 1] - cross[:, 1],
                                  strict=True):
                drift[bool(gridded)].append(abs(u))
        assert max(drift[False]) <= 0.2 * 1.05, name
        assert 0.2 * 1.05 < max(drift[True]) <= striped.LOCK_SLACK * 0.2 * 1.05, name

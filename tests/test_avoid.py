"""Striped stripes placed out of each other's way: glints outside other grooves' sweeps."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from specholo.errors import SpecholoError
from specholo.setup import Light, Setup, Tool, Viewer
from specholo.simulation.glints import Engraved, find_glints
from specholo.simulation.verify import verify
from specholo.toolpaths import striped
from specholo.toolpaths.common import Runs, make_runs
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.striped import StripeOptions, design_striped

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
#: The README's drag tip at its design depth: tip radius 0.05 mm, 0.0115 mm deep.
TOOL = Tool(0.05, 0.0115)


def _setup() -> Setup:
    return Setup(light=Light(math.radians(45.0)),
                 viewer=Viewer(600.0, 0.0, math.radians(45.0), 64.0), tool=TOOL)


def _scene(n: int = 16, seed: int = 3) -> np.ndarray:
    """Points crowded into a small box at several depths: their grooves must cross."""
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n),
                            rng.uniform(-30, -10, n)])


def _runs(points: np.ndarray, setup: Setup) -> Runs:
    half = setup.viewer.design_range
    n = len(points)
    return make_runs(points, np.arange(n), np.full(n, -half), np.full(n, half))


def _design(points: np.ndarray, placement: str, setup: Setup,
            info: dict[str, str] | None = None) -> Grooves:
    grooves, dropped = design_striped(_runs(points, setup), setup,
                                      StripeOptions(placement=placement), info=info)
    assert dropped.size == 0
    return grooves


def _centrelines(eng: Engraved, path_of_arc: np.ndarray,
                 step: float = 0.002) -> tuple[np.ndarray, np.ndarray]:
    """Centreline points (m, 2) every ``step`` mm or closer, and their paths (m,)."""
    length = np.abs(eng.sweep) * eng.radius
    length = np.where(eng.radius > 0, length, np.linalg.norm(eng.end - eng.start, axis=1))
    k = np.maximum(np.ceil(length / step).astype(int), 1) + 1
    idx = np.repeat(np.arange(len(k)), k)
    u = np.concatenate([np.linspace(0.0, 1.0, q) for q in k])
    pts, _ = eng.at(idx, u)
    return pts[:, :2], path_of_arc[idx]


def _survival(grooves: Grooves, setup: Setup, azimuths: np.ndarray) -> tuple[float, int]:
    """Share of the glints no other path's swept tip contains, and how many glints.

    A glint of tilt t sits R sin t from its own centreline, at the height where
    a cut of the same depth is R sin t wide: another path destroys it exactly
    when its centreline passes closer to the glint than that.
    """
    eng = Engraved.from_grooves(grooves, setup.tool)
    arc_path = np.repeat(np.arange(grooves.n_paths), grooves.path_sizes - 1)
    line, owner = _centrelines(eng, arc_path)
    tree = cKDTree(line)
    r_tip, z_centre = setup.tool.radius, setup.tool.radius - setup.tool.depth
    kept = total = 0
    for theta in azimuths:
        for eye in setup.viewer.stereo(np.array([theta])):
            gl = find_glints(eng, eye[0], setup.light)
            cos_t = np.clip((z_centre - gl.point[:, 2]) / r_tip, -1.0, 1.0)
            reach = r_tip * np.sqrt(1.0 - cos_t**2)
            for g, r, path in zip(gl.point[:, :2], reach, gl.path, strict=True):
                near = tree.query_ball_point(g, r - 1e-4)
                total += 1
                kept += not np.any(owner[near] != path)
    return kept / total, total


@pytest.fixture(scope="module")
def designs() -> dict[str, Grooves]:
    setup = _setup()
    pts = _scene()
    return {p: _design(pts, p, setup) for p in ("phase", "avoid")}


def test_own_centreline_is_the_kill_radius() -> None:
    """The glint's horizontal distance from its own centreline is R sin t, t its tilt."""
    setup = _setup()
    grooves = _design(np.array([[0.0, 0.0, -20.0]]), "phase", setup)
    eng = Engraved.from_grooves(grooves, setup.tool)
    arc_path = np.repeat(np.arange(grooves.n_paths), grooves.path_sizes - 1)
    line, owner = _centrelines(eng, arc_path, step=0.0005)
    gl = find_glints(eng, setup.viewer.eye(np.array([0.3]))[0], setup.light)
    assert len(gl.path) >= 1
    r_tip, z_centre = setup.tool.radius, setup.tool.radius - setup.tool.depth
    for g, path in zip(gl.point, gl.path, strict=True):
        own = np.min(np.linalg.norm(line[owner == path] - g[:2], axis=1))
        sin_t = math.sqrt(1.0 - ((z_centre - g[2]) / r_tip) ** 2)
        assert own == pytest.approx(r_tip * sin_t, abs=2e-4)


def test_avoiding_keeps_glints_out_of_other_grooves(designs: dict[str, Grooves]) -> None:
    """Crowded stipples: most glints stay outside every other path's sweep, far more
    than when each stipple is designed alone."""
    setup = _setup()
    az = np.radians(np.arange(-45.0, 46.0, 15.0))
    alone, n_alone = _survival(designs["phase"], setup, az)
    placed, n_placed = _survival(designs["avoid"], setup, az)
    assert n_alone > 100 and n_placed > 100
    assert placed > 0.9
    assert placed > alone + 0.1


def test_avoiding_keeps_the_ideal_glints_on_the_sightline(designs: dict[str, Grooves]) -> None:
    """Every stipple glints for both eyes at every azimuth, within the band of its point."""
    setup = _setup()
    pts = _scene()
    for r in verify(designs["avoid"], pts, setup):
        assert r.visibility == 1.0
        assert r.max_error < 0.25


def test_avoiding_keeps_the_groove_length(designs: dict[str, Grooves]) -> None:
    """Jumping between leaves moves grooves, it does not lengthen them."""
    a, b = designs["avoid"].total_length(), designs["phase"].total_length()
    assert a == pytest.approx(b, rel=0.01)


def _same(a: Grooves, b: Grooves) -> bool:
    return bool(np.array_equal(a.path_sizes, b.path_sizes)
                and np.array_equal(a.vertices, b.vertices))


def test_auto_places_a_small_design_by_avoiding(designs: dict[str, Grooves]) -> None:
    """A design whose plan fits is placed out of the way, and says so."""
    info: dict[str, str] = {}
    grooves = _design(_scene(), "auto", _setup(), info)
    assert info == {"placement": "avoid"}
    assert _same(grooves, designs["avoid"])


def test_auto_falls_back_to_phase_over_the_work_bound(
        designs: dict[str, Grooves], monkeypatch: pytest.MonkeyPatch) -> None:
    """Over the plan's bound "auto" takes the phase walk, and says why."""
    monkeypatch.setattr(striped, "AUTO_MAX_PLAN_SAMPLES", 1000)
    info: dict[str, str] = {}
    grooves = _design(_scene(), "auto", _setup(), info)
    assert info["placement"] == "phase"
    assert "plan samples" in info["fallback"]
    assert _same(grooves, designs["phase"])


def test_avoid_that_does_not_fit_is_refused(
        designs: dict[str, Grooves], monkeypatch: pytest.MonkeyPatch) -> None:
    """With memory for the phase walk but not the plan: auto takes phase, avoid is refused."""
    import specholo.scene.loading as loading

    setup, pts = _setup(), _scene()
    # Room for the phase walk (a few MB here) but not for the plan's index.
    cap, likely = striped._plan_estimate(_runs(pts, setup), setup, StripeOptions())
    room = likely * striped.PLAN_BYTES_PER_SAMPLE
    monkeypatch.setattr(loading, "available_memory", lambda: room)
    info: dict[str, str] = {}
    assert _same(_design(pts, "auto", setup, info), designs["phase"])
    assert info["placement"] == "phase" and "memory" in info["fallback"]
    with pytest.raises(SpecholoError, match="--placement avoid: .*memory.*--placement phase"):
        _design(pts, "avoid", setup)


def test_the_placement_used_is_recorded() -> None:
    """hologram.json keeps the setting ("auto") and gives the placement used in its stats."""
    from specholo.jobs.flat.folder import DesignConfig, design, hologram_json

    cfg = DesignConfig(stipples=30, size=20.0)
    d = design(EXAMPLE, cfg, check_overlaps=False)
    info = hologram_json(d)
    assert info["settings"]["placement"] == "auto"
    assert info["stats"]["placement"] == "avoid"
    assert info["stats"]["placement_fallback"] is None


def test_the_index_size_does_not_change_the_stripes(monkeypatch: pytest.MonkeyPatch) -> None:
    """The placed grooves' index starts small and doubles, its hash table sized from
    the plan's estimate: neither changes a choice (the same stripes with the
    smallest table, every cell's points sharing chains with others')."""
    from specholo.toolpaths import _avoid_kernel

    setup, pts = _setup(), _scene()
    wide = _design(pts, "avoid", setup)
    monkeypatch.setattr(_avoid_kernel, "table_bits", lambda points: _avoid_kernel.MIN_TABLE_BITS)
    assert _same(_design(pts, "avoid", setup), wide)


def test_glints_beyond_the_cell_size_are_found(monkeypatch: pytest.MonkeyPatch) -> None:
    """Cells sized for a shallower wall than the glints need: the queries search
    more cells and make the same choices."""
    from specholo.toolpaths import _avoid_kernel

    setup, pts = _setup(), _scene()
    wide = _design(pts, "avoid", setup)
    place = _avoid_kernel.place

    def small_cells(*args: object, **options: object) -> object:
        return place(*args[:-1], 0.2 * float(args[-1]), **options)  # type: ignore[arg-type]

    monkeypatch.setattr(_avoid_kernel, "place", small_cells)
    assert _same(_design(pts, "avoid", setup), wide)


def test_auto_falls_back_to_phase_where_the_plan_outgrows_its_estimate() -> None:
    """Eyes far above the plate make the glints drift far faster than the plan's
    estimate: "auto" gives the plan one larger try, then walks by phase (the
    grooves still serve every view) instead of growing the plan for minutes."""
    from specholo.jobs.flat.folder import DesignConfig, design

    bunny = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
    d = design(bunny, DesignConfig(stipples=8, eye_height=1e5), check_overlaps=False,
               expect_as_cut=False)
    assert d.placement is not None and d.placement["placement"] == "phase"
    assert "does not settle" in d.placement["fallback"]
    assert d.grooves.n_paths > 0


def test_auto_places_a_nearly_flat_trough_by_phase_at_once():
    # A laser trough 0.1 um deep curves with a radius of 6 mm and offers walls
    # a few hundredths of a millimetre from its centre: the avoiding plan's
    # searches would scan that radius in cells of the walls' reach (minutes for
    # 8 stipples). "auto" places it by phase and says why.
    from specholo.jobs.flat.folder import DesignConfig, design

    bunny = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
    d = design(bunny, DesignConfig(stipples=8, size=653.0, depth=0.0001, tool="laser"),
               check_overlaps=False, expect_as_cut=False)
    assert d.placement is not None and d.placement["placement"] == "phase"
    assert "wall radius" in d.placement["fallback"]

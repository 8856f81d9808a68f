"""A flat plate's design: the model placed and stippled, occlusion, the tool
check, the grooves, and what will survive the cutting (model -> stipples ->
optics -> toolpaths). Its folder is written and read by
:mod:`specholo.jobs.flat.folder`."""


from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from specholo import __version__
from specholo.errors import SpecholoError
from specholo.fabrication.plate import PLATE_MARGIN, fit_plate
from specholo.optics.cutters import (
    Cutter,
    ViewCheck,
    check_views,
    depth_for,
    needed_tilts,
    steepest_wall,
)
from specholo.setup import (
    Setup,
)
from specholo.toolpaths.common import Runs, make_runs
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.overlap import Overlaps, groove_overlaps

if TYPE_CHECKING:
    from specholo.simulation.survival import AsCut

from specholo.jobs.flat.settings import (
    BAND,
    DEPTH_ALLOWANCE,
    TILT_MARGIN,
    DesignConfig,
)
from specholo.jobs.plate_common import stipple_model


@dataclass
class Design:
    """A designed hologram: the placed model, its stipples, and the grooves."""

    config: DesignConfig
    model: Any  # scene.loading.Model
    points: np.ndarray  # (n, 3)
    normals: np.ndarray | None  # (n, 3)
    runs: Runs
    grooves: Grooves
    dropped: np.ndarray  # stipple ids that could not be designed
    timings: dict[str, float]
    views: ViewCheck | None = None  # the tool's walls against the tilts needed
    overlaps: Overlaps | None = None  # where grooves cut into each other
    plate: np.ndarray | None = None  # (2, 2) plate corners, mm
    coverage: Coverage | None = None  # which stipples got a groove
    as_cut: AsCut | None = None  # what survives the cutting, per azimuth
    placement: dict[str, str] | None = None  # striped: "placement" used, "fallback" why
    thinned: np.ndarray | None = None  # stipple ids left uncut by thinning
    thinning: dict[str, Any] | None = None  # its stereo points as cut, before and after
    up_hint: str = ""  # the --up the model's own flat base suggests, in words ('' if none)
    band_note: str = ""  # why the band is what it is, where the design chose it ('' if not)
    light: Any = None  # the light to use (simulation.lighting.LightChoice), or None


@dataclass(frozen=True)
class Coverage:
    """How many stipples got a groove, and why the others did not.

    Attributes:
        stipples: stipples of the design.
        hidden: stipples no eye in the viewing range sees (the model hides them
            or they face away from every eye): they get no groove.
        dropped: stipples seen but whose groove the method could not design.
        grooved: stipples with at least one path.
        thinned: stipples left uncut by thinning (:mod:`specholo.simulation.thinning`):
            other grooves' cuts would take their glints, and theirs others'.
    """

    stipples: int
    hidden: int
    dropped: int
    grooved: int
    thinned: int = 0

    @property
    def ungrooved(self) -> int:
        """Stipples without a groove."""
        return self.stipples - self.grooved

    @property
    def mostly_ungrooved(self) -> bool:
        """Whether most stipples have no groove: the plate shows little of the model."""
        return 2 * self.ungrooved > self.stipples

    def reasons(self, dropped_why: str = "") -> str:
        """Why the stipples without a groove have none, e.g. "120 are hidden from
        every view (...), 30 could not be designed" (``dropped_why`` follows the latter)."""
        parts = []
        if self.hidden:
            parts.append(f"{self.hidden} {'is' if self.hidden == 1 else 'are'} hidden from "
                         f"every view ({_HIDDEN_WHY})")
        if self.dropped:
            parts.append(f"{self.dropped} could not be designed{dropped_why}")
        if self.thinned:
            parts.append(f"{self.thinned} {'is' if self.thinned == 1 else 'are'} left uncut "
                         f"({THINNED_WHY})")
        rest = self.ungrooved - self.hidden - self.dropped - self.thinned
        if rest > 0:
            parts.append(f"{rest} got no path")
        return ", ".join(parts)

    def describe(self) -> str:
        """One line: how many stipples have no groove, and why."""
        if self.ungrooved == self.hidden:
            return (f"{self.hidden} of {self.stipples} stipples are hidden from every view "
                    f"and have no groove ({_HIDDEN_WHY})")
        return f"{self.ungrooved} of {self.stipples} stipples have no groove: {self.reasons()}"


#: Why a stipple is hidden from every view.
_HIDDEN_WHY = "the model hides them or they face away from every eye"
#: Why thinning leaves a stipple uncut.
THINNED_WHY = ("thinned: on the cut plate the grooves crossing them would take their "
               "glints, and theirs more of the others'")


def coverage(n: int, runs: Runs, grooves: Grooves, dropped: np.ndarray,
             thinned: int = 0) -> Coverage:
    """Count the stipples with a groove, those hidden from every view, those
    dropped and those thinning left uncut.

    One pass over the runs and the paths (no sort): cheap beside the design.
    """
    seen = np.zeros(n, dtype=bool)
    seen[runs.stipple] = True
    has = np.zeros(n, dtype=bool)
    ids = np.asarray(grooves.stipple)
    has[ids[(ids >= 0) & (ids < n)]] = True
    return Coverage(n, n - int(np.count_nonzero(seen)), int(len(dropped)),
                    int(np.count_nonzero(has)), thinned)


def groove_extent(grooves: Grooves) -> np.ndarray:
    """(2, 2) corners of the grooves' centrelines, arcs included where they bulge
    past their end points (the tool follows the arc, not its chord)."""
    return grooves.extent()


def plate_rect(grooves: Grooves, width: float, config: DesignConfig,
               extent: np.ndarray | None = None) -> np.ndarray:
    """The plate's corners (2, 2), centred on the plate origin; refuse one too small.

    Args:
        grooves: the design's grooves.
        width: groove width, mm (grooves reach half of it past their centrelines).
        config: plate_width / plate_height, or None to fit the grooves with a margin.
        extent: the grooves' :func:`groove_extent`, if already known.
    """
    lo, hi = groove_extent(grooves) if extent is None else extent
    reach = np.maximum(np.abs(lo), np.abs(hi)) + 0.5 * width
    need = 2.0 * reach
    size = np.array([config.plate_width or 0.0, config.plate_height or 0.0])
    given = size > 0
    for axis, name in ((0, "width"), (1, "height")):
        if given[axis] and size[axis] < need[axis]:
            raise SpecholoError(
                f"plate {name} {size[axis]:g} mm is smaller than the design, which needs "
                f"{need[axis]:.1f} mm (grooves reach +-{reach[axis]:.1f} mm from the centre)")
    fitted = fit_plate(np.stack([lo, hi]), width, PLATE_MARGIN)
    size = np.where(given, size, fitted[1] - fitted[0])
    return np.stack([-0.5 * size, 0.5 * size])


def auto_depth(cutter: Cutter, config: DesignConfig, points: np.ndarray, runs: Runs,
               tilts: np.ndarray | None = None) -> float:
    """Shallowest depth whose walls serve every view with :data:`TILT_MARGIN` to
    spare, plus :data:`DEPTH_ALLOWANCE` for a machine's depth error, to the
    micrometre above; the tool's fallback depth when no depth can (a V-bit).
    Where the views need walls steeper than the tool's shape offers (a cone's
    flank), the depth that reaches its steepest wall: every view the tool can
    serve is served, and the tool check names the rest.
    ``tilts`` are the runs' :func:`needed_tilts`, if already known."""
    if tilts is None:
        setup = config.setup()
        tilts, _ = needed_tilts(points, runs.stipple, runs.start, runs.end, setup.light,
                                setup.viewer)
    need = float(tilts.max()) + TILT_MARGIN if tilts.size else TILT_MARGIN
    steepest = steepest_wall(cutter)
    if steepest is None:
        return config.depth_mm
    depth = depth_for(cutter, min(need, steepest))
    if depth is None:
        return config.depth_mm
    depth = math.ceil((depth + DEPTH_ALLOWANCE) * 1000.0 - 1e-9) / 1000.0
    # A ball or round tip shallower than its reach: beyond it the walls stop at the shank.
    try:
        cutter.check_depth(depth)
    except SpecholoError:
        return config.depth_mm
    return depth


def design_runs(runs: Runs, config: DesignConfig,
                info: dict[str, str] | None = None) -> tuple[Grooves, np.ndarray]:
    """Grooves for the given view intervals with the configured method.

    ``info``, if given, gets the striped design's placement used and why "auto"
    fell back (see :func:`~specholo.toolpaths.striped.design_striped`).
    """
    from specholo.toolpaths.classic import design_classic
    from specholo.toolpaths.hyperbola import design_hyperbola
    from specholo.toolpaths.striped import StripeOptions, design_striped

    setup = config.setup()
    if config.method == "striped":
        return design_striped(runs, setup, StripeOptions(band=float(config.band or BAND),
                                                         placement=config.placement), info=info)
    if config.method == "hyperbola":
        from specholo.toolpaths.hyperbola import serves

        ok = serves(runs, setup)
        dropped = np.setdiff1d(runs.stipple[~ok], runs.stipple[ok])
        return design_hyperbola(runs.take(ok), setup), dropped.astype(np.int64)
    return design_classic(runs, setup), np.zeros(0, dtype=np.int64)


def up_hint(model: Any, config: DesignConfig) -> str:
    """Where a placed mesh stands on a flat base that is not its bottom on the
    plate (a z-up CAD or slicer file read y-up lies on its back), the ``--up``
    that stands it upright, in words; '' otherwise."""
    from specholo.scene.pose import axis_name, standing_up

    mesh = model.mesh
    if mesh is None:
        return ""
    up = standing_up(mesh.vertices, mesh.faces)  # in the plate's axes, as placed
    if up is None or up == "y":
        return ""
    extent = np.ptp(np.asarray(mesh.vertices, dtype=float), axis=0)
    if up in ("z", "-z") and extent[2] < 0.5 * min(extent[0], extent[1]):
        return ""  # a relief or a plaque, facing the viewer as it is meant to
    vector = np.zeros(3)
    vector["xyz".index(up[-1])] = -1.0 if up.startswith("-") else 1.0
    name = axis_name(vector @ config.pose().rotation().T)  # back to the file's axes
    if name is None or name == config.up:
        return ""
    return (f"the model stands on a flat base with its {name} axis up (as CAD and slicer "
            f"files place a part), and is placed with {config.up} up, lying on its side or "
            f"back: add --up {name}")


def design(model_path: str | os.PathLike[str], config: DesignConfig,
           rng: np.random.Generator | None = None, check_overlaps: bool | None = None,
           expect_as_cut: bool | None = None,
           sample: Callable[[np.ndarray], np.ndarray] | None = None) -> Design:
    """Load, place, stipple, crop by occlusion, check the tool, design the grooves.

    Args:
        model_path: mesh or point-cloud file.
        config: the options.
        rng: random generator for stippling; default seeded from ``config.seed``.
        check_overlaps: count where grooves cut into each other (crossings,
            neighbouring stripes, their coverage); None for designs that
            skip the as-cut estimate, which then gives the rough share of
            glints that survive from the coverage.
        expect_as_cut: find which glints survive the other grooves' cuts
            (:func:`expected_as_cut`); None for designs of at most
            :data:`AS_CUT_MAX_STIPPLES` stipples.
        sample: design only the stipples it keeps ((n,) bool of the (n, 3)
            stipples), placed and banded as the whole design's: a part of the
            plate at the whole design's density, which a quick estimate
            designs in its stead (:func:`specholo.studio.estimate.estimate`).

    Raises:
        SpecholoError: on bad input, a plate smaller than the design, or (with
            ``config.strict``) a tool whose walls lose views.
    """
    from specholo.scene.stippling import Stipples
    from specholo.visibility.occlusion import visible_intervals

    if not isinstance(config, DesignConfig):
        raise SpecholoError(f"design takes a grooved design's settings (DesignConfig), got "
                            f"{type(config).__name__}: a ridged design is made by "
                            "design_ridged_model")
    setup = config.setup()
    timings: dict[str, float] = {}
    model, st, config = stipple_model(model_path, config, rng, timings)
    points = st.points
    band_note = ""
    if config.band_share is not None and config.method == "striped":
        config, band_note = machine_band(config, points)
        setup = config.setup()
    if sample is not None:
        keep = np.asarray(sample(points), dtype=bool)
        st = Stipples(points[keep], None if st.normals is None else st.normals[keep])
        points = st.points
    t0 = time.perf_counter()
    iv = visible_intervals(model.mesh, points, st.normals, setup.viewer)
    runs = make_runs(points, iv.stipple, iv.start, iv.end)
    timings["occlusion"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    cutter = config.cutter()
    # The tilts depend on the views and the light, not on the depth: found once.
    needed = needed_tilts(points, runs.stipple, runs.start, runs.end, setup.light,
                          setup.viewer)
    if config.depth is None:
        config = dataclasses.replace(
            config, depth=auto_depth(cutter, config, points, runs, tilts=needed[0]))
        setup = config.setup()
    views = check_views(cutter, config.depth_mm, points, runs.stipple, runs.start, runs.end,
                        setup.light, setup.viewer, known=needed)
    del needed  # ~10^8 samples at a million stipples: not kept through the walk
    if config.strict and views.lost > 0:
        raise SpecholoError(
            f"the {cutter.describe()} at {config.depth_mm:g} mm: {views.lost_views()}")
    timings["tool check"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    placed: dict[str, str] = {}
    grooves, dropped = design_runs(runs, config, placed)
    timings["toolpaths"] = time.perf_counter() - t0
    cover = coverage(len(points), runs, grooves, dropped)
    if cover.grooved == 0:
        # A plate with nothing to cut: refused before any file is written.
        from collections import Counter

        why = Counter(r.split(":")[0] for r in drop_reasons(points, dropped, setup).values())
        reasons = "" if not why else " (" + ", ".join(
            f"{n}: {r}" for r, n in sorted(why.items())) + ")"
        raise SpecholoError(f"no stipple gets a groove: {cover.reasons(reasons)}")
    section = cutter.section(config.depth_mm)
    if expect_as_cut is None:
        expect_as_cut = len(points) <= AS_CUT_MAX_STIPPLES
    if check_overlaps is None:
        # The as-cut estimate says what survives from the grooves themselves;
        # the tallies would add a rougher figure and, on a first run, about
        # 5 s of compiling.
        check_overlaps = not expect_as_cut
    t0 = time.perf_counter()
    as_cut, thinned, thinning = None, np.zeros(0, dtype=np.int64), None
    if expect_as_cut:
        as_cut, grooves, thinned, thinning = thin_as_cut(config, points, runs, grooves)
        if len(thinned):
            cover = coverage(len(points), runs, grooves, dropped, len(thinned))
    timings["as cut"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    light = _light_to_use(config, points, runs, grooves) if expect_as_cut else None
    timings["light"] = time.perf_counter() - t0
    # One pass over the arcs (or none, when the walk found them), for the plate and
    # the overlaps (which need the length).
    if check_overlaps:
        extent, total = grooves.extent_and_length()
    else:
        extent, total = grooves.extent(), 0.0
    plate = plate_rect(grooves, section.width, config, extent)
    t0 = time.perf_counter()
    overlaps = groove_overlaps(grooves, section.width, extent=extent,
                               total_length=total) if check_overlaps else None
    timings["overlaps"] = time.perf_counter() - t0
    return Design(config, model, points, st.normals, runs, grooves, dropped, timings,
                  views, overlaps, plate, cover, as_cut, placement=placed or None,
                  thinned=thinned if len(thinned) else None, thinning=thinning,
                  up_hint=up_hint(model, config), band_note=band_note, light=light)


def stipple_spacing(points: np.ndarray, distance: float) -> float | None:
    """The median angle between a stipple and its nearest neighbour, seen from
    the viewing distance straight on, arcmin (None for fewer than two)."""
    from scipy.spatial import cKDTree

    p = np.asarray(points, dtype=float)
    if len(p) < 2:
        return None
    # Seen from the eyes, a point d behind the plate is (D + d) away.
    gap, _ = cKDTree(p).query(p, k=2)
    far = distance - p[:, 2]
    return float(np.median(np.degrees(gap[:, 1] / far)) * 60.0)


def machine_band(config: DesignConfig, points: np.ndarray) -> tuple[DesignConfig, str]:
    """The band a machine whose strokes lift is given (``config.band_share``, see
    :data:`~specholo.jobs.flat.settings.MACHINE_BAND_SHARE`): seen from the viewing
    distance, that share of the neighbouring stipples' spacing, never finer
    than the default, to 0.01 mm. Returns the settings with that band (and no
    share left to apply) and a few words saying why, for the summary."""
    share = float(config.band_share or 0.0)
    default = float(config.band or BAND)
    distance = config.setup().viewer.distance
    spacing = stipple_spacing(points, distance)
    done = dataclasses.replace(config, band_share=None)
    if spacing is None:
        return done, ""
    wanted = distance * math.tan(math.radians(share * spacing / 60.0))
    band = max(default, math.floor(wanted * 100.0) / 100.0)
    note = (f"chosen for {config.machine}, whose strokes each lift the tool: "
            f"{share:g} of the stipples' spacing")
    return dataclasses.replace(done, band=band), note


#: Head azimuths of the design's as-cut estimate are at most this far apart, degrees.
AS_CUT_STEP_DEG = 5.0
#: "auto" thins where the plate as cut shows at least this share more stereo
#: points: on the README example 0.05% at 2,000 stipples (kept whole), 4.2% at
#: 4,000, 45% at 8,000.
THIN_MIN_GAIN = 0.02
#: Most stipples whose as-cut figures a design finds by itself. Finding every
#: eye's glints costs about a verification (~30 s at 10^5 stipples, against a
#: ~5 s walk), so larger designs leave it to ``specholo verify --cut``.
AS_CUT_MAX_STIPPLES = 20_000
#: What a design without its own as-cut figures says instead.
AS_CUT_SKIPPED = (f"as cut: not estimated by designs of over {AS_CUT_MAX_STIPPLES:,} "
                  "stipples; `specholo verify FOLDER --cut` measures it")


def expected_as_cut(config: DesignConfig, points: np.ndarray, runs: Runs,
                    grooves: Grooves) -> AsCut:
    """The stereo figures of the plate as cut, every :data:`AS_CUT_STEP_DEG` over the range.

    Each eye's designed glints are kept where no other groove's cut removes
    them (:func:`~specholo.simulation.survival.verify_as_cut`). A stipple is
    unoccluded for an eye when the eye's azimuth lies in one of the stipple's
    view intervals (``runs``, what the grooves were designed to serve) rather
    than by casting rays again: the same edges to ~0.01 degrees, at no cost.
    """
    return thin_as_cut(dataclasses.replace(config, thin="off"), points, runs, grooves)[0]


def _light_to_use(config: DesignConfig, points: np.ndarray, runs: Runs,
                  grooves: Grooves) -> Any:
    """The light that gives this plate its sharpest image
    (:func:`~specholo.simulation.lighting.choose_light`), each stipple seen from
    the azimuths the design serves it."""
    from specholo.simulation.lighting import choose_light

    return choose_light(grooves, points, config.setup(), _served(runs))


def _served(runs: Runs) -> Any:
    """Which stipples an eye sees past the model: those whose visible azimuths
    (the design's occlusion intervals) hold the eye's."""
    from specholo.visibility.occlusion import Intervals

    seen_from = Intervals(runs.stipple, runs.start, runs.end)

    def vis(p: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        # verify asks for all the stipples, in order, from one eye
        return seen_from.contains(np.arange(len(p)), np.arctan2(eyes[:, 0], eyes[:, 2]))

    return vis


def thin_as_cut(config: DesignConfig, points: np.ndarray, runs: Runs,
                grooves: Grooves) -> tuple[AsCut, Grooves, np.ndarray, dict[str, Any] | None]:
    """The plate as cut (:func:`expected_as_cut`), thinned as ``config.thin`` says.

    Thinning (:func:`~specholo.simulation.thinning.thin`) leaves uncut the
    stipples whose grooves take more stereo points from the others than they
    show. "on" keeps it wherever it shows more; "auto" where it shows at
    least :data:`THIN_MIN_GAIN` more (a plate that loses a few glints keeps
    every stipple its drawing has); "off" never thins.

    Returns:
        The figures, the grooves to cut, the ids of the stipples left uncut, and
        (where thinning was weighed) the stereo points as cut, mean per azimuth,
        with every stipple cut and thinned, and whether it thinned.
    """
    from specholo.simulation.survival import as_cut_report, eye_glints, survivors
    from specholo.simulation.thinning import thin
    from specholo.simulation.verify import view_azimuths
    setup = config.setup()
    vis = _served(runs)
    az = view_azimuths(setup.viewer.half_range, math.radians(AS_CUT_STEP_DEG))
    cutter, depth = config.cutter(), config.depth_mm
    glints = eye_glints(grooves, points, setup, cutter, depth, az)
    seen = glints.seen_by(points, vis)
    none = np.zeros(0, dtype=np.int64)
    if config.thin == "off":
        keep = survivors(grooves, glints.point, glints.path, cutter, depth)
        return as_cut_report(glints, keep, points, seen), grooves, none, None
    th = thin(grooves, glints, seen[0::2] & seen[1::2], cutter, depth)
    need = th.shown_all * (1.0 + (THIN_MIN_GAIN if config.thin == "auto" else 0.0))
    done = bool(th.shown > need and th.keep.any())
    # Weighed but not kept (auto, under its gain), the figures say what it would give.
    info = {"thinned": done, "stipples_left_uncut": len(th.left_uncut) if done else 0,
            "stipples_thinning_leaves_uncut": len(th.left_uncut),
            "stereo_points_all_cut": th.shown_all / len(az),
            "stereo_points_thinned": th.shown / len(az)}
    if not done:
        return as_cut_report(glints, th.alive_all, points, seen), grooves, none, info
    ids = np.asarray(grooves.stipple, dtype=np.int64)
    paths = np.flatnonzero(~np.isin(ids, th.left_uncut))
    return (as_cut_report(glints, th.alive, points, seen), grooves.take(paths), th.left_uncut,
            info)


def as_cut_json(as_cut: AsCut) -> dict[str, Any]:
    """``hologram.json``'s ``expected``: the as-cut stereo visibility per azimuth."""
    figures = as_cut.mean_and_lowest()
    mean, low, at = figures if figures is not None else (None, None, None)
    return {"as_cut_stereo_visibility": {
        "mean": mean, "lowest": low, "lowest_azimuth_deg": at,
        "per_azimuth": [
            {"azimuth_deg": r.azimuth,
             "visibility": None if math.isnan(r.visibility) else r.visibility,
             "stipples_seen": r.stipples_seen,
             "glints": [int(v) for v in g], "surviving": [int(v) for v in s]}
            for r, g, s in zip(as_cut.reports, as_cut.glints, as_cut.surviving, strict=True)],
        "how": ("share of the stipples unoccluded for both eyes whose left and right designed "
                "glints both survive every other groove's cut (exact for a round tip cut "
                "within its radius); glints and surviving count each eye's glints, left and "
                "right"),
    }}


class StippleRows:
    """The stipples of ``hologram.json`` (id, position, visible azimuths in degrees),
    made a block at a time as they are written: as one list, a million
    stipples' dictionaries would hold ~1 GB for the whole of the writing."""

    def __init__(self, points: np.ndarray, runs: Runs) -> None:
        self.points = points
        self.runs = runs

    def __len__(self) -> int:
        return len(self.points)

    def blocks(self, size: int = 1 << 16) -> Iterator[list[dict[str, Any]]]:
        """Lists of up to ``size`` stipples' rows, in id order."""
        by_id = np.argsort(self.runs.stipple, kind="stable")  # each stipple's runs in order
        ids = self.runs.stipple[by_id]
        for a in range(0, len(self.points), size):
            b = min(a + size, len(self.points))
            lo, hi = np.searchsorted(ids, [a, b])
            iv: list[list[list[float]]] = [[] for _ in range(b - a)]
            for s, x, y in zip(ids[lo:hi].tolist(),
                               np.degrees(self.runs.start[by_id[lo:hi]]).tolist(),
                               np.degrees(self.runs.end[by_id[lo:hi]]).tolist(), strict=True):
                iv[s - a].append([round(x, 4), round(y, 4)])
            yield [{"id": i, "x": float(p[0]), "y": float(p[1]), "z": float(p[2]),
                    "visible_deg": iv[i - a]}
                   for i, p in enumerate(self.points[a:b].tolist(), start=a)]


def hologram_json(d: Design) -> dict[str, Any]:
    """The design's settings, figures and stipples, for ``hologram.json``."""
    setup = d.config.setup()
    lo, hi = d.grooves.bounds()
    cover = d.coverage or coverage(len(d.points), d.runs, d.grooves, d.dropped)
    return {
        "specholo_version": __version__,
        "settings": asdict(d.config),
        "frame": "plate mm: x right, y up, z toward the viewer, plate at z = 0",
        "tool": {"kind": d.config.tool, "description": d.config.cutter().describe(),
                 "depth_mm": d.config.depth_mm,
                 "groove_width_mm": d.config.cutter().section(d.config.depth_mm).width,
                 "round_model": {"radius_mm": setup.tool.radius, "depth_mm": setup.tool.depth,
                                 "max_wall_tilt_deg": math.degrees(setup.tool.max_tilt)}},
        "views": d.views.as_dict() if d.views is not None else None,
        "overlaps": d.overlaps.as_dict() if d.overlaps is not None else None,
        "expected": (as_cut_json(d.as_cut) if d.as_cut is not None else
                     {"as_cut_stereo_visibility": None, "why": AS_CUT_SKIPPED}),
        "light_to_use": d.light.as_dict() if d.light is not None else None,
        "plate": {"groove_extent_mm": [lo.tolist(), hi.tolist()],
                  "plate_mm": d.plate.tolist() if d.plate is not None else None,
                  "stock_thickness_mm": d.config.stock_thickness},
        "stats": {"stipples": len(d.points), "paths": d.grooves.n_paths,
                  "dots": int(d.grooves.is_dot.sum()),
                  "groove_length_mm": d.grooves.total_length(),
                  "dropped_stipples": d.dropped.tolist(),
                  "dropped_reasons": drop_reasons(d.points, d.dropped, setup),
                  "hidden_stipples": cover.hidden,
                  "stipples_with_grooves": cover.grooved,
                  "thinned_stipples": [] if d.thinned is None else d.thinned.tolist(),
                  "thinning": d.thinning,
                  # what "auto" chose, and why it fell back (settings keep "auto")
                  **({"placement": d.placement["placement"],
                      "placement_fallback": d.placement.get("fallback")}
                     if d.placement else {})},
        "stipples": StippleRows(d.points, d.runs),
    }


def run_record(config: DesignConfig, command: list[str] | None,
               seconds: dict[str, Any]) -> dict[str, Any]:
    """What a flat design's ``run.json`` records
    (:func:`specholo.staging.run_record`), with its settings."""
    from specholo.staging import run_record as record

    return record("flat", command, seconds, asdict(config))


def drop_reasons(points: np.ndarray, dropped: np.ndarray, setup: Setup) -> dict[str, str]:
    """Why each dropped stipple could not be designed, by id (as a JSON key)."""
    from specholo.toolpaths.striped import at_light

    near = at_light(np.asarray(points, dtype=float).reshape(-1, 3)[dropped], setup)
    return {str(int(i)): ("at the light: its glint would be the light itself" if n else
                          "light in the eyes' plane: its groove would run vertically")
            for i, n in zip(dropped.tolist(), near.tolist(), strict=True)}



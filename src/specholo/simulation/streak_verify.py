"""Verification under a light of real size on a surface of real gloss.

The same stereo figures as :func:`~specholo.simulation.verify.verify`, with
each glint a streak (:mod:`specholo.simulation.streaks`): each eye sees a
stipple at its designed streaks' brightness-weighted centres, and the
verification also counts the end spills each eye sees as glints of their own.
On the plate as cut, every piece of a streak another groove's cut removes is
dark (:func:`~specholo.simulation.survival.survivors` on every cell), and the
rest of the streak still shines, its centre moved.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo.optics.spread import Spread
from specholo.setup import Setup
from specholo.simulation._streak_kernel import nearest
from specholo.simulation.glints import Engraved, Glints, find_glints
from specholo.simulation.streaks import (
    ACUITY,
    SPILL_SEPARATION,
    Streaks,
    bright_spills,
    false_glints,
    find_streaks,
    join,
)
from specholo.simulation.survival import on_real_wall, survivors
from specholo.simulation.verify import (
    CHUNK_VERTICES,
    ViewReport,
    VisibilityFn,
    _chunks,
    view_azimuths,
    view_report,
)
from specholo.toolpaths.grooves import Grooves


@dataclass(frozen=True)
class StreakReport(ViewReport):
    """A :class:`~specholo.simulation.verify.ViewReport` of streaks.

    Attributes:
        end_spills: end spills an eye sees as glints of their own (bright
            enough and more than 0.25 mm from every designed glint), the mean
            of the two eyes.
        streak_length: median length of the designed streaks where they are at
            least half as bright per mm as at their brightest, mm.
        centre_shift: median distance of a designed streak's centre from its
            point glint, mm (a streak cut short by its stripe's end or a gap).
    """

    end_spills: float = 0.0
    streak_length: float = math.nan
    centre_shift: float = math.nan


@dataclass(frozen=True)
class EyeStreaks:
    """Every eye's streaks, eye after eye (left, right of each azimuth in turn).

    Attributes:
        azimuths: (k,) head azimuths, radians.
        eyes: per azimuth, the (left, right) eye positions.
        streaks: per eye, its streaks over the whole plate (paths and stipples global).
        points: per eye, its point glints (the point model's), for how far
            each streak's centre moved from its own.
    """

    azimuths: np.ndarray
    eyes: list[tuple[np.ndarray, np.ndarray]]
    streaks: list[Streaks]
    points: list[Glints]


def eye_streaks(grooves: Grooves, n: int, setup: Setup, spread: Spread, azimuths: np.ndarray,
                chunk_vertices: int = CHUNK_VERTICES) -> EyeStreaks:
    """Each eye's streaks on the ideal grooves, found a stipple chunk at a time.

    Args:
        grooves: the grooves; n: the number of stipples they draw.
        setup: light, viewer and tool; spread: the light's size and the gloss.
        azimuths: (k,) head azimuths, radians.
        chunk_vertices: groove vertices searched at once.
    """
    eyes = [tuple(e[0] for e in setup.viewer.stereo(np.array([theta]))) for theta in azimuths]
    found: list[list[Streaks]] = [[] for _ in range(2 * len(azimuths))]
    point: list[list[Glints]] = [[] for _ in range(2 * len(azimuths))]
    for _, _, paths in _chunks(grooves, n, chunk_vertices):
        part = grooves.take(paths) if len(paths) != grooves.n_paths else grooves
        eng = Engraved.from_grooves(part, setup.tool)
        for j, pair in enumerate(eyes):
            for side, eye in enumerate(pair):
                st = find_streaks(eng, eye, setup.light, spread)
                found[2 * j + side].append(st.offset(paths))
                gl = find_glints(eng, eye, setup.light)
                point[2 * j + side].append(Glints(paths[gl.path], gl.stipple, gl.point))
        del eng
    return EyeStreaks(np.asarray(azimuths, dtype=float), eyes,  # type: ignore[arg-type]
                      [join(parts) for parts in found], [_join_points(p) for p in point])


def streak_view(theta: float, points: np.ndarray, left: Streaks, right: Streaks,
                eye_l: np.ndarray, eye_r: np.ndarray, vis_l: np.ndarray,
                vis_r: np.ndarray, point_glints: tuple[Glints, Glints] | None = None
                ) -> StreakReport:
    """One head's figures from both eyes' streaks (as
    :func:`~specholo.simulation.verify.view_report` gives them from glints),
    with the end spills, the streaks' length and how far their centres moved
    from the point glints (``point_glints``, each eye's, when given)."""
    left, right = _gathered(left, eye_l), _gathered(right, eye_r)
    gl, gr = left.glints(), right.glints()
    # what each eye sees of a stipple: its designed streaks, with the light of
    # the bright stripe ends beside them; the spills farther off are points of
    # their own, counted apart
    seen_l, seen_r = (_with_spills(g, st) for g, st in ((gl, left), (gr, right)))
    base = view_report(theta, points, seen_l, seen_r, eye_l, eye_r, vis_l, vis_r)
    spills = [len(false_glints(st, g.image())) for st, g in ((left, gl), (right, gr))]
    lengths = np.concatenate([_fwhm(st)[st.designed & (st.brightness > 0)]
                              for st in (left, right)])
    shift = math.nan
    if point_glints is not None:
        moved = [_shift(g, p) for g, p in zip((gl, gr), point_glints, strict=True)]
        both = np.concatenate(moved)
        shift = float(np.median(both)) if both.size else math.nan
    return StreakReport(**dataclasses.asdict(base), end_spills=float(np.mean(spills)),
                        streak_length=float(np.median(lengths)) if lengths.size else math.nan,
                        centre_shift=shift)


#: Streak cells held at once, over all the eyes of a batch of head azimuths
#: (about 100 bytes each with the survival test's own arrays): a plate whose
#: eyes' cells would pass it is verified a few azimuths at a time. The README
#: example (about 150,000 cells an eye) fits whole, 38 eyes in 1.8 GB.
CELL_BUDGET = 12_000_000


def verify_streaks(grooves: Grooves, points: np.ndarray, setup: Setup, spread: Spread,
                   visible: VisibilityFn | None = None, azimuths: np.ndarray | None = None,
                   cut: tuple[Any, float] | None = None,
                   chunk_vertices: int = CHUNK_VERTICES) -> list[StreakReport]:
    """Stereo eye pairs along the arc, each glint a streak.

    Args:
        grooves: the engraved grooves; points: (n, 3) the stipples they show.
        setup: light, viewer and the ball model of the tool.
        spread: the light's size and the surface's gloss.
        visible: occlusion test; None means every stipple is unoccluded.
        azimuths: head azimuths, radians; default every <= 5 degrees over the range.
        cut: ``(cutter, depth)`` to verify the plate as cut: the pieces of each
            streak another path's cut removes are dark; None for the ideal grooves.
        chunk_vertices: groove vertices searched at once.

    Returns:
        One report per azimuth.
    """
    ideal, as_cut = verify_streaks_both(grooves, points, setup, spread, visible, azimuths, cut,
                                        chunk_vertices)
    return as_cut if as_cut is not None else ideal


def verify_streaks_both(grooves: Grooves, points: np.ndarray, setup: Setup, spread: Spread,
                        visible: VisibilityFn | None = None,
                        azimuths: np.ndarray | None = None,
                        cut: tuple[Any, float] | None = None,
                        chunk_vertices: int = CHUNK_VERTICES,
                        budget: int = CELL_BUDGET
                        ) -> tuple[list[StreakReport], list[StreakReport] | None]:
    """:func:`verify_streaks` on the ideal grooves and, with ``cut``, on the plate
    as cut, from the same streaks, a batch of azimuths at a time so that the
    cells held stay under ``budget`` (the first azimuth measures how many an
    eye has).

    Returns:
        The ideal reports, and the as-cut ones (None without ``cut``).
    """
    points = np.asarray(points, dtype=float)
    if azimuths is None:
        azimuths = view_azimuths(setup.viewer.half_range)
    azimuths = np.asarray(azimuths, dtype=float)
    ideal: list[StreakReport] = []
    as_cut: list[StreakReport] = []
    at, batch = 0, 1
    while at < len(azimuths):
        part = azimuths[at:at + batch]
        found = eye_streaks(grooves, len(points), setup, spread, part, chunk_vertices)
        ideal += streak_reports(found, points, visible)
        if cut is not None:
            as_cut += streak_reports(cut_streaks(found, grooves, setup, *cut), points, visible)
        cells = max((len(st.run) for st in found.streaks), default=0)
        at += len(part)
        batch = max(1, budget // max(2 * cells, 1))
    return ideal, (as_cut if cut is not None else None)


def streak_reports(found: EyeStreaks, points: np.ndarray,
                   visible: VisibilityFn | None = None) -> list[StreakReport]:
    """The figures per head azimuth of every eye's streaks (:func:`streak_view`).

    Args:
        found: every eye's streaks (:func:`eye_streaks`, or :func:`cut_streaks`).
        points: (n, 3) the stipples; visible: the occlusion test, or None.
    """
    n = len(points)
    reports = []
    for j, theta in enumerate(found.azimuths):
        eye_l, eye_r = found.eyes[j]
        vis_l = vis_r = np.ones(n, dtype=bool)
        if visible is not None and n:
            vis_l = visible(points, np.broadcast_to(eye_l, (n, 3)))
            vis_r = visible(points, np.broadcast_to(eye_r, (n, 3)))
        reports.append(streak_view(float(theta), points, found.streaks[2 * j],
                                   found.streaks[2 * j + 1], eye_l, eye_r, vis_l, vis_r,
                                   (found.points[2 * j], found.points[2 * j + 1])))
    return reports


def cut_streaks(found: EyeStreaks, grooves: Grooves, setup: Setup, cutter: Any,
                depth: float) -> EyeStreaks:
    """Every eye's streaks with the cells another path's cut (``cutter`` to
    ``depth`` mm) removes made dark: one survival test for all the cells of
    every eye (the grooves are streamed once)."""
    moved, paths = [], []
    for j, pair in enumerate(found.eyes):
        for side, eye in enumerate(pair):
            st = found.streaks[2 * j + side]
            cells = Glints(st.path[st.run], st.stipple[st.run], st.point)
            moved.append(on_real_wall(cells, setup.tool, cutter, depth, setup.light, eye))
            paths.append(cells.path)
    sizes = [len(p) for p in paths]
    keep = survivors(grooves, np.concatenate(moved).reshape(-1, 3),
                     np.concatenate(paths).astype(np.int64), cutter, depth)
    parts = np.split(keep, np.cumsum(sizes)[:-1])
    eyes = [eye for pair in found.eyes for eye in pair]
    return EyeStreaks(found.azimuths, found.eyes,
                      [_parted(st.cut(k), eye)
                       for st, k, eye in zip(found.streaks, parts, eyes, strict=True)],
                      found.points)


def _parted(st: Streaks, eye: np.ndarray) -> Streaks:
    """The streaks as cut, each broken where its pieces lie farther apart than
    the eye resolves (:data:`~specholo.simulation.streaks.ACUITY`) from ``eye``."""
    if st.count == 0:
        return st
    return st.split(ACUITY * np.linalg.norm(st.centre - eye, axis=1))


def _gathered(st: Streaks, eye: np.ndarray) -> Streaks:
    """The streaks with each end spill nearer its path's designed streak than
    the eye resolves (:data:`~specholo.simulation.streaks.ACUITY`) from ``eye``
    taken into it."""
    if st.count == 0:
        return st
    return st.gather(ACUITY * np.linalg.norm(st.centre - eye, axis=1))


def _fwhm(st: Streaks) -> np.ndarray:
    """(r,) each streak's length where it is at least half as bright per mm as at
    its brightest, mm."""
    with np.errstate(divide="ignore", invalid="ignore"):
        density = np.where(st.length > 0, st.weight / st.length, 0.0)
    peak = np.zeros(st.count)
    np.maximum.at(peak, st.run, density)
    bright = (density >= 0.5 * peak[st.run]) & (peak[st.run] > 0)
    return np.bincount(st.run, weights=st.length * bright, minlength=st.count)


def _shift(streak: Glints, point: Glints) -> np.ndarray:
    """(m,) distance of each streak centre from the point glint on its own path
    (streaks whose path has no point glint left out)."""
    if len(streak.path) == 0 or len(point.path) == 0:
        return np.zeros(0)
    order = np.argsort(point.path, kind="stable")
    at = np.searchsorted(point.path[order], streak.path)
    at = np.minimum(at, len(order) - 1)
    same = point.path[order][at] == streak.path
    return np.linalg.norm(streak.point[same] - point.point[order][at[same]], axis=1)


def _join_points(parts: list[Glints]) -> Glints:
    if not parts:
        return Glints(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)))
    return Glints(np.concatenate([p.path for p in parts]),
                  np.concatenate([p.stipple for p in parts]),
                  np.concatenate([p.point for p in parts]).reshape(-1, 3))


def _with_spills(designed: Glints, streaks: Streaks) -> Glints:
    """An eye's image of the stipples: each designed glint with the light of
    the bright end spills within
    :data:`~specholo.simulation.streaks.SPILL_SEPARATION` of it (nearer it than
    any other) at their brightness-weighted centre, sorted by stipple. Nearer
    than that a viewer sees one spot; farther off a spill is a false glint,
    counted apart."""
    image = designed.image()
    spills = bright_spills(streaks)
    to = nearest(image.point, spills.point, SPILL_SEPARATION)
    joined = to >= 0
    if not joined.any():
        return image
    b = image.brightness
    sb = spills.brightness
    assert b is not None and sb is not None
    light = b.copy()
    np.add.at(light, to[joined], sb[joined])
    moment = image.point * b[:, None]
    np.add.at(moment, to[joined], spills.point[joined] * sb[joined, None])
    return Glints(image.path, image.stipple, moment / light[:, None], light)

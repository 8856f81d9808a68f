"""Glints on engraved grooves, seen by one eye.

A groove cut by a round tool along a path with tangent t glints for an eye where
the normality vector h (the half vector) is perpendicular to t and tilted from
the plate normal by no more than the groove's walls offer. On a circular arc the
first condition puts the glint where the radius is parallel to h's plate
component; at finite distances h itself turns along the arc, so we solve it
numerically on each arc.
A dimple glints wherever h's tilt is within the tool's wall tilt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from specholo.optics.normality import normality, tilt, unit
from specholo.setup import Light, Tool
from specholo.simulation import _glint_kernel as _kernel
from specholo.toolpaths.grooves import Grooves

_LINE_BULGE = 1e-9


@dataclass(frozen=True)
class ArcIndex:
    """Arcs sorted by plate cell, then by tangent direction, to skip hopeless ones.

    An arc can glint for an eye only where its tangent is perpendicular to the
    plate part of h, and h turns slowly across the plate (by about the cell size
    over the eye's distance). So per cell only the arcs whose tangent lies near
    that direction need the exact test; arcs that turn a lot are always tested.

    Attributes:
        cell_size: mm.
        origin: (2,) lower-left corner of the cell grid.
        ny: cells per grid column.
        keys: (k',) sorted cell * 4 + tangent angle mod pi, for narrow arcs.
        order: (k',) arc index of each key.
        cells: (c,) distinct cells holding narrow arcs; centres (c, 2).
        wide: (w,) arcs turning more than WIDE radians: always candidates.
        half_length: half the longest narrow arc's chord, mm.
        layout: (k',) the arc in each row of the index: ``order``, then ``wide``
            (both are views of it).
    """

    cell_size: float
    origin: np.ndarray
    ny: int
    keys: np.ndarray
    order: np.ndarray
    cells: np.ndarray
    centres: np.ndarray
    wide: np.ndarray
    half_length: float
    layout: np.ndarray

    WIDE = 0.01  # half-turn (radians) above which an arc is always tested
    CELL = 5.0  # mm

    @property
    def size(self) -> int:
        """Number of arcs indexed (narrow and wide)."""
        return len(self.layout)

    @classmethod
    def build(cls, mid: np.ndarray, tangent: np.ndarray, half_turn: np.ndarray,
              chord: np.ndarray) -> ArcIndex:
        """Index arcs by middle point (k, 2), tangent angle, half turn and chord (k,)."""
        narrow = np.flatnonzero(half_turn <= cls.WIDE)
        wide = np.flatnonzero(half_turn > cls.WIDE)
        origin, top = _kernel.extent(mid) if len(mid) else (np.zeros(2), np.zeros(2))
        # Cells of CELL mm, larger on a plate so wide the cells would outnumber
        # the arcs by far (the grid must fit in memory).
        size = cls.CELL
        if len(mid):
            wx, wy = (float(v) for v in top - origin)
            most = 4 * len(narrow) + 1024
            if (wx / size + 1.0) * (wy / size + 1.0) > most:
                size = max(size, math.sqrt(wx * wy / most), (wx + wy) / most)
        cell, angle, nx, ny = _kernel.cell_keys(mid, tangent, narrow, origin, size)
        order, keys, cells = _kernel.sort_by_cell(cell, angle, nx * ny)
        del cell, angle
        centres = origin + (np.stack([cells // ny, cells % ny], axis=1) + 0.5) * size
        half_length = float(0.5 * chord[narrow].max()) if len(narrow) else 0.0
        # (half_turn is infinite for arcs at sharp corners: they join ``wide``.)
        layout = np.concatenate([narrow[order], wide])
        return cls(size, origin, ny, keys, layout[:len(order)], cells, centres,
                   layout[len(order):], half_length, layout)

    def ranges(self, eye: np.ndarray, light: Light, reach: float,
               spread: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Rows of :attr:`layout` holding the arcs that may glint for an eye.

        Args:
            eye: (3,) eye position.
            light: the light.
            reach: how far (mm) a glint may sit from its arc's middle: half the
                longest arc plus the wall offset.
            spread: how far (radians) the wall's normal may stray from h along
                the groove and still glint (a light of real size, a rough
                surface: see :mod:`specholo.optics.spread`); 0 for a point glint.

        Returns:
            starts (r,) and ends (r,): sorted disjoint ranges [start, end).
        """
        n = len(self.order)
        if len(self.cells) == 0:
            return np.array([n], np.int64), np.array([self.size], np.int64)
        c3 = np.concatenate([self.centres, np.zeros((len(self.cells), 1))], axis=1)
        h = normality(c3, light, eye)
        hxy = np.hypot(h[:, 0], h[:, 1])
        # How far h may turn within a cell: both unit vectors move by about
        # (distance from the cell centre) / (distance to eye or light).
        span = 0.75 * self.cell_size + reach
        turn = span / np.linalg.norm(eye - c3, axis=1)
        if light.distance is not None:
            turn = turn + span / np.linalg.norm(light.position - c3, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            delta = np.where(hxy > 4.0 * turn, 2.0 * turn / hxy, np.pi)
        delta = delta + self.WIDE + 1e-3
        if spread > 0.0:
            # psi = asin(h . t) ~ sin(tilt) x (the tangent's turn from the wanted one)
            sin_tilt = hxy / np.linalg.norm(h, axis=1)
            ratio = math.sin(min(spread, 0.5 * math.pi)) / np.maximum(sin_tilt, 1e-300)
            delta = delta + np.where(ratio < 1.0, np.arcsin(np.minimum(ratio, 1.0)), np.pi)
        want = np.mod(np.arctan2(h[:, 1], h[:, 0]) + 0.5 * np.pi, np.pi)
        lo, hi = want - delta, want + delta
        base = self.cells * 4.0
        i0 = np.empty((3, len(self.cells)), np.int64)
        i1 = np.empty_like(i0)
        # Intervals may wrap around 0 or pi: query each part separately.
        for r, (a, b) in enumerate((
                (np.maximum(lo, 0.0), np.minimum(hi, np.pi)),
                (np.mod(lo, np.pi) * (lo < 0) + np.pi * (lo >= 0), np.full_like(lo, np.pi)),
                (np.zeros_like(hi), np.mod(hi, np.pi) * (hi > np.pi)))):
            i0[r] = np.searchsorted(self.keys, base + a, side="left")
            i1[r] = np.searchsorted(self.keys, base + b, side="right")
        return _kernel.merge_ranges(i0, i1, n, self.size)

    def candidates(self, eye: np.ndarray, light: Light, reach: float) -> np.ndarray:
        """Arcs that may glint for an eye, sorted (arguments as :meth:`ranges`).

        Returns:
            (m,) arc indices.
        """
        return np.sort(self.layout[_kernel.expand(*self.ranges(eye, light, reach))])


@dataclass(frozen=True)
class Engraved:
    """Groove geometry prepared for glint finding.

    The glint search reads the indexed arcs' geometry packed in index order;
    the per-arc arrays in path order (``start`` to ``direction``) are worked
    out on first use, so a verification of millions of arcs never holds both.

    Attributes:
        grooves: the grooves.
        tool: the cutting tool (its wall tilt bounds the glints).
        path: (k,) path index of each arc.
        dot_pos: (q, 2) dimples; dot_path (q,).
        index: arcs sorted by plate cell and tangent direction (see :class:`ArcIndex`).
        kinked: (k,) whether the path turns at the end of each arc (a corner).
        geometry: (k', 7) the indexed arcs packed in index order (rows as
            ``index.layout``; see :func:`~specholo.simulation._glint_kernel.index_arcs`).
        kinks: (c,) arcs after which the path turns, ascending.
        kink_rows: (c, 2) index rows of each such arc and the next (-1: not indexed).
        start, end: (k, 2) arc end points.
        centre: (k, 2) arc centres (start point for straight segments).
        radius: (k,) radii (0 for straight segments).
        start_angle, sweep: (k,) polar angle of the start about the centre, signed sweep.
        direction: (k, 2) unit direction of straight segments.
    """

    grooves: Grooves
    tool: Tool
    path: np.ndarray
    dot_pos: np.ndarray
    dot_path: np.ndarray
    index: ArcIndex
    kinked: np.ndarray
    geometry: np.ndarray
    kinks: np.ndarray
    kink_rows: np.ndarray

    @classmethod
    def from_grooves(cls, grooves: Grooves, tool: Tool) -> Engraved:
        vertices = np.ascontiguousarray(grooves.vertices, dtype=float)
        bulges = np.ascontiguousarray(grooves.bulges, dtype=float)
        first, path = _kernel.arcs_of(np.asarray(grooves.offsets, np.int64), len(vertices))
        # Large outputs are allocated here, by numpy, which asks for huge pages:
        # their rows are then read in random order without a TLB miss each.
        k = len(first)
        mid, packed = np.empty((k, 2)), np.empty((k, 7))
        mid_tangent, turn, chord, kinked = _kernel.index_arcs(
            vertices, bulges, first, path, _LINE_BULGE, ArcIndex.WIDE, mid, packed)
        del first
        index = ArcIndex.build(mid, mid_tangent, turn, chord)
        del mid, mid_tangent, turn, chord
        geometry = np.empty((index.size, 7))
        _kernel.gather_rows(packed, index.layout, geometry)
        del packed
        kinks = np.flatnonzero(kinked)
        kink_rows = np.full((len(kinks), 2), -1, np.int64)
        if len(kinks):
            row = np.full(len(path), -1, np.int64)
            row[index.layout] = np.arange(index.size)
            kink_rows[:, 0], kink_rows[:, 1] = row[kinks], row[kinks + 1]
        dot_pos, dot_path = grooves.dots()
        return cls(grooves, tool, path, dot_pos, dot_path, index, kinked, geometry, kinks,
                   kink_rows)

    @cached_property
    def kink_turn(self) -> np.ndarray:
        """(c,) how far the path turns at each of :attr:`kinks`, radians."""
        return self.turn_after(self.kinks)

    def turn_after(self, arcs: np.ndarray) -> np.ndarray:
        """(c,) how far the path turns from each given arc (path order) into the
        next, radians."""
        if len(arcs) == 0:
            return np.zeros(0)
        _, t0 = self.at(arcs, np.ones(len(arcs)))
        _, t1 = self.at(arcs + 1, np.zeros(len(arcs)))
        cross = t0[:, 0] * t1[:, 1] - t0[:, 1] * t1[:, 0]
        return np.abs(np.arctan2(cross, np.einsum("ij,ij->i", t0, t1)))

    @cached_property
    def open_ends(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The ends of the paths that are not closed: each end's path (e,), its
        point (e, 2) and the unit direction (e, 2) along the path out of the
        groove there (starts first, then ends)."""
        path = self.path
        first = np.flatnonzero(np.r_[True, path[1:] != path[:-1]]) if len(path) else path
        last = np.r_[first[1:] - 1, len(path) - 1] if len(path) else path
        start, t0 = self.at(first, np.zeros(len(first)))
        end, t1 = self.at(last, np.ones(len(last)))
        open_ = np.linalg.norm(end - start, axis=1) > CLOSED
        return (np.concatenate([path[first[open_]], path[last[open_]]]),
                np.concatenate([start[open_, :2], end[open_, :2]]),
                np.concatenate([-t0[open_], t1[open_]]))

    @cached_property
    def span(self) -> float:
        """How far from the plate centre, in plan, any point of a groove lies, mm:
        every point of an arc lies within half the longest chord of its ends' box."""
        xy = self.grooves.vertices
        if len(xy) == 0:
            return 0.0
        far = np.abs(np.concatenate([xy.min(axis=0), xy.max(axis=0)])).reshape(2, 2).max(0)
        return float(np.hypot(*far)) + self.index.half_length

    @cached_property
    def _arcs(self) -> tuple[np.ndarray, ...]:
        """start, end, centre, radius, start_angle, sweep, direction in path order."""
        seg = self.grooves.segments()
        centre, radius, start_angle, sweep, direction, *_ = _kernel.prepare(
            seg.start, seg.end, seg.bulge, seg.path, _LINE_BULGE, ArcIndex.WIDE)
        return seg.start, seg.end, centre, radius, start_angle, sweep, direction

    @property
    def start(self) -> np.ndarray:
        return self._arcs[0]

    @property
    def end(self) -> np.ndarray:
        return self._arcs[1]

    @property
    def centre(self) -> np.ndarray:
        return self._arcs[2]

    @property
    def radius(self) -> np.ndarray:
        return self._arcs[3]

    @property
    def start_angle(self) -> np.ndarray:
        return self._arcs[4]

    @property
    def sweep(self) -> np.ndarray:
        return self._arcs[5]

    @property
    def direction(self) -> np.ndarray:
        return self._arcs[6]

    def at(self, idx: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (k, 3) and unit tangents (k, 2) at parameters u in [0, 1] of arcs idx."""
        r = self.radius[idx]
        ang = self.start_angle[idx] + u * self.sweep[idx]
        cos, sin = np.cos(ang), np.sin(ang)
        arc_pt = self.centre[idx] + r[:, None] * np.stack([cos, sin], axis=1)
        arc_t = np.sign(self.sweep[idx])[:, None] * np.stack([-sin, cos], axis=1)
        line_pt = self.start[idx] + u[:, None] * (self.end[idx] - self.start[idx])
        is_arc = (r > 0)[:, None]
        return _lift(np.where(is_arc, arc_pt, line_pt)), np.where(is_arc, arc_t,
                                                                  self.direction[idx])


#: A path whose ends lie this near each other is closed (it has no ends), mm.
CLOSED = 1e-6
#: A glint this many times fainter than its stipple's brightest for the same
#: eye is haze, not the stipple's image: a corner where a path turns sweeps
#: every wall direction between its tangents and glints for many eyes, but as
#: a sphere of the tip's radius R (brightness R^2), where a designed glint on a
#: groove of curvature radius rho has about R rho / sin(tilt): on the default
#: drag tip (R 0.025 mm) a groove of 1 mm is already 40 times brighter.
FAINT_RATIO = 20.0
#: A glint this many times fainter than the plate's typical stipple is not
#: seen at all beside them: 5 magnitudes. Typical is the brightness of the
#: stipples that give half the light (the median of the stipples' brightest
#: glints, each weighted by its brightness), so that many faint stipples do not
#: drag it down. A turning path's corner is about 2,000 times fainter than the
#: README example's glints, and so is a dimple (a dot) beside grooves; a plate
#: of dots alone keeps them, being its own typical stipple.
INVISIBLE_RATIO = 100.0
#: A path turning less than this (radians) at a vertex glints there as its
#: groove does, not as a corner: a program's rounded digits leave kinks of up
#: to 2e-3 rad between short arcs, and any real light or gloss spreads a glint
#: wider than that across them (a physically based render of plates cut from
#: their programs shows every such glint at full brightness).
SOFT_CORNER = 0.01
#: Longest radius of curvature along a wall counted, mm: a straight groove's
#: glint spreads as far as h turns along it, about the viewing distance.
MAX_ALONG_RADIUS = 1000.0


@dataclass(frozen=True)
class Glints:
    """Glints seen by one eye.

    Attributes:
        path: (g,) index of the groove path that glints.
        stipple: (g,) the stipple that path draws.
        point: (g, 3) glint positions in mm.
        brightness: (g,) reflecting area per steradian of the wall normal, mm^2/sr
            (the product of the wall's two radii of curvature there): how bright
            the glint is under a given light and pupil; None where unknown (every
            glint then counts alike).
    """

    path: np.ndarray
    stipple: np.ndarray
    point: np.ndarray
    brightness: np.ndarray | None = None

    def take(self, keep: np.ndarray) -> Glints:
        """The glints at ``keep`` (a mask or indexes), brightness and all."""
        return Glints(self.path[keep], self.stipple[keep], self.point[keep],
                      None if self.brightness is None else self.brightness[keep])

    def image(self, ratio: float = FAINT_RATIO,
              invisible: float = INVISIBLE_RATIO) -> Glints:
        """The glints that make the stipples' image for this eye: those at least
        1/``ratio`` as bright as their stipple's brightest and 1/``invisible``
        as bright as the typical stipple's (the median of the stipples'
        brightest, weighted by their brightness: see :data:`INVISIBLE_RATIO`);
        all of them, without brightness. The rest are haze: a turning path's
        corners beside the designed glints."""
        b = self.brightness
        if b is None or len(b) == 0:
            return self
        n = int(self.stipple.max()) + 1
        top = np.zeros(n)
        np.maximum.at(top, self.stipple, b)
        lit = np.sort(top[np.unique(self.stipple)])
        light = np.cumsum(lit)
        typical = float(lit[np.searchsorted(light, 0.5 * light[-1])])
        return self.take((b * ratio >= top[self.stipple]) & (b * invisible >= typical))


def _wrap_half(a: np.ndarray) -> np.ndarray:
    """Angles folded to [-pi/2, pi/2): directions that differ by pi are the same line."""
    return (a + 0.5 * np.pi) % np.pi - 0.5 * np.pi


def _lift(xy: np.ndarray) -> np.ndarray:
    return np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)


def wall_glint(centre: np.ndarray, tool: Tool, light: Light,
               eye: np.ndarray, iterations: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Where on a ball-end groove's wall the glint sits, and the normality vector there.

    The tool's ball (centre R - d above the plate) leaves a wall whose normal at
    a point g points to the ball centre c: the glint is g = c - R h/|h|, off the
    toolpath by R sin(tilt) across the groove and below the plate surface.

    Args:
        centre: (k, 2) toolpath points (ball centres seen from above).
        tool: the ball-end tool.
        light: the light.
        eye: (3,) eye.
        iterations: fixed-point steps (h changes by ~R / distance between them).

    Returns:
        g (k, 3) glint points and h (k, 3) there.
    """
    c3 = np.concatenate([centre, np.full((len(centre), 1), tool.radius - tool.depth)], axis=1)
    g = _lift(centre)
    for _ in range(iterations):
        g = c3 - tool.radius * unit(normality(g, light, eye))
    return g, normality(g, light, eye)


def find_glints(eng: Engraved, eye: np.ndarray, light: Light, iterations: int = 12,
                indexed: bool = True) -> Glints:
    """All glints an eye sees on the engraved grooves.

    At finite distances h turns along a groove nearly as fast as a gently
    curved groove's tangent does, so the glint is bracketed by the sign of
    h . t at each arc's ends and found by regula falsi (Illinois), never by a
    fixed point that could fail to converge. Glints sit on the groove wall.

    Args:
        eng: prepared groove geometry.
        eye: (3,) eye position in mm.
        light: the light.
        iterations: root refinements.
        indexed: test only the arcs the index says may glint (the result is the
            same; False tests every arc).

    Returns:
        The glints, sorted by stipple, with their brightness
        (:attr:`Glints.brightness`).
    """
    eye = np.asarray(eye, dtype=float)
    max_tilt = eng.tool.max_tilt
    paths: list[np.ndarray] = []
    points: list[np.ndarray] = []
    bright: list[np.ndarray] = []
    # a corner or a dimple reflects as a sphere of the ball's radius
    sphere = eng.tool.radius**2

    k = len(eng.path)
    if k:
        reach = eng.index.half_length + eng.tool.radius
        if indexed:
            starts, ends = eng.index.ranges(eye, light, reach)
        else:
            starts, ends = np.array([0]), np.array([eng.index.size])
        is_point = light.distance is not None
        lvec = np.asarray(light.position if is_point else light.direction, dtype=float)
        tool = (eng.tool.radius, eng.tool.depth, max_tilt, eye, lvec, is_point)
        # Corners: consecutive arcs of one path, both candidates (a corner's
        # directions lie between theirs, so both are near the wanted one). The
        # ball sweeps every direction between the two tangents there.
        if len(eng.kinks):
            inside = eng.kink_rows >= 0
            if indexed:
                at = np.searchsorted(starts, eng.kink_rows, side="right") - 1
                inside &= (at >= 0) & (eng.kink_rows < np.append(ends, 0)[at])
            sel = inside.all(axis=1)
            ok, pts = _kernel.corner_glints(eng.kink_rows[sel], eng.geometry, *tool)
            at = eng.kinks[sel][ok]
            paths.append(eng.path[at])
            points.append(pts[ok])
            b = np.full(len(at), sphere)
            # a kink narrower than any light's lobe is the groove running on:
            # as bright as the arc after it
            soft = eng.kink_turn[sel][ok] < SOFT_CORNER
            if soft.any():
                b[soft] = _groove_brightness(eng.radius[at[soft] + 1], pts[ok][soft], eng.tool,
                                             light, eye)
            bright.append(b)
        rows = _kernel.expand(starts, ends)
        ok, pts = _kernel.arc_glints(rows, eng.geometry, *tool, iterations)
        # Back to arc order, as the arcs were before the index sorted them.
        arc = eng.index.layout[rows[ok]]
        order = np.argsort(arc)
        paths.append(eng.path[arc[order]])
        points.append(pts[ok][order])
        bright.append(_groove_brightness(eng.geometry[rows[ok], 2][order], points[-1],
                                         eng.tool, light, eye))

    # Dimples offer every normal up to the wall tilt.
    if len(eng.dot_path):
        s, h = wall_glint(eng.dot_pos, eng.tool, light, eye)
        ok = tilt(h) <= max_tilt
        paths.append(eng.dot_path[ok])
        points.append(s[ok])
        bright.append(np.full(int(ok.sum()), sphere))

    if not paths:
        return Glints(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)),
                      np.zeros(0))
    path = np.concatenate(paths)
    point = np.concatenate(points)
    brightness = np.concatenate(bright)
    stipple = eng.grooves.stipple[path]
    order = np.argsort(stipple, kind="stable")
    return Glints(path[order], stipple[order], point[order], brightness[order])


def _groove_brightness(radius: np.ndarray, point: np.ndarray, tool: Tool, light: Light,
                       eye: np.ndarray) -> np.ndarray:
    """(g,) brightness of glints on groove walls (see :attr:`Glints.brightness`): the
    ball's radius R across the groove times the wall's radius of curvature along
    it, rho / sin(tilt) for a centreline of radius ``radius`` (g,) (0: straight,
    taken as :data:`MAX_ALONG_RADIUS`), tilt the wall normal's from vertical
    at the glints ``point`` (g, 3). (The wall of a ball swept along a curve is a
    tube: along it the normal turns with the tangent only by its horizontal part.)"""
    h = normality(point, light, eye)
    sin_tilt = np.hypot(h[:, 0], h[:, 1]) / np.linalg.norm(h, axis=1)
    rho = np.where(radius > 0, radius, MAX_ALONG_RADIUS)
    along = np.minimum(rho / np.maximum(sin_tilt, 1e-12), MAX_ALONG_RADIUS)
    return tool.radius * along

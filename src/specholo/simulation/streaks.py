"""Glints as streaks: what a light of real size on a surface of real gloss shows.

The point model (:mod:`specholo.simulation.glints`) puts a glint where a
groove's wall normal is the half vector h exactly. Under a light of real size
on a real surface a wall glints wherever its normal is within the lobe of
:class:`~specholo.optics.spread.Spread` of h. Along a groove the wall normal
turns with the tangent, so each glint becomes a *streak*: the stretch of wall
where psi = asin(h . t / |h|) lies within the lobe's reach, each piece as
bright as its length times the lobe at its psi (times the ball's radius R,
the wall's radius across the groove, as the point model's brightness).

A streak is where the eye sees its stipple's light, so stereo takes its
brightness-weighted centre. Where a stripe ends before its streak does, the
streak is cut short and its centre moves in; where another groove's cut
passes through it, that piece is gone and the rest still shines (a gap, not
a lost glint). A streak whose psi never reaches zero on its path (its point
glint lies past the path's end, or past a corner) is an *end spill*: light a
stripe's end throws for views its neighbour serves. Bright spills far from
every designed glint are false glints.

:func:`find_streaks` walks each candidate arc (the glint index's, widened by
the lobe's reach) in compiled steps fine enough to resolve a groove's width,
and returns the lit cells grouped into streaks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from specholo.optics.normality import tilt
from specholo.optics.spread import Spread
from specholo.setup import Light
from specholo.simulation import _glint_kernel
from specholo.simulation._streak_kernel import streak_cells, within
from specholo.simulation.glints import FAINT_RATIO, Engraved, Glints, wall_glint

#: Longest step along a groove near a streak, mm: a fifth of the default drag
#: tip's groove (0.05 mm wide), so a crossing's gap spans several steps.
STEP = 0.01
#: A path turning less than this (radians) between two arcs keeps a streak
#: going: a program's rounded digits leave kinks of up to 2e-3 rad between
#: short arcs, and a kink turns the wall's normal by less than a lobe is wide.
CORNER = 0.01
#: What the eye resolves, radians (1 arcmin): pieces of a streak farther apart
#: than this, seen from the eye, are two glints.
ACUITY = math.radians(1.0 / 60.0)
#: A spill counts as a false glint this far from every designed glint, mm:
#: nearer, it merges with one (the verification's p95 error limit).
SPILL_SEPARATION = 0.25


@dataclass(frozen=True)
class Streaks:
    """The streaks one eye sees: lit cells along the grooves, grouped by streak.

    Attributes:
        path: (r,) the path of each streak; stipple: (r,) the stipple it shows.
        designed: (r,) whether the streak holds its path's point glint (psi
            crosses zero on it); the others are end spills.
        run: (c,) the streak of each cell, ascending.
        point: (c, 3) each cell's middle on the wall, mm.
        weight: (c,) each cell's brightness (mm^2/sr, as
            :attr:`~specholo.simulation.glints.Glints.brightness`); 0 where cut away.
        length: (c,) each cell's length along the groove, mm.
    """

    path: np.ndarray
    stipple: np.ndarray
    designed: np.ndarray
    run: np.ndarray
    point: np.ndarray
    weight: np.ndarray
    length: np.ndarray

    @property
    def count(self) -> int:
        return len(self.path)

    @cached_property
    def brightness(self) -> np.ndarray:
        """(r,) each streak's whole brightness: the sum of its cells'."""
        return np.bincount(self.run, weights=self.weight, minlength=self.count)

    @cached_property
    def centre(self) -> np.ndarray:
        """(r, 3) each streak's brightness-weighted centre (its first cell where dark)."""
        w = self.weight
        total = self.brightness
        out = np.zeros((self.count, 3))
        for axis in range(3):
            out[:, axis] = np.bincount(self.run, weights=w * self.point[:, axis],
                                       minlength=self.count)
        first = np.searchsorted(self.run, np.arange(self.count))
        dark = total <= 0.0
        out[~dark] /= total[~dark, None]
        if len(self.point):
            out[dark] = self.point[np.minimum(first[dark], len(self.point) - 1)]
        return out

    @cached_property
    def extent(self) -> np.ndarray:
        """(r,) each streak's lit length along its groove, mm: the cells that give
        more than a thousandth of its brightness."""
        lit = self.weight > 1e-3 * self.brightness[self.run]
        return np.bincount(self.run, weights=self.length * lit, minlength=self.count)

    def cut(self, keep: np.ndarray) -> Streaks:
        """The streaks with the cells not in ``keep`` ((c,) bool) cut away (dark)."""
        return Streaks(self.path, self.stipple, self.designed, self.run, self.point,
                       np.where(keep, self.weight, 0.0), self.length)

    def split(self, reach: np.ndarray) -> Streaks:
        """The streaks broken where a cut leaves pieces an eye sees apart.

        Consecutive lit pieces of a streak (runs of its cells with light, in
        order along the groove) whose brightness-weighted centres are more
        than ``reach`` ((r,) mm, per streak) apart become streaks of their own,
        each keeping the streak's path, stipple and ``designed``: a crossing
        cuts a gap into a streak, and nearer than the eye resolves the pieces
        either side are one spot, farther off two. A dark cell goes with the
        piece before it (the first piece, before any).
        """
        c = len(self.run)
        if c == 0:
            return self
        begins, centre = self.pieces
        if len(begins) < 2:
            return self
        run_of = self.run[begins]
        far = np.linalg.norm(np.diff(centre, axis=0), axis=1) > np.asarray(reach)[run_of[1:]]
        cut_at = begins[1:][far & (run_of[1:] == run_of[:-1])]
        if not len(cut_at):
            return self
        first = np.r_[True, self.run[1:] != self.run[:-1]]
        starts = np.zeros(c, dtype=bool)
        starts[cut_at] = True
        starts |= first
        new_run = np.cumsum(starts) - 1
        old = self.run[starts]
        return Streaks(self.path[old], self.stipple[old], self.designed[old], new_run,
                       self.point, self.weight, self.length)

    @cached_property
    def pieces(self) -> tuple[np.ndarray, np.ndarray]:
        """The lit pieces of the streaks (runs of cells with light, in order
        along the groove): the first cell of each (p,) and each one's
        brightness-weighted centre (p, 3)."""
        lit = self.weight > 0.0
        first = np.r_[True, self.run[1:] != self.run[:-1]] if len(self.run) else lit
        starts_piece = lit & (first | ~np.r_[False, lit[:-1]])
        begins = np.flatnonzero(starts_piece)
        piece = np.cumsum(starts_piece) - 1
        ok = lit & (piece >= 0)
        total = np.bincount(piece[ok], weights=self.weight[ok], minlength=len(begins))
        moment = np.stack([np.bincount(piece[ok], weights=self.weight[ok] * self.point[ok, k],
                                       minlength=len(begins)) for k in range(3)], axis=1)
        return begins, moment.reshape(-1, 3) / np.maximum(total, 1e-300)[:, None]

    def gather(self, reach: np.ndarray) -> Streaks:
        """The streaks with each end spill (a cap, a stripe end's light) taken
        into its path's designed streak where its centre lies within ``reach``
        ((r,) mm, per streak) of the centre of one of that streak's lit pieces
        (as :meth:`split` parts them): nearer than the eye resolves they are
        one spot, at their joint brightness-weighted centre, however faint
        the spill. A spill nearer several takes the nearest."""
        if self.count == 0 or self.designed.all() or not self.designed.any():
            return self
        centre, bright = self.centre, self.brightness
        spill = np.flatnonzero(~self.designed & (bright > 0.0))
        begins, at = self.pieces
        owner = self.run[begins]
        mine = np.flatnonzero(self.designed[owner])  # the designed streaks' pieces
        # every (spill, piece of a designed streak of its path) pair
        order = mine[np.argsort(self.path[owner[mine]], kind="stable")]
        i, j = _same_path_pairs(self.path[owner[order]], self.path[spill])
        which, near_piece = spill[i], order[j]
        cand = owner[near_piece]
        d = np.linalg.norm(at[near_piece] - centre[which], axis=1)
        near = d <= np.asarray(reach)[which]
        which, cand, d = which[near], cand[near], d[near]
        if not len(which):
            return self
        best = np.lexsort((d, which))  # each spill's nearest first
        first = np.r_[True, which[best][1:] != which[best][:-1]]
        into = np.full(self.count, -1, np.int64)
        into[which[best][first]] = cand[best][first]
        taken = into >= 0
        new_id = np.cumsum(~taken) - 1
        target = np.where(taken, new_id[np.maximum(into, 0)], new_id)
        run = target[self.run]
        cells = np.argsort(run, kind="stable")
        keep = ~taken
        return Streaks(self.path[keep], self.stipple[keep], self.designed[keep], run[cells],
                       self.point[cells], self.weight[cells], self.length[cells])

    def offset(self, paths: np.ndarray) -> Streaks:
        """The same streaks with each path renamed ``paths[path]`` (a chunk's paths)."""
        return Streaks(paths[self.path], self.stipple, self.designed, self.run, self.point,
                       self.weight, self.length)

    def glints(self) -> Glints:
        """The designed streaks as glints at their centres, sorted by stipple (the
        ones cut away entirely are gone)."""
        keep = self.designed & (self.brightness > 0.0)
        return _sorted(Glints(self.path[keep], self.stipple[keep], self.centre[keep],
                              self.brightness[keep]))

    def spills(self) -> Glints:
        """The end spills as glints at their centres, sorted by stipple."""
        keep = ~self.designed & (self.brightness > 0.0)
        return _sorted(Glints(self.path[keep], self.stipple[keep], self.centre[keep],
                              self.brightness[keep]))


def join(parts: list[Streaks]) -> Streaks:
    """One eye's streaks from several chunks of the grooves (paths already global)."""
    if not parts:
        return _empty()
    base = np.cumsum([0] + [p.count for p in parts[:-1]])
    return Streaks(np.concatenate([p.path for p in parts]),
                   np.concatenate([p.stipple for p in parts]),
                   np.concatenate([p.designed for p in parts]),
                   np.concatenate([p.run + b for p, b in zip(parts, base, strict=True)]),
                   np.concatenate([p.point for p in parts]).reshape(-1, 3),
                   np.concatenate([p.weight for p in parts]),
                   np.concatenate([p.length for p in parts]))


def bright_spills(streaks: Streaks) -> Glints:
    """The end spills bright enough for an eye to see as glints: at least 1/20
    as bright (:data:`~specholo.simulation.glints.FAINT_RATIO`) as their own
    stipple's brightest designed glint and as the typical stipple's (the
    image's rule, :meth:`~specholo.simulation.glints.Glints.image`, where a
    stipple with no designed glint has the typical one). They are part of
    what the eye sees of their stipple."""
    spills = streaks.spills()
    if len(spills.path) == 0:
        return spills
    designed = streaks.glints()
    b = spills.brightness
    assert b is not None and designed.brightness is not None
    if len(designed.path) == 0:
        return spills
    n = int(max(designed.stipple.max(), spills.stipple.max())) + 1
    top = np.zeros(n)
    np.maximum.at(top, designed.stipple, designed.brightness)
    lit = np.sort(top[np.unique(designed.stipple)])
    light = np.cumsum(lit)
    typical = float(lit[np.searchsorted(light, 0.5 * light[-1])])
    # as bright as a glint of its own stipple's image would have to be, and
    # never fainter than a glint of the typical stipple's image
    return spills.take(b * FAINT_RATIO >= np.maximum(top[spills.stipple], typical))


def false_glints(streaks: Streaks, image: Glints,
                 separation: float = SPILL_SEPARATION) -> np.ndarray:
    """The end spills an eye sees as glints of their own (:func:`bright_spills`)
    more than ``separation`` mm from every designed glint of the image: a
    point where the model has none.

    Args:
        streaks: the eye's streaks.
        image: the designed glints that make its image (bright enough).

    Returns:
        (f, 3) where the false glints are.
    """
    at = bright_spills(streaks).point
    return at[~within(image.point, at, separation)]


def find_streaks(eng: Engraved, eye: np.ndarray, light: Light, spread: Spread,
                 step: float = STEP) -> Streaks:
    """Every streak an eye sees on the engraved grooves.

    Args:
        eng: prepared groove geometry (ball-end walls, as the point model's).
        eye: (3,) eye position, mm.
        light: the light (its size is ``spread``'s).
        spread: the light's size and the surface's gloss.
        step: longest step along a groove near a streak, mm.

    Returns:
        The streaks, each with its cells.
    """
    eye = np.asarray(eye, dtype=float)
    tool = eng.tool
    beta = 0.5 * spread.light_size
    tail = float(spread.reach(0.0))
    parts: list[Streaks] = []
    if len(eng.path):
        reach = eng.index.half_length + tool.radius
        # k is at most 1 / |l + v|: bounded where the light is not behind the eye's back
        widest = float(spread.reach(2.0))
        starts, ends = eng.index.ranges(eye, light, reach, spread=widest)
        rows = _glint_kernel.expand(starts, ends)
        is_point = light.distance is not None
        lvec = np.asarray(light.position if is_point else light.direction, dtype=float)
        cell_row, s, f = streak_cells(rows, eng.geometry, tool.radius, tool.depth, tool.max_tilt,
                                      eye, lvec, is_point, beta, tail, step,
                                      _turn_rate(eng, eye, light))
        parts.append(_group(eng, rows, cell_row, s, f, spread))
    if len(eng.path):
        parts.append(_caps(eng, eye, light, parts[0]))
    if len(eng.dot_path):
        parts.append(_dots(eng, eye, light))
    return join(parts) if parts else _empty()


def _turn_rate(eng: Engraved, eye: np.ndarray, light: Light) -> float:
    """A bound on how fast h turns along a groove, rad/mm: a unit vector toward a
    point at distance d turns at most 1 / d per mm moved, and h sums two."""
    if len(eng.grooves.vertices) == 0:
        return 0.0
    span = eng.span
    rate = 2.0 / max(float(np.linalg.norm(eye)) - span, 1.0)
    if light.distance is not None:
        rate += 2.0 / max(light.distance - span, 1.0)
    return rate


def _group(eng: Engraved, rows: np.ndarray, cell_row: np.ndarray, s: np.ndarray, f: np.ndarray,
           spread: Spread) -> Streaks:
    """The walk's cells grouped into streaks: runs of cells that follow one
    another along a path with no corner between."""
    if len(cell_row) == 0:
        return _empty()
    arc = eng.index.layout[rows[cell_row]]
    order = np.lexsort((s[:, 0], arc))
    arc, s, f = arc[order], s[order], f[order]
    path = eng.path[arc]
    length = s[:, 1] - s[:, 0]
    arc_length = _arc_length(eng, arc)
    prev = slice(None, -1)
    nxt = slice(1, None)
    same_arc = (arc[nxt] == arc[prev]) & (np.abs(s[nxt, 0] - s[prev, 1]) <= 1e-9)
    next_arc = ((arc[nxt] == arc[prev] + 1) & (path[nxt] == path[prev])
                & (s[prev, 1] >= arc_length[prev] - 1e-9) & (s[nxt, 0] <= 1e-9))
    if next_arc.any():
        at = np.flatnonzero(next_arc)
        next_arc[at] = eng.turn_after(arc[at]) < CORNER
    starts = np.r_[True, ~(same_arc | next_arc)]
    run = np.cumsum(starts) - 1
    psi_a, psi_b, k = f[:, 3], f[:, 4], f[:, 5]
    weight = eng.tool.radius * length * spread.mass(psi_a, psi_b, k)
    crosses = psi_a * psi_b <= 0.0
    # (a zero on a join between arcs may fall between their cells by a rounding)
    crosses[1:] |= ~starts[1:] & (psi_b[:-1] * psi_a[1:] <= 0.0)
    n_runs = int(run[-1]) + 1
    designed = np.bincount(run, weights=crosses, minlength=n_runs) > 0
    first = np.flatnonzero(starts)
    run_path = path[first]
    return Streaks(run_path, eng.grooves.stipple[run_path], designed, run.astype(np.int64),
                   np.ascontiguousarray(f[:, :3]), weight, length)


def _arc_length(eng: Engraved, arc: np.ndarray) -> np.ndarray:
    """(c,) the length of each given arc (path order), mm."""
    r = eng.radius[arc]
    return np.where(r > 0, np.abs(r * eng.sweep[arc]),
                    np.linalg.norm(eng.end[arc] - eng.start[arc], axis=1))


def _dots(eng: Engraved, eye: np.ndarray, light: Light) -> Streaks:
    """Dimples: a sphere of the ball's radius offers every normal, so a dot is a
    point of brightness R^2 as in the point model, one cell each."""
    pos, path = eng.dot_pos, eng.dot_path
    g, h = wall_glint(pos, eng.tool, light, eye)
    ok = tilt(h) <= eng.tool.max_tilt
    q = int(ok.sum())
    return Streaks(path[ok], eng.grooves.stipple[path[ok]], np.ones(q, dtype=bool),
                   np.arange(q, dtype=np.int64), g[ok], np.full(q, eng.tool.radius**2),
                   np.zeros(q))


def _caps(eng: Engraved, eye: np.ndarray, light: Light, walls: Streaks) -> Streaks:
    """The caps a groove's ends leave: past its last point the tool's ball
    leaves a concave half dimple, whose normals point back into the groove.
    Where h does, the cap glints as a dot does (a point of brightness R^2, the
    ball's Gaussian curvature whatever the lobe), at the ball's point whose
    normal is h: one cell each, an end spill of its path. A closed path has
    no ends.

    A cap is far too faint to be seen on its own (about 1/250 of a typical
    glint on the render judge's plates); it counts only in the spot of its
    own stripe's designed streak, nearer it than the eye resolves
    (:meth:`Streaks.gather`). So only the caps within that reach of a
    designed streak of ``walls`` on their path are kept: on the README
    example, about 1 in 100 of those facing h."""
    path, at, out = eng.open_ends
    # a cap glints within the ball's radius of its end, in plan
    near = np.zeros((len(at), 3))
    near[:, :2] = at
    reach = ACUITY * np.linalg.norm(near - eye, axis=1)
    boxes = _designed_boxes(walls)
    maybe = np.flatnonzero(_near_designed(near, path, boxes, reach + eng.tool.radius))
    g, h = wall_glint(at[maybe], eng.tool, light, eye)
    ok = (np.einsum("ij,ij->i", h[:, :2], out[maybe]) < 0.0) & (tilt(h) <= eng.tool.max_tilt)
    ok &= _near_designed(g, path[maybe], boxes, ACUITY * np.linalg.norm(g - eye, axis=1))
    owner = path[maybe[ok]]
    q = int(ok.sum())
    return Streaks(owner, eng.grooves.stipple[owner], np.zeros(q, dtype=bool),
                   np.arange(q, dtype=np.int64), g[ok], np.full(q, eng.tool.radius**2),
                   np.zeros(q))


def _designed_boxes(walls: Streaks) -> tuple[np.ndarray, ...]:
    """The designed streaks of ``walls`` sorted by path: their paths (d,) and
    the boxes about their cells, lower (d, 2) and upper (d, 2) corners."""
    mine = np.flatnonzero(walls.designed)
    if not len(mine):
        return np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros((0, 2))
    begins = np.flatnonzero(np.r_[True, walls.run[1:] != walls.run[:-1]])  # runs ascend
    lo = np.minimum.reduceat(walls.point[:, :2], begins, axis=0)[mine]
    hi = np.maximum.reduceat(walls.point[:, :2], begins, axis=0)[mine]
    order = np.argsort(walls.path[mine], kind="stable")
    return walls.path[mine][order], lo[order], hi[order]


def _near_designed(at: np.ndarray, path: np.ndarray, boxes: tuple[np.ndarray, ...],
                   reach: np.ndarray) -> np.ndarray:
    """(q,) whether each point (q, 3) on a path (q,) lies within ``reach`` (q,)
    of the box about a designed streak on that path (:func:`_designed_boxes`)."""
    key, lo, hi = boxes
    keep = np.zeros(len(at), dtype=bool)
    if not len(key) or not len(at):
        return keep
    which, box = _same_path_pairs(key, path)
    gap = np.maximum(np.maximum(lo[box] - at[which, :2], at[which, :2] - hi[box]), 0.0)
    keep[which[np.hypot(gap[:, 0], gap[:, 1]) <= reach[which]]] = True
    return keep


def _same_path_pairs(key: np.ndarray, path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every pair (i, j) with ``key[j] == path[i]``, ``key`` sorted: two (m,)
    index arrays, i ascending."""
    start = np.searchsorted(key, path, side="left")
    n = np.searchsorted(key, path, side="right") - start
    i = np.repeat(np.arange(len(path)), n)
    return i, np.repeat(start, n) + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)


def _sorted(gl: Glints) -> Glints:
    return gl.take(np.argsort(gl.stipple, kind="stable"))


def _empty() -> Streaks:
    z = np.zeros(0, np.int64)
    return Streaks(z, z, np.zeros(0, dtype=bool), z, np.zeros((0, 3)), np.zeros(0), np.zeros(0))


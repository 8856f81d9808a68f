"""The plate as the tool actually cuts it, and the glints on that surface.

:func:`cut_surface` sweeps a rotationally symmetric tool along every move of a
program (straight segments and arcs at constant depth, plunges for dots) into
a height field of the plate: at a sample the swept surface of one move is
tip_z + profile(distance to the move in the plane), exact for a constant-depth
move, and the plate is the lowest of all moves. Each sample remembers the move
that cut it deepest, so every glint belongs to a path and hence to a stipple.

Where grooves cross or run closer than a groove width, one cut removes part of
the other's wall. :func:`find_cut_glints` finds the glints on that real
surface, and :func:`verify_cut` measures them exactly as
:func:`~specholo.simulation.verify.verify` measures the ideal grooves.

Glints. The sample grid sees the cross-section of a groove coarsely (the wall
normal of a ball of radius R turns by resolution / R per sample: 4.6 degrees
at 0.02 mm for R = 0.25) but the glint's place along the groove is set by a
slow turn (resolution / the groove's radius of curvature, 15 to 260 mm on
the bundled designs), so no single
angular lobe both samples the cross-section and keeps the bright streak short
along the groove. Each sample therefore uses the analytic surface of the move
that cut it (its slope and curvature): Newton's method gives where, near the
sample, the normal equals h, and the sample votes for that point with a
Gaussian weight of its distance (sigma = one sample: a lobe whose angular
width is the normal's change over one sample, in every direction). A path's
glint is the weighted centroid of its votes, and it is seen when the votes add
up to at least half a full neighbourhood: the glint point is on this path's
own surviving surface, not cut away by another groove, past its end or over
its rim.

The caps a ball leaves where it plunges and retracts offer every normal, so
nearly every path shows a faint glint at one of its ends for every eye. They
are R / (radius of curvature) as bright as a groove's glint (hundreds of times
fainter on these designs) and the ideal model has none, so they are kept
apart (``CutGlints.cap``) and left out of the verification unless asked for.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.errors import positive as _positive
from specholo.fabrication.stl import STL_FACES as STL_FACES
from specholo.fabrication.stl import write_stl as write_stl
from specholo.setup import Light, Setup, Tool
from specholo.simulation import _cut_kernel as _k
from specholo.simulation.glints import Glints
from specholo.simulation.verify import (
    ViewReport,
    VisibilityFn,
    view_azimuths,
    view_report,
)
from specholo.toolpaths.grooves import Grooves

#: Samples of a profile table.
PROFILE_SAMPLES = 8192
#: Tangent jump (radians) above which a joint between two moves is a corner.
CORNER = 1e-3
#: Rows per band of the parallel sweep.
BAND_ROWS = 16
#: Largest height field :func:`cut_surface` builds (samples).
MAX_SAMPLES = 600_000_000
#: Groove vertices swept at a time once a program has more than CHUNK_FROM: it
#: is built and cut a run of paths at a time, and only the moves that cut some
#: sample deepest are kept, so memory follows the field, not the program. A
#: chunk this small also sweeps faster than larger ones (its moves stay in
#: cache): at 10^5 stipples 26 s against 36 s for chunks of 10^6 vertices.
CHUNK_VERTICES = 100_000
CHUNK_FROM = 4_000_000

_LINE_BULGE = 1e-9
_PTR_BLOCK = 1 << 20


# ---------------------------------------------------------------------------
# Tool profiles


@dataclass(frozen=True)
class ToolProfile:
    """A rotationally symmetric tool's cutting surface, tabulated.

    Heights are above the tip at distance r from the axis, on a uniform grid of
    r with slopes, interpolated by cubic Hermite (slopes and curvature give
    the cut surface's normals and the glints' brightness). Past the table the
    last tangent line continues.

    Attributes:
        step: spacing of the table in r, mm.
        height: (n + 1,) heights at r = 0, step, ..., n step, mm.
        slope: (n + 1,) d height / d r there.
    """

    step: float
    height: np.ndarray
    slope: np.ndarray

    @property
    def reach(self) -> float:
        """Largest distance from the axis the table describes, mm."""
        return self.step * (len(self.height) - 1)

    def __call__(self, r: np.ndarray) -> np.ndarray:
        """Heights (n,) at distances r (n,) mm."""
        r = np.asarray(r, dtype=float)
        return _k.profile_many(r.ravel(), self.step, self.height, self.slope).reshape(r.shape)

    def cut_radius(self, depth: float) -> float:
        """Half the width of a groove ``depth`` deep: where the profile reaches it, mm."""
        above = np.flatnonzero(self.height >= depth)
        if len(above) == 0:
            return self.reach  # the tool's side wall stands at its reach
        i = int(above[0])
        if i == 0:
            return 0.0
        lo, hi = (i - 1) * self.step, i * self.step
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if _k.profile(mid, self.step, self.height, self.slope)[0] >= depth:
                hi = mid
            else:
                lo = mid
        return hi

    @classmethod
    def ball(cls, radius: float, samples: int = PROFILE_SAMPLES) -> ToolProfile:
        """Ball end of radius R: R - sqrt(R^2 - r^2), tabulated to 0.995 R (slope 10)."""
        radius = _positive("ball radius", radius)
        r = np.linspace(0.0, 0.995 * radius, samples + 1)
        root = np.sqrt(radius * radius - r * r)
        return cls(float(r[1]), radius - root, r / root)

    @classmethod
    def vbit(cls, angle: float, tip_flat: float = 0.0, reach: float = 1.0,
             samples: int = PROFILE_SAMPLES) -> ToolProfile:
        """V-bit of included ``angle`` (radians) with a tip flat (mm), out to ``reach`` mm."""
        if not (math.isfinite(angle) and 0.0 < angle < math.pi):
            raise SpecholoError(f"V-bit angle must be in (0, 180) degrees, got "
                                f"{math.degrees(angle):g}")
        if not (math.isfinite(tip_flat) and tip_flat >= 0.0):
            raise SpecholoError(f"tip flat must be >= 0 mm, got {tip_flat}")
        reach = _positive("reach", reach)
        r = np.linspace(0.0, reach, samples + 1)
        cot = 1.0 / math.tan(0.5 * angle)
        return cls(float(r[1]), np.maximum(r - 0.5 * tip_flat, 0.0) * cot,
                   np.where(r > 0.5 * tip_flat, cot, 0.0))

    @classmethod
    def from_samples(cls, r: np.ndarray, height: np.ndarray,
                     samples: int = PROFILE_SAMPLES) -> ToolProfile:
        """A measured profile: heights (m,) at increasing distances r (m,) from 0.

        Interpolated by a monotone cubic (no overshoot at a facet's edge) and
        resampled on a uniform table up to r[-1].
        """
        from scipy.interpolate import PchipInterpolator

        r = np.asarray(r, dtype=float)
        height = np.asarray(height, dtype=float)
        if r.ndim != 1 or r.shape != height.shape or len(r) < 2:
            raise SpecholoError(f"profile needs matching 1-D r and height of at least 2 "
                                f"samples, got shapes {r.shape} and {height.shape}")
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(height))):
            raise SpecholoError("profile samples must be finite")
        if r[0] != 0.0 or np.any(np.diff(r) <= 0):
            raise SpecholoError(f"profile distances must start at 0 and increase, got "
                                f"{r[:4].tolist()}...")
        if height[0] != 0.0 or np.any(np.diff(height) < 0):
            raise SpecholoError("profile heights must start at 0 (the tip) and not decrease")
        f = PchipInterpolator(r, height)
        grid = np.linspace(0.0, r[-1], samples + 1)
        return cls(float(grid[1]), f(grid), f.derivative()(grid))

    @classmethod
    def from_function(cls, fn: Callable[[np.ndarray], np.ndarray], reach: float,
                      samples: int = PROFILE_SAMPLES) -> ToolProfile:
        """Tabulate height = fn(r) (vectorised) on [0, reach]; non-finite values end the table."""
        reach = _positive("reach", reach)
        r = np.linspace(0.0, reach, samples + 1)
        h = np.asarray(fn(r), dtype=float)
        finite = np.isfinite(h)
        n = int(np.argmin(finite)) if not finite.all() else len(h)
        if n < 3:
            raise SpecholoError(f"tool profile is not finite near its axis (r <= {r[2]:g} mm)")
        return cls.from_samples(r[:n], h[:n] - h[0], samples)


def as_profile(tool: Any, depth: float) -> ToolProfile:
    """The profile of a tool given as a ToolProfile, a ball :class:`~specholo.setup.Tool`,
    an object with a ``height(r)`` method (any cutter; ``height(r, depth)`` too), or a
    callable height(r).

    Callables are tabulated out to 1.5 times the cut's half width at ``depth`` (or
    to where they stop being finite), which covers every sample a cut can reach.
    """
    if isinstance(tool, ToolProfile):
        return tool
    if isinstance(tool, Tool):
        return ToolProfile.ball(tool.radius)
    fn = getattr(tool, "height", tool)
    if not callable(fn):
        raise SpecholoError(f"not a tool profile: {tool!r}")
    if "depth" in inspect.signature(fn).parameters:
        depth_fn = fn

        def fn(r: np.ndarray) -> np.ndarray:
            return np.asarray(depth_fn(r, depth=depth))

    def height(r: float) -> float:
        return float(np.asarray(fn(np.array([r])), dtype=float)[0])

    # Double r until the tool rises 1.5 times the depth (or ends), then bisect.
    lo, hi = 0.0, max(depth, 1e-3)
    while math.isfinite(height(hi)) and height(hi) < 1.5 * depth:
        if height(hi) >= (1.0 - 1e-6) * depth and height(hi) - height(lo) <= 1e-6 * depth:
            return ToolProfile.from_function(fn, hi)  # levels off at the depth (a laser)
        lo, hi = hi, 2.0 * hi
        if hi > 1e4:
            raise SpecholoError(f"tool profile never reaches the depth {depth:g} mm")
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if math.isfinite(height(mid)) and height(mid) < 1.5 * depth:
            lo = mid
        else:
            hi = mid
    return ToolProfile.from_function(fn, lo if lo > 0 else hi)


# ---------------------------------------------------------------------------
# Moves


@dataclass(frozen=True)
class Moves:
    """The cutting moves of a program, in path order (one row per move).

    Attributes:
        geo: (k, 8) geometry, columns as in ``_cut_kernel`` (start, end, centre,
            radius, sweep).
        kind: (k,) int8 0 straight, 1 arc, 2 plunge (a dot).
        flags: (k,) int8 open start / end of the path, corner at start / end.
        path: (k,) path of each move.
        path_ptr: (n_paths + 1,) first move of each path.
        grooves: the grooves the moves cut.
    """

    geo: np.ndarray
    kind: np.ndarray
    flags: np.ndarray
    path: np.ndarray
    path_ptr: np.ndarray
    grooves: Grooves

    @classmethod
    def from_grooves(cls, grooves: Grooves) -> Moves:
        """Moves of grooves: each path's arcs, or one plunge for a dot."""
        seg = grooves.segments()
        centre, radius, start_angle, sweep = seg.geometry()
        k = len(seg)
        direction, length = _chords(seg.start, seg.end)
        arc = (np.abs(seg.bulge) >= _LINE_BULGE) & np.isfinite(radius) & (length > 0)
        kind = np.where(arc, _k.ARC, np.where(length > 0, _k.LINE, _k.POINT)).astype(np.int8)
        geo = np.zeros((k, _k.N_GEO))
        geo[:, _k.SX:_k.SY + 1] = seg.start
        geo[:, _k.EX:_k.EY + 1] = seg.end
        geo[arc, _k.CX:_k.CY + 1] = centre[arc]
        geo[arc, _k.RHO] = radius[arc]
        geo[arc, _k.SWEEP] = sweep[arc]
        # Tangents at both ends of each move, for corners.
        sg = np.sign(sweep)
        t_start = np.where(arc, start_angle + 0.5 * np.pi * sg,
                           np.arctan2(direction[:, 1], direction[:, 0]))
        t_end = np.where(arc, t_start + sweep, t_start)

        dot_pos, dot_path = grooves.dots()
        dots = np.zeros((len(dot_path), _k.N_GEO))
        dots[:, _k.SX:_k.SY + 1] = dot_pos
        dots[:, _k.EX:_k.EY + 1] = dot_pos
        path = np.concatenate([seg.path, dot_path]).astype(np.int64)
        order = np.argsort(path, kind="stable")
        geo = np.concatenate([geo, dots])[order]
        kind = np.concatenate([kind, np.full(len(dot_path), _k.POINT, np.int8)])[order]
        t_start = np.concatenate([t_start, np.zeros(len(dot_path))])[order]
        t_end = np.concatenate([t_end, np.zeros(len(dot_path))])[order]
        path = path[order]

        n = grooves.n_paths
        path_ptr = _path_ptr(path, n)
        flags = np.zeros(len(path), np.int8)
        first = path_ptr[:-1][np.diff(path_ptr) > 0]
        last = path_ptr[1:][np.diff(path_ptr) > 0] - 1
        flags[first] |= _k.OPEN_START
        flags[last] |= _k.OPEN_END
        jump = np.abs((t_start[1:] - t_end[:-1] + np.pi) % (2 * np.pi) - np.pi)
        corner = np.flatnonzero((path[1:] == path[:-1]) & (jump > CORNER))
        flags[corner] |= _k.CORNER_END
        flags[corner + 1] |= _k.CORNER_START
        return cls(np.ascontiguousarray(geo), kind, flags, path, path_ptr, grooves)

    @classmethod
    def from_rows(cls, geo: np.ndarray, kind: np.ndarray, flags: np.ndarray, path: np.ndarray,
                  grooves: Grooves) -> Moves:
        """Some moves of ``grooves``' program, rows in program order (path sorted)."""
        path = np.asarray(path, dtype=np.int64)
        return cls(np.ascontiguousarray(geo), kind, flags, path,
                   _path_ptr(path, grooves.n_paths), grooves)

    def __len__(self) -> int:
        return len(self.kind)

    def boxes(self) -> np.ndarray:
        """(k, 4) extent of each move: x min, x max, y min, y max (mm)."""
        g = self.geo
        xs = np.stack([g[:, _k.SX], g[:, _k.EX]], axis=1)
        ys = np.stack([g[:, _k.SY], g[:, _k.EY]], axis=1)
        box = np.stack([xs.min(1), xs.max(1), ys.min(1), ys.max(1)], axis=1)
        arc = np.flatnonzero(self.kind == _k.ARC)
        if len(arc):
            a0 = np.arctan2(g[arc, _k.SY] - g[arc, _k.CY], g[arc, _k.SX] - g[arc, _k.CX])
            sw = g[arc, _k.SWEEP]
            rho = g[arc, _k.RHO]
            # An arc reaches its circle's extreme in a direction it sweeps past.
            for phi, col, sign in ((0.0, 1, 1), (0.5 * np.pi, 3, 1), (np.pi, 0, -1),
                                   (1.5 * np.pi, 2, -1)):
                passes = np.mod(np.sign(sw) * (phi - a0), 2 * np.pi) <= np.abs(sw)
                centre = g[arc, _k.CX] if col < 2 else g[arc, _k.CY]
                extreme = centre + sign * rho
                box[arc, col] = np.where(
                    passes, (np.maximum if sign > 0 else np.minimum)(box[arc, col], extreme),
                    box[arc, col])
        return box

    def shapes(self, r_cut: float, margin: float) -> np.ndarray:
        """(k, 8) the region each move can cut, for the sweep (see ``_cut_kernel.sweep``).

        A move's chord rectangle reaches r_cut (plus an arc's sagitta) across
        and past its ends only by ``margin`` where the path goes on smoothly
        (the next move cuts there at least as deep) and by r_cut at a path's
        end or a corner, so each sample near a path is visited about once.
        """
        g = self.geo
        k = len(self)
        direction, length = _chords(g[:, _k.SX:_k.SY + 1], g[:, _k.EX:_k.EY + 1])
        shape = np.zeros((k, 8))
        shape[:, 0:2] = g[:, _k.SX:_k.SY + 1]
        shape[:, 2:4] = direction
        half = 0.5 * np.abs(g[:, _k.SWEEP])
        sagitta = g[:, _k.RHO] * (1.0 - np.cos(half))
        w = r_cut + sagitta
        # The arc's end radii lean out of the chord's normals by half the sweep.
        lean = w * np.tan(np.minimum(half, 0.5 * np.pi - 1e-3))
        open_start = (self.flags & (_k.OPEN_START | _k.CORNER_START)) > 0
        open_end = (self.flags & (_k.OPEN_END | _k.CORNER_END)) > 0
        shape[:, 4] = -np.where(open_start, r_cut, margin) - lean
        shape[:, 5] = length + np.where(open_end, r_cut, margin) + lean
        shape[:, 6] = np.where(self.kind == _k.POINT, r_cut, w)
        shape[:, 7] = np.where(self.kind == _k.POINT, 1.0,
                               np.where(half > 0.5 * np.pi - 1e-3, 2.0, 0.0))
        return shape


def _path_ptr(path: np.ndarray, n: int) -> np.ndarray:
    """(n + 1,) first row of each of n paths in sorted ``path`` (k,), a block at a time:
    a kept table has a field's worth of rows but may number tens of millions of paths."""
    ptr = np.empty(n + 1, np.int64)
    for a in range(0, n + 1, _PTR_BLOCK):
        b = min(a + _PTR_BLOCK, n + 1)
        ptr[a:b] = np.searchsorted(path, np.arange(a, b))
    return ptr


def _chords(start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit chord directions (k, 2), zero where a move has no length, and lengths (k,).

    The same values as ``_cut_kernel.chord``, which recomputes them from the ends.
    """
    chord = end - start
    length = np.hypot(chord[:, 0], chord[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        direction = chord / length[:, None]
    return np.where(length[:, None] > 0, direction, 0.0), length


# ---------------------------------------------------------------------------
# Height field


@dataclass(frozen=True)
class HeightField:
    """A cut plate sampled on a square grid.

    Sample [j, i] lies at (origin[0] + i resolution, origin[1] + j resolution):
    rows run up the plate (y), columns to the right (x).

    Attributes:
        z: (ny, nx) float32 heights, mm (0 uncut, < 0 cut).
        origin: (2,) position of sample [0, 0], mm.
        resolution: sample spacing, mm.
        labels: (ny, nx) int32 path that cut each sample deepest, -1 uncut.
        moves: (ny, nx) int32 move (row of ``program``) that cut it deepest, -1 uncut.
        program: the moves.
        profile: the tool.
        depth: tip depth of every move, mm.
    """

    z: np.ndarray
    origin: np.ndarray
    resolution: float
    labels: np.ndarray
    moves: np.ndarray
    program: Moves
    profile: ToolProfile
    depth: float

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.z.shape[0]), int(self.z.shape[1]))

    @property
    def x(self) -> np.ndarray:
        """(nx,) sample x positions, mm."""
        return self.origin[0] + self.resolution * np.arange(self.z.shape[1])

    @property
    def y(self) -> np.ndarray:
        """(ny,) sample y positions, mm."""
        return self.origin[1] + self.resolution * np.arange(self.z.shape[0])

    @property
    def bounds(self) -> np.ndarray:
        """(2, 2) first and last sample positions (x, y), mm."""
        hi = self.origin + self.resolution * (np.array(self.z.shape[::-1]) - 1)
        return np.stack([self.origin, hi])

    def surface(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact heights and unit normals of the cut plate at points.

        Each point takes the surface of the move that cut its nearest sample
        (the plane z = 0 where that sample is uncut).

        Args:
            xy: (n, 2) points, mm.

        Returns:
            z (n,) and normals (n, 3).
        """
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        ij = np.rint((xy - self.origin) / self.resolution).astype(np.int64)
        ny, nx = self.shape
        inside = (ij[:, 0] >= 0) & (ij[:, 0] < nx) & (ij[:, 1] >= 0) & (ij[:, 1] < ny)
        m = np.full(len(xy), -1, np.int64)
        m[inside] = self.moves[ij[inside, 1], ij[inside, 0]]
        p, g = self.profile, self.program
        z, grad = _k.surface_at(xy, m, g.geo, g.kind, g.flags, self.depth, p.step, p.height,
                                p.slope)
        normal = np.concatenate([-grad, np.ones((len(xy), 1))], axis=1)
        return z, normal / np.linalg.norm(normal, axis=1, keepdims=True)


def cut_surface(grooves: Grooves, tool_profile: ToolProfile | Tool | Any, depth: float,
                bounds: np.ndarray | None = None, resolution: float = 0.02) -> HeightField:
    """Sweep the tool along every move into a height field of the plate.

    Args:
        grooves: the program's paths (from the design, or read back with
            :func:`~specholo.fabrication.programs.gcode_reader.read_gcode`).
        tool_profile: the tool (see :func:`as_profile`).
        depth: depth of the tool's tip below the plate on every move, mm.
        bounds: (2, 2) lower-left and upper-right corners of the plate region to
            simulate, mm; default the grooves' extent plus a groove half width.
            Moves outside it are skipped, so any crop is cheap.
        resolution: sample spacing, mm.

    Returns:
        The height field; samples start at the lower-left corner and reach or
        just pass the upper-right one.

    Raises:
        SpecholoError: on a bad depth, resolution or bounds, or a field too large.
    """
    depth = _positive("cut depth", depth)
    res = _positive("resolution", resolution)
    profile = as_profile(tool_profile, depth)
    r_cut = profile.cut_radius(depth)
    if bounds is None:
        b = grooves.extent()  # arcs count where they bulge past their ends
        bounds = np.stack([b[0] - r_cut - res, b[1] + r_cut + res])
    bounds = np.asarray(bounds, dtype=float)
    if bounds.shape != (2, 2) or not np.all(np.isfinite(bounds)) or np.any(
            bounds[1] <= bounds[0]):
        raise SpecholoError(f"bounds must be [[x0, y0], [x1, y1]] with x1 > x0 and y1 > y0, "
                            f"got {bounds.tolist()}")
    nx, ny = (np.ceil((bounds[1] - bounds[0]) / res - 1e-9).astype(np.int64) + 1).tolist()
    if nx * ny > MAX_SAMPLES:
        raise SpecholoError(f"a {nx} x {ny} height field is too large (at most "
                            f"{MAX_SAMPLES:,} samples): crop the bounds or coarsen the "
                            f"resolution {res:g} mm")
    x0, y0 = bounds[0]
    z = np.zeros((ny, nx), np.float32)
    move = np.full((ny, nx), -1, np.int32)
    grid = (float(x0), float(y0), res, nx, ny)
    total = len(grooves.vertices)
    if grooves.n_paths > 1 and total > CHUNK_FROM:
        cuts = np.searchsorted(grooves.offsets, np.arange(CHUNK_VERTICES, total, CHUNK_VERTICES))
        cuts = np.unique(np.clip(cuts, 1, grooves.n_paths - 1))
        ends = np.concatenate([[0], cuts, [grooves.n_paths]]).tolist()
        program = _sweep_chunks(grooves, list(zip(ends[:-1], ends[1:], strict=True)), grid,
                                depth, r_cut, profile, z, move)
    else:
        program = Moves.from_grooves(grooves)
        _sweep(program, 0, grid, depth, r_cut, profile, z, move)
    # move -1 (uncut) picks the appended -1
    labels = np.append(program.path.astype(np.int32), np.int32(-1))[move]
    return HeightField(z, bounds[0].copy(), res, labels, move, program, profile, depth)


def _sweep_chunks(grooves: Grooves, chunks: list[tuple[int, int]],
                  grid: tuple[float, float, float, int, int], depth: float, r_cut: float,
                  profile: ToolProfile, z: np.ndarray, move: np.ndarray) -> Moves:
    """Cut the program a run of paths at a time; the moves that cut some sample deepest.

    The chunks go in program order and the kernel keeps the first of equally
    deep moves, so the field is that of one sweep. Moves are numbered across
    the chunks, then renumbered among those kept, which are built again chunk
    by chunk: no table of the whole program is ever held.
    """
    # A path of k vertices makes at most k moves.
    if len(grooves.vertices) > np.iinfo(np.int32).max:
        raise SpecholoError(f"the program has up to {len(grooves.vertices):,} moves, more than "
                            "a height field can number: simulate fewer paths at a time")
    first = [0]
    for p0, p1 in chunks:
        part = Moves.from_grooves(grooves.take(np.arange(p0, p1)))
        _sweep(part, first[-1], grid, depth, r_cut, profile, z, move)
        first.append(first[-1] + len(part))
    cut = move >= 0
    used, renumber = np.unique(move[cut], return_inverse=True)
    move[cut] = renumber
    del cut, renumber  # a field's worth of int64: not held while the table is rebuilt
    geo = np.empty((len(used), _k.N_GEO))
    kind, flags = np.empty(len(used), np.int8), np.empty(len(used), np.int8)
    path = np.empty(len(used), np.int64)
    ends = np.searchsorted(used, first)
    for (p0, p1), lo, a, b in zip(chunks, first[:-1], ends[:-1], ends[1:], strict=True):
        if a == b:
            continue
        part = Moves.from_grooves(grooves.take(np.arange(p0, p1)))
        rows = used[a:b] - lo
        geo[a:b], kind[a:b], flags[a:b] = part.geo[rows], part.kind[rows], part.flags[rows]
        path[a:b] = part.path[rows] + p0
    return Moves.from_rows(geo, kind, flags, path, grooves)


def _sweep(program: Moves, base: int, grid: tuple[float, float, float, int, int], depth: float,
           r_cut: float, profile: ToolProfile, z: np.ndarray, move: np.ndarray) -> None:
    """Cut a program's moves into z and move (numbered from ``base``), in place."""
    if not len(program):
        return
    x0, y0, res, nx, ny = grid
    ext = program.boxes()
    box = np.empty((len(program), 4), np.int64)
    box[:, 0] = np.maximum(np.ceil((ext[:, 0] - r_cut - x0) / res), 0)
    box[:, 1] = np.minimum(np.floor((ext[:, 1] + r_cut - x0) / res), nx - 1)
    box[:, 2] = np.maximum(np.ceil((ext[:, 2] - r_cut - y0) / res), 0)
    box[:, 3] = np.minimum(np.floor((ext[:, 3] + r_cut - y0) / res), ny - 1)
    live = np.flatnonzero((box[:, 1] >= box[:, 0]) & (box[:, 3] >= box[:, 2]))
    b0 = box[live, 2] // BAND_ROWS
    nb = box[live, 3] // BAND_ROWS - b0 + 1
    which = np.repeat(live, nb)
    band = np.repeat(b0, nb) + (np.arange(int(nb.sum())) - np.repeat(np.cumsum(nb) - nb, nb))
    order = np.argsort(band, kind="stable")  # keeps program order within a band
    n_bands = (ny + BAND_ROWS - 1) // BAND_ROWS
    band_ptr = np.searchsorted(band[order], np.arange(n_bands + 1)).astype(np.int64)
    _k.sweep(program.geo, program.kind, box, program.shapes(r_cut, res), band_ptr,
             which[order].astype(np.int64), BAND_ROWS, x0, y0, res, depth, r_cut,
             profile.step, profile.height, profile.slope, base, z, move)


def cut_design(loaded: Any, resolution: float = 0.02,
               bounds: np.ndarray | None = None) -> HeightField:
    """Cut a loaded design (``pipeline.Loaded``) with its own tool and depth.

    Args:
        loaded: the design, its grooves read from the G-code or the design file.
        resolution: sample spacing, mm.
        bounds: (2, 2) plate region, mm; default the grooves' extent.
    """
    config = loaded.config
    cutter = config.cutter() if callable(getattr(config, "cutter", None)) else None
    tool = cutter if cutter is not None else config.setup().tool
    return cut_surface(loaded.grooves, tool, float(config.depth), bounds, resolution)


# ---------------------------------------------------------------------------
# Glints


@dataclass(frozen=True)
class CutCells:
    """A height field's cut samples grouped by the move that cut them.

    Attributes:
        field: the height field.
        ptr: (k + 1,) samples of move m are ``cells[ptr[m]:ptr[m + 1]]``.
        cells: (c,) flat sample indices (j nx + i).
    """

    field: HeightField
    ptr: np.ndarray
    cells: np.ndarray

    @classmethod
    def build(cls, field: HeightField) -> CutCells:
        """Group the field's cut samples (a counting sort; once per field, for every eye)."""
        ptr, cells = _k.group_cells(field.moves, len(field.program))
        return cls(field, ptr, cells)


@dataclass(frozen=True)
class CutGlints:
    """Glints an eye sees on a cut plate.

    Attributes:
        glints: the glints (path, stipple, point), sorted by stipple.
        cap: (g,) glints on the cap at a path's end (not a designed glint).
        coverage: (g,) share of the glint's neighbourhood that its own path cut
            (1 for an intact wall; below MIN_COVERAGE nothing is reported).
        brightness: (g,) reflecting area per steradian of h, mm^2/sr: how bright
            the glint is for a given light and pupil.
    """

    glints: Glints
    cap: np.ndarray
    coverage: np.ndarray
    brightness: np.ndarray

    def designed(self) -> Glints:
        """The glints on the grooves and dots, without the caps."""
        keep = ~self.cap
        g = self.glints
        return Glints(g.path[keep], g.stipple[keep], g.point[keep], self.brightness[keep])


#: Lobe width, in samples of position (see the module docstring).
SIGMA_SAMPLES = 1.0
#: A glint counts when its votes reach this share of a full neighbourhood.
MIN_COVERAGE = 0.5
#: Newton steps per sample.
NEWTON_STEPS = 4


def find_cut_glints(cells: CutCells | HeightField, eye: np.ndarray, light: Light,
                    caps: bool = False, min_coverage: float = MIN_COVERAGE) -> CutGlints:
    """All glints an eye sees on the cut plate.

    Only the samples of moves that may glint for this eye are visited (h . t
    changes sign along the move, extended by the lobe's reach, or nearly so),
    plus every dot and corner; the caps only when asked.

    Args:
        cells: the height field's cut samples (prepare them once for many eyes),
            or the height field.
        eye: (3,) eye position, mm.
        light: the light.
        caps: also report glints on the caps at paths' ends.
        min_coverage: share of a full neighbourhood a glint's votes must reach.

    Returns:
        The glints, sorted by stipple.
    """
    if isinstance(cells, HeightField):
        cells = CutCells.build(cells)
    hf = cells.field
    g = hf.program
    eye = np.asarray(eye, dtype=float)
    res = hf.resolution
    sigma = SIGMA_SAMPLES * res
    r_cut = hf.profile.cut_radius(hf.depth)
    point = light.distance is not None
    lvec = np.asarray(light.position if point else light.direction, dtype=float)
    centre = np.array([*hf.bounds.mean(axis=0), 0.0])
    far = float(np.linalg.norm(eye - centre))
    if point:
        far = min(far, float(np.linalg.norm(lvec - centre)))
    ext = 5.0 * sigma + res
    tol = 2.0 * (r_cut + ext) / max(far, 1e-9)
    body_ok = _k.screen(g.geo, g.kind, g.flags, hf.depth, ext, tol, eye, lvec, point)
    want = body_ok | ((g.flags & (_k.OPEN_START | _k.OPEN_END)) > 0) if caps else body_ok
    has_cells = np.diff(cells.ptr) > 0
    paths = np.unique(g.path[want & has_cells])
    sums, cap, count = _k.glints(
        paths, g.path_ptr, body_ok, caps, cells.ptr, cells.cells, hf.shape[1],
        float(hf.origin[0]), float(hf.origin[1]), res, g.geo, g.kind, g.flags, hf.depth,
        hf.profile.step, hf.profile.height, hf.profile.slope, eye, lvec, point, sigma,
        NEWTON_STEPS, 1e-4, 2.0 * res, 1e-6)
    slot = np.arange(_k.MAX_CLUSTERS)[None, :] < count[:, None]
    full = 2.0 * math.pi * SIGMA_SAMPLES**2  # the votes of an intact neighbourhood
    coverage = sums[..., 0] / full
    keep = slot & (coverage >= min_coverage)
    q, t = np.nonzero(keep)
    s = sums[q, t]
    point3 = s[:, 1:4] / s[:, :1]
    path = paths[q]
    h = _normality(point3, light, eye)
    cos_tilt = h[:, 2] / np.linalg.norm(h, axis=1)
    brightness = s[:, 4] / s[:, 0] / cos_tilt**3
    stipple = g.grooves.stipple[path]
    order = np.argsort(stipple, kind="stable")
    return CutGlints(Glints(path[order], stipple[order], point3[order]), cap[q, t][order],
                     coverage[q, t][order], brightness[order])


def _normality(points: np.ndarray, light: Light, eye: np.ndarray) -> np.ndarray:
    v = eye - points
    return light.towards(points) + v / np.linalg.norm(v, axis=1, keepdims=True)


# ---------------------------------------------------------------------------
# Verification


def _view_report(theta: float, points: np.ndarray, gl: Glints, gr: Glints, eye_l: np.ndarray,
                 eye_r: np.ndarray, visible: VisibilityFn | None) -> ViewReport:
    """The figures :func:`~specholo.simulation.verify.verify` reports for one head."""
    n = len(points)
    if visible is None or n == 0:
        vis_l = vis_r = np.ones(n, dtype=bool)
    else:
        vis_l = visible(points, np.broadcast_to(eye_l, (n, 3)))
        vis_r = visible(points, np.broadcast_to(eye_r, (n, 3)))
    return view_report(theta, points, gl, gr, eye_l, eye_r, vis_l, vis_r)


def verify_cut(field: HeightField | CutCells, points: np.ndarray, setup: Setup,
               visible: VisibilityFn | None = None, azimuths: np.ndarray | None = None,
               caps: bool = False) -> list[ViewReport]:
    """:func:`~specholo.simulation.verify.verify` on the cut plate instead of ideal grooves.

    Args:
        field: the cut plate (or its cells, prepared once for several runs).
        points: (n, 3) stipple points the grooves should show.
        setup: light and viewer (the tool is the field's).
        visible: occlusion test; None means every stipple is unoccluded.
        azimuths: head azimuths in radians; default every <= 5 degrees over the range.
        caps: count the caps' faint glints too.

    Returns:
        One report per azimuth, with the same figures as ``verify``.
    """
    cells = field if isinstance(field, CutCells) else CutCells.build(field)
    points = np.asarray(points, dtype=float)
    if azimuths is None:
        azimuths = view_azimuths(setup.viewer.half_range)
    reports = []
    for theta in azimuths:
        eyes_l, eyes_r = setup.viewer.stereo(np.array([theta]))
        found = [find_cut_glints(cells, e[0], setup.light, caps=caps) for e in (eyes_l, eyes_r)]
        gl, gr = (f.glints if caps else f.designed() for f in found)
        reports.append(_view_report(float(theta), points, gl, gr, eyes_l[0], eyes_r[0],
                                    visible))
    return reports


def agreement(ideal: list[ViewReport], cut: list[ViewReport]) -> list[dict[str, float]]:
    """Per azimuth, cut-plate figures minus ideal-groove figures (mm and shares)."""
    keys = ("median_error", "p95_error", "p95_depth_error", "max_error", "visibility",
            "false_glints")
    out = []
    for a, b in zip(ideal, cut, strict=True):
        if not math.isclose(a.azimuth, b.azimuth, abs_tol=1e-9):
            raise SpecholoError(f"reports are for different azimuths: {a.azimuth:g} and "
                                f"{b.azimuth:g} degrees")
        row = {"azimuth": a.azimuth}
        row.update({k: getattr(b, k) - getattr(a, k) for k in keys})
        out.append(row)
    return out


# ---------------------------------------------------------------------------
# STL



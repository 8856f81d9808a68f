"""Continuous grooves for a view that circles the scene several times per plate turn.

The paper's 720-degree holograms: as the plate turns once, the view circles a
head twice, with a different face on each circuit. In the plate frame the eyes
circle the axis once per turn (:mod:`specholo.toolpaths.spinning`), so the scene
must turn too: with ``turns`` = T its orientation in the plate frame is
R_z((T - 1) phi), and the view's angle about the scene is T phi.

A stipple fixed to such a scene cannot be served by a continuous groove. For a
distant viewer the groove traced by its sightline crossings x(phi) has
x' . e = (J R(2 phi) p) . e != 0 off the axis, so the glint leaves the
crossing. What the groove condition allows (the paper: "solve for motions of
the virtual scene") is a point that moves along its own sightline: if
c'(phi) is parallel to the sightline s(phi), the crossing's velocity is the one
of a fixed point at c's depth, perpendicular to the view, and the glint stays
on it. So each stipple here is a point that *slides over the turning surface*
along its sightline: at every plate angle it lies on the scene at its current
orientation, and the eyes see it there. Its speed follows from staying on the
surface, lambda = (T - 1)(J c . N) / (s . N) for a surface normal N; near a
silhouette s . N goes to 0 and the point is dropped.

Numerically the motion is stepped on a grid of plate angles: the point keeps
its plate-frame position, the scene turns by one step under it, and the point
moves along the sightline to the midpoint eye (at the step's middle) onto the
turned surface (a ray cast, embree when installed). A point lives for the run
of angles around its birth where it stays on the surface, faces the eyes and
neither eye has it hidden, and off the plate's plane (a groove's curvature
changes sign there).

Each track gets one open groove through its support function over a window of
normal directions, s(psi) = sum_m a_m T_m(u) (Chebyshev, u the window mapped to
[-1, 1]): "eye i at angle phi_j sees the track's point c(phi_j) at its
sightline crossing" is linear in the coefficients, as for the closed grooves,
and both eyes over the whole life are fitted at once. The groove keeps only the
normal directions both eyes serve within the life, so an eye never sees a
stipple its partner does not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.polynomial import chebyshev as cheb

from specholo.errors import SpecholoError
from specholo.setup import Tool
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.spinning import (
    RELIEF_MARGIN,
    SpinDesign,
    SpinSetup,
    crossings,
    max_wall_tilt,
    rotate_z,
)

#: Plate-angle step of the tracks, radians.
STEP = math.radians(0.5)
#: A point closer than this to the plate's plane ends its life, mm.
PLANE_GAP = 0.2
#: Largest move along the sightline in one step, mm (more: a silhouette).
MAX_SLIDE = 2.0
#: Shortest life kept, radians of plate angle (both eyes must share part of it).
MIN_LIFE = math.radians(20.0)
#: Longest life, radians (a groove's normal directions must not wrap round).
MAX_LIFE = math.radians(300.0)
#: Lives longer than this are thinned so that every plate angle gets the same
#: density of live stipples (a long life would otherwise be drawn more often).
THIN_LIFE = math.radians(30.0)
#: Candidates traced at once (each holds a (K, 3) track and normals).
MAX_BATCH = 6000
#: Chebyshev degree of a groove per radian of its window, and the bounds.
DEGREE_PER_RAD = 15.0
DEGREE_RANGE = (6, 48)
#: Margin inside the normal directions both eyes serve, radians.
SERVE_MARGIN = math.radians(0.25)


def scene_angle(turns: int, phi: np.ndarray) -> np.ndarray:
    """The scene's orientation about z in the plate frame at plate angles phi (k,)."""
    return (turns - 1) * np.asarray(phi, dtype=float)


@dataclass(frozen=True)
class Tracks:
    """Stipples sliding over a turning scene, sampled on a grid of plate angles.

    Attributes:
        turns: view circuits per plate turn.
        phi: (K,) plate angles of the grid over one turn, radians.
        position: (n, K, 3) plate-frame positions, mm; NaN where not alive.
        alive: (n, K) bool, the stipple is on the surface, facing and not hidden
            from either eye at grid angle j: a glint of it is right for either eye.
        scene: (n,) index of the scene each stipple lies on.
        shown: (n, K) bool, the angles at which both eyes are meant to see it
            (set by the design: within the life, where both eyes' glints fall
            on the groove kept); None: wherever alive.
    """

    turns: int
    phi: np.ndarray
    position: np.ndarray
    alive: np.ndarray
    scene: np.ndarray
    shown: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.scene)

    def at(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (n, k, 3), alive (n, k) and shown (n, k) at plate angles phi
        (k,), radians.

        Linear between grid angles; alive (shown) only where both neighbours are.
        """
        k_grid = len(self.phi)
        step = 2.0 * math.pi / k_grid
        f = (np.asarray(phi, dtype=float) % (2.0 * math.pi)) / step
        j0 = np.floor(f).astype(int) % k_grid
        j1 = (j0 + 1) % k_grid
        w = (f - np.floor(f))[None, :, None]
        exact = w[0, :, 0] < 1e-9
        masks = []
        for mask in (self.alive, self.alive if self.shown is None else self.shown):
            both = mask[:, j0] & mask[:, j1]
            both[:, exact] = mask[:, j0[exact]]
            masks.append(both)
        pos = (1.0 - w) * self.position[:, j0] + w * self.position[:, j1]
        pos[:, exact] = self.position[:, j0[exact]]
        return pos, masks[0], masks[1]


def eye_gap(setup: SpinSetup) -> float:
    """Plate angle between the two eyes seen from the axis, radians: a groove
    direction serves one eye this much earlier than the other."""
    across = setup.distance * math.cos(setup.elevation)
    return 2.0 * math.atan(0.5 * setup.ipd / across)


def _intervals(n_scenes: int, k_grid: int, margin: int) -> list[tuple[int, int, bool]]:
    """Grid index range [a, b) of each scene's life (maybe past 0 or K: taken
    modulo K) and whether it wraps round the turn. A scene lives ``margin`` steps
    either side of its part of the turn, so that both eyes are served up to the
    hand-over (each eye then sees the other scene's stipples alone for a moment)."""
    if n_scenes == 1:
        return [(0, k_grid, True)]
    return [(s * k_grid // n_scenes - margin, (s + 1) * k_grid // n_scenes + margin, False)
            for s in range(n_scenes)]


def _walk(mesh: Any, setup: SpinSetup, turns: int, phi: np.ndarray, birth: np.ndarray,
          u0: np.ndarray, span: tuple[int, int, bool], direction: int,
          pos: np.ndarray, nrm: np.ndarray) -> None:
    """Step the points born at grid indices ``birth`` (m,) from model-frame points
    u0 (m, 3) one way round (+1 or -1), writing plate-frame positions and
    model-frame normals into pos, nrm (m, K, 3) until each leaves the surface."""
    k_grid = len(phi)
    a, b, wrap = span
    mid_eye = setup.world_eyes().mean(axis=0)
    m = len(birth)
    cur = rotate_z(u0, scene_angle(turns, phi[birth % k_grid]))  # plate frame
    live = np.ones(m, dtype=bool)
    limit = (b - a) - 1 if wrap else k_grid
    for s in range(1, limit + 1):
        j = birth + direction * s
        if wrap:
            j = a + (j - a) % (b - a)
        else:
            live &= (j >= a) & (j < b)
        j = j % k_grid
        idx = np.flatnonzero(live)
        if not len(idx):
            return
        jj = j[idx]
        # the sightline at the step's middle; the surface at its end
        t_mid = phi[jj] - 0.5 * direction * (2.0 * math.pi / k_grid)
        eye = rotate_z(np.broadcast_to(mid_eye, (len(idx), 3)), -t_mid)
        turn = -scene_angle(turns, phi[jj])
        o = rotate_z(cur[idx], turn)
        d = rotate_z(eye, turn) - o
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        start = o - MAX_SLIDE * d
        loc, ray, tri = mesh.ray.intersects_location(start, d, multiple_hits=True)
        off = np.abs(np.einsum("ij,ij->i", loc - start[ray], d[ray]) - MAX_SLIDE)
        best = np.full(len(idx), -1)
        order = np.argsort(off)[::-1]  # nearest hit of each ray written last
        best[ray[order]] = order
        ok = best >= 0
        ok[ok] = off[best[ok]] < MAX_SLIDE
        fn = np.zeros((len(idx), 3))
        fn[ok] = np.asarray(mesh.face_normals)[tri[best[ok]]]
        ok &= np.einsum("ij,ij->i", fn, d) > 0.0  # the surface faces the eyes
        live[idx[~ok]] = False
        good = idx[ok]
        cur[good] = rotate_z(loc[best[ok]], -turn[ok])
        pos[good, j[good]] = cur[good]
        nrm[good, j[good]] = fn[ok]


def _lives(ok: np.ndarray, birth: np.ndarray) -> np.ndarray:
    """(m, K) the run of ``ok`` (m, K) round each birth index (wrapping round)."""
    m, k_grid = ok.shape
    out = np.zeros_like(ok)
    cap = int(MAX_LIFE / (2.0 * math.pi) * k_grid) // 2  # either side of the birth
    for r in range(m):  # runs are cheap to find per row; rows are the few
        row = ok[r]
        i0 = int(birth[r])
        if not row[i0]:
            continue
        if row.all():
            row = row.copy()
            row[(i0 + k_grid // 2) % k_grid] = False
        rolled = np.roll(row, -i0)
        fwd = min(int(np.argmin(rolled)), cap)  # first dark step ahead
        back = min(int(np.argmin(rolled[::-1])), cap - 1)  # first dark step behind
        sel = (i0 + np.arange(-back, fwd)) % k_grid
        out[r, sel] = True
    return out


def slide_tracks(meshes: list[Any], setup: SpinSetup, turns: int, count: int,
                 rng: np.random.Generator, step: float = STEP,
                 occlusion: bool = True, max_rounds: int = 24) -> Tracks:
    """Stipples sliding over the scenes, about ``count`` of them live at any angle.

    Args:
        meshes: one placed mesh (the view circles it ``turns`` times, continuously)
            or ``turns`` meshes (the k-th shown over the k-th part of the turn).
        setup: the viewer and light.
        turns: view circuits per plate turn (>= 2).
        count: live stipples wanted at each plate angle (a mean over the turn).
        rng: random generator (surface samples, birth angles, thinning).
        step: grid step of plate angle, radians.
        occlusion: end a life where either eye has the point hidden.
        max_rounds: batches of candidates drawn at most.

    Returns:
        The tracks of every stipple kept.
    """

    if turns < 2:
        raise SpecholoError(f"sliding stipples need at least 2 turns of the view, got {turns}")
    if len(meshes) not in (1, turns):
        raise SpecholoError(f"give one model, or one per turn of the view ({turns}); "
                            f"got {len(meshes)}")
    if any(m is None for m in meshes):
        raise SpecholoError("a view that circles the scene needs a mesh (a surface to slide "
                            "over), not a point cloud")
    # Rays through every hit and sampling the surface are trimesh's.
    meshes = [m.to_trimesh() if hasattr(m, "to_trimesh") else m for m in meshes]
    k_grid = int(round(2.0 * math.pi / step))
    phi = np.arange(k_grid) * (2.0 * math.pi / k_grid)
    gap = int(math.ceil(eye_gap(setup) / (2.0 * math.pi / k_grid)))
    # lives reach past the hand-over by the eye gap, the serving margin and a step
    margin = gap + int(math.ceil(2.0 * SERVE_MARGIN / (2.0 * math.pi / k_grid))) + 1
    spans = _intervals(len(meshes), k_grid, margin)
    eyes = setup.eyes(phi)  # (2, K, 3)
    parts: list[tuple[np.ndarray, np.ndarray, int]] = []
    for s, (mesh, span) in enumerate(zip(meshes, spans, strict=True)):
        a, b, wrap = span
        nominal = (b - a) if wrap else (b - a - 2 * margin)
        got_pos: list[np.ndarray] = []
        got_alive: list[np.ndarray] = []
        live_sum = 0.0  # mean stipples shown per angle of the interval so far
        batch = min(max(64, 4 * count), MAX_BATCH)
        for _ in range(max_rounds):
            pos, alive = _candidates(mesh, setup, turns, phi, eyes, span, batch, rng, occlusion)
            got_pos.append(pos)
            got_alive.append(alive)
            # both eyes are served for all but two eye gaps of each life
            gain = float(np.maximum(alive.sum(axis=1) - 2 * gap, 0).sum()) / nominal
            live_sum += gain
            if live_sum >= count:
                break
            # the next batch sized from this one's yield, with a margin
            batch = int(min(max(64, 1.2 * (count - live_sum) * batch / max(gain, 1e-3)),
                            MAX_BATCH))
        pos_s = np.concatenate(got_pos)
        alive_s = np.concatenate(got_alive)
        if live_sum > count and len(alive_s):  # too many: keep a random share
            take = rng.random(len(alive_s)) < count / live_sum
            pos_s, alive_s = pos_s[take], alive_s[take]
        parts.append((pos_s, alive_s, s))
    position = np.concatenate([p for p, _, _ in parts]) if parts else np.zeros((0, k_grid, 3))
    alive = np.concatenate([al for _, al, _ in parts])
    scene = np.concatenate([np.full(len(al), s, dtype=np.int64) for _, al, s in parts])
    return Tracks(turns, phi, position, alive, scene)


def _candidates(mesh: Any, setup: SpinSetup, turns: int, phi: np.ndarray, eyes: np.ndarray,
                span: tuple[int, int, bool], m: int, rng: np.random.Generator,
                occlusion: bool) -> tuple[np.ndarray, np.ndarray]:
    """Tracks (m', K, 3) and lives (m', K) of m candidates born at random angles of
    the span on random surface points; short lives dropped and long ones thinned."""
    import trimesh

    a, b, _ = span
    k_grid = len(phi)
    u0, face = trimesh.sample.sample_surface(mesh, m, seed=int(rng.integers(2**31)))
    n0 = np.asarray(mesh.face_normals)[face]
    birth = rng.integers(a, b, m)  # may lie past 0 or K (a scene's margin)
    at = birth % k_grid
    pos = np.full((m, k_grid, 3), np.nan)
    nrm = np.zeros((m, k_grid, 3))
    pos[np.arange(m), at] = rotate_z(u0, scene_angle(turns, phi[at]))
    nrm[np.arange(m), at] = n0
    _walk(mesh, setup, turns, phi, birth, u0, span, +1, pos, nrm)
    _walk(mesh, setup, turns, phi, birth, u0, span, -1, pos, nrm)
    ok = np.isfinite(pos[..., 0]) & (np.abs(np.nan_to_num(pos[..., 2])) > PLANE_GAP)
    if occlusion:
        ii, jj = np.nonzero(ok)
        turn = -scene_angle(turns, phi[jj])
        um = rotate_z(pos[ii, jj], turn)
        seen = np.ones(len(ii), dtype=bool)
        for e in range(2):
            seen &= _visible(mesh, um, nrm[ii, jj], rotate_z(eyes[e, jj], turn))
        ok[ii[~seen], jj[~seen]] = False
    alive = _lives(ok, at)
    life = alive.sum(axis=1) * (2.0 * math.pi / k_grid)
    keep = (life >= MIN_LIFE) & (rng.random(m) < THIN_LIFE / np.maximum(life, THIN_LIFE))
    pos[~alive] = np.nan
    return pos[keep], alive[keep]


def _visible(mesh: Any, points: np.ndarray, normals: np.ndarray, eyes: np.ndarray) -> np.ndarray:
    from specholo.visibility.occlusion import visible

    return visible(mesh, points, normals, eyes)


def _basis(psi: np.ndarray, mid: np.ndarray, half: np.ndarray, degree: int) -> np.ndarray:
    """(..., 2, degree+1) contribution of each Chebyshev coefficient to x(psi).

    psi (..., k) with the window's middle and half width (..., 1).
    """
    u = (psi - mid) / half
    v = cheb.chebvander(u, degree)
    dmat = np.stack([np.concatenate([cheb.chebder(np.eye(degree + 1)[m]), [0.0]])
                     for m in range(degree + 1)], axis=1)
    dv = (v @ dmat) / half[..., None]
    n = np.stack([np.cos(psi), np.sin(psi)], axis=-1)
    t = np.stack([-np.sin(psi), np.cos(psi)], axis=-1)
    return v[..., None, :] * n[..., :, None] + dv[..., None, :] * t[..., :, None]


def _half_psi(setup: SpinSetup, x: np.ndarray, eyes: np.ndarray) -> np.ndarray:
    h = setup.half_vectors(x, np.broadcast_to(eyes, x.shape))
    return np.arctan2(h[..., 1], h[..., 0])


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class ArcFit:
    """Open grooves fitted to tracks.

    Attributes:
        coef: (n, D+1) Chebyshev coefficients of each support function (zero-padded).
        window: (n, 2) middle and half width of each window of normal directions.
        served: (n, 2) the normal directions both eyes serve within the life.
        shown: (n, K) the grid angles at which both eyes' glints fall on them.
        tilts: (lo, hi) tilt of h over the fitted glints, radians.
    """

    coef: np.ndarray
    window: np.ndarray
    served: np.ndarray
    shown: np.ndarray
    tilts: tuple[float, float]


def fit_arcs(tracks: Tracks, setup: SpinSetup, chunk: int = 128) -> ArcFit:
    """Fit one open groove per track for both eyes over its life."""
    n, k_grid = tracks.alive.shape
    eyes = setup.eyes(tracks.phi)  # (2, K, 3)
    deg_hi = DEGREE_RANGE[1]
    coef = np.zeros((n, deg_hi + 1))
    window = np.zeros((n, 2))
    served = np.zeros((n, 2))
    shown = np.zeros((n, k_grid), dtype=bool)
    lo_tilt, hi_tilt = math.inf, -math.inf
    life = tracks.alive.sum(axis=1)
    order = np.argsort(life, kind="stable")  # similar windows share a degree
    start = _life_starts(tracks.alive)
    for lo in range(0, n, chunk):
        rows = order[lo:lo + chunk]
        # each life in time order from its first angle (lives may wrap round)
        span = int(life[rows].max()) if len(rows) else 0
        cols = (start[rows, None] + np.arange(span)[None, :]) % k_grid  # (c, J)
        sel = np.take_along_axis(tracks.alive[rows], cols, axis=1)
        w = np.concatenate([sel, sel], axis=1).astype(float)  # (c, 2J)
        e = np.concatenate([eyes[0][cols], eyes[1][cols]], axis=1)  # (c, 2J, 3)
        p = np.nan_to_num(tracks.position[rows[:, None], cols])
        target = crossings(e, np.concatenate([p, p], axis=1))  # (c, 2J, 3)
        psi = _half_psi(setup, target, e)
        # unwrap each eye along its life, then put the right eye on the left's branch
        psi = np.concatenate([np.unwrap(psi[:, :span], axis=1),
                              np.unwrap(psi[:, span:], axis=1)], axis=1)
        jump = psi[:, span] - psi[:, 0]
        psi[:, span:] += (_wrap(jump) - jump)[:, None]
        masked = np.where(w > 0, psi, np.nan)
        p_lo, p_hi = np.nanmin(masked, axis=1), np.nanmax(masked, axis=1)
        mid = 0.5 * (p_lo + p_hi)
        half = np.maximum(0.5 * (p_hi - p_lo), 1e-3) * 1.05  # room for the refinement
        deg = int(np.clip(math.ceil(DEGREE_PER_RAD * 2.0 * float(half.max())),
                          *DEGREE_RANGE))
        m = deg + 1
        for _ in range(3):
            a = _basis(psi, mid[:, None], half[:, None], deg)  # (c, 2J, 2, m)
            aw = (a * w[..., None, None]).reshape(len(rows), -1, m)
            flat = a.reshape(len(rows), -1, m)
            ata = np.matmul(aw.transpose(0, 2, 1), flat) + 1e-9 * np.eye(m)
            atb = np.matmul(aw.transpose(0, 2, 1), target[..., :2].reshape(len(rows), -1, 1))
            c = np.linalg.solve(ata, atb)[..., 0]
            x = np.matmul(flat, c[..., None]).reshape(a.shape[:3])
            x3 = np.concatenate([x, np.zeros(x.shape[:-1] + (1,))], axis=-1)
            psi = psi + _wrap(_half_psi(setup, x3, e) - psi)
            psi = np.clip(psi, (mid - half)[:, None], (mid + half)[:, None])
        coef[rows, :m] = c
        window[rows] = np.stack([mid, half], axis=1)
        pl = np.where(w[:, :span] > 0, psi[:, :span], np.nan)
        pr = np.where(w[:, span:] > 0, psi[:, span:], np.nan)
        s_lo = np.maximum(np.nanmin(pl, 1), np.nanmin(pr, 1)) + SERVE_MARGIN
        s_hi = np.minimum(np.nanmax(pl, 1), np.nanmax(pr, 1)) - SERVE_MARGIN
        served[rows] = np.stack([s_lo, s_hi], axis=1)
        # shown: both eyes' glints at that angle fall on the kept part
        inside = ((psi >= s_lo[:, None]) & (psi <= s_hi[:, None])) & (w > 0)
        both = inside[:, :span] & inside[:, span:]
        rr = np.repeat(rows, span).reshape(len(rows), span)
        shown[rr[both], cols[both]] = True
        h = setup.half_vectors(x3, e)
        tilt = np.arctan2(np.hypot(h[..., 0], h[..., 1]), h[..., 2])[w > 0]
        if len(tilt):
            lo_tilt, hi_tilt = min(lo_tilt, float(tilt.min())), max(hi_tilt, float(tilt.max()))
    return ArcFit(coef, window, served, shown, (lo_tilt, hi_tilt))


def _life_starts(alive: np.ndarray) -> np.ndarray:
    """(n,) grid index where each (contiguous, maybe wrapping) life begins."""
    before = np.roll(alive, 1, axis=1)
    begins = alive & ~before
    return np.where(begins.any(axis=1), begins.argmax(axis=1), 0)


def arc_points(fit: ArcFit, i: int, psi: np.ndarray) -> np.ndarray:
    """Points (k, 2) of groove i at normal directions psi (k,)."""
    deg = int(np.max(np.flatnonzero(fit.coef[i]), initial=0))
    deg = max(deg, 1)
    a = _basis(psi, np.array(fit.window[i, 0]), np.array(fit.window[i, 1]), deg)
    return np.einsum("kdm,m->kd", a, fit.coef[i, :deg + 1])


def design_sliding(tracks: Tracks, setup: SpinSetup, tool: Tool,
                   fit: ArcFit | None = None, spacing: float = math.radians(0.5)
                   ) -> SpinDesign:
    """One open groove per track, cropped to the normal directions both eyes serve.

    Args:
        tracks: the sliding stipples.
        setup: the viewer and light (on the axis).
        tool: the ball-end cutter, checked against the wall tilts the views need.
        fit: what :func:`fit_arcs` returned, if the caller has it.
        spacing: vertex spacing in normal direction, radians.

    Returns:
        A design whose ``tracks`` say where and when each stipple should be seen
        (alive where both eyes are served); its ``points`` are each track's
        position where it is first alive.

    Raises:
        SpecholoError: if the tool's walls are not steep enough for the views.
    """
    fit = fit_arcs(tracks, setup) if fit is None else fit
    offered = max_wall_tilt(tool)
    if len(tracks) and fit.tilts[1] > offered:
        raise SpecholoError(
            f"the views need wall tilts up to {math.degrees(fit.tilts[1]):.1f} deg but the "
            f"{tool.radius:g} mm ball at {tool.depth:g} mm depth offers "
            f"{math.degrees(offered):.1f} deg; cut deeper or raise the viewer")
    tilts = fit.tilts if len(tracks) else (0.0, 0.0)
    verts: list[np.ndarray] = []
    sizes: list[int] = []
    owner: list[int] = []
    sides: list[int] = []
    side = np.zeros(len(tracks), dtype=np.int64)
    for i in range(len(tracks)):  # one polyline per stipple; the heavy work is batched above
        lo, hi = fit.served[i]
        if not (math.isfinite(lo) and math.isfinite(hi)) or hi - lo < 2.0 * spacing:
            continue
        # glints fall between segment midpoints: reach half a step past each end
        lo, hi = lo - 0.5 * spacing, hi + 0.5 * spacing
        psi = np.linspace(lo, hi, int(math.ceil((hi - lo) / spacing)) + 1)
        xy = arc_points(fit, i, psi)
        # the radius of curvature's sign says which wall the glint is on
        rho = np.einsum("kd,kd->k", np.diff(xy, axis=0),
                        np.stack([-np.sin(psi[:-1]), np.cos(psi[:-1])], -1))
        side[i] = -1 if np.median(rho) >= 0 else 1
        verts.append(xy)
        sizes.append(len(xy))
        owner.append(i)
        sides.append(int(side[i]))
    vertices = np.concatenate(verts) if verts else np.zeros((0, 2))
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    grooves = Grooves(vertices, np.zeros(len(vertices)), offsets,
                      np.asarray(owner, dtype=np.int64))
    first = tracks.alive.argmax(axis=1) if len(tracks) else np.zeros(0, dtype=int)
    points = tracks.position[np.arange(len(tracks)), first] if len(tracks) else \
        np.zeros((0, 3))
    relief = max(tilts[0] - RELIEF_MARGIN, 0.0)
    # what the verification expects: each stipple where both eyes are served
    shown = fit.shown & tracks.alive
    n_scenes = int(tracks.scene.max()) + 1 if len(tracks) else 1
    if n_scenes > 1:  # each model is meant for its own part of the turn only
        k_grid = len(tracks.phi)
        part = np.arange(k_grid) * n_scenes // k_grid  # (K,) the scene meant at each angle
        shown &= part[None, :] == tracks.scene[:, None]
    return SpinDesign(setup, points, fit.coef, side, grooves,
                      np.asarray(sides, dtype=np.int64), tilts, relief,
                      tracks=replace(tracks, shown=shown), window=fit.window)

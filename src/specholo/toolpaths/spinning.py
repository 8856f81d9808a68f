"""Continuous closed grooves for a plate turning about its normal.

The plate (z = 0, normal +z) turns by an angle phi about the z axis, on a
turntable or a wall spinner, under a light on that axis; the viewer stands
still. In the plate frame the eyes circle the axis (they are turned by -phi),
the light stays put, and the scene, which turns with the plate, is fixed. Each
stipple gets one closed groove that glints for every phi: no stripes, no
hand-over, one continuous toolpath.

A closed convex groove is written through its support function
s(psi) = a0 + sum_k (a_k cos k psi + b_k sin k psi): its point with in-plane
normal n(psi) = (cos psi, sin psi) is x(psi) = s n + s' t, t = (-sin psi, cos psi).
A ball-end groove glints for an eye where its tangent is perpendicular to the
half vector h, that is where n(psi) is parallel to h's in-plane part. So the
condition "eye i at angle phi_j sees the stipple at its sightline crossing X_ij"
is linear in the coefficients once psi_ij (the direction of h at X_ij) is known:
x(psi_ij) = X_ij. Solving these for both eyes over the whole turn in the least
squares sense, and refining psi at the fitted points, gives the closed groove
closest to exact.

Why it is not exact at a finite distance: with the light on the axis and the
eyes far away the groove is a circle about the stipple's foot, radius
|p_z| cot(elevation), and exact for both eyes at every angle. Nearer, the
disparity the two eyes need changes round the turn with the eyes' distance to
the glint, which asks the groove's radius of curvature to change by a first
harmonic of psi; a closed curve's radius of curvature has none. What remains
is a depth error that grows with the stipple's depth and its distance from the
axis and falls as the viewer steps back; the verifier measures it per angle.
With the light off the axis the two eyes ask for different grooves and the
error reaches millimetres, so the light must be on the axis.

A symmetric groove glints on both walls: the other wall shows every stipple's
mirror image through the plate at the same time (the "twin"). ``walls="one"``
designs a groove whose other wall is cut away (a sawtooth ring: the serving
wall, then a vertical riser), which the verifier models.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo.errors import SpecholoError, positive
from specholo.setup import Tool
from specholo.toolpaths.grooves import Grooves

#: Walls a spinning groove may keep.
WALLS = ("one", "both")
#: Ranges (lowest, highest, unit) of the viewer and light of a turning plate and
#: of a steady image, as a flat design's (``settings.SETTING_BOUNDS``): eyes
#: from 10 mm to 10 km away, a light on the axis from 1 mm to 10 km in front.
#: Beyond them the optics divide by nothing or overflow, and no plate is seen
#: that way. (The eyes' spacing is a setting's, bounded where the settings are:
#: a model of the optics may spread them as far as it moves them away.)
VIEW_BOUNDS: dict[str, tuple[float, float, str]] = {
    "view_distance": (10.0, 1e7, "mm"), "light_height": (1.0, 1e7, "mm"),
    "eye_height": (-1e5, 1e5, "mm")}


def within(name: str, value: float, lo: float, hi: float, unit: str) -> float:
    """``value`` as a float if it lies in [lo, hi], else one line naming the
    setting (as its option, ``view-distance``) and its range."""
    try:
        v = float(value)
    except OverflowError:  # an integer beyond any float
        v = math.inf
    if not lo <= v <= hi:  # NaN too
        option = name.replace("_", "-")
        raise SpecholoError(f"{option} {v:g} {unit} is out of range: it must be in "
                            f"[{lo:g}, {hi:g}] {unit}")
    return v


def view_within(name: str, value: float) -> float:
    """:func:`within` the setting's :data:`VIEW_BOUNDS`."""
    return within(name, value, *VIEW_BOUNDS[name])


@dataclass(frozen=True)
class SpinSetup:
    """A plate turning about its normal, seen by a viewer standing still.

    Attributes:
        distance: from the plate centre to the point between the eyes, mm.
        elevation: the eyes' angle above the plate's plane, radians (pi/2 is on
            the axis, which the light takes).
        ipd: interocular distance, mm.
        light_height: a point light on the axis this far in front of the plate,
            mm; None for a distant light along the axis.
        harmonics: harmonics of each groove's support function (1: a circle with
            its centre and radius fitted; more measured no better, as the closure
            argument above says).
        angles: plate angles over the turn that the fit uses.
        samples: vertices of each closed groove.
        walls: "one" (the unused wall cut away) or "both" (a plain groove).
    """

    distance: float = 600.0
    elevation: float = math.radians(45.0)
    ipd: float = 64.0
    light_height: float | None = None
    harmonics: int = 1
    angles: int = 144
    samples: int = 192
    walls: str = "one"

    def __post_init__(self) -> None:
        view_within("view_distance", self.distance)
        positive("ipd", self.ipd)
        el = float(self.elevation)
        if not (math.isfinite(el) and math.radians(5.0) <= el <= math.radians(85.0)):
            raise SpecholoError(f"viewer elevation must be in [5, 85] degrees, got "
                                f"{math.degrees(el):g}")
        if self.ipd >= self.distance:
            raise SpecholoError(f"ipd {self.ipd:g} mm must be below the viewer distance "
                                f"{self.distance:g} mm")
        if self.light_height is not None:
            view_within("light_height", self.light_height)
        if not 1 <= int(self.harmonics) <= 32:
            raise SpecholoError(f"harmonics must be in [1, 32], got {self.harmonics}")
        if not 16 <= int(self.angles) <= 3600:
            raise SpecholoError(f"angles must be in [16, 3600], got {self.angles}")
        if not 16 <= int(self.samples) <= 4096:
            raise SpecholoError(f"samples must be in [16, 4096], got {self.samples}")
        if self.walls not in WALLS:
            raise SpecholoError(f"walls must be one of {', '.join(WALLS)}, got {self.walls!r}")

    def world_eyes(self) -> np.ndarray:
        """(2, 3) left and right eye in the world frame (the plate at angle 0)."""
        c = self.distance * np.array([0.0, -math.cos(self.elevation), math.sin(self.elevation)])
        half = 0.5 * self.ipd * np.array([1.0, 0.0, 0.0])
        return np.stack([c - half, c + half])

    def eyes(self, phi: np.ndarray) -> np.ndarray:
        """Eyes in the plate frame with the plate turned by ``phi``.

        Args:
            phi: (k,) plate angles, radians.

        Returns:
            (2, k, 3) left and right eye positions, mm.
        """
        return rotate_z(self.world_eyes()[:, None, :], -np.asarray(phi, dtype=float)[None, :])

    def light_dirs(self, x: np.ndarray) -> np.ndarray:
        """Unit vectors (..., 3) from plate points ``x`` (..., 3) to the light."""
        if self.light_height is None:
            return np.broadcast_to(np.array([0.0, 0.0, 1.0]), x.shape)
        v = np.array([0.0, 0.0, self.light_height]) - x
        return v / np.linalg.norm(v, axis=-1, keepdims=True)

    def half_vectors(self, x: np.ndarray, eye: np.ndarray) -> np.ndarray:
        """Unnormalised half vectors (..., 3) at plate points x for eyes ``eye``."""
        u = eye - x
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        return u + self.light_dirs(x)


def rotate_z(v: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """Rotate vectors (..., 3) about z by ``angle`` (broadcast against v[..., 0])."""
    c, s = np.cos(angle), np.sin(angle)
    x, y = v[..., 0], v[..., 1]
    return np.stack([c * x - s * y, s * x + c * y, np.broadcast_to(v[..., 2], np.shape(c * x))],
                    axis=-1)


def crossings(eyes: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Where sightlines from ``eyes`` (..., 3) through ``points`` (..., 3) meet z = 0."""
    t = eyes[..., 2] / (eyes[..., 2] - points[..., 2])
    return eyes + (points - eyes) * t[..., None]


def _basis(psi: np.ndarray, harmonics: int) -> np.ndarray:
    """(..., 2, m) contribution of each support-function coefficient to x(psi)."""
    n = np.stack([np.cos(psi), np.sin(psi)], axis=-1)
    t = np.stack([-np.sin(psi), np.cos(psi)], axis=-1)
    cols = [n]
    for k in range(1, harmonics + 1):
        c, s = np.cos(k * psi), np.sin(k * psi)
        cols.append(c[..., None] * n - (k * s)[..., None] * t)
        cols.append(s[..., None] * n + (k * c)[..., None] * t)
    return np.stack(cols, axis=-1)


def groove_points(coef: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Groove points (n, k, 2) at normal directions psi (n, k) for coefficients (n, m)."""
    harmonics = (coef.shape[-1] - 1) // 2
    return np.einsum("nkdm,nm->nkd", _basis(psi, harmonics), coef)


@dataclass(frozen=True)
class SpinDesign:
    """Closed grooves for a turning plate.

    Attributes:
        setup: the geometry.
        points: (n, 3) stipples in the plate frame, mm.
        coef: (n, 2K+1) support-function coefficients of each stipple's groove.
        side: (n,) +1 where the groove serves with the wall on its right (going
            along the path), -1 with the wall on its left.
        grooves: the sampled paths (closed unless cropped), one per stipple or
            several where occlusion crops it; ``grooves.stipple`` names the stipple.
        path_side: (n_paths,) the serving wall of each path (see ``side``).
        tilts: (lo, hi) tilts of h over every glint the fit asks for, radians.
        relief_tilt: with ``walls="one"`` the other wall keeps only tilts below
            this (radians); the relief cut removes the rest.
        tracks: for a view circling the scene several times per turn, the
            stipples sliding over it (:mod:`specholo.toolpaths.sliding`); then
            ``coef`` holds each open groove's Chebyshev coefficients over its
            ``window`` (n, 2) of normal directions. None for fixed stipples.
        window: see ``tracks``.
    """

    setup: SpinSetup
    points: np.ndarray
    coef: np.ndarray
    side: np.ndarray
    grooves: Grooves
    path_side: np.ndarray
    tilts: tuple[float, float]
    relief_tilt: float
    tracks: Any = None
    window: np.ndarray | None = None


#: The relief cut leaves the other wall's tilts this far below the lowest needed.
RELIEF_MARGIN = math.radians(3.0)
#: Included angle of the V-bit that cuts the relief.
RELIEF_ANGLE = math.radians(30.0)


def fit_grooves(points: np.ndarray, setup: SpinSetup, chunk: int = 2048
                ) -> tuple[np.ndarray, tuple[float, float]]:
    """Support-function coefficients (n, 2K+1) of the closed grooves, fitted for both
    eyes, and the (lo, hi) tilt of h over the glints they serve (radians).

    Args:
        points: (n, 3) stipples in the plate frame, mm (off the plate: |z| > 0).
        setup: the geometry.
        chunk: stipples solved at once (memory ~ chunk * angles * K).
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    m = 2 * setup.harmonics + 1
    coef = np.zeros((len(points), m))
    lo_tilt, hi_tilt = math.inf, -math.inf
    phi = np.linspace(0.0, 2.0 * np.pi, setup.angles, endpoint=False)
    eyes = setup.eyes(phi).reshape(-1, 3)  # (2J, 3): left then right
    for lo in range(0, len(points), chunk):
        p = points[lo:lo + chunk]
        target = crossings(eyes[None, :, :], p[:, None, :])  # (c, 2J, 3)
        psi = _psi(setup, target, eyes)
        for _ in range(3):  # psi from h at the fitted points, then refit
            a = _basis(psi, setup.harmonics)  # (c, 2J, 2, m)
            ata = np.einsum("nkdm,nkdl->nml", a, a)
            atb = np.einsum("nkdm,nkd->nm", a, target[..., :2])
            ata += 1e-12 * np.eye(m)
            c = np.linalg.solve(ata, atb[..., None])[..., 0]
            x = np.einsum("nkdm,nm->nkd", a, c)
            x3 = np.concatenate([x, np.zeros(x.shape[:-1] + (1,))], -1)
            psi = _psi(setup, x3, eyes)
        coef[lo:lo + chunk] = c
        h = setup.half_vectors(x3, np.broadcast_to(eyes, x3.shape))
        tilt = np.arctan2(np.hypot(h[..., 0], h[..., 1]), h[..., 2])
        lo_tilt, hi_tilt = min(lo_tilt, float(tilt.min())), max(hi_tilt, float(tilt.max()))
    return coef, (lo_tilt, hi_tilt)


def _psi(setup: SpinSetup, x: np.ndarray, eyes: np.ndarray) -> np.ndarray:
    h = setup.half_vectors(x, np.broadcast_to(eyes, x.shape))
    return np.arctan2(h[..., 1], h[..., 0])


def design_spinning(points: np.ndarray, setup: SpinSetup, tool: Tool,
                    visible: np.ndarray | None = None,
                    coef: np.ndarray | None = None,
                    fitted: tuple[np.ndarray, tuple[float, float]] | None = None
                    ) -> SpinDesign:
    """Design one closed groove per stipple for a turning plate.

    Args:
        points: (n, 3) stipples in the plate frame, mm.
        setup: the geometry.
        tool: the ball-end cutter (checked against the wall tilts the views need).
        visible: optional (n, samples) bool: vertex k of stipple i's groove is
            kept (its point is not hidden for the plate angle that vertex serves,
            see :func:`vertex_angles`); None keeps every groove whole.
        coef: optional (n, 2K+1) support-function coefficients to use instead of
            the fit (for example :func:`classic_circles`, to compare).
        fitted: what :func:`fit_grooves` returned for these points and setup,
            if the caller already has it.

    Returns:
        The design; stipples on the plate's plane (|z| < 1e-6 mm) get a dimple.

    Raises:
        SpecholoError: if the tool's walls are not steep enough for the views.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) and not np.all(np.isfinite(points)):
        raise SpecholoError("stipples must be finite")
    fit_coef, tilts = fit_grooves(points, setup) if fitted is None else fitted
    coef = fit_coef if coef is None else np.asarray(coef, dtype=float)
    offered = max_wall_tilt(tool)
    if len(points) and tilts[1] > offered:
        raise SpecholoError(
            f"the views need wall tilts up to {math.degrees(tilts[1]):.1f} deg but the "
            f"{tool.radius:g} mm ball at {tool.depth:g} mm depth offers "
            f"{math.degrees(offered):.1f} deg; cut deeper or raise the viewer")
    if not len(points):
        tilts = (0.0, 0.0)
    relief = max(tilts[0] - RELIEF_MARGIN, 0.0)
    # a0 > 0: the groove point lies towards h (the inner wall serves: wall on the left
    # when going the way psi increases); a0 < 0 flips the traversal and the wall.
    side = np.where(coef[:, 0] >= 0, -1, 1).astype(np.int64) if len(points) else \
        np.zeros(0, dtype=np.int64)
    k = setup.samples
    psi = np.linspace(0.0, 2.0 * np.pi, k, endpoint=False)
    xy = groove_points(coef, np.broadcast_to(psi, (len(points), k)))  # (n, k, 2)
    flat = np.abs(points[:, 2]) < 1e-6
    keep = np.ones((len(points), k), dtype=bool) if visible is None else \
        np.asarray(visible, dtype=bool).reshape(len(points), k)
    verts: list[np.ndarray] = []
    sizes: list[int] = []
    owner: list[int] = []
    sides: list[int] = []
    whole = keep.all(axis=1) & ~flat
    # whole grooves in one go: k vertices and the first again to close the loop
    idx = np.flatnonzero(whole)
    closed = np.concatenate([xy[idx], xy[idx, :1]], axis=1)
    for i in np.flatnonzero(flat & keep.any(axis=1)):
        verts.append(points[i:i + 1, :2])
        sizes.append(1)
        owner.append(int(i))
        sides.append(int(side[i]))
    for j, run in _runs(xy, keep, np.flatnonzero(~whole & ~flat)):
        verts.append(run)
        sizes.append(len(run))
        owner.append(j)
        sides.append(int(side[j]))
    all_verts = np.concatenate([closed.reshape(-1, 2)] + verts) if len(verts) or len(idx) \
        else np.zeros((0, 2))
    all_sizes = np.concatenate([np.full(len(idx), k + 1, dtype=np.int64),
                                np.asarray(sizes, dtype=np.int64)])
    all_owner = np.concatenate([idx, np.asarray(owner, dtype=np.int64)])
    all_sides = np.concatenate([side[idx], np.asarray(sides, dtype=np.int64)])
    order = np.argsort(all_owner, kind="stable")
    starts = np.concatenate([[0], np.cumsum(all_sizes)])
    pieces = [all_verts[starts[j]:starts[j + 1]] for j in order]
    vertices = np.concatenate(pieces) if pieces else np.zeros((0, 2))
    offsets = np.concatenate([[0], np.cumsum(all_sizes[order])]).astype(np.int64)
    grooves = Grooves(vertices, np.zeros(len(vertices)), offsets, all_owner[order])
    return SpinDesign(setup, points, coef, side, grooves, all_sides[order], tilts, relief)


def _runs(xy: np.ndarray, keep: np.ndarray, rows: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """Kept runs of vertices of the cropped grooves, the loop's wrap joined."""
    out = []
    k = keep.shape[1]
    for i in rows:  # only grooves that occlusion crops
        mask = keep[i]
        if not mask.any():
            continue
        start = int(np.argmin(mask))  # a hidden vertex: runs never wrap past it
        order = (np.arange(k) + start) % k
        m = mask[order]
        edges = np.flatnonzero(np.diff(np.concatenate([[0], m.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            if b - a >= 2:
                out.append((int(i), xy[i, order[a:b]]))
    return out


def vertex_angles(coef: np.ndarray, setup: SpinSetup, eye: int) -> np.ndarray:
    """The plate angle (n, samples) at which each groove vertex glints for one
    eye (0 left, 1 right), radians in [0, 2 pi)."""
    k = setup.samples
    psi = np.linspace(0.0, 2.0 * np.pi, k, endpoint=False)
    phi = np.linspace(0.0, 2.0 * np.pi, setup.angles, endpoint=False)
    eyes = setup.eyes(phi)[eye]
    n = len(coef)
    out = np.zeros((n, k))
    for lo in range(0, n, 2048):
        c = coef[lo:lo + 2048]
        # psi of the glint at each fit angle, from the groove point it lands on
        x = np.zeros((len(c), len(phi), 3))
        x[..., :2] = groove_points(c, np.zeros((len(c), len(phi))))
        psi_j = np.zeros((len(c), len(phi)))
        for _ in range(4):
            psi_j = _psi(setup, x, eyes[None])
            x[..., :2] = groove_points(c, psi_j)
        # psi falls by one turn as phi rises by one; unwrap, then interpolate phi(psi)
        un = np.unwrap(psi_j, axis=1)
        for r in range(len(c)):
            u, f = un[r][::-1], phi[::-1]
            base = u[0]
            q = (psi - base) % (2.0 * np.pi) + base
            uu = np.concatenate([u, [u[0] + 2.0 * np.pi]])
            ff = np.concatenate([f, [f[0] - 2.0 * np.pi]])
            out[lo + r] = np.interp(q, uu, ff) % (2.0 * np.pi)
    return out


def max_wall_tilt(tool: Tool) -> float:
    """Steepest wall tilt (radians) a ball of radius R cut d deep offers: asin(w / 2R)."""
    r, d = tool.radius, tool.depth
    half = math.sqrt(max(2.0 * r * d - d * d, 0.0))
    return math.asin(min(half / r, 1.0))


def relief_grooves(design: SpinDesign, tool: Tool) -> tuple[Grooves, float]:
    """The relief cut that takes away the non-serving wall (``walls="one"``).

    A V-bit of :data:`RELIEF_ANGLE` runs along the groove's edge on the other
    side, deep enough that its inner face, nearly vertical, passes below the ball's
    wall wherever that wall is tilted more than ``design.relief_tilt``: what stays
    is the ball's floor (tilts too small to serve a view) and the V's face (too
    steep).

    Returns:
        The offset paths (dimples omitted) and the relief depth, mm.
    """
    g = design.grooves
    r, d = tool.radius, tool.depth
    half = math.sqrt(max(2.0 * r * d - d * d, 0.0))
    u0 = r * math.sin(design.relief_tilt)
    floor = d - (r - math.sqrt(r * r - u0 * u0))  # depth of the ball's wall at u0
    depth = floor + (half - u0) / math.tan(0.5 * RELIEF_ANGLE)
    keep = ~g.is_dot
    if not keep.any():
        return Grooves.empty(), depth
    sizes = g.path_sizes
    v = g.vertices
    idx = np.arange(len(v))
    start = np.repeat(g.offsets[:-1], sizes)
    end = np.repeat(g.offsets[1:] - 1, sizes)
    closed = np.repeat(np.linalg.norm(v[g.offsets[1:] - 1] - v[g.offsets[:-1]], axis=1)
                       < 1e-9, sizes)
    # neighbours along the path; a closed path's ends meet past its repeated vertex
    prev = np.where(idx > start, idx - 1, np.where(closed, end - 1, idx))
    nxt = np.where(idx < end, idx + 1, np.where(closed, start + 1, idx))
    t = v[nxt] - v[prev]
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
    left = np.stack([-t[:, 1], t[:, 0]], axis=1)
    # the serving wall is on the path's right (+1) or left (-1): cut the other edge
    side = np.repeat(design.path_side, sizes)
    off = v + (side * half)[:, None] * left
    path_of = np.repeat(np.arange(g.n_paths), sizes)
    mask = keep[path_of]
    new_sizes = sizes[keep]
    return Grooves(off[mask], np.zeros(int(mask.sum())),
                   np.concatenate([[0], np.cumsum(new_sizes)]).astype(np.int64),
                   g.stipple[keep]), depth


def classic_circles(points: np.ndarray, setup: SpinSetup) -> np.ndarray:
    """Coefficients (n, 2K+1) of the classic turntable grooves: circles about each
    stipple's foot, radius |z| cot(elevation), exact only for a distant viewer."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    coef = np.zeros((len(points), 2 * setup.harmonics + 1))
    coef[:, 0] = -points[:, 2] / math.tan(setup.elevation)
    coef[:, 1] = points[:, 0]
    coef[:, 2] = points[:, 1]
    return coef

"""Refraction holograms: a clear plate lit from behind, its front face engraved.

The plate (index n, acrylic by default) has its engraved front face at z = 0 and
a planar back face at z = -T; the light is behind it. A ray from the light
refracts into the plate at the back face, crosses it, and leaves through the
front optic toward the eye. Three models of the front optic:

- **single interface** (:meth:`~specholo.optics.surfaces.PointOptics.lens`): the
  light itself inside the medium; level sets of n |s - i| + sigma |s - p| are
  Cartesian ovals.
- **two surfaces, planar back** (:class:`TwoSurfaceOptics`), exact: by Fermat's
  principle the optical path from the light to a point s inside the plate is
  L(s) = min over b on the back face of |b - i| + n |s - b|, and
  grad L = n u(s - b) is the ray direction in the plate times n. Level sets of
  Phi(s) = L(s) + sigma |s - p| therefore satisfy normality exactly:
  -grad Phi = n u(b - s) + u(e - s) for eyes on sightlines through p.
- **the paper's approximation** (:func:`approximate_optics`): the rays inside
  the plate diverge from roughly one point (the centre of divergence), so the
  front face is the Cartesian oval n |s - c| + sigma |s - p| with the light's
  focus moved to c. For a point light on the axis and paraxial rays c is the
  light seen through the back face, n times as far behind it
  (:func:`paraxial_centre`); off axis the in-plate rays are astigmatic, and
  :func:`fitted_centre` takes the point nearest (least squares) to the rays
  that reach the optic. With a sun the rays inside stay parallel and the
  approximation is exact.

:func:`approximation_error` traces the exact rays through the approximate
surface and reports how far the glints move (angle, plate position, and the
apparent point seen in stereo).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from specholo.errors import SpecholoError
from specholo.optics.stereo import triangulate
from specholo.optics.surfaces import (
    ImplicitOptics,
    PointOptics,
    Source,
    refract,
    sightline_on_level,
)
from specholo.setup import ACRYLIC_INDEX as ACRYLIC_INDEX
from specholo.setup import ClearPlate as ClearPlate


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles (k,) between vectors a and b (k, 3), accurate near 0."""
    a, b = _unit(a), _unit(b)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def check_back_light(source: Source, plate: ClearPlate) -> None:
    """Refuse a light that is not behind the plate's back face."""
    if source.position is not None and not source.position[2] < plate.back_z:
        raise SpecholoError(f"the light must be behind the back face (z < {plate.back_z:g} mm), "
                            f"got z = {source.position[2]:g}")
    if source.direction is not None and not source.direction[2] < 0:
        raise SpecholoError(f"a sun lighting the plate from behind needs a direction with z < 0, "
                            f"got {source.direction.tolist()}")


def back_entry(source: Source, s: np.ndarray,
               plate: ClearPlate) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Light paths from the source through the back face to points inside the plate.

    Fermat's principle: the entry point b on the back face minimises
    |b - i| + n |s - b|, which is Snell's law at b. For a point light, b lies on
    the segment under i and s, at a distance r from i's foot where
    r / |b - i| = n (rho - r) / |s - b|; a safeguarded Newton solve finds it.

    Args:
        source: the light, behind the back face.
        s: (..., 3) points inside the plate (back_z < z), mm.
        plate: the plate.

    Returns:
        Optical path lengths L (...) in mm (for a sun, up to a constant), entry
        points b (..., 3), and unit ray directions in the plate (..., 3).
    """
    s = np.asarray(s, dtype=float)
    n = float(plate.index)
    zb = plate.back_z
    if source.position is None:
        sun = np.asarray(source.direction)
        d_in = -sun
        d = np.broadcast_to(refract(d_in, np.array([0.0, 0.0, 1.0]), 1.0, n), s.shape)
        # A plane wave: its optical path is n d.s plus a constant fixed on the back face.
        t = (s[..., 2] - zb) / d[..., 2]
        b = s - t[..., None] * d
        const = (-sun[2] - n * d[..., 2]) * zb
        return n * np.sum(d * s, axis=-1) + const, b, d.copy()
    i = np.asarray(source.position)
    a = zb - i[2]
    c = s[..., 2] - zb
    dxy = s[..., :2] - i[:2]
    rho = np.linalg.norm(dxy, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = n * rho * a / (c + n * a)  # the paraxial solution
        lo = np.zeros_like(rho)
        hi = rho.copy()
        for _ in range(60):
            big_a = np.sqrt(r * r + a * a)
            big_c = np.sqrt((rho - r) ** 2 + c * c)
            f = r / big_a - n * (rho - r) / big_c
            lo = np.where(f < 0, r, lo)
            hi = np.where(f > 0, r, hi)
            df = a * a / big_a**3 + n * c * c / big_c**3
            step = f / df
            r_new = r - step
            outside = ~((r_new > lo) & (r_new < hi))
            r_new = np.where(outside, 0.5 * (lo + hi), r_new)
            if np.all(np.abs(r_new - r) <= 1e-13 * (1.0 + rho)):
                r = r_new
                break
            r = r_new
        u = np.where(rho[..., None] > 0, dxy / rho[..., None], 0.0)
    b = np.concatenate([i[:2] + r[..., None] * u, np.full(rho.shape + (1,), zb)], axis=-1)
    length = np.linalg.norm(b - i, axis=-1) + n * np.linalg.norm(s - b, axis=-1)
    return length, b, _unit(s - b)


@dataclass(frozen=True, eq=False)
class TwoSurfaceOptics(ImplicitOptics):
    """Exact front optics of a plate with a planar back: Phi(s) = L(s) + sigma |s - p|.

    Attributes:
        points: (n, 3) virtual points p, mm.
        sigma: (n,) +1 for p in front of the plate, -1 behind the front face.
        source: the light, behind the back face.
        plate: the plate.
    """

    points: np.ndarray
    sigma: np.ndarray
    source: Source
    plate: ClearPlate

    def __post_init__(self) -> None:
        check_back_light(self.source, self.plate)
        pts = np.asarray(self.points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
            raise SpecholoError(f"points must be finite with shape (n, 3), got {pts.shape}")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "sigma", np.asarray(self.sigma, dtype=float))

    @classmethod
    def for_points(cls, points: np.ndarray, source: Source,
                   plate: ClearPlate) -> TwoSurfaceOptics:
        """sigma from each point's side of the front face."""
        points = np.asarray(points, dtype=float)
        return cls(points, np.where(points[:, 2] > 0.0, 1.0, -1.0), source, plate)

    def phi(self, s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        p = self._p(s, stipple, self.points)
        sigma = self._p(s, stipple, self.sigma)
        length, _, _ = back_entry(self.source, s, self.plate)
        return length + sigma * np.linalg.norm(s - p, axis=-1)

    def gradient(self, s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        p = self._p(s, stipple, self.points)
        sigma = self._p(s, stipple, self.sigma)
        _, _, d = back_entry(self.source, s, self.plate)
        return self.plate.index * d + sigma[..., None] * _unit(s - p)

    def sightline_point(self, eyes: np.ndarray, level: np.ndarray,
                        stipple: np.ndarray | None = None) -> np.ndarray:
        """Where the sightline from each eye through its p meets the level set (k, 3)."""
        eyes = np.asarray(eyes, dtype=float)
        idx = np.arange(len(self.points)) if stipple is None else np.asarray(stipple)
        return sightline_on_level(self, eyes, self.points[idx], self.sigma[idx], level, idx, 0.0)


def paraxial_centre(source: Source, plate: ClearPlate) -> np.ndarray:
    """Centre of divergence of paraxial rays: the light seen through the back face (3,).

    Raises:
        SpecholoError: for a sun (its rays stay parallel: use the sun itself).
    """
    check_back_light(source, plate)
    if source.position is None:
        raise SpecholoError("a sun has no centre of divergence (its rays stay parallel)")
    i = source.position
    a = plate.back_z - i[2]
    return np.array([i[0], i[1], plate.back_z - plate.index * a])


def fitted_centre(source: Source, plate: ClearPlate, region: np.ndarray) -> np.ndarray:
    """The point nearest, in least squares, to the in-plate rays reaching a region.

    Args:
        source: a point light behind the plate.
        plate: the plate.
        region: (m, 3) sample points of the optic (m >= 2, not all on one ray).

    Returns:
        (3,) centre of divergence, mm.
    """
    check_back_light(source, plate)
    if source.position is None:
        raise SpecholoError("a sun has no centre of divergence (its rays stay parallel)")
    region = np.asarray(region, dtype=float)
    _, _, d = back_entry(source, region, plate)
    proj = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    a = proj.sum(axis=0)
    rhs = np.einsum("kij,kj->i", proj, region)
    return np.linalg.solve(a, rhs)


def approximate_optics(points: np.ndarray, centre: np.ndarray,
                       plate: ClearPlate) -> PointOptics:
    """The paper's approximation: Cartesian ovals n |s - c| + sigma |s - p| (focus c)."""
    return PointOptics.lens(points, Source(position=np.asarray(centre, dtype=float)),
                            plate.index, 1.0)


@dataclass(frozen=True, eq=False)
class CentredOptics(ImplicitOptics):
    """The paper's approximation with a centre of divergence per stipple:
    phi_k(s) = n |s - c_k| + sigma_k |s - p_k| (Cartesian ovals with foci c_k, p_k).

    Attributes:
        points: (n, 3) virtual points p, mm.
        sigma: (n,) +1 for p in front of the plate, -1 behind the front face.
        centres: (n, 3) centres of divergence c, mm.
        index: the plate's refractive index n.
    """

    points: np.ndarray
    sigma: np.ndarray
    centres: np.ndarray
    index: float

    def phi(self, s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        p = self._p(s, stipple, self.points)
        c = self._p(s, stipple, self.centres)
        sigma = self._p(s, stipple, self.sigma)
        return (self.index * np.linalg.norm(s - c, axis=-1)
                + sigma * np.linalg.norm(s - p, axis=-1))

    def gradient(self, s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        p = self._p(s, stipple, self.points)
        c = self._p(s, stipple, self.centres)
        sigma = self._p(s, stipple, self.sigma)
        return self.index * _unit(s - c) + sigma[..., None] * _unit(s - p)


def exit_direction(optics: ImplicitOptics, source: Source, plate: ClearPlate,
                   s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
    """Directions (k, 3) in which the real light leaves the front optic at points s (k, 3)."""
    _, _, d = back_entry(source, s, plate)
    return refract(d, optics.gradient(s, stipple), plate.index, 1.0)


@dataclass(frozen=True)
class ApproximationError:
    """How far the paper's approximation moves a stipple's glints (lengths in mm).

    Attributes:
        light_distance: distance of the light from the back face's centre, mm.
        thickness: plate thickness, mm.
        depth: p_z of the stipple, mm.
        centre: "paraxial" or "fitted".
        max_tilt: largest angle between the approximate and the exact surface
            normals at the designed glints, radians.
        max_angle: largest angle between the real exit ray at the designed glint
            and the direction to the eye, radians.
        p95_offset: 95th percentile of the distance the glint moves on the
            optic (where the real light reaches the eye), mm.
        max_offset: the largest such distance, mm.
        p95_error: 95th percentile over the stereo pairs of the apparent point's
            distance from p, mm.
        max_error: the worst pair's.
    """

    light_distance: float
    thickness: float
    depth: float
    centre: str
    max_tilt: float
    max_angle: float
    p95_offset: float
    max_offset: float
    p95_error: float
    max_error: float


def real_glints(optics: ImplicitOptics, level: np.ndarray, source: Source, plate: ClearPlate,
                eyes: np.ndarray, start: np.ndarray, stipple: np.ndarray,
                iterations: int = 20, step: float = 1e-4) -> np.ndarray:
    """Where on a front optic the real light reaches each eye.

    Newton's method over the plate position (x, y) of a point on the level set
    (its height solved at each step): the exit ray must point at the eye.

    Args:
        optics: the front optic. level: (k,) its level per eye.
        source, plate: the light and the plate.
        eyes: (k, 3) eyes. start: (k, 3) first guesses (the designed glints).
        stipple: (k,) stipple per eye.
        iterations: Newton steps.
        step: finite-difference step, mm.

    Returns:
        (k, 3) glint points; NaN where none was found.
    """
    xy = np.asarray(start, dtype=float)[:, :2].copy()

    def residual(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        z = optics.height(q, level, stipple, z0=0.0)
        s = np.concatenate([q, z[:, None]], axis=1)
        t = exit_direction(optics, source, plate, s, stipple)
        want = _unit(eyes - s)
        # The exit ray's miss, in two directions across the line of sight.
        a = _unit(np.cross(want, np.array([0.0, 1.0, 0.0])))
        b = np.cross(want, a)
        return np.stack([np.sum(t * a, axis=1), np.sum(t * b, axis=1)], axis=1), s

    r, s = residual(xy)
    for _ in range(iterations):
        rx, _ = residual(xy + np.array([step, 0.0]))
        ry, _ = residual(xy + np.array([0.0, step]))
        jac = np.stack([(rx - r) / step, (ry - r) / step], axis=2)
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        with np.errstate(invalid="ignore", divide="ignore"):
            delta = np.stack([jac[:, 1, 1] * r[:, 0] - jac[:, 0, 1] * r[:, 1],
                              jac[:, 0, 0] * r[:, 1] - jac[:, 1, 0] * r[:, 0]], axis=1)
            delta /= det[:, None]
        delta = np.where(np.isfinite(delta), delta, 0.0)
        # Damped: halve a step until the miss shrinks (the level sets can be steep).
        alpha = np.ones(len(xy))
        norm = np.linalg.norm(r, axis=1)
        for _ in range(12):
            trial = xy - alpha[:, None] * delta
            r_new, s_new = residual(trial)
            better = np.linalg.norm(r_new, axis=1) < norm
            if better.all():
                break
            alpha = np.where(better, alpha, 0.5 * alpha)
        xy = np.where(better[:, None], trial, xy)
        r = np.where(better[:, None], r_new, r)
        s = np.where(better[:, None], s_new, s)
        if np.all(np.abs(alpha[:, None] * delta) < 1e-11):
            break
    miss = np.linalg.norm(r, axis=1)
    s[~(miss < 1e-8)] = np.nan
    return s


def approximation_error(point: np.ndarray, source: Source, plate: ClearPlate,
                        eyes_left: np.ndarray, eyes_right: np.ndarray,
                        centre: str = "fitted") -> ApproximationError:
    """Measure the paper's approximation against the exact two-surface optic.

    Each eye's glint is designed where its sightline through p crosses the
    front face, on the level set through that point (as a ridged optic's facet
    would be). There the approximate surface's normal is compared with the
    exact one, the real light (refracted at the back face, then at the
    approximate front surface) is traced, the point of the approximate level
    set where it really reaches the eye is found, and each eye pair's two real
    glints are triangulated.

    Args:
        point: (3,) the stipple p.
        source: a point light behind the plate (or a sun: the error is then zero).
        plate: the plate.
        eyes_left, eyes_right: (k, 3) stereo pairs.
        centre: "paraxial" or "fitted" centre of divergence.

    Returns:
        The errors.
    """
    if centre not in ("paraxial", "fitted"):
        raise SpecholoError(f"centre must be 'paraxial' or 'fitted', got {centre!r}")
    point = np.asarray(point, dtype=float)
    pts = point[None]
    exact = TwoSurfaceOptics.for_points(pts, source, plate)
    eyes = np.concatenate([eyes_left, eyes_right])
    k = len(eyes)
    idx = np.zeros(k, dtype=np.int64)
    t = -point[2] / (eyes[:, 2] - point[2])
    crossing = point + t[:, None] * (eyes - point)
    crossing[:, 2] = 0.0
    if source.position is None:
        approx: ImplicitOptics = exact
    else:
        c = (paraxial_centre(source, plate) if centre == "paraxial"
             else fitted_centre(source, plate, crossing))
        approx = approximate_optics(pts, c, plate)
    level = approx.phi(crossing, idx)
    n_exact = _unit(exact.gradient(crossing, idx))
    n_approx = _unit(approx.gradient(crossing, idx))
    tilt = _angle(n_exact, n_approx)
    t_exit = exit_direction(approx, source, plate, crossing, idx)
    angle = _angle(t_exit, eyes - crossing)
    real = real_glints(approx, level, source, plate, eyes, crossing, idx)
    offset = np.linalg.norm(real - crossing, axis=1)
    h = len(eyes_left)
    apparent, _ = triangulate(eyes_left, real[:h], eyes_right, real[h:])
    err = np.linalg.norm(apparent - point, axis=1)
    distance = (float(np.linalg.norm(source.position - np.array([0.0, 0.0, plate.back_z])))
                if source.position is not None else math.inf)
    return ApproximationError(
        light_distance=distance, thickness=float(plate.thickness), depth=float(point[2]),
        centre=centre, max_tilt=float(np.nanmax(tilt)), max_angle=float(np.nanmax(angle)),
        p95_offset=float(np.nanpercentile(offset, 95)),
        max_offset=float(np.nanmax(offset)), p95_error=float(np.nanpercentile(err, 95)),
        max_error=float(np.nanmax(err)))


def back_light(distance: float, elevation: float, plate: ClearPlate) -> Source:
    """A point light ``distance`` mm behind the back face's centre, ``elevation``
    radians above the plate's axis (behind and above the plate)."""
    if not (math.isfinite(distance) and distance > 0):
        raise SpecholoError(f"light distance must be a positive number of mm, got {distance:g}")
    if not (math.isfinite(elevation) and abs(elevation) < 0.5 * math.pi):
        raise SpecholoError(f"light elevation must be within (-90, 90) degrees, got "
                            f"{math.degrees(elevation):g}")
    return Source(position=np.array([0.0, distance * math.sin(elevation),
                                     plate.back_z - distance * math.cos(elevation)]))


def approximation_table(distances: tuple[float, ...] = (150.0, 300.0, 600.0, 1200.0),
                        thicknesses: tuple[float, ...] = (3.0, 6.0, 10.0),
                        depths: tuple[float, ...] = (-20.0, -40.0, -60.0),
                        elevation: float = math.radians(30.0),
                        eyes: tuple[np.ndarray, np.ndarray] | None = None,
                        index: float = ACRYLIC_INDEX,
                        offset_xy: tuple[float, float] = (15.0, 10.0),
                        ) -> list[ApproximationError]:
    """The approximation's error over a grid of configurations, both centres.

    Args:
        distances: light distances behind the back face, mm.
        thicknesses: plate thicknesses, mm.
        depths: stipple depths p_z, mm.
        elevation: the light's angle above the axis, radians.
        eyes: stereo pairs (left (k, 3), right (k, 3)); default heads at 600 mm
            over +-30 degrees azimuth and +-15 degrees elevation.
        index: plate index.
        offset_xy: the stipple's (x, y), mm.

    Returns:
        One row per configuration and centre.
    """
    if eyes is None:
        eyes = _default_pairs()
    rows = []
    for thickness in thicknesses:
        plate = ClearPlate(thickness, index)
        for distance in distances:
            source = back_light(distance, elevation, plate)
            for depth in depths:
                p = np.array([offset_xy[0], offset_xy[1], depth])
                for centre in ("paraxial", "fitted"):
                    rows.append(approximation_error(p, source, plate, eyes[0], eyes[1], centre))
    return rows


def _default_pairs() -> tuple[np.ndarray, np.ndarray]:
    az, el = np.meshgrid(np.radians(np.arange(-30.0, 31.0, 10.0)),
                         np.radians(np.arange(-15.0, 16.0, 7.5)))
    az, el = az.ravel(), el.ravel()
    head = 600.0 * np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], 1)
    tangent = np.stack([np.cos(az), np.zeros_like(az), -np.sin(az)], axis=1)
    return head - 32.0 * tangent, head + 32.0 * tangent

"""Single-point optics as level sets of one implicit function (Brand, eq. 1).

For a virtual point p lit by a light i, every level set of

    phi(s) = eta1 |s - i| + sigma eta2 |s - p|        (sun: -eta1 l.s + sigma eta2 |s - p|)

satisfies the normality constraint for every eye on every sightline through p:
its gradient is minus the normality vector h = eta1 u(i - s) + eta2 u(e - s),
because u(e - s) = -sigma u(s - p) on such a sightline. sigma = +1 when p lies
between the eye and s (p in front of the optic), -1 when s lies between the eye
and p (p behind it). The level sets are

- prolate ellipsoids with foci i and p (mirror, sigma = +1),
- hyperboloid sheets with foci i and p (mirror, sigma = -1),
- paraboloids with focus p and axis l (mirror, sun),
- Cartesian ovals, revolute quartics with foci i and p (refraction, eta1 != eta2;
  with a sun they reduce to conics of eccentricity eta1 / eta2),

and two degenerate cases: p on the host surface (the optic shrinks to a fixed
dot at p) and p at the light (spheres about i).

Everything is vectorised over stipples and sample points: ``s`` has shape
(n, ..., 3) with the stipple on the first axis, or any shape with an explicit
``stipple`` index array broadcast against it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from specholo.errors import SpecholoError
from specholo.setup import Light


class Kind(IntEnum):
    """What the level sets of a stipple's phi are."""

    ELLIPSOID = 0
    HYPERBOLOID = 1
    PARABOLOID = 2
    CARTESIAN_OVAL = 3
    DOT = 4
    SPHERE = 5
    #: Refraction through a clear plate's planar back and the front optic: level
    #: sets of the Fermat path length (:class:`~specholo.optics.refraction.TwoSurfaceOptics`).
    TWO_SURFACE = 6


#: Newton steps of the level-set solvers (they converge in 3-5 on these optics).
MAX_NEWTON = 40


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass(frozen=True, eq=False)
class Source:
    """A light anywhere: a point, or collimated (a sun) from a direction.

    Attributes:
        position: (3,) point light in mm, or None for a sun.
        direction: (3,) unit vector toward a sun (None for a point light).
    """

    position: np.ndarray | None = None
    direction: np.ndarray | None = None

    def __post_init__(self) -> None:
        if (self.position is None) == (self.direction is None):
            raise SpecholoError("a light needs exactly one of a position and a direction")
        if self.position is not None:
            pos = np.asarray(self.position, dtype=float)
            if pos.shape != (3,) or not np.all(np.isfinite(pos)):
                raise SpecholoError(f"light position must be 3 finite numbers, got {pos}")
            object.__setattr__(self, "position", pos)
        else:
            d = np.asarray(self.direction, dtype=float)
            norm = float(np.linalg.norm(d)) if d.shape == (3,) else 0.0
            if not (math.isfinite(norm) and norm > 0):
                raise SpecholoError(f"light direction must be a finite nonzero 3-vector, got {d}")
            object.__setattr__(self, "direction", d / norm)

    @classmethod
    def from_light(cls, light: Light) -> Source:
        """The source of a :class:`~specholo.setup.Light`."""
        if light.distance is None:
            return cls(direction=light.direction)
        return cls(position=light.position)

    @property
    def is_point(self) -> bool:
        """True for a point light."""
        return self.position is not None

    def towards(self, s: np.ndarray) -> np.ndarray:
        """Unit vectors (..., 3) from points s (..., 3) toward the light."""
        s = np.asarray(s, dtype=float)
        if self.position is None:
            return np.broadcast_to(np.asarray(self.direction), s.shape).copy()
        return _unit(self.position - s)

    def path(self, s: np.ndarray) -> np.ndarray:
        """The light's term of phi (..., ): |s - i|, or -l.s for a sun."""
        s = np.asarray(s, dtype=float)
        if self.position is None:
            return -(s @ self.direction)
        return np.linalg.norm(s - self.position, axis=-1)


def as_source(light: Light | Source) -> Source:
    """A :class:`Source` from either kind of light."""
    return light if isinstance(light, Source) else Source.from_light(light)


def refract(direction: np.ndarray, normal: np.ndarray, eta1: float,
            eta2: float) -> np.ndarray:
    """Snell's law in vector form.

    Args:
        direction: (..., 3) unit propagation directions in the medium of index eta1.
        normal: (..., 3) surface normals (any length, either orientation).
        eta1: index on the incident side.
        eta2: index on the transmitted side.

    Returns:
        (..., 3) unit transmitted directions; NaN where the ray is totally reflected.
    """
    d = np.asarray(direction, dtype=float)
    n = _unit(np.asarray(normal, dtype=float))
    c = -np.sum(d * n, axis=-1, keepdims=True)
    n = np.where(c < 0, -n, n)  # the normal faces the incoming ray
    c = np.abs(c)
    r = eta1 / eta2
    k = 1.0 - r * r * (1.0 - c * c)
    with np.errstate(invalid="ignore"):
        t = r * d + (r * c - np.sqrt(k)) * n
    return np.where(k >= 0, t, np.nan)


class ImplicitOptics:
    """An optic given by an implicit function phi whose level sets are the surfaces.

    Subclasses provide :meth:`phi` and :meth:`gradient`; the solvers here find
    where a level set meets vertical lines (height fields) and sightlines.
    The gradient is minus the normality vector: for a mirror lit from the
    front phi decreases toward the viewer (+z).
    """

    points: np.ndarray
    #: (n,) +1 for p in front of the optic, -1 behind it.
    sigma: np.ndarray

    def phi(self, s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
        """phi at points s (..., 3) (see the module docstring for the shapes)."""
        raise NotImplementedError

    def gradient(self, s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
        """grad phi (..., 3) at points s (..., 3)."""
        raise NotImplementedError

    def _p(self, s: np.ndarray, stipple: np.ndarray | None, values: np.ndarray) -> np.ndarray:
        """Per-stipple values (n, ...) broadcast against samples s (..., 3)."""
        if stipple is None:
            n = len(self.points)
            if s.ndim < 2 or s.shape[0] != n:
                raise SpecholoError(f"samples need the stipple on their first axis ({n}), "
                                    f"got shape {s.shape}")
            return values.reshape((n,) + (1,) * (s.ndim - 2) + values.shape[1:])
        return values[np.asarray(stipple, dtype=np.int64)]

    def height(self, xy: np.ndarray, level: np.ndarray, stipple: np.ndarray | None = None,
               z0: float | np.ndarray = 0.0, tol: float = 1e-12) -> np.ndarray:
        """Heights z where the level set phi = level crosses vertical lines.

        Newton's method from z0 on phi(x, y, z) - level; phi is monotone in z
        near the host (d phi / dz = -h_z, and h_z < 0 would face the optic
        away from the eyes).

        Args:
            xy: (..., 2) plate positions, mm.
            level: (...) levels (broadcast).
            stipple: stipple index per sample, or None (first axis is the stipple).
            z0: starting height(s), mm.
            tol: convergence tolerance on z, mm, per mm of |level| above 1
                (phi is a sum of distances: rounding grows with it).

        Returns:
            (...) heights, mm; NaN where Newton does not converge.
        """
        xy = np.asarray(xy, dtype=float)
        z = np.broadcast_to(np.asarray(z0, dtype=float), xy.shape[:-1]).copy()
        level = np.broadcast_to(np.asarray(level, dtype=float), z.shape)
        done = np.zeros(z.shape, dtype=bool)
        for _ in range(MAX_NEWTON):
            s = np.concatenate([xy, z[..., None]], axis=-1)
            g = self.phi(s, stipple) - level
            dz = self.gradient(s, stipple)[..., 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(done, 0.0, g / dz)
            z = z - step
            done |= np.abs(step) <= tol * np.maximum(1.0, np.abs(level))
            if done.all():
                break
        return np.where(done & np.isfinite(z), z, np.nan)

    def line_level(self, origin: np.ndarray, direction: np.ndarray, level: np.ndarray,
                   stipple: np.ndarray | None, t0: np.ndarray,
                   tol: float = 1e-12) -> np.ndarray:
        """Parameters t where origin + t direction meets the level set phi = level.

        Args:
            origin: (..., 3) line origins. direction: (..., 3) (any length).
            level: (...) levels. stipple: as in :meth:`phi`. t0: (...) first guesses.
            tol: tolerance on t times |direction|, mm, per mm of |level| above 1.

        Returns:
            (...) parameters; NaN where Newton does not converge.
        """
        origin = np.asarray(origin, dtype=float)
        direction = np.asarray(direction, dtype=float)
        t = np.array(np.broadcast_to(t0, origin.shape[:-1]), dtype=float)
        length = np.linalg.norm(direction, axis=-1)
        done = np.zeros(t.shape, dtype=bool)
        for _ in range(MAX_NEWTON):
            s = origin + t[..., None] * direction
            g = self.phi(s, stipple) - level
            dg = np.sum(self.gradient(s, stipple) * direction, axis=-1)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(done, 0.0, g / dg)
            t = t - step
            done |= np.abs(step) * length <= tol * np.maximum(1.0, np.abs(level))
            if done.all():
                break
        return np.where(done & np.isfinite(t), t, np.nan)


@dataclass(frozen=True, eq=False)
class PointOptics(ImplicitOptics):
    """The single-point optics of n stipples: phi_k(s) = eta1 |s - i| + sigma_k eta2 |s - p_k|.

    Attributes:
        points: (n, 3) virtual points p, mm.
        sigma: (n,) +1 (p in front of the optic) or -1 (behind).
        source: the light.
        eta1: index on the light's side (1 for a mirror).
        eta2: index on the eye's side (1 for a mirror).
    """

    points: np.ndarray
    sigma: np.ndarray
    source: Source
    eta1: float = 1.0
    eta2: float = 1.0

    def __post_init__(self) -> None:
        pts = _points(self.points)
        sigma = np.asarray(self.sigma, dtype=float)
        if sigma.shape != (len(pts),) or not np.all(np.abs(sigma) == 1.0):
            raise SpecholoError(f"sigma must be +1 or -1 per point, got {sigma[:5]}")
        for name in ("eta1", "eta2"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v > 0):
                raise SpecholoError(f"{name} must be a positive refractive index, got {v:g}")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "sigma", sigma)

    @classmethod
    def mirror(cls, points: np.ndarray, light: Light | Source,
               host_z: float = 0.0) -> PointOptics:
        """Reflection optics of points over a flat host z = host_z (sigma from p's side)."""
        points = _points(points)
        return cls(points, _side(points, host_z), as_source(light))

    @classmethod
    def lens(cls, points: np.ndarray, source: Source, eta1: float, eta2: float = 1.0,
             host_z: float = 0.0) -> PointOptics:
        """Single-interface refraction: light in a medium of index eta1, eye in eta2."""
        points = _points(points)
        return cls(points, _side(points, host_z), source, eta1, eta2)

    def phi(self, s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        p = self._p(s, stipple, self.points)
        sigma = self._p(s, stipple, self.sigma)
        return self.eta1 * self.source.path(s) + sigma * self.eta2 * np.linalg.norm(s - p,
                                                                                   axis=-1)

    def gradient(self, s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        p = self._p(s, stipple, self.points)
        sigma = self._p(s, stipple, self.sigma)
        return -self.eta1 * self.source.towards(s) + (sigma * self.eta2)[..., None] * _unit(s - p)

    def normality(self, s: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        """h = eta1 u(i - s) + eta2 u(e - s) at points s (..., 3) for eyes (..., 3)."""
        s = np.asarray(s, dtype=float)
        return self.eta1 * self.source.towards(s) + self.eta2 * _unit(np.asarray(eyes) - s)

    def kinds(self, host_z: float = 0.0, tol: float = 1e-9) -> np.ndarray:
        """The kind of each stipple's level sets.

        Args:
            host_z: height of the flat host, mm.
            tol: distance within which p counts as on the host or at the light, mm.

        Returns:
            (n,) int8 :class:`Kind` values.
        """
        p = self.points
        kind = np.where(self.sigma > 0, Kind.ELLIPSOID, Kind.HYPERBOLOID).astype(np.int8)
        if not self.source.is_point:
            kind[:] = Kind.PARABOLOID
        if self.eta1 != self.eta2:
            kind[:] = Kind.CARTESIAN_OVAL
        if self.source.position is not None:
            kind[np.linalg.norm(p - self.source.position, axis=1) <= tol] = Kind.SPHERE
        kind[np.abs(p[:, 2] - host_z) <= tol] = Kind.DOT
        return kind

    def sightline_point(self, eyes: np.ndarray, level: np.ndarray,
                        stipple: np.ndarray | None = None, host_z: float = 0.0) -> np.ndarray:
        """Where the sightline from each eye through its p meets the level set.

        The solution is searched on the side of p the optic serves: between p
        and the eye for sigma = -1, beyond p for sigma = +1.

        Args:
            eyes: (k, 3) eye positions. level: (k,) levels.
            stipple: (k,) stipple per eye, or None when k = n (one eye per stipple).
            host_z: height of the host, where the search starts.

        Returns:
            (k, 3) points; NaN rows where the sightline misses the level set.
        """
        eyes = np.asarray(eyes, dtype=float)
        idx = np.arange(len(self.points)) if stipple is None else np.asarray(stipple)
        p = self.points[idx]
        sigma = self.sigma[idx]
        return sightline_on_level(self, eyes, p, sigma, level, idx, host_z)


def _points(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise SpecholoError(f"points must be finite with shape (n, 3), got {pts.shape}")
    return pts


def _side(points: np.ndarray, host_z: float) -> np.ndarray:
    """sigma of each point: +1 in front of the host (toward the viewer), -1 behind or on it."""
    return np.where(points[:, 2] > host_z, 1.0, -1.0)


def sightline_on_level(optics: ImplicitOptics, eyes: np.ndarray, p: np.ndarray,
                       sigma: np.ndarray, level: np.ndarray, idx: np.ndarray,
                       host_z: float) -> np.ndarray:
    """Where sightlines from eyes (k, 3) through points p (k, 3) meet level sets.

    Newton's method along each line from its crossing with z = host_z; the
    point must lie between p and the eye for sigma = -1 and beyond p for +1.

    Args:
        optics: the optic (its stipples indexed by idx (k,)).
        eyes, p: (k, 3). sigma: (k,). level: (k,) levels. host_z: host height, mm.

    Returns:
        (k, 3) points, NaN rows where the sightline misses the level set.
    """
    d = eyes - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (host_z - p[:, 2]) / d[:, 2]
    t = optics.line_level(p, d, np.asarray(level, dtype=float), idx, t0)
    ok = np.where(sigma < 0, (t > 0) & (t < 1), t < 0)
    s = p + t[:, None] * d
    s[~ok] = np.nan
    return s

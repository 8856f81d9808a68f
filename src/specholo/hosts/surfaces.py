"""Host surfaces in the plate frame: planes, cylinders, spheres, height fields,
meshes and hosts made of several panels.

Every host answers the same three questions, vectorised over many points or
rays, all lengths in mm:

- :meth:`Host.intersect`: where rays first meet the surface, with the outward
  normal there (toward the viewer's side) and a ``valid`` mask;
- :meth:`Host.normal`: the outward unit normal N(s) at points on the surface;
- :meth:`Host.project`: the surface point nearest a point close to it.

Each host passes through the origin with N = +z there, so a curved host and the
flat plate of the other designs share the frame (x right, y up, z toward the
viewer). ``part`` numbers the separate pieces of a host (panels): a groove never
crosses from one to another.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from specholo.errors import SpecholoError

#: Rays start this far back along their direction so a point on the surface
#: finds itself (mm).
_EPS = 1e-9


@dataclass(frozen=True)
class Hit:
    """First intersections of n rays with a host.

    Attributes:
        point: (n, 3) hit points, mm (NaN where not valid).
        normal: (n, 3) outward unit normals there.
        t: (n,) ray parameters (distance in units of the direction's length).
        part: (n,) which piece of the host was hit (0 for one-piece hosts).
        valid: (n,) bool, the ray met the host.
    """

    point: np.ndarray
    normal: np.ndarray
    t: np.ndarray
    part: np.ndarray
    valid: np.ndarray


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise SpecholoError(f"host {name} must be a positive number of mm, got {value!r}")
    return v


def _rays(origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    o = np.asarray(origins, dtype=float).reshape(-1, 3)
    d = np.asarray(directions, dtype=float).reshape(-1, 3)
    o, d = np.broadcast_arrays(o, d)
    return np.array(o), np.array(d)


def _miss(n: int) -> Hit:
    nan = np.full((n, 3), np.nan)
    return Hit(nan, nan.copy(), np.full(n, np.nan), np.zeros(n, dtype=np.int64),
               np.zeros(n, dtype=bool))


class Host(Protocol):
    """What every host surface provides (see the module notes)."""

    @property
    def kind(self) -> str:
        """The host's name ("plane", "cylinder", ...)."""
        ...

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> Hit:
        """First hits (t > 0) of rays origins + t directions, each (n, 3)."""
        ...

    def normal(self, points: np.ndarray) -> np.ndarray:
        """Outward unit normals (n, 3) at points (n, 3) on the surface."""
        ...

    def project(self, points: np.ndarray) -> np.ndarray:
        """Nearest surface points (n, 3) to points (n, 3) close to the surface."""
        ...

    def part(self, points: np.ndarray) -> np.ndarray:
        """Which piece (n,) of the host each surface point lies on."""
        ...

    def describe(self) -> dict[str, Any]:
        """The host's settings, for ``hologram.json``."""
        ...


def blocked(host: Host, points: np.ndarray, targets: np.ndarray,
            directional: bool = False) -> np.ndarray:
    """Whether the host itself hides targets from points on its surface.

    Args:
        host: the host.
        points: (n, 3) points on the surface.
        targets: (n, 3) positions (eyes, a point light), or unit directions (a sun)
            when ``directional``.
        directional: targets are directions to infinity.

    Returns:
        (n,) bool: the way out from the point is blocked (by the host, or because
        the target is behind the surface there).
    """
    points = np.asarray(points, dtype=float)
    targets = np.broadcast_to(np.asarray(targets, dtype=float), points.shape)
    n = host.normal(points)
    d = targets if directional else targets - points
    behind = np.sum(d * n, axis=1) <= 0
    start = points + 1e-6 * n
    hit = host.intersect(start, d)
    reach = np.inf if directional else 1.0
    return behind | (hit.valid & (hit.t < reach))


@dataclass(frozen=True)
class Plane:
    """The flat plate z = 0 (optionally bounded to width x height about the origin)."""

    width: float = math.inf
    height: float = math.inf
    kind: str = field(default="plane", init=False)

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> Hit:
        o, d = _rays(origins, directions)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -o[:, 2] / d[:, 2]
        p = o + t[:, None] * d
        p[:, 2] = 0.0
        ok = (np.isfinite(t) & (t > -_EPS) & (np.abs(p[:, 0]) <= 0.5 * self.width)
              & (np.abs(p[:, 1]) <= 0.5 * self.height))
        normal = np.broadcast_to(np.array([0.0, 0.0, 1.0]), p.shape).copy()
        p[~ok] = np.nan
        return Hit(p, normal, np.where(ok, t, np.nan), np.zeros(len(p), np.int64), ok)

    def normal(self, points: np.ndarray) -> np.ndarray:
        return np.broadcast_to(np.array([0.0, 0.0, 1.0]),
                               np.asarray(points).reshape(-1, 3).shape).copy()

    def project(self, points: np.ndarray) -> np.ndarray:
        q = np.array(points, dtype=float).reshape(-1, 3)
        q[:, 2] = 0.0
        return q

    def part(self, points: np.ndarray) -> np.ndarray:
        return np.zeros(len(np.asarray(points).reshape(-1, 3)), dtype=np.int64)

    def describe(self) -> dict[str, Any]:
        return {"kind": "plane", "width": _finite_or_none(self.width),
                "height": _finite_or_none(self.height)}


def _finite_or_none(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


@dataclass(frozen=True)
class Cylinder:
    """A cylinder (a cup, a bangle) with a vertical axis, its front at the origin.

    The axis is the line x = 0, z = -radius; the surface spans |y| <= height / 2
    and faces outward (convex toward the viewer).

    Attributes:
        radius: cylinder radius, mm.
        height: axial extent, mm.
    """

    radius: float = 40.0
    height: float = 80.0
    kind: str = field(default="cylinder", init=False)

    def __post_init__(self) -> None:
        _positive("radius", self.radius)
        _positive("height", self.height)

    @property
    def axis_z(self) -> float:
        return -self.radius

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> Hit:
        o, d = _rays(origins, directions)
        r = self.radius
        ox, oz = o[:, 0], o[:, 2] - self.axis_z
        dx, dz = d[:, 0], d[:, 2]
        a = dx * dx + dz * dz
        b = 2.0 * (ox * dx + oz * dz)
        c = ox * ox + oz * oz - r * r
        disc = b * b - 4.0 * a * c
        with np.errstate(invalid="ignore", divide="ignore"):
            sq = np.sqrt(disc)
            t1 = (-b - sq) / (2.0 * a)
            t2 = (-b + sq) / (2.0 * a)
        t = np.where(t1 > -_EPS, t1, t2)  # the entry when outside, else the exit
        p = o + t[:, None] * d
        ok = (disc >= 0) & (a > 0) & (t > -_EPS) & (np.abs(p[:, 1]) <= 0.5 * self.height)
        p[~ok] = np.nan
        return Hit(p, self.normal(p), np.where(ok, t, np.nan),
                   np.zeros(len(p), np.int64), ok)

    def normal(self, points: np.ndarray) -> np.ndarray:
        q = np.asarray(points, dtype=float).reshape(-1, 3)
        v = np.stack([q[:, 0], np.zeros(len(q)), q[:, 2] - self.axis_z], axis=1)
        return _unit(v)

    def project(self, points: np.ndarray) -> np.ndarray:
        q = np.asarray(points, dtype=float).reshape(-1, 3)
        n = self.normal(q)
        out = np.array([0.0, 0.0, self.axis_z]) + self.radius * n
        out[:, 1] = q[:, 1]
        return out

    def part(self, points: np.ndarray) -> np.ndarray:
        return np.zeros(len(np.asarray(points).reshape(-1, 3)), dtype=np.int64)

    def angle(self, points: np.ndarray) -> np.ndarray:
        """Angle (n,) about the axis from the front (+z), radians, positive toward +x."""
        q = np.asarray(points, dtype=float).reshape(-1, 3)
        return np.arctan2(q[:, 0], q[:, 2] - self.axis_z)

    def describe(self) -> dict[str, Any]:
        return {"kind": "cylinder", "radius": self.radius, "height": self.height,
                "axis": "y", "axis_z": self.axis_z}


@dataclass(frozen=True)
class Sphere:
    """A sphere (a bowl's outside, a globe) centred at (0, 0, -radius)."""

    radius: float = 50.0
    kind: str = field(default="sphere", init=False)

    def __post_init__(self) -> None:
        _positive("radius", self.radius)

    @property
    def centre(self) -> np.ndarray:
        return np.array([0.0, 0.0, -self.radius])

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> Hit:
        o, d = _rays(origins, directions)
        oc = o - self.centre
        a = np.sum(d * d, axis=1)
        b = 2.0 * np.sum(oc * d, axis=1)
        c = np.sum(oc * oc, axis=1) - self.radius**2
        disc = b * b - 4.0 * a * c
        with np.errstate(invalid="ignore", divide="ignore"):
            sq = np.sqrt(disc)
            t1 = (-b - sq) / (2.0 * a)
            t2 = (-b + sq) / (2.0 * a)
        t = np.where(t1 > -_EPS, t1, t2)
        p = o + t[:, None] * d
        ok = (disc >= 0) & (a > 0) & (t > -_EPS)
        p[~ok] = np.nan
        return Hit(p, self.normal(p), np.where(ok, t, np.nan),
                   np.zeros(len(p), np.int64), ok)

    def normal(self, points: np.ndarray) -> np.ndarray:
        return _unit(np.asarray(points, dtype=float).reshape(-1, 3) - self.centre)

    def project(self, points: np.ndarray) -> np.ndarray:
        return self.centre + self.radius * self.normal(points)

    def part(self, points: np.ndarray) -> np.ndarray:
        return np.zeros(len(np.asarray(points).reshape(-1, 3)), dtype=np.int64)

    def describe(self) -> dict[str, Any]:
        return {"kind": "sphere", "radius": self.radius}


class HeightField:
    """Any smooth height field z = f(x, y) over a rectangle, from samples.

    The samples are interpolated by a bicubic spline (scipy), so normals are
    continuous. Rays are intersected by Newton's method from the plane z = 0.

    Args:
        x: (nx,) increasing sample abscissae, mm.
        y: (ny,) increasing sample ordinates, mm.
        z: (ny, nx) heights, mm (0 at the origin for the shared frame).
    """

    kind = "heightfield"

    def __init__(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> None:
        from scipy.interpolate import RectBivariateSpline

        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        z = np.asarray(z, dtype=float)
        if x.ndim != 1 or y.ndim != 1 or z.shape != (len(y), len(x)):
            raise SpecholoError(
                f"height field needs x (nx,), y (ny,) and z (ny, nx); got {x.shape}, "
                f"{y.shape}, {z.shape}")
        if len(x) < 4 or len(y) < 4:
            raise SpecholoError("height field needs at least 4 x 4 samples")
        if not (np.all(np.diff(x) > 0) and np.all(np.diff(y) > 0)):
            raise SpecholoError("height field x and y must be strictly increasing")
        if not (np.isfinite(x).all() and np.isfinite(y).all() and np.isfinite(z).all()):
            raise SpecholoError("height field has NaN or infinite values")
        self.x, self.y, self.z = x, y, z
        self._spline = RectBivariateSpline(y, x, z, kx=3, ky=3)

    @classmethod
    def from_function(cls, fn: Any, width: float, height: float,
                      step: float = 1.0) -> HeightField:
        """Sample z = fn(x, y) (numpy-vectorised) over width x height about the origin."""
        _positive("width", width)
        _positive("height", height)
        nx = max(int(math.ceil(width / step)) + 1, 4)
        ny = max(int(math.ceil(height / step)) + 1, 4)
        x = np.linspace(-0.5 * width, 0.5 * width, nx)
        y = np.linspace(-0.5 * height, 0.5 * height, ny)
        xx, yy = np.meshgrid(x, y)
        return cls(x, y, np.asarray(fn(xx, yy), dtype=float))

    def _f(self, x: np.ndarray, y: np.ndarray, dx: int = 0, dy: int = 0) -> np.ndarray:
        return np.asarray(self._spline.ev(y, x, dx=dy, dy=dx))

    def _inside(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return ((x >= self.x[0]) & (x <= self.x[-1]) & (y >= self.y[0]) & (y <= self.y[-1]))

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> Hit:
        o, d = _rays(origins, directions)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -o[:, 2] / d[:, 2]
        t = np.where(np.isfinite(t), t, 0.0)
        for _ in range(30):
            p = o + t[:, None] * d
            x = np.clip(p[:, 0], self.x[0], self.x[-1])
            y = np.clip(p[:, 1], self.y[0], self.y[-1])
            g = p[:, 2] - self._f(x, y)
            dg = d[:, 2] - self._f(x, y, 1, 0) * d[:, 0] - self._f(x, y, 0, 1) * d[:, 1]
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(np.abs(dg) > 1e-12, g / dg, 0.0)
            t = t - np.clip(step, -50.0, 50.0)
        p = o + t[:, None] * d
        resid = np.abs(p[:, 2] - self._f(p[:, 0], p[:, 1]))
        ok = (t > -_EPS) & (resid < 1e-7) & self._inside(p[:, 0], p[:, 1])
        p[~ok] = np.nan
        return Hit(p, self.normal(np.where(ok[:, None], p, 0.0)), np.where(ok, t, np.nan),
                   np.zeros(len(p), np.int64), ok)

    def normal(self, points: np.ndarray) -> np.ndarray:
        q = np.asarray(points, dtype=float).reshape(-1, 3)
        fx = self._f(q[:, 0], q[:, 1], 1, 0)
        fy = self._f(q[:, 0], q[:, 1], 0, 1)
        return _unit(np.stack([-fx, -fy, np.ones(len(q))], axis=1))

    def project(self, points: np.ndarray) -> np.ndarray:
        q = np.array(points, dtype=float).reshape(-1, 3)
        # One step along the normal: exact to second order in the small offset.
        for _ in range(2):
            s = q.copy()
            s[:, 2] = self._f(q[:, 0], q[:, 1])
            n = self.normal(s)
            q = q - np.sum((q - s) * n, axis=1)[:, None] * n
        q[:, 2] = self._f(q[:, 0], q[:, 1])
        return q

    def part(self, points: np.ndarray) -> np.ndarray:
        return np.zeros(len(np.asarray(points).reshape(-1, 3)), dtype=np.int64)

    def describe(self) -> dict[str, Any]:
        return {"kind": "heightfield", "x": [float(self.x[0]), float(self.x[-1])],
                "y": [float(self.y[0]), float(self.y[-1])], "samples": list(self.z.shape[::-1]),
                "z": [float(self.z.min()), float(self.z.max())]}


class MeshHost:
    """Any triangle mesh as host (a vase, a sculpture), its normals smoothed.

    Rays are cast with trimesh (Embree when installed). The normal at a point is
    the vertex normals interpolated over its triangle, so a groove's glints move
    smoothly across faces of a finely tessellated surface. The mesh is used as
    given, in the plate frame, facing +z.

    Args:
        mesh: a ``trimesh.Trimesh``.
    """

    kind = "mesh"

    def __init__(self, mesh: Any) -> None:
        import trimesh

        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise SpecholoError("a mesh host needs a triangle mesh with faces")
        self.mesh = mesh
        self._vn = np.asarray(mesh.vertex_normals, dtype=float)
        self._tri = np.asarray(mesh.triangles, dtype=float)
        self._faces = np.asarray(mesh.faces)
        from scipy.spatial import cKDTree

        self._kd = cKDTree(np.asarray(mesh.vertices, dtype=float))
        # How far above the surface projection rays start: a few edge lengths.
        self._reach = 4.0 * float(np.mean(mesh.edges_unique_length))
        try:
            from trimesh.ray.ray_pyembree import RayMeshIntersector
            self._ray: Any = RayMeshIntersector(mesh)
        except Exception:  # Embree is optional: the pure-Python caster is exact, slower
            self._ray = mesh.ray

    def _smooth(self, points: np.ndarray, tri: np.ndarray) -> np.ndarray:
        import trimesh

        bary = trimesh.triangles.points_to_barycentric(self._tri[tri], points)
        vn = self._vn[self._faces[tri]]
        return _unit(np.einsum("nk,nkj->nj", bary, vn))

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> Hit:
        o, d = _rays(origins, directions)
        n = len(o)
        out = _miss(n)
        if n == 0:
            return out
        dn = _unit(d)
        good = np.isfinite(dn).all(axis=1) & np.isfinite(o).all(axis=1)
        idx = np.flatnonzero(good)
        if idx.size == 0:
            return out
        loc, ray, tri = self._ray.intersects_location(o[idx], dn[idx], multiple_hits=True)
        if len(ray) == 0:
            return out
        dist = np.sum((loc - o[idx][ray]) * dn[idx][ray], axis=1)
        keep = dist > -_EPS
        if not keep.any():  # every hit lies behind its ray's start
            return out
        loc, ray, tri, dist = loc[keep], ray[keep], tri[keep], dist[keep]
        order = np.lexsort((dist, ray))
        first = order[np.r_[True, ray[order][1:] != ray[order][:-1]]]
        rows = idx[ray[first]]
        point = out.point
        normal = out.normal
        t = out.t
        valid = out.valid
        point[rows] = loc[first]
        normal[rows] = self._smooth(loc[first], tri[first])
        t[rows] = dist[first] / np.linalg.norm(d[rows], axis=1)
        valid[rows] = True
        return Hit(point, normal, t, out.part, valid)

    def _closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest surface points and their smooth normals.

        Points near the surface (as groove samples are) are cast back onto it
        along the normal of their nearest vertex, with Embree; the few rays that
        miss (near an edge of the mesh) fall back to an exact closest-point query.
        """
        from trimesh.proximity import closest_point

        _, vertex = self._kd.query(points)
        n = self._vn[vertex]
        reach = self._reach
        hit = self.intersect(points + reach * n, -n)
        near = hit.valid & (np.abs(hit.t) <= 2.0 * reach)
        out_p = np.where(near[:, None], hit.point, 0.0)
        out_n = np.where(near[:, None], hit.normal, 0.0)
        miss = np.flatnonzero(~near)
        if miss.size:
            q, _, tri = closest_point(self.mesh, points[miss])
            out_p[miss] = q
            out_n[miss] = self._smooth(np.asarray(q), np.asarray(tri))
        return out_p, out_n

    def normal(self, points: np.ndarray) -> np.ndarray:
        q = np.asarray(points, dtype=float).reshape(-1, 3)
        if len(q) == 0:
            return np.zeros((0, 3))
        return self._closest(q)[1]

    def project(self, points: np.ndarray) -> np.ndarray:
        q = np.asarray(points, dtype=float).reshape(-1, 3)
        if len(q) == 0:
            return q.copy()
        return self._closest(q)[0]

    def part(self, points: np.ndarray) -> np.ndarray:
        return np.zeros(len(np.asarray(points).reshape(-1, 3)), dtype=np.int64)

    def describe(self) -> dict[str, Any]:
        b = np.asarray(self.mesh.bounds, dtype=float)
        return {"kind": "mesh", "faces": int(len(self._faces)), "bounds": b.tolist()}


@dataclass(frozen=True)
class Panel:
    """A flat rectangular panel: its centre, outward normal and up direction.

    Attributes:
        centre: (3,) centre, mm.
        normal: (3,) outward normal (toward the viewer's side).
        up: (3,) the panel's up direction (made orthogonal to the normal).
        width, height: size, mm.
    """

    centre: tuple[float, float, float]
    normal: tuple[float, float, float]
    width: float
    height: float
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """centre, right, up, normal: (3,) each."""
        n = np.asarray(self.normal, dtype=float)
        if not (np.isfinite(n).all() and np.linalg.norm(n) > 0):
            raise SpecholoError(f"panel normal must be a nonzero vector, got {self.normal}")
        n = n / np.linalg.norm(n)
        u = np.asarray(self.up, dtype=float)
        u = u - np.dot(u, n) * n
        if not np.linalg.norm(u) > 1e-9:
            raise SpecholoError(f"panel up {self.up} must not be parallel to its normal")
        u = u / np.linalg.norm(u)
        return np.asarray(self.centre, dtype=float), np.cross(u, n), u, n


class Panels:
    """A host made of several separate flat panels (a triptych, a folded screen).

    Each panel is its own piece: rays take the nearest panel they meet, and a
    groove ends where its sightline crossings pass from one panel to another.
    """

    kind = "panels"

    def __init__(self, panels: list[Panel]) -> None:
        if not panels:
            raise SpecholoError("a panels host needs at least one panel")
        for p in panels:
            _positive("panel width", p.width)
            _positive("panel height", p.height)
        self.panels = list(panels)
        frames = [p.frame() for p in self.panels]
        self._c = np.array([f[0] for f in frames])
        self._r = np.array([f[1] for f in frames])
        self._u = np.array([f[2] for f in frames])
        self._n = np.array([f[3] for f in frames])
        self._half = np.array([[0.5 * p.width, 0.5 * p.height] for p in self.panels])

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> Hit:
        o, d = _rays(origins, directions)
        best = _miss(len(o))
        tb = np.full(len(o), np.inf)
        for k in range(len(self.panels)):
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.sum((self._c[k] - o) * self._n[k], axis=1) / (d @ self._n[k])
            p = o + t[:, None] * d
            rel = p - self._c[k]
            ok = (np.isfinite(t) & (t > -_EPS)
                  & (np.abs(rel @ self._r[k]) <= self._half[k, 0])
                  & (np.abs(rel @ self._u[k]) <= self._half[k, 1]) & (t < tb))
            tb[ok] = t[ok]
            best.point[ok] = p[ok]
            best.normal[ok] = self._n[k]
            best.part[ok] = k
            best.valid[ok] = True
        best.t[best.valid] = tb[best.valid]
        return best

    def part(self, points: np.ndarray) -> np.ndarray:
        q = np.asarray(points, dtype=float).reshape(-1, 3)
        dist = np.stack([np.abs((q - self._c[k]) @ self._n[k]) for k in range(len(self.panels))])
        return np.argmin(dist, axis=0).astype(np.int64)

    def normal(self, points: np.ndarray) -> np.ndarray:
        return self._n[self.part(points)].copy()

    def project(self, points: np.ndarray) -> np.ndarray:
        q = np.asarray(points, dtype=float).reshape(-1, 3)
        k = self.part(q)
        n = self._n[k]
        return q - np.sum((q - self._c[k]) * n, axis=1)[:, None] * n

    def describe(self) -> dict[str, Any]:
        return {"kind": "panels", "panels": [
            {"centre": list(p.centre), "normal": list(p.normal), "up": list(p.up),
             "width": p.width, "height": p.height} for p in self.panels]}

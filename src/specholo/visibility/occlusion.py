"""Occlusion: from which eye positions each stipple of a mesh can be seen.

A stipple is visible from an eye when the eye is on the outer side of the face
the stipple lies on and the segment from the stipple to the eye crosses no
triangle of the mesh. Along the viewer's arc this gives, for every stipple, a
set of azimuth intervals in which its glint may be shown; outside them the
hologram must keep it dark, or the model would look transparent.
"""

from __future__ import annotations

import math
import os
import threading
import weakref
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeAlias

import numpy as np

from specholo.errors import SpecholoError
from specholo.scene.mesh import Mesh
from specholo.setup import Viewer
from specholo.visibility import _ray_kernel

if TYPE_CHECKING:
    import trimesh

#: A mesh the tests take: specholo's own, or a trimesh (anything with vertices,
#: faces, face_normals, triangles, scale and, without embree, ray).
AnyMesh: TypeAlias = "Mesh | trimesh.Trimesh"

try:  # trimesh's embree tracer is used through its scene, set up in bulk
    import embreex  # noqa: F401

    _HAVE_EMBREE = True
except ImportError:  # pragma: no cover - platforms without embree wheels
    _HAVE_EMBREE = False

# Rays start this far (times the mesh's bounding-box diagonal) off the surface
# along the face normal, so they don't hit the stipple's own face; embree works
# in float32 (~1e-7 relative), so this leaves two orders of magnitude of margin.
_OFFSET = 1e-5
# Rays traced per call, to bound the memory of the temporary arrays.
_CHUNK = 1 << 20
# Chunks traced at once: numpy's big operations and part of embree's work
# release the GIL, so threads share the ray casts (1.2-1.3x on two cores).
_WORKERS = max(1, min(4, os.cpu_count() or 1))
# Fewest rays worth a chunk of their own.
_MIN_SHARED = 1 << 14


def _check(points: np.ndarray, normals: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise SpecholoError(f"stipple points must have shape (n, 3), got {points.shape}")
    if normals is None:
        raise SpecholoError("stipples on a mesh need their face normals for occlusion tests")
    normals = np.asarray(normals, dtype=np.float64)
    if normals.shape != points.shape:
        raise SpecholoError(
            f"stipple normals must have the shape of the points {points.shape}, got {normals.shape}"
        )
    return points, normals


def visible(
    mesh: AnyMesh | None,
    points: np.ndarray,
    normals: np.ndarray | None,
    eyes: np.ndarray,
) -> np.ndarray:
    """Which points are visible from their eyes.

    Args:
        mesh: the occluding mesh (the model the points lie on), or None for a
            point cloud, which hides nothing.
        points: (n, 3) points on the mesh surface, mm.
        normals: (n, 3) outward unit normals of the faces the points lie on
            (may be None when mesh is None).
        eyes: (n, 3) eye positions, one per point, or (3,) one eye for all.

    Returns:
        (n,) bool: point i is visible from eye i.

    Raises:
        SpecholoError: shapes don't match, or normals are missing for a mesh.
    """
    if mesh is None:
        return np.ones(len(np.asarray(points).reshape(-1, 3)), dtype=bool)
    points, normals = _check(points, normals)
    # A copy, never the read-only broadcast view: a read-only array is another
    # type to numba, and the ray kernels would be compiled twice.
    eyes = np.array(np.broadcast_to(np.asarray(eyes, dtype=np.float64), points.shape))
    result = np.zeros(len(points), dtype=bool)
    # At least one chunk per worker once there are enough rays to share.
    chunk = min(_CHUNK, max(_MIN_SHARED, -(-len(points) // _WORKERS)))

    def trace(lo: int) -> None:
        sl = slice(lo, lo + chunk)
        result[sl] = _visible_rays(mesh, points[sl], normals[sl], eyes[sl], 0)

    _each(trace, range(0, len(points), chunk), mesh)
    return result


def _each(trace: Callable[[int], None], starts: range, mesh: AnyMesh) -> None:
    """trace(start) for every start, in threads, which share the mesh's ray index
    (built first, so that no thread waits for it)."""
    if len(starts) <= 1:
        for lo in starts:
            trace(lo)
        return
    _scene(mesh)
    with ThreadPoolExecutor(_WORKERS) as pool:
        list(pool.map(trace, starts))


class _Scene:
    """The mesh's embree scene, built as trimesh builds it (vertices shifted to
    their minimum and scaled to a box of ~100, in single precision), so a ray
    set up in that frame (:func:`_ray_kernel.rays`) hits what trimesh's would."""

    def __init__(self, mesh: AnyMesh) -> None:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        vertices = np.array(mesh.vertices, dtype=np.float64)
        self.origin = vertices.min(axis=0)
        self.scale = 100.0 / float(mesh.scale)
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(scene=self.scene,
                     vertices=((vertices - self.origin) * self.scale).astype(np.float32),
                     indices=np.asarray(mesh.faces).astype(np.int32))
        self.key = hash(mesh)

    def first(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(k,) index of the first triangle each ray hits, -1 for none."""
        return np.asarray(self.scene.run(origins, directions), dtype=np.int64)


# By the mesh's id (a mesh's hash changes with its data); dropped with the mesh.
_SCENES: dict[int, _Scene] = {}
_SCENES_LOCK = threading.Lock()


def _scene(mesh: AnyMesh) -> _Scene | None:
    """The mesh's cached scene (rebuilt if the mesh changed), or None without embreex."""
    if not _HAVE_EMBREE:
        return None
    with _SCENES_LOCK:
        scene = _SCENES.get(id(mesh))
        if scene is None:
            weakref.finalize(mesh, _SCENES.pop, id(mesh), None)
        if scene is None or scene.key != hash(mesh):
            scene = _SCENES[id(mesh)] = _Scene(mesh)
        return scene


def _ray_ends(points: np.ndarray, normals: np.ndarray, eyes: np.ndarray, grid: int,
              rays: np.ndarray, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Origins (k, 3), lifted off the face, and vectors to the eye (k, 3) of some rays."""
    pi, ej = (rays // grid, rays % grid) if grid > 0 else (rays, rays)
    origins = points[pi] + offset * normals[pi]
    return origins, eyes[ej] - origins


def _visible_rays(mesh: AnyMesh, points: np.ndarray, normals: np.ndarray,
                  eyes: np.ndarray, grid: int) -> np.ndarray:
    """Visibility along the rays of :mod:`._ray_kernel` (point i, eye j of ray k).

    Returns:
        (n_rays,) bool, n_rays = len(points) * grid, or len(points) for grid 0.
    """
    n_rays = len(points) * grid if grid > 0 else len(points)
    result = _ray_kernel.facing(points, normals, eyes, grid, n_rays)
    idx = np.flatnonzero(result)
    if len(idx) == 0:
        return result
    offset = _OFFSET * float(mesh.scale)
    scene = _scene(mesh)
    if scene is not None:
        o32, d32 = _ray_kernel.rays(points, normals, eyes, grid, idx, offset, scene.origin,
                                    scene.scale)
        tri = scene.first(o32, d32)
        del o32, d32
    else:  # trimesh's own ray tracer, on the same rays
        origins, to_eye = _ray_ends(points, normals, eyes, grid, idx, offset)
        tri = np.asarray(mesh.ray.intersects_first(
            origins, to_eye / np.linalg.norm(to_eye, axis=1)[:, None]), dtype=np.int64)
    hit = np.flatnonzero(tri >= 0)
    if len(hit):
        # The first hit blocks the view only if it lies before the eye: find its
        # distance along the ray from the plane of the triangle hit.
        ray = idx[hit]
        origins, to_eye = _ray_ends(points, normals, eyes, grid, ray, offset)
        reach = np.linalg.norm(to_eye, axis=1)
        directions = to_eye / reach[:, None]
        face = tri[hit]
        plane_n = np.asarray(mesh.face_normals, dtype=np.float64)[face]
        plane_p = np.asarray(mesh.triangles, dtype=np.float64)[face, 0]
        num = np.einsum("ij,ij->i", plane_n, plane_p - origins)
        den = np.einsum("ij,ij->i", plane_n, directions)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = num / den
        # A ray running in the plane of the hit face (den ~ 0) is blocked by it.
        blocked = ~np.isfinite(t) | (t < reach)
        result[ray[blocked]] = False
    return result


@dataclass(frozen=True, eq=False)
class Intervals:
    """Azimuth intervals of the viewer's arc in which stipples are visible.

    Intervals are closed, disjoint per stipple, and sorted by stipple then start.

    Attributes:
        stipple: (k,) int64 stipple index of each interval.
        start: (k,) float64 start azimuth, radians.
        end: (k,) float64 end azimuth, radians (> start).
    """

    stipple: np.ndarray
    start: np.ndarray
    end: np.ndarray

    def __len__(self) -> int:
        return len(self.stipple)

    def for_stipple(self, i: int) -> np.ndarray:
        """The intervals of one stipple.

        Args:
            i: stipple index.

        Returns:
            (m, 2) rows of (start, end) in radians, sorted; m = 0 if never visible.
        """
        lo = int(np.searchsorted(self.stipple, i, side="left"))
        hi = int(np.searchsorted(self.stipple, i, side="right"))
        return np.stack([self.start[lo:hi], self.end[lo:hi]], axis=1)

    def contains(self, stipple_ids: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """Whether each stipple is visible at each azimuth.

        Args:
            stipple_ids: (n,) stipple indices.
            theta: (n,) azimuths in radians (broadcast against stipple_ids).

        Returns:
            (n,) bool: theta[j] lies in one of stipple_ids[j]'s intervals.
        """
        ids, theta = np.broadcast_arrays(
            np.asarray(stipple_ids, dtype=np.int64), np.asarray(theta, dtype=np.float64)
        )
        ids, theta = ids.ravel(), theta.ravel()
        first = np.searchsorted(self.stipple, ids, side="left")
        lo = first.copy()
        hi = np.searchsorted(self.stipple, ids, side="right")
        # Vectorised binary search, within each stipple's run, for the first
        # interval starting after theta.
        while True:
            active = lo < hi
            if not active.any():
                break
            mid = (lo + hi) // 2
            after = np.zeros(len(ids), dtype=bool)
            after[active] = self.start[mid[active]] > theta[active]
            hi = np.where(active & after, mid, hi)
            lo = np.where(active & ~after, mid + 1, lo)
        j = lo - 1
        inside = j >= first
        result = np.zeros(len(ids), dtype=bool)
        result[inside] = theta[inside] <= self.end[j[inside]]
        return result


def visible_intervals(
    mesh: AnyMesh | None,
    points: np.ndarray,
    normals: np.ndarray | None,
    viewer: Viewer,
    step: float = math.radians(1.0),
    refine: int = 6,
) -> Intervals:
    """Azimuth intervals of the viewer's arc from which each stipple is visible.

    Visibility is sampled from eyes ``viewer.eye(theta)`` on a grid of spacing
    at most ``step`` over [-design_range, +design_range]; each change between
    neighbouring samples is then narrowed by ``refine`` bisection steps and its
    edge placed mid-bracket, within step / 2**(refine + 1) of the true edge.
    Gaps or blinks narrower than the grid step may be missed.

    Args:
        mesh: the occluding mesh, or None for a point cloud (always visible).
        points: (n, 3) stipple positions, mm.
        normals: (n, 3) outward unit normals (None allowed when mesh is None).
        viewer: the viewer's arc.
        step: largest grid spacing in azimuth, radians (> 0).
        refine: bisection steps per edge (>= 0).

    Returns:
        The visible intervals of every stipple, sorted by stipple then start; a
        stipple visible over the whole arc has one interval covering it.

    Raises:
        SpecholoError: step is not positive, refine is negative, or the shapes
            of points and normals don't match.
    """
    step = float(step)
    if not math.isfinite(step) or step <= 0:
        raise SpecholoError(f"visibility step must be a positive angle, got {step:g}")
    if int(refine) != refine or refine < 0:
        raise SpecholoError(f"visibility refinement steps must be an integer >= 0, got {refine}")
    refine = int(refine)
    half = float(viewer.design_range)

    if mesh is None:
        n = len(np.asarray(points).reshape(-1, 3))
        return Intervals(
            stipple=np.arange(n, dtype=np.int64),
            start=np.full(n, -half),
            end=np.full(n, half),
        )
    points, normals = _check(points, normals)
    n = len(points)

    grid = np.linspace(-half, half, max(1, math.ceil(2.0 * half / step)) + 1)
    g = len(grid)
    eyes = np.ascontiguousarray(viewer.eye(grid), dtype=np.float64)
    seen = np.zeros((n, g), dtype=bool)
    per_chunk = max(1, _CHUNK // g)

    def trace(lo: int) -> None:
        sl = slice(lo, min(n, lo + per_chunk))
        m = sl.stop - sl.start
        seen[sl] = _visible_rays(mesh, points[sl], normals[sl], eyes, g).reshape(m, g)

    _each(trace, range(0, n, per_chunk), mesh)

    # Narrow every visible/hidden change on the grid, all at once.
    ti, tj = np.nonzero(seen[:, 1:] != seen[:, :-1])
    a, b = grid[tj], grid[tj + 1]
    seen_a = seen[ti, tj]
    for _ in range(refine):
        mid = 0.5 * (a + b)
        same = visible(mesh, points[ti], normals[ti], viewer.eye(mid)) == seen_a
        a = np.where(same, mid, a)
        b = np.where(same, b, mid)
    edge = 0.5 * (a + b)

    # Per stipple, starts and ends alternate along the arc, so sorting each list
    # by (stipple, azimuth) pairs the k-th start with the k-th end.
    open_all = np.flatnonzero(seen[:, 0])
    close_all = np.flatnonzero(seen[:, -1])
    rising = ~seen_a
    start_id = np.concatenate([open_all, ti[rising]])
    start = np.concatenate([np.full(len(open_all), -half), edge[rising]])
    end_id = np.concatenate([ti[~rising], close_all])
    end = np.concatenate([edge[~rising], np.full(len(close_all), half)])
    so = np.lexsort((start, start_id))
    eo = np.lexsort((end, end_id))
    return Intervals(stipple=start_id[so].astype(np.int64), start=start[so], end=end[eo])

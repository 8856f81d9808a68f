"""Stippling: blue-noise points on a model's surface.

Each stipple becomes one glint of the hologram, so stipples should cover the
surface evenly without clumps: a Poisson-disk set, where no two stipples are
closer than a radius r. It is built from many uniform random candidates by
keeping a maximal independent set of the graph joining candidates closer than
r, chosen greedily in a random priority order: one compiled pass in that order
keeps each candidate with no kept one within r (:mod:`._disk_kernel`).
"""

from __future__ import annotations

import math
import numbers
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from specholo.errors import SpecholoError
from specholo.scene._disk_kernel import AXIS_BITS, greedy_disk
from specholo.scene._sample_kernel import sample_surface
from specholo.scene.loading import Model, available_memory, format_bytes, mesh_memory
from specholo.scene.mesh import Mesh

# Candidates drawn per wanted stipple: more gives a tighter (more saturated)
# Poisson-disk set, at a cost linear in the ratio; beyond 4 the gain is small.
_CANDIDATES_PER_STIPPLE = 4
# Fewest candidates drawn for a count: with 4 per stipple, a design of a few
# stipples has too few to choose from, and two of them may land far closer
# than the spacing their number allows (on a box, 7 stipples from 28 draws).
_MIN_CANDIDATES = 256
# Surface area per point of the greedy set of radius r from that many candidates,
# in units of r^2 (measured on two models from 10^4 to 10^6 stipples: the set at
# r = sqrt(area / (2.2 N)) holds N to 1.05 N points, so the search's first
# radius is mostly accepted; a fully saturated set would reach ~1.44).
_AREA_PER_POINT = 2.2
# Mean candidates within r of a candidate at that ratio (4 pi / 2.2 ~ 5.7).
_NEIGHBOURS_PER_CANDIDATE = 8.0
# Greedy radius over the median nearest-neighbour distance of the candidates,
# for candidates spread over a surface at the ratio above.
_R0_PER_NEIGHBOUR_DISTANCE = 3.1
# Largest candidate set built, to keep memory bounded (~1 GB at worst).
_MAX_CANDIDATES = 10_000_000
# For a requested count, accept a radius whose set has N..(1 + slack) N points.
_COUNT_SLACK = 0.05
_MAX_SEARCH_STEPS = 16
#: Peak memory of a whole design per stipple, bytes: stippling, occlusion, the
#: tool check, the grooves (built in place, ~5.7 KB per stipple) and overlaps.
#: Measured on the bunny: 10^5 stipples peak near 1.6 GB, 10^6 near 7.8 GB.
BYTES_PER_STIPPLE = 9_000
#: Memory a design takes whatever its size (compiled kernels, ray tracer, the
#: walk's chunk), bytes.
BASE_BYTES = 800_000_000
#: Output written per stipple (G-code, SVG, grooves, JSON), bytes.
OUTPUT_BYTES_PER_STIPPLE = 30_000


def estimate_memory(n_stipples: int, n_faces: int = 0, n_vertices: int = 0) -> int:
    """Peak memory of designing a hologram of that many stipples, bytes (an estimate).

    Args:
        n_stipples: the number of stipples.
        n_faces: faces of the model's mesh (0 for a point cloud).
        n_vertices: vertices of the model's mesh.

    Returns:
        The estimated peak in bytes; Python ints never overflow, so absurd
        counts (10^12) give absurd but exact estimates.
    """
    return (BASE_BYTES + int(n_stipples) * BYTES_PER_STIPPLE
            + mesh_memory(int(n_vertices), int(n_faces)))


def check_memory(n_stipples: int, n_faces: int = 0, n_vertices: int = 0,
                 request: str | None = None) -> None:
    """Refuse a design that would not fit in the memory available, before it starts.

    Args:
        n_stipples: the number of stipples.
        n_faces: faces of the model's mesh (0 for a point cloud or when not loaded yet).
        n_vertices: vertices of the model's mesh.
        request: how the user asked for it, for the message (default
            ``stipples = N``).

    Raises:
        SpecholoError: e.g. "stipples = 1000000000 would need ~60 TB of memory;
            this machine has 20.1 GB available".
    """
    need = estimate_memory(n_stipples, n_faces, n_vertices)
    room = available_memory()
    if room is not None and need > room:
        what = request or f"stipples = {int(n_stipples)}"
        raise SpecholoError(f"{what} would need ~{format_bytes(need)} of memory; "
                            f"this machine has {format_bytes(room)} available")


def check_disk(n_stipples: int, folder: str | os.PathLike[str]) -> None:
    """Refuse to write a design whose files would not fit on the disk holding ``folder``.

    Args:
        n_stipples: the number of stipples.
        folder: the output folder, or the nearest existing folder above it.

    Raises:
        SpecholoError: the disk has less free space than the files need.
    """
    try:
        place = Path(folder).resolve()
        while not place.exists() and place != place.parent:
            place = place.parent
        usage = shutil.disk_usage(place)
    except (OSError, ValueError):  # unreadable, or a NUL byte: writing will say
        return
    if usage.total == 0:  # /proc and the like report no size at all
        return
    free = usage.free
    need = int(n_stipples) * OUTPUT_BYTES_PER_STIPPLE
    if need > free:
        raise SpecholoError(f"{int(n_stipples)} stipples would write ~{format_bytes(need)} of "
                            f"files; {place} has {format_bytes(free)} free")


@dataclass(frozen=True, eq=False)
class Stipples:
    """Points on a model's surface.

    Attributes:
        points: (n, 3) float64 positions, mm.
        normals: (n, 3) float64 outward unit normals of the face each point lies
            on, or None for a point cloud.
    """

    points: np.ndarray
    normals: np.ndarray | None

    def __len__(self) -> int:
        return len(self.points)


def stipple(
    model: Model,
    rng: np.random.Generator,
    count: int | None = None,
    spacing: float | None = None,
) -> Stipples:
    """Place blue-noise stipples on a model.

    Exactly one of ``count`` and ``spacing`` is given. A mesh is sampled over its
    surface (area weighted); a point cloud is thinned, never added to.

    Args:
        model: the model (usually already placed, in mm).
        rng: random generator; the same seed gives the same stipples.
        count: number of stipples N. Exactly N are returned, unless the model
            cannot give that many (a point cloud with fewer distinct points).
        spacing: minimum distance between stipples, mm.

    Returns:
        The stipples: points (n, 3) and, for a mesh, normals (n, 3).

    Raises:
        SpecholoError: neither or both of count and spacing are given, count is
            not a positive integer, spacing is not a positive finite number, or
            the request needs more candidates than can be held in memory.
    """
    if (count is None) == (spacing is None):
        raise SpecholoError("give exactly one of stipple count and stipple spacing")
    n_wanted: int | None = None
    if count is not None:
        if isinstance(count, bool) or not isinstance(count, numbers.Integral) or count <= 0:
            raise SpecholoError(f"stipple count must be a positive integer, got {count!r}")
        n_wanted = int(count)
    if spacing is not None:
        s = float(spacing)
        if not math.isfinite(s) or s <= 0:
            raise SpecholoError(f"stipple spacing must be a positive number of mm, got {s:g}")

    points = np.asarray(model.points, dtype=np.float64)
    if len(points) == 0 or not np.isfinite(points).all():
        raise SpecholoError("the model has no points, or NaN or infinite coordinates")
    # Work at unit scale: scaling by a power of two is exact, so the stipples are
    # the same as at the model's own scale, but areas and squared distances
    # neither overflow (coordinates of 1e300) nor underflow (1e-300).
    largest = float(np.max(np.abs(points)))
    k = math.frexp(largest)[1] if largest > 0 else 0
    unit = np.ldexp(points, -k)
    unit_spacing = None if spacing is None else math.ldexp(float(spacing), -k)
    with np.errstate(all="ignore"):
        if model.mesh is not None:
            mesh = Mesh(unit, model.mesh.faces)
            st = _stipple_mesh(mesh, rng, n_wanted, unit_spacing, 2.0**k)
        else:
            st = _stipple_cloud(unit, rng, n_wanted, unit_spacing)
    return Stipples(points=np.ldexp(st.points, k), normals=st.normals)


def _stipple_mesh(
    mesh: Mesh, rng: np.random.Generator, count: int | None, spacing: float | None,
    unit: float = 1.0,
) -> Stipples:
    """Stipples of a mesh; ``unit`` is the model's length per unit of ``mesh`` (for messages)."""
    area = float(mesh.area)
    if not area > 0:
        raise SpecholoError("mesh has zero surface area; cannot stipple it")
    if count is not None:
        n_candidates = max(_MIN_CANDIDATES, _CANDIDATES_PER_STIPPLE * count)
        if n_candidates > _MAX_CANDIDATES:
            raise SpecholoError(
                f"stipple count {count} is too large "
                f"(at most {_MAX_CANDIDATES // _CANDIDATES_PER_STIPPLE}; the design would "
                f"need ~{format_bytes(estimate_memory(count))} of memory)"
            )
    else:
        assert spacing is not None
        estimate = area / (_AREA_PER_POINT * spacing**2)
        if not estimate * _CANDIDATES_PER_STIPPLE <= _MAX_CANDIDATES:
            raise SpecholoError(
                f"stipple spacing {spacing * unit:g} mm is too small for this model "
                f"(about {estimate:.3g} stipples)"
            )
        n_candidates = max(16, math.ceil(_CANDIDATES_PER_STIPPLE * estimate))

    points, face = sample_surface(mesh.vertices, mesh.faces, mesh.area_faces, n_candidates, rng)
    if count is not None:
        r0 = math.sqrt(area / (_AREA_PER_POINT * count * (1.0 + 0.5 * _COUNT_SLACK)))
        keep = _select_count(points, rng, count, r0)
    else:
        assert spacing is not None
        keep = _select_spacing(points, rng, spacing)
    normals = np.asarray(mesh.face_normals, dtype=np.float64)[face[keep]]
    return Stipples(points=points[keep], normals=normals)


def _stipple_cloud(
    points: np.ndarray, rng: np.random.Generator, count: int | None, spacing: float | None
) -> Stipples:
    from scipy.spatial import cKDTree  # (only clouds need it: scipy takes a while to import)

    # Repeated points would only inflate the neighbour graph.
    _, first = np.unique(points, axis=0, return_index=True)
    distinct = np.sort(first)
    n = len(distinct)
    if count is not None:
        if n <= count:
            return Stipples(points=points[distinct], normals=None)
        # Thin to as many candidates as a mesh would get, so the neighbour
        # graph stays small however dense the cloud is.
        m = min(n, max(_MIN_CANDIDATES, _CANDIDATES_PER_STIPPLE * count))
        cand = distinct if m == n else np.sort(rng.choice(distinct, size=m, replace=False))
        sub = points[cand]
        nn = cKDTree(sub).query(sub, k=2)[0][:, 1]
        # On a surface the greedy radius is ~3.1 median neighbour distances of
        # the candidates; the search corrects it for volumes and lines.
        r0 = _R0_PER_NEIGHBOUR_DISTANCE * float(np.median(nn))
        keep = cand[_select_count(sub, rng, count, r0)]
    else:
        assert spacing is not None
        cand = distinct
        if n > 1:
            # Probe how many points lie within the spacing; thin a dense cloud
            # to about as many neighbours per candidate as a mesh would get.
            probe = rng.choice(n, size=min(n, 1000), replace=False)
            tree = cKDTree(points[distinct])
            within = tree.query_ball_point(points[distinct[probe]], spacing, return_length=True)
            crowd = float(np.mean(within)) - 1.0
            if crowd > _NEIGHBOURS_PER_CANDIDATE:
                m = max(1, math.ceil(n * _NEIGHBOURS_PER_CANDIDATE / crowd))
                cand = np.sort(rng.choice(distinct, size=m, replace=False))
        keep = cand[_select_spacing(points[cand], rng, spacing)]
    return Stipples(points=points[keep], normals=None)


def _select_spacing(points: np.ndarray, rng: np.random.Generator, r: float) -> np.ndarray:
    """Indices of a Poisson-disk subset of radius r."""
    return _DiskSets(points, rng.permutation(len(points))).independent_set(r)


def _select_count(
    points: np.ndarray, rng: np.random.Generator, count: int, r0: float
) -> np.ndarray:
    """Indices of ``count`` points of a Poisson-disk subset, searching the radius.

    The set size falls roughly like r^-2, so the radius is updated by a secant
    step in log-log space, kept inside the bracket found so far (bisection in
    log r when the secant leaves it).
    """
    sets = _DiskSets(points, rng.permutation(len(points)))
    target = count * (1.0 + 0.5 * _COUNT_SLACK)
    above: tuple[float, np.ndarray] | None = None  # largest r with >= count points
    below: float | None = None  # smallest r with < count points
    best_short: np.ndarray | None = None
    history: list[tuple[float, int]] = []
    r = r0
    chosen: np.ndarray | None = None
    for _ in range(_MAX_SEARCH_STEPS):
        selected = sets.independent_set(r)
        k = len(selected)
        history.append((r, k))
        if count <= k <= count * (1.0 + _COUNT_SLACK):
            chosen = selected
            break
        if k >= count:
            if above is None or r > above[0]:
                above = (r, selected)
        else:
            if below is None or r < below:
                below = r
            if best_short is None or k > len(best_short):
                best_short = selected
        slope = 1.5  # k ~ r^-slope for a fixed candidate set on a surface (measured)
        if len(history) >= 2:
            (r1, k1), (r2, k2) = history[-2], history[-1]
            if r1 != r2 and k1 != k2 and k1 > 0 and k2 > 0:
                slope = min(3.0, max(0.5, -math.log(k1 / k2) / math.log(r1 / r2)))
        r_next = r * (k / target) ** (1.0 / slope)
        r_next = min(2.0 * r, max(0.5 * r, r_next))
        if above is not None and below is not None and not above[0] < r_next < below:
            r_next = math.sqrt(above[0] * below)
        r = r_next
    if chosen is None:
        if above is not None:
            chosen = above[1]
        else:
            # Too few distinct candidates for the count: return what there is.
            assert best_short is not None
            return best_short
    if len(chosen) > count:
        # Drop the surplus at random: removing points keeps the minimum distance.
        chosen = np.sort(rng.choice(chosen, size=count, replace=False))
    return chosen


class _DiskSets:
    """Greedy Poisson-disk sets of one candidate set, for the radii of a search.

    Candidates are taken in a fixed random priority order; the set at radius r
    is what one pass in that order keeps, no two closer than r.
    """

    def __init__(self, points: np.ndarray, priority: np.ndarray) -> None:
        """``priority`` (n,) is a permutation of 0 .. n - 1, the highest taken first."""
        n = len(priority)
        # The inverse permutation: argsort of a permutation without the sort.
        self.order = np.empty(n, dtype=np.intp)
        self.order[n - 1 - np.asarray(priority)] = np.arange(n)
        # In the order taken, so the pass reads them one after another.
        self.points = np.ascontiguousarray(points[self.order], dtype=np.float64)
        # Column by column: numpy reduces a (n, 3) array along its rows ~20x slower.
        self.lo = np.array([c.min() for c in self.points.T]) if len(points) else np.zeros(3)
        span = (np.array([c.max() for c in self.points.T]) - self.lo if len(points)
                else np.zeros(3))
        self.extent = float(np.max(span))

    def independent_set(self, r: float) -> np.ndarray:
        """(k,) sorted int64 indices of the greedy set at radius r."""
        # Cubes a little over 2 r (so rounding never hides a neighbour), and
        # few enough along an axis for the cube numbers to pack in an int64.
        side = max(2.0 * r * (1.0 + 1e-9), self.extent * (1.0 + 1e-9) / 2.0**AXIS_BITS,
                   np.finfo(float).tiny)
        kept = np.zeros(len(self.order), dtype=bool)
        kept[self.order] = greedy_disk(self.points, r, self.lo, side)
        return np.flatnonzero(kept).astype(np.int64)


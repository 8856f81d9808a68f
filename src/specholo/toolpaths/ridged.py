"""Ridged (Fresnel) optics with full parallax, sharing one plate.

Each stipple's optic is a foliation of level sets of its phi
(:mod:`specholo.optics.surfaces`), exact for every eye, horizontal and vertical
motion alike. Taken inside a shell of thickness 2 Delta below the plate it
becomes a sawtooth height field z(x, y) in [-2 Delta, 0]: facet k is the level
set phi = c0 + k dc over the plate region where the (cone-projected) plate value
of phi lies in (c0 + (k - 1) dc, c0 + k dc]. The sector boundaries (risers) are
cones from an apex q in front of the plate, the eye at the middle of the views
the region serves, so q sees every riser edge-on. A height field cannot
overhang: where a cone would undercut the higher facet (its high side faces
away from q) the riser stands vertical instead, as the top of the solid does.
dc is chosen so that facets stay within the shell.

One plate cell has one normal and sends one ray: a stipple's optic needs the
whole patch where its sightlines cross the plate for all the eyes that see it,
so the patches of many stipples overlap and must share the plate. Eyes are
sampled on a grid of azimuth and elevation at the viewing distance, their
visibility is ray cast (:func:`specholo.visibility.occlusion.visible`), and
each stipple's patch is rasterised on a grid of blocks (the plate cells whose
sightline through p reaches an eye that sees it). Every stipple gets a seed in
its patch, spread over the plate like a Poisson-disk set and aimed at a target
view from a low-discrepancy sequence over the range (so the views served cover
it evenly), and each block goes to the stipple with the nearest seed among
those it serves, in a metric that stretches x by ``aspect``: regions are
contiguous and wide, so both eyes of a head (their crossings IPD d / (D + d)
apart) fall in one region for many views. The share of its visible views each
stipple keeps is its kept patch area over its patch area (the sightline map is
nearly affine over a patch); stipples with no region are dropped.

Full parallax costs plate area: a patch is about D^2 Omega (d / (D + d))^2 for
a view range of solid angle Omega, so each eye sees roughly plate area / patch
area glints whatever the number of stipples. And like every Fresnel mirror lit
obliquely, a facet loses about tan(tilt of h) cot(light elevation) of its width
to the shadow of the riser beside it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numba as nb
import numpy as np

from specholo._compiling import kernel
from specholo.errors import SpecholoError
from specholo.hosts.flat import sightline_crossing
from specholo.optics.surfaces import ImplicitOptics, Kind, PointOptics, Source
from specholo.setup import BackLight, Setup, Viewer
from specholo.toolpaths.heightmap import HeightMap

#: Facet depth used, as a share of the shell (the rest absorbs the cone sectors).
DEPTH_MARGIN = 0.95
#: Smallest factor by which a leaning cone riser may shrink the facet step.
MIN_LEAN_FACTOR = 0.3
#: Largest number of sectors a column of the shell may cross.
MAX_SECTORS = 8
#: How many times wider than its two eyes' sightlines lie apart on the plate a
#: region is made: a head whose one eye's sightline falls in a region has the
#: other's there too for about 1 - 1/EYE_SPAN of its views.
EYE_SPAN = 2.5
#: Largest horizontal stretch of the regions (a region this many times wider
#: than high serves a band of elevations 1/64 of its azimuths).
MAX_ASPECT = 64.0
#: Models of a refraction plate's front optic (see :class:`Refraction`).
REFRACTION_MODELS = ("exact", "approx", "single")


@dataclass(frozen=True)
class RidgeOptions:
    """Settings of the ridged construction (mm and radians).

    Attributes:
        delta: shell half-thickness Delta: facets lie in [-2 Delta, 0], mm.
        resolution: plate raster spacing, mm.
        block: assignment raster spacing, mm (a multiple of the resolution).
        elevation_range: largest head elevation served, radians (the azimuth
            range is the viewer's).
        view_step: spacing of the eye grid, radians.
        aspect: horizontal stretch of the regions (>= 1); None: regions
            :data:`EYE_SPAN` times as wide as a head's two sightlines through
            a stipple lie apart on the plate (:func:`region_aspect`).
        margin: blank border around the patches, mm (a milling ball needs its radius).
        dot_depth: |p_z| below which a stipple is a dot (a small cap at p), mm.
        dot_radius: radius of a dot's spherical cap, mm.
        max_cells: largest raster built.
    """

    delta: float = 0.1
    resolution: float = 0.02
    block: float = 0.2
    elevation_range: float = math.radians(20.0)
    view_step: float = math.radians(1.0)
    aspect: float | None = None
    margin: float = 1.0
    dot_depth: float = 0.5
    dot_radius: float = 0.2
    max_cells: int = 300_000_000

    def __post_init__(self) -> None:
        for name in ("delta", "resolution", "block", "view_step", "dot_radius"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v > 0):
                raise SpecholoError(f"{name.replace('_', ' ')} must be positive, got {v:g}")
        for name in ("margin", "dot_depth"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise SpecholoError(f"{name.replace('_', ' ')} must be >= 0, got {v:g}")
        if self.aspect is not None and not (math.isfinite(self.aspect) and self.aspect >= 1.0):
            raise SpecholoError(f"aspect must be at least 1, got {self.aspect:g}")
        e = float(self.elevation_range)
        if not (math.isfinite(e) and 0.0 <= e < math.radians(80.0)):
            raise SpecholoError(f"elevation range must be in [0, 80) degrees, got "
                                f"{math.degrees(e):g}")
        if abs(self.ratio * self.resolution - self.block) > 1e-9 * self.block:
            raise SpecholoError(f"block {self.block:g} mm must be a whole number of "
                                f"resolution steps ({self.resolution:g} mm)")

    @property
    def ratio(self) -> int:
        """Raster cells per block side."""
        return max(1, round(self.block / self.resolution))


def refraction_optics(points: np.ndarray, light: BackLight, model: str = "exact",
                      samples: np.ndarray | None = None,
                      owner: np.ndarray | None = None) -> ImplicitOptics:
    """The front optic of a refraction plate: clear, lit from behind, its front face
    ridged.

    The light shines through the planar back face z = -T (``light`` carries the
    plate's thickness and index); the front face z = 0 holds the facets, level
    sets of the front optic's phi:

    - ``exact``: the two-surface optic, L(s) + sigma |s - p| with L the Fermat
      path from the light through the back face
      (:class:`~specholo.optics.refraction.TwoSurfaceOptics`);
    - ``approx``: the paper's approximation, the Cartesian oval
      n |s - c| + sigma |s - p| about a centre of divergence c per stipple,
      fitted (least squares, :func:`~specholo.optics.refraction.fitted_centre`)
      to the in-plate rays that reach the stipple's region
      (:class:`~specholo.optics.refraction.CentredOptics`); with a sun the
      in-plate rays are parallel and it is the exact optic;
    - ``single``: the single-interface oval n |s - i| + sigma |s - p|, as if the
      light were inside the plate (the back face ignored;
      :meth:`~specholo.optics.surfaces.PointOptics.lens`).

    Args:
        points: (n, 3) stipples, mm.
        light: the light behind the plate.
        model: one of :data:`REFRACTION_MODELS`.
        samples: for ``approx``, (m, 3) points of the stipples' regions, mm.
        owner: for ``approx``, (m,) the stipple of each sample; a stipple without
            samples gets the paraxial centre.

    Returns:
        The optic (phi increasing toward the viewer; see :class:`FacingOptics`).
    """
    from specholo.optics.refraction import (
        CentredOptics,
        TwoSurfaceOptics,
        back_entry,
        paraxial_centre,
    )

    if not isinstance(light, BackLight):
        raise SpecholoError("a refraction plate is lit from behind (a BackLight)")
    if model not in REFRACTION_MODELS:
        raise SpecholoError(f"refraction model must be one of {', '.join(REFRACTION_MODELS)}, "
                            f"got {model!r}")
    points = np.asarray(points, dtype=float)
    plate = light.plate
    source = Source.from_light(light)
    if model == "single":
        return PointOptics.lens(points, source, plate.index, 1.0)
    if model == "exact" or source.position is None:
        return TwoSurfaceOptics.for_points(points, source, plate)
    n = len(points)
    centres = np.broadcast_to(paraxial_centre(source, plate), (n, 3)).copy()
    if samples is not None and owner is not None and len(samples):
        # Least squares over each stipple's rays: sum (I - d d^T) c = sum (I - d d^T) s.
        _, _, d = back_entry(source, samples, plate)
        proj = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
        mat = np.zeros((n, 3, 3))
        rhs = np.zeros((n, 3))
        np.add.at(mat, owner, proj)
        np.add.at(rhs, owner, np.einsum("kij,kj->ki", proj, samples))
        has = np.bincount(owner, minlength=n) >= 2
        # A whisker of regularisation toward the paraxial centre: a small region's
        # rays are nearly parallel, and the centre along them barely matters.
        lam = 1e-12 * np.trace(mat, axis1=1, axis2=2)[:, None]
        mat_r = mat + lam[..., None] * np.eye(3)[None]
        rhs_r = rhs + lam * centres
        with np.errstate(all="ignore"):
            fit = np.linalg.solve(mat_r[has], rhs_r[has][..., None])[..., 0]
        ok = np.all(np.isfinite(fit), axis=1) & (fit[:, 2] < plate.back_z)
        idx = np.flatnonzero(has)[ok]
        centres[idx] = fit[ok]
    sigma = np.where(points[:, 2] > 0.0, 1.0, -1.0)
    return CentredOptics(points, sigma, centres, float(plate.index))


def _refraction_kernel(optics: ImplicitOptics, light: BackLight,
                       n: int) -> tuple[bool, bool, np.ndarray, float]:
    """The raster kernel's description of a refraction optic's light term:
    (fermat, point, focus (n, 3), const); see :func:`_phi_refract`."""
    from specholo.optics.refraction import CentredOptics, TwoSurfaceOptics, back_entry

    source = Source.from_light(light)
    plate = light.plate
    if isinstance(optics, CentredOptics):
        return False, True, np.ascontiguousarray(optics.centres, dtype=float), 0.0
    if isinstance(optics, TwoSurfaceOptics):
        if source.position is not None:
            return True, True, np.tile(source.position, (n, 1)), 0.0
        # A plane wave in the plate: n d.s plus the constant TwoSurfaceOptics uses.
        _, _, d = back_entry(source, np.zeros((1, 3)), plate)
        const = float((-np.asarray(source.direction)[2] - plate.index * d[0, 2]) * plate.back_z)
        return False, False, np.tile(-d[0], (n, 1)), const
    if source.position is not None:
        return False, True, np.tile(source.position, (n, 1)), 0.0
    return False, False, np.tile(np.asarray(source.direction), (n, 1)), 0.0


@dataclass(frozen=True, eq=False)
class FacingOptics(ImplicitOptics):
    """Another optic's phi negated, so that it decreases toward the viewer (+z) as a
    mirror's does, which is how the ridged construction stacks its facets. The
    level sets and normals are the other optic's.

    Attributes:
        points: (n, 3) virtual points. sigma: (n,) their sides.
        inner: the optic.
    """

    points: np.ndarray
    sigma: np.ndarray
    inner: ImplicitOptics

    @classmethod
    def of(cls, inner: ImplicitOptics) -> FacingOptics:
        return cls(inner.points, inner.sigma, inner)

    def phi(self, s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
        return -self.inner.phi(s, stipple)

    def gradient(self, s: np.ndarray, stipple: np.ndarray | None = None) -> np.ndarray:
        return -self.inner.gradient(s, stipple)


@dataclass(frozen=True, eq=False)
class RidgedPlate:
    """A ridged full-parallax design: the plate's height field and what it shows.

    Attributes:
        heights: the plate (heights and the stipple of each cell).
        optics: every stipple's phi (the mirror's for the design's light; for a
            refraction plate its optic, negated so that it decreases toward the
            viewer as a mirror's does, :class:`FacingOptics`).
        kind: (n,) int8 :class:`~specholo.optics.surfaces.Kind` of each optic.
        level0: (n,) c0, the level of the facet through the region's centre.
        step: (n,) dc, the level step between facets.
        apex: (n, 3) apex q of the riser cones, mm (NaN if dropped).
        seed: (n, 2) seed of the region, mm (NaN if none).
        patch_area: (n,) area of the patch, mm^2.
        area: (n,) area kept, mm^2.
        kept: (n,) share of its visible views the stipple's region serves.
        dropped: (k,) stipples with no region.
        delta: shell half-thickness, mm.
        azimuths: (na,) eye-grid azimuths, radians.
        elevations: (ne,) eye-grid elevations, radians.
        visible: (n, na, ne) bool: which grid eyes see each stipple unoccluded.
        block_labels: (nby, nbx) int32 stipple of each block, -1 blank.
        block: block size, mm.
        timings: seconds per stage.
        model: "mirror", or the refraction model (:data:`REFRACTION_MODELS`).
    """

    heights: HeightMap
    optics: ImplicitOptics
    kind: np.ndarray
    level0: np.ndarray
    step: np.ndarray
    apex: np.ndarray
    seed: np.ndarray
    patch_area: np.ndarray
    area: np.ndarray
    kept: np.ndarray
    dropped: np.ndarray
    delta: float
    azimuths: np.ndarray
    elevations: np.ndarray
    visible: np.ndarray
    block_labels: np.ndarray
    block: float
    timings: dict[str, float] = field(default_factory=dict)
    model: str = "mirror"

    @property
    def points(self) -> np.ndarray:
        """(n, 3) stipples, mm."""
        return self.optics.points

    def summary(self) -> dict[str, Any]:
        """Figures of the design, for JSON."""
        live = self.area > 0
        visible_any = self.visible.any(axis=(1, 2))
        return {
            "stipples": len(self.points),
            "visible_in_range": int(visible_any.sum()),
            "kept_stipples": int(live.sum()),
            "dropped_stipples": self.dropped.tolist(),
            "median_kept_share": float(np.median(self.kept[live])) if live.any() else 0.0,
            "mean_kept_share": float(self.kept[visible_any].mean()) if visible_any.any()
            else 0.0,
            "plate_area_mm2": float(np.prod(self.heights.bounds[1] - self.heights.bounds[0])),
            "used_area_mm2": float(self.area.sum()),
            "patch_area_sum_mm2": float(self.patch_area.sum()),
            "shell_mm": [-2.0 * self.delta, 0.0],
            "deepest_mm": float(np.min(self.heights.z)),
            "resolution_mm": self.heights.resolution,
            "block_mm": self.block,
            "seconds": self.timings,
        }

    def stipple_records(self) -> list[dict[str, Any]]:
        """Per stipple: kind, kept share, areas, facet levels and riser apex."""
        names = {k.value: k.name.lower() for k in Kind}
        out = []
        for i in range(len(self.points)):
            out.append({
                "id": i, "kind": names[int(self.kind[i])],
                "sigma": int(self.optics.sigma[i]),
                "kept_share": float(self.kept[i]), "kept_area_mm2": float(self.area[i]),
                "patch_area_mm2": float(self.patch_area[i]),
                "level0_mm": float(self.level0[i]), "level_step_mm": float(self.step[i]),
                "apex_mm": [None if not np.isfinite(v) else float(v) for v in self.apex[i]],
            })
        return out


def eye_grid(viewer: Viewer, azimuths: np.ndarray, elevations: np.ndarray) -> np.ndarray:
    """Single eyes on the eyes' sphere (radius ``viewer.eye_radius`` about the
    plate centre raised to the eye height) at each azimuth and elevation.

    Args:
        viewer: the viewer.
        azimuths: (na,) radians. elevations: (ne,) radians.

    Returns:
        (na, ne, 3) eye positions, mm.
    """
    return view_eyes(viewer, np.asarray(azimuths, dtype=float)[:, None],
                     np.asarray(elevations, dtype=float)[None, :])


def view_eyes(viewer: Viewer, azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
    """Single eyes on the eyes' sphere at azimuths and elevations (radians,
    broadcast against each other); shape (..., 3), mm."""
    az, el = np.broadcast_arrays(np.asarray(azimuth, dtype=float),
                                 np.asarray(elevation, dtype=float))
    r = viewer.eye_radius
    return np.stack([r * np.cos(el) * np.sin(az), viewer.height + r * np.sin(el),
                     r * np.cos(el) * np.cos(az)], axis=-1)


def _grid(half: float, step: float) -> np.ndarray:
    n = max(1, math.ceil(2.0 * half / step - 1e-9)) + 1
    return np.linspace(-half, half, n)


def view_grid(viewer: Viewer, options: RidgeOptions) -> tuple[np.ndarray, np.ndarray]:
    """Azimuths and elevations (radians) of the eye grid: the head range widened by
    the eyes' offset from the head and half a degree."""
    el_half = options.elevation_range + math.radians(0.5)
    return _grid(viewer.design_range, options.view_step), _grid(el_half, options.view_step)


@kernel()
def _patches(points: np.ndarray, box: np.ndarray, bx0: float, by0: float, block: float,
             nbx: int, eye_y: float, radius: float, az0: float, daz: float, el0: float,
             del_: float, visible: np.ndarray, dot: np.ndarray,
             dot_reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Blocks whose sightline through each stipple reaches an eye that sees it
    (for a dot, the blocks its cap touches, if any grid eye sees it).

    Returns a CSR list: blocks of stipple j are cells[ptr[j]:ptr[j + 1]] (flat
    block index row * nbx + column).
    """
    n = points.shape[0]
    na = visible.shape[1]
    ne = visible.shape[2]
    ptr = np.zeros(n + 1, np.int64)
    for sweep in range(2):
        if sweep == 1:
            cells = np.empty(ptr[n], np.int64)
        else:
            cells = np.empty(0, np.int64)
        for j in range(n):
            px, py, pz = points[j, 0], points[j, 1], points[j, 2]
            ox, oy, oz = px, py - eye_y, pz
            oo = ox * ox + oy * oy + oz * oz - radius * radius
            count = 0
            for bj in range(box[j, 2], box[j, 3] + 1):
                cy = by0 + (bj + 0.5) * block
                for bi in range(box[j, 0], box[j, 1] + 1):
                    cx = bx0 + (bi + 0.5) * block
                    if dot[j]:
                        if (cx - px) ** 2 + (cy - py) ** 2 <= dot_reach * dot_reach:
                            if sweep == 1:
                                cells[ptr[j] + count] = bj * nbx + bi
                            count += 1
                        continue
                    dx, dy, dz = cx - px, cy - py, -pz
                    dd = dx * dx + dy * dy + dz * dz
                    od = ox * dx + oy * dy + oz * dz
                    disc = od * od - dd * oo
                    if disc < 0.0 or dd == 0.0:
                        continue
                    # The eye lies beyond the plate from a point behind it, and
                    # before the point (t < 0) when the point is in front.
                    if pz < 0.0:
                        t = (-od + math.sqrt(disc)) / dd
                        if t <= 1.0:
                            continue
                    else:
                        t = (-od - math.sqrt(disc)) / dd
                        if t >= 0.0:
                            continue
                    ex, ey, ez = px + t * dx, py + t * dy - eye_y, pz + t * dz
                    az = math.atan2(ex, ez)
                    el = math.asin(min(1.0, max(-1.0, ey / radius)))
                    ia = int(math.floor((az - az0) / daz + 0.5))
                    ie = int(math.floor((el - el0) / del_ + 0.5))
                    if ia < 0 or ia >= na or ie < 0 or ie >= ne or not visible[j, ia, ie]:
                        continue
                    if sweep == 1:
                        cells[ptr[j] + count] = bj * nbx + bi
                    count += 1
            if sweep == 0:
                ptr[j + 1] = ptr[j] + count
    return ptr, cells


def _eye_through(points: np.ndarray, xy: np.ndarray, viewer: Viewer) -> np.ndarray:
    """Eyes (k, 3) on the eyes' sphere on the sightlines from points (k, 3) through
    plate points (k, 2)."""
    c = np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)
    d = c - points
    o = points - np.array([0.0, viewer.height, 0.0])
    dd = np.sum(d * d, axis=1)
    od = np.sum(o * d, axis=1)
    oo = np.sum(o * o, axis=1) - viewer.eye_radius**2
    root = np.sqrt(np.maximum(od * od - dd * oo, 0.0))
    t = np.where(points[:, 2] < 0, (-od + root) / dd, (-od - root) / dd)
    return points + t[:, None] * d


@kernel(helper=True)
def _phi(x: float, y: float, z: float, px: float, py: float, pz: float, sg: float,
         point: bool, lx: float, ly: float, lz: float) -> tuple[float, float]:
    """phi of a mirror optic and d phi / dz at (x, y, z)."""
    dx, dy, dz = x - px, y - py, z - pz
    rp = math.sqrt(dx * dx + dy * dy + dz * dz)
    if point:
        ax, ay, az = x - lx, y - ly, z - lz
        ri = math.sqrt(ax * ax + ay * ay + az * az)
        return ri + sg * rp, az / ri + sg * dz / rp
    return -(lx * x + ly * y + lz * z) + sg * rp, -lz + sg * dz / rp


@kernel(helper=True)
def _back_path(x: float, y: float, z: float, ix: float, iy: float, iz: float, n: float,
               zback: float) -> tuple[float, float]:
    """The Fermat path from a point light behind the back face z = zback to a point
    inside the plate, min over b of |b - i| + n |s - b|, and its z-derivative
    n (z - zback) / |s - b| (the solve of
    :func:`~specholo.optics.refraction.back_entry`, for one point)."""
    a = zback - iz
    c = z - zback
    dx, dy = x - ix, y - iy
    rho = math.sqrt(dx * dx + dy * dy)
    r = n * rho * a / (c + n * a)
    lo, hi = 0.0, rho
    for _ in range(60):
        big_a = math.sqrt(r * r + a * a)
        big_c = math.sqrt((rho - r) ** 2 + c * c)
        f = r / big_a - n * (rho - r) / big_c
        if f < 0:
            lo = r
        elif f > 0:
            hi = r
        r_new = r - f / (a * a / big_a**3 + n * c * c / big_c**3)
        if not lo < r_new < hi:
            r_new = 0.5 * (lo + hi)
        if abs(r_new - r) <= 1e-13 * (1.0 + rho):
            r = r_new
            break
        r = r_new
    big_c = math.sqrt((rho - r) ** 2 + c * c)
    return math.sqrt(r * r + a * a) + n * big_c, n * c / big_c


@kernel(helper=True)
def _phi_refract(x: float, y: float, z: float, px: float, py: float, pz: float, sg: float,
                 fermat: bool, point: bool, fx: float, fy: float, fz: float, n: float,
                 zback: float, const: float) -> tuple[float, float]:
    """Minus the phi of a refraction optic, and its z-derivative, at (x, y, z).

    The light's term: the Fermat path through the back face from a point light f
    (``fermat`` and ``point``); n |s - f| about a point f (a Cartesian oval's
    focus); or -n f.s + const for light from the direction f (a plane wave)."""
    dx, dy, dz = x - px, y - py, z - pz
    rp = math.sqrt(dx * dx + dy * dy + dz * dz)
    if fermat and point:
        big_l, lz = _back_path(x, y, z, fx, fy, fz, n, zback)
    elif point:
        ax, ay, az = x - fx, y - fy, z - fz
        ri = math.sqrt(ax * ax + ay * ay + az * az)
        big_l, lz = n * ri, n * az / ri
    else:
        big_l, lz = -n * (fx * x + fy * y + fz * z) + const, -n * fz
    return -(big_l + sg * rp), -(lz + sg * dz / rp)


@kernel(parallel=True)
def _raster(block_labels: np.ndarray, ratio: int, x0: float, y0: float, res: float,
            points: np.ndarray, sigma: np.ndarray, level0: np.ndarray, step: np.ndarray,
            apex: np.ndarray, dot: np.ndarray, dot_radius: float, point: bool,
            light: np.ndarray, zbot: float, z_out: np.ndarray, lab_out: np.ndarray,
            refract: bool, fermat: bool, focus: np.ndarray, index: float, zback: float,
            const: float) -> None:
    """The sawtooth height field: for each cell, the top of the solid formed by
    each cone sector's material below its facet (a mirror's optic, or with
    ``refract`` a refraction optic, :func:`_phi_refract`, with the light's term
    per stipple in ``focus``)."""
    ny, nx = z_out.shape
    lx, ly, lz = light[0], light[1], light[2]
    for r in nb.prange(ny):
        y = y0 + r * res
        brow = r // ratio
        for c in range(nx):
            lab = block_labels[brow, c // ratio]
            lab_out[r, c] = lab
            if lab < 0:
                z_out[r, c] = 0.0
                continue
            x = x0 + c * res
            px, py, pz = points[lab, 0], points[lab, 1], points[lab, 2]
            if dot[lab]:
                rr2 = (x - px) ** 2 + (y - py) ** 2
                cap = math.sqrt(dot_radius**2 - rr2) - dot_radius if rr2 < dot_radius**2 \
                    else zbot
                z_out[r, c] = max(cap, zbot)
                continue
            sg = sigma[lab]
            c0 = level0[lab]
            dc = step[lab]
            qx, qy, qz = apex[lab, 0], apex[lab, 1], apex[lab, 2]
            fx, fy, fz = focus[lab, 0], focus[lab, 1], focus[lab, 2]
            if refract:
                f0, g0 = _phi_refract(x, y, 0.0, px, py, pz, sg, fermat, point, fx, fy, fz,
                                      index, zback, const)
            else:
                f0, g0 = _phi(x, y, 0.0, px, py, pz, sg, point, lx, ly, lz)
            # The plate point the cone from q projects the column's bottom onto.
            t = -zbot / (qz - zbot)
            if refract:
                fb, _ = _phi_refract(x + t * (qx - x), y + t * (qy - y), 0.0, px, py, pz, sg,
                                     fermat, point, fx, fy, fz, index, zback, const)
            else:
                fb, _ = _phi(x + t * (qx - x), y + t * (qy - y), 0.0, px, py, pz, sg, point,
                             lx, ly, lz)
            k_top = math.ceil((f0 - c0) / dc)
            k_bot = math.ceil((fb - c0) / dc)
            k_lo = min(k_top, k_bot)
            k_hi = min(max(k_top, k_bot), k_lo + MAX_SECTORS)
            best = zbot
            for k in range(k_lo, k_hi + 1):
                c_lo = c0 + (k - 1) * dc
                c_hi = c0 + k * dc
                # The column's depths in sector k (the cone value is linear in z
                # to ~1e-4 of a sector over the shell).
                if fb == f0:
                    z_lo, z_hi = zbot, 0.0
                else:
                    za = zbot * (c_lo - f0) / (fb - f0)
                    zb = zbot * (c_hi - f0) / (fb - f0)
                    z_lo = max(min(za, zb), zbot)
                    z_hi = min(max(za, zb), 0.0)
                    if z_hi < z_lo:
                        continue
                # The facet phi = c_hi over this column (Newton from the plate).
                z = (f0 - c_hi) / g0
                for _ in range(6):
                    if refract:
                        f, g = _phi_refract(x, y, z, px, py, pz, sg, fermat, point, fx, fy,
                                            fz, index, zback, const)
                    else:
                        f, g = _phi(x, y, z, px, py, pz, sg, point, lx, ly, lz)
                    z -= (f - c_hi) / g
                top = min(z, z_hi)
                if top >= z_lo and top > best:
                    best = top
            z_out[r, c] = min(best, 0.0)


def design_ridged(points: np.ndarray, normals: np.ndarray | None, mesh: Any, setup: Setup,
                  options: RidgeOptions | None = None,
                  plate: np.ndarray | None = None,
                  refraction: str | None = None) -> RidgedPlate:
    """Design a ridged full-parallax plate for stipples of a model.

    A mirror for a light in front (a :class:`~specholo.setup.Light`); for a light
    behind the plate (a :class:`~specholo.setup.BackLight`) a clear refraction
    plate, its front face ridged with the optic ``refraction`` names
    (:func:`refraction_optics`).

    Args:
        points: (n, 3) stipples, mm.
        normals: (n, 3) their outward face normals (None for a point cloud).
        mesh: the occluding mesh (a :class:`~specholo.scene.mesh.Mesh` or a trimesh) or None.
        setup: light and viewer (the viewer's azimuth range and distance).
        options: the construction's settings.
        plate: (2, 2) plate corners, mm; default the patches' extent plus the margin.
        refraction: with a light behind the plate, the front optic's model
            (:data:`REFRACTION_MODELS`, default ``"exact"``); None for a mirror.

    Returns:
        The plate.

    Raises:
        SpecholoError: on bad input, or a raster larger than ``options.max_cells``.
    """
    import time

    from specholo.visibility.occlusion import visible as ray_visible

    opts = options or RidgeOptions()
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3 or not np.all(np.isfinite(points)):
        raise SpecholoError(f"stipples must be finite with shape (n, 3), got {points.shape}")
    n = len(points)
    viewer = setup.viewer
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    source = Source.from_light(setup.light)
    back = setup.light if isinstance(setup.light, BackLight) else None
    if back is None and refraction is not None:
        raise SpecholoError("a refraction plate is lit from behind: its light must be a "
                            "BackLight")
    model = "mirror" if back is None else (refraction or "exact")
    optics: ImplicitOptics
    if back is None:
        mirror = PointOptics.mirror(points, source)
        optics = mirror
        kind = mirror.kinds(tol=opts.dot_depth)
    else:
        # Built once the regions are known (the approximation fits a centre to each).
        optics = refraction_optics(points, back, "exact" if model == "approx" else model)
        kind = np.full(n, Kind.TWO_SURFACE if model == "exact" else Kind.CARTESIAN_OVAL,
                       dtype=np.int8)
        kind[np.abs(points[:, 2]) <= opts.dot_depth] = Kind.DOT
    dot = kind == Kind.DOT
    nearest_eye = viewer.distance * math.cos(viewer.design_range)
    if n and points[:, 2].max() >= 0.9 * nearest_eye:
        raise SpecholoError(f"stipples reach z = {points[:, 2].max():.1f} mm, too close to the "
                            f"eyes (nearest eye depth {nearest_eye:.1f} mm)")

    # Visibility on the eye grid.
    az, el = view_grid(viewer, opts)
    eyes = eye_grid(viewer, az, el).reshape(-1, 3)
    g = len(eyes)
    if mesh is None or n == 0:
        seen = np.ones((n, g), dtype=bool)
    elif normals is None:
        raise SpecholoError("stipples on a mesh need their face normals for occlusion tests")
    else:
        seen = ray_visible(mesh, np.repeat(points, g, axis=0), np.repeat(normals, g, axis=0),
                           np.tile(eyes, (n, 1))).reshape(n, g)
    timings["visibility"] = time.perf_counter() - t0

    # Patches on the block raster.
    t0 = time.perf_counter()
    cross = sightline_crossing(np.broadcast_to(eyes, (n, g, 3)),
                               np.broadcast_to(points[:, None, :], (n, g, 3)))[..., :2]
    spacing = (opts.view_step * viewer.eye_radius * np.abs(points[:, 2])
               / np.maximum(viewer.eye_radius - np.abs(points[:, 2]), 1.0))
    live = seen.any(axis=1)
    lo = np.full((n, 2), np.nan)
    hi = np.full((n, 2), np.nan)
    if live.any():
        masked = np.where(seen[live][..., None], cross[live], np.nan)
        pad = spacing[live, None] + opts.block
        lo[live] = np.nanmin(masked, axis=1) - pad
        hi[live] = np.nanmax(masked, axis=1) + pad
    if plate is None:
        if live.any():
            corner_lo = np.min(lo[live], axis=0) - opts.margin
            corner_hi = np.max(hi[live], axis=0) + opts.margin
        else:
            corner_lo, corner_hi = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
        # Whole blocks, symmetric about the plate centre.
        half = np.ceil(np.maximum(-corner_lo, corner_hi) / opts.block) * opts.block
        plate = np.stack([-half, half])
    plate = np.asarray(plate, dtype=float)
    if plate.shape != (2, 2) or not np.all(np.isfinite(plate)) or np.any(plate[1] <= plate[0]):
        raise SpecholoError(f"plate must be [[x0, y0], [x1, y1]] with x1 > x0 and y1 > y0, "
                            f"got {plate.tolist()}")
    nbx, nby = (np.floor((plate[1] - plate[0]) / opts.block + 1e-9).astype(int)).tolist()
    ratio = opts.ratio
    nx, ny = nbx * ratio, nby * ratio
    if nx * ny > opts.max_cells:
        raise SpecholoError(f"a {nx} x {ny} raster is too large (at most {opts.max_cells:,} "
                            f"cells): coarsen the resolution {opts.resolution:g} mm or narrow "
                            "the view range")
    bx0, by0 = plate[0]
    box = np.zeros((n, 4), np.int64)
    box[:, 0] = np.floor((np.nan_to_num(lo[:, 0], nan=1.0) - bx0) / opts.block)
    box[:, 1] = np.floor((np.nan_to_num(hi[:, 0], nan=0.0) - bx0) / opts.block)
    box[:, 2] = np.floor((np.nan_to_num(lo[:, 1], nan=1.0) - by0) / opts.block)
    box[:, 3] = np.floor((np.nan_to_num(hi[:, 1], nan=0.0) - by0) / opts.block)
    # A dot's cap spans its radius about p, whatever the eye.
    reach = opts.dot_radius + 0.75 * opts.block
    box[dot & live, 0] = np.floor((points[dot & live, 0] - reach - bx0) / opts.block)
    box[dot & live, 1] = np.floor((points[dot & live, 0] + reach - bx0) / opts.block)
    box[dot & live, 2] = np.floor((points[dot & live, 1] - reach - by0) / opts.block)
    box[dot & live, 3] = np.floor((points[dot & live, 1] + reach - by0) / opts.block)
    box[:, 0::2] = np.maximum(box[:, 0::2], 0)
    box[:, 1] = np.minimum(box[:, 1], nbx - 1)
    box[:, 3] = np.minimum(box[:, 3], nby - 1)
    box[~live] = [0, -1, 0, -1]
    vis_grid = np.ascontiguousarray(seen.reshape(n, len(az), len(el)))
    daz = float(az[1] - az[0]) if len(az) > 1 else 1.0
    del_ = float(el[1] - el[0]) if len(el) > 1 else 1.0
    ptr, cells = _patches(points, box, float(bx0), float(by0), float(opts.block), nbx,
                          float(viewer.height), float(viewer.eye_radius), float(az[0]), daz,
                          float(el[0]), del_, vis_grid, dot, float(reach))
    counts = np.diff(ptr)
    owner = np.repeat(np.arange(n), counts)
    timings["patches"] = time.perf_counter() - t0

    # Seeds and regions.
    t0 = time.perf_counter()
    aspect = opts.aspect if opts.aspect is not None else region_aspect(
        points, counts, np.unique(cells).size, viewer, opts.block)
    seed_block = _seeds(ptr, cells, counts, nbx, nby, aspect, points, viewer,
                        opts.elevation_range, bx0, by0, opts.block)
    block_labels = _assign(cells, owner, seed_block, nbx, nby, aspect)
    region = np.bincount(block_labels[block_labels >= 0], minlength=n)
    kept = np.where(counts > 0, region / np.maximum(counts, 1), 0.0)
    block_area = opts.block**2
    dropped = np.flatnonzero(region == 0)
    timings["assignment"] = time.perf_counter() - t0

    # Facet parameters per stipple.
    t0 = time.perf_counter()
    centres_x = bx0 + (np.arange(nbx) + 0.5) * opts.block
    centres_y = by0 + (np.arange(nby) + 0.5) * opts.block
    flat = np.flatnonzero(block_labels.ravel() >= 0)
    lab = block_labels.ravel()[flat]
    bxy = np.stack([centres_x[flat % nbx], centres_y[flat // nbx]], axis=1)
    if back is not None:
        samples = owner_s = None
        if model == "approx":
            # Each block's centre and corners, in the middle of the shell.
            offsets = 0.5 * opts.block * np.array([[0, 0], [-1, -1], [-1, 1], [1, -1], [1, 1]])
            sxy = (bxy[:, None, :] + offsets[None]).reshape(-1, 2)
            samples = np.concatenate([sxy, np.full((len(sxy), 1), -opts.delta)], axis=1)
            owner_s = np.repeat(lab, len(offsets))
        optics = FacingOptics.of(refraction_optics(points, back, model, samples, owner_s))
    centroid = np.full((n, 2), np.nan)
    for axis in range(2):
        centroid[:, axis] = np.bincount(lab, bxy[:, axis], minlength=n) / np.maximum(region, 1)
    has = region > 0
    apex = np.full((n, 3), np.nan)
    apex[has] = _eye_through(points[has], centroid[has], viewer)
    level0 = np.zeros(n)
    level0[has] = optics.phi(np.concatenate([centroid[has], np.zeros((int(has.sum()), 1))],
                                            axis=1), np.flatnonzero(has))
    step = np.full(n, 2.0 * opts.delta)
    if flat.size:
        s = np.concatenate([bxy, np.full((len(bxy), 1), -opts.delta)], axis=1)
        grad = optics.gradient(s, lab)
        hz = -grad[:, 2]
        tilt = np.hypot(grad[:, 0], grad[:, 1]) / hz
        lean = (np.hypot(*(apex[lab, :2] - bxy).T) / apex[lab, 2])
        factor = hz * np.maximum(1.0 - tilt * lean, MIN_LEAN_FACTOR)
        worst = np.full(n, np.inf)
        np.minimum.at(worst, lab, factor)
        step[has] = 2.0 * opts.delta * DEPTH_MARGIN * worst[has]
    timings["facets"] = time.perf_counter() - t0

    # The raster.
    t0 = time.perf_counter()
    z = np.zeros((ny, nx), np.float32)
    labels = np.full((ny, nx), -1, np.int32)
    light = (source.position if source.position is not None else source.direction)
    safe_apex = np.where(np.isfinite(apex), apex, np.array([0.0, 0.0, viewer.distance]))
    if back is None:
        fermat, point, focus, const = False, source.is_point, np.zeros((n, 3)), 0.0
        index, zback = 1.0, 0.0
    else:
        inner = optics.inner if isinstance(optics, FacingOptics) else optics
        fermat, point, focus, const = _refraction_kernel(inner, back, n)
        index, zback = float(back.index), -float(back.thickness)
    _raster(np.ascontiguousarray(block_labels), ratio, float(bx0 + 0.5 * opts.resolution),
            float(by0 + 0.5 * opts.resolution), float(opts.resolution), points,
            optics.sigma, level0, step, safe_apex, dot, float(opts.dot_radius),
            source.is_point, np.asarray(light, dtype=float), -2.0 * opts.delta, z, labels,
            back is not None, fermat, np.ascontiguousarray(focus, dtype=float), index, zback,
            const)
    heights = HeightMap(z, np.array([bx0 + 0.5 * opts.resolution,
                                     by0 + 0.5 * opts.resolution]), opts.resolution, labels)
    timings["raster"] = time.perf_counter() - t0
    seed_xy = np.full((n, 2), np.nan)
    ok = seed_block >= 0
    seed_xy[ok, 0] = centres_x[seed_block[ok] % nbx]
    seed_xy[ok, 1] = centres_y[seed_block[ok] // nbx]
    return RidgedPlate(
        heights=heights, optics=optics, kind=kind, level0=level0, step=step, apex=apex,
        seed=seed_xy, patch_area=counts * block_area, area=region * block_area, kept=kept,
        dropped=dropped, delta=float(opts.delta), azimuths=az, elevations=el,
        visible=vis_grid, block_labels=block_labels, block=float(opts.block),
        timings=timings, model=model)


def region_aspect(points: np.ndarray, counts: np.ndarray, union: int, viewer: Viewer,
                  block: float) -> float:
    """The horizontal stretch that makes the regions :data:`EYE_SPAN` times as
    wide as a head's two sightlines through a stipple lie apart on the plate
    (the median stipple's, IPD |p_z| / (D - p_z)), at the area each region gets
    (the patches' union over the stipples with a patch); within [1, :data:`MAX_ASPECT`].

    Args:
        points: (n, 3) stipples, mm.
        counts: (n,) blocks in each stipple's patch (0: none).
        union: blocks in the patches' union.
        viewer: the viewer (IPD, eye distance).
        block: block side, mm.
    """
    live = counts > 0
    if not live.any() or union <= 0:
        return 1.0
    z = points[live, 2]
    apart = viewer.ipd * np.abs(z) / np.maximum(viewer.eye_radius - z, 1.0)
    width = EYE_SPAN * float(np.median(apart)) / block  # blocks
    area = union / float(live.sum())  # blocks per region
    return float(min(max(width * width / area, 1.0), MAX_ASPECT))


def _seeds(ptr: np.ndarray, cells: np.ndarray, counts: np.ndarray, nbx: int, nby: int,
           aspect: float, points: np.ndarray, viewer: Viewer, elevation_range: float,
           bx0: float, by0: float, block: float) -> np.ndarray:
    """One seed block per stipple with a patch, spread over the plate and the views.

    Each stipple gets a target view from a low-discrepancy (R2) sequence over
    the heads' range of azimuth and elevation, so that the views the regions
    serve cover the range evenly. Stipples with the smallest patches choose
    first; each takes, among its patch blocks at least r from every seed so
    far (in the stretched metric), the one nearest its target view's sightline
    crossing; if there is none, its block farthest from the seeds. r is set so
    that the seeds' disks would fill the patches' union about evenly.
    """
    n = len(counts)
    seed = np.full(n, -1, np.int64)
    union = np.unique(cells).size
    live = np.flatnonzero(counts > 0)
    if live.size == 0:
        return seed
    # Per-seed area in the stretched metric, in block units.
    r = 0.75 * math.sqrt(union / aspect / live.size)
    r2 = r * r
    dist = np.full((nby, nbx), np.inf)
    wx = math.ceil(2.0 * r * aspect) + 1
    wy = math.ceil(2.0 * r) + 1
    order = live[np.argsort(counts[live], kind="stable")]
    k = np.arange(1, len(order) + 1)
    u = np.mod(0.5 + k * 0.7548776662466927, 1.0)
    v = np.mod(0.5 + k * 0.5698402909980532, 1.0)
    target_eyes = view_eyes(viewer, (2.0 * u - 1.0) * viewer.half_range,
                            (2.0 * v - 1.0) * elevation_range)
    target = sightline_crossing(target_eyes, points[order])[:, :2]
    tx = (target[:, 0] - bx0) / block - 0.5
    ty = (target[:, 1] - by0) / block - 0.5
    for q, j in enumerate(order):
        cand = cells[ptr[j]:ptr[j + 1]]
        ci, cj = cand % nbx, cand // nbx
        d = dist[cj, ci]
        far = d >= r2
        if far.any():
            off = ((ci - tx[q]) / aspect) ** 2 + (cj - ty[q]) ** 2
            pick = int(np.argmin(np.where(far, off, np.inf)))
        else:
            pick = int(np.argmax(d))
        seed[j] = cand[pick]
        si, sj = int(ci[pick]), int(cj[pick])
        x0, x1 = max(si - wx, 0), min(si + wx + 1, nbx)
        y0, y1 = max(sj - wy, 0), min(sj + wy + 1, nby)
        gx = ((np.arange(x0, x1) - si) / aspect) ** 2
        gy = (np.arange(y0, y1) - sj) ** 2.0
        np.minimum(dist[y0:y1, x0:x1], gy[:, None] + gx[None, :], out=dist[y0:y1, x0:x1])
    return seed


def _assign(cells: np.ndarray, owner: np.ndarray, seed: np.ndarray, nbx: int, nby: int,
            aspect: float) -> np.ndarray:
    """Each block to the stipple with the nearest seed among those it serves."""
    labels = np.full(nbx * nby, -1, np.int32)
    ok = seed[owner] >= 0
    cells, owner = cells[ok], owner[ok]
    if cells.size == 0:
        return labels.reshape(nby, nbx)
    s = seed[owner]
    d2 = ((cells % nbx - s % nbx) / aspect) ** 2 + (cells // nbx - s // nbx) ** 2.0
    order = np.lexsort((owner, d2, cells))
    first = order[np.r_[True, cells[order][1:] != cells[order][:-1]]]
    labels[cells[first]] = owner[first]
    return labels.reshape(nby, nbx)


@dataclass(frozen=True)
class StereoBudget:
    """How many stipples a ridged plate can show one head, from its regions.

    One plate cell sends one ray, so each eye sees about (plate area) / (one
    stipple's patch) stipples whatever their number; both eyes see a stipple
    only where its region holds both their sightlines. Found on the heads'
    grid, from the regions' geometry (the physics of ``verify`` then loses
    the glints that riser shadows or region edges cut).

    Attributes:
        per_head: mean stipples whose regions hold both eyes' sightlines (and
            both eyes see them), over the heads.
        per_eye: mean stipples whose regions hold one eye's sightline.
        ceiling: plate area over the median patch area: what each eye could
            see if every cell served a stipple in view.
        eye_spacing: median distance on the plate between a stipple's two
            eyes' sightlines, mm (a region narrower than this never holds both).
        region_width: median width (x extent) of the regions, mm.
        heads: heads counted.
    """

    per_head: float
    per_eye: float
    ceiling: float
    eye_spacing: float
    region_width: float
    heads: int

    def as_dict(self) -> dict[str, float]:
        return {"stipples_per_head_both_eyes": self.per_head,
                "stipples_per_eye": self.per_eye, "ceiling_per_eye": self.ceiling,
                "eye_spacing_on_plate_mm": self.eye_spacing,
                "region_width_mm": self.region_width, "heads": float(self.heads)}


def stereo_budget(plate: RidgedPlate, viewer: Viewer, elevation_range: float,
                  step: float = math.radians(2.0)) -> StereoBudget:
    """The plate's :class:`StereoBudget` over heads every ``step`` radians within
    the viewer's azimuth range and +-``elevation_range``."""
    points = plate.points
    n = len(points)
    labels = plate.block_labels
    nby, nbx = labels.shape
    x0, y0 = plate.heights.bounds[0] - 0.5 * plate.heights.resolution
    az = _grid(viewer.half_range, step)
    el = _grid(elevation_range, step)
    half = viewer.eye_half_angle
    grid_az, grid_el = plate.azimuths, plate.elevations
    ids = np.arange(n)
    both_total = eye_total = 0.0
    spacing: list[np.ndarray] = []

    def look(eye: np.ndarray, a: float, e: float) -> tuple[np.ndarray, np.ndarray]:
        cross = sightline_crossing(np.broadcast_to(eye, (n, 3)), points)[:, :2]
        bx = np.floor((cross[:, 0] - x0) / plate.block).astype(np.int64)
        by = np.floor((cross[:, 1] - y0) / plate.block).astype(np.int64)
        inside = (bx >= 0) & (bx < nbx) & (by >= 0) & (by < nby)
        mine = np.zeros(n, dtype=bool)
        mine[inside] = labels[by[inside], bx[inside]] == ids[inside]
        ia = int(np.clip(np.rint(np.interp(a, grid_az, np.arange(len(grid_az)))), 0,
                         len(grid_az) - 1))
        ie = int(np.clip(np.rint(np.interp(e, grid_el, np.arange(len(grid_el)))), 0,
                         len(grid_el) - 1))
        return mine & plate.visible[:, ia, ie], cross

    for a in az:
        for e in el:
            left, cl = look(view_eyes(viewer, a - half, e), a - half, e)
            right, cr = look(view_eyes(viewer, a + half, e), a + half, e)
            both_total += float(np.count_nonzero(left & right))
            eye_total += 0.5 * float(np.count_nonzero(left) + np.count_nonzero(right))
            spacing.append(np.hypot(*(cl - cr).T))
    heads = len(az) * len(el)
    live = plate.area > 0
    ceiling = 0.0
    if live.any():
        ceiling = float(np.prod(plate.heights.bounds[1] - plate.heights.bounds[0])
                        / np.median(plate.patch_area[live]))
    flat = labels.ravel()
    has = flat >= 0
    cols = np.flatnonzero(has) % nbx
    lo = np.full(n, np.iinfo(np.int64).max)
    hi = np.full(n, -1)
    np.minimum.at(lo, flat[has], cols)
    np.maximum.at(hi, flat[has], cols)
    width = (hi - lo + 1)[live] * plate.block
    return StereoBudget(both_total / heads, eye_total / heads, ceiling,
                        float(np.median(np.concatenate(spacing))) if spacing else 0.0,
                        float(np.median(width)) if width.size else 0.0, heads)

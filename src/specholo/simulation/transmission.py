"""Glints of a clear plate lit from behind (refraction holograms), found by tracing
the light through it.

The plate (index n) has a planar back face z = -T and its front face, the
height field, at z <= 0; the light (:class:`~specholo.setup.BackLight`) is
behind it. For an eye and each cell s of the front face:

1. The ray from the light that reaches s inside the plate is found from the
   geometry alone: in the plane of incidence, the angle of incidence at the
   back face whose refracted ray ends at s (bisection on the horizontal reach
   a tan(theta) + c tan(theta')); its direction in the plate is the incoming
   ray refracted at the back face by Snell's law in vector form
   (:func:`refract`, the numba twin of :func:`specholo.optics.surfaces.refract`).
   A sun's rays are refracted the same way, all alike.
2. That ray is refracted again at the cell, through the cell's normal from the
   height field (as :mod:`specholo.simulation.heightfield` takes it, one-sided
   across risers), into air; a totally reflected ray is lost.
3. The cell shines for the eye with a Gaussian lobe of the angle between the
   exit ray and the direction to the eye, of angular sigma twice ``lobe``: the
   spread of the ray a mirror facet of roughness ``lobe`` reflects, so spots
   are as large on both kinds of plate. (A refracting facet turns its exit ray
   by about n - 1 times a turn of its normal: for acrylic that is a facet
   roughness of about 4 ``lobe``.)
4. The light must reach s through glass, and the eye must see s through air:
   the in-plate ray is marched back below the deepest cut (a stretch in air
   means the light came through a riser), and the ray to the eye forward until
   it rises above the plate (a riser in the way hides the cell).

Nothing of the design's optics is used: no level sets, no Fermat path. The lit
cells are grouped into glints and measured (centroid or fit) exactly as on a
mirror plate (:func:`specholo.simulation.heightfield.find_field_glints`, which
hands a :class:`~specholo.setup.BackLight` over to :func:`find_transmitted_glints`).
Only the tiles whose facet slopes come near the normal that would send the
light to the eye (n d - u, Snell's law solved for the normal) are searched.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from specholo._compiling import kernel
from specholo.errors import SpecholoError
from specholo.setup import BackLight
from specholo.simulation.cut import MIN_COVERAGE
from specholo.simulation.field_glints import (
    CUTOFF,
    ESTIMATES,
    LOBE,
    MAX_CELL_TURN,
    FieldGlints,
    SlopeIndex,
    _blocked,
    _cell_turn,
    _gather,
    _height_at,
    _lobe_over_cell,
    _normal,
)
from specholo.toolpaths.heightmap import HeightMap

#: Angular sigma of the exit ray's lobe, in units of a mirror plate's lobe (whose
#: reflected ray spreads twice as much as its normals).
EXIT_LOBE = 2.0
#: Safety factor on the slope reach of the tile search (the exit ray's sensitivity
#: to the normal varies with the incidence).
REACH_SAFETY = 2.0


@kernel()
def refract(dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, eta1: float,
            eta2: float) -> tuple[float, float, float, bool]:
    """Snell's law in vector form for one ray (see
    :func:`specholo.optics.surfaces.refract`): the unit direction (dx, dy, dz) in
    the medium of index eta1 through a surface of normal (nx, ny, nz) (any length,
    either orientation) into index eta2; False where it is totally reflected."""
    q = math.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx / q, ny / q, nz / q
    c = -(dx * nx + dy * ny + dz * nz)
    if c < 0.0:
        nx, ny, nz, c = -nx, -ny, -nz, -c
    r = eta1 / eta2
    k = 1.0 - r * r * (1.0 - c * c)
    if k < 0.0:
        return 0.0, 0.0, 0.0, False
    f = r * c - math.sqrt(k)
    return r * dx + f * nx, r * dy + f * ny, r * dz + f * nz, True


@kernel()
def in_plate(x: float, y: float, z: float, light: np.ndarray, point: bool, n: float,
             zback: float) -> tuple[float, float, float]:
    """Unit direction, inside the plate, of the light that reaches (x, y, z) there
    (zback < z): the incoming ray refracted at the back face z = zback.

    For a point light i (behind the back face), the entry point lies in the
    vertical plane through i and s, at the angle of incidence theta whose
    horizontal reach a tan(theta) + c tan(theta') (a the light's depth below the
    back face, c the point's height above it, sin theta' = sin theta / n)
    equals their horizontal distance: found by bisection on sin theta. For a
    sun (``light`` the direction toward it) the incoming ray is -light."""
    if point:
        a = zback - light[2]
        c = z - zback
        hx, hy = x - light[0], y - light[1]
        rho = math.sqrt(hx * hx + hy * hy)
        if rho == 0.0:
            ix, iy, iz = 0.0, 0.0, 1.0
        else:
            lo, hi = 0.0, 1.0
            for _ in range(80):
                u = 0.5 * (lo + hi)
                w = u / n
                reach = a * u / math.sqrt(1.0 - u * u) + c * w / math.sqrt(1.0 - w * w)
                if reach < rho:
                    lo = u
                else:
                    hi = u
                if hi - lo <= 1e-17:
                    break
            u = 0.5 * (lo + hi)
            # The incoming ray from i to the entry point b = i + a (tan theta e_rho, 1).
            tan_t = u / math.sqrt(1.0 - u * u)
            ix, iy, iz = a * tan_t * hx / rho, a * tan_t * hy / rho, a
            q = math.sqrt(ix * ix + iy * iy + iz * iz)
            ix, iy, iz = ix / q, iy / q, iz / q
    else:
        ix, iy, iz = -light[0], -light[1], -light[2]
    dx, dy, dz, _ = refract(ix, iy, iz, 0.0, 0.0, 1.0, 1.0, n)
    return dx, dy, dz


@kernel(helper=True)
def _through_glass(z: np.ndarray, x0: float, y0: float, res: float, sx: float, sy: float,
                   sz: float, dx: float, dy: float, dz: float, floor: float) -> bool:
    """Whether the in-plate ray reaching (sx, sy, sz) along the unit (dx, dy, dz)
    came through glass all the way from below the deepest cut ``floor`` (marched
    back in half-cell steps; a point above the height field is in air)."""
    horiz = math.sqrt(dx * dx + dy * dy)
    if dz <= 0.0:
        return False
    if horiz * (sz - floor) <= 1e-12 * dz:
        return True
    dt = 0.5 * res / horiz
    t = dt
    while True:
        pz = sz - t * dz
        if pz <= floor:
            return True
        if _height_at(z, x0, y0, res, sx - t * dx, sy - t * dy) < pz - 1e-7:
            return False
        t += dt


@kernel(helper=True)
def _tile_target(x0: float, y0: float, res: float, tile: int, ty: int, tx: int,
                 eye: np.ndarray, light: np.ndarray, point: bool, n: float, zback: float,
                 reach: float, spread: float) -> tuple[float, float, float]:
    """Slope of the normal that would send the light to the eye at a tile's centre
    (n d - u, Snell's law solved for the normal), and how far (in slope) a cell of
    the tile may be from it and still glint; a negative reach for a tile where
    that normal would face sideways or away (no height field can glint)."""
    cy = y0 + (ty * tile + 0.5 * (tile - 1)) * res
    cx = x0 + (tx * tile + 0.5 * (tile - 1)) * res
    ux, uy, uz = eye[0] - cx, eye[1] - cy, eye[2]
    dist = math.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / dist, uy / dist, uz / dist
    dx, dy, dz = in_plate(cx, cy, 0.0, light, point, n, zback)
    mx, my, mz = n * dx - ux, n * dy - uy, n * dz - uz
    if mz <= 1e-9:
        return 0.0, 0.0, -1.0
    mu = math.sqrt(mx * mx + my * my + mz * mz)
    gx, gy = -mx / mz, -my / mz
    span = 0.75 * tile * res + spread
    turn = span / dist
    if point:
        dl = math.sqrt((light[0] - cx) ** 2 + (light[1] - cy) ** 2 + light[2] ** 2)
        turn += n * span / dl
    m = REACH_SAFETY * (reach + 2.0 * turn / mu) * (1.0 + gx * gx + gy * gy)
    return gx, gy, m


@kernel(parallel=True)
def _candidate_tiles(box: np.ndarray, x0: float, y0: float, res: float, tile: int,
                     eye: np.ndarray, light: np.ndarray, point: bool, n: float,
                     zback: float, reach: float, spread: float) -> np.ndarray:
    """1 for tiles with a slope box within reach of the slope that would glint."""
    nty, ntx, k_boxes = box.shape[0], box.shape[1], box.shape[2]
    flag = np.zeros((nty, ntx), np.uint8)
    for ty in nb.prange(nty):
        for tx in range(ntx):
            if box[ty, tx, 0, 0] > box[ty, tx, 0, 1]:
                continue
            gx, gy, m = _tile_target(x0, y0, res, tile, ty, tx, eye, light, point, n, zback,
                                     reach, spread)
            if m < 0.0:
                continue
            for k in range(k_boxes):
                if (box[ty, tx, k, 0] - m <= gx <= box[ty, tx, k, 1] + m
                        and box[ty, tx, k, 2] - m <= gy <= box[ty, tx, k, 3] + m):
                    flag[ty, tx] = 1
                    break
    return flag


@kernel(helper=True)
def _exit_mismatch(nx_: float, ny_: float, nz_: float, x: float, y: float, h: float,
                   eye: np.ndarray, light: np.ndarray, point: bool, n: float,
                   zback: float) -> tuple[float, float, bool, float, float, float]:
    """The exit ray's miss of the eye at a cell of normal (nx_, ny_, nz_), in a
    tangent basis of the direction to the eye (m1, m2), whether light leaves
    toward the eye (no total reflection), and the in-plate direction."""
    dx, dy, dz = in_plate(x, y, h, light, point, n, zback)
    tx, ty, tz, ok = refract(dx, dy, dz, nx_, ny_, nz_, n, 1.0)
    if not ok:
        return 0.0, 0.0, False, dx, dy, dz
    ux, uy, uz = eye[0] - x, eye[1] - y, eye[2] - h
    r = math.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / r, uy / r, uz / r
    q = math.sqrt(ux * ux + uz * uz)
    e1x, e1z = uz / q, -ux / q
    e2x, e2y, e2z = uy * e1z, uz * e1x - ux * e1z, -uy * e1x
    m1 = tx * e1x + tz * e1z
    m2 = tx * e2x + ty * e2y + tz * e2z
    # The exit ray must head toward the eye, not away from it.
    if tx * ux + ty * uy + tz * uz <= 0.0:
        return 0.0, 0.0, False, dx, dy, dz
    return m1, m2, True, dx, dy, dz


@kernel(helper=True)
def _slope_mismatch(gx: float, gy: float, x: float, y: float, h: float, eye: np.ndarray,
                    light: np.ndarray, point: bool, n: float,
                    zback: float) -> tuple[float, float, bool]:
    """:func:`_exit_mismatch` for the normal of slope (gx, gy)."""
    norm = math.sqrt(gx * gx + gy * gy + 1.0)
    m1, m2, lit, _, _, _ = _exit_mismatch(-gx / norm, -gy / norm, 1.0 / norm, x, y, h, eye,
                                          light, point, n, zback)
    return m1, m2, lit


@kernel(helper=True)
def _mismatch_gradient(z: np.ndarray, labels: np.ndarray, j: int, i: int, res: float,
                       gx: float, gy: float, x: float, y: float, h: float, eye: np.ndarray,
                       light: np.ndarray, point: bool, n: float,
                       zback: float) -> tuple[float, float, float, float, bool]:
    """The exit ray's miss turning across the cell, per mm (j11, j12, j21, j22),
    as the cell's facet turns (:func:`~specholo.simulation.field_glints._cell_turn`);
    False where the facet does not turn or a probe's ray is lost."""
    txx, tyy, txy = _cell_turn(z, labels, j, i, res)
    if txx == 0.0 and tyy == 0.0 and txy == 0.0:
        return 0.0, 0.0, 0.0, 0.0, False
    a1, a2, la = _slope_mismatch(gx + 0.5 * txx, gy + 0.5 * txy, x, y, h, eye, light, point,
                                 n, zback)
    b1, b2, lb = _slope_mismatch(gx - 0.5 * txx, gy - 0.5 * txy, x, y, h, eye, light, point,
                                 n, zback)
    c1, c2, lc = _slope_mismatch(gx + 0.5 * txy, gy + 0.5 * tyy, x, y, h, eye, light, point,
                                 n, zback)
    d1, d2, ld = _slope_mismatch(gx - 0.5 * txy, gy - 0.5 * tyy, x, y, h, eye, light, point,
                                 n, zback)
    if not (la and lb and lc and ld):
        return 0.0, 0.0, 0.0, 0.0, False
    return (a1 - b1) / res, (c1 - d1) / res, (a2 - b2) / res, (c2 - d2) / res, True


@kernel(parallel=True)
def _lit_cells(z: np.ndarray, labels: np.ndarray, x0: float, y0: float, res: float,
               tile: int, tiles: np.ndarray, eye: np.ndarray, light: np.ndarray, point: bool,
               n: float, zback: float, cut: float, reach: float,
               spread: float) -> tuple[np.ndarray, np.ndarray]:
    """Cells (flat indices) of the given tiles whose exit ray comes within the
    lobe's cut ``cut`` (radians) of the eye; per tile in a (t, tile^2) buffer with
    counts (t,)."""
    ny, nx = z.shape
    ntx = (nx + tile - 1) // tile
    out = np.empty((tiles.size, tile * tile), np.int64)
    count = np.zeros(tiles.size, np.int64)
    for k in nb.prange(tiles.size):
        ty = tiles[k] // ntx
        tx = tiles[k] % ntx
        tgx, tgy, m = _tile_target(x0, y0, res, tile, ty, tx, eye, light, point, n, zback,
                                   reach, spread)
        c = 0
        for j in range(ty * tile, min((ty + 1) * tile, ny)):
            y = y0 + j * res
            for i in range(tx * tile, min((tx + 1) * tile, nx)):
                if labels[j, i] < 0:
                    continue
                nx_, ny_, nz_, ok = _normal(z, labels, j, i, res)
                if not ok:
                    continue
                # Cheap test on the slope first; the traced one on the few left.
                gx, gy = -nx_ / nz_, -ny_ / nz_
                if abs(gx - tgx) > m + 0.5 * MAX_CELL_TURN or \
                        abs(gy - tgy) > m + 0.5 * MAX_CELL_TURN:
                    continue
                x = x0 + i * res
                m1, m2, lit, _, _, _ = _exit_mismatch(nx_, ny_, nz_, x, y, z[j, i],
                                                      eye, light, point, n, zback)
                if not lit:
                    continue
                if m1 * m1 + m2 * m2 > cut * cut:
                    # The facet turns across the cell: the exit ray may meet the eye in it.
                    j11, j12, j21, j22, turns = _mismatch_gradient(
                        z, labels, j, i, res, gx, gy, x, y, z[j, i], eye, light, point, n,
                        zback)
                    if not turns:
                        continue
                    half = 0.5 * res * max(abs(j11) + abs(j12), abs(j21) + abs(j22))
                    if math.sqrt(m1 * m1 + m2 * m2) > cut + half:
                        continue
                out[k, c] = j * nx + i
                c += 1
        count[k] = c
    return out, count


@kernel(parallel=True)
def _spots(z: np.ndarray, labels: np.ndarray, x0: float, y0: float, res: float,
           flat: np.ndarray, eye: np.ndarray, light: np.ndarray, point: bool, n: float,
           zback: float, sigma: float, shadows: bool, floor: float) -> np.ndarray:
    """Per lit cell: weight, x, y, z, the exit ray's 2-D miss, the slope and |det|
    of the miss's gradient per mm^2 (k, 9); where the miss turns by more than
    the lobe across the cell, the lobe is averaged over sub-samples of its
    linear change and x, y, z are their weighted mean (as on a mirror plate)."""
    nx = z.shape[1]
    out = np.zeros((flat.size, 9))
    for k in nb.prange(flat.size):
        j = flat[k] // nx
        i = flat[k] % nx
        x = x0 + i * res
        y = y0 + j * res
        h = z[j, i]
        nx_, ny_, nz_, _ = _normal(z, labels, j, i, res)
        m1, m2, lit, dx, dy, dz = _exit_mismatch(nx_, ny_, nz_, x, y, h, eye, light, point,
                                                 n, zback)
        w = math.exp(-(m1 * m1 + m2 * m2) / (2.0 * sigma * sigma)) if lit else 0.0
        gx0, gy0 = -nx_ / nz_, -ny_ / nz_
        det = 0.0
        px, py, pz = x, y, h
        if lit:
            j11, j12, j21, j22, turns = _mismatch_gradient(z, labels, j, i, res, gx0, gy0, x,
                                                           y, h, eye, light, point, n, zback)
            if turns:
                det = abs(j11 * j22 - j12 * j21)
                if max(abs(j11) + abs(j12), abs(j21) + abs(j22)) * res > sigma:
                    w, du, dv = _lobe_over_cell(m1, m2, j11, j12, j21, j22, res, sigma)
                    px, py = x + du, y + dv
                    pz = h + gx0 * du + gy0 * dv
        if shadows and w > 0.0:
            ex, ey, ez = eye[0] - x, eye[1] - y, eye[2] - h
            r = math.sqrt(ex * ex + ey * ey + ez * ez)
            if _blocked(z, x0, y0, res, x, y, h, ex / r, ey / r, ez / r) or \
                    not _through_glass(z, x0, y0, res, x, y, h, dx, dy, dz, floor):
                w = 0.0
        out[k, 0] = w
        out[k, 1] = px
        out[k, 2] = py
        out[k, 3] = pz
        out[k, 4] = m1
        out[k, 5] = m2
        out[k, 6] = gx0
        out[k, 7] = gy0
        out[k, 8] = det
    return out


def light_vector(light: BackLight) -> tuple[np.ndarray, bool]:
    """The light as the kernels take it: its position (point light) or the
    direction toward it (sun), and whether it is a point."""
    if light.distance is None:
        return np.asarray(light.direction, dtype=float), False
    return np.asarray(light.position, dtype=float), True


def in_plate_directions(light: BackLight, s: np.ndarray) -> np.ndarray:
    """Directions (k, 3) in the plate of the light reaching points s (k, 3) there."""
    s = np.ascontiguousarray(np.asarray(s, dtype=float).reshape(-1, 3))
    return _in_plate_many(s, *light_vector(light), float(light.index), -float(light.thickness))


@kernel()
def _in_plate_many(s: np.ndarray, light: np.ndarray, point: bool, n: float,
                   zback: float) -> np.ndarray:
    out = np.empty_like(s)
    for k in range(s.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = in_plate(s[k, 0], s[k, 1], s[k, 2], light, point, n,
                                                   zback)
    return out


def find_transmitted_glints(field: HeightMap | SlopeIndex, eye: np.ndarray, light: BackLight,
                            lobe: float = LOBE, shadows: bool = True,
                            min_coverage: float = MIN_COVERAGE,
                            estimate: str = "centroid") -> FieldGlints:
    """All glints an eye sees on the ridged front face of a clear plate lit from behind.

    Args:
        field: the front face, with labels (the stipple of each cell), or its slope
            index (build it once for many eyes).
        eye: (3,) eye position, mm.
        light: the light behind the plate (its thickness and index are the plate's).
        lobe: the lobe of a mirror plate, radians: the exit ray's lobe is twice it,
            as a mirror's reflected ray's is.
        shadows: trace the light through the glass and the eye ray over the field.
        min_coverage: share of an uncropped spot's weight a glint needs.
        estimate: ``"centroid"`` or ``"fit"``: which point ``glints`` holds.

    Returns:
        The glints, sorted by stipple.
    """
    if not isinstance(light, BackLight):
        raise SpecholoError("a clear plate's glints need a light behind it (a BackLight)")
    if not (math.isfinite(lobe) and lobe > 0):
        raise SpecholoError(f"lobe must be a positive angle, got {lobe}")
    if estimate not in ESTIMATES:
        raise SpecholoError(f"estimate must be one of {', '.join(ESTIMATES)}, got {estimate!r}")
    index = field if isinstance(field, SlopeIndex) else SlopeIndex.build(field)
    hm = index.field
    assert hm.labels is not None
    eye = np.asarray(eye, dtype=float)
    lvec, point = light_vector(light)
    n = float(light.index)
    zback = -float(light.thickness)
    if not float(np.min(hm.z)) > zback:
        raise SpecholoError(f"the front face reaches the back face (z = {zback:g} mm)")
    sigma = EXIT_LOBE * float(lobe)
    z = np.ascontiguousarray(hm.z)
    labels = np.ascontiguousarray(hm.labels)
    x0, y0 = (float(v) for v in hm.origin)
    res = hm.resolution
    spread = index.depth
    # A cell's normal within the cut: the exit ray turns by at least n - 1 times
    # the normal's turn.
    reach = CUTOFF * sigma / (n - 1.0)
    flag = _candidate_tiles(index.box, x0, y0, res, index.tile, eye, lvec, point, n, zback,
                            reach + 0.5 * MAX_CELL_TURN, spread)
    tiles = np.flatnonzero(flag)
    buf, count = _lit_cells(z, labels, x0, y0, res, index.tile, tiles, eye, lvec, point, n,
                            zback, CUTOFF * sigma, reach, spread)
    flat = buf[np.arange(buf.shape[1])[None, :] < count[:, None]]
    cells = _spots(z, labels, x0, y0, res, flat, eye, lvec, point, n, zback, sigma, shadows,
                   -index.depth - 1e-6)
    lab = labels.ravel()[flat]
    keep = cells[:, 0] > 0
    return _gather(cells[keep], lab[keep], sigma, res, min_coverage, estimate)

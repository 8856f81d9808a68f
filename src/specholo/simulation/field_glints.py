"""Glints on a height field lit from the front: the lighting model of the plate.

For an eye and the light, every cell's normal comes from the height field
(central differences, or the one-sided one across a riser or a region edge:
where the two one-sided slopes differ by more than :data:`KINK` the smaller
is the facet's), and the cell shines with a Gaussian specular lobe of its
angle to the normality vector h (angular sigma ``lobe``, cut at
:data:`CUTOFF` sigmas); shadows and riser hiding are traced over the field.
The surface between the samples is smooth: where a facet's normal turns by
more than the lobe across one cell (an optic for a point a few millimetres
behind the plate turns it by ~res / 2d radians a cell, several lobes), the
lobe is averaged over sub-samples of the cell with the normal turning as
the neighbouring cells say (:data:`MAX_SUBSAMPLES` a side), so a spot
smaller than a cell is found, at its place within the cell, with the weight
a continuous mirror gives it.
Only the tiles whose facet slopes come near h's are searched
(:class:`SlopeIndex`, built once per field). The clear plate
(:mod:`specholo.simulation.transmission`) uses the same index and kernels;
:mod:`specholo.simulation.heightfield` verifies plates with both.

Lit cells of one stipple (the cell's label) within :data:`LINK` cells of each
other form a glint; a spot cut by a riser or its shadow keeps both parts,
which lie on the same sightline (each facet is a level set of the same phi).
Its position is

- ``centroid``: the intensity-weighted centroid in 3D of its cells;
- ``fit``: where the normal equals h, from a weighted linear fit of each cell's
  angular mismatch (n - h in a tangent basis of h) over its position within
  each facet, as the cut simulation (:mod:`specholo.simulation.cut`) votes for
  the exact glint. A spot cropped by a riser or a region edge biases the
  centroid toward the part that is left, not the fit.

Either way the glint counts only when its weight reaches ``min_coverage`` of an
uncropped spot's (2 pi sigma^2 / |det J| / cell area, J the fitted mismatch
gradient), as in the cut simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from specholo._compiling import kernel
from specholo.errors import SpecholoError
from specholo.setup import Light
from specholo.simulation.cut import MIN_COVERAGE
from specholo.simulation.glints import Glints
from specholo.toolpaths.heightmap import HeightMap

#: Angular sigma of the specular lobe, radians.
LOBE = 4e-4
#: Cells within this many sigmas of h are lit.
CUTOFF = 3.0
#: Difference of the two one-sided slopes above which a cell sits on a kink
#: (a riser or a region edge); facets turn by ~resolution / 20 mm per cell.
KINK = 0.25
ESTIMATES = ("centroid", "fit")
#: Most sub-samples a side of a cell whose normal turns by several lobes.
MAX_SUBSAMPLES = 24
#: Largest change of a facet's slope across one cell that the search allows
#: for (an optic for a point 0.5 mm behind the plate, at 0.02 mm cells).
MAX_CELL_TURN = 0.02
#: Cells steeper than this (riser walls) are not searched: h would have to tilt
#: more than 72 degrees from the plate normal to make them glint.
MAX_SLOPE = 3.0
#: Lit cells of one stipple this close (cells) form one glint: a riser or a
#: riser's shadow across a spot leaves a gap of a few cells between its parts.
LINK = 8.0
#: Neighbouring lit cells lie on one facet when their heights agree with its
#: slope to this share of a cell (facets curve by ~1e-5 mm per cell; risers drop
#: by the facet depth).
FACET_TOL = 0.1
#: Side of the tiles that index the field's slopes, cells.
TILE = 16
#: Slope boxes per tile, and the slope radius that opens a new one.
TILE_BOXES = 4
BOX_RADIUS = 0.02


@kernel(helper=True)
def _slope(zm: float, z0: float, zp: float, ok_m: bool, ok_p: bool,
           res: float) -> tuple[float, bool]:
    """Slope at a cell from its two neighbours, one-sided across a kink."""
    if ok_m and ok_p:
        fm = (z0 - zm) / res
        fp = (zp - z0) / res
        if abs(fp - fm) <= KINK:
            return 0.5 * (fm + fp), True
        return (fm if abs(fm) < abs(fp) else fp), True
    if ok_m:
        return (z0 - zm) / res, True
    if ok_p:
        return (zp - z0) / res, True
    return 0.0, False


@kernel(helper=True)
def _slopes(z: np.ndarray, labels: np.ndarray, j: int, i: int,
            res: float) -> tuple[float, float, bool]:
    """The facet slope (gx, gy) at a cell (:func:`_normal`'s, as slopes)."""
    nx_, ny_, nz_, ok = _normal(z, labels, j, i, res)
    return -nx_ / nz_, -ny_ / nz_, ok


@kernel(helper=True)
def _on_facet(z: np.ndarray, labels: np.ndarray, j: int, i: int, dj: int, di: int,
              gx: float, gy: float, res: float) -> bool:
    """Whether the neighbour (j + dj, i + di) lies on the cell's own facet: the
    same stipple, at the height the cell's slope predicts (not across a riser
    or onto the next facet's level)."""
    ny, nx = z.shape
    jj, ii = j + dj, i + di
    if jj < 0 or ii < 0 or jj >= ny or ii >= nx or labels[jj, ii] != labels[j, i]:
        return False
    return abs(z[jj, ii] - z[j, i] - (gx * di + gy * dj) * res) <= FACET_TOL * res


@kernel(helper=True)
def _cell_turn(z: np.ndarray, labels: np.ndarray, j: int, i: int,
               res: float) -> tuple[float, float, float]:
    """How the facet's slope (gx, gy) changes across the cell, per cell: d gx/dx,
    d gy/dy and the cross term, times res, from the slopes of the neighbours
    on the same facet (:func:`_on_facet`); 0 where none is, or the change is
    more than a facet turns (:data:`MAX_CELL_TURN`)."""
    gx, gy, ok = _slopes(z, labels, j, i, res)
    if not ok:
        return 0.0, 0.0, 0.0
    # Both neighbours on each axis must lie on the facet and agree on its turn:
    # a facet's curve is smooth, a riser's foot or the plate's edge is not.
    turn = np.zeros((2, 2, 2))  # axis, side, (d gx, d gy)
    for axis in range(2):
        for side in range(2):
            di = (2 * side - 1) if axis == 0 else 0
            dj = (2 * side - 1) if axis == 1 else 0
            if not _on_facet(z, labels, j, i, dj, di, gx, gy, res):
                return 0.0, 0.0, 0.0
            sx, sy, okn = _slopes(z, labels, j + dj, i + di, res)
            if not okn:
                return 0.0, 0.0, 0.0
            sign = 2 * side - 1
            turn[axis, side, 0] = (sx - gx) * sign
            turn[axis, side, 1] = (sy - gy) * sign
    for axis in range(2):
        for c in range(2):
            a, b = turn[axis, 0, c], turn[axis, 1, c]
            if abs(a - b) > 0.5 * max(abs(a), abs(b)) + 1e-5:
                return 0.0, 0.0, 0.0
    txx = 0.5 * (turn[0, 0, 0] + turn[0, 1, 0])
    tyy = 0.5 * (turn[1, 0, 1] + turn[1, 1, 1])
    # The slope field of a surface is a gradient: its cross terms agree.
    cross = 0.25 * (turn[0, 0, 1] + turn[0, 1, 1] + turn[1, 0, 0] + turn[1, 1, 0])
    if abs(txx) > MAX_CELL_TURN or abs(tyy) > MAX_CELL_TURN or abs(cross) > MAX_CELL_TURN:
        return 0.0, 0.0, 0.0
    return txx, tyy, cross


@kernel(helper=True)
def _mismatch(gx: float, gy: float, e1x: float, e1z: float, e2x: float, e2y: float,
              e2z: float) -> tuple[float, float]:
    """The angular mismatch (2,) of the normal of slope (gx, gy) to h, in h's
    tangent basis e1, e2."""
    norm = math.sqrt(gx * gx + gy * gy + 1.0)
    nx_, ny_, nz_ = -gx / norm, -gy / norm, 1.0 / norm
    return nx_ * e1x + nz_ * e1z, nx_ * e2x + ny_ * e2y + nz_ * e2z


@kernel(helper=True)
def _lobe_over_cell(m1: float, m2: float, j11: float, j12: float, j21: float, j22: float,
                    res: float, lobe: float) -> tuple[float, float, float]:
    """The lobe averaged over a cell whose mismatch is m at its centre and turns
    by J (per mm) across it, as sub-samples (at most :data:`MAX_SUBSAMPLES` a
    side, enough that each turns by half a lobe): the weight, and the weighted
    mean offset (du, dv) from the centre, mm."""
    spread = max(abs(j11) + abs(j12), abs(j21) + abs(j22)) * res
    sub = min(MAX_SUBSAMPLES, int(math.ceil(2.0 * spread / lobe)))
    tw = 0.0
    sx = 0.0
    sy = 0.0
    for a in range(sub):
        u = ((a + 0.5) / sub - 0.5) * res
        for b in range(sub):
            v = ((b + 0.5) / sub - 0.5) * res
            q1 = m1 + j11 * u + j12 * v
            q2 = m2 + j21 * u + j22 * v
            w = math.exp(-(q1 * q1 + q2 * q2) / (2.0 * lobe * lobe))
            tw += w
            sx += w * u
            sy += w * v
    if tw <= 0.0:
        return 0.0, 0.0, 0.0
    return tw / (sub * sub), sx / tw, sy / tw


@kernel(helper=True)
def _normal(z: np.ndarray, labels: np.ndarray, j: int, i: int,
            res: float) -> tuple[float, float, float, bool]:
    ny, nx = z.shape
    lab = labels[j, i]
    ok_l = i > 0 and labels[j, i - 1] == lab
    ok_r = i < nx - 1 and labels[j, i + 1] == lab
    ok_d = j > 0 and labels[j - 1, i] == lab
    ok_u = j < ny - 1 and labels[j + 1, i] == lab
    z0 = z[j, i]
    gx, okx = _slope(z[j, i - 1] if ok_l else z0, z0, z[j, i + 1] if ok_r else z0, ok_l, ok_r,
                     res)
    gy, oky = _slope(z[j - 1, i] if ok_d else z0, z0, z[j + 1, i] if ok_u else z0, ok_d, ok_u,
                     res)
    norm = math.sqrt(gx * gx + gy * gy + 1.0)
    return -gx / norm, -gy / norm, 1.0 / norm, okx and oky


@kernel()
def _half(x: float, y: float, z: float, eye: np.ndarray, light: np.ndarray,
          point: bool) -> tuple[float, float, float]:
    """Unit normality vector h at (x, y, z)."""
    ex, ey, ez = eye[0] - x, eye[1] - y, eye[2] - z
    r = math.sqrt(ex * ex + ey * ey + ez * ez)
    if point:
        lx, ly, lz = light[0] - x, light[1] - y, light[2] - z
        q = math.sqrt(lx * lx + ly * ly + lz * lz)
        lx, ly, lz = lx / q, ly / q, lz / q
    else:
        lx, ly, lz = light[0], light[1], light[2]
    hx, hy, hz = ex / r + lx, ey / r + ly, ez / r + lz
    q = math.sqrt(hx * hx + hy * hy + hz * hz)
    return hx / q, hy / q, hz / q


@kernel(parallel=True)
def _tile_boxes(z: np.ndarray, labels: np.ndarray, res: float, tile: int, k_boxes: int,
                radius: float) -> np.ndarray:
    """Per tile of tile x tile cells, up to k_boxes boxes covering the facet slopes
    (gx, gy) it holds (min gx, max gx, min gy, max gy; unused boxes empty as
    +inf, -inf). A slope joins the first box whose seed slope is within
    ``radius``, else opens a box, else joins the nearest; facets of one
    stipple and riser walls fall in separate boxes. Cells steeper than
    :data:`MAX_SLOPE` (risers) cannot glint and are left out."""
    ny, nx = z.shape
    nty = (ny + tile - 1) // tile
    ntx = (nx + tile - 1) // tile
    box = np.empty((nty, ntx, k_boxes, 4))
    for ty in nb.prange(nty):
        seed = np.empty((k_boxes, 2))
        for tx in range(ntx):
            used = 0
            for k in range(k_boxes):
                box[ty, tx, k, 0] = np.inf
                box[ty, tx, k, 1] = -np.inf
                box[ty, tx, k, 2] = np.inf
                box[ty, tx, k, 3] = -np.inf
            for j in range(ty * tile, min((ty + 1) * tile, ny)):
                for i in range(tx * tile, min((tx + 1) * tile, nx)):
                    if labels[j, i] < 0:
                        continue
                    nx_, ny_, nz_, ok = _normal(z, labels, j, i, res)
                    if not ok:
                        continue
                    gx, gy = -nx_ / nz_, -ny_ / nz_
                    if gx * gx + gy * gy > MAX_SLOPE * MAX_SLOPE:
                        continue
                    pick = -1
                    nearest = 0
                    best = np.inf
                    for k in range(used):
                        d = max(abs(gx - seed[k, 0]), abs(gy - seed[k, 1]))
                        if d <= radius:
                            pick = k
                            break
                        if d < best:
                            best = d
                            nearest = k
                    if pick < 0:
                        if used < k_boxes:
                            pick = used
                            seed[used, 0] = gx
                            seed[used, 1] = gy
                            used += 1
                        else:
                            pick = nearest
                    b = box[ty, tx, pick]
                    b[0], b[1] = min(b[0], gx), max(b[1], gx)
                    b[2], b[3] = min(b[2], gy), max(b[3], gy)
    return box


@kernel(helper=True)
def _tile_target(x0: float, y0: float, res: float, tile: int, ty: int, tx: int,
                 eye: np.ndarray, light: np.ndarray, point: bool, reach: float,
                 spread: float) -> tuple[float, float, float]:
    """Slope of h at a tile's centre, and how far (in slope) a cell of the tile
    may be from it and still glint: the lobe's reach, h's change across the
    tile and over the shell's depth."""
    cy = y0 + (ty * tile + 0.5 * (tile - 1)) * res
    cx = x0 + (tx * tile + 0.5 * (tile - 1)) * res
    hx, hy, hz = _half(cx, cy, 0.0, eye, light, point)
    gx, gy = -hx / hz, -hy / hz
    dist = math.sqrt((eye[0] - cx) ** 2 + (eye[1] - cy) ** 2 + eye[2] ** 2)
    if point:
        dl = math.sqrt((light[0] - cx) ** 2 + (light[1] - cy) ** 2 + light[2] ** 2)
        dist = min(dist, dl)
    # An angle a is up to a (1 + g^2) in slope.
    m = (reach + 2.0 * (0.75 * tile * res + spread) / dist) * (1.0 + gx * gx + gy * gy)
    return gx, gy, m


@kernel(parallel=True)
def _candidate_tiles(box: np.ndarray, x0: float, y0: float, res: float, tile: int,
                     eye: np.ndarray, light: np.ndarray, point: bool, reach: float,
                     spread: float) -> np.ndarray:
    """1 for tiles with a slope box within reach of the slope of h at the tile."""
    nty, ntx, k_boxes = box.shape[0], box.shape[1], box.shape[2]
    flag = np.zeros((nty, ntx), np.uint8)
    for ty in nb.prange(nty):
        for tx in range(ntx):
            if box[ty, tx, 0, 0] > box[ty, tx, 0, 1]:
                continue
            gx, gy, m = _tile_target(x0, y0, res, tile, ty, tx, eye, light, point, reach,
                                     spread)
            for k in range(k_boxes):
                if (box[ty, tx, k, 0] - m <= gx <= box[ty, tx, k, 1] + m
                        and box[ty, tx, k, 2] - m <= gy <= box[ty, tx, k, 3] + m):
                    flag[ty, tx] = 1
                    break
    return flag


@kernel(parallel=True)
def _lit_cells(z: np.ndarray, labels: np.ndarray, x0: float, y0: float, res: float,
               tile: int, tiles: np.ndarray, eye: np.ndarray, light: np.ndarray, point: bool,
               cos_cut: float, reach: float, spread: float) -> tuple[np.ndarray, np.ndarray]:
    """Cells (flat indices) of the given tiles whose normal lies within the lobe's
    cut of h; returned per tile in a (t, tile^2) buffer with counts (t,)."""
    ny, nx = z.shape
    ntx = (nx + tile - 1) // tile
    out = np.empty((tiles.size, tile * tile), np.int64)
    count = np.zeros(tiles.size, np.int64)
    for k in nb.prange(tiles.size):
        ty = tiles[k] // ntx
        tx = tiles[k] % ntx
        tgx, tgy, m = _tile_target(x0, y0, res, tile, ty, tx, eye, light, point, reach, spread)
        c = 0
        for j in range(ty * tile, min((ty + 1) * tile, ny)):
            y = y0 + j * res
            for i in range(tx * tile, min((tx + 1) * tile, nx)):
                if labels[j, i] < 0:
                    continue
                nx_, ny_, nz_, ok = _normal(z, labels, j, i, res)
                if not ok:
                    continue
                # Cheap test on the slope first; the exact one on the few left.
                gx, gy = -nx_ / nz_, -ny_ / nz_
                if abs(gx - tgx) > m + 0.5 * MAX_CELL_TURN or \
                        abs(gy - tgy) > m + 0.5 * MAX_CELL_TURN:
                    continue
                hx, hy, hz = _half(x0 + i * res, y, z[j, i], eye, light, point)
                cos_n = nx_ * hx + ny_ * hy + nz_ * hz
                if cos_n < cos_cut:
                    # The normal turns across the cell: it may meet h within it.
                    txx, tyy, txy = _cell_turn(z, labels, j, i, res)
                    turn = 0.5 * (abs(txx) + abs(tyy) + 2.0 * abs(txy)) * nz_ * nz_
                    if turn <= 0.0 or math.acos(min(cos_n, 1.0)) > reach + turn:
                        continue
                out[k, c] = j * nx + i
                c += 1
        count[k] = c
    return out, count


@kernel(helper=True)
def _height_at(z: np.ndarray, x0: float, y0: float, res: float, x: float,
               y: float) -> float:
    """Bilinear height; 0 (the plate surface) outside the field."""
    ny, nx = z.shape
    u = (x - x0) / res
    v = (y - y0) / res
    i = int(math.floor(u))
    j = int(math.floor(v))
    if i < 0 or j < 0 or i >= nx - 1 or j >= ny - 1:
        return 0.0
    a = u - i
    b = v - j
    return ((1 - a) * (1 - b) * z[j, i] + a * (1 - b) * z[j, i + 1]
            + (1 - a) * b * z[j + 1, i] + a * b * z[j + 1, i + 1])


@kernel(helper=True)
def _blocked(z: np.ndarray, x0: float, y0: float, res: float, sx: float, sy: float,
             sz: float, dx: float, dy: float, dz: float) -> bool:
    """Whether the ray from (sx, sy, sz) along the unit (dx, dy, dz) meets the
    height field before rising above the plate (z = 0, its highest point)."""
    if dz <= 0.0:
        return True
    horiz = math.sqrt(dx * dx + dy * dy)
    if horiz * (-sz) <= 1e-12 * dz:
        return False
    # Steps of half a cell across the plate, starting past the cell itself.
    dt = 0.5 * res / horiz
    t = dt
    while True:
        pz = sz + t * dz
        if pz >= 0.0:
            return False
        if _height_at(z, x0, y0, res, sx + t * dx, sy + t * dy) > pz + 1e-7:
            return True
        t += dt


@kernel(parallel=True)
def _spots(z: np.ndarray, labels: np.ndarray, x0: float, y0: float, res: float,
           flat: np.ndarray, eye: np.ndarray, light: np.ndarray, point: bool, lobe: float,
           shadows: bool) -> np.ndarray:
    """Per lit cell: weight, x, y, z, the 2-D angular mismatch and the slope, and
    |det| of the mismatch's gradient over the cell, per mm^2 (0 where the facet
    does not turn across it) (k, 9). Where the normal turns by more than the
    lobe across the cell, the weight is the lobe averaged over sub-samples and
    x, y, z their weighted mean."""
    nx = z.shape[1]
    out = np.zeros((flat.size, 9))
    for k in nb.prange(flat.size):
        j = flat[k] // nx
        i = flat[k] % nx
        x = x0 + i * res
        y = y0 + j * res
        h = z[j, i]
        nx_, ny_, nz_, _ = _normal(z, labels, j, i, res)
        hx, hy, hz = _half(x, y, h, eye, light, point)
        # A tangent basis of h: e1 horizontal, e2 = h x e1.
        q = math.sqrt(hx * hx + hz * hz)
        e1x, e1z = hz / q, -hx / q
        e2x, e2y, e2z = hy * e1z, hz * e1x - hx * e1z, -hy * e1x
        m1 = nx_ * e1x + nz_ * e1z
        m2 = nx_ * e2x + ny_ * e2y + nz_ * e2z
        w = math.exp(-(m1 * m1 + m2 * m2) / (2.0 * lobe * lobe))
        gx0, gy0 = -nx_ / nz_, -ny_ / nz_
        txx, tyy, txy = _cell_turn(z, labels, j, i, res)
        det = 0.0
        px, py, pz = x, y, h
        if txx != 0.0 or tyy != 0.0 or txy != 0.0:
            # The mismatch's gradient across the cell, per mm.
            ax1, ax2 = _mismatch(gx0 + 0.5 * txx, gy0 + 0.5 * txy, e1x, e1z, e2x, e2y, e2z)
            bx1, bx2 = _mismatch(gx0 - 0.5 * txx, gy0 - 0.5 * txy, e1x, e1z, e2x, e2y, e2z)
            ay1, ay2 = _mismatch(gx0 + 0.5 * txy, gy0 + 0.5 * tyy, e1x, e1z, e2x, e2y, e2z)
            by1, by2 = _mismatch(gx0 - 0.5 * txy, gy0 - 0.5 * tyy, e1x, e1z, e2x, e2y, e2z)
            j11, j21 = (ax1 - bx1) / res, (ax2 - bx2) / res
            j12, j22 = (ay1 - by1) / res, (ay2 - by2) / res
            det = abs(j11 * j22 - j12 * j21)
            if max(abs(j11) + abs(j12), abs(j21) + abs(j22)) * res > lobe:
                w, du, dv = _lobe_over_cell(m1, m2, j11, j12, j21, j22, res, lobe)
                px, py = x + du, y + dv
                pz = h + gx0 * du + gy0 * dv
        if shadows and w > 0.0:
            ex, ey, ez = eye[0] - x, eye[1] - y, eye[2] - h
            r = math.sqrt(ex * ex + ey * ey + ez * ez)
            if point:
                lx, ly, lz = light[0] - x, light[1] - y, light[2] - h
                s = math.sqrt(lx * lx + ly * ly + lz * lz)
                lx, ly, lz = lx / s, ly / s, lz / s
            else:
                lx, ly, lz = light[0], light[1], light[2]
            if _blocked(z, x0, y0, res, x, y, h, ex / r, ey / r, ez / r) or \
                    _blocked(z, x0, y0, res, x, y, h, lx, ly, lz):
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


@dataclass(frozen=True)
class FieldGlints:
    """Glints an eye sees on a height field.

    Attributes:
        glints: the glints (``path`` and ``stipple`` are the stipple), sorted by
            stipple, at the chosen estimate.
        centroid: (g, 3) intensity-weighted centroids of the lit cells, mm.
        fitted: (g, 3) points where the fitted normal equals h, mm (the
            centroid where the fit is degenerate).
        weight: (g,) summed lobe weights (cells at full brightness).
        coverage: (g,) weight over an uncropped spot's.
        spread: (g,) weighted RMS distance of the lit cells from the centroid, mm.
    """

    glints: Glints
    centroid: np.ndarray
    fitted: np.ndarray
    weight: np.ndarray
    coverage: np.ndarray
    spread: np.ndarray


@dataclass(frozen=True, eq=False)
class SlopeIndex:
    """The range of facet slopes in each tile of a height field, so an eye's glint
    search visits only the tiles that may hold one (built once per field).

    Attributes:
        field: the height map.
        tile: tile side, cells.
        box: (nty, ntx, k, 4) min and max of gx, then of gy, per box of a tile.
        depth: the deepest cut, mm.
    """

    field: HeightMap
    tile: int
    box: np.ndarray
    depth: float

    @classmethod
    def build(cls, hm: HeightMap, tile: int = TILE) -> SlopeIndex:
        """Index a labelled height map."""
        if hm.labels is None:
            raise SpecholoError("the height map needs labels (the stipple of each cell) to "
                                "find glints")
        box = _tile_boxes(np.ascontiguousarray(hm.z), np.ascontiguousarray(hm.labels),
                          hm.resolution, int(tile), TILE_BOXES, BOX_RADIUS)
        return cls(hm, int(tile), box, float(max(0.0, -float(np.min(hm.z)))))


def _source_vector(light: Light) -> tuple[np.ndarray, bool]:
    if light.distance is None:
        return np.asarray(light.direction, dtype=float), False
    return np.asarray(light.position, dtype=float), True


def find_reflected_glints(field: HeightMap | SlopeIndex, eye: np.ndarray, light: Light,
                      lobe: float = LOBE, shadows: bool = True,
                      min_coverage: float = MIN_COVERAGE,
                      estimate: str = "centroid") -> FieldGlints:
    """All glints an eye sees on a labelled height field.

    Args:
        field: the plate, with labels (the stipple of each cell), or its slope
            index (build it once for many eyes).
        eye: (3,) eye position, mm.
        light: the light.
        lobe: angular sigma of the specular lobe, radians.
        shadows: trace the light and eye rays over the field (riser shadows).
        min_coverage: share of an uncropped spot's weight a glint needs.
        estimate: ``"centroid"`` or ``"fit"``: which point ``glints`` holds.

    Returns:
        The glints, sorted by stipple.

    Raises:
        SpecholoError: the field has no labels, or a bad lobe or estimate.

    The light is in front of the plate, which is a mirror (a light behind it is
    :func:`specholo.simulation.transmission.find_transmitted_glints`'s).
    """
    if not (math.isfinite(lobe) and lobe > 0):
        raise SpecholoError(f"lobe must be a positive angle, got {lobe}")
    if estimate not in ESTIMATES:
        raise SpecholoError(f"estimate must be one of {', '.join(ESTIMATES)}, got {estimate!r}")
    index = field if isinstance(field, SlopeIndex) else SlopeIndex.build(field)
    hm = index.field
    assert hm.labels is not None
    eye = np.asarray(eye, dtype=float)
    lvec, point = _source_vector(light)
    z = np.ascontiguousarray(hm.z)
    labels = np.ascontiguousarray(hm.labels)
    x0, y0 = (float(v) for v in hm.origin)
    res = hm.resolution
    spread = index.depth
    # A cell's normal turns by up to half of MAX_CELL_TURN past its centre's.
    flag = _candidate_tiles(index.box, x0, y0, res, index.tile, eye, lvec, point,
                            CUTOFF * lobe + 0.5 * MAX_CELL_TURN, spread)
    tiles = np.flatnonzero(flag)
    buf, count = _lit_cells(z, labels, x0, y0, res, index.tile, tiles, eye, lvec, point,
                            math.cos(CUTOFF * lobe), CUTOFF * lobe, spread)
    flat = buf[np.arange(buf.shape[1])[None, :] < count[:, None]]
    cells = _spots(z, labels, x0, y0, res, flat, eye, lvec, point, float(lobe), shadows)
    lab = labels.ravel()[flat]
    keep = cells[:, 0] > 0
    return _gather(cells[keep], lab[keep], lobe, res, min_coverage, estimate)


def _components(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Connected components (n,) of the graph with edges a[k] - b[k]."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def _gather(cells: np.ndarray, lab: np.ndarray, lobe: float, res: float,
            min_coverage: float, estimate: str) -> FieldGlints:
    """Group lit cells into glints and measure each.

    Cells of one stipple within :data:`LINK` cells of each other form a glint;
    within it, neighbours whose heights agree with the facet's slope form a
    facet (a spot may straddle a riser: both parts lie on the same sightline).
    The mismatch gradient J is fitted within facets (common to the glint), and
    each facet's zero of the mismatch is found from its own mean.
    """
    from scipy.spatial import cKDTree

    if lab.size == 0:
        empty = np.zeros((0, 3))
        return FieldGlints(Glints(np.zeros(0, np.int64), np.zeros(0, np.int64), empty), empty,
                           empty, np.zeros(0), np.zeros(0), np.zeros(0))
    k = len(lab)
    w = cells[:, 0]
    xyz = cells[:, 1:4]
    pairs = cKDTree(xyz[:, :2]).query_pairs(LINK * res + 1e-9 * res, output_type="ndarray")
    pairs = pairs[lab[pairs[:, 0]] == lab[pairs[:, 1]]]
    glint = _components(k, pairs[:, 0], pairs[:, 1])
    near = np.linalg.norm(xyz[pairs[:, 0], :2] - xyz[pairs[:, 1], :2], axis=1) <= 1.5 * res
    step = xyz[pairs[:, 1]] - xyz[pairs[:, 0]]
    predicted = np.sum(cells[pairs[:, 0], 6:8] * step[:, :2], axis=1)
    same = near & (np.abs(step[:, 2] - predicted) <= FACET_TOL * res)
    facet = _components(k, pairs[same, 0], pairs[same, 1])
    glint_ids, glint = np.unique(glint, return_inverse=True)
    facet_ids, facet = np.unique(facet, return_inverse=True)
    g, f = len(glint_ids), len(facet_ids)
    facet_glint = np.zeros(f, np.int64)
    facet_glint[facet] = glint

    def per(index: np.ndarray, size: int, v: np.ndarray) -> np.ndarray:
        return np.bincount(index, w * v, minlength=size)

    wf = np.bincount(facet, w, minlength=f)
    mean_f = np.stack([per(facet, f, cells[:, c]) for c in (1, 2, 3, 4, 5)], 1) / wf[:, None]
    d = cells[:, 1:6] - mean_f[facet]
    # Within-facet covariances, summed per glint: position-position and mismatch-position.
    sxx = np.stack([per(glint, g, d[:, 0] * d[:, 0]), per(glint, g, d[:, 0] * d[:, 1]),
                    per(glint, g, d[:, 1] * d[:, 1])], axis=1)
    smx = np.stack([per(glint, g, d[:, 3] * d[:, 0]), per(glint, g, d[:, 3] * d[:, 1]),
                    per(glint, g, d[:, 4] * d[:, 0]), per(glint, g, d[:, 4] * d[:, 1])], 1)
    wg = np.bincount(glint, w, minlength=g)
    det_xx = sxx[:, 0] * sxx[:, 2] - sxx[:, 1] ** 2
    good = det_xx > (0.05 * res * res) ** 2 * wg**2
    safe = np.where(good, det_xx, 1.0)
    inv_xx = np.stack([sxx[:, 2], -sxx[:, 1], sxx[:, 0]], axis=1) / safe[:, None]
    j11 = smx[:, 0] * inv_xx[:, 0] + smx[:, 1] * inv_xx[:, 1]
    j12 = smx[:, 0] * inv_xx[:, 1] + smx[:, 1] * inv_xx[:, 2]
    j21 = smx[:, 2] * inv_xx[:, 0] + smx[:, 3] * inv_xx[:, 1]
    j22 = smx[:, 2] * inv_xx[:, 1] + smx[:, 3] * inv_xx[:, 2]
    det_j = j11 * j22 - j12 * j21
    good &= np.abs(det_j) > 1e-12
    safe_j = np.where(good, det_j, 1.0)
    # Each facet's zero of m = m_mean + J (x - x_mean), and its height on the facet.
    gf = facet_glint
    dx = -(j22[gf] * mean_f[:, 3] - j12[gf] * mean_f[:, 4]) / safe_j[gf]
    dy = -(-j21[gf] * mean_f[:, 3] + j11[gf] * mean_f[:, 4]) / safe_j[gf]
    slope_f = np.stack([per(facet, f, cells[:, 6]), per(facet, f, cells[:, 7])], 1) / wf[:, None]
    zero_f = np.stack([mean_f[:, 0] + dx, mean_f[:, 1] + dy,
                       mean_f[:, 2] + slope_f[:, 0] * dx + slope_f[:, 1] * dy], axis=1)
    centroid = np.stack([per(glint, g, cells[:, c]) for c in (1, 2, 3)], 1) / wg[:, None]
    fitted = np.stack([np.bincount(gf, wf * zero_f[:, c], minlength=g) for c in range(3)],
                      axis=1) / wg[:, None]
    fitted = np.where(good[:, None], fitted, centroid)
    full = 2.0 * math.pi * lobe * lobe / np.abs(safe_j) / (res * res)
    coverage = np.where(good, wg / full, (wg >= 1.0) * 1.0)
    if cells.shape[1] > 8:
        # A spot within a cell or two has no fit: its cells' own turn says how
        # large the uncropped spot is.
        det_c = per(glint, g, cells[:, 8]) / wg
        small = ~good & (det_c > 0)
        full_c = 2.0 * math.pi * lobe * lobe / np.where(small, det_c, 1.0) / (res * res)
        coverage = np.where(small, wg / full_c, coverage)
    dc = xyz[:, :2] - centroid[glint, :2]
    spread = np.sqrt(per(glint, g, np.sum(dc * dc, axis=1)) / wg)
    stipple = np.zeros(g, np.int64)
    stipple[glint] = lab
    ok = coverage >= min_coverage
    order = np.flatnonzero(ok)[np.argsort(stipple[ok], kind="stable")]
    point = (centroid if estimate == "centroid" else fitted)[order]
    return FieldGlints(Glints(stipple[order], stipple[order], point), centroid[order],
                       fitted[order], wg[order], coverage[order], spread[order])


# ---------------------------------------------------------------------------
# Verification

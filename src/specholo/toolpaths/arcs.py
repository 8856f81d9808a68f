"""Circular-arc splines: biarcs that match a curve's points and tangents exactly.

Glints sit where a groove's tangent is perpendicular to the half vector, so the
tangent matters more than the position: a biarc through two samples matches both
samples' tangents exactly and varies smoothly between them. Compiled with numba:
millions of sample pairs are joined per design.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from specholo._compiling import kernel


@kernel(helper=True)
def _half_turn_bulge(ax: float, ay: float, bx: float, by: float) -> float:
    """tan(angle from a to b / 2): the bulge of an arc making that angle with its chord."""
    # tan(phi / 2) = sin / (1 + cos) = (1 - cos) / sin, whichever does not cancel.
    cross, dot = ax * by - ay * bx, ax * bx + ay * by
    m = math.sqrt((ax * ax + ay * ay) * (bx * bx + by * by))
    if dot >= 0.0:
        return cross / (m + dot) if m > 0.0 else 0.0
    if cross != 0.0:
        return (m - dot) / cross
    return math.tan(0.5 * math.atan2(cross, dot))  # exactly reversed


@kernel(helper=True)
def _biarc(p0x: float, p0y: float, t0x: float, t0y: float, p1x: float, p1y: float,
           t1x: float, t1y: float) -> tuple[float, float, float, float]:
    """Joint and bulges of the equal-leg biarc from (p0, t0) to (p1, t1)."""
    vx, vy = p1x - p0x, p1y - p0y
    vt = vx * (t0x + t1x) + vy * (t0y + t1y)
    vv = vx * vx + vy * vy
    a = 2.0 - 2.0 * (t0x * t1x + t0y * t1y)  # 4 - |t0 + t1|^2, >= 0
    # Rationalised root of a d^2 + 2 vt d - vv = 0: stable when a -> 0.
    root = vt + math.sqrt(max(vt * vt + a * vv, 0.0))
    d = vv / root if root > 0.0 else math.inf
    if not (vt > 0.0 and d < math.sqrt(vv)):
        # Tangents that disagree with the chord (samples out of order, or
        # nearly coincident) have no sensible biarc: a straight segment instead.
        return 0.5 * (p0x + p1x), 0.5 * (p0y + p1y), 0.0, 0.0
    jx = 0.5 * (p0x + p1x + d * (t0x - t1x))
    jy = 0.5 * (p0y + p1y + d * (t0y - t1y))
    b1 = _half_turn_bulge(t0x, t0y, jx - p0x, jy - p0y)
    b2 = _half_turn_bulge(p1x - jx, p1y - jy, t1x, t1y)
    return jx, jy, b1, b2


@kernel(parallel=True)
def _biarcs(p0: np.ndarray, t0: np.ndarray, p1: np.ndarray,
            t1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    k = p0.shape[0]
    joint = np.empty((k, 2))
    b1 = np.empty(k)
    b2 = np.empty(k)
    for i in nb.prange(k):
        joint[i, 0], joint[i, 1], b1[i], b2[i] = _biarc(
            p0[i, 0], p0[i, 1], t0[i, 0], t0[i, 1], p1[i, 0], p1[i, 1], t1[i, 0], t1[i, 1])
    return joint, b1, b2


def biarc(p0: np.ndarray, t0: np.ndarray, p1: np.ndarray,
          t1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Equal-leg biarcs joining (p0, t0) to (p1, t1) with continuous tangent.

    Args:
        p0: (k, 2) start points.
        t0: (k, 2) unit tangents at the start.
        p1: (k, 2) end points.
        t1: (k, 2) unit tangents at the end.

    Returns:
        joint (k, 2): where the two arcs meet; bulge1 (k,), bulge2 (k,). Pairs
        with no sensible biarc get a straight segment (both bulges 0).
    """
    f = np.ascontiguousarray
    return _biarcs(f(p0, dtype=float), f(t0, dtype=float), f(p1, dtype=float),
                   f(t1, dtype=float))


@kernel(parallel=True)
def _fill_chain(points: np.ndarray, tangents: np.ndarray, pair: np.ndarray, slot: np.ndarray,
                vertices: np.ndarray, bulges: np.ndarray) -> None:
    m = points.shape[0]
    for i in nb.prange(m):
        s = slot[i]
        vertices[s, 0], vertices[s, 1] = points[i, 0], points[i, 1]
        if i + 1 < m and pair[i]:
            jx, jy, b1, b2 = _biarc(points[i, 0], points[i, 1], tangents[i, 0],
                                    tangents[i, 1], points[i + 1, 0], points[i + 1, 1],
                                    tangents[i + 1, 0], tangents[i + 1, 1])
            vertices[s + 1, 0], vertices[s + 1, 1] = jx, jy
            bulges[s], bulges[s + 1] = b1, b2
        else:
            bulges[s] = 0.0


def arc_chain(points: np.ndarray, tangents: np.ndarray,
              breaks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Biarc chains through sampled curves, as groove vertex arrays.

    Args:
        points: (m, 2) samples of several curves, each curve's samples consecutive.
        tangents: (m, 2) unit tangents at the samples, along the direction of travel.
        breaks: (m,) True where a sample starts a new curve (``breaks[0]`` is True).

    Returns:
        vertices (m', 2), bulges (m',) and path start offsets (n_curves + 1,): each
        curve of q samples becomes a path of 2q - 1 vertices.
    """
    m = len(points)
    if m == 0:
        return np.zeros((0, 2)), np.zeros(0), np.zeros(1, dtype=np.int64)
    pair = np.zeros(m, dtype=np.bool_)
    pair[:-1] = ~breaks[1:]  # sample i and i + 1 on the same curve
    # Before sample k lie k samples and one joint per sample that is not its curve's last.
    curve = np.cumsum(breaks) - 1
    slot = 2 * np.arange(m) - curve
    n_out = 2 * m - int(breaks.sum())
    vertices = np.empty((n_out, 2))
    bulges = np.empty(n_out)
    _fill_chain(np.ascontiguousarray(points, dtype=float),
                np.ascontiguousarray(tangents, dtype=float), pair, slot, vertices, bulges)
    offsets = np.concatenate([slot[breaks], [n_out]]).astype(np.int64)
    return vertices, bulges, offsets

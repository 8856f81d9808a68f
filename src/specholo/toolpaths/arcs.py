"""Circular-arc splines: biarcs that match a curve's points and tangents exactly.

Glints sit where a groove's tangent is perpendicular to the half vector, so the
tangent matters more than the position: a biarc through two samples matches both
samples' tangents exactly and varies smoothly between them.
"""

from __future__ import annotations

import numpy as np


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(a * b, axis=1)


def bulge_from_start_tangent(p0: np.ndarray, t0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Bulges of arcs leaving p0 along t0 and ending at p1.

    Args:
        p0: (k, 2) start points.
        t0: (k, 2) unit start tangents.
        p1: (k, 2) end points.

    Returns:
        (k,) bulges tan(sweep / 4); the sweep is twice the angle from t0 to the chord.
    """
    chord = p1 - p0
    half_sweep = np.arctan2(_cross(t0, chord), _dot(t0, chord))
    return np.tan(0.5 * half_sweep)


def bulge_to_end_tangent(p0: np.ndarray, p1: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """Bulges of arcs from p0 arriving at p1 along t1; shapes as above."""
    chord = p1 - p0
    half_sweep = np.arctan2(_cross(chord, t1), _dot(chord, t1))
    return np.tan(0.5 * half_sweep)


def biarc(p0: np.ndarray, t0: np.ndarray, p1: np.ndarray,
          t1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Equal-leg biarcs joining (p0, t0) to (p1, t1) with continuous tangent.

    Args:
        p0: (k, 2) start points.
        t0: (k, 2) unit tangents at the start.
        p1: (k, 2) end points.
        t1: (k, 2) unit tangents at the end.

    Returns:
        joint (k, 2): where the two arcs meet; bulge1 (k,), bulge2 (k,).
    """
    v = p1 - p0
    t = t0 + t1
    vt = _dot(v, t)
    vv = _dot(v, v)
    a = 2.0 - 2.0 * _dot(t0, t1)  # 4 - |t|^2, >= 0
    # Rationalised root of a d^2 + 2 vt d - vv = 0: stable when a -> 0.
    with np.errstate(divide="ignore", invalid="ignore"):
        d = vv / (vt + np.sqrt(vt * vt + a * vv))
    # Tangents that disagree with the chord (samples out of order, or nearly
    # coincident) have no sensible biarc: join those with a straight segment.
    bad = ~(np.isfinite(d) & (vt > 0) & (d < np.sqrt(vv)))
    d = np.where(bad, 0.0, d)
    joint = 0.5 * (p0 + p1 + d[:, None] * (t0 - t1))
    b1 = np.where(bad, 0.0, bulge_from_start_tangent(p0, t0, joint))
    b2 = np.where(bad, 0.0, bulge_to_end_tangent(joint, p1, t1))
    return joint, b1, b2


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
    pair = ~breaks[1:]  # sample i and i + 1 on the same curve
    i = np.flatnonzero(pair)
    joint, b1, b2 = biarc(points[i], tangents[i], points[i + 1], tangents[i + 1])
    # Before sample k lie k samples and one joint per sample that is not its curve's last.
    curve = np.cumsum(breaks) - 1
    slot = 2 * np.arange(m) - curve
    n_out = 2 * m - int(breaks.sum())
    vertices = np.empty((n_out, 2))
    bulges = np.zeros(n_out)
    vertices[slot] = points
    vertices[slot[i] + 1] = joint
    bulges[slot[i]] = b1
    bulges[slot[i] + 1] = b2
    starts = slot[breaks]
    offsets = np.concatenate([starts, [n_out]]).astype(np.int64)
    return vertices, bulges, offsets

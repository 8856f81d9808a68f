"""Stripes joined into strokes: a stipple cut in one pass instead of dozens.

Brand's striping hands a stipple's groove over from one stripe to the next at
the band's edges: the stripe ends where the next begins, at the same x and one
band higher or lower (see :mod:`specholo.toolpaths.striped`). Lifting the tool
between them costs a machine about as much as the stripe's cut. A straight
*connector* from the end of one stripe to the start of the next joins them
into one stroke.

A connector is a groove too, and a groove glints where its wall's normal is
the normality vector h = (light + eye) / |light + eye|. The walls of a straight
groove along d have normals perpendicular to d, so the connector sends no
glint to an eye where h . d != 0. With the light above or below the plate
(elevation away from 0) and the eyes on a horizontal arc, h leans toward the
light and d = +-y never meets it: the connector is dark for every view. A
connector is made only where h . d keeps one sign, with a margin, over the
whole viewing range (both eyes' azimuths and heights, at the connector's
ends), so a join never adds a glint on the ideal grooves. What it adds is
groove: the connectors' length cuts other stipples' glints where it crosses
them, and the corners where the tip turns; the design's as-cut step (and
``verify --cut``) counts both.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from specholo.setup import Setup
from specholo.toolpaths.grooves import Grooves

#: Largest step between the ends joined, mm: a stripe's hand-over is one band
#: high (0.1-0.4 mm on the defaults); farther ends are not a hand-over, and a
#: long connector would cross other grooves for nothing.
MAX_STEP = 1.0
#: Ends whose x differ by less than this are one hand-over, mm (the striping
#: computes both from the same azimuth).
SAME_X = 1e-4
#: Least |h . d| over the views for a connector to be dark: about 1 degree off
#: the wall normals' plane, well past a polished lobe (0.02 degrees).
DARK_MARGIN = math.sin(math.radians(1.0))
#: Eye azimuths sampled over the range when deciding a connector is dark.
AZIMUTH_SAMPLES = 25


@dataclass(frozen=True)
class Joined:
    """Grooves with their stripes joined.

    Attributes:
        grooves: the joined grooves (a connector is a straight segment).
        connectors: (c, 2, 2) each connector's ends, mm.
        joined: hand-overs joined.
        kept_apart: hand-overs left apart because a connector there could glint
            or was not allowed (it would cut other glints away).
    """

    grooves: Grooves
    connectors: np.ndarray
    joined: int
    kept_apart: int

    @property
    def connector_length(self) -> float:
        """Total length of the connectors, mm."""
        if not len(self.connectors):
            return 0.0
        d = self.connectors[:, 1] - self.connectors[:, 0]
        return float(np.sqrt((d * d).sum(axis=1)).sum())


def dark(a: np.ndarray, b: np.ndarray, setup: Setup,
         samples: int = AZIMUTH_SAMPLES) -> np.ndarray:
    """Whether straight grooves from a to b ((k, 2) each, mm) send no glint to any
    eye of the viewing range: h . d keeps one sign, at least :data:`DARK_MARGIN`
    from zero, at both ends for every sampled eye.

    Returns:
        (k,) bool.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    d = b - a
    length = np.sqrt((d * d).sum(axis=1))
    d = d / np.maximum(length, 1e-300)[:, None]
    viewer = setup.viewer
    r = viewer.design_range
    eyes = viewer.eye(np.linspace(-r, r, samples))  # (s, 3)
    lo = np.full(len(a), np.inf)
    hi = np.full(len(a), -np.inf)
    for end in (a, b):
        p = np.concatenate([end, np.zeros((len(end), 1))], axis=1)
        light = setup.light
        if light.distance is None:
            to_light = np.broadcast_to(np.asarray(light.direction, dtype=float), p.shape)
        else:
            to_light = np.asarray(light.position, dtype=float) - p
            to_light = to_light / np.linalg.norm(to_light, axis=1, keepdims=True)
        for eye in eyes:
            to_eye = eye - p
            to_eye = to_eye / np.linalg.norm(to_eye, axis=1, keepdims=True)
            h = to_light + to_eye
            h = h / np.linalg.norm(h, axis=1, keepdims=True)
            dot = h[:, 0] * d[:, 0] + h[:, 1] * d[:, 1]
            np.minimum(lo, dot, out=lo)
            np.maximum(hi, dot, out=hi)
    return (length > 0) & ((lo > DARK_MARGIN) | (hi < -DARK_MARGIN))


def _ends(grooves: Grooves) -> tuple[np.ndarray, np.ndarray]:
    """Every path's two ends (2 n, 2): path j's start at 2 j, its end at 2 j + 1;
    and each end's path (2 n,)."""
    off = grooves.offsets
    v = grooves.vertices
    ends = np.empty((2 * grooves.n_paths, 2))
    ends[0::2] = v[off[:-1]]
    ends[1::2] = v[off[1:] - 1]
    return ends, np.repeat(np.arange(grooves.n_paths), 2)


def hand_overs(grooves: Grooves, max_step: float = MAX_STEP) -> np.ndarray:
    """Pairs of path ends (h, 2) that are a stripe hand-over: the same stipple,
    the same x within :data:`SAME_X`, at most ``max_step`` apart in y, two
    different paths, and no third end there (the ends are numbered as in
    :func:`_ends`; dots take no part)."""
    ends, path = _ends(grooves)
    if not len(ends):
        return np.zeros((0, 2), dtype=np.int64)
    stipple = grooves.stipple[path]
    live = ~grooves.is_dot[path]
    order = np.lexsort((ends[:, 0], stipple))
    order = order[live[order]]
    x = ends[order, 0]
    s = stipple[order]
    close = (s[1:] == s[:-1]) & (np.abs(x[1:] - x[:-1]) <= SAME_X)
    # A pair stands alone: its neighbours on either side are not at that x too.
    alone = close.copy()
    alone[1:] &= ~close[:-1]
    alone[:-1] &= ~close[1:]
    i = np.flatnonzero(alone)
    a, b = order[i], order[i + 1]
    ok = (path[a] != path[b]) & (np.abs(ends[a, 1] - ends[b, 1]) <= max_step)
    return np.stack([a[ok], b[ok]], axis=1)


def join_stripes(grooves: Grooves, setup: Setup, max_step: float = MAX_STEP,
                 allow: Callable[[np.ndarray], np.ndarray] | None = None) -> Joined:
    """Join each stipple's stripes where they hand over and a connector there
    would be dark (:func:`dark`), into as few strokes as the hand-overs allow.

    Args:
        grooves: the designed grooves (any order).
        setup: the light and viewer the connectors must stay dark for.
        max_step: largest hand-over step joined, mm.
        allow: given the dark connectors' ends (c, 2, 2), mm, which of them
            (c,) bool may be cut (the design's test that a connector cuts no
            other groove's glints away); None allows every dark one.

    Returns:
        The joined grooves, in the order of their first stripe, and the connectors.
    """
    pairs = hand_overs(grooves, max_step)
    ends, _ = _ends(grooves)
    ok = dark(ends[pairs[:, 0]], ends[pairs[:, 1]], setup) if len(pairs) else \
        np.zeros(0, dtype=bool)
    if allow is not None and ok.any():
        where = np.flatnonzero(ok)
        ok[where] = np.asarray(allow(np.stack([ends[pairs[where, 0]], ends[pairs[where, 1]]],
                                              axis=1)), dtype=bool)
    kept_apart = int((~ok).sum())
    pairs = pairs[ok]
    n = grooves.n_paths
    partner = np.full(2 * n, -1, dtype=np.int64)
    partner[pairs[:, 0]] = pairs[:, 1]
    partner[pairs[:, 1]] = pairs[:, 0]
    off = grooves.offsets
    v = grooves.vertices
    bulge = grooves.bulges
    seen = np.zeros(n, dtype=bool)
    verts: list[np.ndarray] = []
    bulges: list[np.ndarray] = []
    sizes: list[int] = []
    owner: list[int] = []
    connectors: list[tuple[np.ndarray, np.ndarray]] = []

    def piece(j: int, forward: bool) -> tuple[np.ndarray, np.ndarray]:
        pv = v[off[j]:off[j + 1]]
        pb = bulge[off[j]:off[j + 1]]
        if forward:
            return pv, pb
        # Reversed: the arcs run the other way, so each bulge changes sign and
        # moves to the arc's new first vertex.
        rb = np.zeros_like(pb)
        rb[:-1] = -pb[:-1][::-1]
        return pv[::-1], rb

    for first in range(n):
        if seen[first]:
            continue
        # Walk back to a chain's free end (or round a loop to where it began).
        j, end = first, 2 * first  # leave path j through its start
        while partner[end] >= 0 and not seen[partner[end] // 2] and partner[end] // 2 != first:
            other = partner[end]
            j = other // 2
            end = 2 * j + (1 - other % 2)  # the far end of that path
        # Now walk forward from the free end `end` of path j.
        chain_v: list[np.ndarray] = []
        chain_b: list[np.ndarray] = []
        entry = end  # the end the chain enters path j by
        while True:
            seen[j] = True
            forward = entry % 2 == 0
            pv, pb = piece(j, forward)
            if chain_v:
                connectors.append((chain_v[-1][-1].copy(), pv[0].copy()))
            chain_v.append(pv)
            chain_b.append(pb)
            exit_end = 2 * j + (1 if forward else 0)
            nxt = partner[exit_end]
            if nxt < 0 or seen[nxt // 2]:
                break
            j, entry = nxt // 2, nxt
        cv = np.concatenate(chain_v)
        cb = np.concatenate(chain_b)  # each piece's last bulge is 0: the connector
        verts.append(cv)
        bulges.append(cb)
        sizes.append(len(cv))
        owner.append(int(grooves.stipple[first]))
    if not sizes:
        return Joined(grooves, np.zeros((0, 2, 2)), 0, kept_apart)
    joined = Grooves(np.concatenate(verts), np.concatenate(bulges),
                     np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                     np.asarray(owner, dtype=np.int64))
    conn = np.array([[a, b] for a, b in connectors]).reshape(-1, 2, 2)
    return Joined(joined, conn, len(connectors), kept_apart)

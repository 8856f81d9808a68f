"""Striped grooves on any host and along any motion: the paper's construction
with the conforming tangent t1 = n x N(s).

For one family of states tau (see :mod:`specholo.scene.motion`) and one stipple
whose target point at state tau is P(tau), the sightline from the eye E(tau)
through P(tau) meets the host at s(tau). A ball-end groove (radius R, depth d
along the local normal N) glints on its wall at g = c + (R - d) N - R n, where
c is the groove's centreline on the host and n = h / |h| the normality vector
at g. The design target is the centreline point c*(tau) whose wall glint lies
on the sightline (found by fixed-point steps at the glint's own depth).

The groove cannot simply follow c*: it must run along t = N x h, perpendicular
to h within the host's tangent plane, or it would not glint. So it follows t
(a predictor-corrector step on the surface, projected back onto the host) just
far enough that the glint stays exactly on the sightline along the eyes'
baseline v (the direction that sets the depth), and its offset u from the
target along N x v drifts. Where |u| exceeds the band w the stripe ends and the
next starts at the band's other edge (Brand's striping), so the error across
the sightline stays within w (plus one state's drift at a hand-over). A groove
running nearly across the baseline (|t . v| < MIN_ALONG) cannot do this and the
state is lost (the flat plate's "light in the eyes' plane"). Each new stripe starts one
state early and each old one ends one state late, so neighbouring stripes share
the hand-over. Samples keep their exact tangents; the simulator interpolates
between them as along a smooth curve.

Loops run over the states (hundreds); every step is vectorised over stipples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.hosts.surfaces import Host, blocked
from specholo.setup import Tool

#: Smallest |t . v| (groove tangent along the eyes' baseline) a stripe may have:
#: a groove running across the baseline cannot keep its glint on the sightline.
MIN_ALONG = 0.05
#: Fixed-point steps for the wall glint's normal (each gains ~ R / distance).
WALL_ITERATIONS = 3


def _unit(v: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def half_vector(g: np.ndarray, eye: np.ndarray, light: np.ndarray, point_light: bool
                ) -> np.ndarray:
    """Normality vectors h (n, 3) at glints g (n, 3) for eyes and lights (n, 3) or (3,)."""
    to_light = _unit(light - g) if point_light else _unit(np.broadcast_to(light, g.shape))
    return to_light + _unit(eye - g)


def wall_glint(c: np.ndarray, normal: np.ndarray, eye: np.ndarray, light: np.ndarray,
               point_light: bool, tool: Tool) -> tuple[np.ndarray, np.ndarray]:
    """The wall glint g and its h for centreline points c (n, 3) with host normals (n, 3).

    Returns:
        g (n, 3) and h (n, 3).
    """
    centre = c + (tool.radius - tool.depth) * normal
    g = c
    for _ in range(WALL_ITERATIONS):
        h = half_vector(g, eye, light, point_light)
        g = centre - tool.radius * _unit(h)
    return g, half_vector(g, eye, light, point_light)


@dataclass(frozen=True)
class ConformingOptions:
    """Settings of the conforming striping.

    Attributes:
        band: half-width w of the band about the target across the groove, mm.
    """

    band: float = 0.2

    def __post_init__(self) -> None:
        if not (math.isfinite(self.band) and self.band > 0):
            raise SpecholoError(f"band must be a positive number of mm, got {self.band}")


@dataclass
class ConformingGrooves:
    """Grooves as samples along stripes, sorted by stripe then state.

    Attributes:
        point: (k, 3) centreline samples on the host, mm.
        tangent: (k, 3) unit groove tangents there.
        normal: (k, 3) host normals there.
        stripe: (k,) stripe id (consecutive samples of one id form a groove).
        stipple: (k,) stipple each sample serves.
        state: (k,) index of the design state of each sample.
        family: (k,) index of the family (0, or 0/1 for left/right eyes).
        stats: figures of the construction.
    """

    point: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray
    stripe: np.ndarray
    stipple: np.ndarray
    state: np.ndarray
    family: np.ndarray
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def segments(self) -> np.ndarray:
        """Indices (s,) of samples that start a segment (the next sample is its end)."""
        if len(self.stripe) < 2:
            return np.zeros(0, dtype=np.int64)
        return np.flatnonzero(self.stripe[1:] == self.stripe[:-1])

    def length(self) -> float:
        """Total groove length, mm."""
        s = self.segments
        return float(np.linalg.norm(self.point[s + 1] - self.point[s], axis=1).sum())

    def paths(self) -> list[np.ndarray]:
        """Each stripe's centreline samples (k_i, 3), in stripe order."""
        if len(self.stripe) == 0:
            return []
        cut = np.flatnonzero(np.diff(self.stripe)) + 1
        return np.split(self.point, cut)

    def save(self, path: Any) -> None:
        np.savez_compressed(path, point=self.point, tangent=self.tangent, normal=self.normal,
                            stripe=self.stripe, stipple=self.stipple, state=self.state,
                            family=self.family)

    @classmethod
    def load(cls, path: Any, stipples: int | None = None) -> ConformingGrooves:
        """Read grooves written by :meth:`save`, checked: samples (k, 3) finite and
        within reach, ids (k,) whole numbers, stipple ids below ``stipples`` if given
        (they index the stipples in the verification).

        Raises:
            SpecholoError: an unreadable file or arrays unlike these.
        """
        from specholo.readback import ArraySpec, bounded, load_arrays, within
        from specholo.toolpaths.grooves import MAX_COORDINATE

        vec, ids = ArraySpec((None, 3), finite=True), ArraySpec((None,), np.int64)
        a = load_arrays(path, {"point": vec, "tangent": vec, "normal": vec, "stripe": ids,
                               "stipple": ids, "state": ids, "family": ids})
        name, k = str(path), len(a["point"])
        if any(len(v) != k for v in a.values()):
            raise SpecholoError(f"{name}: its arrays are of different lengths")
        most = np.iinfo(np.int64).max
        top = most if stipples is None else stipples - 1
        # Families: the walking eyes (0), or the left and right eye under a moving light.
        if k and not (within(a["stipple"], 0, top) and within(a["state"], 0, most)
                      and within(a["family"], 0, 1)):
            raise SpecholoError(f"{name}: stipple, state or family ids out of range")
        if not all(bounded(a[v], MAX_COORDINATE) for v in ("point", "tangent", "normal")):
            raise SpecholoError(f"{name}: samples beyond {MAX_COORDINATE:g} mm")
        return cls(a["point"], a["tangent"], a["normal"], a["stripe"], a["stipple"], a["state"],
                   a["family"])


def _target(host: Host, eye: np.ndarray, light: np.ndarray, point_light: bool,
            points: np.ndarray, tool: Tool) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                      np.ndarray, np.ndarray]:
    """Centreline targets whose wall glint lies on the sightline.

    Args:
        eye, light: (n, 3) per stipple. points: (n, 3) targets P.

    Returns:
        c* (n, 3), host normal (n, 3), h (n, 3) at the glint, part (n,), valid (n,).
    """
    hit = host.intersect(eye, points - eye)
    s = np.where(hit.valid[:, None], hit.point, 0.0)
    normal = np.where(hit.valid[:, None], hit.normal, np.array([0.0, 0.0, 1.0]))
    c = s
    g = s
    h = half_vector(g, eye, light, point_light)
    for _ in range(WALL_ITERATIONS):
        n = _unit(h)
        depth = tool.radius * np.sum(n * normal, axis=1) - (tool.radius - tool.depth)
        toward = np.sum((eye - s) * normal, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            g = s + (depth / toward)[:, None] * (s - eye)
        h = half_vector(g, eye, light, point_light)
        c = g + tool.radius * _unit(h) - (tool.radius - tool.depth) * normal
    c = host.project(c)
    normal = host.normal(c)
    ok = hit.valid & np.isfinite(c).all(axis=1)
    return c, normal, h, hit.part, ok


def _tangent(normal: np.ndarray, h: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    t = _unit(np.cross(normal, h))
    if previous is not None:
        flip = np.sum(t * previous, axis=1) < 0
        t[flip] *= -1.0
    return t


def _along_baseline(normal: np.ndarray, baseline: np.ndarray) -> np.ndarray:
    """The eyes' baseline direction (3,) projected into the tangent planes (n, 3)."""
    b = np.broadcast_to(baseline, normal.shape)
    return _unit(b - np.sum(b * normal, axis=1)[:, None] * normal)


def _reach(want: np.ndarray, t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """How far (n,) to go along t so the move's component along v matches want's."""
    tv = np.sum(t * v, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.sum(want * v, axis=1) / tv
    return np.where(np.abs(tv) >= MIN_ALONG, lam, 0.0)


def design_family(host: Host, eye: np.ndarray, light: np.ndarray, baseline: np.ndarray,
                  point_light: bool,
                  targets: np.ndarray, active: np.ndarray, tool: Tool,
                  options: ConformingOptions, stripe_start: int = 0,
                  family_index: int = 0) -> ConformingGrooves:
    """Stripe the grooves of n stipples along one family of m states.

    Args:
        host: the host surface.
        eye: (m, 3) eyes. light: (m, 3) light positions or directions.
        baseline: (m, 3) unit direction from the left eye to the right at each state.
        point_light: whether ``light`` holds positions.
        targets: (n, m, 3) each stipple's target point at each state (plate frame).
        active: (n, m) bool, the stipple is shown at that state (scene keyed and
            not occluded).
        tool: the ball-end groove model (radius, depth).
        options: band.
        stripe_start: first stripe id to use.
        family_index: recorded with every sample.

    Returns:
        The grooves (samples sorted by stripe, then state) and their figures.
    """
    n, m = active.shape
    w = options.band
    out: dict[str, list[np.ndarray]] = {k: [] for k in
                                        ("point", "tangent", "normal", "stripe", "stipple",
                                         "state")}
    running = np.zeros(n, dtype=bool)
    c = np.zeros((n, 3))
    t = np.zeros((n, 3))
    part = np.full(n, -1, dtype=np.int64)
    stripe = np.full(n, -1, dtype=np.int64)
    next_id = stripe_start
    prev_target: np.ndarray | None = None
    prev_ok = np.zeros(n, dtype=bool)
    lost_tilt = 0
    lost_steep = 0
    missed = 0
    served = 0
    cos_tilt = math.cos(tool.max_tilt)

    def emit(idx: np.ndarray, pts: np.ndarray, tans: np.ndarray, nrm: np.ndarray,
             ids: np.ndarray, j: int) -> None:
        if idx.size == 0:
            return
        out["point"].append(pts)
        out["tangent"].append(tans)
        out["normal"].append(nrm)
        out["stripe"].append(ids)
        out["stipple"].append(idx)
        out["state"].append(np.full(idx.size, j, dtype=np.int64))

    for j in range(m):
        act = np.flatnonzero(active[:, j])
        ok = np.zeros(n, dtype=bool)
        target = np.zeros((n, 3))
        tgt_part = np.full(n, -1, dtype=np.int64)
        if act.size:
            ej = np.broadcast_to(eye[j], (act.size, 3))
            lj = np.broadcast_to(light[j], (act.size, 3))
            cs, ns, hs, ps, valid = _target(host, ej, lj, point_light, targets[act, j], tool)
            tilt_ok = np.sum(_unit(hs) * ns, axis=1) >= cos_tilt
            lit = ~blocked(host, np.where(valid[:, None], cs, 0.0), lj,
                           directional=not point_light)
            good = valid & tilt_ok & lit
            lost_tilt += int((valid & ~tilt_ok).sum())
            missed += int((~valid).sum())
            ok[act[good]] = True
            target[act] = cs
            tgt_part[act] = ps
        served += int(ok.sum())
        # Stripes whose stipple is no longer shown, or whose crossing moved to
        # another piece of the host, end here.
        running &= ok & (tgt_part == part)
        cont = np.flatnonzero(running & ok)
        if cont.size:
            ej = np.broadcast_to(eye[j], (cont.size, 3))
            lj = np.broadcast_to(light[j], (cont.size, 3))
            c0, t0 = c[cont], t[cont]
            v = _along_baseline(host.normal(c0), baseline[j])
            want = target[cont] - c0
            # Predictor along the old tangent, corrector along the mean tangent;
            # each step keeps the glint exactly on the sightline along the eyes'
            # baseline (what sets depth) and lets it drift across it.
            cp = host.project(c0 + _reach(want, t0, v)[:, None] * t0)
            _, hp = wall_glint(cp, host.normal(cp), ej, lj, point_light, tool)
            tp = _tangent(host.normal(cp), hp, t0)
            tm = _unit(t0 + tp)
            c1 = host.project(c0 + _reach(want, tm, v)[:, None] * tm)
            n1 = host.normal(c1)
            _, h1 = wall_glint(c1, n1, ej, lj, point_light, tool)
            t1 = _tangent(n1, h1, t0)
            v1 = _along_baseline(n1, baseline[j])
            drift = _unit(np.cross(n1, v1))
            u = np.sum((c1 - target[cont]) * drift, axis=1)
            steep = np.abs(np.sum(t1 * v1, axis=1)) < MIN_ALONG
            u[steep] = np.inf
            c[cont], t[cont] = c1, t1
            emit(cont[~steep], c1[~steep], t1[~steep], n1[~steep], stripe[cont[~steep]], j)
            over = np.abs(u) > w
            lost_steep += int(steep.sum())
            # Restart at the band's other edge, one state early.
            rs = cont[over]
            if rs.size:
                running[rs] = False
                sign = np.where(steep[over], 0.0, np.sign(u[over]))
                edge = -sign[:, None] * w * drift[over]
                start = host.project(target[rs] + edge)
                _start_stripes(rs, start, j, host, eye, light, baseline, point_light, tool, c,
                               t, part, stripe, running, tgt_part, prev_target, prev_ok,
                               emit, next_id)
                next_id += rs.size
        new = np.flatnonzero(ok & ~running)
        if new.size:
            _start_stripes(new, target[new], j, host, eye, light, baseline, point_light, tool,
                           c, t, part, stripe, running, tgt_part, prev_target, prev_ok,
                           emit, next_id)
            next_id += new.size
        prev_target = target
        prev_ok = ok

    if out["point"]:
        cat = {k: np.concatenate(v) for k, v in out.items()}
    else:
        cat = {k: np.zeros((0, 3)) if k in ("point", "tangent", "normal")
               else np.zeros(0, dtype=np.int64) for k in out}
    order = np.lexsort((cat["state"], cat["stripe"]))
    cat = {k: v[order] for k, v in cat.items()}
    # A stripe of one sample has no length and serves no view: drop it.
    counts = np.bincount(cat["stripe"] - stripe_start, minlength=max(next_id - stripe_start, 0))
    keep = counts[cat["stripe"] - stripe_start] >= 2 if len(cat["stripe"]) else np.zeros(
        0, dtype=bool)
    cat = {k: v[keep] for k, v in cat.items()}
    grooves = ConformingGrooves(cat["point"], cat["tangent"], cat["normal"], cat["stripe"],
                                cat["stipple"], cat["state"],
                                np.full(int(keep.sum()), family_index, dtype=np.int64))
    grooves.stats = {"stripes": int(np.unique(grooves.stripe).size), "samples": int(keep.sum()),
                     "states_served": served, "states_lost_to_tilt": lost_tilt,
                     "states_lost_to_steep_grooves": lost_steep,
                     "states_missing_the_host": missed,
                     "next_stripe": next_id}
    return grooves


def _start_stripes(idx: np.ndarray, start: np.ndarray, j: int, host: Host, eye: np.ndarray,
                   light: np.ndarray, baseline: np.ndarray, point_light: bool, tool: Tool,
                   c: np.ndarray, t: np.ndarray, part: np.ndarray, stripe: np.ndarray,
                   running: np.ndarray, tgt_part: np.ndarray, prev_target: np.ndarray | None,
                   prev_ok: np.ndarray, emit: Any, first_id: int) -> None:
    """Start stripes for stipples idx at points ``start`` (k, 3) at state j.

    Each also gets a sample one state back (where the stipple was shown then),
    so that it overlaps the stripe it takes over from.
    """
    k = idx.size
    ej = np.broadcast_to(eye[j], (k, 3))
    lj = np.broadcast_to(light[j], (k, 3))
    n0 = host.normal(start)
    _, h0 = wall_glint(start, n0, ej, lj, point_light, tool)
    t0 = _tangent(n0, h0, None)
    ids = np.arange(first_id, first_id + k, dtype=np.int64)
    if j > 0 and prev_target is not None:
        back = prev_ok[idx]
        b = idx[back]
        if b.size:
            eb = np.broadcast_to(eye[j - 1], (b.size, 3))
            lb = np.broadcast_to(light[j - 1], (b.size, 3))
            want = prev_target[b] - start[back]
            v = _along_baseline(n0[back], baseline[j - 1])
            cb = host.project(start[back] + _reach(want, t0[back], v)[:, None] * t0[back])
            nb_ = host.normal(cb)
            _, hb = wall_glint(cb, nb_, eb, lb, point_light, tool)
            tb = _tangent(nb_, hb, t0[back])
            emit(b, cb, tb, nb_, ids[back], j - 1)
    emit(idx, start, t0, n0, ids, j)
    c[idx], t[idx] = start, t0
    part[idx] = tgt_part[idx]
    stripe[idx] = ids
    running[idx] = True

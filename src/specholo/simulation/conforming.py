"""Glints on grooves on any host, and what moving viewers see of them.

A groove sample carries its centreline point c, unit tangent t and host normal
N. For an eye and a light, each sample's wall glint g (the point of the ball-end
wall whose normal is h) and f = h(g) . t are computed; a glint lies where f
changes sign between two samples of one stripe (interpolated there, as along a
smooth curve through the samples with those tangents). It is kept when h's tilt
from the host normal is within the groove's walls and neither the eye nor the
light is hidden from it by the host itself. Nothing here uses the design's
targets: the glints come from the engraved geometry alone.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from specholo.hosts.surfaces import Host, blocked
from specholo.setup import Tool
from specholo.simulation.glints import Glints
from specholo.simulation.verify import stereo_errors
from specholo.toolpaths.conforming import ConformingGrooves, wall_glint


def find_conforming_glints(grooves: ConformingGrooves, host: Host, eye: np.ndarray,
                           light: np.ndarray, point_light: bool, tool: Tool) -> Glints:
    """The glints one eye sees.

    Args:
        grooves: the engraved grooves.
        host: their host.
        eye: (3,) the eye, plate frame.
        light: (3,) light position, or unit direction for a sun.
        point_light: whether ``light`` is a position.
        tool: the groove's ball model.

    Returns:
        Glints sorted by stipple: path is the stripe id.
    """
    seg = grooves.segments
    empty = Glints(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)))
    if seg.size == 0:
        return empty
    k = len(grooves.point)
    e = np.broadcast_to(np.asarray(eye, dtype=float), (k, 3))
    li = np.broadcast_to(np.asarray(light, dtype=float), (k, 3))
    g, h = wall_glint(grooves.point, grooves.normal, e, li, point_light, tool)
    f = np.sum(h * grooves.tangent, axis=1)
    f0, f1 = f[seg], f[seg + 1]
    cross = (f0 == 0) | (f0 * f1 < 0)
    s = seg[cross]
    if s.size == 0:
        return empty
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(f0[cross] == 0, 0.0, f0[cross] / (f0[cross] - f1[cross]))
    u = np.clip(u, 0.0, 1.0)[:, None]
    c = (1 - u) * grooves.point[s] + u * grooves.point[s + 1]
    c = host.project(c)
    normal = host.normal(c)
    gp, hp = wall_glint(c, normal, e[: s.size], li[: s.size], point_light, tool)
    hn = hp / np.linalg.norm(hp, axis=1, keepdims=True)
    tilt_ok = np.sum(hn * normal, axis=1) >= math.cos(tool.max_tilt) - 1e-9
    seen = ~blocked(host, c, e[: s.size]) & ~blocked(host, c, li[: s.size],
                                                     directional=not point_light)
    keep = tilt_ok & seen
    stip = grooves.stipple[s[keep]]
    order = np.argsort(stip, kind="stable")
    return Glints(grooves.stripe[s[keep]][order], stip[order], gp[keep][order])


@dataclass(frozen=True)
class PositionReport:
    """Figures for one viewer position (lengths mm, angles degrees).

    Attributes:
        position: the driver value (head azimuth, light elevation or plate angle).
        shown: stipples shown to both eyes (keyed and unoccluded).
        median_error, p95_error, max_error: distance from the triangulated point
            to the target.
        p95_depth_error: the part along the host normal at the plate centre (z).
        visibility: share of the shown stipples that glint for both eyes.
        stray: share of glints from stipples not shown to that eye (hidden,
            another scene, another time).
        glints: glints per eye (mean of the two).
    """

    position: float
    shown: int
    median_error: float
    p95_error: float
    max_error: float
    p95_depth_error: float
    visibility: float
    stray: float
    glints: float


def position_report(position: float, targets: tuple[np.ndarray, np.ndarray],
                    shown: tuple[np.ndarray, np.ndarray], eyes: np.ndarray,
                    glints: tuple[Glints, Glints]) -> PositionReport:
    """Triangulate the stipples both eyes see and compare them with their targets.

    Args:
        position: driver value, degrees.
        targets: each eye's target points (n, 3) (the scene as that eye should see it).
        shown: (n,) bool per eye, the stipple should glint for that eye.
        eyes: (2, 3) left and right eyes.
        glints: each eye's glints.
    """
    n = len(targets[0])
    gl, gr = glints
    lit_l = np.bincount(gl.stipple, minlength=n) > 0
    lit_r = np.bincount(gr.stipple, minlength=n) > 0
    both = shown[0] & shown[1]
    ids = np.flatnonzero(both & lit_l & lit_r)
    ref = 0.5 * (targets[0] + targets[1])
    e, depth = stereo_errors(ref, gl, gr, eyes[0], eyes[1], ids)
    stray = (int((~shown[0][gl.stipple]).sum()) + int((~shown[1][gr.stipple]).sum()))
    total = len(gl.stipple) + len(gr.stipple)

    def pct(v: np.ndarray, q: float) -> float:
        return float(np.percentile(v, q)) if v.size else math.nan

    return PositionReport(
        position=position, shown=int(both.sum()), median_error=pct(e, 50),
        p95_error=pct(e, 95), max_error=float(e.max()) if e.size else math.nan,
        p95_depth_error=pct(np.abs(depth), 95),
        visibility=float(ids.size / both.sum()) if both.any() else math.nan,
        stray=float(stray / total) if total else 0.0, glints=0.5 * total)


def summarise(reports: list[PositionReport]) -> dict[str, float]:
    """Worst figures over all positions."""
    def pick(key: str, fn: Any) -> float:
        vals = [getattr(r, key) for r in reports if not math.isnan(getattr(r, key))]
        return float(fn(vals)) if vals else math.nan

    return {"worst_p95_error": pick("p95_error", max),
            "worst_median_error": pick("median_error", max),
            "worst_p95_depth_error": pick("p95_depth_error", max),
            "min_visibility": pick("visibility", min), "max_stray": pick("stray", max)}


def reports_to_dicts(reports: list[PositionReport]) -> list[dict[str, float]]:
    return [asdict(r) for r in reports]

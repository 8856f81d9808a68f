"""What each eye sees on a turning plate: glints found on the engraved grooves alone.

For each plate angle the eyes are turned into the plate frame; on every
polyline segment of every groove the glint condition t . h = 0 is tested
between neighbouring segments (a sign change), the glint placed by linear
interpolation, its wall read from the side h leans to, and kept if that wall
exists (``walls``: with the relief cut, the other wall keeps only its shallow
floor) and its tilt is one the ball offers. Each stipple's glints
for the two eyes are triangulated and compared with the stipple, which is
fixed in the plate frame when the scene turns with the plate, and otherwise
where its track has it at that angle (:mod:`specholo.toolpaths.sliding`). Glints on a wall
that does not serve (the twin) are counted as stray.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from specholo.optics.stereo import triangulate
from specholo.setup import Tool
from specholo.toolpaths.spinning import SpinDesign, max_wall_tilt


@dataclass(frozen=True)
class SpinGlints:
    """Glints for one eye at one plate angle.

    Attributes:
        point: (g, 3) glint positions in the plate frame, mm (z = 0).
        stipple: (g,) stipple of the groove each lies on.
        serving: (g,) True on the groove's serving wall, False on the other.
    """

    point: np.ndarray
    stipple: np.ndarray
    serving: np.ndarray


def find_spin_glints(design: SpinDesign, eye: np.ndarray, tool: Tool,
                     walls: str | None = None) -> SpinGlints:
    """Glints of the design's grooves for one eye in the plate frame.

    Args:
        design: the grooves and their serving walls.
        eye: (3,) eye position in the plate frame, mm.
        tool: the ball that cut them (its steepest wall).
        walls: "one" or "both"; default the design's.
    """
    walls = walls or design.setup.walls
    g = design.grooves
    seg = g.segments()
    if len(seg) == 0:
        # dimples only: a dimple glints wherever the tilt fits
        return _dimples(design, eye, tool)
    d = seg.end - seg.start
    length = np.linalg.norm(d, axis=1)
    mid = 0.5 * (seg.start + seg.end)
    mid3 = np.concatenate([mid, np.zeros((len(mid), 1))], axis=1)
    h = design.setup.half_vectors(mid3, np.broadcast_to(eye, mid3.shape))
    t = d / np.where(length > 0, length, 1.0)[:, None]
    f = t[:, 0] * h[:, 0] + t[:, 1] * h[:, 1]
    # neighbour of each segment: the next in its path, and for closed paths the first
    nxt = np.arange(1, len(seg) + 1)
    path = seg.path
    last = np.ones(len(seg), dtype=bool)
    last[:-1] = path[1:] != path[:-1]
    first_of = np.searchsorted(path, path, side="left")
    v = g.vertices
    closed = np.linalg.norm(v[g.offsets[1:] - 1] - v[g.offsets[:-1]], axis=1) < 1e-9
    nxt = np.where(last, np.where(closed[path], first_of, -1), np.minimum(nxt, len(seg) - 1))
    ok = nxt >= 0
    a = np.flatnonzero(ok & (np.sign(f) != np.sign(f[np.maximum(nxt, 0)])))
    b = nxt[a]
    w = f[a] / (f[a] - f[b])
    point = mid[a] + (mid[b] - mid[a]) * w[:, None]
    hh = h[a] + (h[b] - h[a]) * w[:, None]
    # wall: h leaning to the path's left (n_L . h > 0) lights the right-hand wall
    tt = t[a] + (t[b] - t[a]) * w[:, None]
    lean = -tt[:, 1] * hh[:, 0] + tt[:, 0] * hh[:, 1]
    side = np.where(lean > 0, 1, -1)
    path_side = design.path_side[path[a]]
    serving = side == path_side
    tilt = np.arctan2(np.hypot(hh[:, 0], hh[:, 1]), hh[:, 2])
    keep = tilt <= max_wall_tilt(tool)
    if walls == "one":  # the relief cut left the other wall only its shallow floor
        keep &= serving | (tilt < design.relief_tilt)
    pts = np.concatenate([point[keep], np.zeros((int(keep.sum()), 1))], axis=1)
    stip = g.stipple[path[a][keep]]
    dots = _dimples(design, eye, tool)
    return SpinGlints(np.concatenate([pts, dots.point]), np.concatenate([stip, dots.stipple]),
                      np.concatenate([serving[keep], dots.serving]))


def _dimples(design: SpinDesign, eye: np.ndarray, tool: Tool) -> SpinGlints:
    pos, idx = design.grooves.dots()
    p3 = np.concatenate([pos, np.zeros((len(pos), 1))], axis=1)
    h = design.setup.half_vectors(p3, np.broadcast_to(eye, p3.shape))
    keep = np.arctan2(np.hypot(h[:, 0], h[:, 1]), h[:, 2]) <= max_wall_tilt(tool)
    return SpinGlints(p3[keep], design.grooves.stipple[idx][keep], np.ones(int(keep.sum()),
                                                                            dtype=bool))


@dataclass(frozen=True)
class SpinReport:
    """Verification at one plate angle.

    Attributes:
        angle_deg: plate angle, degrees.
        median_mm, p95_mm: error of the triangulated point against the stipple.
        depth_p95_mm: the same for its z alone.
        visibility: share of the stipples meant to be seen (not hidden at this
            angle) that both eyes see; NaN where none is meant (a hand-over
            between scenes).
        stray: glints on walls that do not serve, or extra glints on a groove.
        shown: stipples meant to be seen by both eyes.
    """

    angle_deg: float
    median_mm: float
    p95_mm: float
    depth_p95_mm: float
    visibility: float
    stray: int
    shown: int = 0

    def as_dict(self) -> dict[str, float]:
        return {"angle_deg": self.angle_deg, "median_mm": self.median_mm,
                "p95_mm": self.p95_mm, "depth_p95_mm": self.depth_p95_mm,
                "visibility": self.visibility, "stray": self.stray, "shown": self.shown}


def verify_spinning(design: SpinDesign, tool: Tool, angles_deg: np.ndarray,
                    shown: np.ndarray | None = None, walls: str | None = None
                    ) -> list[SpinReport]:
    """Turn the plate through ``angles_deg`` and measure what both eyes see.

    Args:
        design: the design (its grooves are all the simulator looks at, besides
            the serving wall of each path, which says which wall the cut kept).
        tool: the ball.
        angles_deg: (k,) plate angles, degrees.
        shown: optional (2, n, k) bool, stipple i not hidden from the left (0)
            or right (1) eye at angle j; default all. A glint of a hidden
            stipple is stray; visibility counts the stipples neither eye has hidden.
        walls: override the design's walls ("one" or "both").

    Returns:
        One report per angle.
    """
    n = len(design.points)
    out = []
    phis = np.radians(np.asarray(angles_deg, dtype=float))
    eyes = design.setup.eyes(phis)  # (2, k, 3)
    targets = meant_all = None
    if design.tracks is not None:  # sliding stipples: where each should be, when
        targets, live, meant_all = design.tracks.at(phis)
        if shown is None:
            shown = np.stack([live, live])
    for j, phi in enumerate(phis):
        sees = np.ones((2, n), dtype=bool) if shown is None else np.asarray(shown)[:, :, j]
        meant = sees[0] & sees[1]
        if meant_all is not None:  # one eye may see a live stipple its partner does not
            meant &= meant_all[:, j]
        hits = []
        stray = 0
        for e in range(2):
            gl = find_spin_glints(design, eyes[e, j], tool, walls)
            stray += int((~gl.serving).sum())
            s = gl.stipple[gl.serving]
            stray += int((~sees[e][s]).sum())
            count = np.bincount(s, minlength=n)
            stray += int(np.maximum(count - 1, 0).sum())
            first = np.full(n, -1)
            order = np.argsort(s, kind="stable")[::-1]
            first[s[order]] = order  # any one glint per stipple
            hits.append((first, gl.point[gl.serving]))
        both = (hits[0][0] >= 0) & (hits[1][0] >= 0)
        sel = np.flatnonzero(both & meant)
        if len(sel):
            x1 = hits[0][1][hits[0][0][sel]]
            x2 = hits[1][1][hits[1][0][sel]]
            e1 = np.broadcast_to(eyes[0, j], x1.shape)
            e2 = np.broadcast_to(eyes[1, j], x2.shape)
            p = triangulate(e1, x1, e2, x2)[0]
            want = design.points[sel] if targets is None else targets[sel, j]
            err = np.linalg.norm(p - want, axis=1)
            dz = np.abs(p[:, 2] - want[:, 2])
            med, p95, dp95 = (float(np.median(err)), float(np.percentile(err, 95)),
                              float(np.percentile(dz, 95)))
        else:
            med = p95 = dp95 = math.nan
        n_meant = int(meant.sum())
        vis = len(sel) / n_meant if n_meant else math.nan
        out.append(SpinReport(float(math.degrees(phi)), med, p95, dp95, vis, stray, n_meant))
    return out

"""Optics whose image stays put while the light moves a little: scoops.

A viewer stands still in front of a flat plate (z = 0, normal +z, y up) and the
sun moves in elevation over a small range (a lamp that is bumped or swings, a
window's light through the day). A groove in the plate's plane glints where its
tangent is perpendicular to the half vector h; as the light moves h turns and the
glint slides along the groove, so the image drifts with the light.

The fix: for each eye and stipple, a short cut whose ball-centre path, at the
point that serves, has the 3D tangent t = h x dh/da (a the light's elevation).
Then t . h = 0 for the light at the middle of the range and, to first order,
over the whole range: the glint does not move. Off that point the path curves
in the plane of t and h, towards h (a scoop rising out of the plate at both
ends), so t(u) . h = 0 nowhere else for this eye. The other eye, whose h is
turned by about IPD / D, would glint on the scoop a distance
u = Rp |t . h_other| away; the scoop's radius Rp is chosen so that point lies
above the plate, where there is no wall: each eye sees only its own scoops.

The ball's point that glints is its centre minus R h (the wall whose normal is
h), placed on the eye's sightline through the stipple. ``shape="flat"`` makes
the classic alternative for comparison: a straight groove at constant depth in
the plate's plane, perpendicular to h's in-plane part, as long as the scoop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from specholo.errors import SpecholoError, positive
from specholo.setup import Tool
from specholo.toolpaths.spinning import view_within

SHAPES = ("scoop", "flat")
#: The other eye's glint point must clear the plate by this factor in u.
CLEARANCE = 1.1
#: Scoop radius bounds, mm.
RADIUS_RANGE = (2.0, 200.0)
#: Share of the cut's depth by which a glinting wall point must stay below the
#: plate over the light's range: the glint's drift is predicted to first order
#: and the cut is a polyline, which put glints of the shallowest scoops 0.6 um
#: out of the plate at the range's ends.
WALL_MARGIN = 0.1


@dataclass(frozen=True)
class SteadySetup:
    """A still viewer and a sun that moves over a small range of elevation.

    Attributes:
        distance: plate centre to the point between the eyes, mm (the eyes on +z).
        height: the eyes' height (y), mm.
        ipd: interocular distance, mm.
        light_elevation: the light's middle elevation, radians (direction (0, cos, sin)).
        light_sweep: the light moves this far either way, radians.
        samples: path vertices per scoop.
    """

    distance: float = 600.0
    height: float = 0.0
    ipd: float = 64.0
    light_elevation: float = math.radians(45.0)
    light_sweep: float = math.radians(5.0)
    samples: int = 41

    def __post_init__(self) -> None:
        view_within("view_distance", self.distance)
        positive("ipd", self.ipd)
        view_within("eye_height", self.height)
        if self.ipd >= self.distance:
            raise SpecholoError(f"ipd {self.ipd:g} mm must be below the viewer distance "
                                f"{self.distance:g} mm")
        el, hr = float(self.light_elevation), float(self.light_sweep)
        if not (math.isfinite(el) and math.radians(5.0) <= el <= math.radians(175.0)):
            raise SpecholoError(f"light elevation must be in [5, 175] degrees, got "
                                f"{math.degrees(el):g}")
        if not (math.isfinite(hr) and 0.0 < hr <= math.radians(15.0)):
            raise SpecholoError(f"light sweep must be in (0, 15] degrees either way, got "
                                f"{math.degrees(hr):g}")
        if not 5 <= int(self.samples) <= 1001:
            raise SpecholoError(f"samples must be in [5, 1001], got {self.samples}")

    def eyes(self) -> np.ndarray:
        """(2, 3) left and right eye, mm."""
        c = np.array([0.0, self.height, self.distance])
        half = np.array([0.5 * self.ipd, 0.0, 0.0])
        return np.stack([c - half, c + half])

    def light(self, elevation: np.ndarray | float) -> np.ndarray:
        """Unit directions (..., 3) to the sun at the given elevations, radians."""
        a = np.asarray(elevation, dtype=float)
        return np.stack([np.zeros_like(a), np.cos(a), np.sin(a)], axis=-1)


def unit_half(x: np.ndarray, eye: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Unit half vectors (..., 3) at points x (..., 3) for an eye (3,) and sun (3,)."""
    u = eye - x
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    h = u + light
    return h / np.linalg.norm(h, axis=-1, keepdims=True)


@dataclass(frozen=True)
class SteadyDesign:
    """Scoops (or flat grooves) for a still viewer under a moving sun.

    Attributes:
        setup: the geometry.
        points: (n, 3) stipples, mm.
        centres: (m, 3) ball-centre path vertices of all cuts, mm.
        offsets: (c + 1,) path c is centres[offsets[c]:offsets[c + 1]].
        stipple: (c,) the stipple each cut serves.
        eye: (c,) the eye it serves (0 left, 1 right).
        radius: (c,) each scoop's radius in the plane of t and h, mm (inf: flat).
        shape: "scoop" or "flat".
        dropped: stipples left out because no scoop short of
            ``RADIUS_RANGE[1]`` keeps the other eye's glint off it, or keeps its
            own glint inside the cut over the light's range without cutting
            deeper than the depth.
    """

    setup: SteadySetup
    points: np.ndarray
    centres: np.ndarray
    offsets: np.ndarray
    stipple: np.ndarray
    eye: np.ndarray
    radius: np.ndarray
    shape: str
    dropped: int = 0

    @property
    def n_cuts(self) -> int:
        return len(self.stipple)


def design_steady(points: np.ndarray, setup: SteadySetup, tool: Tool,
                  shape: str = "scoop") -> SteadyDesign:
    """One cut per stipple and eye whose glint stays put over the light's range.

    Args:
        points: (n, 3) stipples, mm (off the plate, in front of the eyes' plane).
        setup: the geometry.
        tool: the ball; its centre rides R - d above the cut's deepest point.
        shape: "scoop" (steady) or "flat" (the classic groove, for comparison).

    Returns:
        The design: two cuts per stipple kept, the left eye's cuts then the right's.

    Raises:
        SpecholoError: a bad shape, or a view needing a wall the ball cannot offer.
    """
    if shape not in SHAPES:
        raise SpecholoError(f"shape must be one of {', '.join(SHAPES)}, got {shape!r}")
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) and not np.all(np.isfinite(points)):
        raise SpecholoError("stipples must be finite")
    eyes = setup.eyes()
    if len(points) and points[:, 2].max() >= setup.distance * 0.9:
        raise SpecholoError("stipples must lie well in front of the eyes")
    r_ball, d = tool.radius, tool.depth
    mid = setup.light_elevation
    light = setup.light(mid)
    da = 1e-4
    n = len(points)
    k = setup.samples
    cuts_c, stip, which, radii = [], [], [], []
    clear = np.ones(n, dtype=bool)
    for e in range(2):  # two eyes: the work inside is over all stipples at once
        eye, other = eyes[e], eyes[1 - e]
        # A scoop whose tangent slopes (t_z != 0) is a circle that dips below its
        # glint point, by up to four times the depth asked: the cut is raised by
        # that dip so its deepest tip is at -d, and the glint point P rides up its
        # sightline by as much. A second pass finds h, and so the scoop, at the
        # raised P (the same turn of t: h turns by ~1e-4 rad).
        lift = np.zeros(n)  # how far P is raised
        turn: np.ndarray | None = None
        for _ in range(2 if shape == "scoop" else 1):
            # the glinting ball point P on the sightline, at the depth its wall reaches
            p_pt = _at_depth(eye, points, 0.0)
            for _ in range(3):
                h = unit_half(p_pt, eye, light)
                reach = d - r_ball * (1.0 - h[:, 2])  # P's depth below the plate, unraised
                if np.any(reach <= 0):
                    worst = math.degrees(math.acos(float(h[:, 2].min())))
                    raise SpecholoError(f"the views need walls tilted {worst:.1f} deg, more "
                                        f"than the {r_ball:g} mm ball at {d:g} mm depth "
                                        "offers; cut deeper")
                p_pt = _at_depth(eye, points, -np.maximum(reach - lift, 0.0))
            h = unit_half(p_pt, eye, light)
            reach = d - r_ball * (1.0 - h[:, 2])
            h2 = unit_half(p_pt, eye, setup.light(mid + da))
            h1 = unit_half(p_pt, eye, setup.light(mid - da))
            for hh in (unit_half(p_pt, eye, setup.light(mid + f * setup.light_sweep))
                       for f in (-1.0, 1.0)):
                if np.any(d - r_ball * (1.0 - hh[:, 2]) <= 0):
                    raise SpecholoError("over the light's range the views need walls steeper "
                                        f"than the {r_ball:g} mm ball at {d:g} mm offers; cut "
                                        "deeper or narrow the range")
            dh = (h2 - h1) / (2 * da)
            centre = p_pt + r_ball * h
            raised = lift
            if shape == "scoop":
                steps = [setup.light(mid + f * setup.light_sweep)
                         for f in (-1.0, -0.5, 0.0, 0.5, 1.0)]
                t, rp, ok, turn = _choose_scoop(h, dh, reach, r_ball,
                                                [unit_half(p_pt, eye, la) for la in steps],
                                                [unit_half(p_pt, other, la) for la in steps],
                                                WALL_MARGIN * d, turn)
                lift = rp * (np.hypot(t[:, 2], h[:, 2]) - h[:, 2])
            else:  # in the plate's plane, perpendicular to h's in-plane part
                t = np.stack([-h[:, 1], h[:, 0], np.zeros(n)], axis=1)
                t /= np.linalg.norm(t, axis=1, keepdims=True)
                rp = np.full(n, RADIUS_RANGE[0] * 9.0)  # only sets the flat cut's length
                ok = np.ones(n, dtype=bool)
        clear &= ok
        # the tip's height -(d - raised) + u t_z + u^2 h_z / 2Rp reaches the plate at both
        # ends (a flat cut: where its ball's tip would, were it a scoop)
        tz, hz = t[:, 2], h[:, 2]
        root = np.sqrt(np.maximum(tz**2 + 2.0 * (d - raised) * hz / rp, 0.0))
        u_lo, u_hi = 1.02 * rp * (-tz - root) / hz, 1.02 * rp * (-tz + root) / hz
        if shape == "flat":
            u_lo, u_hi = -0.5 * (u_hi - u_lo), 0.5 * (u_hi - u_lo)
        f = np.linspace(0.0, 1.0, k)[None, :]
        u = u_lo[:, None] + f * (u_hi - u_lo)[:, None]  # (n, k)
        if shape == "scoop":
            ang = u / rp[:, None]
            path = (centre[:, None, :] + (rp[:, None] * np.sin(ang))[..., None] * t[:, None, :]
                    + (rp[:, None] * (1.0 - np.cos(ang)))[..., None] * h[:, None, :])
            # P was raised by the first pass's dip: the cut is raised by what its
            # lowest vertex still sinks below -d (a hair), so the tool tip, R below
            # the centre, never goes deeper than the depth asked.
            sink = -d - (path[:, :, 2].min(axis=1) - r_ball)
            path[:, :, 2] += np.maximum(sink, 0.0)[:, None]
            radii.append(rp)
        else:
            path = centre[:, None, :] + u[..., None] * t[:, None, :]
            radii.append(np.full(n, math.inf))
        cuts_c.append(path)
        stip.append(np.arange(n))
        which.append(np.full(n, e))
    keep = np.concatenate([clear, clear])
    kept = np.flatnonzero(clear)
    renum = np.full(n, -1)
    renum[kept] = np.arange(len(kept))
    centres = np.concatenate(cuts_c)[keep].reshape(-1, 3) if n else np.zeros((0, 3))
    offsets = np.arange(2 * len(kept) + 1, dtype=np.int64) * k
    return SteadyDesign(setup, points[kept], centres, offsets,
                        renum[np.concatenate(stip)[keep]], np.concatenate(which)[keep],
                        np.concatenate(radii)[keep], shape, n - len(kept))


#: Turns of the scoop's tangent about h tried, radians.
TURNS = np.linspace(-0.3, 0.3, 61)


def _choose_scoop(h: np.ndarray, dh: np.ndarray, reach: np.ndarray, r_ball: float,
                  over: list[np.ndarray], over_o: list[np.ndarray], margin: float = 0.0,
                  turn: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Tangent t (n, 3), radius Rp (n,), feasibility (n,) and turn (n,) (an index
    into :data:`TURNS`) of each scoop.

    t = h x dh/da keeps the glint still to first order, but the slope it gives
    the path can put the other eye's glint point (u_o = -Rp b) inside the cut.
    So t is turned about h by the angle, among :data:`TURNS` (or the given
    ``turn``), that keeps that point above the plate for every light in the range
    (the other eye's half vectors ``over_o``) with the least predicted drift:
    this eye's glint moves to u = -Rp t . (h(a) - h), largest over its half
    vectors ``over``; its wall point must stay ``margin`` below the plate there.

    The scoop dips Rp (|(t_z, h_z)| - h_z) below its point at u = 0 and is raised
    by that much (its deepest tip at the depth), so P lies that much above
    ``reach``, its depth below the plate unraised; a scoop whose P would leave
    the plate is not feasible.
    """
    t0 = np.cross(h, dh)
    t0 /= np.linalg.norm(t0, axis=1, keepdims=True)
    w = np.cross(h, t0)
    turns = TURNS if turn is None else TURNS[turn][:, None]
    c, s = np.cos(turns)[..., None], np.sin(turns)[..., None]
    t = c * t0[:, None, :] + s * w[:, None, :]  # (n, G, 3)
    tz, hz = t[..., 2], h[:, None, 2]
    dip = np.hypot(tz, hz) - hz
    clear2 = CLEARANCE**2
    want = np.zeros(t.shape[:2])
    for h_o in over_o:
        b = np.einsum("ngj,nj->ng", t, h_o) / np.einsum("nj,nj->n", h, h_o)[:, None]
        gain = 0.5 * b**2 * hz - b * tz
        # the other eye's wall point starts sink - Rp dip below the plate (the scoop
        # raised): Rp gain >= CLEARANCE^2 (sink - Rp dip) lifts it out
        sink = np.maximum(reach - r_ball * (h[:, 2] - h_o[:, 2]), 0.0)[:, None]
        need = np.where(gain > 0, clear2 * sink / np.maximum(gain + clear2 * dip, 1e-12),
                        math.inf)
        want = np.maximum(want, need)
    rp = np.clip(want, *RADIUS_RANGE)
    depth = reach[:, None] - rp * dip  # P's depth, raised
    inside = depth > margin
    drift = np.zeros_like(rp)
    for ha in over:
        u = -rp * np.einsum("ngj,nj->ng", t, ha - h)
        drift = np.maximum(drift, np.abs(u))
        ang = u / rp
        wall = (-depth + r_ball * (hz - ha[:, None, 2]) + rp * np.sin(ang) * tz
                + rp * (1.0 - np.cos(ang)) * hz)
        inside &= wall < -margin
    drift = np.where((want <= RADIUS_RANGE[1]) & inside, drift, math.inf)
    best = np.argmin(drift, axis=1)
    rows = np.arange(len(h))
    chosen = best if turn is None else turn
    return t[rows, best], rp[rows, best], np.isfinite(drift[rows, best]), chosen


def _at_depth(eye: np.ndarray, points: np.ndarray, z: np.ndarray | float) -> np.ndarray:
    """Where sightlines from eye (3,) through points (n, 3) reach height z (n,)."""
    s = (eye[2] - np.asarray(z)) / (eye[2] - points[:, 2])
    return eye + (points - eye) * s[:, None]


def tool_tips(design: SteadyDesign, tool: Tool) -> np.ndarray:
    """(m, 3) tool-tip positions of a vertical ball-end cutter (centre minus R in z)."""
    return design.centres - np.array([0.0, 0.0, tool.radius])

"""Cutters: the grooves they leave, and the views those grooves can serve.

A groove glints where its wall's normal is the normality vector h, so the tilts
of h a design needs (the paper's orthogonal tangent t2: the angle between the
plate normal and h along the toolpath) must be among the wall tilts the tool's
cross-section offers. A round tip (ball-end mill, diamond drag tip, scriber
point) offers every tilt from 0 up to where the cut meets the surface; a V-bit
offers only its flank's tilt (and 0 on its tip flat); a laser's Gaussian trough
every tilt up to its steepest slope.

Every tool is rotationally symmetric, described by the height of its cutting
surface above its tip at distance r from its axis (``height``), which is what a
cut simulation sweeps. For designing and the ideal-groove simulation each tool
also gives a ball-end model of its round part (``model``): the glint on a round
wall sits R h/|h| from the ball centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from specholo._compiling import kernel
from specholo._threads import chunked
from specholo.errors import SpecholoError
from specholo.errors import positive as _positive
from specholo.setup import Light, Tool, Viewer

#: Tolerance when comparing a needed tilt with a facet's, radians (~0.06 degrees).
TILT_TOLERANCE = 1e-3
#: Names accepted by :func:`make_cutter`.
KINDS = ("ball", "vbit", "drag", "scriber", "laser")


@dataclass(frozen=True)
class Section:
    """What a groove's cross-section offers.

    Attributes:
        width: groove width at the plate surface, mm.
        tilts: wall tilt intervals (lo, hi) in radians, lo == hi for a flat facet.
    """

    width: float
    tilts: tuple[tuple[float, float], ...]

    def covers(self, tilt: np.ndarray, tolerance: float = TILT_TOLERANCE) -> np.ndarray:
        """Which needed tilts (n,) some wall offers; (n,) bool."""
        tilt = np.asarray(tilt, dtype=float)
        ok = np.zeros(tilt.shape, dtype=bool)
        for lo, hi in self.tilts:
            ok |= (tilt >= lo - tolerance) & (tilt <= hi + tolerance)
        return ok

    @property
    def max_tilt(self) -> float:
        """Steepest wall tilt, radians."""
        return max(hi for _, hi in self.tilts)


@dataclass(frozen=True)
class BallEnd:
    """Ball-end mill. Attributes: radius (mm)."""

    radius: float = 0.25
    kind = "ball"

    def __post_init__(self) -> None:
        _positive("ball radius", self.radius)

    def height(self, r: np.ndarray) -> np.ndarray:
        """Cutting surface height above the tip (n,) at distances r (n,) mm; inf past the ball."""
        r = np.asarray(r, dtype=float)
        R = self.radius
        with np.errstate(invalid="ignore"):
            return np.where(r <= R, R - np.sqrt(np.maximum(R * R - r * r, 0.0)), np.inf)

    def check_depth(self, depth: float) -> None:
        """Refuse depths the tool cannot cut as a round groove."""
        _positive("groove depth", depth)
        if depth > self.radius:
            raise SpecholoError(
                f"groove depth {depth:g} mm exceeds the ball radius {self.radius:g} mm: the "
                "shank would cut vertical walls that never glint; use a larger ball")

    def section(self, depth: float) -> Section:
        self.check_depth(depth)
        return Section(Tool(self.radius, depth).width,
                       ((0.0, math.acos((self.radius - depth) / self.radius)),))

    def model(self, depth: float) -> Tool:
        self.check_depth(depth)
        return Tool(self.radius, depth)

    def describe(self) -> str:
        return f"ball end, radius {self.radius:g} mm"


@dataclass(frozen=True)
class RoundCone:
    """A cone with a spherical tip: diamond drag engraver or hand scriber point.

    Attributes:
        tip_radius: radius of the rounded tip, mm.
        angle: the cone's included angle, radians.
        max_depth: deepest groove the tip can drag or scratch, mm.
    """

    # A glint is lost where another cut's centreline passes within R sin(tilt)
    # of it (same depth), so the tip radius sets what survives the crossings:
    # 0.025 mm keeps 87% of the README example's stipples in stereo as cut,
    # 0.05 mm 64% (docs: verification, *As cut*).
    tip_radius: float = 0.025
    angle: float = math.radians(90.0)
    max_depth: float = 0.3
    kind = "drag"

    def __post_init__(self) -> None:
        _positive("tip radius", self.tip_radius)
        if not (math.isfinite(self.angle) and 0 < self.angle < math.pi):
            raise SpecholoError(
                f"tool angle must be in (0, 180) degrees, got {math.degrees(self.angle):g}")

    @property
    def _joint(self) -> tuple[float, float]:
        """Where the sphere meets the cone: distance from the axis and height."""
        half = 0.5 * self.angle
        r = self.tip_radius
        return r * math.cos(half), r * (1.0 - math.sin(half))

    def height(self, r: np.ndarray) -> np.ndarray:
        r = np.asarray(r, dtype=float)
        rj, hj = self._joint
        R = self.tip_radius
        sphere = R - np.sqrt(np.maximum(R * R - np.minimum(r, rj) ** 2, 0.0))
        return np.where(r <= rj, sphere, hj + (r - rj) / math.tan(0.5 * self.angle))

    def check_depth(self, depth: float) -> None:
        _positive("groove depth", depth)
        if depth > self.max_depth:
            raise SpecholoError(f"groove depth {depth:g} mm is deeper than a {self.kind} tip "
                                f"can cut ({self.max_depth:g} mm)")

    def section(self, depth: float) -> Section:
        self.check_depth(depth)
        rj, hj = self._joint
        if depth <= hj:
            return Section(Tool(self.tip_radius, depth).width,
                           ((0.0, math.acos((self.tip_radius - depth) / self.tip_radius)),))
        flank = 0.5 * math.pi - 0.5 * self.angle
        width = 2.0 * (rj + (depth - hj) * math.tan(0.5 * self.angle))
        return Section(width, ((0.0, flank),))

    def model(self, depth: float) -> Tool:
        self.check_depth(depth)
        return Tool(self.tip_radius, min(depth, self._joint[1]))

    def describe(self) -> str:
        name = "diamond drag tip" if self.kind == "drag" else "scriber point"
        return (f"{name}, tip radius {self.tip_radius:g} mm, "
                f"{math.degrees(self.angle):g} degree cone")


@dataclass(frozen=True)
class Scriber(RoundCone):
    """A hand scriber's hardened point (a sharper, finer round cone)."""

    tip_radius: float = 0.05
    angle: float = math.radians(60.0)
    kind = "scriber"


@dataclass(frozen=True)
class VBit:
    """V-bit engraving cutter.

    Attributes:
        angle: included angle, radians.
        tip_flat: width of the flat at its tip, mm (0 for a sharp point).
        max_depth: length of its cutting flank, mm.
    """

    angle: float = math.radians(60.0)
    tip_flat: float = 0.0
    max_depth: float = 3.0
    kind = "vbit"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.angle) and 0 < self.angle < math.pi):
            raise SpecholoError(
                f"tool angle must be in (0, 180) degrees, got {math.degrees(self.angle):g}")
        if not (math.isfinite(self.tip_flat) and self.tip_flat >= 0):
            raise SpecholoError(f"tip flat must be >= 0 mm, got {self.tip_flat}")

    def height(self, r: np.ndarray) -> np.ndarray:
        r = np.asarray(r, dtype=float)
        return np.maximum(r - 0.5 * self.tip_flat, 0.0) / math.tan(0.5 * self.angle)

    def check_depth(self, depth: float) -> None:
        _positive("groove depth", depth)
        if depth > self.max_depth:
            raise SpecholoError(f"groove depth {depth:g} mm is deeper than the V-bit's "
                                f"flank ({self.max_depth:g} mm)")

    def section(self, depth: float) -> Section:
        self.check_depth(depth)
        flank = 0.5 * math.pi - 0.5 * self.angle
        tilts = ((flank, flank),) if self.tip_flat == 0 else ((0.0, 0.0), (flank, flank))
        return Section(self.tip_flat + 2.0 * depth * math.tan(0.5 * self.angle), tilts)

    def model(self, depth: float) -> Tool:
        # No round part: a round tip of a hundredth of the groove's width reaching the
        # flank's tilt places glints on the centreline; the section says which survive.
        self.check_depth(depth)
        flank = 0.5 * math.pi - 0.5 * self.angle
        r = 0.01 * self.section(depth).width
        return Tool(r, r * (1.0 - math.cos(flank)))

    def describe(self) -> str:
        flat = f", {self.tip_flat:g} mm tip flat" if self.tip_flat else ""
        return f"V-bit, {math.degrees(self.angle):g} degrees{flat}"


@dataclass(frozen=True)
class Laser:
    """A laser ablating a Gaussian trough: depth d exp(-2 r^2 / w0^2), w0 = spot / 2.

    Attributes:
        spot: 1/e^2 spot diameter, mm.
        max_depth: deepest trough it ablates cleanly, mm.
    """

    spot: float = 0.1
    max_depth: float = 0.5
    kind = "laser"

    def __post_init__(self) -> None:
        _positive("laser spot diameter", self.spot)

    def height(self, r: np.ndarray, depth: float = 1.0) -> np.ndarray:
        """Trough floor height above its deepest point for a trough ``depth`` deep."""
        w0 = 0.5 * self.spot
        return depth * (1.0 - np.exp(-2.0 * np.asarray(r, dtype=float) ** 2 / (w0 * w0)))

    def check_depth(self, depth: float) -> None:
        _positive("groove depth", depth)
        if depth > self.max_depth:
            raise SpecholoError(f"groove depth {depth:g} mm is deeper than the laser ablates "
                                f"cleanly ({self.max_depth:g} mm)")

    def section(self, depth: float) -> Section:
        self.check_depth(depth)
        w0 = 0.5 * self.spot
        # Steepest slope of the Gaussian, at r = w0 / 2: 2 d / w0 * exp(-1/2).
        return Section(self.spot, ((0.0, math.atan(2.0 * depth / w0 * math.exp(-0.5))),))

    def model(self, depth: float) -> Tool:
        # The trough's floor is a circle of radius w0^2 / (4 d) near its bottom.
        self.check_depth(depth)
        w0 = 0.5 * self.spot
        radius = w0 * w0 / (4.0 * depth)
        return Tool(radius, radius * (1.0 - math.cos(self.section(depth).max_tilt)))

    def describe(self) -> str:
        return f"laser, {self.spot:g} mm spot"


Cutter = BallEnd | RoundCone | VBit | Laser


def make_cutter(kind: str, radius: float | None = None, angle_deg: float | None = None,
                tip_flat: float = 0.0, spot: float | None = None) -> Cutter:
    """A cutter from command-line style settings (mm, degrees).

    Args:
        kind: one of :data:`KINDS`.
        radius: ball or tip radius (ball, drag, scriber), mm.
        angle_deg: included angle (vbit, drag, scriber), degrees.
        tip_flat: V-bit tip flat, mm.
        spot: laser spot diameter, mm.
    """
    angle = None if angle_deg is None else math.radians(float(angle_deg))
    if kind == "ball":
        return BallEnd() if radius is None else BallEnd(float(radius))
    if kind in ("drag", "scriber"):
        cls = RoundCone if kind == "drag" else Scriber
        base = cls()
        return cls(base.tip_radius if radius is None else float(radius),
                   base.angle if angle is None else angle)
    if kind == "vbit":
        return VBit(VBit().angle if angle is None else angle, float(tip_flat))
    if kind == "laser":
        return Laser() if spot is None else Laser(float(spot))
    raise SpecholoError(f"tool must be one of {', '.join(KINDS)}, got {kind!r}")


@dataclass(frozen=True)
class ViewCheck:
    """The wall tilts a design needs against those its tool offers.

    Attributes:
        needed: (lo, hi) range of tilts of h over every served view, radians.
        offered: the tool's section.
        lost: share of served views (sampled per degree of azimuth) the walls
            cannot serve.
        stipples_losing: stipples losing at least one view.
        suggestion: a tool or depth that covers every view, in words ('' if none
            is needed).
    """

    needed: tuple[float, float]
    offered: Section
    lost: float
    stipples_losing: int
    suggestion: str
    lost_azimuths: tuple[float, float] | None = None

    def as_dict(self) -> dict[str, object]:
        return {
            "needed_tilt_deg": [math.degrees(v) for v in self.needed],
            "offered_tilt_deg": [[math.degrees(a), math.degrees(b)]
                                 for a, b in self.offered.tilts],
            "groove_width_mm": self.offered.width,
            "views_lost": self.lost, "stipples_losing_views": self.stipples_losing,
            "lost_azimuth_deg": (None if self.lost_azimuths is None
                                 else [math.degrees(v) for v in self.lost_azimuths]),
            "suggestion": self.suggestion,
        }

    def lost_views(self) -> str:
        """Which views are lost, in words ('' if none): the eye azimuths and the
        share of the sampled views."""
        if self.lost <= 0:
            return ""
        where = ""
        if self.lost_azimuths is not None:
            lo, hi = (math.degrees(v) for v in self.lost_azimuths)
            where = (f" at eye azimuths {lo:+.0f} deg" if round(lo) == round(hi)
                     else f" at eye azimuths {lo:+.0f} to {hi:+.0f} deg")
        share = f"{100 * self.lost:.1f}%" if self.lost >= 0.001 else "under 0.1%"
        return (f"{share} of views lost{where} "
                f"({self.stipples_losing} stipples); {self.suggestion}")


def _sampled_tilts(points: np.ndarray, stipple: np.ndarray, start: np.ndarray,
                   end: np.ndarray, count: np.ndarray, first: np.ndarray, light: np.ndarray,
                   point_light: bool, radius: float, height: float) -> np.ndarray:
    """Tilt of h at each run's samples (run i's at first[i] .. first[i] + count[i] - 1).

    One pass, nothing of size (samples, 3) in memory: a million stipples take
    ~10^8 samples.
    """
    out = np.empty(first[-1])
    chunked(_tilts_of, 0, start.size, points, stipple, start, end, count, first, light,
            point_light, radius, height, out, grain=256)
    return out


@kernel(nogil=True)
def _tilts_of(lo: int, hi: int, points: np.ndarray, stipple: np.ndarray, start: np.ndarray,
              end: np.ndarray, count: np.ndarray, first: np.ndarray, light: np.ndarray,
              point_light: bool, radius: float, height: float, out: np.ndarray) -> None:
    """:func:`_sampled_tilts` of runs lo .. hi - 1 into out."""
    for i in range(lo, hi):
        p = stipple[i]
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        last = max(count[i] - 1, 1)
        for k in range(count[i]):
            theta = start[i] + (k / last) * (end[i] - start[i])
            ex, ey, ez = radius * math.sin(theta), height, radius * math.cos(theta)
            # The sightline from the eye through the point, where it meets z = 0.
            t = ez / (ez - pz)
            gx, gy = ex + t * (px - ex), ey + t * (py - ey)
            ux, uy, uz = ex - gx, ey - gy, ez
            inv = 1.0 / math.sqrt(ux * ux + uy * uy + uz * uz)
            lx, ly, lz = light[0], light[1], light[2]
            if point_light:
                lx, ly = lx - gx, ly - gy
                linv = 1.0 / math.sqrt(lx * lx + ly * ly + lz * lz)
                lx, ly, lz = lx * linv, ly * linv, lz * linv
            hx, hy, hz = lx + ux * inv, ly + uy * inv, lz + uz * inv
            c = hz / math.sqrt(hx * hx + hy * hy + hz * hz)
            out[first[i] + k] = math.acos(min(max(c, -1.0), 1.0))


def needed_tilts(points: np.ndarray, stipple: np.ndarray, start: np.ndarray, end: np.ndarray,
                 light: Light, viewer: Viewer,
                 step: float = math.radians(1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Tilt of h where each stipple's sightlines cross the plate, over its served views.

    Args:
        points: (n, 3) stipples.
        stipple, start, end: (r,) view intervals (stipple id, eye azimuths in radians).
        light: the :class:`~specholo.setup.Light`.
        viewer: the :class:`~specholo.setup.Viewer` (eyes on its circle, at its height).
        step: azimuth sampling, radians (each interval's ends are always sampled).

    Returns:
        tilts (s,) in radians, and (r + 1,) where each interval's samples start
        (interval i's are tilts[first[i]:first[i + 1]]).
    """
    start = np.ascontiguousarray(start, dtype=float)
    end = np.ascontiguousarray(end, dtype=float)
    stipple = np.ascontiguousarray(stipple, dtype=np.int64)
    count = np.maximum(np.ceil((end - start) / step).astype(np.int64), 0) + 1
    first = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    point_light = light.distance is not None
    where = light.position if point_light else light.direction
    tilts = _sampled_tilts(np.ascontiguousarray(points, dtype=float), stipple, start, end,
                           count, first, np.asarray(where, dtype=float), point_light,
                           viewer.eye_radius, float(viewer.height))
    return tilts, first


def check_views(cutter: Cutter, depth: float, points: np.ndarray, stipple: np.ndarray,
                start: np.ndarray, end: np.ndarray, light: Light, viewer: Viewer,
                known: tuple[np.ndarray, np.ndarray] | None = None) -> ViewCheck:
    """Check that the tool's walls offer every tilt the served views need.

    Args:
        cutter: the tool.
        depth: groove depth, mm.
        points, stipple, start, end, light, viewer: as :func:`needed_tilts`.
        known: what :func:`needed_tilts` returns for them, if already found.

    Returns:
        The check, with a suggestion when views are lost.
    """
    section = cutter.section(depth)
    tilts, first = known if known is not None else needed_tilts(
        points, stipple, start, end, light, viewer)
    if tilts.size == 0:
        return ViewCheck((0.0, 0.0), section, 0.0, 0, "")
    ok = section.covers(tilts)
    lost = float(1.0 - ok.mean())
    bad = np.flatnonzero(~ok)
    run = np.searchsorted(first, bad, side="right") - 1
    owner = np.asarray(stipple)[run]
    losing = int(np.unique(owner).size)
    needed = (float(tilts.min()), float(tilts.max()))
    azimuths = None
    if bad.size:
        # The eye azimuth of each lost sample, as _tilts_of spaced them.
        k = bad - first[run]
        last = np.maximum(first[run + 1] - first[run] - 1, 1)
        s0, s1 = np.asarray(start, dtype=float)[run], np.asarray(end, dtype=float)[run]
        theta = s0 + (k / last) * (s1 - s0)
        azimuths = (float(theta.min()), float(theta.max()))
    return ViewCheck(needed, section, lost, losing,
                     "" if lost == 0 else suggest(cutter, depth, needed[1]), azimuths)


def steepest_wall(cutter: Cutter) -> float | None:
    """The steepest wall tilt (radians) the tool's shape offers at any depth, or
    None for a tool of one tilt (a V-bit): a round drag tip's cone flank, a
    ball's or a laser's nearly upright wall."""
    if isinstance(cutter, RoundCone):
        return 0.5 * math.pi - 0.5 * cutter.angle
    if isinstance(cutter, (BallEnd, Laser)):
        return 0.5 * math.pi - 1e-6
    return None


def depth_for(cutter: Cutter, tilt: float) -> float | None:
    """Shallowest depth (mm) whose walls reach ``tilt`` radians, or None if none does."""
    if not 0.0 <= tilt < 0.5 * math.pi:
        return None
    if isinstance(cutter, BallEnd):
        return cutter.radius * (1.0 - math.cos(tilt))
    if isinstance(cutter, RoundCone):
        if tilt > 0.5 * math.pi - 0.5 * cutter.angle:
            return None
        return cutter.tip_radius * (1.0 - math.cos(tilt))
    if isinstance(cutter, Laser):
        return math.tan(tilt) * 0.25 * cutter.spot * math.exp(0.5)
    return None


def suggest(cutter: Cutter, depth: float, tilt: float) -> str:
    """A depth or tool whose walls reach ``tilt`` radians, in words."""
    deg = math.degrees(tilt)
    need = f"walls up to {deg:.1f} degrees"

    def mm(v: float) -> str:  # rounded up: the suggestion must suffice
        return f"{math.ceil(v * 1000.0) / 1000.0:.3f}"

    if tilt >= 0.5 * math.pi - 1e-6:
        return f"{need} cannot be cut; lower the view range or raise the light"
    if isinstance(cutter, BallEnd):
        d = cutter.radius * (1.0 - math.cos(tilt))
        return f"{need}: cut at least {mm(d)} mm deep with this ball"
    if isinstance(cutter, RoundCone):
        flank = 0.5 * math.pi - 0.5 * cutter.angle
        if tilt <= flank:
            d = cutter.tip_radius * (1.0 - math.cos(tilt))
            return f"{need}: cut at least {mm(d)} mm deep with this tip"
        # Rounded down: a cone of the stated angle must offer the wall.
        angle = math.floor(180.0 - 2.0 * deg)
        return (f"{need}, steeper than this {math.degrees(cutter.angle):.0f} degree cone's "
                f"{math.degrees(flank):.1f} degree flanks: a cone of at most {angle} degrees "
                "included angle, or a ball end, would serve them")
    if isinstance(cutter, Laser):
        d = math.tan(tilt) * 0.25 * cutter.spot * math.exp(0.5)
        return f"{need}: ablate at least {mm(d)} mm deep with this spot"
    r = 0.25
    return (f"{need}: a V-bit offers a single wall tilt; use a ball end (e.g. radius {r:g} mm, "
            f"depth {mm(r * (1.0 - math.cos(tilt)))} mm) or a round drag tip")

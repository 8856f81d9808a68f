"""The physical setup of a hologram: light, viewer, cutting tool, machining.

All lengths in mm, all angles in radians, in the plate frame (x right, y up,
z toward the viewer, plate at z = 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from specholo.errors import SpecholoError


def _finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise SpecholoError(f"{name} must be a finite number, got {value}")
    return value


@dataclass(frozen=True)
class Light:
    """A sun (collimated) or a point light in the y-z plane above the plate.

    Attributes:
        elevation: angle a of the light direction (0, cos a, sin a) above the
            plate, in radians; 0 grazes the plate from above, pi/2 shines straight on.
        distance: distance of a point light from the plate centre along that
            direction in mm, or None for a sun.
    """

    elevation: float
    distance: float | None = None

    def __post_init__(self) -> None:
        a = _finite("light elevation", self.elevation)
        if not 0.0 < a < math.pi:
            raise SpecholoError(
                f"light elevation must be in (0, 180) degrees (light in front of the plate), "
                f"got {math.degrees(a):g}"
            )
        if self.distance is not None:
            d = _finite("light distance", self.distance)
            if d <= 0:
                raise SpecholoError(f"light distance must be positive, got {d:g}")

    @property
    def direction(self) -> np.ndarray:
        """Unit vector (3,) from the plate centre toward the light."""
        return np.array([0.0, math.cos(self.elevation), math.sin(self.elevation)])

    @property
    def position(self) -> np.ndarray | None:
        """Point light position (3,) in mm, or None for a sun."""
        return None if self.distance is None else self.distance * self.direction

    def towards(self, points: np.ndarray) -> np.ndarray:
        """Unit vectors from points toward the light.

        Args:
            points: (n, 3) positions in mm.

        Returns:
            (n, 3) unit vectors.
        """
        points = np.asarray(points, dtype=float)
        if self.distance is None:
            return np.broadcast_to(self.direction, points.shape).copy()
        v = self.position - points
        return v / np.linalg.norm(v, axis=-1, keepdims=True)



#: Refractive index of PMMA (acrylic) for visible light.
ACRYLIC_INDEX = 1.49
#: Largest refractive index of a clear plate (diamond is 2.42).
MAX_INDEX = 3.0


@dataclass(frozen=True)
class ClearPlate:
    """A clear plate: engraved front face at z = 0, planar back face at z = -thickness.

    Attributes:
        thickness: plate thickness T, mm.
        index: refractive index n of the plate (air is 1).
    """

    thickness: float = 3.0
    index: float = ACRYLIC_INDEX

    def __post_init__(self) -> None:
        t = float(self.thickness)
        if not (math.isfinite(t) and t > 0):
            raise SpecholoError(f"plate thickness must be a positive number of mm, got {t:g}")
        n = float(self.index)
        if not (math.isfinite(n) and n > 1.0):
            raise SpecholoError(f"plate index must be a finite number above 1, got {n:g}")

    @property
    def back_z(self) -> float:
        """Height of the back face, mm."""
        return -float(self.thickness)


@dataclass(frozen=True)
class BackLight(Light):
    """A light BEHIND a clear plate, shining through it (refraction holograms).

    The same frame as :class:`Light`: the direction from the plate centre toward
    the light is (0, cos a, sin a), now with a in (-pi, 0): -pi/2 shines
    straight through from behind, a near 0 grazes the back from above. A point
    light sits ``distance`` mm from the plate centre (the front face's) along
    that direction, and must lie behind the back face z = -thickness.

    Attributes:
        elevation: angle a, radians, in (-pi, 0).
        distance: point light distance from the plate centre, mm, or None for a sun.
        thickness: plate thickness T (front face z = 0, back face z = -T), mm.
        index: refractive index n of the plate (air is 1).
    """

    thickness: float = 3.0
    index: float = ACRYLIC_INDEX

    def __post_init__(self) -> None:
        a = _finite("light elevation", self.elevation)
        if not -math.pi < a < 0.0:
            raise SpecholoError(
                f"a refraction plate is lit from behind: light elevation must be in "
                f"(-180, 0) degrees (-90 straight behind), got {math.degrees(a):g}")
        t = _finite("plate thickness", self.thickness)
        if t <= 0:
            raise SpecholoError(f"plate thickness must be positive, got {t:g}")
        n = _finite("refractive index", self.index)
        if not 1.0 < n <= MAX_INDEX:
            raise SpecholoError(f"refractive index must be above 1 and at most {MAX_INDEX:g}, "
                                f"got {n:g}")
        if self.distance is not None:
            d = _finite("light distance", self.distance)
            if d <= 0:
                raise SpecholoError(f"light distance must be positive, got {d:g}")
            z = d * math.sin(a)
            if not z < -t:
                raise SpecholoError(
                    f"the light must be behind the plate's back face (z < {-t:g} mm): at "
                    f"{d:g} mm and {math.degrees(a):g} degrees it is at z = {z:.3g} mm")

    @property
    def plate(self) -> ClearPlate:
        """The clear plate the light shines through."""
        return ClearPlate(float(self.thickness), float(self.index))

@dataclass(frozen=True)
class Viewer:
    """Eyes moving on a horizontal arc about the plate centre.

    Attributes:
        distance: arc radius D in mm.
        height: eye height y_e in mm.
        half_range: largest azimuth |theta| of the arc, in radians (< pi/2).
        ipd: interocular distance in mm; the eyes sit IPD apart along the arc's tangent.
    """

    distance: float = 600.0
    height: float = 0.0
    half_range: float = math.radians(45.0)
    ipd: float = 64.0

    def __post_init__(self) -> None:
        d = _finite("view distance", self.distance)
        _finite("eye height", self.height)
        r = _finite("view range", self.half_range)
        ipd = _finite("interocular distance", self.ipd)
        if d <= 0:
            raise SpecholoError(f"view distance must be positive, got {d:g}")
        if not 0.0 <= r < math.pi / 2:
            raise SpecholoError(
                f"view range must be in [0, 90) degrees (eyes in front of the plate), "
                f"got {math.degrees(r):g}"
            )
        if not 0.0 < ipd < d:
            raise SpecholoError(f"interocular distance must be in (0, view distance), got {ipd:g}")
        if math.cos(r) * d <= 0.5 * ipd:
            raise SpecholoError("eyes at the edge of the view range would be behind the plate")

    @property
    def eye_half_angle(self) -> float:
        """Azimuth offset of each eye from the head's azimuth, in radians."""
        return math.atan2(0.5 * self.ipd, self.distance)

    @property
    def eye_radius(self) -> float:
        """Distance of every eye from the plate centre, mm.

        Eyes sit IPD/2 off the arc along its tangent, so all of them lie on one
        circle of radius sqrt(D^2 + (IPD/2)^2): designs aim at that circle, where
        real eyes are, rather than at the arc of head centres.
        """
        return math.hypot(self.distance, 0.5 * self.ipd)

    @property
    def design_range(self) -> float:
        """Largest eye azimuth on the eyes' circle, radians: the range designs serve."""
        # A small margin so eyes exactly at the edge still meet a groove, not its end.
        return self.half_range + self.eye_half_angle + math.radians(0.5)

    def head(self, theta: np.ndarray) -> np.ndarray:
        """Head centres on the arc.

        Args:
            theta: (n,) azimuths in radians.

        Returns:
            (n, 3) positions (D sin theta, y_e, D cos theta).
        """
        theta = np.asarray(theta, dtype=float)
        return np.stack(
            [self.distance * np.sin(theta), np.full_like(theta, self.height),
             self.distance * np.cos(theta)],
            axis=-1,
        )

    def eye(self, theta: np.ndarray) -> np.ndarray:
        """Single eyes at azimuths theta on the eyes' circle (radius :attr:`eye_radius`).

        Args:
            theta: (n,) eye azimuths in radians.

        Returns:
            (n, 3) eye positions.
        """
        theta = np.asarray(theta, dtype=float)
        r = self.eye_radius
        return np.stack(
            [r * np.sin(theta), np.full_like(theta, self.height), r * np.cos(theta)], axis=-1)

    def stereo(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Left and right eyes of heads on the arc looking at the plate centre.

        Args:
            theta: (n,) head azimuths in radians.

        Returns:
            Two (n, 3) arrays: left and right eye positions, IPD apart along the
            arc's tangent (both on the eyes' circle).
        """
        theta = np.asarray(theta, dtype=float)
        centre = self.head(theta)
        tangent = np.stack([np.cos(theta), np.zeros_like(theta), -np.sin(theta)], axis=-1)
        half = 0.5 * self.ipd * tangent
        return centre - half, centre + half


@dataclass(frozen=True)
class Tool:
    """A ball-end cutter (or round engraving tip) cutting grooves of a fixed depth.

    Attributes:
        radius: ball radius R in mm.
        depth: groove depth d in mm (0 < d <= R).
    """

    radius: float = 0.25
    depth: float = 0.08

    def __post_init__(self) -> None:
        r = _finite("tool radius", self.radius)
        d = _finite("groove depth", self.depth)
        if r <= 0:
            raise SpecholoError(f"tool radius must be positive, got {r:g}")
        if not 0 < d <= r:
            raise SpecholoError(f"groove depth must be in (0, tool radius {r:g}], got {d:g}")

    @property
    def max_tilt(self) -> float:
        """Largest tilt of the groove wall normal from the plate normal, radians."""
        return math.acos((self.radius - self.depth) / self.radius)

    @property
    def width(self) -> float:
        """Groove width at the plate surface, mm."""
        r, d = self.radius, self.depth
        return 2.0 * math.sqrt(r * r - (r - d) ** 2)


#: Lowest safe height, mm. Rapids travel at the safe height above the surface:
#: a blank is flat and level to tens of micrometres at best (stock bows, a
#: table is trammed to ~0.05 mm over a plate), so a rapid any closer drags the
#: tip across the plate at full speed wherever it stands proud.
MIN_SAFE_Z = 0.1
#: Lowest hop clearance, mm. A hop (see :class:`Machining`) starts where a
#: groove ended and ends where the next begins, at most ``hop_max`` away: over
#: a few mm a plate flat to a few hundredths over its whole size changes by a
#: micrometre or two, so what the hop must clear is the local error of Z = 0,
#: which the grooves' own depth (12-80 um) already needs well below its size,
#: and the lip a ploughing tip raises beside a groove (a few um).
MIN_HOP = 0.01
#: Highest hop clearance, mm: a lift of a millimetre is a full retract (the
#: default safe height).
MAX_HOP = 1.0
#: Longest hop, mm: over 10 mm a plate tilted 0.05 mm across 100 mm rises by
#: 5 um, still well inside the lowest clearance.
MAX_HOP_DISTANCE = 10.0
#: Highest cutting and plunge feed, mm/min: beyond the fastest machines (a
#: linear-motor router runs at ~60 m/min), and short enough that every firmware
#: reads the F word whole (GRBL reads 8 significant digits).
MAX_FEED = 100_000.0
#: Highest spindle speed, rpm (air-bearing spindles reach a few hundred thousand).
MAX_SPINDLE = 1e6


@dataclass(frozen=True)
class Machining:
    """Feeds and heights for the G-code (mm and mm/min), shared by every job: a
    setting no machine should run is refused here, before any program is written.

    Between two paths the tool retracts to ``safe_z`` and rapids over, unless
    the next path starts at most ``hop_max`` from where the last one ended: it
    then *hops*, lifting only ``hop`` above the surface and moving over at the
    cutting feed (a ``G1``: rapids stay at the safe height), and plunges that
    short way back. ``hop_max`` 0 turns hops off. The default clearance 0.03 mm
    is about twice what a hop must clear (see :data:`MIN_HOP`); each further
    0.01 mm costs 0.01 mm / ``plunge`` per hop. The default distance 3 mm is
    about where, at the default feeds and heights, a hop stops being faster than
    a full retract: it saves 0.58 s of plunging (0.97 mm at 100 mm/min) and
    loses 0.18 s per mm of travel (300 rather than 3000 mm/min), even at 3.2 mm.
    """

    feed: float = 300.0
    plunge: float = 100.0
    safe_z: float = 1.0
    spindle: float = 12000.0
    hop: float = 0.03
    hop_max: float = 3.0

    def __post_init__(self) -> None:
        for name in ("feed", "plunge", "safe_z"):
            v = _finite(name.replace("_", " "), getattr(self, name))
            if v <= 0:
                raise SpecholoError(f"{name.replace('_', ' ')} must be positive, got {v:g}")
        for name in ("feed", "plunge"):
            v = float(getattr(self, name))
            if v > MAX_FEED:
                raise SpecholoError(f"{name} {v:g} mm/min is out of range: at most "
                                    f"{MAX_FEED:g} mm/min")
        if self.safe_z < MIN_SAFE_Z:
            raise SpecholoError(f"safe z {self.safe_z:g} mm is out of range: rapids need at least "
                                f"{MIN_SAFE_Z:g} mm of clearance above the surface")
        s = _finite("spindle speed", self.spindle)
        if not 0 <= s <= MAX_SPINDLE:
            raise SpecholoError(f"spindle speed must be in [0, {MAX_SPINDLE:g}] rpm, got {s:g}")
        h = _finite("hop", self.hop)
        if not (MIN_HOP <= h <= MAX_HOP and h < self.safe_z):
            raise SpecholoError(f"hop {h:g} mm is out of range: it must be in [{MIN_HOP:g}, "
                                f"{MAX_HOP:g}] mm and below the safe height {self.safe_z:g} mm")
        d = _finite("hop max", self.hop_max)
        if not 0 <= d <= MAX_HOP_DISTANCE:
            raise SpecholoError(f"hop max {d:g} mm is out of range: it must be in "
                                f"[0, {MAX_HOP_DISTANCE:g}] mm (0 for no hops)")

    def hops(self, lengths: np.ndarray) -> np.ndarray:
        """Which moves between paths, of XY lengths (k,) mm, are hops (bool (k,)).

        The writer and the time estimate both decide here, so they agree."""
        lengths = np.asarray(lengths, dtype=float)
        if self.hop_max <= 0:
            return np.zeros(lengths.shape, dtype=bool)
        return lengths <= self.hop_max


#: How a non-spinning tip may be held: ``rigid`` (the Z the program says is
#: the tip's) or ``spring`` (a spring-loaded drag engraver, whose spring presses
#: the tip on the plate and gives way to its height).
HOLDERS = ("rigid", "spring")
#: Spring compression a spring holder cuts with by default, mm: the program cuts
#: this far below the touch-off and the spring, not the Z, sets the force.
#: Makers of spring-loaded diamond drag engravers have users program the
#: engraving a few tenths of a millimetre below the touch-off, 0.010-0.020 in
#: (0.25-0.5 mm) in the instructions of hobby-router drag bits; 0.3 mm lies in
#: that range. What depth a preload cuts depends on the spring and the plate:
#: test strokes on scrap set it (docs/fabrication.md, *Holders*).
DEFAULT_PRELOAD = 0.3
#: Lowest and highest preload, mm. Below 0.05 mm the plate's own height error
#: over the grooves (a few hundredths, see :data:`SPRING_LIFT`) changes the
#: compression, and so the force, by as much as the preload itself; beyond 2 mm
#: a holder's spring (a few millimetres of travel) nears the end of its stroke,
#: where it stops being a spring.
PRELOAD_RANGE = (0.05, 2.0)
#: Lowest height of a spring holder's tip between strokes, mm. A spring holder
#: is touched off at one point and nothing measures the plate elsewhere, so
#: unlike a rigid holder's hop over a levelled plate (:data:`MIN_HOP`), its lift
#: must clear the plate's height error relative to Z0 anywhere on the grooves,
#: not the change over a few mm: a blank clamped on a surfaced spoilboard lies
#: flat to about 0.03 mm over its size, and a touch-off on a paper shim is good
#: to about 0.02 mm (the jog step and the shim's drag). At a rigid holder's
#: 0.03 mm hop a spring holder's tip stays on the plate wherever the plate
#: stands a little proud, and drags across it on every hop: a scratch.
SPRING_LIFT = 0.05


@dataclass(frozen=True)
class Holder:
    """How a tip is held in the machine (mm).

    A ``rigid`` holder cuts at the Z the program gives, so the plate's height
    must be known to a fraction of the groove's depth (probed and levelled). A
    ``spring`` holder is touched off on the plate (Z = 0 with the tip touching)
    and cuts at Z = -``preload``: the spring, compressed by the preload, presses
    the tip and the groove's depth follows from that force, whatever the
    plate's height; between strokes the tip lifts at least :data:`SPRING_LIFT`
    above the surface.

    Attributes:
        kind: one of :data:`HOLDERS`.
        preload: a spring holder's compression while it cuts, mm.
    """

    kind: str = "rigid"
    preload: float = DEFAULT_PRELOAD

    def __post_init__(self) -> None:
        if self.kind not in HOLDERS:
            raise SpecholoError(f"holder must be one of {', '.join(HOLDERS)}, got {self.kind!r}")
        p = _finite("preload", self.preload)
        lo, hi = PRELOAD_RANGE
        if not lo <= p <= hi:
            raise SpecholoError(f"preload {p:g} mm is out of range: it must be in [{lo:g}, "
                                f"{hi:g}] mm of spring compression")

    @property
    def spring(self) -> bool:
        """True for a spring-loaded holder."""
        return self.kind == "spring"

    def lift(self, hop: float) -> float:
        """The height of the moves between strokes over the plate, mm: the hop
        height, raised to :data:`SPRING_LIFT` for a spring holder."""
        return max(float(hop), SPRING_LIFT) if self.spring else float(hop)

    def program(self, depth: float, machining: Machining) -> tuple[float, Machining]:
        """What the program runs at: the depth its cuts' Z reaches (the groove's,
        or a spring holder's preload) and the machining with the hop height at
        :meth:`lift`. The writer and the time estimate both take it from here."""
        if not self.spring:
            return float(depth), machining
        return float(self.preload), replace(machining, hop=self.lift(machining.hop))


@dataclass(frozen=True)
class Setup:
    """Everything physical a design depends on."""

    light: Light = field(default_factory=lambda: Light(math.radians(45.0)))
    viewer: Viewer = field(default_factory=Viewer)
    tool: Tool = field(default_factory=Tool)
    machining: Machining = field(default_factory=Machining)


#: Physical bounds of the design settings: (lowest, highest, unit), both included.
#: Beyond them a design is not a hologram anyone can cut or see (a 2 m tool, a
#: 1 nm band, eyes 100 km up), and the construction's work grows without bound.
SETTING_BOUNDS: dict[str, tuple[float, float, str]] = {
    "size": (0.01, 10_000.0, "mm"),
    "center_z": (-10_000.0, 10_000.0, "mm"),
    "rotate_x": (-360.0, 360.0, "degrees"),
    "rotate_y": (-360.0, 360.0, "degrees"),
    "rotate_z": (-360.0, 360.0, "degrees"),
    "offset_x": (-10_000.0, 10_000.0, "mm"),
    "offset_y": (-10_000.0, 10_000.0, "mm"),
    "light_distance": (1.0, 1e7, "mm"),
    "view_distance": (10.0, 1e7, "mm"),
    "view_range": (0.0, 89.0, "degrees"),
    "eye_height": (-1e5, 1e5, "mm"),
    "ipd": (1.0, 1000.0, "mm"),
    "spacing": (0.001, 10_000.0, "mm"),
    "band": (0.001, 1000.0, "mm"),
    "tool_radius": (0.001, 25.0, "mm"),
    "tool_angle": (1.0, 179.0, "degrees"),
    "tip_flat": (0.0, 10.0, "mm"),
    "spot": (0.005, 1.0, "mm"),
    "depth": (1e-4, 100.0, "mm"),
    "plate_width": (1.0, 100_000.0, "mm"),
    "plate_height": (1.0, 100_000.0, "mm"),
    "stock_thickness": (0.001, 1000.0, "mm"),
    "feed": (0.01, MAX_FEED, "mm/min"),
    "plunge": (0.01, MAX_FEED, "mm/min"),
    "safe_z": (MIN_SAFE_Z, 1000.0, "mm"),
    "hop": (MIN_HOP, MAX_HOP, "mm"),
    "hop_max": (0.0, MAX_HOP_DISTANCE, "mm"),
    "spindle": (0.0, 1e6, "rpm"),
}

"""Machines a design can be timed on: their kinematics and feeds, each sourced.

A :class:`MachineProfile` holds what the time estimate
(:func:`specholo.fabrication.programs.timing.estimate_time`) needs of one class of
machine: how fast and how hard its axes move, how it takes corners, the feeds a
drag tip or scriber runs at on it, and what a plotter's pen or a galvo's beam
costs per stroke. :data:`MACHINES` holds one entry a profile, by name;
:func:`machine_profile` looks one up. Every profile names in ``source`` where
its figures come from, and which of them are typical values rather than
published ones (docs/machines.md gives the table).

Rates are in mm/min, as every feed at the edges of specholo is; accelerations
in mm/s^2; delays in seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from specholo.errors import SpecholoError

#: Kinds of machine: a spindle or drag-tip router or mill (with a Z axis), a pen
#: plotter (a pen lift instead of Z), a CO2 gantry laser and a galvo marker.
KINDS = ("router", "mill", "plotter", "co2", "galvo")
#: The tools each kind carries (``DesignConfig.tool``): a plotter drags its tip
#: in the pen holder (nothing spins), a laser is only a laser.
TOOLS = {"router": ("ball", "vbit", "drag", "scriber"), "mill": ("ball", "vbit", "drag", "scriber"),
         "plotter": ("drag", "scriber"), "co2": ("laser",), "galvo": ("laser",)}

#: inches to mm (AxiDraw's figures are in inches).
_INCH = 25.4


@dataclass(frozen=True)
class MachineProfile:
    """One class of machine, as the time estimate models it.

    Attributes:
        name: the table's key, what ``--machine`` takes.
        kind: one of :data:`KINDS`.
        title: a few words a maker recognises ("Shapeoko-class GRBL").
        source: where the figures come from, and which are typical values.
        xy_rate: X/Y maximum rate, mm/min: rapids, a plotter's pen-up travel,
            a laser's travel between strokes (a galvo's jump speed).
        feed: default cutting feed, mm/min (a laser's mark speed).
        xy_accel: X/Y acceleration, mm/s^2; None for a galvo, whose mirrors'
            inertia the estimate neglects.
        junction_deviation: GRBL's ``$11``, mm: the speed through a corner
            (for another controller the tolerance that limits it the same way).
        z_rate: Z maximum rate, mm/min; None without a Z axis.
        z_accel: Z acceleration, mm/s^2; None without a Z axis.
        plunge: default plunge feed, mm/min; None without a Z axis.
        pen_raise: seconds a plotter takes to lift its pen after a stroke.
        pen_lower: seconds a plotter takes to lower its pen before a stroke.
        laser_on_delay: seconds a galvo waits for the laser at a stroke's start.
        laser_off_delay: seconds a galvo waits for the laser at a stroke's end.
        jump_delay: seconds a galvo lets its mirrors settle after a jump.
        polygon_delay: seconds a galvo waits at each corner of a stroke.
    """

    name: str
    kind: str
    title: str
    source: str
    xy_rate: float
    feed: float
    xy_accel: float | None = None
    junction_deviation: float = 0.0
    z_rate: float | None = None
    z_accel: float | None = None
    plunge: float | None = None
    pen_raise: float = 0.0
    pen_lower: float = 0.0
    laser_on_delay: float = 0.0
    laser_off_delay: float = 0.0
    jump_delay: float = 0.0
    polygon_delay: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise SpecholoError(f"machine kind must be one of {', '.join(KINDS)}, "
                                f"got {self.kind!r}")
        positive: list[tuple[str, float | None]] = [("xy_rate", self.xy_rate),
                                                     ("feed", self.feed)]
        if self.kind != "galvo":  # a galvo's mirrors are modelled without inertia
            positive.append(("xy_accel", self.xy_accel))
        if self.has_z:
            positive += [("z_rate", self.z_rate), ("z_accel", self.z_accel),
                         ("plunge", self.plunge)]
        for name, value in positive:
            if value is None or not (math.isfinite(value) and value > 0):
                raise SpecholoError(f"machine {self.name}: {name} must be a positive number, "
                                    f"got {value}")
        for name in ("junction_deviation", "pen_raise", "pen_lower", "laser_on_delay",
                     "laser_off_delay", "jump_delay", "polygon_delay"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise SpecholoError(f"machine {self.name}: {name} must be a number >= 0, "
                                    f"got {value}")

    @property
    def has_z(self) -> bool:
        """Whether the tool plunges and retracts on a Z axis (a router or a mill)."""
        return self.kind in ("router", "mill")

    @property
    def lifts(self) -> bool:
        """Whether every stroke lifts the tool and lowers it again (a router's or
        mill's Z, a plotter's pen), costing about as much as a short cut."""
        return self.kind in ("router", "mill", "plotter")

    @property
    def laser(self) -> bool:
        """Whether it marks with a beam (no plunges, retracts or hops)."""
        return self.kind in ("co2", "galvo")

    @property
    def tools(self) -> tuple[str, ...]:
        """The ``--tool`` values it carries."""
        return TOOLS[self.kind]

    @property
    def mark_speed(self) -> float:
        """A laser's default mark speed, mm/min (its :attr:`feed`)."""
        return self.feed

    @property
    def jump_speed(self) -> float:
        """A laser's travel speed between strokes, mm/min (its :attr:`xy_rate`)."""
        return self.xy_rate


#: Where the GRBL figures are: the settings page of GRBL 1.1's wiki and its
#: per-machine defaults file.
_GRBL = ("gnea/grbl wiki, Grbl v1.1 Configuration ($11 junction deviation 0.010 mm, the "
         "default); gnea/grbl grbl/defaults.h")

#: The profiles, one entry each (:data:`MACHINES` indexes them by name).
PROFILES: tuple[MachineProfile, ...] = (
    MachineProfile(
        name="grbl-router", kind="router", title="Shapeoko-class GRBL",
        source=(f"{_GRBL}: DEFAULTS_SHAPEOKO_3 ($110-$112 5000 mm/min, $120/$121 400 mm/s^2); "
                "Z 50 mm/s^2 is the lead-screw Z of DEFAULTS_SHAPEOKO_2 and DEFAULTS_X_CARVE "
                "(the belt-Z Shapeoko 3 lists 400), typical of a Z-Plus or HDZ; feed 1000 and "
                "plunge 300 mm/min typical of diamond drag engraving"),
        xy_rate=5000.0, xy_accel=400.0, junction_deviation=0.01,
        z_rate=5000.0, z_accel=50.0, feed=1000.0, plunge=300.0),
    MachineProfile(
        name="linuxcnc-mill", kind="mill", title="benchtop LinuxCNC mill",
        source=("LinuxCNC configs/sim/axis/axis_mm.ini, the example of the INI docs "
                "([AXIS_X/Y/Z] MAX_VELOCITY 30.48 mm/s, MAX_ACCELERATION 508 mm/s^2); its "
                "trajectory planner blends corners (G64), taken as a 0.01 mm tolerance "
                "(typical: the program sets no G64 P); feed 1000 and plunge 300 mm/min "
                "typical of diamond drag engraving"),
        xy_rate=30.48 * 60.0, xy_accel=508.0, junction_deviation=0.01,
        z_rate=30.48 * 60.0, z_accel=508.0, feed=1000.0, plunge=300.0),
    MachineProfile(
        name="pen-plotter", kind="plotter", title="AxiDraw-class plotter",
        source=("evil-mad/axidraw axidraw_conf.py 3.9 defaults (speed_pendown 25 and "
                "speed_penup 75 % of speed_lim_xy_hr 8.6979 in/s over 110; accel 75 % of "
                "accel_rate 40 in/s^2; pen 60/30 % up/down, pen_rate_raise 75, "
                "pen_rate_lower 50, servo_move_min 45 ms, servo_move_slope 2.69 ms/%, "
                "servo_sweep_time 200 ms, as its pen_handling times them); junction "
                "deviation 0.01 mm typical (GRBL's default, as vpype-gcode plotters run)"),
        xy_rate=75 * 8.6979 / 110 * _INCH * 60.0, xy_accel=0.75 * 40.0 * _INCH,
        junction_deviation=0.01, feed=25 * 8.6979 / 110 * _INCH * 60.0,
        pen_raise=0.130, pen_lower=0.146),
    MachineProfile(
        name="co2-laser", kind="co2", title="40-100 W CO2 gantry laser, LightBurn",
        source=("typical of Ruida controllers under LightBurn (not published figures): "
                "idle speed 300 mm/s, acceleration 3000 mm/s^2, mark speed 100 mm/s for a "
                "shallow trough in acrylic; corners as a 0.02 mm junction deviation"),
        xy_rate=300.0 * 60.0, xy_accel=3000.0, junction_deviation=0.02, feed=100.0 * 60.0),
    MachineProfile(
        name="galvo-fiber", kind="galvo", title="20-30 W galvo fiber marker, EzCad/LightBurn",
        source=("meerk40t/meerk40t balormk/device.py, the defaults of its driver for "
                "EzCad2 (BJJCZ) boards: cut speed 100 mm/s, travel 2000 mm/s, laser on "
                "100 us, laser off 100 us, polygon 100 us, long-jump delay 200 us (short "
                "jumps 8 us: the estimate takes the long one for every jump)"),
        xy_rate=2000.0 * 60.0, feed=100.0 * 60.0,
        laser_on_delay=100e-6, laser_off_delay=100e-6, jump_delay=200e-6,
        polygon_delay=100e-6),
)

#: Every profile by name.
MACHINES: dict[str, MachineProfile] = {p.name: p for p in PROFILES}


def machine_profile(name: str) -> MachineProfile:
    """The profile called ``name``.

    Raises:
        SpecholoError: naming the profiles, if there is none of that name.
    """
    try:
        return MACHINES[name]
    except (KeyError, TypeError):
        raise SpecholoError(f"unknown machine {name!r}: one of "
                            f"{', '.join(MACHINES)}") from None

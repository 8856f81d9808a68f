"""The design command's settings (``specholo design`` and its TOML), in the
units users speak (mm, degrees): every option with its bounds and defaults,
checked once, and turned into the library's setup (radians) by
:meth:`DesignConfig.setup`."""


from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields
from typing import Any

from specholo.errors import SpecholoError
from specholo.fabrication.plate import STOCK_THICKNESS
from specholo.fabrication.programs.machines import MACHINES, MachineProfile, machine_profile
from specholo.optics.cutters import (
    Cutter,
    make_cutter,
)
from specholo.scene.pose import UP_AXES, Pose
from specholo.setup import (
    ACRYLIC_INDEX,
    DEFAULT_PRELOAD,
    HOLDERS,
    MAX_INDEX,
    PRELOAD_RANGE,
    SETTING_BOUNDS,
    BackLight,
    Holder,
    Light,
    Machining,
    Setup,
    Viewer,
)
from specholo.toolpaths.striped import PLACEMENTS

METHODS = ("striped", "hyperbola", "arc", "ridged")
#: Thinning a crowded plate (see :func:`specholo.jobs.flat.design.thin_as_cut`).
THINNING = ("auto", "on", "off")
DEFAULT_STIPPLES = 2000
#: Fallback groove depth (mm) and spindle speed (rpm) by tool. A design without a
#: depth cuts just deep enough for the wall tilts its views need (see
#: :data:`TILT_MARGIN`); drag tips, scribers and lasers do not spin.
#: Extra wall tilt (radians) over the steepest a design needs, when choosing its depth.
TILT_MARGIN = math.radians(2.0)
#: Extra depth (mm) a design without a depth cuts beyond what its steepest wall
#: needs: a groove cut shallower than that loses the views of its steep walls,
#: while grooves all cut deeper keep every glint (a glint's removal radius is
#: R sin(tilt) whatever the shared depth). On the README example grooves cut
#: at random within +-5 um of the design's depth keep 0.87 of the stipples in
#: stereo as cut (lowest view), as at the depth itself; without the 5 um, +-2 um
#: keeps 0.72 (benchmarks/depth_tolerance.py).
DEPTH_ALLOWANCE = 0.005
#: Half-height of a striped design's band, mm: 0.2 for machines; 1 for the hand
#: scriber, whose strokes a person traces one by one (on the example's 150
#: stipples, 17 strokes a stipple of 2.6 mm and a p95 error under 0.9 mm,
#: against 70 strokes of 0.5 mm at 0.2; docs/fabrication.md).
BAND = 0.2
HAND_BAND = 1.0
#: With a machine whose every stroke lifts the tool (a router's or mill's Z, a
#: plotter's pen: ``MachineProfile.lifts``), the band is chosen so that, seen
#: from the viewing distance, it is this share of the neighbouring stipples'
#: spacing (never finer than :data:`BAND`): a stroke's lift costs as much as its
#: cut there, and the band sets the strokes. On the README example on the
#: grbl-router (2026-12-07): 8.1 arcmin between stipples, a band of 0.28 mm,
#: 106,434 strokes for 130,187 at 0.2, 6 h 32 min for 7 h 41 min with a rigid
#: holder, the plate as cut 0.91 / 0.88 (mean / lowest) for 0.90 / 0.87, and a
#: worst p95 error of 0.22 mm for 0.16 (docs/machines.md).
MACHINE_BAND_SHARE = 0.2
TOOL_DEFAULTS = {"ball": (0.08, 12000.0), "drag": (0.006, 0.0), "scriber": (0.012, 0.0),
                 "vbit": (0.05, 12000.0), "laser": (0.04, 0.0)}


#: Ball radius (mm) of a ridged plate's finishing raster when none is given: it
#: must follow facets a few tenths of a millimetre wide.
RIDGED_BALL_RADIUS = 0.05
#: A ridged design's own defaults (the rest are the grooved designs'): on the
#: bundled bunny about 60 stipples a head glint for both eyes where the
#: grooved defaults (a 60 mm model 40 mm deep, +-45 x +-15 deg) gave 1.4.
RIDGED_DEFAULTS = {"size": 50.0, "center_z": -20.0, "view_range": 20.0,
                   "elevation_range": 8.0}
#: Largest head elevation range of a ridged design, degrees.
MAX_ELEVATION_RANGE = 80.0
#: Smallest and largest raster spacing of a ridged plate, mm.
RASTER_RANGE = (0.002, 1.0)
#: Side of the blocks a ridged plate is shared out by, mm (a whole number of raster cells).
RIDGED_BLOCK = 0.2
#: What a ridged plate does with the light: a mirror lit from the front, or a clear
#: plate lit from behind (refraction).
OPTICS = ("reflect", "refract")
#: Models of a refraction plate's front optic (``toolpaths.ridged.REFRACTION_MODELS``).
REFRACTION_MODELS = ("exact", "approx", "single")
#: The light of a refraction plate when no elevation is given: straight behind, degrees.
BACK_LIGHT_ELEVATION = -90.0


#: Largest magnitude of any length, angle, feed or speed setting: far beyond any
#: plate, light or machine, and small enough that squares and products stay finite.
MAX_SETTING = 1e12



def _check_bounds(config: Any) -> None:
    """Refuse a setting outside its physical bounds (:data:`SETTING_BOUNDS`), naming it."""
    for name, (lo, hi, unit) in SETTING_BOUNDS.items():
        value = getattr(config, name)
        if value is not None and not lo <= value <= hi:
            raise SpecholoError(f"{name.replace('_', '-')} {value:g} {unit} is out of range: "
                                f"it must be in [{lo:g}, {hi:g}] {unit}")
    # A laser's trough is modelled by the circle its floor follows, of radius
    # spot^2 / (16 depth): a shallow trough of a wide spot is nearly flat.
    radius = config.setup().tool.radius
    most = SETTING_BOUNDS["tool_radius"][1]
    if radius > most:
        raise SpecholoError(f"a {config.depth_mm:g} mm deep groove of this {config.tool} is "
                            f"too flat to show a glint (its floor curves with a radius of "
                            f"{radius:.3g} mm, at most {most:g}): set a larger --depth")


def _check_setting(config: Any, name: str, kind: str) -> None:
    """Refuse a setting of the wrong type or size, naming it.

    A TOML string, list, table or date where a number is expected, a bool for a
    number, NaN, infinity or a number beyond :data:`MAX_SETTING`; a whole float
    where an int is expected becomes the int.
    """
    value = getattr(config, name)
    option = name.replace("_", "-")
    if value is None and "None" in kind:
        return
    if kind.startswith("bool"):
        if not isinstance(value, bool):
            raise SpecholoError(f"{option} must be true or false, got {value!r}")
    elif kind.startswith("str"):
        if not isinstance(value, str):
            raise SpecholoError(f"{option} must be a string, got {value!r}")
    elif kind.startswith(("int", "float")):
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise SpecholoError(f"{option} must be a number, got {value!r}")
        try:
            number = float(value)
        except OverflowError:  # an int beyond any float
            number = math.inf
        if not math.isfinite(number):
            raise SpecholoError(f"{option} must be a finite number, got {value!r}")
        if kind.startswith("int"):
            if not number.is_integer():
                raise SpecholoError(f"{option} must be a whole number, got {value!r}")
            whole = int(getattr(config, name))
            if whole < 0:
                raise SpecholoError(f"{option} must not be negative, got {value!r}")
            object.__setattr__(config, name, whole)
        elif abs(number) > MAX_SETTING:
            raise SpecholoError(f"{option} {value!r} is out of range (at most {MAX_SETTING:g})")


@dataclass(frozen=True)
class DesignConfig:
    """Every design option, in the units of the command line (mm, degrees).

    Attributes mirror the ``specholo design`` options of the same names.
    """

    size: float = 60.0
    center_z: float = -40.0
    up: str = "y"
    rotate_x: float = 0.0
    rotate_y: float = 0.0
    rotate_z: float = 0.0
    offset_x: float = 0.0
    offset_y: float = 0.0
    light_elevation: float = 45.0
    light_distance: float | None = None
    view_distance: float = 600.0
    view_range: float = 45.0
    eye_height: float = 0.0
    ipd: float = 64.0
    stipples: int | None = None
    spacing: float | None = None
    visibility: float | None = None
    seed: int = 0
    method: str = "striped"
    band: float | None = None
    band_share: float | None = None
    placement: str = "auto"
    thin: str = "auto"
    tool: str = "drag"
    tool_radius: float | None = None
    tool_angle: float | None = None
    tip_flat: float = 0.0
    spot: float | None = None
    depth: float | None = None
    strict: bool = False
    dialect: str | None = None
    units: str = "mm"
    order: bool = True
    plate_width: float | None = None
    plate_height: float | None = None
    fit: bool = False
    stock_thickness: float = STOCK_THICKNESS
    feed: float = 300.0
    plunge: float = 100.0
    safe_z: float = 1.0
    hop: float = 0.03
    hop_max: float = 3.0
    spindle: float | None = None
    holder: str | None = None
    preload: float | None = None
    machine: str | None = None
    elevation_range: float = 15.0
    shell: float = 0.1
    raster: float = 0.02
    optic: str = "reflect"
    refraction: str = "exact"
    index: float = ACRYLIC_INDEX

    def __post_init__(self) -> None:
        for f in fields(self):
            _check_setting(self, f.name, str(f.type))
        # The spindle defaults by tool (a frozen dataclass: filled in once here); the
        # depth is chosen by design() from the wall tilts the views need.
        _, spindle = TOOL_DEFAULTS.get(self.tool, (0.08, 0.0))
        if self.spindle is None:
            object.__setattr__(self, "spindle", spindle)
        if self.band is None:
            object.__setattr__(self, "band", HAND_BAND if self.tool == "scriber" else BAND)
        # Marlin's programs drive a laser (no Z, the beam switched around each
        # groove); GRBL's and LinuxCNC's plunge a cutter: a laser defaults to
        # Marlin, and a cutter's program is never written as a laser's.
        if self.dialect is None:
            object.__setattr__(self, "dialect", "marlin" if self.tool == "laser" else "grbl")
        if self.dialect not in ("grbl", "linuxcnc", "marlin"):
            raise SpecholoError(f"dialect must be grbl, linuxcnc or marlin, got {self.dialect!r}")
        if self.method != "ridged" and (self.dialect == "marlin") != (self.tool == "laser"):
            raise SpecholoError(
                f"--dialect marlin drives a laser: --tool {self.tool} needs --dialect grbl or "
                "linuxcnc"
                if self.dialect == "marlin" else
                f"a laser is driven by --dialect marlin ({self.dialect} programs plunge a cutter)")
        if self.up not in UP_AXES:
            raise SpecholoError(f"up must be one of {', '.join(UP_AXES)}, got {self.up!r}")
        if self.units not in ("mm", "inch"):
            raise SpecholoError(f"units must be mm or inch, got {self.units!r}")
        if self.placement not in PLACEMENTS:
            raise SpecholoError(f"placement must be one of {', '.join(PLACEMENTS)}, got "
                                f"{self.placement!r}")
        if self.thin not in THINNING:
            raise SpecholoError(f"thin must be one of {', '.join(THINNING)}, got {self.thin!r}")
        if self.method not in METHODS:
            raise SpecholoError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        if self.stipples is not None and self.spacing is not None:
            raise SpecholoError("give either stipples or spacing, not both")
        if self.stipples is not None and (isinstance(self.stipples, bool)
                                          or int(self.stipples) != self.stipples
                                          or self.stipples <= 0):
            raise SpecholoError(f"stipples must be a positive integer, got {self.stipples}")
        if self.visibility is not None and not 0.0 < self.visibility < 1.0:
            raise SpecholoError("visibility must be a share between 0 and 1 (e.g. 0.8), "
                                f"got {self.visibility}")
        if self.visibility is not None and self.spacing is not None:
            raise SpecholoError("give either visibility or spacing, not both")
        if self.visibility is not None and self.method == "ridged":
            raise SpecholoError("visibility needs a grooved design (striped, hyperbola or arc): "
                                "a ridged plate's facets do not cut into each other")
        if self.spacing is not None and not (math.isfinite(self.spacing) and self.spacing > 0):
            raise SpecholoError(f"spacing must be a positive number of mm, got {self.spacing}")
        for name in ("size", "center_z", "band"):
            if not math.isfinite(getattr(self, name)):
                raise SpecholoError(f"{name.replace('_', '-')} must be finite, got "
                                    f"{getattr(self, name)}")
        if not (self.band is not None and self.band > 0):
            raise SpecholoError(f"band must be positive, got {self.band}")
        if self.band_share is not None and not (math.isfinite(self.band_share)
                                                and 0.0 < self.band_share <= 1.0):
            raise SpecholoError(f"band share must be in (0, 1], got {self.band_share}")
        if not self.size > 0:
            raise SpecholoError(f"size must be a positive number of mm, got {self.size}")
        if self.fit and (self.plate_width is None or self.plate_height is None):
            raise SpecholoError("fit scales the model to a plate: give plate-width and "
                                "plate-height")
        for name in ("plate_width", "plate_height"):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v)
                                      and v > 0):
                raise SpecholoError(f"{name.replace('_', '-')} must be a positive number of mm, "
                                    f"got {v}")
        if not (isinstance(self.stock_thickness, (int, float))
                and math.isfinite(self.stock_thickness) and self.stock_thickness > 0):
            raise SpecholoError(f"stock-thickness must be a positive number of mm, got "
                                f"{self.stock_thickness}")
        if isinstance(self.depth, (int, float)) and self.depth >= self.stock_thickness:
            raise SpecholoError(f"groove depth {self.depth:g} mm must be less than the stock "
                                f"thickness {self.stock_thickness:g} mm")
        self._check_holder()
        self._check_ridged_ranges()
        self._check_optic()
        self.setup()  # validates the physical settings
        _check_bounds(self)
        self._check_machine()
        self._check_ridged_machine()

    def _check_holder(self) -> None:
        """Fill in and refuse the tip's holder (a frozen dataclass: once, here).

        A drag tip or scriber is held in a spring holder by default (the spring
        sets the force, the plate may be as flat as a hobby machine holds it), a
        ball or V-bit mill, or any tip the spindle turns, rigidly in its
        spindle; a laser has none. A spring holder's tip does not spin, and its
        preload is a spring compression within
        :data:`~specholo.setup.PRELOAD_RANGE`.
        """
        spring_tools = ("drag", "scriber")
        if self.tool == "laser":
            if self.holder is not None or self.preload is not None:
                raise SpecholoError("a laser has no holder: leave out --holder and --preload")
            return
        if self.holder is None:
            # a tip the spindle turns is held by the spindle, rigidly
            spun = (self.spindle or 0.0) > 0
            object.__setattr__(self, "holder",
                               "spring" if self.tool in spring_tools and not spun
                               and self.method != "ridged" else "rigid")
        if self.holder not in HOLDERS:
            raise SpecholoError(f"holder must be one of {', '.join(HOLDERS)}, got "
                                f"{self.holder!r}")
        if self.holder == "rigid":
            if self.preload is not None:
                raise SpecholoError("preload is a spring holder's compression: add --holder "
                                    "spring, or leave out --preload")
            return
        if self.tool not in spring_tools:
            raise SpecholoError(f"a spring holder drags a tip that does not spin: --tool "
                                f"{self.tool} is held rigid (--holder rigid)")
        if (self.spindle or 0.0) > 0:
            raise SpecholoError("a spring holder's tip does not spin: set --spindle 0")
        preload = DEFAULT_PRELOAD if self.preload is None else float(self.preload)
        object.__setattr__(self, "preload", preload)
        lo, hi = PRELOAD_RANGE
        if not lo <= preload <= hi:
            raise SpecholoError(f"preload {preload:g} mm is out of range: it must be in "
                                f"[{lo:g}, {hi:g}] mm of spring compression")

    def holder_setup(self) -> Holder | None:
        """The tip's :class:`~specholo.setup.Holder` (None for a laser)."""
        if self.holder is None:
            return None
        return Holder(str(self.holder), float(self.preload or DEFAULT_PRELOAD))

    def _check_ridged_ranges(self) -> None:
        """Refuse ridged settings out of range."""
        if not 0.0 <= self.elevation_range < MAX_ELEVATION_RANGE:
            raise SpecholoError(f"elevation-range must be in [0, {MAX_ELEVATION_RANGE:g}) "
                                f"degrees, got {self.elevation_range:g}")
        if not self.shell > 0:
            raise SpecholoError(f"shell must be a positive number of mm, got {self.shell:g}")
        if 2.0 * self.shell >= self.stock_thickness:
            raise SpecholoError(f"a shell of {self.shell:g} mm cuts {2 * self.shell:g} mm deep, "
                                f"not less than the stock thickness {self.stock_thickness:g} mm")
        if not RASTER_RANGE[0] <= self.raster <= RASTER_RANGE[1]:
            raise SpecholoError(f"raster must be in [{RASTER_RANGE[0]:g}, {RASTER_RANGE[1]:g}] "
                                f"mm, got {self.raster:g}")

    def _check_optic(self) -> None:
        """Refuse a refraction plate that is not ridged, or refraction settings on a mirror."""
        if self.optic not in OPTICS:
            raise SpecholoError(f"optic must be reflect or refract, got {self.optic!r}")
        if self.refraction not in REFRACTION_MODELS:
            raise SpecholoError(f"refraction must be one of {', '.join(REFRACTION_MODELS)}, "
                                f"got {self.refraction!r}")
        if self.optic == "refract":
            if self.method != "ridged":
                raise SpecholoError(f"a refraction plate is a ridged design: use --method ridged "
                                    f"(got {self.method})")
            if not self.light_elevation < 0.0:
                raise SpecholoError(f"a refraction plate is lit from behind: light-elevation must "
                                    f"be in (-180, 0) degrees (-90 straight behind), got "
                                    f"{self.light_elevation:g}")
            if not 1.0 < self.index <= MAX_INDEX:
                raise SpecholoError(f"index {self.index:g} is out of range: a clear plate's "
                                    f"refractive index must be above 1 and at most {MAX_INDEX:g}")
        elif self.index != ACRYLIC_INDEX or self.refraction != "exact":
            raise SpecholoError("index and refraction are settings of a clear plate lit from "
                                "behind: add --optic refract")

    def _check_ridged_machine(self) -> None:
        """Refuse a machine or tool that cannot mill a ridged plate."""
        if self.method != "ridged":
            return
        if self.tool != "ball":
            raise SpecholoError(f"a ridged plate is milled with a ball-end mill: use --tool ball "
                                f"(got {self.tool})")
        if self.depth is not None:
            raise SpecholoError("depth is a groove's; a ridged plate is cut 2 x shell deep "
                                "(set --shell)")
        if self.dialect == "marlin":
            raise SpecholoError("a ridged plate is milled: use --dialect grbl or linuxcnc "
                                "(marlin drives a laser)")
        if self.units != "mm":
            raise SpecholoError("a ridged plate's G-code is written in mm: use --units mm")
        if not (self.spindle or 0.0) > 0:
            raise SpecholoError("a ridged plate is milled: --spindle must be positive")
        if self.ball_radius < self.raster:
            raise SpecholoError(f"tool-radius {self.ball_radius:g} mm is finer than the raster "
                                f"{self.raster:g} mm: the ball must span a raster cell")
        if (self.plate_width is None) != (self.plate_height is None):
            raise SpecholoError("a ridged plate needs both plate-width and plate-height, "
                                "or neither")

    @property
    def profile(self) -> MachineProfile | None:
        """The machine the design is timed on (``--machine``), or None for the
        estimate's own model."""
        return None if self.machine is None else machine_profile(self.machine)

    def _check_machine(self) -> None:
        """Refuse an unknown machine, a tool it does not carry, and feeds above
        its rates (the feeds default to its own in :meth:`from_dict`)."""
        profile = self.profile
        if profile is None:
            return
        if self.method == "ridged":
            raise SpecholoError("--machine times a grooved design: a ridged plate's raster "
                                "is timed at its feed (leave out --machine)")
        if self.tool not in profile.tools:
            fits = [m.name for m in MACHINES.values() if self.tool in m.tools]
            raise SpecholoError(f"the {profile.name} ({profile.title}) carries "
                                f"--tool {' or '.join(profile.tools)}, not {self.tool}: "
                                f"--tool {self.tool} runs on {', '.join(fits)}")
        limits = [("feed", self.feed, profile.xy_rate, "X/Y")]
        if profile.z_rate is not None:
            limits.append(("plunge", self.plunge, profile.z_rate, "Z"))
        for name, value, most, axes in limits:
            if value > most:
                raise SpecholoError(f"{name} {value:g} mm/min is above the {profile.name}'s "
                                    f"{axes} maximum rate {most:g} mm/min")

    @property
    def ball_radius(self) -> float:
        """Ball radius of a ridged plate's finishing raster, mm."""
        return float(self.tool_radius) if self.tool_radius is not None else RIDGED_BALL_RADIUS

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> DesignConfig:
        """Build from a mapping with option names (dashes or underscores)."""
        if not isinstance(values, dict):
            raise SpecholoError(f"settings must be a table of options, got {values!r:.60}")
        known = {f.name for f in fields(cls)}
        clean: dict[str, Any] = {}
        for key, value in values.items():
            name = str(key).replace("-", "_")
            if name not in known:
                raise SpecholoError(f"unknown setting {key!r}")
            clean[name] = value
        if clean.get("method") == "ridged":
            clean.setdefault("tool", "ball")  # a ridged plate is milled
            # Each plate cell serves one stipple in one direction, so a head sees
            # about (plate area) / (a stipple's patch, ~ solid angle x depth^2)
            # stipples: a full-parallax plate needs a narrower zone and a model
            # nearer the plate than a grooved one to show an image.
            for key, value in RIDGED_DEFAULTS.items():
                clean.setdefault(key, value)
        chosen = clean.get("machine")
        if isinstance(chosen, str) and chosen in MACHINES:
            # The machine's own feeds (and a laser's tool and a mill's dialect)
            # where none is given; given ones are checked against its rates.
            profile = MACHINES[chosen]
            clean.setdefault("feed", profile.feed)
            if profile.plunge is not None:
                clean.setdefault("plunge", profile.plunge)
            if profile.laser:
                clean.setdefault("tool", "laser")
            if profile.kind == "mill":
                clean.setdefault("dialect", "linuxcnc")
            if profile.lifts and "band" not in clean and \
                    clean.get("method", "striped") == "striped" and \
                    clean.get("tool", "drag") != "scriber":
                # its strokes cost a lift each: the band is chosen from the
                # stipples' spacing (MACHINE_BAND_SHARE), unless one is given
                clean.setdefault("band_share", MACHINE_BAND_SHARE)
        if clean.get("optic") == "refract":
            clean.setdefault("light_elevation", BACK_LIGHT_ELEVATION)  # behind the plate
        try:
            return cls(**clean)
        except TypeError as exc:
            raise SpecholoError(f"bad setting: {exc}") from exc

    @property
    def depth_mm(self) -> float:
        """Groove depth, mm: as given, else the tool's fallback default.

        A ridged plate has no grooves: its ball reaches the shell's depth, stated
        here within the ball's radius so the tool model stays a valid groove."""
        if self.depth is not None:
            return float(self.depth)
        if self.method == "ridged":
            return min(2.0 * float(self.shell), self.ball_radius)
        return TOOL_DEFAULTS.get(self.tool, (0.08, 0.0))[0]

    def cutter(self) -> Cutter:
        """The cutting tool, built once per settings (they are frozen, and so is it)."""
        built = self.__dict__.get("_cutter")
        if built is None:
            try:
                built = make_cutter(self.tool, self.tool_radius, self.tool_angle,
                                    float(self.tip_flat), self.spot)
            except (TypeError, ValueError) as exc:
                if isinstance(exc, SpecholoError):
                    raise
                raise SpecholoError(f"bad setting: {exc}") from exc
            # a frozen dataclass refuses setattr; its __dict__ holds the one copy
            self.__dict__["_cutter"] = built
        return built

    def pose(self) -> Pose:
        """How the model is turned and moved onto the plate (not the stripes'
        ``placement``)."""

        return Pose(self.up, (self.rotate_x, self.rotate_y, self.rotate_z),
                         (self.offset_x, self.offset_y))

    def setup(self) -> Setup:
        """The physical setup in library units (radians), built once per settings:
        every layer a design passes through asks for it, and gets the same one."""
        built = self.__dict__.get("_setup")
        if built is None:
            built = self._build_setup()
            self.__dict__["_setup"] = built
        return built

    def _build_setup(self) -> Setup:
        try:
            distance = None if self.light_distance is None else float(self.light_distance)
            elevation = math.radians(float(self.light_elevation))
            return Setup(
                light=(BackLight(elevation, distance, float(self.stock_thickness),
                                 float(self.index)) if self.optic == "refract"
                       else Light(elevation, distance)),
                viewer=Viewer(float(self.view_distance), float(self.eye_height),
                              math.radians(float(self.view_range)), float(self.ipd)),
                tool=self.cutter().model(self.depth_mm),
                machining=Machining(float(self.feed), float(self.plunge), float(self.safe_z),
                                    float(self.spindle or 0.0), float(self.hop),
                                    float(self.hop_max)),
            )
        except (TypeError, ValueError) as exc:
            if isinstance(exc, SpecholoError):
                raise
            raise SpecholoError(f"bad setting: {exc}") from exc



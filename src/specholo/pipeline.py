"""The whole job: model in, engraving files and a simulated preview out.

The library entry points behind the CLI. Settings arrive in the units users
speak (degrees, mm) and are converted once, here, to the library's radians.
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
import os
import time
from collections.abc import Iterable, Iterator
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from specholo import __version__
from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open
from specholo.fabrication.plate import PLATE_MARGIN, Plate, fit_plate
from specholo.fabrication.tools import (
    Cutter,
    ViewCheck,
    check_views,
    depth_for,
    make_cutter,
    needed_tilts,
)
from specholo.scene.pose import UP_AXES, Pose
from specholo.setup import (
    ACRYLIC_INDEX,
    MAX_FEED,
    MAX_HOP,
    MAX_HOP_DISTANCE,
    MAX_INDEX,
    MIN_HOP,
    MIN_SAFE_Z,
    BackLight,
    Light,
    Machining,
    Setup,
    Viewer,
)
from specholo.toolpaths.common import Runs, make_runs
from specholo.toolpaths.grooves import MAX_COORDINATE, Grooves
from specholo.toolpaths.overlap import Overlaps, groove_overlaps
from specholo.toolpaths.striped import PLACEMENTS

if TYPE_CHECKING:
    from specholo.simulation.survival import AsCut

METHODS = ("striped", "hyperbola", "arc", "ridged")
DEFAULT_STIPPLES = 2000
#: Fallback groove depth (mm) and spindle speed (rpm) by tool. A design without a
#: depth cuts just deep enough for the wall tilts its views need (see
#: :data:`TILT_MARGIN`); drag tips, scribers and lasers do not spin.
#: Extra wall tilt (radians) over the steepest a design needs, when choosing its depth.
TILT_MARGIN = math.radians(2.0)
#: Half-height of a striped design's band, mm: 0.2 for machines; 1 for the hand
#: scriber, whose strokes a person traces one by one (on the example's 150
#: stipples, 17 strokes a stipple of 2.6 mm and a p95 error under 0.9 mm,
#: against 70 strokes of 0.5 mm at 0.2; docs/fabrication.md).
BAND = 0.2
HAND_BAND = 1.0
TOOL_DEFAULTS = {"ball": (0.08, 12000.0), "drag": (0.012, 0.0), "scriber": (0.012, 0.0),
                 "vbit": (0.05, 12000.0), "laser": (0.04, 0.0)}


#: Ball radius (mm) of a ridged plate's finishing raster when none is given: it
#: must follow facets a few tenths of a millimetre wide.
RIDGED_BALL_RADIUS = 0.05
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
    placement: str = "auto"
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
    stock_thickness: float = 3.0
    feed: float = 300.0
    plunge: float = 100.0
    safe_z: float = 1.0
    hop: float = 0.03
    hop_max: float = 3.0
    spindle: float | None = None
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
        self._check_ridged_ranges()
        self._check_optic()
        self.setup()  # validates the physical settings
        _check_bounds(self)
        self._check_ridged_machine()

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
        """The cutting tool."""
        try:
            return make_cutter(self.tool, self.tool_radius, self.tool_angle,
                               float(self.tip_flat), self.spot)
        except (TypeError, ValueError) as exc:
            if isinstance(exc, SpecholoError):
                raise
            raise SpecholoError(f"bad setting: {exc}") from exc

    def pose(self) -> Pose:
        """How the model is turned and moved onto the plate (not the stripes'
        ``placement``)."""

        return Pose(self.up, (self.rotate_x, self.rotate_y, self.rotate_z),
                         (self.offset_x, self.offset_y))

    def setup(self) -> Setup:
        """The physical setup in library units (radians)."""
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


@dataclass
class Design:
    """A designed hologram: the placed model, its stipples, and the grooves."""

    config: DesignConfig
    model: Any  # scene.loading.Model
    points: np.ndarray  # (n, 3)
    normals: np.ndarray | None  # (n, 3)
    runs: Runs
    grooves: Grooves
    dropped: np.ndarray  # stipple ids that could not be designed
    timings: dict[str, float]
    views: ViewCheck | None = None  # the tool's walls against the tilts needed
    overlaps: Overlaps | None = None  # where grooves cut into each other
    plate: np.ndarray | None = None  # (2, 2) plate corners, mm
    coverage: Coverage | None = None  # which stipples got a groove
    as_cut: AsCut | None = None  # what survives the cutting, per azimuth
    placement: dict[str, str] | None = None  # striped: "placement" used, "fallback" why


@dataclass(frozen=True)
class Coverage:
    """How many stipples got a groove, and why the others did not.

    Attributes:
        stipples: stipples of the design.
        hidden: stipples no eye in the viewing range sees (the model hides them
            or they face away from every eye): they get no groove.
        dropped: stipples seen but whose groove the method could not design.
        grooved: stipples with at least one path.
    """

    stipples: int
    hidden: int
    dropped: int
    grooved: int

    @property
    def ungrooved(self) -> int:
        """Stipples without a groove."""
        return self.stipples - self.grooved

    @property
    def mostly_ungrooved(self) -> bool:
        """Whether most stipples have no groove: the plate shows little of the model."""
        return 2 * self.ungrooved > self.stipples

    def reasons(self, dropped_why: str = "") -> str:
        """Why the stipples without a groove have none, e.g. "120 are hidden from
        every view (...), 30 could not be designed" (``dropped_why`` follows the latter)."""
        parts = []
        if self.hidden:
            parts.append(f"{self.hidden} {'is' if self.hidden == 1 else 'are'} hidden from "
                         f"every view ({_HIDDEN_WHY})")
        if self.dropped:
            parts.append(f"{self.dropped} could not be designed{dropped_why}")
        rest = self.ungrooved - self.hidden - self.dropped
        if rest > 0:
            parts.append(f"{rest} got no path")
        return ", ".join(parts)

    def describe(self) -> str:
        """One line: how many stipples have no groove, and why."""
        if self.ungrooved == self.hidden:
            return (f"{self.hidden} of {self.stipples} stipples are hidden from every view "
                    f"and have no groove ({_HIDDEN_WHY})")
        return f"{self.ungrooved} of {self.stipples} stipples have no groove: {self.reasons()}"


#: Why a stipple is hidden from every view.
_HIDDEN_WHY = "the model hides them or they face away from every eye"


def coverage(n: int, runs: Runs, grooves: Grooves, dropped: np.ndarray) -> Coverage:
    """Count the stipples with a groove, those hidden from every view and those dropped.

    One pass over the runs and the paths (no sort): cheap beside the design.
    """
    seen = np.zeros(n, dtype=bool)
    seen[runs.stipple] = True
    has = np.zeros(n, dtype=bool)
    ids = np.asarray(grooves.stipple)
    has[ids[(ids >= 0) & (ids < n)]] = True
    return Coverage(n, n - int(np.count_nonzero(seen)), int(len(dropped)),
                    int(np.count_nonzero(has)))


def groove_extent(grooves: Grooves) -> np.ndarray:
    """(2, 2) corners of the grooves' centrelines, arcs included where they bulge
    past their end points (the tool follows the arc, not its chord)."""
    return grooves.extent()


def plate_rect(grooves: Grooves, width: float, config: DesignConfig,
               extent: np.ndarray | None = None) -> np.ndarray:
    """The plate's corners (2, 2), centred on the plate origin; refuse one too small.

    Args:
        grooves: the design's grooves.
        width: groove width, mm (grooves reach half of it past their centrelines).
        config: plate_width / plate_height, or None to fit the grooves with a margin.
        extent: the grooves' :func:`groove_extent`, if already known.
    """
    lo, hi = groove_extent(grooves) if extent is None else extent
    reach = np.maximum(np.abs(lo), np.abs(hi)) + 0.5 * width
    need = 2.0 * reach
    size = np.array([config.plate_width or 0.0, config.plate_height or 0.0])
    given = size > 0
    for axis, name in ((0, "width"), (1, "height")):
        if given[axis] and size[axis] < need[axis]:
            raise SpecholoError(
                f"plate {name} {size[axis]:g} mm is smaller than the design, which needs "
                f"{need[axis]:.1f} mm (grooves reach +-{reach[axis]:.1f} mm from the centre)")
    fitted = fit_plate(np.stack([lo, hi]), width, PLATE_MARGIN)
    size = np.where(given, size, fitted[1] - fitted[0])
    return np.stack([-0.5 * size, 0.5 * size])


def check_points(points: np.ndarray, setup: Setup) -> None:
    """Refuse points the viewer could not look at through the plate."""
    v = setup.viewer
    nearest_eye = v.distance * math.cos(v.design_range)
    if len(points) and points[:, 2].max() >= 0.9 * nearest_eye:
        raise SpecholoError(
            f"model reaches z = {points[:, 2].max():.1f} mm, too close to the eyes "
            f"(nearest eye depth {nearest_eye:.1f} mm); move it back with --center-z")


def auto_depth(cutter: Cutter, config: DesignConfig, points: np.ndarray, runs: Runs,
               tilts: np.ndarray | None = None) -> float:
    """Shallowest depth, to the micrometre above, whose walls serve every view, plus
    :data:`TILT_MARGIN`; the tool's fallback depth when no depth can (a V-bit).
    ``tilts`` are the runs' :func:`needed_tilts`, if already known."""
    if tilts is None:
        setup = config.setup()
        tilts, _ = needed_tilts(points, runs.stipple, runs.start, runs.end, setup.light,
                                setup.viewer)
    need = float(tilts.max()) + TILT_MARGIN if tilts.size else TILT_MARGIN
    depth = depth_for(cutter, min(need, 0.5 * math.pi - 1e-6))
    if depth is None:
        return config.depth_mm
    depth = math.ceil(depth * 1000.0) / 1000.0
    # A ball or round tip shallower than its reach: beyond it the walls stop at the shank.
    try:
        cutter.check_depth(depth)
    except SpecholoError:
        return config.depth_mm
    return depth


def design_runs(runs: Runs, config: DesignConfig,
                info: dict[str, str] | None = None) -> tuple[Grooves, np.ndarray]:
    """Grooves for the given view intervals with the configured method.

    ``info``, if given, gets the striped design's placement used and why "auto"
    fell back (see :func:`~specholo.toolpaths.striped.design_striped`).
    """
    from specholo.toolpaths.classic import design_classic
    from specholo.toolpaths.hyperbola import design_hyperbola
    from specholo.toolpaths.striped import StripeOptions, design_striped

    setup = config.setup()
    if config.method == "striped":
        return design_striped(runs, setup, StripeOptions(band=float(config.band or BAND),
                                                         placement=config.placement), info=info)
    if config.method == "hyperbola":
        from specholo.toolpaths.hyperbola import serves

        ok = serves(runs, setup)
        dropped = np.setdiff1d(runs.stipple[~ok], runs.stipple[ok])
        return design_hyperbola(runs.take(ok), setup), dropped.astype(np.int64)
    return design_classic(runs, setup), np.zeros(0, dtype=np.int64)


def stipple_model(model_path: str | os.PathLike[str], config: DesignConfig,
                  rng: np.random.Generator | None, timings: dict[str, float]
                  ) -> tuple[Any, Any, DesignConfig]:
    """Load and place the model and stipple it; refuse what would not fit in memory or
    could not be seen through the plate.

    Returns:
        The placed model, its stipples (``timings["stippling"]`` is set) and the
        config, whose size is the fitted one with ``config.fit``.
    """
    from specholo.scene.loading import load_model
    from specholo.scene.placement import place
    from specholo.scene.stippling import check_memory, stipple

    setup = config.setup()
    rng = rng if rng is not None else np.random.default_rng(config.seed)
    count = None if config.spacing is not None else (config.stipples or DEFAULT_STIPPLES)
    if count is not None:
        check_memory(count)  # stipples = 10**9 is refused before any work
    t0 = time.perf_counter()
    pose = config.pose()
    loaded = load_model(model_path)
    if config.fit:
        config = dataclasses.replace(config, size=fitted_size(loaded, config))
    model = place(loaded, config.size, config.center_z, pose.rotation(), pose.offset)
    st = stipple(model, rng, count=count, spacing=config.spacing)
    check_points(st.points, setup)
    mesh = model.mesh
    check_memory(len(st.points), 0 if mesh is None else len(mesh.faces),
                 0 if mesh is None else len(mesh.vertices),
                 request=None if count is not None else
                 f"spacing = {config.spacing:g} mm ({len(st.points)} stipples)")
    timings["stippling"] = time.perf_counter() - t0
    return model, st, config


def fitted_size(model: Any, config: DesignConfig) -> float:
    """The largest size (mm) at which the model's grooves, as posed, lie on the
    plate ``config`` gives, within its blank border (:mod:`specholo.scene.fit`)."""
    from specholo.scene.fit import fit_size
    from specholo.scene.placement import place

    pose = config.pose()
    unit = place(model, 1.0, 0.0, pose.rotation())  # size 1 about its box centre
    half_width = 0.5 * config.cutter().section(config.depth_mm).width
    reach = (half_width, half_width + (config.band or 0.0))
    size = fit_size(unit.points, np.array([*pose.offset, config.center_z]),
                    (float(config.plate_width or 0.0), float(config.plate_height or 0.0)),
                    config.setup().viewer, reach, PLATE_MARGIN)
    # Recorded with the design, so rounded (down: the rounded size still fits).
    return math.floor(min(size, 10_000.0) * 1e3) / 1e3


def design(model_path: str | os.PathLike[str], config: DesignConfig,
           rng: np.random.Generator | None = None, check_overlaps: bool = True,
           expect_as_cut: bool | None = None) -> Design:
    """Load, place, stipple, crop by occlusion, check the tool, design the grooves.

    Args:
        model_path: mesh or point-cloud file.
        config: the options.
        rng: random generator for stippling; default seeded from ``config.seed``.
        check_overlaps: measure where grooves cut into each other.
        expect_as_cut: find which glints survive the other grooves' cuts
            (:func:`expected_as_cut`); None for designs of at most
            :data:`AS_CUT_MAX_STIPPLES` stipples.

    Raises:
        SpecholoError: on bad input, a plate smaller than the design, or (with
            ``config.strict``) a tool whose walls lose views.
    """
    from specholo.visibility.occlusion import visible_intervals

    if config.method == "ridged":
        raise SpecholoError("a ridged design is made by design_ridged_model, not design")
    setup = config.setup()
    timings: dict[str, float] = {}
    model, st, config = stipple_model(model_path, config, rng, timings)
    points = st.points
    t0 = time.perf_counter()
    iv = visible_intervals(model.mesh, points, st.normals, setup.viewer)
    runs = make_runs(points, iv.stipple, iv.start, iv.end)
    timings["occlusion"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    cutter = config.cutter()
    # The tilts depend on the views and the light, not on the depth: found once.
    needed = needed_tilts(points, runs.stipple, runs.start, runs.end, setup.light,
                          setup.viewer)
    if config.depth is None:
        config = dataclasses.replace(
            config, depth=auto_depth(cutter, config, points, runs, tilts=needed[0]))
        setup = config.setup()
    views = check_views(cutter, config.depth_mm, points, runs.stipple, runs.start, runs.end,
                        setup.light, setup.viewer, known=needed)
    del needed  # ~10^8 samples at a million stipples: not kept through the walk
    if config.strict and views.lost > 0:
        raise SpecholoError(
            f"the {cutter.describe()} at {config.depth_mm:g} mm loses {100 * views.lost:.1f}% "
            f"of the views ({views.stipples_losing} stipples); {views.suggestion}")
    timings["tool check"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    placed: dict[str, str] = {}
    grooves, dropped = design_runs(runs, config, placed)
    timings["toolpaths"] = time.perf_counter() - t0
    cover = coverage(len(points), runs, grooves, dropped)
    if cover.grooved == 0:
        # A plate with nothing to cut: refused before any file is written.
        from collections import Counter

        why = Counter(r.split(":")[0] for r in drop_reasons(points, dropped, setup).values())
        reasons = "" if not why else " (" + ", ".join(
            f"{n}: {r}" for r, n in sorted(why.items())) + ")"
        raise SpecholoError(f"no stipple gets a groove: {cover.reasons(reasons)}")
    section = cutter.section(config.depth_mm)
    # One pass over the arcs (or none, when the walk found them), for the plate and
    # the overlaps (which need the length).
    if check_overlaps:
        extent, total = grooves.extent_and_length()
    else:
        extent, total = grooves.extent(), 0.0
    plate = plate_rect(grooves, section.width, config, extent)
    t0 = time.perf_counter()
    overlaps = groove_overlaps(grooves, section.width, extent=extent,
                               total_length=total) if check_overlaps else None
    timings["overlaps"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if expect_as_cut is None:
        expect_as_cut = len(points) <= AS_CUT_MAX_STIPPLES
    as_cut = expected_as_cut(config, points, runs, grooves) if expect_as_cut else None
    timings["as cut"] = time.perf_counter() - t0
    return Design(config, model, points, st.normals, runs, grooves, dropped, timings,
                  views, overlaps, plate, cover, as_cut, placement=placed or None)


#: Head azimuths of the design's as-cut estimate are at most this far apart, degrees.
AS_CUT_STEP_DEG = 5.0
#: Most stipples whose as-cut figures a design finds by itself. Finding every
#: eye's glints costs about a verification (~30 s at 10^5 stipples, against a
#: ~5 s walk), so larger designs leave it to ``specholo verify --cut``.
AS_CUT_MAX_STIPPLES = 20_000
#: What a design without its own as-cut figures says instead.
AS_CUT_SKIPPED = (f"as cut: not estimated by designs of over {AS_CUT_MAX_STIPPLES:,} "
                  "stipples; `specholo verify FOLDER --cut` measures it")


def expected_as_cut(config: DesignConfig, points: np.ndarray, runs: Runs,
                    grooves: Grooves) -> AsCut:
    """The stereo figures of the plate as cut, every :data:`AS_CUT_STEP_DEG` over the range.

    Each eye's designed glints are kept where no other groove's cut removes
    them (:func:`~specholo.simulation.survival.verify_as_cut`). A stipple is
    unoccluded for an eye when the eye's azimuth lies in one of the stipple's
    view intervals (``runs``, what the grooves were designed to serve) rather
    than by casting rays again: the same edges to ~0.01 degrees, at no cost.
    """
    from specholo.simulation.survival import verify_as_cut
    from specholo.simulation.verify import view_azimuths
    from specholo.visibility.occlusion import Intervals

    setup = config.setup()
    seen_from = Intervals(runs.stipple, runs.start, runs.end)

    def vis(p: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        # verify asks for all the stipples, in order, from one eye
        return seen_from.contains(np.arange(len(p)), np.arctan2(eyes[:, 0], eyes[:, 2]))

    az = view_azimuths(setup.viewer.half_range, math.radians(AS_CUT_STEP_DEG))
    return verify_as_cut(grooves, points, setup, config.cutter(), config.depth_mm, vis, az)


def as_cut_json(as_cut: AsCut) -> dict[str, Any]:
    """``hologram.json``'s ``expected``: the as-cut stereo visibility per azimuth."""
    figures = as_cut.mean_and_lowest()
    mean, low, at = figures if figures is not None else (None, None, None)
    return {"as_cut_stereo_visibility": {
        "mean": mean, "lowest": low, "lowest_azimuth_deg": at,
        "per_azimuth": [
            {"azimuth_deg": r.azimuth,
             "visibility": None if math.isnan(r.visibility) else r.visibility,
             "stipples_seen": r.stipples_seen,
             "glints": [int(v) for v in g], "surviving": [int(v) for v in s]}
            for r, g, s in zip(as_cut.reports, as_cut.glints, as_cut.surviving, strict=True)],
        "how": ("share of the stipples unoccluded for both eyes whose left and right designed "
                "glints both survive every other groove's cut (exact for a round tip cut "
                "within its radius); glints and surviving count each eye's glints, left and "
                "right"),
    }}


class StippleRows:
    """The stipples of ``hologram.json`` (id, position, visible azimuths in degrees),
    made a block at a time as they are written: as one list, a million
    stipples' dictionaries would hold ~1 GB for the whole of the writing."""

    def __init__(self, points: np.ndarray, runs: Runs) -> None:
        self.points = points
        self.runs = runs

    def __len__(self) -> int:
        return len(self.points)

    def blocks(self, size: int = 1 << 16) -> Iterator[list[dict[str, Any]]]:
        """Lists of up to ``size`` stipples' rows, in id order."""
        by_id = np.argsort(self.runs.stipple, kind="stable")  # each stipple's runs in order
        ids = self.runs.stipple[by_id]
        for a in range(0, len(self.points), size):
            b = min(a + size, len(self.points))
            lo, hi = np.searchsorted(ids, [a, b])
            iv: list[list[list[float]]] = [[] for _ in range(b - a)]
            for s, x, y in zip(ids[lo:hi].tolist(),
                               np.degrees(self.runs.start[by_id[lo:hi]]).tolist(),
                               np.degrees(self.runs.end[by_id[lo:hi]]).tolist(), strict=True):
                iv[s - a].append([round(x, 4), round(y, 4)])
            yield [{"id": i, "x": float(p[0]), "y": float(p[1]), "z": float(p[2]),
                    "visible_deg": iv[i - a]}
                   for i, p in enumerate(self.points[a:b].tolist(), start=a)]


def hologram_json(d: Design) -> dict[str, Any]:
    """The design's settings, figures and stipples, for ``hologram.json``."""
    setup = d.config.setup()
    lo, hi = d.grooves.bounds()
    cover = d.coverage or coverage(len(d.points), d.runs, d.grooves, d.dropped)
    return {
        "specholo_version": __version__,
        "settings": asdict(d.config),
        "frame": "plate mm: x right, y up, z toward the viewer, plate at z = 0",
        "tool": {"kind": d.config.tool, "description": d.config.cutter().describe(),
                 "depth_mm": d.config.depth_mm,
                 "groove_width_mm": d.config.cutter().section(d.config.depth_mm).width,
                 "round_model": {"radius_mm": setup.tool.radius, "depth_mm": setup.tool.depth,
                                 "max_wall_tilt_deg": math.degrees(setup.tool.max_tilt)}},
        "views": d.views.as_dict() if d.views is not None else None,
        "overlaps": d.overlaps.as_dict() if d.overlaps is not None else None,
        "expected": (as_cut_json(d.as_cut) if d.as_cut is not None else
                     {"as_cut_stereo_visibility": None, "why": AS_CUT_SKIPPED}),
        "plate": {"groove_extent_mm": [lo.tolist(), hi.tolist()],
                  "plate_mm": d.plate.tolist() if d.plate is not None else None,
                  "stock_thickness_mm": d.config.stock_thickness},
        "stats": {"stipples": len(d.points), "paths": d.grooves.n_paths,
                  "dots": int(d.grooves.is_dot.sum()),
                  "groove_length_mm": d.grooves.total_length(),
                  "dropped_stipples": d.dropped.tolist(),
                  "dropped_reasons": drop_reasons(d.points, d.dropped, setup),
                  "hidden_stipples": cover.hidden,
                  "stipples_with_grooves": cover.grooved,
                  # what "auto" chose, and why it fell back (settings keep "auto")
                  **({"placement": d.placement["placement"],
                      "placement_fallback": d.placement.get("fallback")}
                     if d.placement else {})},
        "stipples": StippleRows(d.points, d.runs),
    }


def run_record(config: DesignConfig, command: list[str] | None,
               seconds: dict[str, Any]) -> dict[str, Any]:
    """What a flat or ridged design's ``run.json`` records
    (:func:`specholo.staging.run_record`), with its settings."""
    from specholo.staging import run_record as record

    return record("ridged" if config.method == "ridged" else "flat", command, seconds,
                  asdict(config))


def drop_reasons(points: np.ndarray, dropped: np.ndarray, setup: Setup) -> dict[str, str]:
    """Why each dropped stipple could not be designed, by id (as a JSON key)."""
    from specholo.toolpaths.striped import at_light

    near = at_light(np.asarray(points, dtype=float).reshape(-1, 3)[dropped], setup)
    return {str(int(i)): ("at the light: its glint would be the light itself" if n else
                          "light in the eyes' plane: its groove would run vertically")
            for i, n in zip(dropped.tolist(), near.tolist(), strict=True)}


#: Files ``write_design`` can add besides the design data, by format name.
FORMATS = {"gcode": "hologram.gcode", "svg": "hologram.svg", "dxf": "hologram.dxf",
           "pdf": "pattern.pdf"}
DEFAULT_FORMATS = ("gcode", "svg")
#: Designs ``pattern.pdf`` is drawn for: an `arc` design's compass pattern, the
#: others' stroke pattern.
PATTERN_METHODS = ("striped", "hyperbola", "arc")


def design_limits(d: Design) -> Any:
    """What a design's G-code may do (``fabrication.check.Limits``), from its
    settings: cut inside the plate (less half a groove, as the tool centre is
    checked), every cut in X/Y at the groove's depth, rapids only at the safe
    height, feed moves between the surface and the safe height (hops) no longer
    than the longest hop nor lower than the hop height, feeds, spindle and
    laser power as set. In mm whatever the program's units: the check reads a
    G20 program in mm."""
    from specholo.fabrication.check import Limits, Stock, tool_kind
    from specholo.fabrication.gcode import GcodeOptions

    m = d.config.setup().machining
    width = d.config.cutter().section(d.config.depth_mm).width
    plate = d.plate if d.plate is not None else plate_rect(d.grooves, width, d.config)
    half = 0.5 * width
    stock = Stock(plate[0, 0] + half, plate[0, 1] + half, plate[1, 0] - half,
                  plate[1, 1] - half, d.config.stock_thickness)
    kind = tool_kind(d.config.tool, m.spindle)
    power = GcodeOptions(dialect="marlin").laser_power if kind == "laser" else m.spindle
    # a laser has no Z: no hops, and its depth is set by power and feed
    milled = kind != "laser"
    return Limits(stock, d.config.depth_mm, m.safe_z, (min(m.feed, m.plunge),
                  max(m.feed, m.plunge)), (power, power), kind,
                  hop_max=m.hop_max if milled else None, hop=m.hop,
                  groove_depth=d.config.depth_mm if milled else None)


def check_written_gcode(path: str | os.PathLike[str], d: Design) -> Any:
    """The independent safety check of a design's G-code (:func:`design_limits`).

    Raises:
        SpecholoError: on any violation, in one line.
    """
    from specholo.fabrication.check import check_program

    return check_program(path, design_limits(d))


def check_formats(formats: tuple[str, ...], method: str) -> None:
    """Refuse unknown formats, and a hand pattern of a design that has no grooves."""
    if method == "ridged":
        from specholo.fabrication.heightmap import RIDGED_FILES

        for f in formats:
            if f not in RIDGED_FILES:
                raise SpecholoError(f"a ridged design's formats are among "
                                    f"{', '.join(RIDGED_FILES)}, got {f!r}")
        return
    for f in formats:
        if f not in FORMATS:
            raise SpecholoError(f"format must be among {', '.join(FORMATS)}, got {f!r}")
    if "pdf" in formats and method not in PATTERN_METHODS:
        raise SpecholoError(f"the pdf pattern is for scribing by hand a design of "
                            f"{', '.join(PATTERN_METHODS)} (got {method!r})")


@dataclass(frozen=True)
class Written:
    """What :func:`write_design` did.

    Attributes:
        timings: seconds spent per output.
        machining: the machining estimate written to ``hologram.json``.
    """

    timings: dict[str, float]
    machining: dict[str, Any]


def dump_design_json(info: dict[str, Any], fh: Any) -> None:
    """``hologram.json``: indented, but its stipples one to a line.

    json writes an indented file in pure Python (15 s for a million
    stipples); the stipples' list goes through its C encoder instead, the same
    values in the same order, a block at a time when they are
    :class:`StippleRows`.
    """
    stipples = info.get("stipples")
    if not stipples:
        json.dump({**info, "stipples": []} if isinstance(stipples, StippleRows) else info, fh,
                  indent=1)
        return
    mark = json.dumps("\x00stipples\x00")  # a string no JSON value of a design holds
    head, tail = json.dumps({**info, "stipples": json.loads(mark)}, indent=1).split(mark)
    fh.write(head)
    fh.write("[\n  ")
    blocks = stipples.blocks() if isinstance(stipples, StippleRows) else [stipples]
    for k, block in enumerate(blocks):
        fh.write(",\n  " if k else "")
        fh.write(json.dumps(block, separators=(", ", ": "))[1:-1].replace("}, {", "},\n  {"))
    fh.write("\n ]")
    fh.write(tail)


def write_design(d: Design, out: str | os.PathLike[str],
                 formats: tuple[str, ...] = DEFAULT_FORMATS,
                 command: list[str] | None = None,
                 inputs: Iterable[str | os.PathLike[str] | None] = ()) -> Written:
    """Write every output of a design into ``out`` (all or nothing).

    Every file but ``run.json`` is the same byte for byte for the same model,
    settings and software; ``run.json`` records this run (see :func:`run_record`).
    Grooves of over a GB (:data:`~specholo.fabrication.order.IN_PLACE_BYTES`)
    are put in cutting order in place: ``d.grooves`` is then in that order.

    Args:
        d: the design.
        out: output folder.
        formats: fabrication files to write, from :data:`FORMATS`.
        command: the command line, for ``run.json`` (default ``sys.argv``).
        inputs: the model and config files, which ``out`` must not hold as
            files a design writes (:func:`specholo.folders.publish`).

    Returns:
        Seconds spent per output, and the machining estimate.
    """
    from specholo.fabrication.gcode import GcodeOptions, check_grooves, write_gcode
    from specholo.fabrication.order import order_paths
    from specholo.fabrication.svg import write_svg
    from specholo.fabrication.timing import estimate_time
    from specholo.folders import check_out
    from specholo.preview.preview import render_preview
    from specholo.scene.stippling import check_disk
    from specholo.staging import stage_design

    check_formats(formats, d.config.method)
    inputs = list(inputs)
    check_out(out, inputs)  # before the ordering and the estimate
    check_disk(len(d.points), out)
    check_grooves(d.grooves)  # e.g. grooves beyond any machine, before ordering them
    setup = d.config.setup()
    timings: dict[str, float] = {}
    grooves = d.grooves
    if d.config.order:
        t0 = time.perf_counter()
        # Grooves of over a GB are put in order in place, through a scratch file
        # beside the output, so that memory never holds two copies of them.
        near = Path(out).absolute().parent
        while not near.is_dir() and near != near.parent:
            near = near.parent
        grooves, order_stats = order_paths(d.grooves, scratch=near)
        d = dataclasses.replace(d, grooves=grooves)
        timings["ordering"] = time.perf_counter() - t0
    info = hologram_json(d)
    options = GcodeOptions(dialect=d.config.dialect,  # type: ignore[arg-type]
                           units=d.config.units)  # type: ignore[arg-type]
    laser = d.config.dialect == "marlin"
    # the program waits options.dwell after starting a spindle (a mill's only)
    estimate = estimate_time(grooves, d.config.depth_mm, setup.machining, laser=laser,
                             dwell=options.dwell if options.mill and setup.machining.spindle > 0
                             else 0.0)
    info["machining"] = {
        "dialect": d.config.dialect, "units": d.config.units,
        "estimated_hours": estimate.total_s / 3600.0,
        "cutting_hours": estimate.cutting_s / 3600.0, "rapid_hours": estimate.rapid_s / 3600.0,
        "plunge_hours": estimate.plunge_s / 3600.0, "hop_hours": estimate.hop_s / 3600.0,
        "hops": estimate.hops, "stipples_per_second": estimate.stipples_per_s,
    }
    if d.config.order:
        info["machining"]["travel_unordered_mm"] = order_stats.travel_before_mm
        info["machining"]["travel_mm"] = order_stats.travel_after_mm
    width = d.config.cutter().section(d.config.depth_mm).width
    plate = Plate.from_corners(d.plate if d.plate is not None else
                               plate_rect(d.grooves, width, d.config),
                               d.config.stock_thickness)
    with stage_design(out, inputs) as stage:
        tmp = stage.path
        if "gcode" in formats:
            t0 = time.perf_counter()
            path = tmp / "hologram.gcode"
            write_gcode(path, grooves, setup.tool, setup.machining,
                        header={"design": d.config.method, "stipples": str(len(d.points)),
                                "cutter": d.config.cutter().describe(),
                                # the limits `specholo check FILE` checks it against, mm
                                **design_limits(d).header()},
                        options=options, depth=d.config.depth_mm, plate=plate)
            timings["gcode"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            safety = stage.check(path.name, design_limits(d))
            info["machining"]["safety_check"] = {"moves": safety.moves, "violations": 0}
            timings["gcode check"] = time.perf_counter() - t0
        if "svg" in formats:
            t0 = time.perf_counter()
            write_svg(tmp / "hologram.svg", grooves, setup.tool, plate=plate)
            timings["svg"] = time.perf_counter() - t0
        if "dxf" in formats:
            from specholo.fabrication.dxf import write_dxf  # ezdxf: only when asked for

            t0 = time.perf_counter()
            write_dxf(tmp / "hologram.dxf", grooves, setup.tool, plate=plate)
            timings["dxf"] = time.perf_counter() - t0
        if "pdf" in formats:
            # matplotlib's PDF: an arc design's compass pattern, else its strokes
            from specholo.fabrication.pattern import write_pattern
            from specholo.fabrication.stroke_pattern import write_stroke_pattern

            t0 = time.perf_counter()
            write = write_pattern if d.config.method == "arc" else write_stroke_pattern
            write(tmp / "pattern.pdf", grooves)
            timings["pdf"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        d.grooves.save(str(tmp / "grooves.npz"))
        with atomic_open(tmp / "stipples.npz", "wb", encoding=None) as fh:
            np.savez_compressed(fh, points=d.points,
                                normals=d.normals if d.normals is not None else np.zeros((0, 3)))
        if d.model.mesh is not None:
            d.model.mesh.export(tmp / "model.ply")
        with atomic_open(tmp / "hologram.json") as fh:
            dump_design_json(info, fh)
        timings["data"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        render_preview(d.grooves, setup, tmp / "preview.png")
        timings["preview"] = time.perf_counter() - t0
        with atomic_open(tmp / "run.json") as fh:
            json.dump(run_record(d.config, command, {"design": d.timings, "writing": timings}),
                      fh, indent=1)
    return Written(timings, info["machining"])


@dataclass
class Loaded:
    """A design read back from its output folder."""

    config: DesignConfig
    points: np.ndarray
    normals: np.ndarray | None
    grooves: Grooves
    mesh: Any


def load_design(folder: str | os.PathLike[str], from_gcode: bool = False) -> Loaded:
    """Read a design folder written by :func:`write_design`.

    Args:
        folder: the output folder.
        from_gcode: read the grooves from ``hologram.gcode`` (the file that will be
            cut) instead of ``grooves.npz``.
    """
    from specholo.scene.loading import read_mesh

    folder = Path(folder)
    info = design_json(folder)
    if info.get("design") in ("composition", "conforming"):
        raise SpecholoError(f"{folder} holds a composed design (specholo compose): verify "
                            "reads it, and its pictures are preview.png and preview.gif")
    config = settings_of(folder, info)
    if config.method == "ridged":
        raise SpecholoError(f"{folder} holds a ridged design (a height field, no "
                            "grooves): render, verify and view read it")
    points, normals = load_stipples(folder / "stipples.npz")
    if from_gcode:
        from specholo.fabrication.gcode_reader import read_gcode

        grooves = read_gcode(folder / "hologram.gcode")
        grooves.validate(len(points), str(folder / "hologram.gcode"))
    else:
        grooves = Grooves.load(folder / "grooves.npz", len(points))
    # A model.ply that exists is read (or refused): skipping one that cannot be
    # read would verify without the occlusion the design had.
    mesh = read_mesh(folder / "model.ply") if (folder / "model.ply").exists() else None
    return Loaded(config, points, normals, grooves, mesh)


def design_json(folder: Path) -> dict[str, Any]:
    """A design folder's hologram.json, a JSON object."""
    from specholo.readback import read_json, table

    meta = folder / "hologram.json"
    if not meta.exists():
        raise SpecholoError(f"{folder} holds no hologram.json: not a design folder")
    return table(read_json(meta), str(meta))


def settings_of(folder: Path, info: dict[str, Any]) -> DesignConfig:
    """The settings a design's hologram.json records, checked as any config is."""
    meta = folder / "hologram.json"
    if "settings" not in info:
        raise SpecholoError(f"{meta} holds no settings: not a design folder")
    try:
        return DesignConfig.from_dict(info["settings"])
    except SpecholoError as exc:
        raise SpecholoError(f"{meta}: {exc}") from exc


def load_stipples(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """A design's stipples.npz: the points (n, 3) and their normals (n, 3), or None
    where the model was a point cloud (stored as (0, 3))."""
    from specholo.readback import ArraySpec, load_arrays, within

    a = load_arrays(path, {"points": ArraySpec((None, 3), finite=True),
                           "normals": ArraySpec((None, 3), finite=True)})
    points, normals = a["points"], a["normals"]
    if not within(points, -MAX_COORDINATE, MAX_COORDINATE):
        raise SpecholoError(f"{path}: points must lie within {MAX_COORDINATE:g} mm")
    if len(normals) not in (0, len(points)):
        raise SpecholoError(f"{path}: {len(normals)} normals for {len(points)} points")
    return points, normals if len(normals) else None


def _visibility(loaded: Loaded) -> Any:
    """The occlusion test of a loaded design's model, or None for point clouds."""
    from specholo.visibility.occlusion import visible

    vis = None
    if loaded.mesh is not None and loaded.normals is not None:
        mesh, normals = loaded.mesh, loaded.normals

        def vis(points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
            return visible(mesh, points, normals, eyes)

    return vis


def verify_design(loaded: Loaded, max_step_deg: float = 5.0) -> list[Any]:
    """Run the stereo verification on a loaded design."""
    from specholo.simulation.verify import verify, view_azimuths

    setup = loaded.config.setup()
    az = view_azimuths(setup.viewer.half_range, math.radians(max_step_deg))
    return verify(loaded.grooves, loaded.points, setup, _visibility(loaded), az)


#: How ``verify --cut`` finds what the cutting leaves (:func:`cut_method`).
CUT_METHODS = ("survival", "field")
#: Height-field sample spacing when none is given, mm.
DEFAULT_RESOLUTION = 0.02


def cut_method(method: str | None, resolution: float | None, stl: object | None) -> str:
    """How to check the plate as cut: ``survival`` (exact, from the grooves) unless
    the height field is asked for, by name or by its own settings (a resolution,
    an STL of the cut plate).

    Raises:
        SpecholoError: a method not in :data:`CUT_METHODS`, or the survival test
            with a height field's setting.
    """
    if method is None:
        return "field" if resolution is not None or stl is not None else "survival"
    if method not in CUT_METHODS:
        raise SpecholoError(f"cut method must be one of {', '.join(CUT_METHODS)}, got "
                            f"{method!r}")
    if method == "survival" and (resolution is not None or stl is not None):
        raise SpecholoError("--resolution and --stl are the height field's: use --cut-method "
                            "field, or leave them out for the exact survival test")
    return method


def verify_cut_design(loaded: Loaded, max_step_deg: float = 5.0,
                      resolution: float | None = None,
                      stl: str | os.PathLike[str] | None = None,
                      method: str | None = None) -> tuple[list[Any], Any]:
    """Verify the design on the plate as cut.

    By default (``survival``) each eye's designed glints are kept where no other
    path's cut removes them (:mod:`specholo.simulation.survival`): exact, with
    no resolution to converge. ``field`` cuts the grooves into a simulated
    height field and finds the glints on that surface (:mod:`specholo.simulation.cut`).

    Args:
        loaded: the design (grooves read back from its G-code, usually).
        max_step_deg: largest azimuth step between eye pairs, degrees.
        resolution: height-field sample spacing, mm (default :data:`DEFAULT_RESOLUTION`).
        stl: also write the cut plate here as a watertight STL (height field only).
        method: ``survival`` or ``field`` (default: see :func:`cut_method`).

    Returns:
        The per-azimuth reports on the cut plate, and the height field (None
        for the survival test).
    """
    from specholo.simulation.verify import view_azimuths

    method = cut_method(method, resolution, stl)
    setup = loaded.config.setup()
    az = view_azimuths(setup.viewer.half_range, math.radians(max_step_deg))
    if method == "survival":
        from specholo.simulation.survival import verify_as_cut

        as_cut = verify_as_cut(loaded.grooves, loaded.points, setup, loaded.config.cutter(),
                               loaded.config.depth_mm, _visibility(loaded), az)
        return as_cut.reports, None
    from specholo.simulation.cut import cut_design, verify_cut, write_stl

    resolution = DEFAULT_RESOLUTION if resolution is None else resolution
    if not (math.isfinite(resolution) and 0.001 <= resolution <= 1.0):
        raise SpecholoError(f"resolution must be in [0.001, 1] mm, got {resolution}")
    field = cut_design(loaded, resolution)
    if stl is not None:
        write_stl(stl, field, loaded.config.stock_thickness)
    return verify_cut(field, loaded.points, setup, _visibility(loaded), az), field

"""What every plate ``specholo design`` makes takes, grooved or ridged, in the
units users speak (mm, degrees): the model's pose, the light, the viewer, the
stipples, the blank, the feeds and the program, with the checks both kinds
run. Each kind's own settings (:class:`specholo.jobs.flat.settings.DesignConfig`,
:class:`specholo.jobs.ridged.settings.RidgedConfig`) add theirs to
:class:`PlateConfig` and build their setup (radians) from it once."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields
from typing import Any, ClassVar, Self

from specholo.errors import SpecholoError
from specholo.fabrication.plate import STOCK_THICKNESS
from specholo.optics.cutters import Cutter
from specholo.scene.pose import UP_AXES, Pose
from specholo.setup import SETTING_BOUNDS, Light, Machining, Setup, Viewer

DEFAULT_STIPPLES = 2000
#: Fallback groove depth (mm) and spindle speed (rpm) by tool. A design without a
#: depth cuts just deep enough for the wall tilts its views need (see
#: :data:`specholo.jobs.flat.settings.TILT_MARGIN`); drag tips, scribers and
#: lasers do not spin.
TOOL_DEFAULTS = {"ball": (0.08, 12000.0), "drag": (0.006, 0.0), "scriber": (0.012, 0.0),
                 "vbit": (0.05, 12000.0), "laser": (0.04, 0.0)}
#: Dialects of the programs a design writes.
DIALECTS = ("grbl", "linuxcnc", "marlin")
#: Largest magnitude of any length, angle, feed or speed setting: far beyond any
#: plate, light or machine, and small enough that squares and products stay finite.
MAX_SETTING = 1e12


def _check_bounds(config: Any) -> None:
    """Refuse a setting outside its physical bounds (:data:`SETTING_BOUNDS`), naming
    it; a kind is checked on the settings it has."""
    for name, (lo, hi, unit) in SETTING_BOUNDS.items():
        value = getattr(config, name, None)
        if value is not None and not lo <= value <= hi:
            raise SpecholoError(f"{name.replace('_', '-')} {value:g} {unit} is out of range: "
                                f"it must be in [{lo:g}, {hi:g}] {unit}")


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


#: Cutters made from settings, by the settings' kind and the values they are
#: made from: each is made once however many settings share it.
_CUTTERS: dict[tuple[Any, ...], Cutter] = {}
_MAX_CUTTERS = 64


@dataclass(frozen=True)
class PlateConfig:
    """The design command's options every plate takes, in the units of the
    command line (mm, degrees); attributes mirror the ``specholo design``
    options of the same names. A kind subclasses it with its own options and
    rules, and says in :attr:`FOREIGN` why it refuses the other kind's."""

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
    seed: int = 0
    tool: str = "drag"
    tool_radius: float | None = None
    dialect: str | None = None
    units: str = "mm"
    plate_width: float | None = None
    plate_height: float | None = None
    fit: bool = False
    stock_thickness: float = STOCK_THICKNESS
    feed: float = 300.0
    plunge: float = 100.0
    safe_z: float = 1.0
    spindle: float | None = None

    #: The other kind's settings, by name, with why this kind refuses each (one
    #: line, naming the option); folders written before each kind had settings
    #: of its own recorded them all (:meth:`from_saved`).
    FOREIGN: ClassVar[dict[str, str]] = {}
    #: The settings the cutter is made from (:meth:`cutter`).
    CUTTER_SETTINGS: ClassVar[tuple[str, ...]] = ("tool", "tool_radius")

    def _check_types(self) -> None:
        for f in fields(self):
            _check_setting(self, f.name, str(f.type))

    def _fill_spindle(self) -> None:
        """The spindle by tool where none is given (a frozen dataclass: filled in once)."""
        if self.spindle is None:
            object.__setattr__(self, "spindle", TOOL_DEFAULTS.get(self.tool, (0.08, 0.0))[1])

    def _check_shared(self) -> None:
        """Refuse the shared settings' bad choices, counts and sizes."""
        if self.dialect not in DIALECTS:
            raise SpecholoError(f"dialect must be grbl, linuxcnc or marlin, got {self.dialect!r}")
        if self.up not in UP_AXES:
            raise SpecholoError(f"up must be one of {', '.join(UP_AXES)}, got {self.up!r}")
        if self.units not in ("mm", "inch"):
            raise SpecholoError(f"units must be mm or inch, got {self.units!r}")
        if self.stipples is not None and self.spacing is not None:
            raise SpecholoError("give either stipples or spacing, not both")
        if self.stipples is not None and (isinstance(self.stipples, bool)
                                          or int(self.stipples) != self.stipples
                                          or self.stipples <= 0):
            raise SpecholoError(f"stipples must be a positive integer, got {self.stipples}")

    def _check_sizes(self) -> None:
        """Refuse a model or a plate of no size."""
        if self.spacing is not None and not (math.isfinite(self.spacing) and self.spacing > 0):
            raise SpecholoError(f"spacing must be a positive number of mm, got {self.spacing}")
        for name in ("size", "center_z"):
            if not math.isfinite(getattr(self, name)):
                raise SpecholoError(f"{name.replace('_', '-')} must be finite, got "
                                    f"{getattr(self, name)}")
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

    @classmethod
    def _given(cls, clean: dict[str, Any]) -> None:
        """Fill in, in place, the defaults that depend on other settings given."""

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> Self:
        """Build from a mapping with option names (dashes or underscores); an
        unknown setting, or the other kind's, is refused in one line."""
        if not isinstance(values, dict):
            raise SpecholoError(f"settings must be a table of options, got {values!r:.60}")
        known = {f.name for f in fields(cls)}
        clean: dict[str, Any] = {}
        for key, value in values.items():
            name = str(key).replace("-", "_")
            if name not in known:
                raise SpecholoError(cls.FOREIGN.get(name, f"unknown setting {key!r}"))
            clean[name] = value
        cls._given(clean)
        try:
            return cls(**clean)
        except TypeError as exc:
            raise SpecholoError(f"bad setting: {exc}") from exc

    @classmethod
    def from_saved(cls, values: dict[str, Any]) -> Self:
        """The settings a folder's ``hologram.json`` recorded. Folders written
        before each kind had its own settings recorded the other kind's too, which
        their design did not use: those are dropped; the rest is read as
        :meth:`from_dict` reads options."""
        if isinstance(values, dict):
            values = {k: v for k, v in values.items()
                      if str(k).replace("-", "_") not in cls.FOREIGN}
        return cls.from_dict(values)

    @property
    def depth_mm(self) -> float:
        """How deep the tool cuts, mm (the kind's own)."""
        raise NotImplementedError

    def fit_band(self) -> float:
        """How far past the grooves' centrelines a model fitted to its plate
        (``fit``) keeps the band's edge, mm."""
        raise NotImplementedError

    def _build_cutter(self) -> Cutter:
        raise NotImplementedError

    def _light(self) -> Light:
        distance = None if self.light_distance is None else float(self.light_distance)
        return Light(math.radians(float(self.light_elevation)), distance)

    def _machining(self) -> Machining:
        return Machining(float(self.feed), float(self.plunge), float(self.safe_z),
                         float(self.spindle or 0.0))

    def cutter(self) -> Cutter:
        """The cutting tool, built once for its settings (:attr:`CUTTER_SETTINGS`):
        settings that differ in anything else (a design choosing its depth makes
        new ones) share it, as it is frozen too."""
        built = self.__dict__.get("_cutter")
        if built is None:
            key = (type(self), *(getattr(self, name) for name in self.CUTTER_SETTINGS))
            built = _CUTTERS.get(key)
            if built is None:
                try:
                    built = self._build_cutter()
                except (TypeError, ValueError) as exc:
                    if isinstance(exc, SpecholoError):
                        raise
                    raise SpecholoError(f"bad setting: {exc}") from exc
                if len(_CUTTERS) >= _MAX_CUTTERS:  # a long-running page's designs
                    _CUTTERS.clear()
                _CUTTERS[key] = built
            # a frozen dataclass refuses setattr; its __dict__ holds the one copy
            self.__dict__["_cutter"] = built
        return built

    def pose(self) -> Pose:
        """How the model is turned and moved onto the plate (not a striped
        design's ``placement``)."""
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
            return Setup(
                light=self._light(),
                viewer=Viewer(float(self.view_distance), float(self.eye_height),
                              math.radians(float(self.view_range)), float(self.ipd)),
                tool=self.cutter().model(self.depth_mm),
                machining=self._machining(),
            )
        except (TypeError, ValueError) as exc:
            if isinstance(exc, SpecholoError):
                raise
            raise SpecholoError(f"bad setting: {exc}") from exc

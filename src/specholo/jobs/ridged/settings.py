"""A ridged plate's settings (``specholo design --method ridged`` and its TOML),
in the units users speak (mm, degrees): what every plate takes
(:class:`specholo.jobs.plate_settings.PlateConfig`) with a ridged plate's own
defaults, and its own options (the heads' elevation range, the shell, the
raster, a clear plate lit from behind), checked once and turned into the
library's setup (radians) by :meth:`RidgedConfig.setup`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from specholo.errors import SpecholoError
from specholo.jobs.plate_settings import PlateConfig, _check_bounds
from specholo.optics.cutters import Cutter, make_cutter
from specholo.setup import ACRYLIC_INDEX, MAX_INDEX, BackLight, Light

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
#: The half-height of the band a ridged plate is fitted to a plate with
#: (``--fit``), mm: the grooved designs' default band, by which ridged plates
#: have always been fitted.
FIT_BAND = 0.2

#: A grooved design's settings (``specholo design`` with a method of grooves),
#: which a ridged plate refuses, each in one line naming its option.
GROOVED_SETTINGS = {
    **{name: f"--{name.replace('_', '-')} is a grooved design's setting (striped, hyperbola "
             f"or arc): a ridged plate has no grooves, leave it out"
       for name in ("band", "band_share", "placement", "thin", "tool_angle", "tip_flat", "spot",
                    "strict", "hop", "hop_max", "holder", "preload")},
    "order": "--no-order is a grooved design's setting (striped, hyperbola or arc): a ridged "
             "plate's raster is cut in its own order, leave it out",
    "depth": "depth is a groove's; a ridged plate is cut 2 x shell deep (set --shell)",
    "visibility": "visibility needs a grooved design (striped, hyperbola or arc): a ridged "
                  "plate's facets do not cut into each other",
    "machine": "--machine times a grooved design: a ridged plate's raster is timed at its "
               "feed (leave out --machine)",
}


@dataclass(frozen=True)
class RidgedConfig(PlateConfig):
    """Every option of a ridged design, in the units of the command line (mm,
    degrees); attributes mirror the ``specholo design`` options of the same names.

    Its own defaults: each plate cell serves one stipple in one direction, so a
    head sees about (plate area) / (a stipple's patch, ~ solid angle x depth^2)
    stipples: a full-parallax plate needs a narrower zone and a model nearer
    the plate than a grooved one to show an image. On the bundled bunny, a 50 mm
    model 20 mm deep seen within +-20 x +-8 deg shows about 60 stipples a head
    in both eyes where the grooved designs' (60 mm, 40 mm deep, +-45 x +-15 deg)
    gave 1.4. A ridged plate is milled with a ball (``tool`` ball).
    """

    size: float = 50.0
    center_z: float = -20.0
    view_range: float = 20.0
    tool: str = "ball"
    method: str = "ridged"
    elevation_range: float = 8.0
    shell: float = 0.1
    raster: float = 0.02
    optic: str = "reflect"
    refraction: str = "exact"
    index: float = ACRYLIC_INDEX

    FOREIGN: ClassVar[dict[str, str]] = GROOVED_SETTINGS

    def __post_init__(self) -> None:
        self._check_types()
        self._fill_spindle()
        if self.dialect is None:
            object.__setattr__(self, "dialect", "grbl")
        if self.method != "ridged":
            raise SpecholoError(f"a ridged design's method is ridged, got {self.method!r}")
        self._check_shared()
        self._check_sizes()
        self._check_ranges()
        self._check_optic()
        if self.tool != "ball":
            raise SpecholoError(f"a ridged plate is milled with a ball-end mill: use --tool ball "
                                f"(got {self.tool})")
        self.setup()  # validates the physical settings
        _check_bounds(self)
        self._check_mill()

    def _check_ranges(self) -> None:
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
        """Refuse refraction settings on a mirror, and a clear plate lit from the front."""
        if self.optic not in OPTICS:
            raise SpecholoError(f"optic must be reflect or refract, got {self.optic!r}")
        if self.refraction not in REFRACTION_MODELS:
            raise SpecholoError(f"refraction must be one of {', '.join(REFRACTION_MODELS)}, "
                                f"got {self.refraction!r}")
        if self.optic == "refract":
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

    def _check_mill(self) -> None:
        """Refuse a machine that cannot mill a ridged plate."""
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

    @classmethod
    def _given(cls, clean: dict[str, Any]) -> None:
        if clean.get("optic") == "refract":
            clean.setdefault("light_elevation", BACK_LIGHT_ELEVATION)  # behind the plate

    @property
    def ball_radius(self) -> float:
        """Ball radius of a ridged plate's finishing raster, mm."""
        return float(self.tool_radius) if self.tool_radius is not None else RIDGED_BALL_RADIUS

    def fit_band(self) -> float:
        return FIT_BAND

    @property
    def depth_mm(self) -> float:
        """How deep the ball reaches, mm: a ridged plate has no grooves; its ball
        reaches the shell's depth, stated here within the ball's radius so the
        tool model stays a valid groove."""
        return min(2.0 * float(self.shell), self.ball_radius)

    def _build_cutter(self) -> Cutter:
        return make_cutter(self.tool, self.tool_radius)

    def _light(self) -> Light:
        if self.optic != "refract":
            return super()._light()
        distance = None if self.light_distance is None else float(self.light_distance)
        return BackLight(math.radians(float(self.light_elevation)), distance,
                         float(self.stock_thickness), float(self.index))

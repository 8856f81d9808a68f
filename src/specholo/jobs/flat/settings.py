"""The design command's settings for a grooved plate (``specholo design`` and
its TOML; methods striped, hyperbola and arc), in the units users speak (mm,
degrees): every option with its bounds and defaults, checked once, and turned
into the library's setup (radians) by :meth:`DesignConfig.setup`. What a
ridged plate shares with it is :class:`specholo.jobs.plate_settings.PlateConfig`'s."""


from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Self

from specholo.errors import SpecholoError
from specholo.fabrication.programs.machines import MACHINES, MachineProfile, machine_profile
from specholo.jobs.plate_settings import TOOL_DEFAULTS, PlateConfig, _check_bounds
from specholo.optics.cutters import Cutter, make_cutter
from specholo.setup import (
    DEFAULT_PRELOAD,
    HOLDERS,
    PRELOAD_RANGE,
    SETTING_BOUNDS,
    Holder,
    Machining,
)
from specholo.toolpaths.striped import PLACEMENTS

METHODS = ("striped", "hyperbola", "arc")
#: Thinning a crowded plate (see :func:`specholo.jobs.flat.design.thin_as_cut`).
THINNING = ("auto", "on", "off")
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

#: A ridged plate's own settings (:mod:`specholo.jobs.ridged.settings`), and why
#: a grooved design refuses each.
RIDGED_SETTINGS = {
    **{name: f"--{name.replace('_', '-')} is a ridged design's setting: add --method ridged"
       for name in ("elevation_range", "shell", "raster", "optic")},
    **{name: f"--{name} is a setting of a ridged design's clear plate lit from behind: add "
             "--method ridged --optic refract" for name in ("refraction", "index")}}


@dataclass(frozen=True)
class DesignConfig(PlateConfig):
    """Every option of a grooved design, in the units of the command line (mm,
    degrees): :class:`~specholo.jobs.plate_settings.PlateConfig`'s and the
    grooves' own.

    Attributes mirror the ``specholo design`` options of the same names.
    """

    visibility: float | None = None
    method: str = "striped"
    band: float | None = None
    band_share: float | None = None
    placement: str = "auto"
    thin: str = "auto"
    tool_angle: float | None = None
    tip_flat: float = 0.0
    spot: float | None = None
    depth: float | None = None
    strict: bool = False
    order: bool = True
    hop: float = 0.03
    hop_max: float = 3.0
    holder: str | None = None
    preload: float | None = None
    machine: str | None = None

    FOREIGN: ClassVar[dict[str, str]] = RIDGED_SETTINGS
    CUTTER_SETTINGS: ClassVar[tuple[str, ...]] = ("tool", "tool_radius", "tool_angle",
                                                  "tip_flat", "spot")

    def __post_init__(self) -> None:
        self._check_types()
        # The spindle defaults by tool (a frozen dataclass: filled in once here); the
        # depth is chosen by design() from the wall tilts the views need.
        self._fill_spindle()
        if self.band is None:
            object.__setattr__(self, "band", HAND_BAND if self.tool == "scriber" else BAND)
        # Marlin's programs drive a laser (no Z, the beam switched around each
        # groove); GRBL's and LinuxCNC's plunge a cutter: a laser defaults to
        # Marlin, and a cutter's program is never written as a laser's.
        if self.dialect is None:
            object.__setattr__(self, "dialect", "marlin" if self.tool == "laser" else "grbl")
        self._check_shared()
        if (self.dialect == "marlin") != (self.tool == "laser"):
            raise SpecholoError(
                f"--dialect marlin drives a laser: --tool {self.tool} needs --dialect grbl or "
                "linuxcnc"
                if self.dialect == "marlin" else
                f"a laser is driven by --dialect marlin ({self.dialect} programs plunge a cutter)")
        if self.placement not in PLACEMENTS:
            raise SpecholoError(f"placement must be one of {', '.join(PLACEMENTS)}, got "
                                f"{self.placement!r}")
        if self.thin not in THINNING:
            raise SpecholoError(f"thin must be one of {', '.join(THINNING)}, got {self.thin!r}")
        if self.method == "ridged":
            raise SpecholoError("a ridged plate has settings of its own: RidgedConfig "
                                "(specholo.jobs.ridged.settings)")
        if self.method not in METHODS:
            raise SpecholoError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        if self.visibility is not None and not 0.0 < self.visibility < 1.0:
            raise SpecholoError("visibility must be a share between 0 and 1 (e.g. 0.8), "
                                f"got {self.visibility}")
        if self.visibility is not None and self.spacing is not None:
            raise SpecholoError("give either visibility or spacing, not both")
        if not math.isfinite(self.band or 0.0):
            raise SpecholoError(f"band must be finite, got {self.band}")
        if not (self.band is not None and self.band > 0):
            raise SpecholoError(f"band must be positive, got {self.band}")
        if self.band_share is not None and not (math.isfinite(self.band_share)
                                                and 0.0 < self.band_share <= 1.0):
            raise SpecholoError(f"band share must be in (0, 1], got {self.band_share}")
        self._check_sizes()
        if isinstance(self.depth, (int, float)) and self.depth >= self.stock_thickness:
            raise SpecholoError(f"groove depth {self.depth:g} mm must be less than the stock "
                                f"thickness {self.stock_thickness:g} mm")
        self._check_holder()
        self.setup()  # validates the physical settings
        _check_bounds(self)
        self._check_trough()
        self._check_machine()

    def _check_trough(self) -> None:
        """Refuse a laser's trough too flat to show a glint.

        A laser's trough is modelled by the circle its floor follows, of radius
        spot^2 / (16 depth): a shallow trough of a wide spot is nearly flat."""
        radius = self.setup().tool.radius
        most = SETTING_BOUNDS["tool_radius"][1]
        if radius > most:
            raise SpecholoError(f"a {self.depth_mm:g} mm deep groove of this {self.tool} is "
                                f"too flat to show a glint (its floor curves with a radius of "
                                f"{radius:.3g} mm, at most {most:g}): set a larger --depth")

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
                               "spring" if self.tool in spring_tools and not spun else "rigid")
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

    @classmethod
    def _given(cls, clean: dict[str, Any]) -> None:
        """The machine's own feeds (and a laser's tool and a mill's dialect) where
        none is given; given ones are checked against its rates."""
        chosen = clean.get("machine")
        if isinstance(chosen, str) and chosen in MACHINES:
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

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> Self:
        """Build from a mapping with option names (dashes or underscores)."""
        if isinstance(values, dict) and values.get("optic") == "refract":
            method = values.get("method", "striped")
            raise SpecholoError(f"a refraction plate is a ridged design: use --method ridged "
                                f"(got {method})")
        return super().from_dict(values)

    def fit_band(self) -> float:
        return float(self.band or 0.0)

    @property
    def depth_mm(self) -> float:
        """Groove depth, mm: as given, else the tool's fallback default."""
        if self.depth is not None:
            return float(self.depth)
        return TOOL_DEFAULTS.get(self.tool, (0.08, 0.0))[0]

    def _build_cutter(self) -> Cutter:
        return make_cutter(self.tool, self.tool_radius, self.tool_angle, float(self.tip_flat),
                           self.spot)

    def _machining(self) -> Machining:
        return Machining(float(self.feed), float(self.plunge), float(self.safe_z),
                         float(self.spindle or 0.0), float(self.hop), float(self.hop_max))

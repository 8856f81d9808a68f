"""The one G-code emitter: how every program specholo writes is set up.

Every program (a flat design's grooves, a ridged plate's raster, a composition
on a curved host in 3 or 4 axes, a turning plate and its relief, a steady
image's scoops, a test coupon) is written through an :class:`Emitter`: one
dialect (:class:`GcodeOptions`: GRBL 1.1, LinuxCNC, or Marlin driving a laser),
one unit (mm or inch, every coordinate and feed converted), one number format
(:func:`format_number`: 5 decimals in mm, 6 in inches, never ``-0``), one
header (title, dialect, units, origin, tool and depth, the plate and how to set
its zero, then the caller's ``key: value`` lines), one set-up (``G21``/``G20
G90 G17 G94 G40``, the spindle and its dwell, the safe height) and one holder
rule (a spring holder cuts at its preload and lifts clear between strokes; a
program whose depth varies along a cut needs a rigid one). The bodies differ:
a flat design's grooves are written by the compiled writer of
:mod:`specholo.fabrication.programs.gcode` from the emitter's texts; paths in X, Y and Z
or X and A by :meth:`Emitter.polyline` and :meth:`Emitter.rotary`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, cast

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.exporting import format_number
from specholo.fabrication.plate import Plate
from specholo.setup import Holder, Machining

#: Decimals of every written coordinate and feed in mm.
DECIMALS = 5
#: Written coordinates are integers in units of 1 / SCALE mm.
SCALE = 10**DECIMALS
#: Decimals of coordinates and feeds written in inches (a grid as fine as in mm).
INCH_DECIMALS = 6
MM_PER_INCH = 25.4
#: Largest I or J (mm) written for single-precision firmware (GRBL, Marlin): a
#: float keeps ~6e-5 mm at 1000 mm, and GRBL reads 8 significant digits, so
#: with 5 decimals every digit of a smaller offset is read.
MAX_ARC_OFFSET_MM = 1000.0

Dialect = Literal["grbl", "linuxcnc", "marlin"]
Units = Literal["mm", "inch"]
DIALECTS: tuple[str, ...] = ("grbl", "linuxcnc", "marlin")
#: Dialects that drive a spindle and plunge in Z.
MILL_DIALECTS: tuple[str, ...] = ("grbl", "linuxcnc")


_DIALECT_NAMES = {"grbl": "GRBL 1.1", "linuxcnc": "LinuxCNC RS274/NGC",
                  "marlin": "Marlin, laser"}


@dataclass(frozen=True)
class GcodeOptions:
    """How a program is written for a machine (feeds, heights and spindle are in
    :class:`~specholo.setup.Machining`).

    Attributes:
        dialect: ``"grbl"`` (GRBL 1.1), ``"linuxcnc"`` or ``"marlin"`` (laser).
        units: ``"mm"`` or ``"inch"``; every coordinate and feed is converted.
        dwell: seconds to wait after starting the spindle (mill dialects; 0 for none).
        header_lines: G-code lines written as they are after the modal setup line
            (e.g. a work offset ``G54`` or coolant ``M8``).
        laser_power: ``S`` value while the laser cuts (marlin), in the firmware's
            power unit (0-255 by default).
        laser_on: ``"M3"`` (constant power) or ``"M4"`` (power scaled with speed in
            Marlin's dynamic laser mode).
        dot_time: seconds the laser fires for a dot (marlin).
        rapid_feed: travel feed of Marlin's ``G0``, mm/min (without G0_FEEDRATE
            Marlin moves ``G0`` at the last ``F``).
    """

    dialect: Dialect = "grbl"
    units: Units = "mm"
    dwell: float = 2.0
    header_lines: tuple[str, ...] = ()
    laser_power: float = 255.0
    laser_on: Literal["M3", "M4"] = "M3"
    dot_time: float = 0.1
    rapid_feed: float = 3000.0

    def __post_init__(self) -> None:
        if self.dialect not in DIALECTS:
            raise SpecholoError(f"G-code dialect must be one of {', '.join(DIALECTS)}, "
                                f"got {self.dialect!r}")
        if self.units not in ("mm", "inch"):
            raise SpecholoError(f"G-code units must be mm or inch, got {self.units!r}")
        if self.laser_on not in ("M3", "M4"):
            raise SpecholoError(f"laser on must be M3 or M4, got {self.laser_on!r}")
        for name in ("dwell", "dot_time", "laser_power", "rapid_feed"):
            v = float(getattr(self, name))
            zero_ok = name in ("dwell", "dot_time")
            if not math.isfinite(v) or v < 0 or (v == 0 and not zero_ok):
                need = ">= 0" if zero_ok else "> 0"
                raise SpecholoError(f"{name.replace('_', ' ')} must be a finite number {need}, "
                                    f"got {v:g}")
        object.__setattr__(self, "header_lines", tuple(self.header_lines))
        for line in self.header_lines:
            if not isinstance(line, str) or not line.strip() or \
                    any(not 32 <= ord(c) < 127 for c in line) or len(line) > 200:
                raise SpecholoError(f"header line must be one line of printable ASCII, "
                                    f"got {line!r}")

    @property
    def mill(self) -> bool:
        """True for the dialects that plunge a spinning cutter."""
        return self.dialect in MILL_DIALECTS

    @property
    def decimals(self) -> int:
        """Decimals of written coordinates and feeds."""
        return DECIMALS if self.units == "mm" else INCH_DECIMALS

    @property
    def per_mm(self) -> float:
        """Written units per mm."""
        return 1.0 if self.units == "mm" else 1.0 / MM_PER_INCH

    @property
    def max_arc_offset(self) -> float:
        """Largest I/J written, mm (infinite for LinuxCNC, which computes in doubles)."""
        return math.inf if self.dialect == "linuxcnc" else MAX_ARC_OFFSET_MM


def comment(text: str, semicolon: bool = False) -> str:
    """``text`` as one comment line: ``(text)``, or ``; text`` for Marlin."""
    # G-code comments cannot nest parentheses or span lines, and LinuxCNC reads
    # lines of at most 255 characters.
    clean = "".join(c if 32 <= ord(c) < 127 else "?" for c in text)[:200]
    if semicolon:
        return f"; {clean}"
    return "(" + clean.replace("(", "[").replace(")", "]") + ")"


#: The drawings a flat design writes beside its program, which carry the plate's marks.
FLAT_DRAWINGS = ("SVG", "DXF")


def plate_lines(plate: Plate, options: GcodeOptions,
                drawings: Sequence[str] | None = FLAT_DRAWINGS) -> list[str]:
    """The header's plate block, comment texts in the program's units: the plate's
    size, corners and thickness, the registration marks, and how to set the
    origin. The words it quotes (``G10 L20``, ``G92``) set the origin of the
    dialect's machine where the tool stands; nothing here moves it.

    ``drawings`` names the drawings written with the program ("SVG", "DXF"),
    whose PLATE layer holds the marks: the header names only those, so that a
    maker looks for no file the design did not write. None: the program's
    plate carries no marks at all (a design that draws none), and the block
    says nothing of them."""
    unit = "mm" if options.units == "mm" else "in"

    def num(mm: float) -> str:
        text = format_number(mm * options.per_mm, options.decimals).rstrip("0").rstrip(".")
        return "0" if text in ("", "-0") else text

    def xy(p: np.ndarray) -> str:
        return f"X{num(p[0])} Y{num(p[1])}"

    thick = f", {num(plate.thickness)} {unit} thick" if plate.thickness is not None else ""
    corners = plate.corners()
    marks = plate.marks()
    lower_left = xy(corners[0])
    centre = "on the origin mark at the plate centre" if drawings is not None else \
        "at the plate centre"
    if options.mill:
        zero = (f"X0 Y0 {centre}, or G10 L20 P1 {lower_left} "
                "with the tool on the lower-left corner; Z0 on the top surface")
    else:
        zero = (f"G92 X0 Y0 with the beam {centre}, or "
                f"G92 {lower_left} on the lower-left corner; focus on the top surface")
    size = (f"plate: {num(plate.width)} x {num(plate.height)} {unit}{thick}, "
            f"corners {xy(corners[0])} to {xy(corners[2])}")
    if drawings is None:
        return [size, f"plate zero: {zero}"]
    return [
        size,
        f"plate marks: crosshair and {num(plate.mark_radius)} {unit} radius circle, "
        + _marks_drawn(drawings) + ", not cut",
        "plate marks at: " + ", ".join(xy(m) for m in marks[:4]) + f", origin {xy(marks[4])}",
        f"plate zero: {zero}",
    ]


def _marks_drawn(drawings: Sequence[str]) -> str:
    """Where the plate marks are drawn, in words: "layer PLATE of the SVG and DXF"."""
    names = list(drawings)
    if not names:
        return "in no drawing of this design"
    listed = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    return f"layer PLATE of the {listed}"


def short_number(value: float) -> str:
    """A setting (dwell, power) with up to 3 decimals and no trailing zeros."""
    text = format_number(value, 3).rstrip("0").rstrip(".")
    return text or "0"


@dataclass(frozen=True)
class Emitter:
    """How one program is written: its dialect and units, its feeds and heights,
    and how its tip is held.

    Attributes:
        options: dialect, units, dwell, extra set-up lines and a laser's settings.
        machining: feeds (mm/min), safe and hop heights (mm), spindle (rpm).
        holder: how the tip is held (mill dialects); None says nothing of it, a
            round tool's program (a spinning cutter is held rigidly).
    """

    options: GcodeOptions = field(default_factory=GcodeOptions)
    machining: Machining = field(default_factory=Machining)
    holder: Holder | None = None

    @property
    def mill(self) -> bool:
        """True for the dialects that plunge a spinning cutter."""
        return self.options.mill

    @property
    def unit(self) -> str:
        """The program's unit as its comments write it: ``mm`` or ``in``."""
        return "mm" if self.options.units == "mm" else "in"

    @property
    def decimals(self) -> int:
        """Decimals of every written coordinate and feed."""
        return self.options.decimals

    @property
    def scale(self) -> float:
        """Written integers (coordinates times 10**decimals) per mm."""
        return 10**self.options.decimals * self.options.per_mm

    @property
    def spring(self) -> bool:
        """Whether a spring holder carries the tip (mill dialects only)."""
        return self.mill and self.holder is not None and self.holder.spring

    def num(self, mm: float) -> str:
        """A length or feed in mm (mm/min) as the program writes it, in its units."""
        return format_number(mm * self.options.per_mm, self.options.decimals)

    def short(self, mm: float) -> str:
        """A length for a comment, in the program's units, without trailing zeros."""
        text = self.num(mm).rstrip("0").rstrip(".")
        return "0" if text in ("", "-0") else text

    def comment(self, text: str) -> str:
        """One comment line in the dialect's form."""
        return comment(text, semicolon=not self.mill)

    def require_mill(self, what: str) -> None:
        """Refuse a laser dialect for a program that moves Z.

        Raises:
            SpecholoError: naming ``what`` and the dialects that can cut it.
        """
        if not self.mill:
            raise SpecholoError(f"{what} moves the tool in Z: write it for a mill "
                                f"(--dialect {' or '.join(MILL_DIALECTS)}), not a laser")

    def require_rigid(self, what: str) -> None:
        """Refuse a spring holder for a program whose depth varies along a cut.

        Raises:
            SpecholoError: a spring's force sets one depth, not a profile.
        """
        if self.spring:
            raise SpecholoError(f"{what} gives each cut a depth that varies along it: a spring "
                                "holder's force sets one depth, so it needs --holder rigid")

    def cut_depth(self, depth: float) -> tuple[float, Machining]:
        """The depth below Z0 the cuts run at, and the machining with the hop height
        the holder needs (:meth:`~specholo.setup.Holder.program`)."""
        if self.mill and self.holder is not None:
            return self.holder.program(depth, self.machining)
        return float(depth), self.machining

    def depth_lines(self, depth: float, levels: np.ndarray | None = None) -> list[str]:
        """The header's depth and holder comments, texts: the depth, or each
        groove's range of Z, or a spring holder's preload, touch-off and
        setting, or a rigid holder's need of a known plate."""
        if not self.mill:
            return []
        cut_depth, machining = self.cut_depth(depth)
        if levels is not None and len(levels) > 1:
            # the caller's header says what each path's Z is for
            return [f"depth: by groove, Z{self.short(-levels[0])} to "
                    f"Z{self.short(-levels[-1])} (see below)"]
        unit = self.unit
        if self.spring:
            assert self.holder is not None
            return [
                f"depth: {self.short(depth)} {unit} expected: the spring's force at "
                f"{self.short(self.holder.preload)} {unit} of preload sets it, not the Z",
                f"holder: spring-loaded; Z0 with the tip touching the plate; cuts at "
                f"Z{self.short(-cut_depth)} (the spring compressed {self.short(cut_depth)} "
                f"{unit}), lifts to Z{self.short(machining.hop)} or "
                f"Z{self.short(machining.safe_z)} between strokes",
                f"touch-off: over X0 Y0, a paper shim on the plate, jog the tip down in "
                f"{self.short(0.01)} {unit} steps until the shim is pinched; G10 L20 P1 Z<the "
                f"shim's thickness>, remove the shim",
                f"preload: cut test strokes on scrap with this program's Z; turn the "
                f"holder's spring (or change --preload) until they are {self.short(depth)} "
                f"{unit} deep",
            ]
        lines = [f"depth: {self.num(depth)} {unit}"]
        if self.holder is not None:
            lines.append(f"holder: rigid; cuts at Z{self.short(-depth)}: the Z is the tip's, so "
                         "the plate's Z must be known to a fraction of the depth over the grooves")
        return lines

    def head(self, title: str, body: Sequence[str] = (), extra: Mapping[str, str] | None = None,
             plate: Plate | None = None, drawings: Sequence[str] | None = FLAT_DRAWINGS,
             origin: str | None = None, safe: float | None = None) -> list[str]:
        """The program's first lines: comments (the title, the dialect and what
        Marlin must be built with, the units, the origin, ``body``, the
        ``extra`` ``key: value`` lines, the plate block of :func:`plate_lines`),
        then the set-up (:meth:`setup`).

        Args:
            title: the first comment.
            body: comment texts that say what is cut and with what (tool, depth).
            extra: ``key: value`` comment lines after them.
            plate: the plate to name, or None for no plate block.
            drawings: the drawings that carry the plate's marks (see
                :func:`plate_lines`).
            origin: the origin's comment text; default the plate centre with Z0
                on its surface (a mill), or the plate centre and focus (a laser).
            safe: the height the set-up rises to, mm; default the safe height.
        """
        opt = self.options
        c = self.comment
        head = [c(title), c(f"dialect: {_DIALECT_NAMES[opt.dialect]}")]
        if not self.mill:
            needs = "LASER_FEATURE (M3/M4/M5) and ARC_SUPPORT (G2/G3)"
            needs += ", INCH_MODE_SUPPORT (G20)" if opt.units == "inch" else ""
            head.append(c(f"needs Marlin built with {needs}"))
        head.append(c(f"units: {opt.units}, absolute coordinates, feed in {self.unit}/min"))
        if origin is None:
            origin = ("origin: plate centre; X right, Y up, Z = 0 on the plate surface"
                      if self.mill else
                      "origin: plate centre; X right, Y up; no Z moves: focus on the plate first")
        head.append(c(origin))
        head += [c(text) for text in body]
        head += [c(f"{k}: {v}") for k, v in (extra or {}).items()]
        if plate is not None:
            head += [c(text) for text in plate_lines(plate, opt, drawings)]
        return head + self.setup(safe)

    def setup(self, safe: float | None = None) -> list[str]:
        """The modal set-up: units, absolute coordinates (a mill: the XY plane,
        feed per minute, no cutter compensation), the options' own lines, then
        a mill's spindle, its dwell and the rise to ``safe`` (default the safe
        height), or a laser switched off."""
        opt = self.options
        units = ["G21" if opt.units == "mm" else "G20", "G90"]
        if not self.mill:  # Marlin reads one command a line
            return [*units, *opt.header_lines, "M5"]
        lines = [" ".join([*units, "G17", "G94", "G40"]), *opt.header_lines]
        if self.machining.spindle > 0:
            lines.append(f"M3 S{round(self.machining.spindle)}")
            if opt.dwell > 0:
                lines.append(f"G4 P{short_number(opt.dwell)}")
        lines.append(f"G0 Z{self.num(self.machining.safe_z if safe is None else safe)}")
        return lines

    def tail(self, safe: float | None = None) -> list[str]:
        """The program's last lines: a mill rises to ``safe`` (if given), stops the
        spindle and ends with ``M2``; Marlin has no program end (``M30`` would
        delete a file from its SD card), each groove having switched the laser off."""
        if not self.mill:
            return []
        rise = [] if safe is None else [f"G0 Z{self.num(safe)}"]
        return rise + (["M5"] if self.machining.spindle > 0 else []) + ["M2"]

    def polyline(self, tip: np.ndarray, label: str, safe: float | None = None) -> list[str]:
        """One cut through the tip positions ``tip`` (k, 3), mm: a rapid over its
        start at ``safe`` (default the safe height), a plunge at the plunge
        feed, feed moves in X, Y and Z, and a rise back to ``safe``."""
        safe = self.machining.safe_z if safe is None else safe
        n = self.num
        lines = [self.comment(label), f"G0 X{n(tip[0, 0])} Y{n(tip[0, 1])}",
                 f"G1 Z{n(tip[0, 2])} F{n(self.machining.plunge)}"]
        feed = f" F{n(self.machining.feed)}"
        for x, y, z in tip[1:]:
            lines.append(f"G1 X{n(x)} Y{n(y)} Z{n(z)}{feed}")
            feed = ""
        lines.append(f"G0 Z{n(safe)}")
        return lines

    def rotary(self, x: np.ndarray, a_deg: np.ndarray, depth: float, label: str) -> list[str]:
        """One cut along a cylinder turned on an A axis: X along the axis (k,), mm,
        A (k,) in degrees (a rotary axis is not scaled by the units), at
        ``depth`` below the surface's top; the same rapid, plunge, feed and rise
        as :meth:`polyline`."""
        n = self.num
        safe = self.machining.safe_z
        lines = [self.comment(label),
                 f"G0 X{n(x[0])} Y{n(0.0)} A{format_number(a_deg[0], DECIMALS)}",
                 f"G1 Z{n(-depth)} F{n(self.machining.plunge)}"]
        feed = f" F{n(self.machining.feed)}"
        for xx, aa in zip(x[1:], a_deg[1:], strict=True):
            lines.append(f"G1 X{n(xx)} A{format_number(aa, DECIMALS)}{feed}")
            feed = ""
        lines.append(f"G0 Z{n(safe)}")
        return lines

#: Why the laser dialect is refused: these programs plunge a cutter in Z.
NO_LASER = "a laser cannot cut these programs"


def check_program_options(dialect: Any, units: Any, names: tuple[str, str] = ("--dialect",
                                                                              "--units")) -> None:
    """Refuse a dialect or unit a turning plate's, a steady image's or a
    composition's program cannot be written in, in one line naming the option
    (``names``: how the caller spells the two) and its choices: these programs
    plunge a cutter, so a mill's dialect (grbl, linuxcnc), in mm or inch."""
    if not isinstance(dialect, str) or dialect not in MILL_DIALECTS:
        raise SpecholoError(f"{names[0]} must be {' or '.join(MILL_DIALECTS)} ({NO_LASER}), "
                            f"got {repr(dialect)[:40]}")
    if not isinstance(units, str) or units not in ("mm", "inch"):
        raise SpecholoError(f"{names[1]} must be mm or inch, got {repr(units)[:40]}")


def program_options(config: Any) -> GcodeOptions:
    """The ``fabrication.programs.program.GcodeOptions`` a job's config
    (``SpinConfig``, ``SteadyConfig``, ``compose.Composition``) writes its programs with:
    its dialect and units."""
    return GcodeOptions(dialect=cast(Dialect, config.dialect), units=cast(Units, config.units))

"""An independent safety check of a G-code program before it runs on a machine.

This is a small modal interpreter of its own, sharing no code with the writer
or reader in :mod:`specholo.fabrication.programs.gcode`, so a mistake there is not
repeated here. It reads ``G0 G1 G2 G3`` (arcs by ``I J`` or ``R``, and their
``P`` as LinuxCNC runs it: ``Pn`` turns n - 1 whole circles before the arc's
end), ``G4 G17 G20 G21 G90 G91 G94``, the harmless ``G40 G49 G54 G61 G64 G80
G91.1``, ``M2 M3 M4 M5 M30`` (and coolant ``M7 M8 M9``, pauses ``M0 M1``),
``F S P N`` words and comments in parentheses or after ``;``, and, for a rotary
axis, ``A`` (degrees). Anything else is reported, since its effect is not
modelled: on an arc a ``P`` that is no whole number of turns of 1 or more
(LinuxCNC reads one within 0.001 of a whole number as that number), a ``P``
that no dwell, G64 or arc reads, and a line longer than :data:`MAX_LINE`
characters, which LinuxCNC's ``rs274`` refuses. Such a line is never held
whole (a file of one endless line is read in bounded memory), and a file
holding a NUL byte is refused outright, as no text.

The limits (:class:`Limits`) come from the job's settings, never from the
program. Three kinds of tool are told apart: a mill (ball, V-bit) cuts only
while it spins, a drag tip or scriber cuts with the spindle off, a laser cuts
wherever it is on and never goes below the surface. It reports, line by line:

- a cut (a feed move that reaches below the surface, or any move with the
  laser on) leaving the stock rectangle, arcs over their whole extent, not
  only their end points, and over their whole circle where they turn more than
  once (tool centre positions: shrink the stock by the tool radius to keep the
  groove walls inside);
- a cut deeper than ``max_depth`` (or the stock thickness) below the surface,
  whatever the tool; on a laser, any move below the surface;
- a rapid (``G0``) moving in X or Y (or turning the rotary axis) below the
  safe height, or plunging below it (on a laser: a rapid with the laser on);
- where the job hops between grooves (``Limits.hop_max``): a feed move in X or
  Y above the surface and below the safe height (a hop) longer than
  ``hop_max`` (along an arc and its turns), lower than ``hop`` above the
  surface, or leaving the stock rectangle; and the hops in a row between one
  cut and the next (or a rise to the safe height), an air path, longer than
  ``hop_max`` together, flagged at the hop where their sum passes it. Such a
  move is not a cut, so nothing else bounds it: unchecked, a "hop" could be a
  long traverse a hair above the plate and over its clamps, in one move or in
  many short ones;
- where the job cuts at one depth (``Limits.groove_depth``, a flat plate's
  grooves): a cut in X or Y at any other depth, as a hop dipping below the
  surface between two grooves would be;
- a feed outside ``feed_range``, a feed move at zero feed, a spindle (laser
  power) switched on outside ``spindle_range``, a mill cutting with the
  spindle off;
- moves from an unknown position, arcs whose end is off their circle, words
  it does not know, and moves after the program end.

The surface is the plate Z = 0, or a host's (``Limits.surface``: its height
under X, Y, for a curved host cut by a vertical tool or a cylinder on a rotary
axis, whose top stays at Z = 0 however it turns); on such a surface a move's
depth is taken at its ends and its middle, and a cut where the host is not is
reported.

Positions, units (G20 converts to mm, feeds too) and modes are followed line by
line; the moves are recorded in a table and checked together with numpy, a
block of lines at a time, each move on its own; only the air paths' lengths
run on from move to move, summed in program order as the blocks are done.
Plain motion lines and comments, nearly all of a large program, are read by a
compiled reader of their own (:mod:`._check_kernel`), the rest in Python. A
report quotes at most 60 characters of a line. Numbers are compared with a
small allowance for the written rounding (``tolerance`` on positions, 10 ppm
on rates).
"""

from __future__ import annotations

import itertools
import math
import os
import re
from array import array
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TextIO

import numpy as np

from specholo._compiling import kernel
from specholo._threads import chunked, concurrent_kernels_safe
from specholo.errors import SpecholoError
from specholo.fabrication import _check_kernel

_INCH = 25.4
# G codes times 10: plane XY, cutter compensation and tool length offsets off,
# work offset 1, path modes, canned cycles off, incremental arc centres, feed per minute
_HARMLESS_G = frozenset({170, 400, 490, 540, 610, 640, 800, 911, 940})
_HARMLESS_M = frozenset({0, 1, 7, 8, 9})
_KNOWN_LETTERS = frozenset("GMXYZIJRFSPNA")
_UNSIGNED = r"(?:\d+\.?\d*|\.\d+)"
_NUM = rf"[-+]?{_UNSIGNED}"
# the common shape of a motion line, read without the general tokenizer: one
# motion code, then axis, centre and (non-negative) feed words in this order
_PLAIN_MOVE = re.compile(rf"\s*G0*([0-3])(?:\s*X({_NUM}))?(?:\s*Y({_NUM}))?(?:\s*Z({_NUM}))?"
                         rf"(?:\s*I({_NUM}))?(?:\s*J({_NUM}))?(?:\s*F(\+?{_UNSIGNED}))?\s*")
_WORD = re.compile(rf"([A-Z])({_NUM})")
_WORDS = re.compile(rf"(?:[A-Z]{_NUM})*")
#: Relative allowance on feeds and speeds: rates written in inches come back
#: in mm/min a few ppm off.
_RATE = 1e-5


@dataclass(frozen=True)
class Stock:
    """The plate blank, mm: origin at the plate centre, top surface at Z = 0.

    Attributes:
        x0, y0: lower-left corner.
        x1, y1: upper-right corner.
        thickness: depth of the blank below its surface (no cut may reach it).
    """

    x0: float
    y0: float
    x1: float
    y1: float
    thickness: float

    def __post_init__(self) -> None:
        values = (self.x0, self.y0, self.x1, self.y1, self.thickness)
        if not all(math.isfinite(float(v)) for v in values):
            raise SpecholoError(f"stock bounds must be finite, got {values}")
        if not (self.x0 < self.x1 and self.y0 < self.y1):
            raise SpecholoError(f"stock must have x0 < x1 and y0 < y1, got {values[:4]}")
        if self.thickness <= 0:
            raise SpecholoError(f"stock thickness must be positive, got {self.thickness:g}")

    @classmethod
    def centred(cls, width: float, height: float, thickness: float) -> Stock:
        """A width x height plate centred on the origin (mm)."""
        return cls(-0.5 * width, -0.5 * height, 0.5 * width, 0.5 * height, thickness)


#: Kinds of tool the check tells apart: a mill spins to cut, a drag tip or
#: scriber cuts with the spindle off, a laser cuts with its beam and stays on
#: the surface.
TOOL_KINDS = ("mill", "drag", "laser")
#: The kind of each cutter of a design (``--tool``).
CUTTER_KINDS = {"ball": "mill", "vbit": "mill", "drag": "drag", "scriber": "drag",
                "laser": "laser"}


#: How a tip is held: ``rigid`` (it cuts at the program's Z) or ``spring`` (a
#: spring-loaded holder: Z = 0 is the tip touching the plate, the cuts run at
#: one Z below it, the preload, and the tip touches the plate wherever the
#: holder runs below its lift height).
HOLDER_KINDS = ("rigid", "spring")


def tool_kind(cutter: str, spindle: float) -> str:
    """The check's kind of tool for a cutter run at a spindle speed (rpm).

    A laser is a laser; any other cutter is a mill when the job spins it and a
    drag tip when it does not (a round engraving tip, say), so the check asks
    of the program what the job's settings say.
    """
    if cutter == "laser":
        return "laser"
    return "mill" if spindle > 0 else "drag"


@dataclass(frozen=True)
class Limits:
    """What a job allows its program to do, from the job's settings (mm, mm/min).

    Attributes:
        stock: where the tool may cut (tool centre positions) and the blank's
            thickness.
        max_depth: deepest cut below the surface, mm.
        safe_z: lowest machine Z of X/Y rapids and of rapids down, mm.
        feed_range: (lowest, highest) feed of feed moves, mm/min.
        spindle_range: (lowest, highest) spindle speed (laser power) when on.
        tool: a kind of :data:`TOOL_KINDS`.
        surface: height (mm) of the surface under points x, y (arrays, mm), NaN
            where there is none; None for the plate Z = 0.
        rotary: the program may turn a rotary axis (``A`` words).
        tolerance: rounding allowance on positions, mm.
        hop_max: longest feed move in X/Y above the surface and below the safe
            height, mm, measured along it (0: none may run there), and longest
            run of such moves between two cuts, summed; None leaves such moves
            unchecked.
        hop: lowest height above the surface of those moves, mm.
        groove_depth: the one depth below the surface (mm) of every cut moving
            in X/Y, or None for cuts at any depth down to ``max_depth``.
        holder: a kind of :data:`HOLDER_KINDS`. A spring holder's program cuts
            at ``groove_depth`` (its preload) and no feed move in X/Y may run
            below ``lift`` unless it is such a cut: there the tip is still on
            the plate, and drags across it.
        lift: a spring holder's lowest height above the surface between
            strokes, mm (None for a rigid holder).
        depths: further depths (mm) a cut in X/Y may run at besides
            ``groove_depth``: a test coupon's rungs, each at its own depth or
            preload.
    """

    stock: Stock
    max_depth: float
    safe_z: float
    feed_range: tuple[float, float]
    spindle_range: tuple[float, float]
    tool: str = "mill"
    surface: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
    rotary: bool = False
    tolerance: float = 1e-4
    hop_max: float | None = None
    hop: float = 0.0
    groove_depth: float | None = None
    holder: str = "rigid"
    lift: float | None = None
    depths: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        pairs = {"feed range": self.feed_range, "spindle range": self.spindle_range}
        for name, pair in pairs.items():
            lo, hi = (float(v) for v in pair)
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo <= hi):
                raise SpecholoError(f"{name} must be two finite numbers 0 <= low <= high, "
                                    f"got {tuple(pair)}")
            object.__setattr__(self, name.replace(" ", "_"), (lo, hi))
        for name in ("max_depth", "safe_z", "tolerance", "hop", "hop_max", "groove_depth",
                     "lift"):
            if getattr(self, name) is None:
                continue
            value = float(getattr(self, name))
            if not math.isfinite(value) or value < 0:
                raise SpecholoError(f"{name.replace('_', ' ')} must be a finite number >= 0, "
                                    f"got {value:g}")
        if self.tool not in TOOL_KINDS:
            raise SpecholoError(f"tool kind must be one of {', '.join(TOOL_KINDS)}, "
                                f"got {self.tool!r}")
        if self.holder not in HOLDER_KINDS:
            raise SpecholoError(f"holder must be one of {', '.join(HOLDER_KINDS)}, "
                                f"got {self.holder!r}")
        object.__setattr__(self, "depths", tuple(float(d) for d in self.depths))
        if any(not (math.isfinite(d) and d >= 0) for d in self.depths) or \
                (self.depths and self.groove_depth is None):
            raise SpecholoError(f"further depths need a groove depth and must be finite "
                                f"numbers >= 0, got {self.depths}")
        if self.holder == "spring" and (self.laser or self.groove_depth is None
                                        or self.lift is None or self.surface is not None):
            raise SpecholoError("a spring holder's limits need a tip that is no laser, its "
                                "cutting depth (groove depth) and its lift, on a flat plate")

    @property
    def laser(self) -> bool:
        return self.tool == "laser"

    def header(self) -> dict[str, str]:
        """The limits as ``key=value`` header lines (``check``, ``check feeds``) that
        ``specholo check FILE`` reads back (:func:`limits_from_header`); none for a
        curved host or a rotary program, whose limits are not numbers alone. The
        plate's corners are rounded outward and the depths down to 0.1 um, so the
        program passes the limits as read back as it passes these."""
        if self.surface is not None or self.rotary:
            return {}
        s = self.stock

        def num(v: float, up: bool | None = None) -> str:
            k = 1e4
            v = float(v) * k
            v = math.ceil(v) if up else math.floor(v) if up is False else round(v)
            return f"{v / k:.4f}".rstrip("0").rstrip(".")

        plate = [("x0", num(s.x0, False)), ("y0", num(s.y0, False)), ("x1", num(s.x1, True)),
                 ("y1", num(s.y1, True)), ("thickness", num(s.thickness)),
                 ("max_depth", num(self.max_depth, True)), ("safe_z", num(self.safe_z, False))]
        if self.groove_depth is not None:
            plate.append(("groove_depth", repr(float(self.groove_depth))))
        if self.depths:
            plate.append(("depths", ",".join(repr(d) for d in self.depths)))
        rest = [("feed", f"{num(self.feed_range[0], False)},{num(self.feed_range[1], True)}"),
                ("spindle", f"{num(self.spindle_range[0], False)},"
                            f"{num(self.spindle_range[1], True)}"),
                ("tool", self.tool), ("tolerance", repr(float(self.tolerance))),
                ("hop", num(self.hop, False))]
        if self.hop_max is not None:
            rest.append(("hop_max", num(self.hop_max, True)))
        if self.holder == "spring":
            rest += [("holder", self.holder), ("lift", num(self.lift or 0.0, False))]
        return {HEADER_KEY: " ".join(f"{k}={v}" for k, v in plate),
                f"{HEADER_KEY} feeds": " ".join(f"{k}={v}" for k, v in rest)}


@dataclass(frozen=True)
class Violation:
    """One thing wrong with a program line.

    Attributes:
        line: 1-based line number.
        text: the line as written (stripped), its first 60 characters at most.
        what: what is wrong, one line.
    """

    line: int
    text: str
    what: str


@dataclass
class CheckReport:
    """What :func:`check_gcode` found.

    Attributes:
        path: the program checked.
        lines: lines read.
        violations: the first ``max_listed`` violations, in line order.
        total_violations: all violations, listed or not.
        moves: moves checked by kind: ``G0``, ``G1``, ``G2``, ``G3``, ``dwell``,
            and ``cutting`` (those that cut).
        deepest: deepest cut below the surface, mm (0 on a laser).
    """

    path: str
    lines: int = 0
    violations: list[Violation] = field(default_factory=list)
    total_violations: int = 0
    moves: dict[str, int] = field(default_factory=lambda: dict.fromkeys(
        ("G0", "G1", "G2", "G3", "dwell", "cutting"), 0))
    deepest: float = 0.0

    @property
    def ok(self) -> bool:
        """True if nothing is wrong."""
        return self.total_violations == 0

    def summary(self) -> str:
        """A few lines for a person: counts, then the violations listed."""
        counts = ", ".join(f"{k} {v}" for k, v in self.moves.items())
        head = (f"{self.path}: {self.lines} lines, moves checked: {counts}; "
                f"{self.total_violations} violation(s)")
        rows = [f"  line {v.line}: {v.what}  [{v.text}]" for v in self.violations]
        if self.total_violations > len(self.violations):
            rows.append(f"  ... and {self.total_violations - len(self.violations)} more")
        return "\n".join([head, *rows])


def _within(value: float, lo: float, hi: float) -> bool:
    return lo * (1.0 - _RATE) <= value <= hi * (1.0 + _RATE)


def _strip_comments(raw: str) -> tuple[str, str | None]:
    """The line without comments, and an error message if a comment is malformed."""
    if "(" not in raw and ")" not in raw and ";" not in raw:
        return raw, None
    out = []
    depth = 0
    for c in raw:
        if depth:
            if c == ")":
                depth = 0
            elif c == "(":
                return "", "nested comment"
        elif c == "(":
            depth = 1
        elif c == ")":
            return "", "')' outside a comment"
        elif c == ";":
            break
        else:
            out.append(c)
    if depth:
        return "", "unclosed comment"
    return "".join(out), None


# Columns of the move table filled by the reader and checked at the end; _TURN
# marks a move that turns the rotary axis, _TURNS counts the whole circles an
# arc runs before its end (its P word less one, LinuxCNC's meaning).
_LINE, _KIND, _X0, _Y0, _Z0, _X1, _Y1, _Z1, _CX, _CY, _FEED, _ON, _TURN, _TURNS = range(14)
_COLS = _check_kernel.ROW


class _Reader:
    """Modal state, one line at a time: records every move for the vectorised
    checks and flags what only the line itself can tell."""

    def __init__(self, flag: Callable[[int, str], None], limits: Limits) -> None:
        self.flag_at = flag
        self.laser = limits.laser
        self.spindle_range = limits.spindle_range
        self.stock = limits.stock
        self.tol = limits.tolerance
        self.rotary = limits.rotary
        self.angle = math.nan  # of the rotary axis, degrees, NaN while unknown
        self.factor = 1.0  # mm per programmed unit
        self.absolute = True
        self.motion: int | None = None
        self.feed = math.nan  # mm/min, NaN until given
        self.speed = 0.0
        self.spindle_on = False
        self.pos = [math.nan, math.nan, math.nan]  # mm, NaN while unknown
        self.ended = False
        self.number = 0
        self.moves = array("d")  # rows of _COLS columns, see _LINE.._TURN
        self.dwells = 0
        self.burns = 0

    def flag(self, what: str) -> None:
        self.flag_at(self.number, what)

    @property
    def tool_on(self) -> bool:
        return self.spindle_on and self.speed > 0

    def line(self, number: int, raw: str) -> None:
        self.number = number
        plain = _PLAIN_MOVE.fullmatch(raw)
        if plain is not None:
            words = {k: float(v) for k, v in zip("XYZIJF", plain.groups()[1:], strict=True)
                     if v is not None}
            if "F" in words:
                self.feed = words["F"] * self.factor
            self.move(int(plain[1]), words)
            return
        body, error = _strip_comments(raw)
        if error:
            self.flag(f"cannot parse: {error}")
            return
        body = "".join(body.split()).upper()
        if body.startswith("/"):  # block delete: the line may run, so check it
            body = body[1:]
        if not body or body == "%":
            return
        if _WORDS.fullmatch(body) is None:
            self.flag("cannot parse")
            return
        g_codes: list[int] = []
        m_codes: list[int] = []
        values: dict[str, float] = {}
        for letter, number_text in _WORD.findall(body):
            value = float(number_text)
            if letter == "G":
                g_codes.append(round(value * 10))
            elif letter == "M":
                m_codes.append(round(value))
            elif letter not in _KNOWN_LETTERS or (letter == "A" and not self.rotary):
                self.flag(f"unsupported word {letter}")
                return
            elif letter in values:
                self.flag(f"{letter} given twice")
                return
            else:
                values[letter] = value
        self.execute(g_codes, m_codes, values)

    def execute(self, g_codes: list[int], m_codes: list[int], values: dict[str, float]) -> None:
        """Run one line's words in the RS274/NGC order of execution."""
        motion: int | None = None
        dwell = False
        units = self.factor
        for g in g_codes:
            if g in (0, 10, 20, 30):
                if motion is not None:
                    self.flag("two motion codes on one line")
                    return
                motion = g // 10
            elif g == 40:
                dwell = True
            elif g in (200, 210):
                units = _INCH if g == 200 else 1.0
            elif g in (900, 910):
                self.absolute = g == 900
            elif g == 800:
                self.motion = None
            elif g not in _HARMLESS_G:
                self.flag(f"unsupported G{g / 10:g}")
                return
        for m in m_codes:
            if m not in (2, 3, 4, 5, 30) and m not in _HARMLESS_M:
                self.flag(f"unsupported M{m}")
                return
        if dwell and motion in (2, 3):
            # LinuxCNC refuses the line: P would be both the dwell and the turns
            self.flag(f"G4 and G{motion} on one line: both read P")
            return
        # F is read in the units the line sets (as GRBL does), and kept in mm/min
        self.factor = units
        if "F" in values:
            if values["F"] < 0:
                self.flag(f"negative feed F{values['F']:g}")
            self.feed = values["F"] * units
        if "S" in values:
            if values["S"] < 0:
                self.flag(f"negative spindle speed S{values['S']:g}")
            self.speed = values["S"]
            if self.spindle_on and not any(m in (3, 4, 5) for m in m_codes):
                self.check_speed()
        for m in m_codes:
            if m in (3, 4):
                self.spindle_on = True
                self.check_speed()
            elif m == 5:
                self.spindle_on = False
        if dwell:
            self.dwell(values)
        # P is a dwell's time, G64's tolerance, or else an arc's number of turns
        turns = None if dwell or 640 in g_codes else values.get("P")
        self.move(motion, values, turns)
        if any(m in (2, 30) for m in m_codes):
            self.ended = True
            self.spindle_on = False

    def check_speed(self) -> None:
        lo, hi = self.spindle_range
        name = "laser power" if self.laser else "spindle speed"
        if self.speed > 0 and not _within(self.speed, lo, hi):
            self.flag(f"{name} S{self.speed:g} outside [{lo:g}, {hi:g}]")

    def dwell(self, values: dict[str, float]) -> None:
        self.dwells += 1
        if "P" not in values or values["P"] < 0:
            self.flag("dwell without a time P >= 0")
        if self.laser and self.tool_on:  # a dwell with the laser on burns a spot
            x, y = self.pos[0], self.pos[1]
            if math.isnan(x) or math.isnan(y):
                self.flag("laser fires at an unknown position")
                return
            self.burns += 1
            s, t = self.stock, self.tol
            if not (s.x0 - t <= x <= s.x1 + t and s.y0 - t <= y <= s.y1 + t):
                self.flag(_outside(s, x, y, x, y))

    def move(self, motion: int | None, values: dict[str, float],
             turns: float | None = None) -> None:
        """Record the line's move, if any; ``turns`` is its P word where no
        dwell or G64 reads it (None without one)."""
        has_axes = "X" in values or "Y" in values or "Z" in values or "A" in values
        has_arc = "I" in values or "J" in values or "R" in values
        if motion is not None:
            self.motion = motion
        if not has_axes and not has_arc:
            if turns is not None:
                self.flag("P word with no dwell or arc to read it")
            return
        kind = self.motion
        if kind is None:
            self.flag("axis words without a motion mode")
            return
        if self.ended:
            self.flag("move after the program end")
        if has_arc and kind < 2:
            self.flag(f"I/J/R words in a G{kind} move")
            return
        extra = 0.0
        if turns is not None:
            if kind < 2:
                self.flag(f"P word in a G{kind} move")
                return
            whole = round(turns)
            # LinuxCNC reads P within 0.001 of a whole number as that number
            if abs(turns - whole) > 1e-3:
                self.flag(f"arc with P{turns:g}: not a whole number of turns")
                return
            if whole < 1:
                self.flag(f"arc with P{turns:g}: fewer than one turn")
                return
            extra = float(whole - 1)
        start = self.pos
        end = list(start)
        for k, axis in enumerate("XYZ"):
            if axis in values:
                v = values[axis] * self.factor
                if not self.absolute and math.isnan(start[k]):
                    self.flag(f"incremental {axis} from an unknown position")
                    return
                end[k] = v if self.absolute else start[k] + v
        angle = self.angle
        if "A" in values:  # degrees, whatever the units
            if not self.absolute and math.isnan(angle):
                self.flag("incremental A from an unknown position")
                return
            angle = values["A"] if self.absolute else angle + values["A"]
        # from an unknown angle, any A may turn the work
        turned = 1.0 if "A" in values and not angle == self.angle else 0.0
        cx = cy = math.nan
        if kind >= 2:
            centre = self.arc_centre(start, end, values, kind == 3)
            if centre is None:
                return
            cx, cy = centre
        self.moves.extend((self.number, kind, *start, *end, cx, cy, self.feed,
                           1.0 if self.tool_on else 0.0, turned, extra))
        self.pos = end
        self.angle = angle

    def arc_centre(self, start: list[float], end: list[float], words: dict[str, float],
                   ccw: bool) -> tuple[float, float] | None:
        """Centre of this move's arc (NaN from an unknown start; None, flagged, if none)."""
        sx, sy, ex, ey = start[0], start[1], end[0], end[1]
        if "R" not in words:
            return sx + words.get("I", 0.0) * self.factor, sy + words.get("J", 0.0) * self.factor
        if "I" in words or "J" in words:
            self.flag("arc with both R and I/J")
            return None
        r = words["R"] * self.factor
        dx, dy = ex - sx, ey - sy
        chord = math.hypot(dx, dy)
        if math.isnan(chord):
            return math.nan, math.nan
        if chord == 0.0:
            self.flag("R arc with its end at its start")
            return None
        if chord > 2.0 * abs(r) + self.tol:
            self.flag(f"R {abs(r):g} too small for a chord of {chord:.5f}")
            return None
        h = math.sqrt(max(r * r - 0.25 * chord * chord, 0.0))
        # the centre of an arc up to 180 degrees lies left of the chord for G3
        # and right for G2; a negative R asks for the longer arc
        side = (1.0 if ccw else -1.0) * (1.0 if r > 0 else -1.0)
        return 0.5 * (sx + ex) - side * h * dy / chord, 0.5 * (sy + ey) + side * h * dx / chord


def _outside(s: Stock, x0: float, y0: float, x1: float, y1: float) -> str:
    return (f"cut leaves the stock: X {x0:.5f}..{x1:.5f}, Y {y0:.5f}..{y1:.5f} "
            f"outside X {s.x0:g}..{s.x1:g}, Y {s.y0:g}..{s.y1:g}")


def _arc_bounds(m: np.ndarray) -> tuple[np.ndarray, ...]:
    """XY bounds x0, y0, x1, y1 (k,) of the arcs in move rows m (k, _COLS), their
    start radius (k,) and how far their end is off it (k,).

    The bounds take the ends and every axis extreme (0, 90, 180, 270 degrees
    about the centre) the arc sweeps over, all four for an arc that turns a
    whole circle or more; the radius is the larger of start and end.
    """
    m = np.ascontiguousarray(m, dtype=float)
    out = np.empty((6, len(m)))
    chunked(_arc_bounds_rows, 0, len(m), m, out, grain=1024)
    return tuple(out)


@kernel(nogil=True)
def _arc_bounds_rows(first: int, stop: int, m: np.ndarray, out: np.ndarray) -> None:
    """:func:`_arc_bounds` of rows first .. stop - 1 (compiled, on every
    thread), into out (6, k)."""
    two_pi = 2.0 * math.pi
    for i in range(first, stop):
        sx, sy, ex, ey = m[i, _X0], m[i, _Y0], m[i, _X1], m[i, _Y1]
        cx, cy = m[i, _CX], m[i, _CY]
        r0 = math.hypot(sx - cx, sy - cy)
        r1 = math.hypot(ex - cx, ey - cy)
        r = max(r0, r1)
        a0 = math.atan2(sy - cy, sx - cx)
        turn = math.atan2(ey - cy, ex - cx) - a0
        ccw = m[i, _KIND] == 3
        if (sx == ex and sy == ey) or m[i, _TURNS] > 0:
            sweep = two_pi if ccw else -two_pi
        else:
            sweep = np.mod(turn, two_pi) if ccw else -np.mod(-turn, two_pi)
        lo, hi = min(a0, a0 + sweep), max(a0, a0 + sweep)
        x0, x1 = min(sx, ex), max(sx, ex)
        y0, y1 = min(sy, ey), max(sy, ey)
        for k in range(4):
            angle = 0.5 * math.pi * k
            # the first copy of this angle at or after the sweep's start
            if angle + two_pi * math.ceil((lo - angle) / two_pi) <= hi:
                px, py = cx + r * math.cos(angle), cy + r * math.sin(angle)
                x0, x1 = min(x0, px), max(x1, px)
                y0, y1 = min(y0, py), max(y1, py)
        out[0, i], out[1, i], out[2, i], out[3, i] = x0, y0, x1, y1
        out[4, i], out[5, i] = r0, abs(r0 - r1)


def _arc_middles(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The XY point (k,), (k,) halfway along each arc of move rows m (k, _COLS),
    its whole turns (P) included."""
    sx, sy, ex, ey, cx, cy = (m[:, c] for c in (_X0, _Y0, _X1, _Y1, _CX, _CY))
    a0 = np.arctan2(sy - cy, sx - cx)
    turn = np.arctan2(ey - cy, ex - cx) - a0
    ccw = m[:, _KIND] == 3
    sweep = np.where(ccw, np.mod(turn, 2.0 * math.pi), -np.mod(-turn, 2.0 * math.pi))
    sweep = np.where((sx == ex) & (sy == ey), np.where(ccw, 2.0, -2.0) * math.pi, sweep)
    sweep += np.where(ccw, 2.0, -2.0) * math.pi * m[:, _TURNS]
    r = np.hypot(sx - cx, sy - cy)
    half = a0 + 0.5 * sweep
    return cx + r * np.cos(half), cy + r * np.sin(half)


def _above_surface(m: np.ndarray, surface: Callable[[np.ndarray, np.ndarray], np.ndarray],
                   rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far the tool stays above a curved surface over each move, mm (n,):
    the least of its ends' and its middle's heights over the surface under them
    (NaN where unknown), and where the surface is missing under them (n,)."""
    above = np.full(len(m), np.nan)
    off = np.zeros(len(m), dtype=bool)
    r = np.flatnonzero(rows)
    if not len(r):
        return above, off
    x0, y0, z0, x1, y1, z1 = (m[r, c] for c in (_X0, _Y0, _Z0, _X1, _Y1, _Z1))
    mx, my = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    arcs = m[r, _KIND] >= 2
    if arcs.any():
        mx[arcs], my[arcs] = _arc_middles(m[r[arcs]])
    # Z goes linearly along a line and a helix: its middle is halfway
    mz = 0.5 * (z0 + z1)
    heights = [np.asarray(surface(x, y), dtype=float) for x, y in ((x0, y0), (x1, y1), (mx, my))]
    least = np.minimum(np.minimum(z0 - heights[0], z1 - heights[1]), mz - heights[2])
    above[r] = least
    off[r] = np.isnan(heights[0]) | np.isnan(heights[1]) | np.isnan(heights[2])
    return above, off


@dataclass
class _Air:
    """The moves of some rows of the move table that make or end air paths
    (see :class:`_AirPaths`), in order.

    Attributes:
        line: (k,) each move's line number.
        length: (k,) the XY length of each hop, mm (0 for a move that is none).
        ends: (k,) the move ends the air path it is in: a cut, or a move up to
            the safe height.
    """

    line: np.ndarray
    length: np.ndarray
    ends: np.ndarray


def _check_moves(m: np.ndarray, flag: Callable[[int, str], None], lim: Limits,
                 floor: float) -> tuple[int, float, _Air | None]:
    """Flag the moves (rows of the move table) that break a limit, each on its own.

    Returns:
        The number of cuts, the deepest cut below the surface (mm, 0 if none),
        and where hops are bounded, the rows' hops and path ends, for
        :class:`_AirPaths` to sum in program order (None where they are not).
    """
    kind = m[:, _KIND]
    line = m[:, _LINE].astype(np.int64)
    x0, y0, z0, x1, y1, z1 = (m[:, c] for c in (_X0, _Y0, _Z0, _X1, _Y1, _Z1))
    on = m[:, _ON] > 0
    feed = m[:, _FEED]
    laser, tol, safe_z, stock = lim.laser, lim.tolerance, lim.safe_z, lim.stock

    def each(mask: np.ndarray, message: Callable[[int], str]) -> None:
        for i in np.flatnonzero(mask):
            flag(int(line[i]), message(int(i)))

    def same(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return (a == b) | (np.isnan(a) & np.isnan(b))  # an axis never given stays put

    # turning the rotary axis moves the work under the tool as X/Y travel does
    moves_xy = ~(same(x0, x1) & same(y0, y1)) | (m[:, _TURN] > 0)
    z_known = ~(np.isnan(z0) | np.isnan(z1))
    # + 0: the sign of a zero from fmin(0, -0) varies with its place in the array
    low = np.where(z_known, np.fmin(z0, z1) + 0.0, np.nan)
    xy_known = ~(np.isnan(x0) | np.isnan(y0) | np.isnan(x1) | np.isnan(y1))
    with np.errstate(invalid="ignore"):
        rapid = kind == 0
        if laser:
            each(rapid & moves_xy & on, lambda i: "rapid with the laser on")
            # a laser works on the surface: a Z below it drives the head into the work
            lowest = np.fmin(z0, z1)
            each(lowest < -tol,
                 lambda i: f"move to Z {lowest[i]:.5f}, below the surface, on a laser")
        else:
            xy = rapid & moves_xy
            each(xy & ~z_known, lambda i: "rapid in X/Y at an unknown height")
            each(xy & (low < safe_z - tol),
                 lambda i: f"rapid in X/Y below the safe height (Z {low[i]:.5f} < {safe_z:g})")
            down = rapid & ~moves_xy & (z1 < safe_z - tol) & ~(z1 >= z0)
            each(down, lambda i: f"rapid down to Z {z1[i]:.5f}, below the safe height {safe_z:g}")

        fed = kind > 0
        lo, hi = lim.feed_range
        each(fed & np.isnan(feed), lambda i: "feed move without F")
        each(fed & (feed == 0), lambda i: "feed move with zero feed")
        rate_ok = (feed >= lo * (1.0 - _RATE)) & (feed <= hi * (1.0 + _RATE))
        each(fed & (feed > 0) & ~rate_ok,
             lambda i: f"feed {feed[i]:g} mm/min outside [{lo:g}, {hi:g}]")

        # a cutter cuts below the surface (a feed from an unknown height may);
        # a laser wherever it is on
        above, off = low, None
        if not laser and lim.surface is not None:
            above, off = _above_surface(m, lim.surface, fed & xy_known & z_known)
        cut = fed & on if laser else fed & ~(above >= 0.0)
        known = xy_known if laser else xy_known & z_known
        each(cut & ~known, lambda i: "feed move from an unknown position")
        cut &= known
        scratch = None  # a spring holder's moves below its lift that are no cut
        if not laser:
            if lim.tool == "mill":
                each(cut & ~on, lambda i: "cut with the spindle off")
            if off is None:
                each(cut & (low < floor - tol),
                     lambda i: f"cut to Z {low[i]:.5f}, deeper than {-floor:g}")
            else:
                each(cut & off, lambda i: "cut where the host has no surface")
                each(cut & (above < floor - tol),
                     lambda i: f"cut {-above[i]:.5f} below the surface, deeper than {-floor:g}")
            if lim.groove_depth is not None:
                # below the surface, an X/Y feed move is a cut whatever it was
                # meant to be: one at another depth than the grooves' is no groove
                gd = lim.groove_depth
                d0, d1 = _depths(m, lim.surface, cut & moves_xy)
                at = np.where(np.abs(d0 + gd) > np.abs(d1 + gd), d0, d1)
                off_depth = (np.abs(d0 + gd) > tol) | (np.abs(d1 + gd) > tol)
                for other in lim.depths:  # a move at one of them all along is a groove
                    off_depth &= (np.abs(d0 + other) > tol) | (np.abs(d1 + other) > tol)
                if lim.holder == "spring":
                    # a spring holder's tip is on the plate wherever the holder
                    # runs below its lift: an X/Y move there that is not a cut at
                    # the preload drags the tip across the plate
                    lift = float(lim.lift or 0.0)
                    at = np.where(cut, at, low)
                    scratch = fed & moves_xy & known & (low < lift - tol) & (off_depth | ~cut)
                    each(scratch,
                         lambda i: f"feed move in X/Y at Z {at[i]:.5f}: a spring holder's tip "
                                   f"touches the plate below the lift {lift:g} (a scratch); "
                                   f"it cuts only at Z {_levels(gd, lim.depths)}")
                else:
                    each(cut & moves_xy & off_depth,
                         lambda i: f"cut in X/Y at Z {at[i]:.5f}, not at the groove depth "
                                   f"{_levels(gd, lim.depths)}")

        # XY extent of each cut: a line on the plate only where below its surface
        sx, sy, ex, ey = x0.copy(), y0.copy(), x1.copy(), y1.copy()
        if not laser and off is None:
            enters = cut & (kind == 1) & (z0 >= 0.0)
            leaves = cut & (kind == 1) & (z1 >= 0.0) & ~enters
            t = np.where(enters | leaves, z0 / np.where(enters | leaves, z0 - z1, 1.0), 0.0)
            px, py = x0 + t * (x1 - x0), y0 + t * (y1 - y0)
            sx, sy = np.where(enters, px, sx), np.where(enters, py, sy)
            ex, ey = np.where(leaves, px, ex), np.where(leaves, py, ey)
        bx0, by0 = np.minimum(sx, ex), np.minimum(sy, ey)
        bx1, by1 = np.maximum(sx, ex), np.maximum(sy, ey)
        # arcs whole, and every arc's ends on its circle
        k = np.flatnonzero((kind >= 2) & known)
        off_circle = np.zeros(len(m), dtype=bool)
        if len(k):
            ax0, ay0, ax1, ay1, r, gap = _arc_bounds(m[k])
            # GRBL's rule, the strictest of the common controllers
            off_circle[k] = (gap > 0.005) & ((gap > 0.5) | (gap > 0.001 * r))
            bx0[k], by0[k], bx1[k], by1[k] = ax0, ay0, ax1, ay1
        each(off_circle, lambda i: "arc end is off its circle")
        cut &= ~off_circle
        s = stock
        out = cut & ((bx0 < s.x0 - tol) | (by0 < s.y0 - tol) | (bx1 > s.x1 + tol)
                     | (by1 > s.y1 + tol))
        each(out, lambda i: _outside(s, bx0[i], by0[i], bx1[i], by1[i]))
        air = None
        if not laser and lim.hop_max is not None:
            hop = fed & moves_xy & known & (above >= 0.0) & (low < safe_z - tol) & ~off_circle
            length = _check_hops(m, each, lim, hop, above, (bx0, by0, bx1, by1), scratch)
            # a cut, or a rise to the safe height, ends the way through the air
            ends = cut | (z1 >= safe_z - tol)
            rows = np.flatnonzero(hop | ends)
            air = _Air(line[rows], np.where(hop, length, 0.0)[rows], ends[rows])
        deepest = 0.0
        if not laser and cut.any():
            deepest = max(deepest, -float(np.nanmin(np.where(cut, above, np.inf))))
    return int(cut.sum()), deepest, air


def _levels(depth: float, others: tuple[float, ...]) -> str:
    """The Z (or Zs) a job's cuts run at, as a report names them."""
    return " or ".join(f"{-d:g}" for d in sorted({depth, *others}))


def _depths(m: np.ndarray, surface: Callable[[np.ndarray, np.ndarray], np.ndarray] | None,
            rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each move's Z at its start and end (n,), (n,) of move rows m, taken above
    the surface under them in the rows ``rows`` (n,) where there is one (a
    levelled plate's probed surface): a cut at one depth below a surface that is
    not flat runs at many Z."""
    z0, z1 = m[:, _Z0], m[:, _Z1]
    r = np.flatnonzero(rows)
    if surface is None or not len(r):
        return z0, z1
    d0, d1 = z0.copy(), z1.copy()
    d0[r] -= np.asarray(surface(m[r, _X0], m[r, _Y0]), dtype=float)
    d1[r] -= np.asarray(surface(m[r, _X1], m[r, _Y1]), dtype=float)
    return d0, d1


def _check_hops(m: np.ndarray, each: Callable[[np.ndarray, Callable[[int], str]], None],
                lim: Limits, hop: np.ndarray, above: np.ndarray,
                bounds: tuple[np.ndarray, ...], scratch: np.ndarray | None = None) -> np.ndarray:
    """Flag the hops (rows ``hop`` (n,) of the move table m: feed moves in X/Y
    between the surface and the safe height) that are, each on its own, too
    long, too low or off the stock; ``above`` (n,) is each move's least height
    over the surface, mm, ``bounds`` its XY extent (x0, y0, x1, y1), each (n,).
    A hop too low that a spring holder's check flagged as a scratch
    (``scratch`` (n,)) is not flagged again.

    Returns:
        (n,) each move's XY length along its path, mm.
    """
    tol, most, least = lim.tolerance, float(lim.hop_max or 0.0), lim.hop
    length = np.hypot(m[:, _X1] - m[:, _X0], m[:, _Y1] - m[:, _Y0])
    arcs = np.flatnonzero(hop & (m[:, _KIND] >= 2))
    if len(arcs):  # along the arc: its chord may be short where it swings wide
        length[arcs] = _arc_lengths(m[arcs])
    each(hop & (length > most + tol),
         lambda i: f"feed move of {length[i]:.5f} mm in X/Y between the surface and the safe "
                   f"height {lim.safe_z:g}: longer than the longest hop {most:g} mm")
    low = hop & (above < least - tol)
    if scratch is not None:
        low &= ~scratch
    each(low,
         lambda i: f"feed move in X/Y {above[i]:.5f} above the surface: below the hop height "
                   f"{least:g}")
    s = lim.stock
    x0, y0, x1, y1 = bounds
    out = hop & ((x0 < s.x0 - tol) | (y0 < s.y0 - tol) | (x1 > s.x1 + tol) | (y1 > s.y1 + tol))
    each(out, lambda i: f"hop leaves the stock: X {x0[i]:.5f}..{x1[i]:.5f}, "
                        f"Y {y0[i]:.5f}..{y1[i]:.5f} outside X {s.x0:g}..{s.x1:g}, "
                        f"Y {s.y0:g}..{s.y1:g}")
    return length


class _AirPaths:
    """The way the tool travels through the air between two cuts, summed over
    blocks of moves in program order.

    ``Limits.hop_max`` bounds a hop, and many short hops in a row travel as
    far as one long one (a drag over the plate written in 3 mm steps): the
    hops between one cut and the next, or a rise to the safe height, are an
    air path, and its XY length is bounded the same. The path is flagged once,
    at the move where its length first passes the bound, unless that move is
    itself longer and flagged on its own. Blocks of moves may split a path
    anywhere: its length so far is carried from one to the next.
    """

    def __init__(self, limits: Limits, flag: Callable[[int, str], None]) -> None:
        self.most = float(limits.hop_max or 0.0)
        self.tol = limits.tolerance
        self.safe_z = limits.safe_z
        self.flag = flag
        self.length = 0.0  # of the path the last block left open, mm
        self.hops = 0  # its hops
        self.flagged = False  # it was already found too long

    def add(self, air: _Air) -> None:
        """Sum the next rows of the program's air paths and flag those too long."""
        k = len(air.line)
        if not k:
            return
        length = air.length
        hop = length > 0.0
        # path of each row: 0 the one carried in, each end opens the next
        starts = np.zeros(k, dtype=bool)
        starts[1:] = air.ends[:-1]
        path = np.cumsum(starts)
        total, count = np.cumsum(length), np.cumsum(hop)
        first = np.flatnonzero(starts)
        # the sums before each path's first row, so a row's sum is a difference
        before = np.concatenate([[-self.length], total[first - 1]])
        hops_before = np.concatenate([[-self.hops], count[first - 1]])
        run, runs = total - before[path], count - hops_before[path]
        over = np.flatnonzero(hop & (run > self.most + self.tol))
        paths, at = np.unique(path[over], return_index=True)
        for p, i in zip(paths, over[at], strict=True):
            if (p == 0 and self.flagged) or length[i] > self.most + self.tol:
                continue
            self.flag(int(air.line[i]),
                      f"{int(runs[i])} hops in a row, {run[i]:.5f} mm in X/Y in all between "
                      f"the surface and the safe height {self.safe_z:g} (no cut or rise to it "
                      f"between): longer than the longest hop {self.most:g} mm")
        if air.ends[-1]:
            self.length, self.hops, self.flagged = 0.0, 0, False
        else:
            last = int(path[-1])
            self.length, self.hops = float(run[-1]), int(runs[-1])
            self.flagged = (self.flagged and last == 0) or (len(paths) > 0 and paths[-1] == last)


def _arc_lengths(m: np.ndarray) -> np.ndarray:
    """XY length (k,) of each arc of move rows m (k, _COLS), along its sweep and
    its whole turns (P)."""
    sx, sy, ex, ey, cx, cy = (m[:, c] for c in (_X0, _Y0, _X1, _Y1, _CX, _CY))
    a0 = np.arctan2(sy - cy, sx - cx)
    turn = np.arctan2(ey - cy, ex - cx) - a0
    ccw = m[:, _KIND] == 3
    sweep = np.where(ccw, np.mod(turn, 2.0 * math.pi), np.mod(-turn, 2.0 * math.pi))
    sweep = np.where((sx == ex) & (sy == ey), 2.0 * math.pi, sweep)  # a full circle
    return np.hypot(sx - cx, sy - cy) * (sweep + 2.0 * math.pi * m[:, _TURNS])


#: Program bytes read at a time, and most lines whose moves are checked together:
#: the check's memory stays bounded however long the program.
_READ_BYTES = 1 << 25
_BLOCK_LINES = 1 << 20
#: Longest line read, characters without its line end: LinuxCNC's rs274 refuses
#: a longer one ("Command too long"; its buffer of 255 bytes holds the line end
#: and a NUL too). A longer line is flagged and not read, and never held whole.
MAX_LINE = 252
_TOO_LONG = f"line longer than {MAX_LINE} characters (LinuxCNC reads no more): not read"
#: Most characters of a line a report quotes.
_QUOTED = 60


class _LoneReturn(Exception):
    """The program ends a line with a carriage return alone."""


class _Binary(Exception):
    """The program holds a NUL byte (on line ``args[0]``): not text at all."""


def _quote(text: str) -> str:
    """A line as a report quotes it: stripped, printable, at most _QUOTED characters."""
    text = "".join(c if c.isprintable() else "?" for c in text.strip()[:_QUOTED + 1])
    return text if len(text) <= _QUOTED else text[:_QUOTED - 3] + "..."


def _text_lines(fh: TextIO) -> Iterator[tuple[str, bool]]:
    """Each line of a text file, its line end kept, and whether it is longer
    than :data:`MAX_LINE`; of a longer line only its first MAX_LINE + 2
    characters are kept, the rest read a little at a time and dropped.

    Raises:
        _Binary: at a line that holds a NUL.
    """
    number = 0
    while True:
        line = fh.readline(MAX_LINE + 2)
        if not line:
            return
        number += 1
        if "\0" in line:
            raise _Binary(number)
        if line.endswith("\n"):
            yield line, len(line) > MAX_LINE + 1
            continue
        if len(line) <= MAX_LINE + 1:  # the last line, with no line end
            yield line, len(line) > MAX_LINE
            continue
        while True:
            rest = fh.readline(1 << 16)
            if "\0" in rest:
                raise _Binary(number)
            if not rest or rest.endswith("\n"):
                break
        yield line, True


def _read_text(path: str | os.PathLike[str], reader: _Reader,
               checked: Callable[[np.ndarray], None]) -> tuple[int, _Reader]:
    """Every line through the reader, as text; the moves checked a block at a time.

    Returns:
        The number of lines, and the reader (its counts of dwells and burns).

    Raises:
        _Binary: the program holds a NUL.
    """
    number = 0
    with open(path, encoding="ascii", errors="replace") as fh:
        for number, (raw, too_long) in enumerate(_text_lines(fh), 1):
            if too_long:
                reader.flag_at(number, _TOO_LONG)
                continue
            reader.line(number, raw)
            if len(reader.moves) >= _BLOCK_LINES * _COLS:
                checked(np.array(reader.moves, dtype=float).reshape(-1, _COLS))
                del reader.moves[:]
    checked(np.array(reader.moves, dtype=float).reshape(-1, _COLS))
    return number, reader


def _read_bytes(path: str | os.PathLike[str], reader: _Reader,
                checked: Callable[[np.ndarray], None]) -> tuple[int, _Reader]:
    """:func:`_read_text`, with the plain lines read by the compiled reader.

    The program is read in blocks of whole lines; in each, runs of plain motion
    lines and comments go through :func:`_check_kernel.plain_lines` and every
    other line through the reader, with the modal state handed between them.

    A line longer than :data:`MAX_LINE` is flagged and skipped, never held
    whole: what is kept of a line not yet ended is at most MAX_LINE + 1 bytes,
    so the memory stays a few blocks' whatever the lines.

    Raises:
        _LoneReturn: where a carriage return ends a line on its own (Python's
            text mode splits lines there, and so must this).
        _Binary: the program holds a NUL.
    """
    number = 1  # of the block's first line
    carry = b""
    skipping = False  # through the rest of a line flagged too long
    with open(path, "rb") as fh:
        while True:
            chunk = data = b""  # the last block's bytes go before the next are read
            chunk = fh.read(_READ_BYTES)
            end = not chunk
            if skipping:
                stop = chunk.find(b"\n")
                skipped = len(chunk) if stop < 0 else stop + 1
                # text mode ends a line at a "\r" unless a "\n" follows it
                if chunk.find(b"\r", 0, skipped) not in (-1, stop - 1):
                    raise _LoneReturn
                if chunk.find(b"\0", 0, skipped) >= 0:
                    raise _Binary(number)
                if stop < 0:
                    if end:
                        return number, reader
                    continue
                chunk, skipping, number = chunk[stop + 1:], False, number + 1
            data = carry + chunk
            nul = data.find(b"\0")
            if nul >= 0:
                if data.find(b"\r", 0, nul) >= 0:
                    raise _LoneReturn  # lines counted as text mode splits them
                raise _Binary(number + data.count(b"\n", 0, nul))
            if end:
                if data:
                    number = _read_block(data, number, False, reader, checked)
                return number - 1, reader
            cut = data.rfind(b"\n") + 1
            # a line not ended yet, already too long (one more for a "\r"
            # before its "\n"), is dropped, not carried
            skipping = len(data) - cut > MAX_LINE + 1
            if skipping and data.find(b"\r", cut) >= 0:
                raise _LoneReturn
            carry = b"" if skipping else data[cut:]
            if cut:
                number = _read_block(memoryview(data)[:cut], number, True, reader, checked)
            if skipping:
                reader.flag_at(number, _TOO_LONG)


def _read_block(block: bytes | memoryview, number: int, ended: bool, reader: _Reader,
                checked: Callable[[np.ndarray], None]) -> int:
    """Read and check a block of lines (``ended``: its last line has its newline).

    Returns:
        The number of the line after the block.
    """
    buf = np.frombuffer(block, dtype=np.uint8)
    returns = np.flatnonzero(buf == 13)
    if len(returns) and (returns[-1] + 1 == len(buf)
                         or np.any(buf[np.minimum(returns + 1, len(buf) - 1)] != 10)):
        raise _LoneReturn
    stops = np.flatnonzero(buf == 10)
    if not ended:
        stops = np.append(stops, len(buf))
    starts = np.concatenate([[0], stops[:-1] + 1])
    # lines too long, their "\r" before "\n" not counted (none ends the block:
    # that one would be alone)
    longer = np.flatnonzero(stops - starts > MAX_LINE)
    if len(longer):
        crlf = buf[stops[longer] - 1] == 13
        longer = longer[stops[longer] - starts[longer] - crlf > MAX_LINE]
    longer = np.append(longer, len(stops))  # so that one always lies ahead
    ahead = 0  # the next of them
    state = np.empty(6)
    for lo in range(0, len(stops), _BLOCK_LINES):
        hi = min(lo + _BLOCK_LINES, len(stops))
        moves = np.empty((hi - lo, _COLS))  # a line moves once at most
        row, i = 0, lo
        while i < hi:
            while longer[ahead] < i:
                ahead += 1
            if reader.absolute and not reader.ended:
                # the compiled reader stops short of a line too long
                bound = min(hi, int(longer[ahead]))
                state[:] = (*reader.pos, reader.feed, reader.factor,
                            -1.0 if reader.motion is None else reader.motion)
                i, row = _check_kernel.plain_lines(
                    buf, starts[:bound], stops[:bound], i, number + i,
                    1.0 if reader.tool_on else 0.0, state, moves, row)
                reader.pos = [float(v) for v in state[:3]]
                reader.feed = float(state[_check_kernel.FEED])
                reader.motion = None if state[_check_kernel.MOTION] < 0 else int(
                    state[_check_kernel.MOTION])
                if i == hi:
                    break
            if i == longer[ahead]:
                reader.flag_at(number + i, _TOO_LONG)
                i += 1
                continue
            raw = bytes(block[starts[i]:stops[i]])
            if i < len(stops) - 1 or ended:  # text mode reads "\r\n" as "\n"
                raw = (raw[:-1] if raw.endswith(b"\r") else raw) + b"\n"
            reader.line(number + i, raw.decode("ascii", errors="replace"))
            if reader.moves:
                moves[row] = reader.moves
                row += 1
                del reader.moves[:]
            i += 1
        checked(moves[:row])
    return number + len(stops)


#: Fewest rows of the move table worth splitting between two threads.
_SPLIT_ROWS = 1 << 16


#: What checking some rows of the move table found: cuts, moves by kind (4,),
#: the deepest cut (mm), the rows' hops for the air paths.
_Part = tuple[int, np.ndarray, float, _Air | None]


class _Checks:
    """Blocks of the move table checked beside the reading: each block's rows
    are split between two threads (numpy's loops and the compiled arc bounds
    release the interpreter's lock) while the next block is read. The blocks
    are checked one at a time and a line's moves are checked after the line
    was read, so every violation is flagged after those the reader flagged on
    the same line, as when checked in the reading thread. The parts' air paths
    (``air``), which run on from row to row, are summed in program order as
    each part is collected, after the part's other flags.
    """

    def __init__(self, check: Callable[[np.ndarray], _Part],
                 air: Callable[[_Air], None]) -> None:
        self.check = check
        self.air = air
        self.cuts = 0
        self.kinds = np.zeros(4, dtype=np.int64)
        self.deepest = 0.0
        self.pending: list[Future[_Part]] = []
        self.pool = ThreadPoolExecutor(2) if concurrent_kernels_safe() else None

    def __enter__(self) -> _Checks:
        return self

    def add(self, moves: np.ndarray) -> None:
        """Check a block of rows (not changed by the caller afterwards)."""
        self._collect()
        if self.pool is None or len(moves) < 2 * _SPLIT_ROWS:
            self._count(self.check(moves))
            return
        half = len(moves) // 2
        self.pending = [self.pool.submit(self.check, part) for part in (moves[:half],
                                                                       moves[half:])]

    def _count(self, result: _Part) -> None:
        self.cuts += result[0]
        self.kinds += result[1]
        self.deepest = max(self.deepest, result[2])
        if result[3] is not None:
            self.air(result[3])

    def _collect(self) -> None:
        pending, self.pending = self.pending, []
        for future in pending:
            self._count(future.result())

    def __exit__(self, kind: object, *rest: object) -> None:
        try:
            if kind is None:
                self._collect()
        finally:
            if self.pool is not None:
                self.pool.shutdown(wait=True, cancel_futures=True)


def check_gcode(path: str | os.PathLike[str], stock: Stock, max_depth: float, safe_z: float,
                feed_range: tuple[float, float], spindle_range: tuple[float, float], *,
                laser: bool = False, tolerance: float = 1e-4,
                max_listed: int = 1000, spindle: bool = True) -> CheckReport:
    """Check that a G-code program stays inside the stock and runs safely
    (:func:`check_limits` with these limits).

    Args:
        path: the program.
        stock: the blank, mm, origin at the plate centre, surface at Z = 0.
        max_depth: deepest cut allowed, mm below the surface.
        safe_z: lowest height for X/Y rapids, mm.
        feed_range: (lowest, highest) feed allowed for feed moves, mm/min.
        spindle_range: (lowest, highest) spindle speed (laser power) allowed
            when switched on.
        laser: the program drives a laser (no Z): a cut is a move with the laser
            on, rapids must have it off, and no move goes below the surface.
        spindle: the tool must spin to cut (False for a drag tip or scriber,
            which cut with the spindle off; their depth is checked all the same).
        tolerance: rounding allowance on positions, mm.
        max_listed: most violations kept in the report (all are counted).

    Raises:
        SpecholoError: if the file cannot be read or the limits are not numbers
            in order.
    """
    tool = "laser" if laser else ("mill" if spindle else "drag")
    limits = Limits(stock, max_depth, safe_z, feed_range, spindle_range, tool,
                    tolerance=tolerance)
    return check_limits(path, limits, max_listed)


def check_limits(path: str | os.PathLike[str], limits: Limits,
                 max_listed: int = 1000) -> CheckReport:
    """Check that a G-code program stays inside the limits and runs safely.

    Lines are read in order for the modal state (plain motion lines and
    comments by a compiled reader, see :mod:`._check_kernel`); the moves are
    checked together (vectorised), a block of lines at a time.

    Args:
        path: the program.
        limits: what the job allows.
        max_listed: most violations kept in the report (all are counted).

    Returns:
        The violations found, in line order, and the moves checked.

    Raises:
        SpecholoError: if the file cannot be read.
    """
    found: list[tuple[int, int, str]] = []

    def flag(number: int, what: str) -> None:
        found.append((number, len(found), what))

    # a spring holder's tip stays on the plate, however far below it the holder
    # runs: its Z is bounded by the preload alone, not by the plate's thickness
    floor = -(limits.max_depth if limits.holder == "spring"
              else min(limits.max_depth, limits.stock.thickness))
    report = CheckReport(os.fspath(path))

    def check_part(moves: np.ndarray) -> _Part:
        """Cuts, move kinds (4,), the deepest cut and the hops of some rows of
        the move table (each row checked on its own; the hops are summed later)."""
        cuts, deepest, air = _check_moves(moves, flag, limits, floor)
        kinds = np.bincount(moves[:, _KIND].astype(np.int64), minlength=4)
        return cuts, kinds, deepest, air

    from specholo.readback import open_regular

    # A FIFO would wait for a writer and a device never end: regular files only.
    os.close(open_regular(path, "G-code file")[0])
    try:
        try:
            with _Checks(check_part, _AirPaths(limits, flag).add) as checks:
                report.lines, used = _read_bytes(path, _Reader(flag, limits), checks.add)
        except _LoneReturn:  # old Mac line ends: read as text, as Python splits them
            found.clear()
            with _Checks(check_part, _AirPaths(limits, flag).add) as checks:
                report.lines, used = _read_text(path, _Reader(flag, limits), checks.add)
    except OSError as exc:
        raise SpecholoError(f"cannot read G-code file {os.fspath(path)!r}: {exc.strerror}") from exc
    except _Binary as exc:
        raise SpecholoError(_binary(path, exc.args[0])) from None
    cuts, kinds = checks.cuts, checks.kinds
    report.moves = {"G0": int(kinds[0]), "G1": int(kinds[1]), "G2": int(kinds[2]),
                    "G3": int(kinds[3]), "dwell": used.dwells, "cutting": cuts + used.burns}
    report.deepest = checks.deepest
    found.sort()
    report.total_violations = len(found)
    listed = found[:max_listed]
    wanted = {number for number, _, _ in listed}
    texts: dict[int, str] = {}
    if wanted:  # a second pass for the text of the lines listed
        with open(path, encoding="ascii", errors="replace") as fh:
            for number, (raw, _) in enumerate(_text_lines(fh), 1):
                if number in wanted:
                    texts[number] = _quote(raw)
    report.violations = [Violation(number, texts.get(number, ""), what)
                         for number, _, what in listed]
    return report


def check_program(path: str | os.PathLike[str], limits: Limits) -> CheckReport:
    """The safety check every program a job keeps passes: the report, or one
    line naming the first violation.

    Raises:
        SpecholoError: the program breaks a limit (its caller then keeps
            nothing), or cannot be read.
    """
    report = check_limits(path, limits, max_listed=1)
    if not report.ok:
        v = report.violations[0]
        more = report.total_violations - 1
        raise SpecholoError(f"the G-code failed its safety check, nothing written: line "
                            f"{v.line}: {v.what} [{v.text}]"
                            + (f" (and {more} more)" if more else ""))
    return report


def _binary(path: str | os.PathLike[str], line: int) -> str:
    return (f"{os.fspath(path)} is not a G-code program: line {line} holds a NUL byte "
            f"(a binary file?)")


#: The header comment that holds a program's own limits (see :meth:`Limits.header`).
HEADER_KEY = "check"
#: Lines of a program's head searched for it.
_HEADER_LINES = 60


def limits_from_header(path: str | os.PathLike[str]) -> Limits | None:
    """The limits a specholo program names in its header (``(check: ...)`` or
    ``; check: ...``), or None when it names none.

    Raises:
        SpecholoError: the line is there but unreadable (a changed or damaged header).
    """
    from specholo.readback import open_regular

    fd, _ = open_regular(path, "G-code file")
    with os.fdopen(fd, "r", encoding="ascii", errors="replace") as fh:
        try:
            head = [raw for raw, too_long in itertools.islice(_text_lines(fh), _HEADER_LINES)
                    if not too_long]
        except _Binary as exc:
            raise SpecholoError(_binary(path, exc.args[0])) from None
    v: dict[str, str] = {}
    for raw in head:
        line = raw.strip()
        text = line[1:-1] if line.startswith("(") and line.endswith(")") else \
            line[1:].strip() if line.startswith(";") else ""
        key, _, rest = text.partition(":")
        if key.strip().split(" ")[0] == HEADER_KEY:
            v.update(item.partition("=")[::2] for item in rest.split() if "=" in item)
    if not v:
        return None
    try:
        stock = Stock(float(v["x0"]), float(v["y0"]), float(v["x1"]), float(v["y1"]),
                      float(v["thickness"]))
        feed, spindle = (tuple(float(x) for x in v[k].split(",")) for k in ("feed", "spindle"))
        return Limits(stock, float(v["max_depth"]), float(v["safe_z"]), (feed[0], feed[1]),
                      (spindle[0], spindle[1]), v["tool"], tolerance=float(v["tolerance"]),
                      hop=float(v["hop"]),
                      hop_max=float(v["hop_max"]) if "hop_max" in v else None,
                      groove_depth=float(v["groove_depth"]) if "groove_depth" in v else None,
                      holder=v.get("holder", "rigid"),
                      lift=float(v["lift"]) if "lift" in v else None,
                      depths=tuple(float(d) for d in v["depths"].split(",")) if "depths" in v
                      else ())
    except (KeyError, ValueError, IndexError) as exc:
        raise SpecholoError(f"{os.fspath(path)}: its check lines are unreadable "
                            f"({type(exc).__name__}: {exc}); give the limits as options"
                            ) from exc

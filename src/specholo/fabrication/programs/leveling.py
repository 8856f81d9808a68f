"""Probing a plate and levelling a rigid holder's program to it.

A rigid holder cuts at the Z the program gives, so over the grooves the
plate's height must be known to about the depth's allowance (5 um on a 11 um
groove), which a hobby machine's table and a clamped blank are not flat to:
over 100 mm they are good to a few hundredths at best. The plate is probed
instead (:func:`write_probe`: a G38.2 grid over the grooves, first at the plate
zero X0 Y0), the probe's log read (:func:`read_probe_log`: GRBL's
``[PRB:x,y,z:1]`` reports or LinuxCNC's probe file) into a height map
(:class:`ProbeMap`, bilinear between the points, heights relative to X0 Y0),
and every Z of the program is offset by the height under it
(:func:`level_program`), long moves split so that their Z follows the map
within :data:`FOLLOW` (1 um). The levelled program is read back by the safety
check with the probed surface as the plate's before it is kept.

A spring holder follows the plate by itself (its spring gives way), so its
program is neither probed for nor levelled.
"""

from __future__ import annotations

import bisect
import contextlib
import math
import os
import re
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open, part_prefix, public_mode, scratch
from specholo.fabrication.exporting import format_number
from specholo.fabrication.programs.program import Emitter, GcodeOptions
from specholo.setup import Machining

if TYPE_CHECKING:
    from specholo.fabrication.check import Limits, Stock

#: Default spacing of the probe grid, mm: a plate bows and a table sags over
#: tens of mm, not over a few, so 10 mm points follow them; a 166 mm plate
#: takes 17 x 17 points, about 12 minutes at :data:`PROBE_FEED`.
PROBE_SPACING = 10.0
#: Finest and coarsest grid spacing accepted, mm.
SPACING_RANGE = (1.0, 100.0)
#: Most points a probe grid may hold (each takes a few seconds on the machine).
MAX_PROBE_POINTS = 10_000
#: Probing feed, mm/min. GRBL and LinuxCNC latch the position when the probe
#: input changes, so the feed adds only the stylus's deflection and the
#: switch's delay: at 25 mm/min (0.4 mm/s) a millisecond's delay is 0.4 um,
#: well inside the map's purpose (5 um), and a point takes about 2.5 s.
PROBE_FEED = 25.0
#: How far below Z0 a probe may go before it stops with an alarm, mm: a plate
#: whose Z0 was set on it roughly (within a few tenths) is met well before.
PROBE_REACH = 1.0
#: Largest error of the levelled program's Z from the map along a move, mm.
FOLLOW = 1e-3
#: Positions closer than this (mm) are one node of the probe grid, and the
#: grooves may reach this far past the map (whose edge height holds there:
#: a plate tilted 1:1000 changes by 0.05 um over it).
NODE_TOLERANCE = 0.05
#: The safety check's allowance on positions for a levelled program, mm: its
#: moves follow the map within FOLLOW, and are written on a grid of 10 nm.
CHECK_TOLERANCE = FOLLOW + 1e-4
#: Largest probe log read, bytes.
MAX_LOG_BYTES = 64 << 20
#: The probe program's and the levelled program's names in a design folder.
PROBE_PROGRAM = "probe.gcode"
LEVELED_PROGRAM = "hologram_leveled.gcode"
#: LinuxCNC's probe results file, as the probe program opens it.
LINUXCNC_LOG = "probe_results.txt"
#: The header line a levelled program holds in place of the check lines.
LEVELLED_KEY = "levelled"

_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_PRB = re.compile(r"\[PRB:([^\]:]*):([01])\]")
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf|infinity)"
_NUMBERS = re.compile(rf"^\s*((?:{_NUMBER})(?:[\s,;]+(?:{_NUMBER}))*)\s*$", re.IGNORECASE)


# ---------------------------------------------------------------- the program


@dataclass(frozen=True)
class _Move:
    """One motion line of a program (mm).

    Attributes:
        kind: 0 rapid, 1 line, 2 clockwise arc, 3 counter-clockwise arc.
        start, end: (x, y, z) before and after; NaN where not known yet.
        centre: (x, y) of an arc's centre, else None.
        words: the line's words (letter -> value, in the program's units).
    """

    kind: int
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    centre: tuple[float, float] | None
    words: dict[str, float]


@dataclass(frozen=True)
class ProgramInfo:
    """What a flat program says of itself.

    Attributes:
        dialect: ``grbl`` or ``linuxcnc`` (from its header).
        units: ``mm`` or ``inch`` (its G20/G21).
        cuts: (2, 2) corners of its cuts' X/Y extent (moves below the surface,
            plunges into it included), mm.
    """

    dialect: str
    units: str
    cuts: np.ndarray


def _lines(path: Path) -> Iterator[str]:
    from specholo.readback import open_regular

    fd, _ = open_regular(path, "G-code file")
    with os.fdopen(fd, "r", encoding="ascii", errors="replace") as fh:
        yield from fh


class _Reader:
    """Reads the motion lines of a specholo program (absolute, XY plane, arcs by
    I J): other words than those are refused in one line."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.pos = [math.nan, math.nan, math.nan]  # mm
        self.factor = 1.0  # mm per written unit
        self.motion = -1
        self.number = 0

    def fail(self, why: str) -> SpecholoError:
        return SpecholoError(f"{self.name} line {self.number}: {why}")

    def read(self, raw: str) -> _Move | None:
        """The line's move, or None for a line that moves nothing."""
        self.number += 1
        body = re.sub(r"\([^)]*\)", "", raw).split(";")[0].strip().upper()
        if not body:
            return None
        words: dict[str, float] = {}
        codes: list[float] = []
        rest = _WORD.sub("", body).strip()
        if rest:
            raise self.fail(f"cannot read {rest[:20]!r}")
        for letter, text in _WORD.findall(body):
            value = float(text)
            if letter == "G":
                codes.append(value)
            elif letter in words:
                raise self.fail(f"{letter} given twice")
            else:
                words[letter] = value
        for g in codes:
            if g in (0, 1, 2, 3):
                self.motion = int(g)
            elif g in (20, 21):
                self.factor = 25.4 if g == 20 else 1.0
            elif g == 91:
                raise self.fail("incremental coordinates (G91): not a specholo program")
            elif g not in (4, 17, 40, 49, 54, 61, 64, 80, 90, 94):
                raise self.fail(f"G{g:g} is not a specholo program's word")
        axes = [k for k in "XYZ" if k in words]
        if not axes:
            if "I" in words or "J" in words:
                raise self.fail("arc centre without an end point")
            return None
        if any(k in words for k in "RAP"):
            raise self.fail("R, A or P words: not a specholo program's move")
        if self.motion < 0:
            raise self.fail("axis words without a motion mode")
        start = (self.pos[0], self.pos[1], self.pos[2])
        end = list(self.pos)
        for k, axis in enumerate("XYZ"):
            if axis in words:
                end[k] = words[axis] * self.factor
        centre = None
        if self.motion >= 2:
            if math.isnan(start[0]) or math.isnan(start[1]):
                raise self.fail("arc from an unknown position")
            centre = (start[0] + words.get("I", 0.0) * self.factor,
                      start[1] + words.get("J", 0.0) * self.factor)
        elif "I" in words or "J" in words:
            raise self.fail(f"I/J words in a G{self.motion} move")
        self.pos = end
        return _Move(self.motion, start, (end[0], end[1], end[2]), centre, words)


def _arc_sweep(move: _Move) -> tuple[float, float, float, float]:
    """An arc's start angle, signed sweep (radians) and its start and end radius."""
    assert move.centre is not None
    cx, cy = move.centre
    (x0, y0, _), (x1, y1, _) = move.start, move.end
    a0, a1 = math.atan2(y0 - cy, x0 - cx), math.atan2(y1 - cy, x1 - cx)
    if move.kind == 3:
        sweep = (a1 - a0) % (2.0 * math.pi)
    else:
        sweep = -((a0 - a1) % (2.0 * math.pi))
    if sweep == 0.0:  # ends at its start: a whole circle
        sweep = 2.0 * math.pi if move.kind == 3 else -2.0 * math.pi
    return a0, sweep, math.hypot(x0 - cx, y0 - cy), math.hypot(x1 - cx, y1 - cy)


def _arc_extent(move: _Move) -> tuple[float, float, float, float]:
    """X/Y bounds (x0, y0, x1, y1) of an arc, its axis extremes included."""
    assert move.centre is not None
    cx, cy = move.centre
    a0, sweep, r0, r1 = _arc_sweep(move)
    r = max(r0, r1)
    xs = [move.start[0], move.end[0]]
    ys = [move.start[1], move.end[1]]
    lo, hi = min(a0, a0 + sweep), max(a0, a0 + sweep)
    for k in range(4):
        angle = 0.5 * math.pi * k
        if angle + 2.0 * math.pi * math.ceil((lo - angle) / (2.0 * math.pi)) <= hi:
            xs.append(cx + r * math.cos(angle))
            ys.append(cy + r * math.sin(angle))
    return min(xs), min(ys), max(xs), max(ys)


def read_program(path: str | os.PathLike[str]) -> ProgramInfo:
    """The dialect, units and cuts' extent of a flat program (:class:`ProgramInfo`).

    Raises:
        SpecholoError: the file is no specholo mill program or cuts nothing.
    """
    path = Path(path)
    reader = _Reader(str(path))
    dialect = ""
    units = "mm"
    bounds = [math.inf, math.inf, -math.inf, -math.inf]
    for raw in _lines(path):
        text = raw.strip()
        if text.startswith("(dialect:"):
            dialect = "linuxcnc" if "LinuxCNC" in text else "grbl" if "GRBL" in text else \
                "marlin"
        move = reader.read(raw)
        if reader.factor != 1.0:
            units = "inch"
        if move is None or move.kind == 0:
            continue
        (x0, y0, z0), (x1, y1, z1) = move.start, move.end
        if not min(z0, z1) < 0.0 or math.isnan(x1) or math.isnan(y1):
            continue
        # a cut, or a plunge into the plate (a dot is no more)
        ext = _arc_extent(move) if move.centre is not None else \
            (x1, y1, x1, y1) if math.isnan(x0) or (x0, y0) == (x1, y1) else \
            (min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1))
        bounds = [min(bounds[0], ext[0]), min(bounds[1], ext[1]),
                  max(bounds[2], ext[2]), max(bounds[3], ext[3])]
    if dialect == "marlin":
        raise SpecholoError(f"{path} drives a laser (Marlin): it has no Z to probe or level")
    if dialect not in ("grbl", "linuxcnc"):
        raise SpecholoError(f"{path} names no dialect in its header: not a specholo program")
    if not math.isfinite(bounds[0]):
        raise SpecholoError(f"{path} cuts nothing: nothing to probe or level")
    return ProgramInfo(dialect, units, np.array([bounds[:2], bounds[2:]]))


def rigid_limits(path: str | os.PathLike[str]) -> Limits:
    """The limits a rigid holder's program names in its header
    (:func:`~specholo.fabrication.check.limits_from_header`).

    Raises:
        SpecholoError: it names none, is a laser's, or a spring holder's (whose
            tip follows the plate: nothing to probe or level).
    """
    from specholo.fabrication.check import limits_from_header

    limits = limits_from_header(path)
    if limits is None:
        raise SpecholoError(f"{path} names no limits in its header (no check lines): probing "
                            "and levelling read a flat design's hologram.gcode")
    if limits.laser:
        raise SpecholoError(f"{path} drives a laser: it has no Z to probe or level")
    if limits.holder == "spring":
        raise SpecholoError(f"{path} is cut in a spring holder, whose tip follows the plate: "
                            "it needs no probing or levelling (its header says how to touch "
                            "off); design with --holder rigid to level a program")
    return limits


# ---------------------------------------------------------------- probing


def probe_grid(area: np.ndarray, spacing: float = PROBE_SPACING) -> tuple[np.ndarray, np.ndarray]:
    """The probe grid's X and Y positions (nx,), (ny,) over an area (2, 2), mm:
    the area's edges and evenly between them, no further apart than ``spacing``.

    Raises:
        SpecholoError: a spacing out of :data:`SPACING_RANGE` or a grid of more
            than :data:`MAX_PROBE_POINTS`.
    """
    lo, hi = SPACING_RANGE
    if not (math.isfinite(spacing) and lo <= spacing <= hi):
        raise SpecholoError(f"probe spacing {spacing:g} mm is out of range: it must be in "
                            f"[{lo:g}, {hi:g}] mm")
    axes = []
    for k in range(2):
        a, b = float(area[0, k]), float(area[1, k])
        n = max(2, math.ceil((b - a) / spacing - 1e-9) + 1)
        axes.append(np.linspace(a, b, n))
    count = len(axes[0]) * len(axes[1])
    if count > MAX_PROBE_POINTS:
        raise SpecholoError(f"a probe grid {spacing:g} mm apart over this plate has {count} "
                            f"points, more than {MAX_PROBE_POINTS}: set a larger --spacing")
    return axes[0], axes[1]


def probe_area(cuts: np.ndarray, stock: Stock) -> np.ndarray:
    """The area to probe (2, 2), mm: the cuts' extent, widened to at least 1 mm
    each way where it is narrower (two grid lines must differ), within the
    plate (``stock``: :class:`~specholo.fabrication.check.Stock`, tool centres)."""
    area = np.array(cuts, dtype=float)
    lows, highs = (stock.x0, stock.y0), (stock.x1, stock.y1)
    for k in range(2):
        short = 1.0 - (area[1, k] - area[0, k])
        if short > 0:
            area[0, k] = max(area[0, k] - 0.5 * short, lows[k])
            area[1, k] = min(area[1, k] + 0.5 * short, highs[k])
    return area


@dataclass(frozen=True)
class ProbeStats:
    """What a probe program does: its points (the grid and the plate zero), the
    grid's shape and spacing (mm), and about how long it runs (s)."""

    points: int
    shape: tuple[int, int]
    spacing: tuple[float, float]
    seconds: float


def write_probe(path: str | os.PathLike[str], area: np.ndarray, dialect: str,
                safe_z: float, spacing: float = PROBE_SPACING,
                source: str = "hologram.gcode") -> ProbeStats:
    """Write the program that probes the plate over ``area`` (2, 2), mm, atomically.

    It probes the plate zero X0 Y0 first (the levelling takes every height
    relative to it, where the cut's Z0 is set), then the grid of
    :func:`probe_grid` row by row, each row the other way. Every point is
    reached by a rapid at ``safe_z`` and probed by ``G38.2`` down to
    :data:`PROBE_REACH` below Z0 at :data:`PROBE_FEED`: a probe that touches
    nothing stops the machine with an alarm. GRBL reports each contact as
    ``[PRB:x,y,z:1]`` (machine coordinates) for the sender to log; LinuxCNC
    writes them to :data:`LINUXCNC_LOG` (``PROBEOPEN``). Written in mm.

    Raises:
        SpecholoError: a dialect that does not probe, a bad spacing or too many points.
    """
    if dialect not in ("grbl", "linuxcnc"):
        raise SpecholoError(f"probe programs are written for grbl or linuxcnc, got {dialect!r}")
    xs, ys = probe_grid(area, spacing)
    points = [(0.0, 0.0)]
    for j, y in enumerate(ys):
        row = xs if j % 2 == 0 else xs[::-1]
        points += [(float(x), float(y)) for x in row]

    def num(v: float) -> str:
        text = format_number(v, 4).rstrip("0").rstrip(".")
        return "0" if text in ("", "-0") else text

    step = (float(xs[1] - xs[0]), float(ys[1] - ys[0]))
    travel = sum(math.dist(a, b) for a, b in zip(points[:-1], points[1:], strict=True))
    # each point: down from the safe height to the plate at the probing feed and
    # back up, with the travel between points at 3000 mm/min
    seconds = len(points) * 60.0 * safe_z / PROBE_FEED + 60.0 * travel / 3000.0 \
        + len(points) * 60.0 * 2.0 * safe_z / 3000.0
    log = ("GRBL reports [PRB:x,y,z:1] in machine coordinates (mm with $13=0): save the "
           "sender's console as the log" if dialect == "grbl" else
           f"LinuxCNC writes x y z ... per point to {LINUXCNC_LOG} (where it runs)")
    # the one emitter's header and set-up, in mm (the log is), the spindle off
    # (M5 among the set-up lines: a touch probe must not turn) and no dwell
    em = Emitter(GcodeOptions(dialect=dialect, dwell=0.0,  # type: ignore[arg-type]
                              header_lines=("M5",)),
                 Machining(safe_z=safe_z, spindle=0.0))
    body = [
        f"grid: {len(ys)} rows of {len(xs)} points, {num(step[0])} x {num(step[1])} mm "
        f"apart, over X{num(xs[0])}..{num(xs[-1])} Y{num(ys[0])}..{num(ys[-1])} (the "
        f"grooves), after X0 Y0; about {max(1, round(seconds / 60.0))} min",
        "probe: a touch probe, or a conductive tool with the plate wired to the probe "
        "input; test the input first; the spindle stays off",
        f"start: X0 Y0 on the origin mark, Z0 set on the plate there to within a few tenths; "
        f"each point is reached at Z{num(safe_z)} and probed down to Z{num(-PROBE_REACH)} at "
        f"{num(PROBE_FEED)} mm/min: a probe touching nothing stops with an alarm",
        f"log: {log}; the first point is X0 Y0, whose height the others are taken from",
        "next: specholo level FOLDER LOG writes hologram_leveled.gcode; cut it with Z0 set "
        "on the plate at X0 Y0 by the cutting tool",
    ]
    lines = em.head(f"specholo probe grid of {source}", body,
                    origin="origin: plate centre; X right, Y up, Z = 0 on the plate surface")
    if dialect == "linuxcnc":
        lines.insert(len(lines) - 1, f"(PROBEOPEN {LINUXCNC_LOG})")
    for x, y in points:
        lines += [f"G0 X{em.num(x)} Y{em.num(y)}",
                  f"G38.2 Z{em.num(-PROBE_REACH)} F{em.num(PROBE_FEED)}",
                  f"G0 Z{em.num(safe_z)}"]
    if dialect == "linuxcnc":
        lines.append("(PROBECLOSE)")
    lines += em.tail()
    with atomic_open(path, "w", encoding="ascii") as fh:
        fh.write("\n".join(lines) + "\n")
    return ProbeStats(len(points), (len(ys), len(xs)), step, seconds)


# ---------------------------------------------------------------- the map


@dataclass(frozen=True)
class ProbeMap:
    """The plate's height (mm) on a grid of probed points, bilinear between
    them and held at the edge's height beyond (:data:`NODE_TOLERANCE`).

    Attributes:
        xs: (nx,) ascending X of the grid's columns, mm.
        ys: (ny,) ascending Y of its rows, mm.
        z: (ny, nx) the heights, relative to the plate zero X0 Y0, mm.
        points: how many points the log held (the plate zero among them).
    """

    xs: np.ndarray
    ys: np.ndarray
    z: np.ndarray
    points: int = 0
    # plain lists of the same: a move's few look-ups cost less than numpy's
    # per-call overhead
    _xs: list[float] = field(init=False, repr=False, compare=False, default_factory=list)
    _ys: list[float] = field(init=False, repr=False, compare=False, default_factory=list)
    _z: list[list[float]] = field(init=False, repr=False, compare=False, default_factory=list)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_xs", [float(v) for v in self.xs])
        object.__setattr__(self, "_ys", [float(v) for v in self.ys])
        object.__setattr__(self, "_z", [[float(v) for v in row] for row in self.z])

    @property
    def low(self) -> float:
        return float(self.z.min())

    @property
    def high(self) -> float:
        return float(self.z.max())

    def covers(self, area: np.ndarray) -> bool:
        """Whether the map reaches over an area (2, 2), within NODE_TOLERANCE."""
        t = NODE_TOLERANCE
        return bool(self.xs[0] - t <= area[0, 0] and area[1, 0] <= self.xs[-1] + t
                    and self.ys[0] - t <= area[0, 1] and area[1, 1] <= self.ys[-1] + t)

    def _locate(self, x: float, y: float) -> tuple[int, int, float, float]:
        """The cell (i, j) under x, y and the point's place u, v in it (clamped)."""
        xs, ys = self._xs, self._ys
        i = min(max(bisect.bisect_right(xs, x) - 1, 0), len(xs) - 2)
        j = min(max(bisect.bisect_right(ys, y) - 1, 0), len(ys) - 2)
        u = min(max((x - xs[i]) / (xs[i + 1] - xs[i]), 0.0), 1.0)
        v = min(max((y - ys[j]) / (ys[j + 1] - ys[j]), 0.0), 1.0)
        return i, j, u, v

    def height(self, x: float, y: float) -> float:
        """The plate's height under x, y, mm."""
        i, j, u, v = self._locate(x, y)
        z = self._z
        return ((z[j][i] * (1.0 - u) + z[j][i + 1] * u) * (1.0 - v)
                + (z[j + 1][i] * (1.0 - u) + z[j + 1][i + 1] * u) * v)

    def bend(self, x: float, y: float) -> tuple[float, float, float, float, float]:
        """The cell under x, y as h = h00 + a u + b v + d u v: its corner height
        h00 and a, b, d (mm), and its width and height (mm)."""
        i, j, _, _ = self._locate(x, y)
        z = self._z
        h00, h10, h01, h11 = z[j][i], z[j][i + 1], z[j + 1][i], z[j + 1][i + 1]
        return (h10 - h00, h01 - h00, h11 - h10 - h01 + h00,
                self._xs[i + 1] - self._xs[i], self._ys[j + 1] - self._ys[j])

    def surface(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Heights under points x, y (arrays, mm), NaN off the map (the safety
        check's surface)."""
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        t = NODE_TOLERANCE
        i = np.clip(np.searchsorted(self.xs, x, side="right") - 1, 0, len(self.xs) - 2)
        j = np.clip(np.searchsorted(self.ys, y, side="right") - 1, 0, len(self.ys) - 2)
        u = np.clip((x - self.xs[i]) / (self.xs[i + 1] - self.xs[i]), 0.0, 1.0)
        v = np.clip((y - self.ys[j]) / (self.ys[j + 1] - self.ys[j]), 0.0, 1.0)
        z = self.z
        h = ((z[j, i] * (1.0 - u) + z[j, i + 1] * u) * (1.0 - v)
             + (z[j + 1, i] * (1.0 - u) + z[j + 1, i + 1] * u) * v)
        on = ((x >= self.xs[0] - t) & (x <= self.xs[-1] + t) & (y >= self.ys[0] - t)
              & (y <= self.ys[-1] + t))
        return np.where(on, h, np.nan)


def _log_points(path: Path) -> tuple[np.ndarray, str]:
    """The points (n, 3) of a probe log, in order, and its kind (``grbl`` or
    ``linuxcnc``)."""
    from specholo.readback import read_bytes

    text = read_bytes(path, MAX_LOG_BYTES, "probe log").decode("ascii", errors="replace")
    rows: list[list[float]] = []
    prb = [(n, m) for n, line in enumerate(text.splitlines(), 1)
           for m in _PRB.finditer(line)]
    if prb:
        for n, m in prb:
            if m.group(2) != "1":
                raise SpecholoError(f"{path} line {n}: a probe that touched nothing "
                                    f"([PRB:...:0]): probe again")
            try:
                values = [float(v) for v in m.group(1).split(",")]
            except ValueError:
                raise SpecholoError(f"{path} line {n}: cannot read {m.group(0)[:60]!r}") from None
            if len(values) < 3:
                raise SpecholoError(f"{path} line {n}: {m.group(0)[:60]!r} has no Z")
            rows.append(values[:3])
        kind = "grbl"
    else:
        for n, line in enumerate(text.splitlines(), 1):
            body = line.split("#")[0].strip()
            if not body:
                continue
            if _NUMBERS.match(body) is None:
                raise SpecholoError(f"{path} line {n}: not a point (x y z, as LinuxCNC's probe "
                                    f"file has them, or GRBL's [PRB:x,y,z:1]): {body[:40]!r}")
            values = [float(v) for v in re.split(r"[\s,;]+", body)]
            if len(values) < 3:
                raise SpecholoError(f"{path} line {n}: {len(values)} numbers, not x y z")
            rows.append(values[:3])
        kind = "linuxcnc"
    points = np.array(rows, dtype=float).reshape(-1, 3)
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if len(bad):
        raise SpecholoError(f"{path}: point {bad[0] + 1} holds a non-finite value "
                            f"({', '.join(f'{v:g}' for v in points[bad[0]])})")
    if np.abs(points).max(initial=0.0) > 1e5:
        raise SpecholoError(f"{path}: a point lies beyond 100 m: not a probe log in mm")
    return points, kind


def _clusters(values: np.ndarray) -> np.ndarray:
    """The distinct positions (k,) among values (n,): those closer than
    NODE_TOLERANCE are one, at their mean."""
    order = np.sort(values)
    cut = np.flatnonzero(np.diff(order) > NODE_TOLERANCE) + 1
    return np.array([part.mean() for part in np.split(order, cut)])


def read_probe_log(path: str | os.PathLike[str]) -> ProbeMap:
    """The plate's height map from a probe log (:class:`ProbeMap`).

    The log is GRBL's console with its ``[PRB:x,y,z:1]`` reports (machine
    coordinates) or LinuxCNC's probe results file (x y z, then any other axes,
    per line, in the program's coordinates). Its first point is the plate zero
    X0 Y0, as the probe program probes it first: every point is taken relative
    to it (a GRBL report's machine coordinates so become the plate's). The rest
    must make a full grid (every row at every column, each within
    :data:`NODE_TOLERANCE` of its line); several points at one node are averaged.

    Raises:
        SpecholoError: in one line: an unreadable line, a non-finite value, a
            failed probe, too few points or no full grid.
    """
    path = Path(path)
    points, kind = _log_points(path)
    if len(points) < 5:
        raise SpecholoError(f"{path} holds {len(points)} probe point(s): a map needs the plate "
                            "zero X0 Y0 and a grid of at least 2 x 2 points")
    first = points[0].copy()
    if kind == "linuxcnc" and np.hypot(first[0], first[1]) > NODE_TOLERANCE:
        raise SpecholoError(f"{path}: its first point is at X{first[0]:g} Y{first[1]:g}, not the "
                            "plate zero X0 Y0 the probe program probes first")
    points = points - first
    grid = points[1:]
    xs, ys = _clusters(grid[:, 0]), _clusters(grid[:, 1])
    if len(xs) < 2 or len(ys) < 2:
        raise SpecholoError(f"{path}: its points lie on {len(xs)} column(s) and {len(ys)} "
                            "row(s): a map needs at least 2 of each")
    ref = points[0]
    on_grid = np.abs(xs - ref[0]).min() <= NODE_TOLERANCE and \
        np.abs(ys - ref[1]).min() <= NODE_TOLERANCE
    use = points if on_grid else grid
    i = np.abs(use[:, 0][:, None] - xs[None, :]).argmin(axis=1)
    j = np.abs(use[:, 1][:, None] - ys[None, :]).argmin(axis=1)
    off = (np.abs(use[:, 0] - xs[i]) > NODE_TOLERANCE) | \
        (np.abs(use[:, 1] - ys[j]) > NODE_TOLERANCE)
    if off.any():
        k = int(np.flatnonzero(off)[0])
        raise SpecholoError(f"{path}: the point at X{use[k, 0]:.3f} Y{use[k, 1]:.3f} (from the "
                            "first) lies on no row and column of the grid")
    total = np.zeros((len(ys), len(xs)))
    count = np.zeros((len(ys), len(xs)), dtype=np.int64)
    np.add.at(total, (j, i), use[:, 2])
    np.add.at(count, (j, i), 1)
    if (count == 0).any():
        jj, ii = np.argwhere(count == 0)[0]
        raise SpecholoError(f"{path}: the points make no full grid: none at X{xs[ii]:.3f} "
                            f"Y{ys[jj]:.3f} (from the first point), where {len(xs)} columns "
                            f"and {len(ys)} rows meet")
    return ProbeMap(xs, ys, total / count, len(points))


# ---------------------------------------------------------------- levelling


def _pieces_line(pmap: ProbeMap, p0: tuple[float, float], p1: tuple[float, float]
                 ) -> list[float]:
    """Where (fractions 0 < t <= 1, the last 1) to end the pieces of a straight
    move from p0 to p1 so that a Z straight along each piece follows the map
    within FOLLOW: the move is split where it crosses the grid's lines (where
    the map bends) and each part, along which the map is a quadratic a + b t +
    c t^2, into n equal pieces off it by at most |c| / (4 n^2)."""
    (x0, y0), (x1, y1) = p0, p1
    dx, dy = x1 - x0, y1 - y0
    length = math.hypot(dx, dy)
    cuts = {1.0}
    for lines, a, d in ((pmap._xs, x0, dx), (pmap._ys, y0, dy)):
        if d != 0.0:
            for g in lines:
                t = (g - a) / d
                if 0.0 < t < 1.0:
                    cuts.add(t)
    ends = _spaced(sorted(cuts), length)
    out: list[float] = []
    prev = 0.0
    for t in ends:
        h0 = pmap.height(x0 + prev * dx, y0 + prev * dy)
        hm = pmap.height(x0 + 0.5 * (prev + t) * dx, y0 + 0.5 * (prev + t) * dy)
        h1 = pmap.height(x0 + t * dx, y0 + t * dy)
        off = 0.5 * abs(h0 - 2.0 * hm + h1)  # |c| / 4 of the part's quadratic
        n = _count(off, (t - prev) * length)
        out += [prev + (t - prev) * (k + 1) / n for k in range(n)]
        prev = t
    return out


def _count(off: float, length: float) -> int:
    """Pieces of a part that bends ``off`` (mm) from its chord, each off by
    off / n^2 within FOLLOW, but none shorter than the written grid resolves."""
    n = max(1, math.ceil(math.sqrt(off / (0.9 * FOLLOW)))) if off > 0 else 1
    return max(1, min(n, int(length / _MIN_PIECE)))


#: Shortest piece of a split move, mm: its ends must differ on the written grid
#: (an arc whose ends coincide would be read as a whole circle).
_MIN_PIECE = 1e-4


def _spaced(ends: list[float], length: float) -> list[float]:
    """Ascending fractions ending in 1, none within _MIN_PIECE (mm along a move
    of ``length``) of the one before or of the move's ends."""
    out: list[float] = []
    prev = 0.0
    for t in ends:
        if (t - prev) * length >= _MIN_PIECE and ((1.0 - t) * length >= _MIN_PIECE or t == 1.0):
            out.append(t)
            prev = t
    if not out or out[-1] != 1.0:
        if out:
            out[-1] = 1.0
        else:
            out = [1.0]
    return out


def _pieces_arc(pmap: ProbeMap, centre: tuple[float, float], a0: float, sweep: float,
                r0: float, r1: float) -> list[float]:
    """Where (fractions of the sweep) to end the pieces of an arc so that a Z
    linear in its angle along each piece follows the map within FOLLOW: split
    where the circle crosses the grid's lines, then each part into pieces short
    enough for the map's bend along it (its second derivative by the angle,
    bounded from the cell's bilinear terms: linear interpolation over an angle
    w is off by at most that times w^2 / 8)."""
    cx, cy = centre
    r = max(r0, r1)
    cuts = {1.0}
    two_pi = 2.0 * math.pi
    for lines, c, trig in ((pmap._xs, cx, math.acos), (pmap._ys, cy, math.asin)):
        for g in lines:
            s = (g - c) / r
            if not -1.0 < s < 1.0:
                continue
            base = trig(s)
            # x = c + r cos(th): th = +-acos; y = c + r sin(th): th = asin, pi - asin
            for th in ((base, -base) if trig is math.acos else (base, math.pi - base)):
                turn = (th - a0) % two_pi if sweep > 0 else (a0 - th) % two_pi
                t = turn / abs(sweep)
                if 0.0 < t < 1.0:
                    cuts.add(t)
    length = abs(sweep) * r
    ends = _spaced(sorted(cuts), length)
    out: list[float] = []
    prev = 0.0
    for t in ends:
        mid = a0 + 0.5 * (prev + t) * sweep
        a, b, d, wx, wy = pmap.bend(cx + r * math.cos(mid), cy + r * math.sin(mid))
        bend = abs(a) * r / wx + abs(b) * r / wy + abs(d) * (r / wx + r / wy
                                                             + 2.0 * r * r / (wx * wy))
        width = (t - prev) * abs(sweep)
        off = bend * width * width / 8.0
        n = _count(4.0 * off, (t - prev) * length)  # _count takes |c| / 4 = off
        out += [prev + (t - prev) * (k + 1) / n for k in range(n)]
        prev = t
    return out


def _point_along(move: _Move, arc: tuple[float, float, float, float] | None,
           t: float) -> tuple[float, float]:
    """The X/Y a fraction t along a move (of its sweep for an arc, whose
    radius runs from its start's to its end's: the written ends are exact)."""
    (x0, y0, _), (x1, y1, _) = move.start, move.end
    if t == 1.0:
        return x1, y1
    if arc is None or move.centre is None:
        return x0 + t * (x1 - x0), y0 + t * (y1 - y0)
    a0, sweep, r0, r1 = arc
    th, r = a0 + t * sweep, r0 + t * (r1 - r0)
    return move.centre[0] + r * math.cos(th), move.centre[1] + r * math.sin(th)


@dataclass(frozen=True)
class Leveled:
    """What :func:`level_program` wrote: the moves split and the program's lines,
    and the map's lowest and highest height (mm)."""

    lines: int
    split: int
    low: float
    high: float


def _levelled_lines(path: Path, pmap: ProbeMap, dec: int, per_mm: float,
                    header: list[str]) -> Iterator[tuple[str, int]]:
    """The levelled program's lines, each with how many more lines its move
    was split into."""
    reader = _Reader(str(path))
    scale = 10 ** dec
    high = pmap.high
    replaced = False

    def num(mm: float) -> str:
        return format_number(mm * per_mm, dec)

    for raw in _lines(path):
        text = raw.rstrip("\n")
        stripped = text.strip()
        if stripped.startswith("(check:") or stripped.startswith("(check feeds:"):
            # the flat plate's limits no longer hold: the levelled ones follow the map
            if not replaced:
                replaced = True
                for line in header:
                    yield line, 0
            continue
        move = reader.read(raw)
        if move is None:
            yield text, 0
            continue
        (x0, y0, _), (x1, y1, z1) = move.start, move.end
        xy_known = not (math.isnan(x1) or math.isnan(y1))
        moves_xy = not (math.isnan(x0) or math.isnan(y0)) and (x0, y0) != (x1, y1)
        feed = f" F{move.words['F']:.{dec}f}" if "F" in move.words else ""
        if move.kind == 0 or not moves_xy:
            # a rapid keeps its X/Y; a Z rises or falls by the plate's height
            # under it (its highest where the position is not known yet)
            if "Z" in move.words:
                h = pmap.height(x1, y1) if xy_known else high
                words = "".join(f" {k}{num(v)}" for k, v in
                                (("X", x1), ("Y", y1)) if k in move.words)
                yield f"G{move.kind}{words} Z{num(z1 + h)}{feed}", 0
            else:
                yield text, 0
            continue
        z0n = move.start[2]
        if math.isnan(z0n) or math.isnan(z1):
            raise reader.fail("a feed move in X/Y at an unknown height")
        # the move's own Z, linear along it, plus the map's height under it
        arc = None if move.centre is None else _arc_sweep(move)
        ts = _pieces_line(pmap, (x0, y0), (x1, y1)) if arc is None or move.centre is None \
            else _pieces_arc(pmap, move.centre, *arc)
        start = (x0, y0)
        pieces = []
        for k, t in enumerate(ts):
            x, y = _point_along(move, arc, t)
            z = z0n + t * (z1 - z0n) + pmap.height(x, y)
            words = f"G{move.kind} X{num(x)} Y{num(y)} Z{num(z)}"
            if move.centre is not None:
                # the centre offset from the written start, as the writer does
                ci = round(move.centre[0] * per_mm * scale) - round(start[0] * per_mm * scale)
                cj = round(move.centre[1] * per_mm * scale) - round(start[1] * per_mm * scale)
                words += f" I{format_number(ci / scale, dec)} J{format_number(cj / scale, dec)}"
            pieces.append(words + (feed if k == 0 else ""))
            start = (x, y)
        yield pieces[0], len(pieces) - 1
        for line in pieces[1:]:
            yield line, 0
    if not replaced:
        raise SpecholoError(f"{path} names no check lines to replace: not a flat design's "
                            "program")


def level_program(src: str | os.PathLike[str], dst: str | os.PathLike[str], pmap: ProbeMap,
                  log_name: str = "the probe log",
                  check: Callable[[Path], object] | None = None) -> Leveled:
    """Write ``src`` levelled to the probed plate ``pmap`` as ``dst``: every Z
    offset by the plate's height under it, moves in X/Y split so that their Z
    follows the map within :data:`FOLLOW`; the header's check lines give way to
    lines saying what was levelled. The file appears only once ``check`` (given
    its path) has passed it: on any error nothing is written.

    Raises:
        SpecholoError: a program that is not a flat specholo mill program, a map
            that does not cover its cuts, or the check's refusal.
    """
    src, dst = Path(src), Path(dst)
    info = read_program(src)
    if not pmap.covers(info.cuts):
        (x0, y0), (x1, y1) = info.cuts
        raise SpecholoError(
            f"{log_name} covers X{pmap.xs[0]:.2f}..{pmap.xs[-1]:.2f} "
            f"Y{pmap.ys[0]:.2f}..{pmap.ys[-1]:.2f} mm, not the grooves' X{x0:.2f}..{x1:.2f} "
            f"Y{y0:.2f}..{y1:.2f}: probe with the folder's probe.gcode (specholo probe)")
    dec = 5 if info.units == "mm" else 6
    per_mm = 1.0 if info.units == "mm" else 1.0 / 25.4
    header = [
        f"({LEVELLED_KEY}: every Z follows the plate probed in {_clean(log_name)}: "
        f"{len(pmap.ys)} rows of {len(pmap.xs)} points over X{pmap.xs[0]:.2f}..{pmap.xs[-1]:.2f}"
        f" Y{pmap.ys[0]:.2f}..{pmap.ys[-1]:.2f} mm, heights {pmap.low:+.4f} to "
        f"{pmap.high:+.4f} mm from X0 Y0)",
        f"({LEVELLED_KEY}: set Z0 on the plate at X0 Y0 with the cutting tool, as the probe's "
        "first point was; the Z follows the map within 0.001 mm)",
        f"({LEVELLED_KEY}: its limits follow the probed plate, which no header line can name: "
        "specholo level checked it when it wrote it)",
    ]
    lines = split = 0
    with scratch():
        fd, tmp = tempfile.mkstemp(prefix=part_prefix(dst), suffix=".part", dir=dst.parent)
        try:
            with os.fdopen(fd, "w", encoding="ascii", newline="\n") as fh:
                for line, extra in _levelled_lines(src, pmap, dec, per_mm, header):
                    fh.write(line + "\n")
                    lines += 1 + extra
                    split += extra
                fh.flush()
                os.fsync(fh.fileno())
            public_mode(tmp)
            if check is not None:
                check(Path(tmp))
            os.replace(tmp, dst)
        except BaseException:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
            raise
    return Leveled(lines, split, pmap.low, pmap.high)


def _clean(text: str) -> str:
    """A name as a G-code comment may hold it (no parentheses, printable ASCII)."""
    clean = "".join(c if 32 <= ord(c) < 127 and c not in "()" else "?" for c in text)
    return clean[-60:]


def leveled_limits(limits: Limits, pmap: ProbeMap) -> Limits:
    """The limits of a program levelled to ``pmap``, from the flat program's
    (:class:`~specholo.fabrication.check.Limits`): depths and hop heights taken
    above the probed surface, rapids at the safe height above its lowest point
    (they keep the Z they rose to), positions within :data:`CHECK_TOLERANCE`."""
    room = limits.safe_z - limits.hop
    if pmap.high - pmap.low >= room:
        raise SpecholoError(f"the probed plate's heights span {pmap.high - pmap.low:.3f} mm, "
                            f"not less than the safe height less the hop ({room:g} mm): a "
                            "rapid could then pass below a hop; seat the plate flatter")
    return replace(limits, surface=pmap.surface, safe_z=limits.safe_z + pmap.low,
                   tolerance=max(limits.tolerance, CHECK_TOLERANCE))

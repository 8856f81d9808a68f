"""G-code for cutting grooves (read back by :mod:`specholo.fabrication.gcode_reader`).

Three dialects share one writer (:class:`GcodeOptions`):

- ``grbl`` (the default): GRBL 1.1 on a mill or engraver. Only words GRBL 1.1
  accepts: ``G0-G3 G4 G17 G20/G21 G40 G90 G94 M2 M3 M5 S F``, comments in
  parentheses, dwell ``P`` in seconds, no tool change. GRBL computes in single
  precision (24-bit mantissa, ~7 digits) and reads at most 8 significant digits
  of a number, so a far-away arc centre (``I``/``J`` beyond
  ``MAX_ARC_OFFSET_MM``) would lose the arc: such arcs are written as chords,
  one ``G1`` if the arc's sagitta is below half the coordinate grid (it is then
  straight as written), else the fewest equal chords each within that sagitta.
  GRBL itself cuts every arc as chords (sagitta up to ``$12``, 2 um by default),
  so the split is far finer than the firmware's own.
- ``linuxcnc``: RS274/NGC as LinuxCNC reads it (double precision, arcs kept).
- ``marlin``: a laser on Marlin. No Z moves (focus is set by hand): each groove
  is a rapid to its start, the laser switched on (``M3`` or ``M4`` with ``S``
  power), its arcs, and ``M5``; a dot fires the laser for ``dot_time`` with
  ``G4``. One command per line (Marlin reads only the first G/M word of a
  line), comments after ``;`` (parenthesised ones need PAREN_COMMENTS), no
  ``M2``/``M30`` (``M30`` deletes a file from the SD card in Marlin). Needs
  Marlin built with LASER_FEATURE and ARC_SUPPORT (and INCH_MODE_SUPPORT for
  inches); wide arcs are split as for GRBL.

A mill program works in absolute coordinates, the XY plane and feed per
minute, with its origin at the plate centre and Z = 0 on the plate surface.
Its header names the plate (:mod:`~specholo.fabrication.plate`): size, corners
and thickness, the registration marks of the drawings written with it (a flat
design's SVG and DXF, a turning plate's SVG), and how to set the origin on it;
comments only, after the ``check`` lines.
Each groove is cut as: a comment ``(stipple N)``, a rapid to its start at the
safe height, a plunge to ``-depth``, its arcs as ``G2``/``G3`` (centre given by
``I J`` relative to the arc's start) or ``G1`` when they are straight, and a
retract. A dot is a plunge and a retract. Where the next groove starts within
``Machining.hop_max`` of the last one's end, the retract goes up only to the
hop height ``Machining.hop`` above the surface, and the move to the next start
is a ``G1`` at the cutting feed at that height (a *hop*; a rapid never runs
below the safe height); the plunge is the same line from there. A tip in a
spring holder (:class:`~specholo.setup.Holder`) cuts at its preload below the
touch-off instead of the depth, and hops no lower than its lift.

Coordinates are written with 5 decimals in mm (10 nm), 6 in inches (25 nm: 5
would round to 0.25 um). Coarser rounding shows: a groove's glints follow its
tangent, and moving the ends of a 0.04 mm arc by 0.05 um (4 decimals in mm)
turns it by ~2e-3 rad, which doubles the image error of a design verified from
its G-code. Every number is rounded to the grid *before* the arc centres are
offset from the arc starts, so the interpreter sees exactly the rounded centre:
the two radii of an arc then differ by less than 3e-5 mm, far inside the
tolerance of LinuxCNC (and GRBL's 5 um).

Writing streams: paths are taken a chunk at a time (at most ``_CHUNK_ROWS``
vertices), so memory does not grow with the program. In a chunk each vertex
becomes one row of text (its ``(stipple N)``/rapid/plunge lines if it starts a
path, its move line otherwise, and the retract if it ends one), described by
columns of numbers and masks (:class:`TextRows`) and written by one compiled
loop, so no Python code runs per line.
"""

from __future__ import annotations

import math
import os
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from specholo._compiling import kernel
from specholo._threads import concurrent_kernels_safe
from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open
from specholo.fabrication.plate import Plate
from specholo.fabrication.program import (
    FLAT_DRAWINGS,
    MAX_ARC_OFFSET_MM,
    SCALE,
    Emitter,
    GcodeOptions,
    short_number,
)
from specholo.setup import Holder, Machining, Tool
from specholo.toolpaths.grooves import Grooves, Segments

#: Arcs are written as straight lines when they bulge less than this from their
#: chord (mm) *and* turn less than ``STRAIGHT_TURN_RAD``: glints follow the
#: tangent, so a long flat arc of a design must stay an arc.
STRAIGHT_SAGITTA_MM = 1e-5
#: Largest angle between an arc straightened and its chord (half its sweep), rad.
STRAIGHT_TURN_RAD = 1e-5
#: Arcs of smaller radius are written as straight lines (mm): LinuxCNC rejects
#: radii under 1.27 um as zero, and the rounded centre of a tinier arc could
#: turn it into a near-full circle.
MIN_ARC_RADIUS_MM = 5e-3
#: Largest sagitta of a chord that replaces (part of) a wide arc, mm: half the
#: grid, so the chords and the arc round to the same written points.
CHORD_SAGITTA_MM = 0.5 / SCALE

_CHUNK_ROWS = 1 << 16
_MAX_COORD_MM = 1e9
_MAX_CHORDS = 10**8


@dataclass(frozen=True)
class GcodeStats:
    """What a written G-code program does.

    Attributes:
        lines: number of lines in the file.
        paths: number of grooves (dots included).
        cutting_length_mm: length of all feed moves (grooves and plunges), mm.
        rapid_length_mm: length of all rapid moves (travel and retracts), mm,
            taking the job to start above the origin (plate centre).
        hops: moves between grooves made as hops (feed moves just above the surface).
        hop_length_mm: XY length of the hops, mm.
    """

    lines: int
    paths: int
    cutting_length_mm: float
    rapid_length_mm: float
    hops: int = 0
    hop_length_mm: float = 0.0


def chord_lengths(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """(k,) distances between points (k, 2): ``np.linalg.norm(end - start, axis=1)``
    to the bit, without numpy's slow reduction along rows of two."""
    d = end - start
    return np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])


def is_straight(segments: Segments) -> np.ndarray:
    """Which arcs the exporters write as straight segments.

    Args:
        segments: arcs of a set of grooves.

    Returns:
        (k,) bool: True where the arc's sagitta is below ``STRAIGHT_SAGITTA_MM``
        and half its sweep below ``STRAIGHT_TURN_RAD``, or its radius below
        ``MIN_ARC_RADIUS_MM``.
    """
    chord = chord_lengths(segments.start, segments.end)
    b = np.abs(segments.bulge)
    # chord / 2 * tan(sweep / 4) is the sagitta, chord (1 + b^2) / (4 b) the radius
    sagitta = 0.5 * chord * b
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        radius = chord * (1.0 + b * b) / (4.0 * b)
    flat = (sagitta < STRAIGHT_SAGITTA_MM) & (2.0 * np.arctan(b) < STRAIGHT_TURN_RAD)
    return flat | ~(radius >= MIN_ARC_RADIUS_MM)


class TextRows:
    """Builds n rows of ASCII text side by side, one column block at a time.

    Blocks are recorded as they are added (a text, a choice of texts, or a
    column of fixed-point numbers, each optionally left out of some rows) and
    written out row by row by one compiled loop in :meth:`tobytes`, so no Python
    code runs per row.
    """

    def __init__(self, n: int) -> None:
        self.n = n
        self._ops: list[tuple[int, int, int, int]] = []  # kind, a, b, mask column (-1: none)
        self._pool = bytearray()  # the texts of all blocks, back to back
        self._options: list[tuple[int, int]] = []  # (pool start, length) of each choice option
        self._masks: list[np.ndarray] = []
        self._columns: list[np.ndarray] = []  # choice indices and numbers, (n,) int64 each
        self._width = 0  # most bytes one row can take

    def _mask(self, mask: np.ndarray | None) -> int:
        if mask is None:
            return -1
        self._masks.append(np.asarray(mask, dtype=bool).reshape(self.n))
        return len(self._masks) - 1

    def _column(self, values: np.ndarray) -> int:
        self._columns.append(np.asarray(values, dtype=np.int64).reshape(self.n))
        return len(self._columns) - 1

    def text(self, text: str, mask: np.ndarray | None = None) -> None:
        """The same text in every row (or in the rows where ``mask`` (n,) is True)."""
        data = text.encode("ascii")
        self._ops.append((_OP_TEXT, len(self._pool), len(data), self._mask(mask)))
        self._pool += data
        self._width += len(data)

    def choice(self, options: Sequence[str], index: np.ndarray) -> None:
        """``options[index[i]]`` in row i; index (n,) ints."""
        index = np.asarray(index, dtype=np.int64)
        if self.n and not (0 <= index.min() and index.max() < len(options)):
            raise ValueError(f"choice index must be in [0, {len(options)}), got "
                             f"{index.min()} to {index.max()}")
        first = len(self._options)
        for option in options:
            data = option.encode("ascii")
            self._options.append((len(self._pool), len(data)))
            self._pool += data
        self._ops.append((_OP_CHOICE, first, self._column(index), -1))
        self._width += max(len(o) for o in options)

    def number(self, q: np.ndarray, decimals: int, mask: np.ndarray | None = None,
               trim: bool = False) -> None:
        """Fixed-point numbers given as integers q (n,) in units of 10**-decimals.

        With ``trim``, trailing zeros of the decimals are left out but for one
        (``10.0``, ``0.25``), as Python writes floats.
        """
        if not 0 <= decimals <= 18:
            raise ValueError(f"decimals must be in [0, 18], got {decimals}")
        kind = _OP_TRIMMED if trim and decimals else _OP_NUMBER
        self._ops.append((kind, decimals, self._column(q), self._mask(mask)))
        self._width += _MAX_NUMBER_BYTES

    def hex(self, q: np.ndarray, mask: np.ndarray | None = None) -> None:
        """Integers q (n,) >= 0 in upper-case hexadecimal (DXF handles)."""
        q = np.asarray(q, dtype=np.int64)
        if self.n and q.min() < 0:
            raise ValueError(f"hexadecimal numbers must be >= 0, got {q.min()}")
        self._ops.append((_OP_HEX, 0, self._column(q), self._mask(mask)))
        self._width += _MAX_NUMBER_BYTES

    def tobytes(self) -> bytes:
        """All rows, concatenated."""
        if not self._ops or self.n == 0:
            return b""
        n = self.n

        def stack(arrays: list[np.ndarray], dtype: type) -> np.ndarray:
            # (n, k): a row's values side by side
            return np.stack(arrays, axis=1).astype(dtype, copy=False) if arrays \
                else np.zeros((n, 0), dtype=dtype)

        options = np.asarray(self._options, dtype=np.int64).reshape(-1, 2)
        out = np.empty(n * self._width, dtype=np.uint8)
        size = _write_rows(n, np.asarray(self._ops, dtype=np.int64),
                           np.frombuffer(bytes(self._pool), dtype=np.uint8), options,
                           stack(self._masks, np.bool_), stack(self._columns, np.int64), out)
        return out[:size].tobytes()


_OP_TEXT, _OP_CHOICE, _OP_NUMBER, _OP_TRIMMED, _OP_HEX = 0, 1, 2, 3, 4
#: Digits of the largest int64, plus a sign and a point.
_MAX_NUMBER_BYTES = 21


@kernel(nogil=True)
def _write_rows(n: int, ops: np.ndarray, pool: np.ndarray, options: np.ndarray, masks: np.ndarray,
                columns: np.ndarray, out: np.ndarray) -> int:
    """Write the rows of a :class:`TextRows` into ``out``; returns the bytes written.

    A number q with d decimals is written like ``-12.0400``: a '-' if q < 0, the
    digits of |q| (at least d + 1 of them, so ``0.05``, never ``.05``) with the
    point before the last d; trimmed, without the trailing zeros but one
    (``-12.04``).
    """
    digits = np.empty(20, dtype=np.uint8)
    pos = 0
    for row in range(n):
        for k in range(ops.shape[0]):
            kind, a, b, m = ops[k, 0], ops[k, 1], ops[k, 2], ops[k, 3]
            if m >= 0 and not masks[row, m]:
                continue
            if kind == 0:
                for i in range(b):  # byte loops: a slice per row costs more than the copy
                    out[pos + i] = pool[a + i]
                pos += b
            elif kind == 1:
                start, length = options[a + columns[row, b], 0], options[a + columns[row, b], 1]
                for i in range(length):
                    out[pos + i] = pool[start + i]
                pos += length
            elif kind == 4:
                q = columns[row, b]
                nd = 0
                while True:
                    digit = q & 15
                    digits[nd] = 48 + digit if digit < 10 else 55 + digit
                    q >>= 4
                    nd += 1
                    if q == 0:
                        break
                for i in range(nd - 1, -1, -1):
                    out[pos] = digits[i]
                    pos += 1
            else:
                q = columns[row, b]
                if q < 0:
                    out[pos] = 45  # '-'
                    pos += 1
                    q = -q
                nd = 0
                while q >= 100:  # two digits a division
                    r = q % 100
                    q //= 100
                    digits[nd] = 48 + r % 10
                    digits[nd + 1] = 48 + r // 10
                    nd += 2
                while True:
                    digits[nd] = 48 + q % 10
                    q //= 10
                    nd += 1
                    if q == 0:
                        break
                while nd <= a:  # the units digit and the decimals always show
                    digits[nd] = 48
                    nd += 1
                skip = 0  # trailing zeros left out
                if kind == 3:
                    while skip < a - 1 and digits[skip] == 48:
                        skip += 1
                for i in range(nd - 1, skip - 1, -1):
                    out[pos] = digits[i]
                    pos += 1
                    if i == a and a > 0:
                        out[pos] = 46  # '.'
                        pos += 1
    return pos


def drawn_extent(grooves: Grooves) -> np.ndarray:
    """(2, 2) corners of the grooves' centrelines as the exporters write them:
    :meth:`~specholo.toolpaths.grooves.Grooves.extent` with the arcs they write
    straight (:func:`is_straight`) taken as their chords, so that a bulge too
    small for its radius to be a finite number does not reach infinity."""
    first, path = grooves.arcs()
    bulge = grooves.bulges[first]
    bent = np.flatnonzero(bulge != 0)
    segs = Segments(grooves.vertices[first[bent]], grooves.vertices[first[bent] + 1],
                    bulge[bent], path[bent])
    flat = bent[is_straight(segs)]
    if len(flat) == 0:
        return grooves.extent()
    bulges = np.array(grooves.bulges, dtype=float)
    bulges[first[flat]] = 0.0
    return Grooves(grooves.vertices, bulges, grooves.offsets, grooves.stipple).extent()


def check_grooves(grooves: Grooves) -> None:
    """Raise SpecholoError unless the grooves can be written (no empty path, finite numbers)."""
    if grooves.has_empty_path():
        raise SpecholoError("grooves contain an empty path")
    # the least and greatest value (NaN if any is NaN) tell, without a copy of the grooves
    ends = [float(f(a)) for a in (grooves.vertices, grooves.bulges) if np.size(a)
            for f in (np.min, np.max)]
    if not all(math.isfinite(e) for e in ends):
        raise SpecholoError("grooves contain non-finite vertices or bulges")
    if np.size(grooves.vertices) and max(-ends[0], ends[1]) > _MAX_COORD_MM:
        raise SpecholoError(f"groove vertices exceed {_MAX_COORD_MM:g} mm")


def chunk_bounds(sizes: np.ndarray, rows: int) -> np.ndarray:
    """Split consecutive paths into chunks of at most ``rows`` vertices.

    Args:
        sizes: (k,) vertices of each path.
        rows: most vertices per chunk; a longer path is a chunk of its own.

    Returns:
        (c + 1,) ascending path indices from 0 to k: chunk i holds paths
        ``bounds[i]:bounds[i + 1]``.
    """
    return _bounds_at(np.cumsum(np.asarray(sizes, dtype=np.int64)), rows)


def path_chunks(grooves: Grooves, rows: int, paths: np.ndarray | None = None) -> np.ndarray:
    """:func:`chunk_bounds` of the grooves' paths ``paths`` (k,) (default all, in
    order), read from their offsets a block at a time: no per-path temporaries
    but the result's (a million-stipple design has 38 million paths)."""
    o = np.asarray(grooves.offsets, dtype=np.int64)
    if paths is None:
        return _bounds_at(o[1:] - o[0] if len(o) and o[0] else o[1:], rows)
    ends = np.empty(len(paths), dtype=np.int64)
    total = 0
    for lo in range(0, len(paths), _BLOCK_PATHS):
        p = np.asarray(paths[lo:lo + _BLOCK_PATHS], dtype=np.int64)
        part = ends[lo:lo + len(p)]
        np.cumsum(o[p + 1] - o[p], out=part)
        part += total
        total = int(part[-1])
    return _bounds_at(ends, rows)


#: Paths whose sizes are gathered at a time by :func:`path_chunks`.
_BLOCK_PATHS = 1 << 22


def _bounds_at(ends: np.ndarray, rows: int) -> np.ndarray:
    """:func:`chunk_bounds` from each path's end (k,), counted in vertices."""
    if rows < 1:
        raise ValueError(f"rows per chunk must be at least 1, got {rows}")
    bounds = [0]
    while bounds[-1] < len(ends):
        lo = bounds[-1]
        before = int(ends[lo - 1]) if lo else 0
        bounds.append(max(int(np.searchsorted(ends, before + rows, side="right")), lo + 1))
    return np.asarray(bounds, dtype=np.int64)


T = TypeVar("T")

#: Threads that make a writer's chunks; the file is written in order as they come.
WRITER_THREADS = 2


def in_order(make: Callable[[int, int], T], bounds: np.ndarray,
             ahead: int = 4) -> Iterator[T]:
    """``make(lo, hi)`` for every chunk of ``bounds`` (c + 1,), made by
    :data:`WRITER_THREADS` threads (the compiled formatting releases the
    interpreter's lock) and yielded in chunk order, at most ``ahead`` chunks
    made before they are used. Leaving early cancels the chunks not begun.
    One thread where numba's threading layer forbids concurrent parallel
    kernels (:func:`specholo._threads.concurrent_kernels_safe`)."""
    pairs = list(zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True))
    if WRITER_THREADS < 2 or len(pairs) < 2 or not concurrent_kernels_safe():
        for lo, hi in pairs:
            yield make(lo, hi)
        return
    pool = ThreadPoolExecutor(WRITER_THREADS)
    try:
        waiting: deque[Future[T]] = deque()
        for lo, hi in pairs:
            waiting.append(pool.submit(make, lo, hi))
            if len(waiting) > ahead:
                yield waiting.popleft().result()
        while waiting:
            yield waiting.popleft().result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def slice_paths(grooves: Grooves, lo: int, hi: int) -> Grooves:
    """Paths ``lo:hi`` of the grooves as grooves of their own (views, not copies)."""
    a, b = int(grooves.offsets[lo]), int(grooves.offsets[hi])
    return Grooves(grooves.vertices[a:b], grooves.bulges[a:b],
                   np.asarray(grooves.offsets[lo:hi + 1], dtype=np.int64) - a,
                   grooves.stipple[lo:hi])


def wide_arcs(segments: Segments, max_offset: float = MAX_ARC_OFFSET_MM) -> np.ndarray:
    """Which arcs have their centre further than ``max_offset`` from their start in X or Y.

    Args:
        segments: k arcs.
        max_offset: largest ``I``/``J`` allowed, mm.

    Returns:
        (k,) bool, True for arcs (not written straight) whose ``I`` or ``J``
        would exceed ``max_offset``.
    """
    wide = np.zeros(len(segments), dtype=bool)
    if not math.isfinite(max_offset):
        return wide
    curved = np.flatnonzero(~is_straight(segments))
    centre, _, _, _ = Segments(segments.start[curved], segments.end[curved],
                               segments.bulge[curved], segments.path[curved]).geometry()
    wide[curved] = np.abs(centre - segments.start[curved]).max(axis=1, initial=0.0) > max_offset
    return wide


def split_wide_arcs(grooves: Grooves, max_offset: float = MAX_ARC_OFFSET_MM,
                    sagitta: float = CHORD_SAGITTA_MM) -> Grooves:
    """Replace the arcs whose centre lies far away by chords.

    Args:
        grooves: m vertices in n paths.
        max_offset: arcs whose ``I`` or ``J`` would exceed this (mm) are replaced.
        sagitta: largest distance between a chord and its arc, mm; an arc within
            it becomes one straight segment.

    Returns:
        The grooves with each wide arc cut into the fewest equal chords (bulge 0)
        whose sagitta is at most ``sagitta``; unchanged if there is none.
    """
    segs = grooves.segments()
    wide = wide_arcs(segs, max_offset)
    if not wide.any():
        return grooves
    w = np.flatnonzero(wide)
    start, end, b = segs.start[w], segs.end[w], segs.bulge[w]
    sweep = 4.0 * np.arctan(b)
    chord = np.linalg.norm(end - start, axis=1)
    radius = chord / (2.0 * np.abs(np.sin(0.5 * sweep)))
    # a chord of sweep phi bulges r (1 - cos(phi / 2)) = 2 r sin^2(phi / 4)
    pieces = np.ceil(np.abs(sweep) / (4.0 * np.arcsin(np.sqrt(sagitta / (2.0 * radius)))))
    pieces = np.maximum(pieces, 1)
    if pieces.sum() > _MAX_CHORDS:
        raise SpecholoError(f"wide arcs would need {pieces.sum():.3g} chords "
                            f"(more than {_MAX_CHORDS:.0e})")
    pieces = pieces.astype(np.int64)

    verts = np.asarray(grooves.vertices, dtype=float).reshape(-1, 2)
    m = len(verts)
    last = np.zeros(m, dtype=bool)
    last[grooves.offsets[1:] - 1] = True
    seg_vertex = np.flatnonzero(~last)[w]  # the vertex each wide arc starts at
    repeat = np.ones(m, dtype=np.int64)
    repeat[seg_vertex] = pieces
    old = np.repeat(np.arange(m), repeat)
    row_start = np.concatenate([[0], np.cumsum(repeat)])
    step = np.arange(len(old)) - row_start[old]  # chord number within its arc
    new_verts = verts[old]
    new_bulges = np.where(step == 0, grooves.bulges[old], 0.0)
    new_bulges[row_start[seg_vertex]] = 0.0
    inner = np.flatnonzero(step > 0)
    if len(inner):
        k = np.searchsorted(seg_vertex, old[inner])  # which wide arc
        t = step[inner] / pieces[k]
        theta = sweep[k]
        u = (end[k] - start[k]) / chord[k, None]
        # from the start, the chord to the point at fraction t of the sweep has
        # length chord sin(t theta / 2) / sin(theta / 2) and turns from the
        # tangent (the chord turned by -theta / 2) by t theta / 2
        length = chord[k] * np.sin(0.5 * t * theta) / np.sin(0.5 * theta)
        turn = 0.5 * theta * (t - 1.0)
        c, s = np.cos(turn), np.sin(turn)
        direction = np.stack([u[:, 0] * c - u[:, 1] * s, u[:, 0] * s + u[:, 1] * c], axis=1)
        new_verts[inner] = start[k] + length[:, None] * direction
    return Grooves(new_verts, new_bulges, row_start[grooves.offsets].astype(np.int64),
                   np.asarray(grooves.stipple, dtype=np.int64))


def write_gcode(
    path: str | os.PathLike[str],
    grooves: Grooves,
    tool: Tool,
    machining: Machining,
    header: dict[str, str] | None = None,
    options: GcodeOptions | None = None,
    depth: float | None = None,
    plate: Plate | None = None,
    width: float | None = None,
    drawings: Sequence[str] = FLAT_DRAWINGS,
    holder: Holder | None = None,
    cut_depths: np.ndarray | None = None,
) -> GcodeStats:
    """Write the program that cuts the grooves, atomically.

    Args:
        path: destination file.
        grooves: m vertices in n paths; path j is preceded by ``(stipple N)``
            (``; stipple N`` for Marlin) with N = ``grooves.stipple[j]``.
        tool: cutter (depth of the grooves, width for the header).
        depth: the cut's depth, mm, when it is not the round model's (a V-bit's
            or a laser's model is a small round tip inside a deeper groove).
        machining: feeds (mm/min), safe height (mm) and spindle speed (rpm; 0
            leaves the spindle alone); the laser ignores the heights and spindle.
        header: extra ``key: value`` lines for the header comments.
        options: dialect, units and the rest (default: GRBL in mm).
        plate: the plate the header names (:func:`plate_lines`); default the
            plate fitted to the grooves (:func:`~specholo.fabrication.plate.fit_plate`
            of their :func:`drawn_extent`).
        width: the groove's width at the surface, mm, when it is not the round
            model's (a drag tip's cone or a V-bit's flanks widen the groove past
            its round tip).
        drawings: the drawings written with the program, which carry the plate's
            marks (:func:`plate_lines`); a flat design's SVG and DXF by default.
        holder: how the tip is held (mill dialects): a spring holder's cuts run
            at its preload below the touch-off and it lifts to
            :meth:`~specholo.setup.Holder.lift` between strokes, and the header
            says how to touch off and set the preload; a rigid one cuts at the
            depth, as without a holder, and the header names it. None: no
            holder line, the program as it always was.
        cut_depths: (n,) the depth below the surface each path plunges to and
            cuts at, mm, where the paths differ (a test coupon's rungs, each at
            its own depth or preload; mill dialects): it replaces the depth's
            or the holder's Z, and the header gives their range.

    Returns:
        Line count, path count and move lengths (mm) of the program.

    Raises:
        SpecholoError: if the grooves hold an empty path or non-finite numbers.
    """
    opt = options or GcodeOptions()
    check_grooves(grooves)
    n_paths = grooves.n_paths
    n_dots = int(np.sum(grooves.path_sizes == 1))
    mill = opt.mill
    depth = tool.depth if depth is None else float(depth)
    width = tool.width if width is None else float(width)
    em = Emitter(opt, machining, holder if mill else None)
    # the Z the cuts run at and the hop height, as the holder needs them
    cut_depth, machining = em.cut_depth(depth)
    # each path's plunge, where they differ: one of a few Z levels per path
    levels, level_of = np.array([cut_depth]), np.zeros(n_paths, dtype=np.int64)
    if mill and cut_depths is not None:
        given = np.asarray(cut_depths, dtype=float).reshape(-1)
        if len(given) != n_paths or not (np.isfinite(given).all() and (given > 0).all()):
            raise SpecholoError(f"cut depths must be {n_paths} positive numbers, one a path")
        levels, level_of = np.unique(given, return_inverse=True)
        cut_depth = float(levels[0]) if len(levels) == 1 else cut_depth
    safe = machining.safe_z
    dec = opt.decimals
    scale = em.scale  # written integers per mm
    num = em.num
    unit = em.unit
    if mill:
        body = [f"tool: {(header or {}).get('cutter', 'ball end')}, round tip radius "
                f"{num(tool.radius)} {unit}, groove width {num(width)} {unit}",
                *em.depth_lines(depth, levels)]
    else:
        body = [f"tool: laser, {opt.laser_on} S{short_number(opt.laser_power)} while "
                f"cutting, dots fire {short_number(opt.dot_time)} s",
                f"depth: set by power and feed (design: {num(depth)} {unit}, "
                f"groove width {num(width)} {unit})"]
    body.append(f"grooves: {n_paths}, dots: {n_dots}")
    if plate is None:
        plate = Plate.fitted(drawn_extent(grooves), width)
    head = em.head("specholo specular hologram", body,
                   {k: v for k, v in (header or {}).items() if k != "cutter"}, plate, drawings)
    tail = em.tail()
    if mill:
        stipple_open, stipple_close = "(stipple ", ")\n"
        start_text = f"G1 Z{num(-cut_depth)} F{num(machining.plunge)}\n"
        start_texts = [f"G1 Z{num(-d)} F{num(machining.plunge)}\n" for d in levels]
        end_text = f"G0 Z{num(safe)}\n"
        hop_end_text = f"G0 Z{num(machining.hop)}\n"
        dot_text = ""
        rapid_text = ""
    else:
        stipple_open, stipple_close = "; stipple ", "\n"
        start_text = f"{opt.laser_on} S{short_number(opt.laser_power)}\n"
        start_texts = [start_text]
        end_text = "M5\n"
        hop_end_text = ""  # a laser has no Z: it travels by rapids with the beam off
        # Marlin's G4 takes P in milliseconds
        dot_text = f"G4 P{round(opt.dot_time * 1000)}\n" if opt.dot_time > 0 else ""
        rapid_text = f" F{num(opt.rapid_feed)}"
    feed = f" F{num(machining.feed)}"

    n_lines = len(head) + len(tail)
    cutting = rapid = hop_length = 0.0
    chords = hop_count = 0
    offsets = grooves.offsets

    def hops_onto(prev: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Which moves from ends prev (k, 2) to starts (k, 2) are hops (k,), and
        their lengths (k,): the same lengths and rule as the time estimate's."""
        air = chord_lengths(prev, starts)
        return (machining.hops(air) if mill else np.zeros(len(air), dtype=bool)), air

    def chunk(lo: int, hi: int) -> tuple[bytes, int, int, float, float, int, float]:
        """Paths lo:hi as program text: (text, lines, chords added, cutting and
        rapid length, hops and their length). Chunks are independent: the move
        onto path lo leaves from the end of path lo - 1 (the origin for the
        first), and path hi - 1 retracts for the move onto path hi."""
        part = slice_paths(grooves, lo, hi)
        rows = _move_rows(part, scale, opt.max_arc_offset)
        g = rows.grooves
        starts = part.vertices[part.offsets[:-1]]
        ends = part.vertices[part.offsets[1:] - 1]
        before = grooves.vertices[offsets[lo] - 1] if lo else np.zeros(2)
        # from the last groove's end (or the origin) to each groove's start
        hop, air = hops_onto(np.vstack([before, ends[:-1]]), starts)
        if lo == 0:
            hop[0] = False  # the job starts at the safe height
        onto_next = hi < n_paths and bool(hops_onto(
            grooves.vertices[offsets[hi] - 1][None], grooves.vertices[offsets[hi]][None])[0][0])
        m = len(g.vertices)
        hop_row = np.zeros(m, dtype=bool)  # the first vertex of a groove hopped onto
        hop_row[g.offsets[:-1][hop]] = True
        low_row = np.zeros(m, dtype=bool)  # the last vertex of a groove left by a hop
        low_row[g.offsets[1:][np.append(hop[1:], onto_next)] - 1] = True
        code = np.where(hop_row, 4, rows.code)
        texts = []
        for r in range(0, len(g.vertices), _CHUNK_ROWS):
            s = slice(r, r + _CHUNK_ROWS)
            t = TextRows(len(rows.code[s]))
            f = rows.first[s]
            t.text(stipple_open, f)
            t.number(rows.stipple[s], 0, f)
            t.choice([stipple_close + "G0", "G1", "G2", "G3", stipple_close + "G1"], code[s])
            t.text(" X")
            t.number(rows.qv[s, 0], dec)
            t.text(" Y")
            t.number(rows.qv[s, 1], dec)
            a = rows.code[s] >= 2
            t.text(" I", a)
            t.number(rows.qij[s, 0], dec, a)
            t.text(" J", a)
            t.number(rows.qij[s, 1], dec, a)
            t.text(feed, rows.second[s] | hop_row[s])  # a hop moves at the cutting feed
            if rapid_text:
                t.text(rapid_text, f)
            t.text("\n")
            if len(levels) > 1:  # the plunge of each path to its own Z
                level = np.repeat(level_of[lo:hi] + 1, np.diff(g.offsets))[s]
                t.choice(["", *start_texts], np.where(f, level, 0))
            else:
                t.text(start_text, f)
            if dot_text:
                t.text(dot_text, f & rows.last[s])
            t.text(end_text, rows.last[s] & ~low_row[s])
            if hop_end_text:
                t.text(hop_end_text, low_row[s])
            texts.append(t.tobytes())
        text = b"".join(texts)
        return (text, text.count(b"\n"), len(g.vertices) - len(part.vertices), rows.length,
                float(air[~hop].sum()), int(hop.sum()), float(air[hop].sum()))

    with atomic_open(path, "wb") as fh:
        fh.write(("\n".join(head) + "\n").encode("ascii"))
        for text, lines, added, length, travel, hops, hopped in in_order(
                chunk, path_chunks(grooves, _CHUNK_ROWS)):
            chords += added
            if chords > _MAX_CHORDS:
                raise SpecholoError(f"wide arcs would need more than {_MAX_CHORDS:.0e} chords")
            cutting += length
            rapid += travel
            hop_count += hops
            hop_length += hopped
            n_lines += lines
            fh.write(text)
        if tail:
            fh.write(("\n".join(tail) + "\n").encode("ascii"))

    # every groove plunges and retracts, from and to the hop height where a hop
    # reaches or leaves it (each hop shortens one plunge and one retract)
    plunged = float(levels[level_of].sum()) if len(levels) > 1 else n_paths * cut_depth
    vertical = n_paths * safe + plunged - hop_count * (safe - machining.hop) if mill else 0.0
    return GcodeStats(
        lines=n_lines,
        paths=n_paths,
        cutting_length_mm=cutting + vertical,
        rapid_length_mm=rapid + vertical,
        hops=hop_count,
        hop_length_mm=hop_length,
    )


@dataclass(frozen=True)
class _MoveRows:
    """The move written on each vertex's row of a program (see :func:`_move_rows`).

    Attributes:
        first: (m,) True where a path starts (comment, rapid, plunge).
        second: (m,) True on a path's second vertex (its first feed move takes ``F``).
        last: (m,) True where a path ends (retract).
        code: (m,) 0 on a path's first vertex, else the move: 1 G1, 2 G2, 3 G3.
        qv: (m, 2) the vertex, in written integers.
        qij: (m, 2) the arc centre from the arc's start (rows of G2/G3), written integers.
        stipple: (m,) stipple id of the vertex's path.
        length: total length of the moves, mm.
        grooves: the grooves written, wide arcs split (m vertices).
    """

    first: np.ndarray
    second: np.ndarray
    last: np.ndarray
    code: np.ndarray
    qv: np.ndarray
    qij: np.ndarray
    stipple: np.ndarray
    length: float
    grooves: Grooves


def _move_rows(grooves: Grooves, scale: float, max_offset: float) -> _MoveRows:
    """One row per vertex of the program that cuts the grooves.

    Args:
        grooves: n paths.
        scale: written integers per mm.
        max_offset: largest I/J, mm; arcs centred further away are split into
            chords first (:func:`split_wide_arcs`).
    """
    segs = grooves.segments()
    curved = np.flatnonzero(~is_straight(segs))
    centre, _, _, _ = Segments(segs.start[curved], segs.end[curved], segs.bulge[curved],
                               segs.path[curved]).geometry()
    # as wide_arcs, without working out the arcs twice
    offset = np.abs(centre - segs.start[curved])
    if math.isfinite(max_offset) and (np.maximum(offset[:, 0], offset[:, 1]) > max_offset).any():
        return _move_rows(split_wide_arcs(grooves, max_offset), scale, math.inf)
    verts = np.asarray(grooves.vertices, dtype=float).reshape(-1, 2)
    m = len(verts)
    offsets = np.asarray(grooves.offsets, dtype=np.int64)
    sizes = np.diff(offsets)

    first = np.zeros(m, dtype=bool)
    first[offsets[:-1]] = True
    last = np.zeros(m, dtype=bool)
    last[offsets[1:] - 1] = True
    second = np.zeros(m, dtype=bool)
    second[offsets[:-1][sizes > 1] + 1] = True

    qv = np.rint(verts * scale).astype(np.int64)
    arc_start = np.flatnonzero(~last)  # vertex where each segment starts
    rows = arc_start + 1  # the segment's move is written on its end vertex's row
    # an arc whose ends round to one point would be read as a full circle
    a, b = qv[arc_start[curved]], qv[rows[curved]]
    keep = (a[:, 0] != b[:, 0]) | (a[:, 1] != b[:, 1])
    arcs = curved[keep]
    code = np.zeros(m, dtype=np.int64)  # 0 first vertex, 1 G1, 2 G2, 3 G3
    code[rows] = 1
    code[rows[arcs]] = np.where(segs.bulge[arcs] < 0, 2, 3)
    qij = np.zeros((m, 2), dtype=np.int64)
    # the interpreter adds I J to the rounded start: offset the rounded centre from it
    qij[rows[arcs]] = np.rint(centre[keep] * scale).astype(np.int64) - qv[arc_start[arcs]]
    stipple = np.repeat(np.asarray(grooves.stipple, dtype=np.int64), sizes)
    lengths = chord_lengths(segs.start, segs.end)
    lengths[arcs] = Segments(segs.start[arcs], segs.end[arcs], segs.bulge[arcs],
                             segs.path[arcs]).lengths()
    return _MoveRows(first, second, last, code, qv, qij, stipple, float(lengths.sum()), grooves)

"""What every exporter of grooves shares: programs and drawings alike.

The G-code writer (:mod:`specholo.fabrication.programs.gcode`) and the drawings
(:mod:`specholo.fabrication.drawings.svg`, ``dxf``, the PDF patterns) write the
same grooves: each checks them first (:func:`check_grooves`), writes the arcs
too flat to matter as straight lines (:func:`is_straight`), frames the drawn
extent (:func:`drawn_extent`), streams the paths a chunk at a time in order on a
few threads (:func:`path_chunks`, :func:`in_order`) and, for the text formats,
writes each chunk's rows of numbers by one compiled loop (:class:`TextRows`).
Numbers are written by :func:`format_number` in fixed point.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TypeVar

import numpy as np

from specholo._compiling import kernel
from specholo._threads import concurrent_kernels_safe
from specholo.errors import SpecholoError
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
#: Largest coordinate a groove may have, mm (a metre is 1e3).
MAX_COORD_MM = 1e9


def format_number(value: float, decimals: int = 5) -> str:
    """Fixed-point text of a number, '.' as decimal point whatever the locale.

    Rounds half to even like the vectorised writer, and never gives ``-0.0000``.
    """
    scale = 10**decimals
    q = round(float(value) * scale)
    sign = "-" if q < 0 else ""
    whole, frac = divmod(abs(q), scale)
    return f"{sign}{whole}.{frac:0{decimals}d}" if decimals else f"{sign}{whole}"


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
    if np.size(grooves.vertices) and max(-ends[0], ends[1]) > MAX_COORD_MM:
        raise SpecholoError(f"groove vertices exceed {MAX_COORD_MM:g} mm")


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

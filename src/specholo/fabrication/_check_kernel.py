"""Compiled reading of the common lines of a G-code program for the safety check.

Most lines of a large program are plain motion lines (``G3 X.. Y.. I.. J..``)
and comments. This reads a run of them straight from the file's bytes into
the check's move table, with the modal state carried in an array, and stops
at the first line it does not take; the check's own line-by-line reader
(:class:`specholo.fabrication.check._Reader`) reads that one. A line is taken
only where it reads exactly as that reader would read it: the plain-move shape
of its regular expression (words X Y Z I J F in that order, numbers of at
most 15 digits with at most 22 after the point, which divide exactly as
``float`` rounds them), in absolute coordinates before the program end, with
no I/J on a G0/G1 move; or a line of whitespace and closed comments only.
Anything else, however harmless, is left to the reader: a ``P`` word (an arc's
number of turns) in particular, so every arc taken here runs once round at most.
"""

from __future__ import annotations

import math

import numpy as np

from specholo._compiling import kernel

#: The modal state's slots: position (mm, NaN while unknown), feed (mm/min,
#: NaN until given), mm per programmed unit, motion mode (-1 for none).
X, Y, Z, FEED, FACTOR, MOTION = range(6)
#: Columns of a move row, as the reader writes them (the last two, set to 0
#: here, mark a move that turns a rotary axis and count an arc's extra whole
#: turns: plain lines have no A or P word).
ROW = 14
_TENS = np.array([10.0**k for k in range(23)])
#: Each byte's place among the words X Y Z I J F, -1 for any other byte.
_WORD_OF = np.full(256, -1, dtype=np.int64)
_WORD_OF[np.frombuffer(b"XYZIJF", dtype=np.uint8)] = np.arange(6)
_MAX_MANTISSA = 10**14  # so a mantissa of 15 digits stays below 2^53
_NOT_TAKEN, _NOTHING = -1, -2


@kernel(helper=True)
def _space(c: int) -> bool:
    """Space, tab, line feed, vertical tab, form feed or carriage return."""
    return c == 32 or 9 <= c <= 13


@kernel()
def _number(buf: np.ndarray, i: int, b: int, signed: bool) -> tuple[float, int]:
    """The number at buf[i:] and where it ends; NaN where there is none (or it
    may not round as ``float`` would)."""
    sign = 1.0
    if i < b and (buf[i] == 43 or (signed and buf[i] == 45)):  # + or -
        sign = -1.0 if buf[i] == 45 else 1.0
        i += 1
    mantissa = 0
    digits = 0
    after = 0
    point = False
    while i < b:
        c = buf[i]
        if 48 <= c <= 57:
            if mantissa >= _MAX_MANTISSA:
                return math.nan, i
            mantissa = 10 * mantissa + (c - 48)
            digits += 1
            if point:
                after += 1
        elif c == 46 and not point:  # .
            point = True
        else:
            break
        i += 1
    if digits == 0 or after >= _TENS.size:
        return math.nan, i
    # Both exact in double, so the one division rounds as float() does.
    return sign * (float(mantissa) / _TENS[after]), i


@kernel(helper=True)
def _plain(buf: np.ndarray, a: int, b: int, words: np.ndarray) -> int:
    """Read the line buf[a:b] (its newline excluded).

    Returns:
        its motion code 0-3 with ``words`` (6,) holding X Y Z I J F (NaN where
        absent); -2 for a line of whitespace and closed comments; -1 for any
        other line.
    """
    i = a
    while i < b and _space(buf[i]):
        i += 1
    if i < b and buf[i] == 40:  # ( : only comments and whitespace may follow
        while i < b:
            c = buf[i]
            if c == 40:
                i += 1
                while i < b and buf[i] != 41:
                    if buf[i] == 40 or buf[i] > 127:
                        return _NOT_TAKEN
                    i += 1
                if i == b:
                    return _NOT_TAKEN  # unclosed
                i += 1
            elif _space(c):
                i += 1
            else:
                return _NOT_TAKEN
        return _NOTHING
    if i == b:
        return _NOTHING
    if buf[i] != 71:  # G
        return _NOT_TAKEN
    i += 1
    zeros = 0
    while i < b and buf[i] == 48:
        zeros += 1
        i += 1
    if i < b and 49 <= buf[i] <= 51:
        motion = buf[i] - 48
        i += 1
    elif zeros > 0:
        motion = 0
    else:
        return _NOT_TAKEN
    for k in range(6):
        words[k] = math.nan
    last = -1
    while True:
        while i < b and _space(buf[i]):
            i += 1
        if i == b:
            return motion
        k = _WORD_OF[buf[i]]
        if k <= last:
            return _NOT_TAKEN
        value, i = _number(buf, i + 1, b, k != 5)
        if math.isnan(value):
            return _NOT_TAKEN
        words[k] = value
        last = k
        # A word must end at whitespace, the next word or the line's end.
        if i < b and not _space(buf[i]) and _WORD_OF[buf[i]] < 0:
            return _NOT_TAKEN


@kernel()
def plain_lines(buf: np.ndarray, starts: np.ndarray, stops: np.ndarray, first: int,
                number: int, tool_on: float, state: np.ndarray, out: np.ndarray,
                row: int) -> tuple[int, int]:
    """Take lines first, first + 1, ... of ``buf`` until one is not taken.

    Args:
        buf: (n,) uint8, the program's bytes.
        starts, stops: (lines,) each line's bytes, newline excluded.
        first: the first line to read; ``number`` its 1-based number in the file.
        tool_on: 1.0 while the spindle (laser) is on, else 0.0.
        state: (6,) the modal state (see :data:`X` ..), updated in place.
        out: (m, ROW) the move table; rows from ``row`` on are written.

    Returns:
        The first line not taken (``starts.size`` if all were) and the next free row.
    """
    words = np.empty(6)
    i = first
    while i < starts.size:
        motion = _plain(buf, starts[i], stops[i], words)
        if motion == _NOT_TAKEN:
            break
        if motion == _NOTHING:
            i += 1
            continue
        arc = not (math.isnan(words[3]) and math.isnan(words[4]))
        if arc and motion < 2:
            break  # flagged by the reader
        factor = state[FACTOR]
        if not math.isnan(words[5]):
            state[FEED] = words[5] * factor
        state[MOTION] = motion
        if math.isnan(words[0]) and math.isnan(words[1]) and math.isnan(words[2]) and not arc:
            i += 1
            continue
        sx, sy, sz = state[X], state[Y], state[Z]
        ex = sx if math.isnan(words[0]) else words[0] * factor
        ey = sy if math.isnan(words[1]) else words[1] * factor
        ez = sz if math.isnan(words[2]) else words[2] * factor
        cx = cy = math.nan
        if motion >= 2:
            cx = sx + (0.0 if math.isnan(words[3]) else words[3]) * factor
            cy = sy + (0.0 if math.isnan(words[4]) else words[4]) * factor
        r = out[row]
        r[0], r[1], r[2], r[3], r[4], r[5], r[6] = number + (i - first), motion, sx, sy, sz, ex, ey
        r[7], r[8], r[9], r[10], r[11] = ez, cx, cy, state[FEED], tool_on
        r[12] = r[13] = 0.0
        row += 1
        state[X], state[Y], state[Z] = ex, ey, ez
        i += 1
    return i, row

"""Reading G-code back into grooves: what a program will cut, for verification.

:func:`read_gcode` reads the programs :mod:`specholo.fabrication.programs.gcode` writes
(and other plain 3-axis programs of G0-G3 moves): every cutting move below the
surface becomes a groove's arc, with the stipple named in its ``(stipple N)``
comment, so the simulator can verify the file that will be cut. A laser's
program (no Z word at all) cuts where its beam is on: feed moves between
``M3``/``M4`` and ``M5``, and a dot where the beam comes on and goes off in
place, each with the stipple of its ``; stipple N`` comment.
"""

from __future__ import annotations

import io
import math
import os
import re
from operator import itemgetter

import numpy as np

from specholo.errors import SpecholoError
from specholo.toolpaths.grooves import Grooves

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)"
_WORD = re.compile(rf"([A-Z])\s*({_NUMBER})", re.ASCII)
_COMMENT = re.compile(r"\(([^()]*)\)")
_STIPPLE = re.compile(r"\s*stipple\s+([-+]?\d+)\s*", re.IGNORECASE)
# write_gcode's own move lines, read without the general tokenizer
_FAST_MOVE = re.compile(
    rf"G([0-3])(?= [XYZ])(?: X({_NUMBER}))?(?: Y({_NUMBER}))?(?: Z({_NUMBER}))?"
    rf"(?: I({_NUMBER}) J({_NUMBER}))?(?: F{_NUMBER})?\s*",
    re.ASCII,
)
_IGNORED_WORDS = frozenset("FSPTNHDQ")
# G codes (times 10) that change nothing read_gcode models: plane XY, absolute
# distances, cutter compensation and tool length offsets off, work offset 1, path
# blending, feed modes, dwell, incremental arc centres, spindle and canned-cycle modes.
_IGNORED_G = frozenset({40, 170, 400, 490, 540, 610, 611, 640, 900, 911,
                        930, 940, 950, 960, 970, 980, 990})
_NAN = math.nan
# Largest number read_gcode accepts in a word, and largest stipple id: a metre
# of travel is 1e3 mm, so 1e9 leaves every sum and square finite.
_MAX_WORD = 1e9
_MAX_STIPPLE = 2**63 - 1


def _line_error(number: int, raw: str, why: str) -> SpecholoError:
    return SpecholoError(f"G-code line {number}: {why}: {raw.strip()!r}")


class _Moves:
    """The motion blocks of a program, as columns (NaN where a word is absent).

    Lines are only tokenised here; modal positions, units, paths and arcs are
    resolved afterwards on whole arrays, which keeps the per-line work small.
    Lines in write_gcode's own move format skip the general tokenizer: they are
    kept as matched text (``fast``) and converted in bulk.
    """

    def __init__(self) -> None:
        self.motion: int | None = None
        self.synced = 0  # line of the last fast move already folded into ``motion``
        self.ended = False
        self.fast_number: list[int] = []
        self.fast_words: list[tuple[str | None, ...]] = []  # G, X, Y, Z, I, J texts
        self.kind: list[int] = []
        self.x: list[float] = []
        self.y: list[float] = []
        self.z: list[float] = []
        self.i: list[float] = []
        self.j: list[float] = []
        self.number: list[int] = []
        self.units: list[tuple[int, float]] = []  # (line, mm per unit) from G20/G21
        self.stipple: list[tuple[int, int]] = []  # (line, id) from (stipple N)
        self.laser: list[tuple[int, bool]] = []  # (line, on) from M3/M4 and M5

    def line(self, number: int, raw: str) -> None:
        if self.fast_number and self.fast_number[-1] > self.synced:
            # a fast move set the modal motion since the last general line
            self.synced = self.fast_number[-1]
            self.motion = int(self.fast_words[-1][0] or 0)
        text = raw.strip()
        if not text or text == "%":
            return
        semi = text.find(";")
        if semi >= 0 and not 0 <= text.find("(") < semi:
            # a ; comment names the stipple too (Marlin's, whose parenthesised
            # comments need a build option)
            found = _STIPPLE.fullmatch(text[semi + 1:])
            if found:
                sid = int(found.group(1))
                if abs(sid) > _MAX_STIPPLE:
                    raise _line_error(number, raw, "stipple id out of range")
                self.stipple.append((number, sid))
            text = text[:semi]
        if "(" in text:
            for comment in _COMMENT.findall(text):
                found = _STIPPLE.fullmatch(comment)
                if found:
                    sid = int(found.group(1))
                    if abs(sid) > _MAX_STIPPLE:
                        raise _line_error(number, raw, "stipple id out of range")
                    self.stipple.append((number, sid))
            text = _COMMENT.sub(" ", text)
            semi = text.find(";")
            if semi >= 0:
                text = text[:semi]
        if "(" in text or ")" in text:
            raise _line_error(number, raw, "unbalanced parentheses")
        code = text.upper().lstrip()
        if code.startswith("/"):
            code = code[1:]
        words = _WORD.findall(code)
        if _WORD.sub("", code).strip():
            raise _line_error(number, raw, "cannot parse")
        if words:
            self.block(number, words, raw)

    def block(self, number: int, words: list[tuple[str, str]], raw: str) -> None:
        values: dict[str, float] = {}
        motion = self.motion
        for letter, text in words:
            value = float(text)
            if not abs(value) <= _MAX_WORD:
                raise _line_error(number, raw, f"{letter} word out of range (beyond "
                                  f"{_MAX_WORD:g})")
            if letter == "G":
                g = round(value * 10)
                if g in (0, 10, 20, 30):
                    motion = g // 10
                elif g == 800:
                    motion = None
                elif g in (200, 210):
                    self.units.append((number, 25.4 if g == 200 else 1.0))
                elif g not in _IGNORED_G:
                    raise _line_error(number, raw, f"unsupported G{value:g}")
            elif letter == "M":
                if round(value) in (2, 30):
                    self.ended = True
                elif round(value) in (3, 4, 5):
                    # a laser's beam (or a spindle: only a program with no Z
                    # word at all reads them as its cuts)
                    self.laser.append((number, round(value) != 5))
            elif letter in "XYZIJ":
                if letter in values:
                    raise _line_error(number, raw, f"{letter} given twice")
                values[letter] = value
            elif letter not in _IGNORED_WORDS:
                raise _line_error(number, raw, f"unsupported word {letter}")
        self.motion = motion
        get = values.get
        has_ij = "I" in values or "J" in values
        if not any(k in values for k in "XYZ"):
            if has_ij:
                raise _line_error(number, raw, "I/J without an end point (full circles are "
                                  "not supported)")
            return
        if motion is None:
            raise _line_error(number, raw, "axis words without a motion mode")
        if motion >= 2 and not has_ij:
            raise _line_error(number, raw, "arc without I/J (R-format arcs are not supported)")
        if motion < 2 and has_ij:
            raise _line_error(number, raw, "I/J outside an arc move")
        self.kind.append(motion)
        self.x.append(get("X", _NAN))
        self.y.append(get("Y", _NAN))
        self.z.append(get("Z", _NAN))
        self.i.append(get("I", 0.0) if has_ij else _NAN)
        self.j.append(get("J", 0.0) if has_ij else _NAN)
        self.number.append(number)

    def columns(self) -> dict[str, np.ndarray]:
        """All moves in line order: kind, number (int) and x, y, z, i, j in mm."""
        cols = {
            "kind": np.asarray(self.kind, dtype=np.int64),
            "number": np.asarray(self.number, dtype=np.int64),
            **{k: np.asarray(getattr(self, k), dtype=float) for k in "xyzij"},
        }
        if self.fast_number:
            n = len(self.fast_number)
            words = self.fast_words

            def floats(k: int) -> np.ndarray:
                return np.fromiter((float(t) if t else _NAN for t in map(itemgetter(k), words)),
                                   float, n)

            fast = {"kind": np.fromiter(map(int, map(itemgetter(0), words)), np.int64, n),
                    "number": np.asarray(self.fast_number, dtype=np.int64),
                    "x": floats(1), "y": floats(2), "z": floats(3), "i": floats(4),
                    "j": floats(5)}
            huge = np.zeros(n, dtype=bool)
            for axis in "xyzij":
                huge |= np.abs(fast[axis]) > _MAX_WORD
            if huge.any():
                first = int(np.argmax(huge))
                raise SpecholoError(f"G-code line {fast['number'][first]}: number out of range "
                                    f"(beyond {_MAX_WORD:g})")
            order = np.argsort(np.concatenate([cols["number"], fast["number"]]), kind="stable")
            cols = {k: np.concatenate([cols[k], fast[k]])[order] for k in cols}
            arc = cols["kind"] >= 2
            bad = arc == np.isnan(cols["i"])
            if bad.any():
                first = int(np.argmax(bad))
                why = "arc without I/J" if arc[first] else "I/J outside an arc move"
                raise SpecholoError(f"G-code line {cols['number'][first]}: {why}")
        if self.units:
            at, factor = (np.asarray(v) for v in zip(*self.units, strict=True))
            idx = np.searchsorted(at, cols["number"], side="right") - 1
            scale = np.where(idx >= 0, factor[np.maximum(idx, 0)], 1.0)
            for axis in "xyzij":
                cols[axis] = cols[axis] * scale
        return cols

    def stipple_at(self, numbers: np.ndarray) -> np.ndarray:
        """The stipple id in force on the given lines (-1 before any)."""
        if not self.stipple:
            return np.full(len(numbers), -1, dtype=np.int64)
        at, ids = (np.asarray(v, dtype=np.int64) for v in zip(*self.stipple, strict=True))
        idx = np.searchsorted(at, numbers, side="right") - 1
        return np.where(idx >= 0, ids[np.maximum(idx, 0)], -1)


def _fill_forward(values: np.ndarray, initial: float) -> np.ndarray:
    """Modal coordinates: each NaN takes the last given value before it."""
    full = np.concatenate([[initial], values])
    idx = np.where(np.isnan(full), 0, np.arange(len(full)))
    return full[np.maximum.accumulate(idx)]


def _assemble(moves: _Moves) -> Grooves:
    cols = moves.columns()
    kind = cols["kind"]
    number = cols["number"]
    ex, ey = cols["x"], cols["y"]
    has_xy = ~(np.isnan(ex) & np.isnan(ey))
    # positions before and after each move; the machine starts at the origin
    x = _fill_forward(ex, 0.0)
    y = _fill_forward(ey, 0.0)
    z = _fill_forward(cols["z"], 0.0)
    start = np.stack([x[:-1], y[:-1]], axis=1)
    end = np.stack([x[1:], y[1:]], axis=1)

    arc = kind >= 2
    centre = start + np.stack([cols["i"], cols["j"]], axis=1)
    r1 = np.linalg.norm(start - centre, axis=1)
    r2 = np.linalg.norm(end - centre, axis=1)
    circle = arc & np.all(start == end, axis=1)
    # LinuxCNC accepts radii differing by up to about 0.025 mm and cuts a spiral;
    # a bulge cannot hold a spiral, so only near-exact arcs are read
    skew = arc & ~(np.abs(r1 - r2) <= np.maximum(5e-3, 1e-3 * r1))
    for bad, why in ((circle, "full circles are not supported"),
                     (skew, "arc radii to start and end differ")):
        if bad.any():
            e = int(np.argmax(bad))
            raise SpecholoError(f"G-code line {number[e]}: {why} (start {start[e].round(5)}, "
                                f"centre {centre[e].round(5)}, end {end[e].round(5)})")

    if moves.laser and np.isnan(cols["z"]).all():  # a laser's: M3..M5, no Z at all
        return _assemble_laser(moves, kind, number, has_xy, start, end, centre, arc)
    below = z[1:] < 0.0
    begins = below & ~(z[:-1] < 0.0)  # a groove starts where the tool goes below the plate
    vertex = below & (begins | has_xy)
    verts = end[vertex]
    path_start = begins[vertex]
    offsets = np.append(np.flatnonzero(path_start), len(verts)).astype(np.int64)
    stipple = moves.stipple_at(number[begins])

    bulges = np.zeros(len(verts))
    cut_arc = (arc & vertex)[vertex] & ~path_start  # arcs between two groove vertices
    k = np.flatnonzero(cut_arc)
    if len(k):
        bulges[k - 1] = _bulge(kind[vertex][k], centre[vertex][k], verts[k - 1], verts[k])
    return Grooves(verts.reshape(-1, 2), bulges, offsets, stipple)


def read_gcode(path: str | os.PathLike[str]) -> Grooves:
    """Read back the grooves a G-code program cuts.

    Understands the subset :func:`write_gcode` writes and reasonably general
    programs: modal ``G0/G1/G2/G3`` with ``X Y Z I J F`` words (G2/G3 with
    incremental ``I J`` in the XY plane), ``G20``/``G21``, comments in
    parentheses or after ``;``. A groove is a run of moves below Z = 0 (a move
    with X or Y words adds a vertex, a move along Z alone does not), or in a
    program with no Z word (a laser's) a run of feed moves with the beam on;
    its stipple id is that of the last ``(stipple N)`` or ``; stipple N``
    comment before it (-1 if none).

    Args:
        path: G-code file.

    Returns:
        The grooves, arcs as bulges.

    Raises:
        SpecholoError: on a line it cannot parse or a construct it does not support.
    """
    from specholo.readback import open_file

    moves = _Moves()
    fast = _FAST_MOVE.fullmatch
    keep_number = moves.fast_number.append
    keep_words = moves.fast_words.append
    try:
        # comments may hold any text; the words themselves must be ASCII. A
        # regular file only: /dev/zero would be one endless line, a FIFO wait.
        with open_file(path, "G-code file") as raw_fh, \
                io.TextIOWrapper(raw_fh, encoding="utf-8", errors="replace") as fh:
            for number, raw in enumerate(fh, 1):
                found = fast(raw)
                if found is not None:
                    keep_number(number)
                    keep_words(found.groups())
                    continue
                moves.line(number, raw)
                if moves.ended:
                    break
    except OSError as exc:
        raise SpecholoError(f"cannot read G-code file {os.fspath(path)!r}: {exc.strerror}") from exc
    return _assemble(moves)


def _bulge(kind: np.ndarray, centre: np.ndarray, start: np.ndarray,
           end: np.ndarray) -> np.ndarray:
    """(k,) bulges of arcs (G2: kind 2, G3: 3) from start to end about centre."""
    u = start - centre
    v = end - centre
    ang = np.arctan2(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0], np.sum(u * v, axis=1))
    # the direction word decides which way round the circle the arc goes
    sweep = np.where(kind == 3, np.where(ang <= 0, ang + 2 * np.pi, ang),
                     np.where(ang >= 0, ang - 2 * np.pi, ang))
    return np.tan(sweep / 4.0)


def _assemble_laser(moves: _Moves, kind: np.ndarray, number: np.ndarray, has_xy: np.ndarray,
                    start: np.ndarray, end: np.ndarray, centre: np.ndarray,
                    arc: np.ndarray) -> Grooves:
    """The grooves of a laser's program (no Z): every feed move (G1-G3) in X/Y
    while the beam is on (after an ``M3``/``M4``, before an ``M5``) cuts, from
    where the beam came on; a beam switched on and off with no move between (a
    dwell) marks a dot where it stands."""
    at, on = (np.asarray(v) for v in zip(*moves.laser, strict=True))
    at = at.astype(np.int64)
    state = np.searchsorted(at, number, side="right") - 1
    beam = np.where(state >= 0, on[np.maximum(state, 0)], False).astype(bool)
    cutting = beam & (kind >= 1) & has_xy
    # a groove begins at a cut whose move before it did not cut, or after the
    # beam went off and on again between the two
    prev = np.concatenate([[-1], state[:-1]])
    begins = cutting & (~np.concatenate([[False], cutting[:-1]]) | (state != prev))
    idx = np.flatnonzero(cutting)
    first = begins[idx]
    count = np.where(first, 2, 1)  # a groove's first cut adds where it started
    where = np.cumsum(count) - 1  # each cut's end vertex
    verts = np.empty((int(count.sum()), 2))
    verts[where] = end[idx]
    verts[where[first] - 1] = start[idx[first]]
    bulges = np.zeros(len(verts))
    arcs = arc[idx]
    bulges[where[arcs] - 1] = _bulge(kind[idx[arcs]], centre[idx[arcs]], start[idx[arcs]],
                                     end[idx[arcs]])
    path_first = where[first] - 1
    path_line = number[idx[first]]
    # dots: each time the beam comes on, goes off again and no cut ran between
    ons = np.flatnonzero(on)
    offs_after = np.searchsorted(at, at[ons], side="right")
    dot_pos, dot_line = [], []
    for k, nxt in zip(ons, offs_after, strict=True):
        stop = at[nxt] if nxt < len(at) else np.iinfo(np.int64).max
        ran = np.searchsorted(number, [at[k], stop])
        if not cutting[ran[0]:ran[1]].any():
            before = ran[0] - 1  # the last move before the beam came on
            dot_pos.append(end[before] if before >= 0 else np.zeros(2))
            dot_line.append(int(at[k]))
    if dot_pos:
        # dots and grooves in program order, each a path
        lines = np.concatenate([path_line, np.asarray(dot_line, dtype=np.int64)])
        order = np.argsort(lines, kind="stable")
        sizes = np.concatenate([np.diff(np.append(path_first, len(verts))),
                                np.ones(len(dot_pos), dtype=np.int64)])
        starts = np.concatenate([path_first, len(verts) + np.arange(len(dot_pos))])
        all_v = np.concatenate([verts, np.asarray(dot_pos, dtype=float)])
        all_b = np.concatenate([bulges, np.zeros(len(dot_pos))])
        take = np.concatenate([np.arange(a, a + n) for a, n in zip(starts[order], sizes[order],
                                                                    strict=True)])
        verts, bulges = all_v[take], all_b[take]
        path_first = np.concatenate([[0], np.cumsum(sizes[order])[:-1]])
        path_line = lines[order]
    offsets = np.append(path_first, len(verts)).astype(np.int64)
    return Grooves(verts.reshape(-1, 2), bulges, offsets, moves.stipple_at(path_line))

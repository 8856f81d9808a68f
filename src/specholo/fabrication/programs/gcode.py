"""G-code for cutting grooves (read back by :mod:`specholo.fabrication.programs.gcode_reader`).

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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open
from specholo.fabrication.exporting import (
    TextRows,
    check_grooves,
    chord_lengths,
    drawn_extent,
    in_order,
    is_straight,
    path_chunks,
    slice_paths,
)
from specholo.fabrication.plate import Plate
from specholo.fabrication.programs.program import (
    FLAT_DRAWINGS,
    MAX_ARC_OFFSET_MM,
    SCALE,
    Emitter,
    GcodeOptions,
    short_number,
)
from specholo.setup import Holder, Machining, Tool
from specholo.toolpaths.grooves import Grooves, Segments

#: Largest sagitta of a chord that replaces (part of) a wide arc, mm: half the
#: grid, so the chords and the arc round to the same written points.
CHORD_SAGITTA_MM = 0.5 / SCALE

_CHUNK_ROWS = 1 << 16
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

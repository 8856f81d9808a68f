"""A printable 1:1 pattern for scribing a `striped` (or `hyperbola`) design by hand.

A striped design with a wide band (``--band 1``) gives each stipple a handful
of short, gently curved grooves: strokes a person can trace with a scriber
along a printed template. The pattern draws every stroke at true size as a thin
line with a tick across each end (where the scriber goes down and comes up);
the strokes of one stipple share a colour and a number, placed left of the
stipple's leftmost stroke, and a checklist at the end lists the numbers with
their stroke counts and pages.

The pages are the scratch pattern's (:mod:`specholo.fabrication.drawings.pattern`):
tiles with overlap strips and registration targets, crop marks, two 50 mm
scale bars per page and an instruction page; where the numbers do not all fit
on one set of pages, the stipples are spread over several *sheets*.

Geometry is in the plate frame (mm, x right, y up, origin at the plate
centre), seen from the viewer's side.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import PathPatch
from matplotlib.path import Path

from specholo.fabrication.drawings.paper import (
    DOT_MM,
    FONT,
    LABEL_PAD,
    LABEL_PT,
    MAX_SHEETS,
    PT_PER_MM,
    RINGS,
    Tiling,
    arc_path,
    char_widths,
    check_overlap,
    draw_labels,
    instruction_page,
    pages_line,
    paper_named,
    place_labels,
    plate_centre,
    print_steps,
    reading_numbers,
    sheets_step,
    table_page,
    table_size,
    text_width,
    tile_axes,
    tile_margins,
    tiled_figures,
    tiling,
    write_pdf,
)
from specholo.fabrication.drawings.svg import arc_bounds
from specholo.fabrication.exporting import check_grooves, format_number, is_straight
from specholo.toolpaths.grooves import Grooves, Segments

#: Line width of a stroke, points: thin, so its middle is clear to follow (and
#: unlike any other line of the page, which tells the strokes apart in the PDF).
STROKE_PT = 0.45
#: Line width of the end ticks and leader lines, points.
TICK_PT = 0.35
#: Half-length of the tick across each end of a stroke, mm: short enough to
#: stay clear of the next stripe of a 0.5 mm band, 1 mm above.
TICK_MM = 0.5
#: Colours of the stipples' strokes and numbers, in turn by number: dark, so
#: they print clearly, and different, so neighbouring groups part.
COLOURS = ("#000000", "#1f4fa8", "#b3261e", "#1e7a34")
# places tried for a number, in order: left of the stipple's leftmost stroke
# first, as its strokes run off to the right
_LEFT_FIRST = ((-1, 0), (-1, 1), (-1, -1), (0, 1), (0, -1), (1, 1), (1, -1), (1, 0))
# a number's anchor is a stroke's end: the leader starts this far off it, mm
_ANCHOR_GAP = 0.4
# blank kept around strokes and dots for the numbers, mm
_STROKE_CLEAR = 0.3
#: Assumed time per stroke (place the point, trace, lift), seconds: for the
#: rough scribing time on the instruction page.
SECONDS_PER_STROKE = 10.0


@dataclass(frozen=True)
class StrokePlan(Tiling):
    """What a stroke pattern shows and where, before anything is drawn.

    Attributes:
        paper, page, frame, overlap, origin, columns, rows: the tiles, as in
            :class:`~specholo.fabrication.drawings.pattern.PatternPlan`.
        strokes: the grooves to scribe (no dots), one path a stroke, in the
            design's order.
        path: (p,) index of each stroke in the design's grooves.
        group: (p,) stipple group of each stroke, from 0.
        box: (p, 2, 2) lower-left and upper-right corners of each stroke, mm
            (grown by its arcs' bulge).
        length: (p,) stroke lengths, mm.
        stipple: (g,) stipple id of each group.
        anchor: (g, 2) the end of each group's leftmost stroke, mm.
        dots: (d, 2) dimples (single plunges), mm; drawn on the first sheet.
        sheet: (g,) sheet of each group, from 0.
        sheets: number of sheets.
        number: (g,) group numbers from 1, in reading order over the pages.
        text: (g,) label text (the number).
        label: (g, 2) centre of each label, mm.
        label_size: (g, 2) width and height of each label's box, mm.
        leader: (g,) True where a line ties a label to its anchor.
        crowded: labels that found no free place even on the last sheet.
        table_rows: checklist lines per column.
        table_columns: checklist columns per page.
    """

    paper: str
    page: np.ndarray
    frame: np.ndarray
    overlap: float
    origin: np.ndarray
    columns: int
    rows: int
    strokes: Grooves
    path: np.ndarray
    group: np.ndarray
    box: np.ndarray
    length: np.ndarray
    stipple: np.ndarray
    anchor: np.ndarray
    dots: np.ndarray
    sheet: np.ndarray
    sheets: int
    number: np.ndarray
    text: np.ndarray
    label: np.ndarray
    label_size: np.ndarray
    leader: np.ndarray
    crowded: int
    table_rows: int
    table_columns: int

    @property
    def tiles(self) -> int:
        """Number of tiles (pages) of one sheet; 0 when there is nothing to draw."""
        return self.columns * self.rows if len(self.path) or len(self.dots) else 0

    @property
    def table_pages(self) -> int:
        """Number of checklist pages."""
        return -(-len(self.stipple) // (self.table_rows * self.table_columns))

    def colour(self, group: np.ndarray) -> list[str]:
        """Colour of each group (by its number)."""
        return [COLOURS[n % len(COLOURS)] for n in self.number[group].tolist()]


def _first_last(segs: Segments) -> tuple[np.ndarray, np.ndarray]:
    """The first and last arc (p,) of each groove of some arcs."""
    if len(segs) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    first = np.flatnonzero(np.r_[True, segs.path[1:] != segs.path[:-1]])
    return first, np.r_[first[1:] - 1, len(segs) - 1]


def _ends(segs: Segments, first: np.ndarray,
          last: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each stroke's two ends (p, 2, 2) and the unit tangents there (p, 2, 2),
    from its first and last arcs: the tangent at an arc's end is its chord
    turned by half its sweep."""
    chord = segs.end - segs.start
    chord /= np.maximum(np.hypot(*chord.T), 1e-300)[:, None]
    half = 2.0 * np.arctan(segs.bulge)  # sweep / 2
    c, s = np.cos(half), np.sin(half)

    def turn(i: np.ndarray, sign: float) -> np.ndarray:
        x, y = chord[i].T
        return np.column_stack([x * c[i] - sign * y * s[i], sign * x * s[i] + y * c[i]])

    ends = np.stack([segs.start[first], segs.end[last]], axis=1)
    tangents = np.stack([turn(first, -1.0), turn(last, 1.0)], axis=1)
    return ends, tangents


def stroke_path(segs: Segments) -> Path:
    """The arcs of some grooves as one path: a MOVETO where each groove
    starts, then its arcs as cubic Béziers (within 1e-5 of their radius of the
    circle) and its straight segments as lines.

    Args:
        segs: the arcs, each groove's in order and together.
    """
    k = len(segs)
    if k == 0:
        return Path(np.zeros((0, 2)), np.zeros(0, dtype=np.uint8))
    straight = is_straight(segs)
    curved = ~straight
    centre, radius, start, sweep = segs.geometry()
    arcs = arc_path(centre[curved], radius[curved], start[curved], sweep[curved])
    pieces = np.maximum(1, np.ceil(np.abs(sweep) / (0.25 * np.pi)))
    # each arc's block: a MOVETO and its Bézier pieces (arc_path's), a straight
    # segment's: a MOVETO and a LINETO
    size = np.where(straight, 2, 1 + 3 * np.where(curved, pieces, 0)).astype(np.int64)
    offset = np.cumsum(size) - size
    verts = np.empty((int(size.sum()), 2))
    codes = np.empty(len(verts), dtype=np.uint8)
    line = offset[straight]
    verts[line], verts[line + 1] = segs.start[straight], segs.end[straight]
    codes[line], codes[line + 1] = Path.MOVETO, Path.LINETO
    block = size[curved]
    inner = np.arange(int(block.sum())) - np.repeat(np.cumsum(block) - block, block)
    where = np.repeat(offset[curved], block) + inner
    verts[where] = arcs.vertices
    codes[where] = np.asarray(arcs.codes)
    # a groove goes on from its previous arc's end: one MOVETO per groove
    keep = np.ones(len(verts), dtype=bool)
    keep[offset[1:][segs.path[1:] == segs.path[:-1]]] = False
    return Path(verts[keep], codes[keep])


def plan_strokes(grooves: Grooves, paper: str = "a4", overlap: float = 10.0) -> StrokePlan:
    """Lay out the stroke pattern of a design.

    Args:
        grooves: any design's grooves (dots allowed); each path is a stroke.
        paper: ``"a4"`` or ``"letter"``.
        overlap: width of the strip neighbouring pages share, mm (5 to 50).

    Returns:
        The plan: tiles, strokes, their groups, labels and page count.

    Raises:
        SpecholoError: if the grooves cannot be written, or the paper or
            overlap is not allowed.
    """
    key, page = paper_named(paper)
    overlap = check_overlap(overlap)
    check_grooves(grooves)
    dots, _ = grooves.dots()
    path = np.flatnonzero(~grooves.is_dot)
    strokes = grooves.take(path)
    segs = strokes.segments()
    ends, _ = _ends(segs, *_first_last(segs))
    p = len(path)

    # a stroke's box: its vertices, grown by its arcs' largest sagitta
    sizes = strokes.path_sizes
    which = np.repeat(np.arange(p), sizes)
    lo = np.full((p, 2), np.inf)
    hi = np.full((p, 2), -np.inf)
    np.minimum.at(lo, which, strokes.vertices)
    np.maximum.at(hi, which, strokes.vertices)
    chord = np.hypot(*(segs.end - segs.start).T)
    sag = np.zeros(p)
    np.maximum.at(sag, segs.path, 0.5 * chord * np.abs(segs.bulge))
    box = np.stack([lo - sag[:, None], hi + sag[:, None]], axis=1)
    length = np.bincount(segs.path, segs.lengths(), minlength=p)

    # groups: one per stipple, in the order they first come
    ids, index, inverse = np.unique(strokes.stipple, return_index=True, return_inverse=True)
    came = np.argsort(index, kind="stable")
    stipple = ids[came]
    rank = np.empty(len(ids), dtype=np.int64)
    rank[came] = np.arange(len(ids))
    group = rank[inverse.ravel()]
    g = len(stipple)
    # the anchor: the leftmost end of the group's strokes
    flat = ends.reshape(-1, 2)
    owner = np.repeat(group, 2)
    order = np.lexsort((flat[:, 0], owner))
    starts = np.searchsorted(owner[order], np.arange(g))
    anchor = flat[order[starts]] if g else np.zeros((0, 2))

    # the numbers, clear of every stroke, dot and other number, on as many
    # sheets as it takes
    widths = char_widths(FONT, LABEL_PT, "0123456789")
    height = 0.73 * LABEL_PT / PT_PER_MM + 2 * LABEL_PAD
    longest = "8" * len(str(max(g, 1)))
    size = np.column_stack([np.full(g, text_width(np.array([longest]), widths)[0]
                                    + 2 * LABEL_PAD), np.full(g, height)])
    seg_lo = np.minimum(segs.start, segs.end) - _STROKE_CLEAR
    seg_hi = np.maximum(segs.start, segs.end) + _STROKE_CLEAR
    seg_group = group[segs.path]
    label = np.zeros((g, 2))
    ok = np.zeros(g, dtype=bool)
    ring = np.zeros(g, dtype=np.int64)
    sheet = np.zeros(g, dtype=np.int64)
    left = np.arange(g)
    for s in range(MAX_SHEETS):
        sheet[left] = s
        mine = np.isin(seg_group, left)
        obstacles = np.column_stack([seg_lo[mine], seg_hi[mine]])
        label[left], ok[left], ring[left] = place_labels(
            anchor[left], size[left], dots if s == 0 else np.zeros((0, 2)), RINGS,
            _LEFT_FIRST, obstacles)
        left = left[~ok[left]]
        if len(left) == 0:
            break
    sheets = int(sheet.max(initial=0)) + 1

    # Tiles: centred on everything drawn, the plate centre included.
    parts = [np.zeros((1, 2)), dots, label - 0.5 * size, label + 0.5 * size]
    if p:
        parts.append(arc_bounds(segs))
    pts = np.concatenate(parts)
    frame, origin, count = tiling(pts.min(axis=0) - 2.0, pts.max(axis=0) + 2.0, page, overlap)
    table_rows, table_columns = table_size(frame, len(_check_line(0, "", "", "")))
    plan = StrokePlan(key, page, frame, overlap, origin, int(count[0]), int(count[1]),
                      strokes, path, group, box, length, stipple, anchor, dots, sheet,
                      sheets, np.zeros(g, dtype=np.int64), np.zeros(g, dtype=object), label,
                      size, ring > 0, int(np.sum(~ok)), table_rows, table_columns)
    number = reading_numbers(plan, anchor, sheet)
    return replace(plan, number=number,
                   text=np.array([str(n) for n in number.tolist()], dtype=object))


def _tile(plan: StrokePlan, sheet: int, col: int, row: int, targets: np.ndarray) -> Figure:
    fig, paper, ax, box = tile_axes(plan, col, row, targets)
    # this sheet's strokes that reach this tile, whole: a stroke across a page
    # edge shows on both pages
    near = np.all((plan.box[:, 1] >= box[0]) & (plan.box[:, 0] <= box[1]), axis=1)
    mine = np.flatnonzero((plan.sheet[plan.group] == sheet) & near)
    segs = plan.strokes.take(mine).segments()
    colour = plan.colour(plan.group[mine])
    for c in COLOURS:
        # one path per colour: few objects in the PDF however many strokes
        these = np.flatnonzero([x == c for x in colour])
        if len(these) == 0:
            continue
        part = np.isin(segs.path, these)
        sub = Segments(segs.start[part], segs.end[part], segs.bulge[part], segs.path[part])
        ax.add_patch(PathPatch(stroke_path(sub), fill=False, lw=STROKE_PT, color=c,
                               capstyle="butt", joinstyle="round", gid=f"strokes {c}"))
    # ticks across both ends of each stroke, where the scriber goes down and up
    ends, tangent = _ends(segs, *_first_last(segs))
    normal = np.stack([-tangent[..., 1], tangent[..., 0]], axis=-1)
    ticks = np.stack([ends - TICK_MM * normal, ends + TICK_MM * normal], axis=2).reshape(-1, 2, 2)
    ax.add_collection(LineCollection(list(ticks), colors=np.repeat(colour, 2).tolist(),
                                     lw=TICK_PT, capstyle="butt", gid="stroke ends"))
    if len(plan.dots) and sheet == 0:
        ax.plot(plan.dots[:, 0], plan.dots[:, 1], "o", ms=DOT_MM * PT_PER_MM, mfc="black",
                mec="none", gid="dots")
    plate_centre(ax)
    groups = np.flatnonzero(plan.sheet == sheet)
    draw_labels(ax, box, groups, plan.anchor, plan.label, plan.label_size, plan.text,
                 plan.leader, plan.colour(np.arange(len(plan.stipple))), _ANCHOR_GAP)
    tile_margins(plan, paper, sheet, col, row, plan.pages)
    return fig


def _check_line(number: int, strokes: str, length: str, page: str) -> str:
    """One line of the checklist (number 0: the heading)."""
    return f"{number or 'No.':>6} {strokes:>7} {length:>8}  {page:>6}  \u25a1"


def _checklist(plan: StrokePlan, index: int) -> Figure:
    per_page = plan.table_rows * plan.table_columns
    order = np.argsort(plan.number)[index * per_page:(index + 1) * per_page]
    col, row = plan.tile_of(plan.anchor[order])
    count = np.bincount(plan.group, minlength=len(plan.stipple))
    length = np.bincount(plan.group, plan.length, minlength=len(plan.stipple))
    lines = [_check_line(int(plan.number[i]), str(count[i]), format_number(length[i], 1),
                         plan.page_name(int(plan.sheet[i]), int(c), int(r)))
             for i, c, r in zip(order.tolist(), col.tolist(), row.tolist(), strict=True)]
    title = (f"Checklist: strokes by stipple number \u2014 page "
             f"{1 + plan.tile_pages + index + 1} of {plan.pages}")
    return table_page(plan, title, _check_line(0, "strokes", "mm", "page")[:-1], lines,
                       plan.table_rows, plan.table_columns)


def _instructions(plan: StrokePlan) -> Figure:
    p, g, d = len(plan.path), len(plan.stipple), len(plan.dots)
    title = (f"Stroke pattern: {p} stroke{'s' * (p != 1)} for {g} stipple{'s' * (g != 1)}"
             + (f", {d} dimple{'s' * (d != 1)}" if d else ""))
    steps = print_steps(plan)
    steps += [
        "Fix the pattern to the plate with \u201cplate top\u201d up (towards the light). A "
        "clear plate (acrylic, glass): tape the pattern face up under it and scribe its top "
        "face, following the lines seen through it. An opaque plate (polished metal): lay "
        "carbon paper face down on the plate, the pattern on top, trace every stroke and "
        "end tick with a hard pencil, then scribe the traced lines. The pattern shows the "
        "plate's front as the viewer sees it; the diamond marks the plate centre.",
        "Each number is one point of the model: its strokes share the number's colour and "
        "run off to its right. Scribe each stroke in one steady pass from end tick to end "
        "tick, the scriber upright, with light and even pressure (a stroke is a gentle "
        "curve: turn the plate rather than the wrist). Stop at the ticks: a stroke's "
        "glint is in place only between them. Tick the number in the checklist at the end "
        "when all its strokes are done.",
    ]
    if plan.sheets > 1:
        steps.append(sheets_step(plan, "stipples", "Scribe"))
    if d:
        steps.append("At each dot, press a small dimple with the scriber point"
                     + (" (dots are on sheet 1)." if plan.sheets > 1 else "."))
    facts = ""
    if p:
        hours = p * SECONDS_PER_STROKE / 3600.0
        facts = (f"{p} strokes, {format_number(plan.length.sum() / 1000.0, 2)} m in all, "
                 f"{format_number(np.min(plan.length), 1)} to "
                 f"{format_number(np.max(plan.length), 1)} mm long (median "
                 f"{format_number(float(np.median(plan.length)), 1)} mm); at about "
                 f"{SECONDS_PER_STROKE:g} s a stroke, {math.ceil(hours * 2) / 2:g} h of "
                 "scribing.")
        if plan.crowded:
            facts += f" {plan.crowded} numbers found no free place and overlap others."
    drawing = stroke_path(plan.strokes.segments())
    return instruction_page(plan, title, pages_line(plan, plan.pages, plan.table_pages,
                                                      "checklist"),
                             steps, facts, drawing, plan.dots)


def stroke_figures(plan: StrokePlan) -> Iterator[Figure]:
    """The pages of a stroke pattern, one figure at a time.

    Args:
        plan: from :func:`plan_strokes`.

    Yields:
        ``plan.pages`` figures of the paper's size at 72 dpi: the instructions,
        the tiles of each sheet row by row from the top left, then the
        checklist. Each tile figure has an axes labelled ``"tile"`` in plate mm
        and one labelled ``"paper"`` in mm from the paper's lower-left corner,
        both at 1:1.
    """
    yield from tiled_figures(plan, lambda: _instructions(plan), _tile, _checklist)


def write_stroke_pattern(path: str | os.PathLike[str], grooves: Grooves, paper: str = "a4",
                         overlap: float = 10.0) -> StrokePlan:
    """Write the printable stroke pattern of a design as a PDF, atomically.

    Args:
        path: destination ``.pdf`` file.
        grooves: the design's grooves (dots allowed); each path is a stroke.
        paper: ``"a4"`` or ``"letter"``.
        overlap: width of the strip neighbouring pages share, mm.

    Returns:
        The plan that was drawn (its ``pages``, ``tiles``, ``sheets`` ...).

    Raises:
        SpecholoError: if the grooves cannot be written, or the paper or
            overlap is not allowed.
    """
    plan = plan_strokes(grooves, paper, overlap)
    write_pdf(path, "specholo stroke pattern", stroke_figures(plan))
    return plan

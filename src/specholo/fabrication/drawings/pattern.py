"""A printable 1:1 pattern for scratching the `arc` design by hand with a compass.

The `arc` design is the classic scratch hologram: one circular arc per groove,
which a person can scratch with a compass (or dividers) set to the arc's
radius, its point on the arc's centre. The pattern shows, at true size, every
arc, its centre as a small cross and its radius (mm, 1 decimal) beside the
cross.

When the radii do not all fit beside their crosses, the crosses are numbered
instead (the numbers follow the pages and run across each page in bands, so
neighbours have neighbouring numbers) and the radii are listed in a table at
the end, which doubles as a checklist. Labels never overlap: where even the
numbers do not fit (a leader line may tie a number to its cross from a little
further away), the arcs that found no room go on a further *sheet*: another
set of the same pages, laid on the plate in the same place after the first.

A drawing larger than the paper is tiled over pages that overlap by a strip
holding registration targets; every page carries crop marks on its frame and
two 50 mm scale bars (across and down) to check that it was printed at 100 %.
The first page says how to print, assemble and use the pattern. The pages
(:class:`~specholo.fabrication.drawings.paper.Tiling`, the tiles' axes and
margins, labels, instruction and table pages) are
:mod:`specholo.fabrication.drawings.paper`'s, which the stroke pattern of the
other designs (:mod:`specholo.fabrication.drawings.stroke_pattern`) prints on too.

Geometry is in the plate frame (mm, x right, y up, origin at the plate
centre), seen from the viewer's side. Figures are 72 dpi, so their display
units are PDF points, and every axes maps 1 mm of plate to 72 / 25.4 pt.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import PathPatch
from matplotlib.path import Path

from specholo.errors import SpecholoError
from specholo.fabrication.drawings.paper import (
    CROSS_MM,
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
    inside,
    instruction_page,
    pages_line,
    paper_named,
    place_labels,
    plate_centre,
    print_steps,
    reading_numbers,
    segments_path,
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


@dataclass(frozen=True)
class PatternPlan(Tiling):
    """What a scratch pattern shows and where, before anything is drawn.

    Attributes:
        paper: paper name (a key of ``PAPERS``).
        page: (2,) paper width and height, mm.
        frame: (2,) width and height of one tile (the drawing area of a page), mm.
        overlap: width of the strip neighbouring tiles share, mm.
        origin: (2,) plate point at the top-left corner of tile A1, mm.
        columns: tiles across.
        rows: tiles down.
        centre: (k, 2) centres of the arcs, mm.
        radius: (k,) radii, mm.
        start: (k,) start angles, radians.
        sweep: (k,) signed sweeps, radians (> 0 anticlockwise).
        path: (k,) index of each arc's path in the grooves.
        dots: (d, 2) dimples (single plunges), mm; drawn on the first sheet.
        sheet: (k,) sheet of each arc, from 0.
        sheets: number of sheets (copies of the tiled pages, each with some of
            the arcs); 1 unless the numbers do not fit on one.
        number: (k,) arc numbers from 1, in reading order over the pages.
        numbered: True when the crosses carry numbers and the radii are in a table.
        text: (k,) label text of each arc (its radius, or ``#`` and its number).
        label: (k, 2) centre of each label, mm.
        label_size: (k, 2) width and height of each label's box, mm.
        leader: (k,) True where a line ties a label to its cross.
        crowded: labels that found no free place even on the last sheet and
            overlap another (0 unless the design needs over ``MAX_SHEETS`` sheets).
        table_rows: table lines per page (and per column of the table).
        table_columns: table columns per page.
    """

    paper: str
    page: np.ndarray
    frame: np.ndarray
    overlap: float
    origin: np.ndarray
    columns: int
    rows: int
    centre: np.ndarray
    radius: np.ndarray
    start: np.ndarray
    sweep: np.ndarray
    path: np.ndarray
    dots: np.ndarray
    sheet: np.ndarray
    sheets: int
    number: np.ndarray
    numbered: bool
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
        return self.columns * self.rows if len(self.centre) or len(self.dots) else 0

    @property
    def table_pages(self) -> int:
        """Number of radius-table pages (0 unless numbered)."""
        per_page = self.table_rows * self.table_columns
        return -(-len(self.radius) // per_page) if self.numbered else 0


def _arcs(grooves: Grooves) -> tuple[Segments, np.ndarray]:
    """The single arcs of an `arc` design, and its dots; refuse anything else."""
    check_grooves(grooves)
    sizes = grooves.path_sizes
    bad = sizes > 2
    if bad.any():
        j = int(np.argmax(bad))
        raise SpecholoError(
            f"the scratch pattern is for the `arc` design (one circular arc per groove), "
            f"but path {j} has {sizes[j]} vertices")
    segs = grooves.segments()
    straight = is_straight(segs)
    if straight.any():
        j = int(segs.path[np.argmax(straight)])
        raise SpecholoError(
            f"the scratch pattern is for the `arc` design (one circular arc per groove), "
            f"but path {j} is straight")
    dots, _ = grooves.dots()
    return segs, dots


def plan_pattern(grooves: Grooves, paper: str = "a4", overlap: float = 10.0) -> PatternPlan:
    """Lay out the scratch pattern of an `arc` design.

    Args:
        grooves: one circular arc per path (dots allowed), as the `arc` design makes.
        paper: ``"a4"`` or ``"letter"``.
        overlap: width of the strip neighbouring pages share, mm (5 to 50).

    Returns:
        The plan: tiles, arcs, labels and page count.

    Raises:
        SpecholoError: if a path is not a single circular arc or a dot, or the
            paper or overlap is not allowed.
    """
    key, page = paper_named(paper)
    overlap = check_overlap(overlap)
    segs, dots = _arcs(grooves)
    centre, radius, start, sweep = segs.geometry()
    k = len(radius)

    # Labels: radii beside the crosses if they all fit there, else numbers, on
    # as many sheets as it takes for every number to find room.
    em = LABEL_PT / PT_PER_MM
    height = 0.73 * em + 2 * LABEL_PAD  # digits' height
    widths = char_widths(FONT, LABEL_PT, "0123456789.#")
    text = np.array([format_number(r, 1) for r in radius.tolist()], dtype=object)
    size = np.column_stack([text_width(text, widths) + 2 * LABEL_PAD, np.full(k, height)])
    label, ok, ring = place_labels(centre, size, dots, RINGS[:1])
    sheet = np.zeros(k, dtype=np.int64)
    numbered = not ok.all()
    if numbered:
        # every number as wide as the longest, so the plan holds before numbering
        longest = "#" + "8" * len(str(k))
        size[:, 0] = text_width(np.array([longest]), widths)[0] + 2 * LABEL_PAD
        left = np.arange(k)
        for s in range(MAX_SHEETS):
            sheet[left] = s
            label[left], ok[left], ring[left] = place_labels(
                centre[left], size[left], dots if s == 0 else np.zeros((0, 2)), RINGS)
            left = left[~ok[left]]
            if len(left) == 0:
                break
    sheets = int(sheet.max(initial=0)) + 1

    # Tiles: centred on everything drawn, the plate centre included.
    parts = [np.zeros((1, 2)), centre - CROSS_MM, centre + CROSS_MM, dots,
             label - 0.5 * size, label + 0.5 * size]
    if k:
        parts.append(arc_bounds(segs))
    pts = np.concatenate(parts)
    lo, hi = pts.min(axis=0) - 2.0, pts.max(axis=0) + 2.0
    frame, origin, count = tiling(lo, hi, page, overlap)
    table_rows, table_columns = table_size(frame, len(_table_line(0, "", "")))

    plan = PatternPlan(key, page, frame, overlap, origin, int(count[0]), int(count[1]),
                       centre, radius, start, sweep, segs.path.copy(), dots, sheet, sheets,
                       np.zeros(k, dtype=np.int64), numbered, text, label, size,
                       ring > 0, int(np.sum(~ok)), table_rows, table_columns)
    number = reading_numbers(plan, centre, sheet)
    if numbered:
        text = np.array([f"#{n}" for n in number.tolist()], dtype=object)
    return replace(plan, number=number, text=text)


def _instructions(plan: PatternPlan, arcs: Path) -> Figure:
    k, d = len(plan.radius), len(plan.dots)
    title = (f"Scratch pattern: {k} arc{'s' * (k != 1)}"
             + (f", {d} dimple{'s' * (d != 1)}" if d else ""))
    steps = print_steps(plan)
    steps.append(
        "Fix the pattern to the plate with \u201cplate top\u201d up (towards the light): under "
        "a clear plate, or on an opaque one (then prick each cross and arc end through the "
        "paper). The pattern shows the plate's front as the viewer sees it; the diamond "
        "marks the plate centre.")
    if plan.numbered:
        steps.append(
            "For each cross: look up its number (#) in the table at the end, set the compass "
            "(dividers) to that radius in mm, put its point on the cross and scratch the drawn "
            "arc from end tick to end tick. Tick the box in the table when done.")
    else:
        steps.append(
            "For each cross: set the compass (dividers) to the radius written beside it (mm), "
            "put its point on the cross and scratch the drawn arc from end tick to end tick.")
    if plan.sheets > 1:
        steps.append(sheets_step(plan, "arcs", "Scratch"))
    if d:
        steps.append("At each dot, press a small dimple with the compass point"
                     + (" (dots are on sheet 1)." if plan.sheets > 1 else "."))
    facts = ""
    if k:
        facts = (f"Radii {format_number(plan.radius.min(), 1)} to "
                 f"{format_number(plan.radius.max(), 1)} mm.")
        if plan.crowded:
            facts += f" {plan.crowded} numbers found no free place and overlap others."
    return instruction_page(plan, title, pages_line(plan, plan.pages, plan.table_pages,
                                                      "radii"),
                             steps, facts, arcs, plan.dots)


def _tile(plan: PatternPlan, sheet: int, col: int, row: int, targets: np.ndarray) -> Figure:
    fig, paper, ax, box = tile_axes(plan, col, row, targets)
    # this sheet's arcs that may show on this tile (their circles reach it)
    c, r = plan.centre, plan.radius
    near = np.all((c + r[:, None] >= box[0]) & (c - r[:, None] <= box[1]), axis=1)
    mine = np.flatnonzero((plan.sheet == sheet) & near)
    ax.add_patch(PathPatch(arc_path(c[mine], r[mine], plan.start[mine], plan.sweep[mine]),
                           fill=False, lw=0.6, color="black", gid="arcs"))
    # ticks across each arc's ends, where the scratch starts and stops
    end = np.concatenate([plan.start[mine], plan.start[mine] + plan.sweep[mine]])
    u = np.column_stack([np.cos(end), np.sin(end)])
    cc = np.concatenate([c[mine], c[mine]])
    rr = np.concatenate([r[mine], r[mine]])[:, None]
    ax.add_patch(PathPatch(segments_path(cc + (rr - 1.0) * u, cc + (rr + 1.0) * u),
                           fill=False, lw=0.5, color="black", gid="arc ends"))
    here = mine[inside(c[mine], box, 2.0 * CROSS_MM)]
    if len(here):
        ax.plot(c[here, 0], c[here, 1], "+", ms=CROSS_MM * PT_PER_MM, mec="tab:red", mew=0.6,
                gid="centres")
    if len(plan.dots) and sheet == 0:
        ax.plot(plan.dots[:, 0], plan.dots[:, 1], "o", ms=DOT_MM * PT_PER_MM, mfc="black",
                mec="none", gid="dots")
    plate_centre(ax)
    draw_labels(ax, box, mine, c, plan.label, plan.label_size, plan.text, plan.leader,
                 ["tab:red"] * len(c), 0.6 * CROSS_MM)
    tile_margins(plan, paper, sheet, col, row, plan.pages)
    return fig


def _table_line(number: int, radius: str, page: str) -> str:
    """One line of the radius table (number 0: the heading)."""
    return f"{'#' + str(number) if number else 'No.':>7} {radius:>9}  {page:>6}  \u25a1"


def _table(plan: PatternPlan, index: int) -> Figure:
    per_page = plan.table_rows * plan.table_columns
    order = np.argsort(plan.number)[index * per_page:(index + 1) * per_page]
    col, row = plan.tile_of(plan.centre[order])
    lines = [_table_line(int(plan.number[i]), format_number(plan.radius[i], 1),
                         plan.page_name(int(plan.sheet[i]), int(c), int(r)))
             for i, c, r in zip(order.tolist(), col.tolist(), row.tolist(), strict=True)]
    title = (f"Compass radii (mm), by cross number \u2014 page "
             f"{1 + plan.tile_pages + index + 1} of {plan.pages}")
    return table_page(plan, title, _table_line(0, "radius mm", "page")[:-1], lines,
                       plan.table_rows, plan.table_columns)


def pattern_figures(plan: PatternPlan) -> Iterator[Figure]:
    """The pages of a scratch pattern, one figure at a time.

    Args:
        plan: from :func:`plan_pattern`.

    Yields:
        ``plan.pages`` figures of the paper's size at 72 dpi: the instructions,
        the tiles of each sheet row by row from the top left, then the radius
        table. Each tile figure has an axes labelled ``"tile"`` in plate mm and
        one labelled ``"paper"`` in mm from the paper's lower-left corner, both
        at 1:1.
    """
    arcs = arc_path(plan.centre, plan.radius, plan.start, plan.sweep)
    yield from tiled_figures(plan, lambda: _instructions(plan, arcs), _tile, _table)


def write_pattern(path: str | os.PathLike[str], grooves: Grooves, paper: str = "a4",
                  overlap: float = 10.0) -> PatternPlan:
    """Write the printable scratch pattern of an `arc` design as a PDF, atomically.

    Args:
        path: destination ``.pdf`` file.
        grooves: one circular arc per path (dots allowed), as the `arc` design makes.
        paper: ``"a4"`` or ``"letter"``.
        overlap: width of the strip neighbouring pages share, mm.

    Returns:
        The plan that was drawn (its ``pages``, ``tiles``, ``numbered`` ...).

    Raises:
        SpecholoError: if a path is not a single circular arc or a dot (the
            pattern is for the `arc` design), or the paper or overlap is not allowed.
    """
    plan = plan_pattern(grooves, paper, overlap)
    write_pdf(path, "specholo scratch pattern", pattern_figures(plan))
    return plan

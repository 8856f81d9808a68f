"""Printing on paper: what every PDF pattern shares.

A pattern is printed at 1:1 on sheets of a named paper size (:data:`PAPERS`),
tiled with margins and crop marks when the plate is larger than a sheet
(:class:`Tiling`), with registration targets and scale bars to check the scale,
labels placed beside what they name, an instruction page and a table page; and
written as one PDF (:func:`write_pdf`). The groove patterns
(:mod:`.pattern`), the hand-scratching stroke patterns (:mod:`.stroke_pattern`)
and a coupon's sheet (:mod:`.sheet`) draw on these.
"""

from __future__ import annotations

import math
import os
import textwrap
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from matplotlib import patheffects, rc_context
from matplotlib.axes import Axes
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.patches import PathPatch, Rectangle
from matplotlib.path import Path
from matplotlib.textpath import TextToPath

from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open

#: Paper sizes (width, height) in mm, portrait.
PAPERS: dict[str, tuple[float, float]] = {"a4": (210.0, 297.0), "letter": (215.9, 279.4)}


#: PDF points per mm.
PT_PER_MM = 72.0 / 25.4


#: Length of the scale bars, mm.
SCALE_BAR_MM = 50.0


# Page layout, mm from the paper's edges to the tile frame: room for the title
# above, the scale bar below, crop marks and the down scale bar at the sides.
_SIDE = 12.0


_TOP = 14.0


_BOTTOM = 26.0


FONT = "DejaVu Sans"


_MONO = "DejaVu Sans Mono"


LABEL_PT = 6.0  # labels beside the crosses: small, but read at arm's length


_TEXT_PT = 8.0


CROSS_MM = 3.0  # span of a centre cross


DOT_MM = 1.2


LABEL_PAD = 0.25  # blank around a label's digits, mm


_LABEL_GAP = 0.5 * CROSS_MM + 0.4  # from a centre to its nearest label


# labels keep this far from other crosses, so a label is not read as theirs
_CROSS_CLEAR = 1.2


# extra distances (mm) tried for a numbered label that does not fit beside its
# cross; it is then tied to the cross by a leader line
RINGS = (0.0, 2.5, 5.0)


#: Most sheets a pattern is spread over; labels left over after that overlap.
MAX_SHEETS = 12


# label positions around a cross, in order of preference: right, then anticlockwise
_DIRECTIONS = ((1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1))


_BAND_MM = 20.0  # height of the bands the numbers run along


_TABLE_LINE = 1.4  # table line spacing, in font sizes


_TARGET_MM = 5.0  # diameter of a registration target


class Tiling:
    """The pages a pattern is tiled over, shared by the patterns' plans.

    A plan has ``paper``, ``page``, ``frame``, ``overlap``, ``origin``,
    ``columns``, ``rows`` and ``sheets`` (see :class:`PatternPlan`) and says how
    many ``tiles`` one sheet has.
    """

    paper: str
    page: np.ndarray
    frame: np.ndarray
    overlap: float
    origin: np.ndarray
    columns: int
    rows: int
    sheets: int

    @property
    def tiles(self) -> int:
        """Number of tiles (pages) of one sheet; 0 when there is nothing to draw."""
        raise NotImplementedError

    @property
    def tile_pages(self) -> int:
        """Number of pattern pages, all sheets."""
        return self.tiles * self.sheets

    @property
    def table_pages(self) -> int:
        """Number of table pages after the tiles."""
        raise NotImplementedError

    @property
    def pages(self) -> int:
        """Total pages: instructions, tiles of every sheet, the table."""
        return 1 + self.tile_pages + self.table_pages

    @property
    def step(self) -> np.ndarray:
        """(2,) distance between neighbouring tiles across and down, mm."""
        return self.frame - self.overlap

    def tile_box(self, column: int, row: int) -> np.ndarray:
        """(2, 2) lower-left and upper-right plate corners of a tile, mm."""
        x0 = self.origin[0] + column * self.step[0]
        y1 = self.origin[1] - row * self.step[1]
        return np.array([[x0, y1 - self.frame[1]], [x0 + self.frame[0], y1]])

    def tile_of(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Column and row (k,) of the tile whose own part (left of and above the
        next tiles' overlap) holds each point (k, 2)."""
        col = np.floor((points[:, 0] - self.origin[0]) / self.step[0])
        row = np.floor((self.origin[1] - points[:, 1]) / self.step[1])
        return (np.clip(col, 0, self.columns - 1).astype(np.int64),
                np.clip(row, 0, self.rows - 1).astype(np.int64))

    def tile_page(self, sheet: int, column: int, row: int) -> int:
        """Page number (from 1) of a tile of a sheet."""
        return 2 + sheet * self.tiles + row * self.columns + column

    def page_name(self, sheet: int, column: int, row: int) -> str:
        """How the pages call a tile: its name, after its sheet's number if there
        are several, e.g. ``B3`` or ``2:B3``."""
        name = tile_name(column, row)
        return f"{sheet + 1}:{name}" if self.sheets > 1 else name


def tiling(lo: np.ndarray, hi: np.ndarray, page: np.ndarray,
           overlap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fewest tiles that cover a drawing, centred on it.

    Args:
        lo, hi: (2,) lower-left and upper-right plate corners of the drawing, mm.
        page: (2,) paper width and height, mm.
        overlap: width of the strip neighbouring tiles share, mm.

    Returns:
        The tile frame (2,), the plate point at the top-left corner of tile A1
        (2,), and the tiles across and down (2,).
    """
    frame = page - np.array([2 * _SIDE, _TOP + _BOTTOM])
    step = frame - overlap
    count = 1 + np.ceil(np.maximum(hi - lo - frame, 0.0) / step).astype(np.int64)
    covered = frame + (count - 1) * step
    mid = 0.5 * (lo + hi)
    origin = np.array([mid[0] - 0.5 * covered[0], mid[1] + 0.5 * covered[1]])
    return frame, origin, count


def check_overlap(overlap: float) -> float:
    """The page overlap as a float, refused outside 5 to 50 mm."""
    overlap = float(overlap)
    if not 5.0 <= overlap <= 50.0:  # also refuses NaN
        raise SpecholoError(f"page overlap must be in [5, 50] mm, got {overlap}")
    return overlap


def tile_name(column: int, row: int) -> str:
    """Name of a tile: column letters then row number from 1, e.g. ``B3``."""
    letters = ""
    c = column + 1
    while c:
        c, rem = divmod(c - 1, 26)
        letters = chr(ord("A") + rem) + letters
    return f"{letters}{row + 1}"


def paper_named(paper: str) -> tuple[str, np.ndarray]:
    key = str(paper).lower()
    if key not in PAPERS:
        raise SpecholoError(f"paper must be one of {', '.join(PAPERS)}, got {paper!r}")
    return key, np.array(PAPERS[key])


def char_widths(family: str, size_pt: float, chars: str) -> dict[str, float]:
    """Advance width of each character, mm (DejaVu digits do not kern)."""
    prop = FontProperties(family=family, size=size_pt)
    t2p = TextToPath()
    return {c: t2p.get_text_width_height_descent(c, prop, ismath=False)[0] / PT_PER_MM
            for c in chars}


def text_width(texts: np.ndarray, widths: dict[str, float]) -> np.ndarray:
    return np.array([sum(widths[c] for c in t) for t in texts.tolist()])


class _Boxes:
    """Axis-aligned boxes in a uniform grid, for quick overlap queries."""

    def __init__(self, cell: float) -> None:
        self.cell = cell
        self.grid: dict[tuple[int, int], list[int]] = {}
        self.boxes: list[tuple[float, float, float, float]] = []
        self.owner: list[int] = []

    def _cells(self, box: tuple[float, float, float, float]) -> Iterator[tuple[int, int]]:
        c = self.cell
        for i in range(math.floor(box[0] / c), math.floor(box[2] / c) + 1):
            for j in range(math.floor(box[1] / c), math.floor(box[3] / c) + 1):
                yield i, j

    def add(self, box: tuple[float, float, float, float], owner: int = -1) -> None:
        k = len(self.boxes)
        self.boxes.append(box)
        self.owner.append(owner)
        for key in self._cells(box):
            self.grid.setdefault(key, []).append(k)

    def hits(self, box: tuple[float, float, float, float], owner: int = -1) -> bool:
        """Whether ``box`` overlaps a box of another owner."""
        boxes, owners = self.boxes, self.owner
        for key in self._cells(box):
            for k in self.grid.get(key, ()):
                b = boxes[k]
                if (box[0] < b[2] and b[0] < box[2] and box[1] < b[3] and b[1] < box[3]
                        and (owner < 0 or owners[k] != owner)):
                    return True
        return False


def place_labels(centre: np.ndarray, size: np.ndarray, dots: np.ndarray,
                  rings: tuple[float, ...],
                  directions: tuple[tuple[int, int], ...] = _DIRECTIONS,
                  obstacles: np.ndarray | None = None,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Greedy label placement around the crosses, nearest free place first.

    A label may not cover a dot, an obstacle, another label, or come within
    ``_CROSS_CLEAR`` of another arc's cross.

    Args:
        centre: (k, 2) crosses (or other anchors), mm.
        size: (k, 2) label box sizes, mm.
        dots: (d, 2) dots, mm.
        rings: extra distances from the cross to try, mm, nearest first.
        directions: places around the cross to try, in order, as (x, y) signs.
        obstacles: (o, 4) boxes no label may cover (x0, y0, x1, y1), mm.

    Returns:
        Label centres (k, 2) (where the first place tried for those that found
        none), whether each found a free place (k,), and the ring index it was
        placed at (k,).
    """
    k = len(centre)
    boxes = _Boxes(10.0)
    half = 0.5 * CROSS_MM + _CROSS_CLEAR
    for i, (x, y) in enumerate(centre.tolist()):
        boxes.add((x - half, y - half, x + half, y + half), i)
    half = 0.5 * DOT_MM + 0.3
    for x, y in dots.tolist():
        boxes.add((x - half, y - half, x + half, y + half))
    for x0, y0, x1, y1 in (obstacles if obstacles is not None else np.zeros((0, 4))).tolist():
        boxes.add((x0, y0, x1, y1))
    pos = np.zeros((k, 2))
    ok = np.zeros(k, dtype=bool)
    ring = np.zeros(k, dtype=np.int64)
    # the crowded crosses first, while there is room around them
    crowd = np.zeros(k, dtype=np.int64)
    if k:
        cell = np.floor(centre / 10.0).astype(np.int64)
        _, inv, count = np.unique(cell, axis=0, return_inverse=True, return_counts=True)
        crowd = count[inv.ravel()]
    for i in np.lexsort((np.arange(k), -crowd)).tolist():
        cx, cy = centre[i]
        hw, hh = 0.5 * size[i]
        for r_index, extra in enumerate(rings):
            d = _LABEL_GAP + extra
            for sx, sy in directions:
                f = 0.7 if sx and sy else 1.0  # diagonal places sit on a circle of radius d
                x = cx + sx * (f * d + hw)
                y = cy + sy * (f * d + hh)
                box = (x - hw, y - hh, x + hw, y + hh)
                if not boxes.hits(box, i):
                    pos[i] = x, y
                    ok[i] = True
                    ring[i] = r_index
                    boxes.add(box, i)
                    break
            if ok[i]:
                break
        if not ok[i]:
            pos[i] = cx + _LABEL_GAP + hw, cy
    return pos, ok, ring


def reading_numbers(plan: Tiling, points: np.ndarray, sheet: np.ndarray) -> np.ndarray:
    """Numbers from 1 (k,) for points (k, 2) on sheets (k,), in reading order:
    sheet, page, then bands down the page, across each band (boustrophedon, so
    neighbours have neighbouring numbers)."""
    col, row = plan.tile_of(points)
    top = plan.origin[1] - row * plan.step[1]
    band = np.floor((top - points[:, 1]) / _BAND_MM).astype(np.int64)
    across = np.where(band % 2 == 0, points[:, 0], -points[:, 0])
    order = np.lexsort((across, band, col, row, sheet))
    number = np.empty(len(points), dtype=np.int64)
    number[order] = np.arange(1, len(points) + 1)
    return number


def arc_path(centre: np.ndarray, radius: np.ndarray, start: np.ndarray,
             sweep: np.ndarray) -> Path:
    """Circular arcs as one path of cubic Béziers (at most 45 degrees each).

    Args:
        centre: (k, 2) centres.
        radius: (k,) radii.
        start: (k,) start angles, radians.
        sweep: (k,) signed sweeps, radians.

    Returns:
        A path with one MOVETO per arc; its distance from the true circle is
        below 1e-5 of the radius.
    """
    k = len(radius)
    pieces = np.maximum(1, np.ceil(np.abs(sweep) / (0.25 * np.pi))).astype(np.int64)
    arc = np.repeat(np.arange(k), pieces)
    first = np.cumsum(pieces) - pieces
    index = np.arange(len(arc)) - first[arc]
    phi = sweep[arc] / pieces[arc]
    a0 = start[arc] + index * phi
    a1 = a0 + phi
    c, r = centre[arc], radius[arc][:, None]
    u0 = np.column_stack([np.cos(a0), np.sin(a0)])
    u1 = np.column_stack([np.cos(a1), np.sin(a1)])
    t = (4.0 / 3.0 * np.tan(phi / 4.0))[:, None]  # handle length of a Bézier arc
    p0, p3 = c + r * u0, c + r * u1
    p1 = p0 + t * r * np.column_stack([-u0[:, 1], u0[:, 0]])
    p2 = p3 - t * r * np.column_stack([-u1[:, 1], u1[:, 0]])
    verts = np.zeros((k + 3 * len(arc), 2))
    codes = np.full(len(verts), Path.CURVE4, dtype=np.uint8)
    move = 3 * first + np.arange(k)  # each arc's MOVETO comes before its pieces
    verts[move] = p0[first]
    codes[move] = Path.MOVETO
    base = 3 * np.arange(len(arc)) + arc + 1
    verts[base], verts[base + 1], verts[base + 2] = p1, p2, p3
    return Path(verts, codes)


def segments_path(a: np.ndarray, b: np.ndarray) -> Path:
    """Straight segments a[i] to b[i] (k, 2) as one path."""
    verts = np.empty((2 * len(a), 2))
    verts[0::2], verts[1::2] = a, b
    codes = np.tile(np.array([Path.MOVETO, Path.LINETO], dtype=np.uint8), len(a))
    return Path(verts, codes)


def _page(plan: Tiling) -> tuple[Figure, Axes]:
    """A blank page and its paper axes (mm from the lower-left corner)."""
    w, h = plan.page
    fig = Figure(figsize=(w / 25.4, h / 25.4), dpi=72)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0), label="paper")
    ax.set_xlim(0.0, w)
    ax.set_ylim(0.0, h)
    ax.set_axis_off()
    return fig, ax


def _scale_bars(ax: Axes) -> None:
    """The 50 mm bars, across (under the frame) and down (in the left margin)."""
    x0, y0 = _SIDE, 9.0
    ticks = np.arange(0.0, SCALE_BAR_MM + 1e-9, 10.0)
    tall = np.where((ticks == 0) | (ticks == SCALE_BAR_MM), 2.5, 1.5)
    ax.plot([x0, x0 + SCALE_BAR_MM], [y0, y0], color="black", lw=0.8, gid="scale bar")
    ax.add_patch(PathPatch(segments_path(np.column_stack([x0 + ticks, np.full_like(ticks, y0)]),
                                          np.column_stack([x0 + ticks, y0 + tall])),
                           fill=False, lw=0.5))
    for t in ticks.tolist():
        ax.text(x0 + t, y0 - 1.2, f"{t:g}" + (" mm" if t == SCALE_BAR_MM else ""),
                fontsize=6, ha="center", va="top")
    ax.text(x0 + SCALE_BAR_MM + 6.0, y0 + 1.0,
            "Print at 100 % (actual size). Both bars must measure 50 mm;\n"
            "if not, fix the print scaling before you scratch.", fontsize=7, va="center")
    # down: clear of the crop marks at the frame's corners
    xv, yv = 6.0, _BOTTOM + 12.0
    ax.plot([xv, xv], [yv, yv + SCALE_BAR_MM], color="black", lw=0.8, gid="scale bar down")
    ax.add_patch(PathPatch(segments_path(np.column_stack([np.full_like(ticks, xv), yv + ticks]),
                                          np.column_stack([xv + tall, yv + ticks])),
                           fill=False, lw=0.5))
    ax.text(xv - 1.0, yv + 0.5 * SCALE_BAR_MM, "50 mm", fontsize=6, rotation=90,
            ha="right", va="center")


def print_steps(plan: Tiling) -> list[str]:
    """The first steps of every pattern: print it true to scale, join its pages."""
    steps = [
        "Print at 100 % (\u201cactual size\u201d; no \u201cfit to page\u201d). Every page has "
        "two 50 mm scale bars, across and down: measure both with a ruler. If either is "
        "not 50 mm, fix the print settings and print again.",
    ]
    if plan.tiles > 1:
        steps.append(
            "Join the pages as in the map below (A1 at the top left). Trim each page along "
            "its frame on the sides marked \u201ccut\u201d, lay it over the grey overlap strip "
            "of its neighbour so the round targets coincide, and tape.")
    return steps


def sheets_step(plan: Tiling, what: str, verb: str) -> str:
    """The step that says how to lay the sheets of a pattern one after another."""
    return (f"The {what} are spread over {plan.sheets} sheets so that every number stays "
            "legible; each sheet is a full set of pages (page titles start with the sheet "
            f"number). {verb} one sheet, then put the next exactly where it was: hinge the "
            "sheets with tape along the same edge, or line up their diamonds and targets "
            "with marks made on the plate.")


def pages_line(plan: Tiling, pages: int, table_pages: int, table: str) -> str:
    """The line under an instruction page's title that says what the pages are."""
    line = (f"{pages} pages: this one, {plan.tile_pages} pattern page"
            f"{'s' * (plan.tile_pages != 1)} ({plan.columns} across \u00d7 {plan.rows} down"
            + (f", {plan.sheets} sheets" if plan.sheets > 1 else "") + ")")
    if table_pages:
        line += f" and {table_pages} page{'s' * (table_pages != 1)} of {table}"
    return f"{line}; paper {plan.paper.upper()}, portrait."


def instruction_page(plan: Tiling, title: str, pages: str, steps: list[str], facts: str,
                      drawing: Path, dots: np.ndarray) -> Figure:
    """The first page: title, numbered steps, facts, and a map of the pages over
    a small drawing of the whole pattern (not to scale)."""
    fig, ax = _page(plan)
    w, h = plan.page
    x = _SIDE
    y = h - _TOP - 4.0
    ax.text(x, y, title, fontsize=15, weight="bold", gid="title")
    ax.text(x, y - 7.0, pages, fontsize=9)
    y -= 16.0
    for i, step in enumerate(steps, start=1):
        body = textwrap.fill(step, 100)
        ax.text(x, y, f"{i}.", fontsize=9, va="top")
        ax.text(x + 5.0, y, body, fontsize=9, va="top", linespacing=1.4)
        y -= 5.2 * (body.count("\n") + 1) + 2.0
    if facts:
        body = textwrap.fill(facts, 105)
        ax.text(x, y, body, fontsize=9, va="top", linespacing=1.4)
        y -= 5.2 * (body.count("\n") + 1) + 3.0

    if plan.tiles:
        box = np.array([x, _BOTTOM + 2.0, w - 2 * _SIDE, y - _BOTTOM - 6.0])
        total = plan.frame + (np.array([plan.columns, plan.rows]) - 1) * plan.step
        scale = min(box[2] / total[0], box[3] / total[1])
        size = total * scale
        left = box[0] + 0.5 * (box[2] - size[0])
        bottom = box[1] + 0.5 * (box[3] - size[1])
        m = fig.add_axes((left / w, bottom / h, size[0] / w, size[1] / h), label="map")
        m.set_xlim(plan.origin[0], plan.origin[0] + total[0])
        m.set_ylim(plan.origin[1] - total[1], plan.origin[1])
        m.set_axis_off()
        m.add_patch(PathPatch(drawing, fill=False, lw=0.4, color="0.4"))
        if len(dots):
            m.plot(dots[:, 0], dots[:, 1], ".", color="0.4", ms=1.5)
        for row in range(plan.rows):
            for col in range(plan.columns):
                (x0, y0), (x1, y1) = plan.tile_box(col, row)
                m.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, lw=0.6,
                                      color="tab:blue"))
                m.text(x0 + 3.0 / scale, y1 - 3.0 / scale, tile_name(col, row), fontsize=8,
                       color="tab:blue", ha="left", va="top")
        m.plot([0.0], [0.0], "D", color="black", ms=3)
    _scale_bars(ax)
    return fig


def _crop_marks(ax: Axes, x0: float, y0: float, x1: float, y1: float) -> None:
    a, b = 1.5, 5.5  # gap and end of each mark, mm from the corner
    starts, ends = [], []
    for cx, sx in ((x0, -1.0), (x1, 1.0)):
        for cy, sy in ((y0, -1.0), (y1, 1.0)):
            starts += [(cx + sx * a, cy), (cx, cy + sy * a)]
            ends += [(cx + sx * b, cy), (cx, cy + sy * b)]
    ax.add_patch(PathPatch(segments_path(np.array(starts), np.array(ends)), fill=False,
                           lw=0.4, gid="crop marks"))


def target_marks(plan: Tiling) -> np.ndarray:
    """Registration targets (t, 2), mm: in the middle of each overlap strip, a
    quarter and three quarters along it, so they show on both pages."""
    pts = []
    half = 0.5 * plan.overlap
    for row in range(plan.rows):
        for col in range(plan.columns):
            (x0, y0), (x1, y1) = plan.tile_box(col, row)
            if col + 1 < plan.columns:
                pts += [(x1 - half, y0 + f * (y1 - y0)) for f in (0.25, 0.75)]
            if row + 1 < plan.rows:
                pts += [(x0 + f * (x1 - x0), y0 + half) for f in (0.25, 0.75)]
    return np.array(pts).reshape(-1, 2)


def inside(points: np.ndarray, box: np.ndarray, pad: float = 0.0) -> np.ndarray:
    """(k,) whether points (k, 2) lie in a (2, 2) box grown by ``pad``."""
    return np.all((points >= box[0] - pad) & (points <= box[1] + pad), axis=1)


def tile_axes(plan: Tiling, col: int, row: int,
               targets: np.ndarray) -> tuple[Figure, Axes, Axes, np.ndarray]:
    """A tile's page: its paper axes, its tile axes in plate mm (1:1) with the
    grey overlap strips and the registration targets, and its plate box (2, 2)."""
    fig, paper = _page(plan)
    w, h = plan.page
    fw, fh = plan.frame
    box = plan.tile_box(col, row)
    (x0, y0), (x1, y1) = box
    ax = fig.add_axes((_SIDE / w, _BOTTOM / h, fw / w, fh / h), label="tile")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_axis_off()

    if col + 1 < plan.columns:
        ax.add_patch(Rectangle((x1 - plan.overlap, y0), plan.overlap, y1 - y0, color="0.88",
                               lw=0, zorder=0))
    if row + 1 < plan.rows:
        ax.add_patch(Rectangle((x0, y0), x1 - x0, plan.overlap, color="0.88", lw=0, zorder=0))
    t = targets[inside(targets, box)]
    if len(t):
        ax.plot(t[:, 0], t[:, 1], "o", ms=_TARGET_MM * PT_PER_MM, mfc="none", mec="0.3",
                mew=0.5, gid="targets")
        ax.plot(t[:, 0], t[:, 1], "+", ms=1.6 * _TARGET_MM * PT_PER_MM, mec="0.3", mew=0.5)
    return fig, paper, ax, box


def plate_centre(ax: Axes) -> None:
    ax.plot([0.0], [0.0], "D", ms=2.0 * PT_PER_MM, mfc="none", mec="black", mew=0.6,
            gid="plate centre")


def draw_labels(ax: Axes, box: np.ndarray, shown: np.ndarray, anchor: np.ndarray,
                 label: np.ndarray, size: np.ndarray, text: np.ndarray, leader: np.ndarray,
                 colour: list[str], gap: float) -> None:
    """The labels among ``shown`` that reach the tile, each with a leader line
    from ``gap`` mm off its anchor where it was placed further away."""
    shown = shown[np.all((label[shown] + 0.5 * size[shown] > box[0])
                         & (label[shown] - 0.5 * size[shown] < box[1]), axis=1)]
    lead = shown[leader[shown]]
    if len(lead):
        # from the anchor to the nearest point of the label's box
        tip = np.clip(anchor[lead], label[lead] - 0.5 * size[lead],
                      label[lead] + 0.5 * size[lead])
        v = tip - anchor[lead]
        unit = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-9)
        ax.add_collection(LineCollection(
            list(np.stack([anchor[lead] + gap * unit, tip], axis=1)),
            colors=[colour[i] for i in lead.tolist()], lw=0.3, gid="leaders"))
    halo = [patheffects.withStroke(linewidth=1.5, foreground="white")]
    em = LABEL_PT / PT_PER_MM
    for i in shown.tolist():
        # the digits' middle on the box's middle
        ax.text(label[i, 0], label[i, 1] - 0.365 * em, text[i], fontsize=LABEL_PT,
                ha="center", va="baseline", color=colour[i], path_effects=halo, clip_on=True,
                gid=f"label {i}")


def tile_margins(plan: Tiling, paper: Axes, sheet: int, col: int, row: int,
                  pages: int) -> None:
    """The paper around a tile: frame, crop marks, title, how the pages join,
    scale bars."""
    w, h = plan.page
    fw, fh = plan.frame
    (x0, y0), (x1, y1) = plan.tile_box(col, row)
    fx0, fy0, fx1, fy1 = _SIDE, _BOTTOM, _SIDE + fw, _BOTTOM + fh
    paper.add_patch(Rectangle((fx0, fy0), fw, fh, fill=False, lw=0.4, gid="frame"))
    _crop_marks(paper, fx0, fy0, fx1, fy1)
    title = (f"{tile_name(col, row)}  (column {col + 1} of {plan.columns}, row {row + 1} of "
             f"{plan.rows})")
    if plan.sheets > 1:
        title = f"Sheet {sheet + 1} of {plan.sheets}: " + title
    paper.text(fx0, h - 6.0, title, fontsize=10, weight="bold", va="center")
    paper.text(fx1, h - 6.0, f"\u2191 plate top     page {plan.tile_page(sheet, col, row)} of "
               f"{pages}", fontsize=8, ha="right", va="center")
    paper.text(fx0 + 2.0, fy1 + 1.0, f"plate x {x0:.1f} to {x1:.1f} mm, y {y0:.1f} to {y1:.1f} mm",
               fontsize=6, color="0.4", va="bottom")
    # how the pages join, in the margins beside the edges concerned
    if col > 0:
        paper.text(fx0 - 1.5, 0.5 * (fy0 + fy1), f"cut \u2014 lay over {tile_name(col - 1, row)}",
                   rotation=90, fontsize=6, ha="right", va="center")
    if row > 0:
        paper.text(0.5 * (fx0 + fx1), fy1 + 1.0, f"cut \u2014 lay over {tile_name(col, row - 1)}",
                   fontsize=6, ha="center", va="bottom")
    if col + 1 < plan.columns:
        paper.text(fx1 + 1.5, 0.5 * (fy0 + fy1), f"grey strip: {tile_name(col + 1, row)} lies "
                   "over it", rotation=90, fontsize=6, ha="left", va="center")
    if row + 1 < plan.rows:
        paper.text(0.5 * (fx0 + fx1), fy0 - 1.5, f"grey strip: {tile_name(col, row + 1)} lies "
                   "over it", fontsize=6, ha="center", va="top")
    _scale_bars(paper)


def table_page(plan: Tiling, title: str, header: str, lines: list[str], rows: int,
                columns: int) -> Figure:
    """A page of a table in columns of ``rows`` lines under ``header``."""
    fig, ax = _page(plan)
    h = plan.page[1]
    ax.text(_SIDE, h - 7.0, title, fontsize=10, weight="bold", va="center")
    column_w = (plan.frame[0] + 8.0) / columns
    line = _TABLE_LINE * _TEXT_PT / PT_PER_MM
    for c in range(columns):
        chunk = lines[c * rows:(c + 1) * rows]
        if not chunk:
            break
        x = _SIDE + c * column_w
        ax.text(x, h - _TOP - 2.0, header, family=_MONO, fontsize=_TEXT_PT, va="top",
                weight="bold")
        ax.text(x, h - _TOP - 2.0 - line, "\n".join(chunk), family=_MONO, fontsize=_TEXT_PT,
                va="top", linespacing=_TABLE_LINE, gid=f"table {c}")
    _scale_bars(ax)
    return fig


def table_size(frame: np.ndarray, width: int) -> tuple[int, int]:
    """Lines per column and columns per page of a table of lines ``width``
    characters wide."""
    line = _TABLE_LINE * _TEXT_PT / PT_PER_MM
    rows = max(1, int((frame[1] - 12.0) // line) - 1)
    mono = char_widths(_MONO, _TEXT_PT, "0")["0"]
    return rows, max(1, int((frame[0] + 8.0) // (width * mono + 8.0)))


def tiled_figures(plan: Tiling, instructions: Callable[[], Figure],
                  tile: Callable[[Any, int, int, int, np.ndarray], Figure],
                  table: Callable[[Any, int], Figure]) -> Iterator[Figure]:
    """A tiled pattern's pages in order: ``instructions()``, ``tile(plan, sheet,
    column, row, targets)`` for each tile of each sheet row by row from the top
    left, then ``table(plan, index)`` for each table page."""
    def build(make: Callable[..., Figure], *args: Any) -> Figure:
        # texts take their font when made, so the setting need not outlive this
        with rc_context({"font.family": FONT}):
            return make(*args)

    yield build(instructions)
    targets = target_marks(plan)
    for sheet in range(plan.sheets if plan.tiles else 0):
        for row in range(plan.rows):
            for col in range(plan.columns):
                yield build(tile, plan, sheet, col, row, targets)
    for index in range(plan.table_pages):
        yield build(table, plan, index)


def write_pdf(path: str | os.PathLike[str], title: str, figures: Iterator[Figure]) -> None:
    """Write a pattern's pages as a PDF at the paper's size (for 1:1 printing),
    atomically, with no creation date (the same design gives the same file)."""
    meta = {"Title": title, "Creator": "specholo", "CreationDate": None}
    # never "tight": the page must keep the paper's size for 1:1 printing
    with rc_context({"savefig.bbox": "standard", "pdf.fonttype": 42}), \
            atomic_open(path, "wb") as fh, PdfPages(fh, metadata=meta) as pdf:
        for fig in figures:
            pdf.savefig(fig)

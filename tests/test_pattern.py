"""Scratch pattern: a PDF at true scale whose crosses, radii and arcs are the design's."""

from __future__ import annotations

import re

import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import PathPatch
from matplotlib.text import Text

from specholo.errors import SpecholoError
from specholo.fabrication.drawings.paper import PAPERS, PT_PER_MM, SCALE_BAR_MM, arc_path, tile_name
from specholo.fabrication.drawings.pattern import pattern_figures, plan_pattern, write_pattern
from specholo.fabrication.exporting import format_number
from specholo.setup import Setup
from specholo.toolpaths.classic import design_classic
from specholo.toolpaths.common import make_runs
from specholo.toolpaths.grooves import Grooves

pypdf = pytest.importorskip("pypdf")


def arc_design(n: int, size: float, seed: int = 0, dots: int = 0) -> Grooves:
    """An `arc` design of n random stipples over a size x size mm square; the
    first ``dots`` lie on the plate and become dimples."""
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(-size / 2, size / 2, n),
                           rng.uniform(-size / 2, size / 2, n), rng.uniform(-40, -5, n)])
    pts[:dots, 2] = 0.0
    start = rng.uniform(-0.8, 0.0, n)
    end = start + rng.uniform(0.3, 0.8, n)
    return design_classic(make_runs(pts, np.arange(n), start, end), Setup())


@pytest.fixture(scope="module")
def sparse() -> Grooves:
    """Few arcs: every radius fits beside its cross, on one page."""
    return arc_design(12, 60.0, dots=2)


@pytest.fixture(scope="module")
def dense() -> Grooves:
    """Many arcs over two pages: numbered crosses, a radius table, several sheets."""
    return arc_design(400, 190.0, seed=3)


def axes(fig: Figure, label: str):
    (ax,) = [a for a in fig.axes if a.get_label() == label]
    return ax


def texts(fig: Figure, prefix: str) -> dict[str, Text]:
    return {t.get_gid(): t for a in fig.axes for t in a.texts
            if (t.get_gid() or "").startswith(prefix)}


def check_one_to_one(ax) -> None:
    """1 mm of the axes' data is 72 / 25.4 pt on the page, both ways."""
    p0 = ax.transData.transform((ax.get_xlim()[0], ax.get_ylim()[0]))
    p1 = ax.transData.transform((ax.get_xlim()[0] + 50.0, ax.get_ylim()[0] + 50.0))
    np.testing.assert_allclose(p1 - p0, [50.0 * PT_PER_MM] * 2, rtol=1e-12)


def pdf_pages(path) -> list:
    return list(pypdf.PdfReader(path).pages)


@pytest.mark.parametrize("paper", ["a4", "letter"])
def test_pdf_pages(tmp_path, sparse, paper):
    out = tmp_path / "p.pdf"
    plan = write_pattern(out, sparse, paper=paper)
    pages = pdf_pages(out)
    assert len(pages) == plan.pages == 2  # instructions and one pattern page
    w, h = (v * PT_PER_MM for v in PAPERS[paper])
    for page in pages:
        assert float(page.mediabox.width) == pytest.approx(w, abs=1e-3)
        assert float(page.mediabox.height) == pytest.approx(h, abs=1e-3)
    first = pages[0].extract_text()
    assert "Print at 100 %" in first and f"{len(plan.radius)} arcs" in first
    assert "2 dimples" in first


def test_scale(sparse, dense):
    for grooves in (sparse, dense):
        plan = plan_pattern(grooves)
        figs = list(pattern_figures(plan))
        assert len(figs) == plan.pages
        w, h = plan.page
        for fig in figs:
            assert fig.dpi == 72  # display units are points
            np.testing.assert_allclose(fig.get_size_inches() * 72, plan.page * PT_PER_MM)
            paper = axes(fig, "paper")
            check_one_to_one(paper)
            assert paper.get_xlim() == (0.0, w) and paper.get_ylim() == (0.0, h)
            # a 50 mm scale bar across and one down on every page
            for gid, axis in (("scale bar", 0), ("scale bar down", 1)):
                (bar,) = [li for li in paper.lines if li.get_gid() == gid]
                pts = paper.transData.transform(bar.get_xydata())
                assert abs(pts[1, axis] - pts[0, axis]) == pytest.approx(
                    SCALE_BAR_MM * PT_PER_MM, rel=1e-12)
        for fig in figs[1:1 + plan.tile_pages]:
            tile = axes(fig, "tile")
            check_one_to_one(tile)
            # the tile's lower-left plate corner sits at the frame's corner on the paper
            x0, y0 = tile.get_xlim()[0], tile.get_ylim()[0]
            corner = axes(fig, "paper").transData.inverted().transform(
                tile.transData.transform((x0, y0)))
            np.testing.assert_allclose(corner, [12.0, 26.0], atol=1e-9)
            np.testing.assert_allclose(np.diff(tile.get_xlim()), plan.frame[0])
            np.testing.assert_allclose(np.diff(tile.get_ylim()), plan.frame[1])


def test_labels_are_radii(sparse):
    """Few arcs: every cross is drawn at its arc's centre with the radius beside it."""
    plan = plan_pattern(sparse)
    assert not plan.numbered and plan.sheets == 1 and plan.crowded == 0
    segs = sparse.segments()
    centre, radius, start, sweep = segs.geometry()
    assert len(radius) == len(plan.radius) == sparse.n_paths - 2
    np.testing.assert_array_equal(plan.centre, centre)
    figs = list(pattern_figures(plan))
    assert plan.tiles == 1 and len(figs) == 2
    tile = axes(figs[1], "tile")
    (crosses,) = [li for li in tile.lines if li.get_gid() == "centres"]
    assert crosses.get_marker() == "+"
    np.testing.assert_array_equal(np.sort(crosses.get_xydata(), axis=0), np.sort(centre, axis=0))
    labels = texts(figs[1], "label ")
    assert len(labels) == len(radius)
    for i, r in enumerate(radius):
        t = labels[f"label {i}"]
        assert t.get_text() == format_number(r, 1)
        # centred in its box, which is beside its own cross: nearer to it than to any other
        x, y = t.get_position()
        assert t.get_horizontalalignment() == "center" and x == plan.label[i, 0]
        assert plan.label[i, 1] - 1.0 < y < plan.label[i, 1]  # the baseline, under the middle
        lo = plan.label[i] - 0.5 * plan.label_size[i]
        hi = plan.label[i] + 0.5 * plan.label_size[i]
        d = np.hypot(*(np.clip(centre, lo, hi) - centre).T)
        assert np.argmin(d) == i and d[i] < 2.0 and np.delete(d, i).min() > 2.5
    (dots,) = [li for li in tile.lines if li.get_gid() == "dots"]
    np.testing.assert_array_equal(dots.get_xydata(), sparse.dots()[0])


def test_arcs_drawn_exactly(sparse):
    plan = plan_pattern(sparse)
    tile = axes(list(pattern_figures(plan))[1], "tile")
    (patch,) = [p for p in tile.patches if p.get_gid() == "arcs"]
    assert isinstance(patch, PathPatch)
    path = patch.get_path()
    # one piece per arc, from its start to its end vertex
    moves = np.flatnonzero(path.codes == path.MOVETO)
    assert len(moves) == len(plan.radius)
    segs = sparse.segments()
    np.testing.assert_allclose(path.vertices[moves], segs.start, atol=1e-9)
    ends = np.append(moves[1:], len(path.vertices)) - 1
    np.testing.assert_allclose(path.vertices[ends], segs.end, atol=1e-9)


def test_arc_path_on_circle():
    rng = np.random.default_rng(1)
    k = 50
    centre = rng.uniform(-50, 50, (k, 2))
    radius = rng.uniform(0.5, 80, k)
    start = rng.uniform(-np.pi, np.pi, k)
    sweep = rng.uniform(-1.99 * np.pi, 1.99 * np.pi, k)
    path = arc_path(centre, radius, start, sweep)
    move = path.codes == path.MOVETO
    arc = np.cumsum(move) - 1
    # points along every cubic piece: its end vertex j and the three before it
    j = np.flatnonzero(~move)[2::3]
    p0, p1, p2, p3 = (path.vertices[j - n] for n in (3, 2, 1, 0))
    t = np.linspace(0.0, 1.0, 9)[:, None, None]
    p = ((1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t**2 * p2
         + t**3 * p3).reshape(-1, 2)
    o = np.tile(arc[j], len(t))
    err = np.abs(np.hypot(*(p - centre[o]).T) - radius[o]) / radius[o]
    assert err.max() < 1e-5
    last = np.append(np.flatnonzero(path.codes == path.MOVETO)[1:], len(path.vertices)) - 1
    a1 = start + sweep
    np.testing.assert_allclose(path.vertices[last],
                               centre + radius[:, None] * np.column_stack([np.cos(a1),
                                                                          np.sin(a1)]),
                               atol=1e-9)


def test_numbered(tmp_path, dense):
    out = tmp_path / "dense.pdf"
    plan = write_pattern(out, dense)
    k = len(plan.radius)
    assert plan.numbered and plan.crowded == 0 and plan.sheets > 1
    assert plan.table_pages >= 1 and plan.tiles == 2
    assert plan.pages == 1 + plan.tiles * plan.sheets + plan.table_pages
    assert len(pdf_pages(out)) == plan.pages
    assert sorted(plan.number.tolist()) == list(range(1, k + 1))
    # no two labels of a sheet overlap
    for s in range(plan.sheets):
        mine = plan.sheet == s
        lo = plan.label[mine] - 0.5 * plan.label_size[mine]
        hi = plan.label[mine] + 0.5 * plan.label_size[mine]
        overlap = ((lo[:, None] < hi[None]) & (lo[None] < hi[:, None])).all(axis=2)
        assert overlap.sum() == mine.sum()  # each box with itself only
    figs = list(pattern_figures(plan))
    _, radius, _, _ = dense.segments().geometry()
    seen = np.zeros(k, dtype=bool)
    for fig in figs[1:1 + plan.tile_pages]:
        for gid, t in texts(fig, "label ").items():
            i = int(gid.split()[1])
            assert t.get_text() == f"#{plan.number[i]}"
            seen[i] = True
    assert seen.all()  # every cross is labelled somewhere
    # the table lists every number with its arc's radius, once
    rows: dict[int, str] = {}
    for fig in figs[1 + plan.tile_pages:]:
        for t in texts(fig, "table ").values():
            for line in t.get_text().splitlines():
                m = re.fullmatch(r"\s*#(\d+)\s+(\d+\.\d)\s+(\d+:[A-Z]+\d+)\s+\u25a1", line)
                assert m, line
                assert int(m.group(1)) not in rows
                rows[int(m.group(1))] = m.group(2)
    assert sorted(rows) == list(range(1, k + 1))
    for i in range(k):
        assert rows[plan.number[i]] == format_number(radius[i], 1)


def test_tiles_cover_the_drawing():
    g = arc_design(40, 420.0, seed=5)
    plan = plan_pattern(g, paper="letter", overlap=12.0)
    assert plan.columns == 3 and plan.rows == 2
    figs = list(pattern_figures(plan))
    names = []
    shown = np.zeros(len(plan.radius), dtype=int)
    for fig in figs[1:1 + plan.tiles]:
        tile = axes(fig, "tile")
        (x0, x1), (y0, y1) = tile.get_xlim(), tile.get_ylim()
        names.append(next(t.get_text() for t in axes(fig, "paper").texts
                          if t.get_fontweight() == "bold").split()[0])
        for li in tile.lines:
            if li.get_gid() == "centres":
                xy = li.get_xydata()
                inside = (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
                shown += np.isin(plan.centre[:, 0], xy[inside, 0])
            if li.get_gid() == "targets":
                # registration targets sit in an overlap strip, so on two pages
                xy = li.get_xydata()
                in_x = (xy[:, 0] > x1 - plan.overlap) | (xy[:, 0] < x0 + plan.overlap)
                in_y = (xy[:, 1] < y0 + plan.overlap) | (xy[:, 1] > y1 - plan.overlap)
                assert np.all(in_x | in_y)
    assert names == ["A1", "B1", "C1", "A2", "B2", "C2"]
    assert np.all(shown >= 1)  # every centre is on some page
    # neighbouring tiles share exactly the overlap
    a, b = plan.tile_box(0, 0), plan.tile_box(1, 0)
    assert a[1, 0] - b[0, 0] == pytest.approx(12.0)
    c = plan.tile_box(0, 1)
    assert a[0, 1] - c[1, 1] == pytest.approx(-12.0) or c[1, 1] - a[0, 1] == pytest.approx(12.0)


def test_tile_names():
    assert [tile_name(c, 0) for c in (0, 1, 25, 26, 27)] == ["A1", "B1", "Z1", "AA1", "AB1"]
    assert tile_name(2, 4) == "C5"


def test_empty(tmp_path):
    out = tmp_path / "e.pdf"
    plan = write_pattern(out, Grooves.empty())
    assert plan.pages == 1 and plan.tiles == 0
    assert len(pdf_pages(out)) == 1


def test_refuses_other_designs(tmp_path, groove_example):
    out = tmp_path / "x.pdf"
    with pytest.raises(SpecholoError, match=r"for the `arc` design .* path 0 has 4 vertices"):
        write_pattern(out, groove_example)
    straight = Grooves(np.array([[0.0, 0.0], [5.0, 0.0]]), np.zeros(2), np.array([0, 2]),
                       np.array([0]))
    with pytest.raises(SpecholoError, match=r"`arc` design .* path 0 is straight"):
        write_pattern(out, straight)
    assert not out.exists()


def test_refuses_a_striped_design(tmp_path):
    from specholo.toolpaths.striped import StripeOptions, design_striped

    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-20, 20, 8), rng.uniform(-20, 20, 8),
                           rng.uniform(-30, -10, 8)])
    runs = make_runs(pts, np.arange(8), np.full(8, -0.5), np.full(8, 0.5))
    grooves, _ = design_striped(runs, Setup(), StripeOptions())
    assert grooves.path_sizes.max() > 2
    with pytest.raises(SpecholoError, match="`arc` design"):
        write_pattern(tmp_path / "x.pdf", grooves)


@pytest.mark.parametrize("kwargs, match", [
    ({"paper": "a3"}, "paper must be one of a4, letter, got 'a3'"),
    ({"overlap": 2.0}, "overlap must be in"),
    ({"overlap": float("nan")}, "overlap must be in"),
])
def test_refuses_bad_options(tmp_path, sparse, kwargs, match):
    with pytest.raises(SpecholoError, match=match):
        write_pattern(tmp_path / "x.pdf", sparse, **kwargs)
    assert list(tmp_path.iterdir()) == []


def test_same_design_same_file(tmp_path, sparse):
    a, b = tmp_path / "a.pdf", tmp_path / "b.pdf"
    write_pattern(a, sparse)
    write_pattern(b, sparse)
    assert a.read_bytes() == b.read_bytes()


def test_lines_are_thin_and_marks_present(sparse):
    """The pattern page has its crop marks, frame and plate centre."""
    plan = plan_pattern(sparse)
    fig = list(pattern_figures(plan))[1]
    paper = axes(fig, "paper")
    gids = {p.get_gid() for p in paper.patches}
    assert {"frame", "crop marks"} <= gids
    marks = next(p for p in paper.patches if p.get_gid() == "crop marks").get_path()
    assert len(marks.vertices) == 16  # two strokes at each of the four corners
    tile = axes(fig, "tile")
    (centre,) = [li for li in tile.lines if li.get_gid() == "plate centre"]
    assert isinstance(centre, Line2D) and centre.get_xydata().tolist() == [[0.0, 0.0]]

"""Stroke pattern: a PDF at true scale whose strokes, read back, are the design's grooves."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from scipy.spatial import cKDTree

from specholo.errors import SpecholoError
from specholo.fabrication.drawings.paper import PT_PER_MM, SCALE_BAR_MM, target_marks
from specholo.fabrication.drawings.stroke_pattern import (
    COLOURS,
    STROKE_PT,
    StrokePlan,
    plan_strokes,
    stroke_figures,
    stroke_path,
    write_stroke_pattern,
)
from specholo.jobs.flat.folder import BAND, HAND_BAND, DesignConfig
from specholo.jobs.plate_common import check_formats
from specholo.setup import Setup
from specholo.toolpaths.common import make_runs
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.striped import StripeOptions, design_striped
from specholo_cli.cli import main

pypdf = pytest.importorskip("pypdf")
from pypdf.generic import ContentStream  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
# the tile frame's lower-left corner, mm from the paper's (the pattern's layout)
FRAME_CORNER = np.array([12.0, 26.0])


def striped(n: int, width: float, height: float, seed: int = 0, band: float = 1.0) -> Grooves:
    """A striped design of n random stipples over a width x height mm box."""
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(-width / 2, width / 2, n),
                           rng.uniform(-height / 2, height / 2, n), rng.uniform(-40, -10, n)])
    runs = make_runs(pts, np.arange(n), np.full(n, -0.6), np.full(n, 0.6))
    grooves, _ = design_striped(runs, Setup(), StripeOptions(band=band))
    return grooves


@pytest.fixture(scope="module")
def small() -> Grooves:
    """A few stipples on one page."""
    return striped(10, 60.0, 60.0)


@pytest.fixture(scope="module")
def wide() -> Grooves:
    """Stipples over several pages, some strokes across the pages' edges."""
    return striped(24, 330.0, 60.0, seed=2)


# ------------------------------------------------------------ reading the PDF back

def _bezier(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray) -> np.ndarray:
    t = np.linspace(0.0, 1.0, 65)[1:, None]
    return (1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t**2 * p2 + t**3 * p3


def densify(line: np.ndarray, step: float) -> np.ndarray:
    """A polyline (k, 2) with points added along its pieces, at most ``step`` apart."""
    d = np.hypot(*np.diff(line, axis=0).T)
    n = np.maximum(1, np.ceil(d / step)).astype(np.int64)
    piece = np.repeat(np.arange(len(d)), n)
    t = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n) + 1) / n[piece]
    return np.concatenate([line[:1], line[piece] + t[:, None] * (line[piece + 1] - line[piece])])


def drawn(page, reader) -> dict:
    """What a page's content stream draws, in PDF points: stroked paths (each
    a list of subpaths, each a polyline sampled along its curves) with their
    line width and stroke colour, and the places XObjects (markers) are put."""
    ops = ContentStream(page.get_contents(), reader).operations
    stack, width, colour, shift = [], 1.0, (0.0, 0.0, 0.0), np.zeros(2)
    paths, places, subs = [], [], []
    for operands, op in ops:
        args = [float(a) for a in operands if isinstance(a, (int, float))]
        if op == b"q":
            stack.append((width, colour, shift.copy()))
        elif op == b"Q":
            width, colour, shift = stack.pop()
        elif op == b"w":
            width = args[0]
        elif op == b"G":
            colour = (args[0],) * 3
        elif op == b"RG":
            colour = tuple(args)
        elif op == b"cm":
            shift = shift + np.array(args[4:6])
        elif op == b"Do":
            places.append(shift.copy())
        elif op == b"m":
            subs.append([np.array(args) + shift])
        elif op == b"l":
            subs[-1].append(np.array(args) + shift)
        elif op == b"c":
            p = np.array(args).reshape(3, 2) + shift
            subs[-1].extend(_bezier(subs[-1][-1], *p))
        elif op == b"re":
            x, y, w, h = args
            subs.append([np.array(v) + shift for v in ((x, y), (x + w, y), (x + w, y + h),
                                                       (x, y + h), (x, y))])
        elif op in (b"S", b"s", b"B", b"b"):
            paths.append({"width": width, "colour": colour, "subs": [np.array(s) for s in subs]})
            subs = []
        elif op in (b"f", b"f*", b"n"):
            subs = []
    return {"paths": paths, "places": places}


def to_plate(plan: StrokePlan, content: dict, col: int, row: int) -> np.ndarray:
    """The matrix-free map from a tile page's points to plate mm: found from the
    frame drawn on the page (its size checks the scale) and the tile's box."""
    frames = [s for p in content["paths"] for s in p["subs"] if len(s) == 5
              and np.allclose(np.ptp(s, axis=0), plan.frame * PT_PER_MM, atol=1e-3)]
    assert len(frames) == 1
    corner_pt = frames[0].min(axis=0)
    np.testing.assert_allclose(corner_pt / PT_PER_MM, FRAME_CORNER, atol=1e-5)
    return plan.tile_box(col, row)[0] - corner_pt / PT_PER_MM


def design_samples(grooves: Grooves, j: int, step: float = 0.02) -> np.ndarray:
    """Points along path j of the grooves, at most ``step`` mm apart."""
    sub = grooves.take(np.array([j])).segments()
    centre, radius, start, sweep = sub.geometry()
    pts = [sub.start[:1]]
    for i in range(len(sub)):
        n = max(2, int(np.ceil(sub.lengths()[i] / step)) + 1)
        t = np.linspace(0.0, 1.0, n)[1:, None]
        if np.isfinite(radius[i]) and radius[i] < 1e6:
            a = start[i] + t[:, 0] * sweep[i]
            pts.append(centre[i] + radius[i] * np.column_stack([np.cos(a), np.sin(a)]))
        else:
            pts.append(sub.start[i] + t * (sub.end[i] - sub.start[i]))
    return np.concatenate(pts)


def tile_pages(plan: StrokePlan):
    """(page index, sheet, column, row) of every tile page, in page order."""
    k = 1
    for sheet in range(plan.sheets):
        for row in range(plan.rows):
            for col in range(plan.columns):
                yield k, sheet, col, row
                k += 1


def read_strokes(path: Path, plan: StrokePlan) -> list[tuple[int, np.ndarray]]:
    """Every stroke drawn on the tile pages, as (page, polyline in plate mm)."""
    reader = pypdf.PdfReader(path)
    colours = [to_rgb(c) for c in COLOURS]
    found = []
    for k, _, col, row in tile_pages(plan):
        content = drawn(reader.pages[k], reader)
        offset = to_plate(plan, content, col, row)
        for p in content["paths"]:
            if p["width"] == pytest.approx(STROKE_PT) and any(
                    np.allclose(p["colour"], c, atol=2e-3) for c in colours):
                found += [(k, densify(s / PT_PER_MM + offset, 0.01)) for s in p["subs"]]
    return found


# ------------------------------------------------------------------------ tests

@pytest.mark.parametrize("which", ["small", "wide"])
def test_strokes_read_back_are_the_grooves(tmp_path, request, which):
    """Each stroke of the PDF, converted back to plate mm through the page's
    frame, lies within 0.1 mm of its groove and covers it end to end; every
    groove is drawn on some page."""
    grooves = request.getfixturevalue(which)
    out = tmp_path / "p.pdf"
    plan = write_stroke_pattern(out, grooves)
    assert len(pypdf.PdfReader(out).pages) == plan.pages
    if which == "wide":
        assert plan.tiles > 1
    found = read_strokes(out, plan)
    starts = cKDTree(np.array([s[0] for _, s in found]))
    seen = np.zeros(grooves.n_paths, dtype=bool)
    pages: dict[int, set[int]] = {}
    for j in np.flatnonzero(~grooves.is_dot):
        truth = design_samples(grooves, int(j))
        hits = starts.query_ball_point(truth[0], 1e-3)
        assert hits, f"stroke {j} is on no page"
        for h in hits:
            k, line = found[h]
            # both ways: the drawn line stays on the groove and reaches all of it
            assert cKDTree(truth).query(line)[0].max() < 0.1
            assert cKDTree(line).query(truth)[0].max() < 0.1
            np.testing.assert_allclose(line[-1], truth[-1], atol=1e-3)
            pages.setdefault(int(j), set()).add(k)
        seen[j] = True
    assert seen[~grooves.is_dot].all()
    # every stroke drawn is one of the design's, drawn once a page
    assert len(found) == sum(len(v) for v in pages.values())
    if which == "wide":
        assert any(len(v) > 1 for v in pages.values())  # across a page edge: on both


def test_registration_and_scale_on_every_page(tmp_path, wide):
    out = tmp_path / "w.pdf"
    plan = write_stroke_pattern(out, wide)
    assert plan.columns > 1
    reader = pypdf.PdfReader(out)
    targets = target_marks(plan)
    for k, page in enumerate(reader.pages):
        content = drawn(page, reader)
        # the two 50 mm scale bars, across and down, on every page
        bars = [s for p in content["paths"] if p["width"] == pytest.approx(0.8)
                for s in p["subs"] if len(s) == 2]
        spans = sorted(tuple(np.round(np.abs(s[1] - s[0]) / PT_PER_MM, 6)) for s in bars)
        assert spans == [(0.0, SCALE_BAR_MM), (SCALE_BAR_MM, 0.0)]
        if k == 0 or k > plan.tile_pages:
            continue
        (_, _, col, row), = [t for t in tile_pages(plan) if t[0] == k]
        # crop marks: two strokes at each of the frame's four corners
        crops = [p for p in content["paths"] if p["width"] == pytest.approx(0.4)
                 and len(p["subs"]) == 8 and all(len(s) == 2 for s in p["subs"])]
        assert len(crops) == 1
        # the registration targets of this tile's overlap strips, where they should be
        offset = to_plate(plan, content, col, row)
        box = plan.tile_box(col, row)
        mine = targets[np.all((targets >= box[0]) & (targets <= box[1]), axis=1)]
        assert len(mine) >= 2
        placed = np.array(content["places"]) / PT_PER_MM + offset
        assert cKDTree(placed).query(mine)[0].max() < 1e-4


def test_groups_numbers_and_checklist(tmp_path, small):
    out = tmp_path / "s.pdf"
    plan = write_stroke_pattern(out, small)
    g = len(plan.stipple)
    assert g == len(np.unique(small.stipple))
    assert sorted(plan.number.tolist()) == list(range(1, g + 1))
    # a group's strokes are its stipple's, and its anchor the left end of one
    assert np.array_equal(plan.stipple[plan.group], small.stipple[plan.path])
    ends = np.concatenate([plan.strokes.vertices[plan.strokes.offsets[:-1]],
                           plan.strokes.vertices[plan.strokes.offsets[1:] - 1]])
    owner = np.concatenate([plan.group, plan.group])
    for i in range(g):
        assert plan.anchor[i, 0] == ends[owner == i, 0].min()
    # the labels on a sheet are apart
    for s in range(plan.sheets):
        mine = plan.sheet == s
        lo = plan.label[mine] - 0.5 * plan.label_size[mine]
        hi = plan.label[mine] + 0.5 * plan.label_size[mine]
        overlap = ((lo[:, None] < hi[None]) & (lo[None] < hi[:, None])).all(axis=2)
        assert overlap.sum() == mine.sum()
    text = pypdf.PdfReader(out).pages[0].extract_text()
    assert f"{len(plan.path)} strokes for {g} stipples" in text and "Print at 100 %" in text
    checklist = "\n".join(p.extract_text() for p in pypdf.PdfReader(out).pages[-plan.table_pages:])
    for n in range(1, g + 1):
        i = int(np.flatnonzero(plan.number == n)[0])
        assert f"{n} {np.sum(plan.group == i)}" in " ".join(checklist.split())


def test_stroke_path_through_every_kind_of_arc(groove_example):
    """Arcs both ways, over 180 degrees, a straight segment: one piece per groove."""
    strokes = groove_example.take(np.flatnonzero(~groove_example.is_dot))
    path = stroke_path(strokes.segments())
    moves = np.flatnonzero(path.codes == path.MOVETO)
    assert len(moves) == strokes.n_paths
    np.testing.assert_allclose(path.vertices[moves], strokes.vertices[strokes.offsets[:-1]])
    for j in range(strokes.n_paths):
        end = moves[j + 1] if j + 1 < len(moves) else len(path.vertices)
        verts, codes = path.vertices[moves[j]:end], path.codes[moves[j]:end]
        line = [verts[0]]
        i = 1
        while i < len(verts):
            if codes[i] == path.LINETO:
                line.append(verts[i])
                i += 1
            else:
                line.extend(_bezier(line[-1], *verts[i:i + 3]))
                i += 3
        truth = design_samples(strokes, j, step=1e-3)
        line = densify(np.array(line), 1e-3)
        assert cKDTree(truth).query(line)[0].max() < 2e-3
        assert cKDTree(line).query(truth)[0].max() < 2e-3


def test_dots_and_empty(tmp_path, groove_example):
    plan = plan_strokes(groove_example)
    assert len(plan.dots) == 1 and len(plan.path) == 2
    figs = list(stroke_figures(plan))
    assert len(figs) == plan.pages
    out = tmp_path / "e.pdf"
    empty = write_stroke_pattern(out, Grooves.empty())
    assert empty.pages == 1 and empty.tiles == 0
    assert len(pypdf.PdfReader(out).pages) == 1


def test_same_design_same_file(tmp_path, small):
    a, b = tmp_path / "a.pdf", tmp_path / "b.pdf"
    write_stroke_pattern(a, small)
    write_stroke_pattern(b, small)
    assert a.read_bytes() == b.read_bytes()


def test_the_hand_scribers_band():
    """A wide band by default for the hand scriber: fewer, longer strokes."""
    assert DesignConfig(tool="scriber").band == HAND_BAND == 1.0
    assert DesignConfig().band == DesignConfig(tool="ball").band == BAND == 0.2
    assert DesignConfig(tool="scriber", band=0.3).band == 0.3
    for method in ("striped", "hyperbola", "arc"):
        check_formats(("gcode", "pdf"), method)
    with pytest.raises(SpecholoError, match=r"^the pdf pattern is for .*\(got 'spin'\)$"):
        check_formats(("pdf",), "spin")


def test_cli_writes_the_stroke_pattern(tmp_path, capsys):
    out = tmp_path / "holo"
    assert main(["design", str(BUNNY), "--out", str(out), "--stipples", "40", "--method",
                 "striped", "--tool", "scriber", "--formats", "pdf"]) == 0
    assert (out / "pattern.pdf").is_file() and not (out / "hologram.gcode").exists()
    info = json.loads((out / "hologram.json").read_text())
    assert info["settings"]["band"] == HAND_BAND
    assert pypdf.PdfReader(out / "pattern.pdf").pages[0].extract_text().startswith(
        "Stroke pattern")
    capsys.readouterr()
    # no pattern for a ridged plate: one line, no traceback, nothing written
    bad = tmp_path / "ridged"
    assert main(["design", str(BUNNY), "--out", str(bad), "--method", "ridged",
                 "--formats", "pdf"]) != 0
    _, err = capsys.readouterr()
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and "pdf" in err
    assert not bad.exists()

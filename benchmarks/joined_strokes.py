"""Stripes joined into strokes, measured on the README example on a named machine.

Usage: python benchmarks/joined_strokes.py [--stipples 2000] [--machine grbl-router]

Designs the README example for the machine (its feeds), then compares three
plates: the stripes as designed; every hand-over joined by a connector that no
eye of the range sees glint (:mod:`specholo.toolpaths.joining`); and only the
connectors whose groove overlaps no other groove (a connector that crosses
another stipple's stripe cuts away that stripe's glint for the views whose
glint sits there, however few). For each: strokes, groove and connector
length, the time on the machine with a rigid and a spring holder (in cutting
order), and the plate as cut: the share of stipples both eyes see (mean and
lowest over the views) and the worst p95 error, at the design's views every
5 degrees and at views off that grid (every 1.37 degrees), with each glint's
brightness (a corner's glints are haze beside the designed ones).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from specholo.fabrication.programs.order import order_paths
from specholo.fabrication.programs.timing import estimate_time
from specholo.jobs.flat.design import design
from specholo.jobs.flat.settings import DesignConfig
from specholo.setup import Holder
from specholo.simulation.survival import as_cut_report, eye_glints, survivors
from specholo.simulation.verify import view_azimuths
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.joining import join_stripes

ROOT = Path(__file__).resolve().parents[1]
#: Spacing of the points the overlap test samples along the grooves, mm.
STEP = 0.01


def _samples(start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points every :data:`STEP` along straight pieces (k, 2) -> (p, 2), and each one's piece."""
    length = np.hypot(*(end - start).T)
    k = np.maximum(np.ceil(length / STEP).astype(int), 1) + 1
    piece = np.repeat(np.arange(len(length)), k)
    u = (np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k - 1, k)
    return start[piece] + (end - start)[piece] * u[:, None], piece


def crossing_free(grooves: Grooves, width: float):  # type: ignore[no-untyped-def]
    """A test for :func:`join_stripes`: connectors whose groove (``width`` wide)
    overlaps no groove but the two stripes it joins (arcs taken as chords: the
    stripes' arcs bulge by well under a micrometre)."""
    seg = grooves.segments()
    points, piece = _samples(seg.start, seg.end)
    owner = seg.path[piece]
    tree = cKDTree(points)

    def allow(connectors: np.ndarray) -> np.ndarray:
        a, b = connectors[:, 0], connectors[:, 1]
        q, which = _samples(a, b)
        own_a, own_b = owner[tree.query(a)[1]], owner[tree.query(b)[1]]
        bad = np.zeros(len(connectors), dtype=bool)
        for i, hits in enumerate(tree.query_ball_point(q, width + STEP / 2)):
            if hits and not bad[which[i]]:
                o = owner[hits]
                c = which[i]
                bad[c] = bool(np.any((o != own_a[c]) & (o != own_b[c])))
        return ~bad

    return allow


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--stipples", type=int, default=2000)
    parser.add_argument("--machine", default="grbl-router")
    args = parser.parse_args()
    cfg = DesignConfig.from_dict(dict(stipples=args.stipples, size=60, center_z=-40,
                                      light_elevation=45, view_distance=600, view_range=45,
                                      machine=args.machine, holder="rigid"))
    d = design(ROOT / "examples" / "bunny.obj", cfg)
    setup = d.config.setup()
    cutter, depth = d.config.cutter(), d.config.depth_mm
    width = cutter.section(depth).width
    t0 = time.perf_counter()
    every = join_stripes(d.grooves, setup)
    apart = join_stripes(d.grooves, setup, allow=crossing_free(d.grooves, width))
    print(f"README example, {args.stipples} stipples, {args.machine}; joining took "
          f"{time.perf_counter() - t0:.0f} s; {every.joined} hand-overs dark, "
          f"{apart.joined} of them crossing no other groove")
    from specholo.visibility.occlusion import Intervals

    seen_from = Intervals(d.runs.stipple, d.runs.start, d.runs.end)

    def vis(p: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        return seen_from.contains(np.arange(len(p)), np.arctan2(eyes[:, 0], eyes[:, 2]))

    grids = {"5 deg": view_azimuths(setup.viewer.half_range),
             "1.37 deg": np.radians(np.arange(-44.63, 45.0, 1.37))}
    print("plate      strokes  groove m  connector m  rigid h  spring h  "
          "as cut (5 deg)   as cut (1.37 deg)   worst p95 mm")
    for name, g, extra in (("stripes", d.grooves, 0.0),
                           ("all joins", every.grooves, every.connector_length),
                           ("no crossing", apart.grooves, apart.connector_length)):
        ordered, _ = order_paths(g)
        hours = []
        for kind in ("rigid", "spring"):
            cut_depth, machining = Holder(kind).program(depth, setup.machining)
            hours.append(estimate_time(ordered, cut_depth, machining,
                                       machine=d.config.profile).total_s / 3600.0)
        figures = []
        worst = 0.0
        for az in grids.values():
            gl = eye_glints(g, d.points, setup, cutter, depth, az)
            keep = survivors(g, gl.point, gl.path, cutter, depth)
            report = as_cut_report(gl, keep, d.points, gl.seen_by(d.points, vis))
            v = report.stereo_visibility
            figures.append(f"{np.nanmean(v):.3f} / {np.nanmin(v):.3f}")
            worst = max(worst, float(np.nanmax([r.p95_error for r in report.reports])))
        print(f"{name:11s} {g.n_paths:7d} {g.total_length() / 1000:9.1f} {extra / 1000:12.1f} "
              f"{hours[0]:8.2f} {hours[1]:9.2f}  {figures[0]:16s} {figures[1]:19s} {worst:.3f}")


if __name__ == "__main__":
    main()

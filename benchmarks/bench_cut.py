"""Time to simulate the cut of a 100 x 100 mm plate, and to find glints on it.

Usage: python benchmarks/bench_cut.py [--size 90] [--stipples 2000] [--plate 100]
       [--resolution 0.02] [--eyes 6] [--stl out.stl]

Designs the bundled bunny in-process (striped, defaults, scaled to ``--size``
mm), cuts its grooves into a ``--plate`` mm square centred on the plate origin
at ``--resolution`` mm, then finds the glints for a few eyes along the viewing
arc. Moves wholly outside the square are skipped by the sweep, so the arcs/s
figure counts only the moves that reach it.
"""

from __future__ import annotations

import argparse
import math
import resource
import time
from pathlib import Path

import numpy as np

from specholo.jobs.flat.folder import DesignConfig, design
from specholo.simulation.cut import CutCells, cut_surface, find_cut_glints, write_stl

MODEL = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--size", type=float, default=90.0)
    ap.add_argument("--stipples", type=int, default=2000)
    ap.add_argument("--plate", type=float, default=100.0)
    ap.add_argument("--resolution", type=float, default=0.02)
    ap.add_argument("--eyes", type=int, default=6)
    ap.add_argument("--stl", type=Path, default=None, help="also write the plate as STL")
    args = ap.parse_args()

    cfg = DesignConfig(size=args.size, stipples=args.stipples)
    d = design(MODEL, cfg)
    setup = d.config.setup()
    half = 0.5 * args.plate
    bounds = np.array([[-half, -half], [half, half]])
    # Compile (or load the cached kernels) on a tiny field first.
    cut_surface(d.grooves, setup.tool, setup.tool.depth, bounds=bounds / 100.0,
                resolution=args.resolution)

    t0 = time.perf_counter()
    hf = cut_surface(d.grooves, setup.tool, setup.tool.depth, bounds=bounds,
                     resolution=args.resolution)
    t_cut = time.perf_counter() - t0
    lo, hi = hf.bounds
    mid = 0.5 * (hf.program.geo[:, 0:2] + hf.program.geo[:, 2:4])
    inside = int(np.all((mid > lo - 1.0) & (mid < hi + 1.0), axis=1).sum())
    cells = hf.z.size
    t0 = time.perf_counter()
    cut = CutCells.build(hf)
    t_group = time.perf_counter() - t0

    theta = np.linspace(-setup.viewer.half_range, setup.viewer.half_range, args.eyes)
    eyes = setup.viewer.eye(theta)
    find_cut_glints(cut, eyes[0], setup.light)  # warm-up
    t0 = time.perf_counter()
    found = [find_cut_glints(cut, e, setup.light) for e in eyes]
    t_eye = (time.perf_counter() - t0) / len(eyes)
    glints = np.mean([len(f.glints.path) for f in found])

    print(f"design: bunny {args.size:g} mm, {len(d.points)} stipples, "
          f"{d.grooves.n_paths:,} paths, {len(hf.program):,} moves "
          f"({inside:,} within the plate)")
    print(f"plate:  {args.plate:g} x {args.plate:g} mm at {args.resolution:g} mm: "
          f"{hf.shape[1]} x {hf.shape[0]} = {cells / 1e6:.1f} M samples, "
          f"{100 * (hf.labels >= 0).mean():.0f}% cut")
    print(f"cut:    {t_cut:.2f} s  ({cells / t_cut / 1e6:.1f} M samples/s, "
          f"{inside / t_cut / 1e3:.0f} k moves/s)")
    print(f"group:  {t_group:.2f} s  (cut samples by move, once per field)")
    print(f"glints: {t_eye * 1e3:.0f} ms per eye  ({glints:.0f} glints per eye, "
          f"mean over {len(eyes)} eyes from {math.degrees(theta[0]):.0f} to "
          f"{math.degrees(theta[-1]):.0f} degrees)")
    if args.stl is not None:
        t0 = time.perf_counter()
        mesh = write_stl(args.stl, hf, thickness=2.0)
        print(f"stl:    {time.perf_counter() - t0:.1f} s, {len(mesh.faces):,} faces")
    print(f"peak memory: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6:.2f} GB")


if __name__ == "__main__":
    main()

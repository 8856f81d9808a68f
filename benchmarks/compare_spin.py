"""Turning plates: the solved closed grooves against circles, by plate angle.

The bunny, 40 mm, straddling the plate, 800 stipples cropped to their visible
plate angles; eyes 64 mm apart at 45 degrees' elevation; a distant light on
the axis. For each viewer distance: the classic circle about each stipple's
foot (radius |z| cot elevation), a support function with six harmonics
fitted, and the default: a circle with its centre and radius fitted, each
verified by the simulator every 5 degrees over the turn.
Prints the 95th-percentile error (depth part in brackets) every 45 degrees,
the worst over the turn, stray glints, and the design and verification speed.

    python benchmarks/compare_spin.py
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from specholo.jobs.spin.design import SpinConfig, SpinPlate, design_spin, summarise, verify_spin
from specholo.toolpaths.spinning import SpinSetup, classic_circles, design_spinning, fit_grooves

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


def main() -> None:
    for dist in (600.0, 1000.0, 1500.0):
        cfg = SpinConfig(setup=SpinSetup(distance=dist))
        t0 = time.perf_counter()
        job = design_spin(BUNNY, cfg, np.random.default_rng(0))
        t_design = time.perf_counter() - t0
        n = len(job.design.points)
        keep = job.keep  # the same crop for every groove shape
        g = job.design.grooves
        variants = {"classic circle": classic_circles(job.design.points, cfg.setup),
                    "six harmonics": fit_grooves(job.design.points,
                                                        replace(cfg.setup, harmonics=6))[0],
                    "fitted circle (default)": None}
        print(f"\nviewer at {dist:.0f} mm: {n} stipples, {g.n_paths} paths, design "
              f"{n / t_design:.0f} stipples/s")
        for name, coef in variants.items():
            if coef is None:
                d = job.design
            else:
                setup = replace(cfg.setup, harmonics=(coef.shape[1] - 1) // 2)
                d = design_spinning(job.design.points, setup, cfg.tool, keep, coef)
            j = SpinPlate(cfg, d, job.mesh, job.normals)
            t0 = time.perf_counter()
            reps = verify_spin(j, 5.0)
            t_verify = time.perf_counter() - t0
            s = summarise(reps)
            cells = " ".join(f"{r.p95_mm:.2f}({r.depth_p95_mm:.2f})" for r in reps[::9])
            print(f"  {name:22s} p95(depth) at 0,45..315 deg: {cells}")
            print(f"  {'':22s} worst p95 {s['worst_p95_mm']:.3f} mm, depth "
                  f"{s['worst_depth_p95_mm']:.3f} mm, lowest visibility "
                  f"{s['lowest_visibility']:.3f}, stray {s['stray']}; verify "
                  f"{len(reps) * n / t_verify:.0f} stipple-angles/s")
        both = replace(cfg.setup, walls="both")
        d = design_spinning(job.design.points, both, cfg.tool, coef=job.design.coef)
        reps = verify_spin(SpinPlate(replace(cfg, setup=both), d, job.mesh, job.normals), 15.0)
        print(f"  plain grooves (both walls): stray glints per angle "
              f"{np.mean([r.stray for r in reps]):.0f} (the mirror twin)")


if __name__ == "__main__":
    main()

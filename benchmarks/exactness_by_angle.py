"""What the eyes see of a default design, by view angle, on a dense azimuth grid.

Usage: python benchmarks/exactness_by_angle.py [--stipples 20000] [--step 0.25]
       [--bin 15]

Designs the bundled bunny with the defaults (striped, occlusion), verifies it
with the stereo simulator at head azimuths --step degrees apart (far closer
than the walk's samples, so errors between samples show), and prints, per bin
of --bin degrees, the worst median, 95th-percentile and depth-only
95th-percentile errors, the worst single error, the least visibility and the
most false glints over the azimuths of the bin. Run it before and after a
change to the design to see that exactness did not move.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from specholo.jobs.flat.folder import DesignConfig, design
from specholo.simulation.verify import verify, view_azimuths
from specholo.visibility.occlusion import visible

MODEL = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--stipples", type=int, default=20_000)
    ap.add_argument("--step", type=float, default=0.25, help="azimuth step, degrees")
    ap.add_argument("--bin", type=float, default=15.0, help="bin width, degrees")
    args = ap.parse_args()
    t0 = time.perf_counter()
    d = design(MODEL, DesignConfig(stipples=args.stipples))
    t1 = time.perf_counter()
    setup = d.config.setup()
    mesh, normals = d.model.mesh, d.normals
    az = view_azimuths(setup.viewer.half_range, math.radians(args.step))
    reports = verify(d.grooves, d.points, setup, lambda p, e: visible(mesh, p, normals, e), az)
    t2 = time.perf_counter()
    print(f"{args.stipples} stipples, {len(d.grooves.vertices):,} vertices: design "
          f"{t1 - t0:.1f} s, verification at {len(az)} azimuths {t2 - t1:.1f} s")
    a = np.array([[r.azimuth, r.median_error, r.p95_error, r.p95_depth_error, r.max_error,
                   r.visibility, r.false_glints] for r in reports])
    print("| azimuth, deg | median mm | p95 mm | depth p95 mm | max mm | visibility | false |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    edges = np.arange(a[0, 0], a[-1, 0] + args.bin, args.bin)
    for lo, hi in zip(edges[:-1], edges[1:], strict=False):
        m = (a[:, 0] >= lo) & ((a[:, 0] < hi) | (hi >= a[-1, 0]))
        if not m.any():
            continue
        worst = np.nanmax(a[m, 1:5], axis=0)
        print(f"| {lo:+.0f} to {min(hi, a[-1, 0]):+.0f} | " + " | ".join(f"{v:.4f}" for v in worst)
              + f" | {np.nanmin(a[m, 5]):.4f} | {np.nanmax(a[m, 6]):.5f} |")


if __name__ == "__main__":
    main()

"""Stripes joined into strokes, measured on the README example.

Usage: python benchmarks/joined_strokes.py [--stipples 2000]

Designs the README example (the as-cut step skipped), joins each stipple's
stripes where a connector stays dark (:mod:`specholo.toolpaths.joining`), and
prints for the stripes as designed and as joined: strokes, groove length,
the machining estimate at the design's feeds, and each eye's glints in the
point model of ``verify`` at a few azimuths (corner glints included).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from specholo.fabrication.timing import estimate_time
from specholo.pipeline import DesignConfig, design
from specholo.simulation.glints import Engraved, find_glints
from specholo.toolpaths.joining import join_stripes

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--stipples", type=int, default=2000)
    args = parser.parse_args()
    cfg = DesignConfig(stipples=args.stipples, size=60, center_z=-40, light_elevation=45,
                       view_distance=600, view_range=45)
    d = design(ROOT / "examples" / "bunny.obj", cfg, expect_as_cut=False)
    setup = d.config.setup()
    t0 = time.perf_counter()
    joined = join_stripes(d.grooves, setup)
    seconds = time.perf_counter() - t0
    print(f"README example, {args.stipples} stipples; joining took {seconds:.2f} s; "
          f"{joined.joined} hand-overs joined, {joined.kept_apart} kept apart")
    print("grooves     strokes   groove m   connector m   hours   glints per eye at -30/0/+30 deg")
    for name, g, extra in (("stripes", d.grooves, 0.0),
                           ("joined", joined.grooves, joined.connector_length)):
        hours = estimate_time(g, d.config.depth_mm, setup.machining).total_s / 3600.0
        eng = Engraved.from_grooves(g, setup.tool)
        counts = [len(find_glints(eng, eye, setup.light).stipple)
                  for eye in setup.viewer.eye(np.radians([-30.0, 0.0, 30.0]))]
        print(f"{name:10s} {g.n_paths:8d} {g.total_length() / 1000:10.1f} "
              f"{extra / 1000:13.1f} {hours:7.2f}   {counts}")


if __name__ == "__main__":
    main()

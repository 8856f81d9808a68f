"""Time to render a 1024x1024 still and a 90-frame turntable, by design size.

Usage: python benchmarks/bench_render.py [--sizes 10000 100000] [--turntable-sizes 10000]

Designs the bundled bunny in-process (striped, defaults). The turntable defaults
to the smaller size only: every frame finds the glints on every groove arc, so
at 100,000 stipples a frame costs seconds.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from specholo.jobs.flat.folder import DesignConfig, Loaded, design
from specholo.preview.motion import turntable
from specholo.preview.render import design_camera, render_still
from specholo.simulation.glints import Engraved

MODEL = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--turntable-sizes", type=int, nargs="*", default=[10_000])
    args = ap.parse_args()
    print(f"{'stipples':>9} {'arcs':>11} {'prepare s':>10} {'still s':>8} {'turntable s':>12} "
          f"{'frames/s':>9}")
    for n in sorted(set(args.sizes) | set(args.turntable_sizes)):
        cfg = DesignConfig(stipples=n)
        d = design(MODEL, cfg)
        setup = d.config.setup()
        t0 = time.perf_counter()
        eng = Engraved.from_grooves(d.grooves, setup.tool)
        prep = time.perf_counter() - t0
        camera = design_camera(setup, d.grooves, width=1024, height=1024)
        still = float("nan")
        if n in args.sizes:
            t0 = time.perf_counter()
            render_still(d.grooves, setup, camera, engraved=eng)
            still = time.perf_counter() - t0
        spin = float("nan")
        if n in args.turntable_sizes:
            loaded = Loaded(d.config, d.points, d.normals, d.grooves, d.model.mesh)
            t0 = time.perf_counter()
            turntable(loaded, 90, size=(512, 512))
            spin = time.perf_counter() - t0
        print(f"{n:>9} {len(eng.path):>11,} {prep:>10.1f} {still:>8.2f} {spin:>12.1f} "
              f"{90 / spin:>9.1f}")


if __name__ == "__main__":
    main()

"""A still viewer under a sun that moves a little: scoops against plain grooves.

The bunny, 40 mm, centred 20 mm behind the plate, 300 stipples of which those
both eyes see are kept; eyes 64 mm apart, 600 mm straight in front; the sun at
45 degrees' elevation moving either way by 1 to 10 degrees; a 0.05 mm ball cut
0.02 mm deep. For each range and shape the simulator moves the sun every
half degree and prints the worst 95th-percentile image drift (how far the
triangulated points move from where they are with the sun at 45 degrees), the
lowest visibility, the stray glints, and the design and verification speed.

    python benchmarks/compare_steady.py
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import numpy as np

from specholo.jobs.steady.design import SteadyConfig, design_steady_job, light_steps, summarise
from specholo.simulation.steady import verify_steady
from specholo.toolpaths.steady import SteadySetup

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


def main() -> None:
    print(f"load average {os.getloadavg()[0]:.1f}")
    for half in (1.0, 2.0, 5.0, 10.0):
        for shape in ("flat", "scoop"):
            cfg = SteadyConfig(shape=shape, setup=SteadySetup(light_sweep=math.radians(half)))
            t0 = time.perf_counter()
            d = design_steady_job(BUNNY, cfg, np.random.default_rng(0))
            t_design = time.perf_counter() - t0
            els = light_steps(cfg.setup, 0.5)
            t0 = time.perf_counter()
            reps = verify_steady(d, cfg.tool, els)
            t_verify = time.perf_counter() - t0
            s = summarise(reps)
            by = " ".join(f"{r.drift_p95_mm:.2f}" for r in reps[::max(1, len(reps) // 4)])
            print(f"light 45 +-{half:4.1f} deg {shape:5s}: {len(d.points)} stipples "
                  f"({d.dropped} dropped), worst drift p95 {s['worst_drift_p95_mm']:.3f} mm "
                  f"[{by}], lowest visibility {s['lowest_visibility']:.3f}, stray "
                  f"{s['stray']}; design {len(d.points) / t_design:.0f} stipples/s, verify "
                  f"{len(reps) * len(d.points) / t_verify:.0f} stipple-lights/s")


if __name__ == "__main__":
    main()

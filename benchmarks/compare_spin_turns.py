"""Turning plates whose view circles the scene twice per turn (720 degrees): the
bunny on the first half turn, the knot on the second, by plate angle.

Both models 40 mm, straddling the plate, about 400 stipples shown at once; eyes
64 mm apart at 45 degrees' elevation; a distant light on the axis. For each
viewer distance the simulator verifies, every 5 degrees over the turn:

- "fixed to the scene": each stipple stays on its point of the turning model
  (the obvious design), with the best open groove least squares can fit to it;
- "sliding (default)": the stipples slide over the turning models along their
  sightlines, which the groove condition allows.

Both use the same lives (the angles where each stipple is shown). Prints the
95th-percentile error every 45 degrees (depth part in brackets), the worst,
the lowest visibility, stray glints, and the design and verification speed.

    python benchmarks/compare_spin_turns.py
"""

from __future__ import annotations

import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from specholo.jobs.spin.design import SpinConfig, SpinPlate, design_spin, summarise, verify_spin
from specholo.toolpaths.sliding import design_sliding, scene_angle
from specholo.toolpaths.spinning import SpinSetup, rotate_z

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def fixed_to_scene(job: SpinPlate) -> SpinPlate:
    """The same lives, each stipple kept on the model point where it was born."""
    t = job.design.tracks
    first = t.alive.argmax(axis=1)
    n = len(t)
    born = t.position[np.arange(n), first]
    home = rotate_z(born, -scene_angle(t.turns, t.phi[first]))  # in the model's frame
    pos = rotate_z(home[:, None, :], scene_angle(t.turns, t.phi)[None, :])
    fixed = replace(t, position=np.where(t.alive[..., None], pos, np.nan), shown=None)
    d = design_sliding(fixed, job.config.setup, job.config.tool)
    return replace(job, design=d)


def main() -> None:
    print(f"load average {os.getloadavg()[0]:.1f}")
    for dist in (600.0, 1000.0, 1500.0):
        cfg = SpinConfig(stipples=400, turns=2, setup=SpinSetup(distance=dist))
        t0 = time.perf_counter()
        job = design_spin([EXAMPLES / "bunny.obj", EXAMPLES / "knot.obj"], cfg,
                          np.random.default_rng(0))
        t_design = time.perf_counter() - t0
        d = job.design
        shown = d.tracks.shown.sum(axis=0).mean()
        print(f"\nviewer at {dist:.0f} mm: {len(d.tracks)} tracks, about {shown:.0f} shown "
              f"at once, {d.grooves.total_length() / 1000:.1f} m of groove, design "
              f"{t_design:.1f} s ({len(d.tracks) / t_design:.0f} tracks/s)")
        for name, j in (("fixed to the scene", fixed_to_scene(job)),
                        ("sliding (default)", job)):
            t0 = time.perf_counter()
            reps = verify_spin(j, 5.0)
            t_verify = time.perf_counter() - t0
            s = summarise(reps)
            cells = " ".join(f"{r.p95_mm:.2f}({r.depth_p95_mm:.2f})" for r in reps[::9])
            work = sum(r.shown for r in reps)
            print(f"  {name:20s} p95(depth) at 0,45..315 deg: {cells}")
            print(f"  {'':20s} worst p95 {s['worst_p95_mm']:.3f} mm, depth "
                  f"{s['worst_depth_p95_mm']:.3f} mm, lowest visibility "
                  f"{s['lowest_visibility']:.3f}, stray {s['stray']} "
                  f"({s['stray'] / max(work, 1):.2%} of the glints meant); verify "
                  f"{work / t_verify:.0f} stipple-angles/s")


if __name__ == "__main__":
    main()

"""How far the studio's quick figures fall from the exact design's.

For each scene (the bundled bunny posed and lit several ways, 1,000 to 3,000
stipples), designs exactly (``specholo.jobs.flat.folder.design``, then the
machining estimate on the grooves in cutting order) and asks the studio's
estimate (``specholo.studio.estimate.estimate``: the exact design of a strip
of the plate at full density), and prints both, the differences and the
seconds each took.

    python benchmarks/studio_estimates.py
"""

from __future__ import annotations

import time
from pathlib import Path

from specholo.fabrication.programs.order import order_paths
from specholo.jobs.flat.design import design
from specholo.jobs.flat.folder import DesignConfig, machining_estimate
from specholo.studio.estimate import estimate

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
SCENES = [
    {"stipples": 1000},
    {"stipples": 2000},
    {"stipples": 3000},
    {"stipples": 1000, "rotate_y": 60},
    {"stipples": 1500, "light_elevation": 30, "center_z": -20},
    {"stipples": 2000, "size": 80, "view_range": 30},
    {"stipples": 2000, "machine": "grbl-router"},
    {"stipples": 1000, "up": "z", "rotate_x": -20, "light_elevation": 60},
]


def main() -> None:
    print("| scene | as cut, exact (mean / lowest) | estimate | strokes exact / estimate "
          "| hours exact / estimate | seconds exact / estimate |")
    print("|---|---|---|---|---|---|")
    worst = {"mean": 0.0, "lowest": 0.0, "strokes": 0.0, "hours": 0.0}
    for scene in SCENES:
        config = DesignConfig.from_dict(scene)
        t0 = time.perf_counter()
        d = design(BUNNY, config)
        grooves = order_paths(d.grooves)[0]
        hours = machining_estimate(d.config, grooves)[2].total_s / 3600.0
        exact_s = time.perf_counter() - t0
        mean, lowest, _ = d.as_cut.mean_and_lowest()
        quick = estimate(BUNNY, config)
        worst["mean"] = max(worst["mean"], abs(quick["as_cut_mean"] - mean))
        worst["lowest"] = max(worst["lowest"], abs(quick["as_cut_lowest"] - lowest))
        worst["strokes"] = max(worst["strokes"], abs(quick["strokes"] / d.grooves.n_paths - 1))
        worst["hours"] = max(worst["hours"], abs(quick["machining_hours"] / hours - 1))
        name = ", ".join(f"{k} {v}" for k, v in scene.items())
        print(f"| {name} | {mean:.3f} / {lowest:.3f} | {quick['as_cut_mean']:.3f} / "
              f"{quick['as_cut_lowest']:.3f} | {d.grooves.n_paths:,} / {quick['strokes']:,} | "
              f"{hours:.2f} / {quick['machining_hours']:.2f} | {exact_s:.1f} / "
              f"{quick['seconds']:.1f} |", flush=True)
    print(f"\nworst: as cut mean {worst['mean']:.3f}, lowest {worst['lowest']:.3f}; strokes "
          f"{100 * worst['strokes']:.0f}%, hours {100 * worst['hours']:.0f}%")


if __name__ == "__main__":
    main()

"""Three-way comparison of the designs on the bundled bunny, as a Markdown table.

Usage: python benchmarks/compare_designs.py [--stipples 2000]

Runs the README's main job (sun at 45 degrees, viewer at 600 mm, +-45 degrees)
with each design method and verifies each with the stereo simulator.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from specholo.jobs.flat.folder import DesignConfig, Loaded, design, verify_design

MODEL = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--stipples", type=int, default=2000)
    args = ap.parse_args()
    results = {}
    for method in ("striped", "hyperbola", "arc"):
        cfg = DesignConfig(size=60, center_z=-40, light_elevation=45, view_distance=600,
                           view_range=45, stipples=args.stipples, method=method)
        d = design(MODEL, cfg)
        results[method] = verify_design(Loaded(d.config, d.points, d.normals, d.grooves,
                                                d.model.mesh))
    print("| azimuth | striped p95 (depth) | visib. | hyperbola p95 (depth) | visib. "
          "| arc p95 (depth) | visib. |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for i, r in enumerate(results["striped"]):
        cells = [f"{r.azimuth:+.0f}°"]
        for method in ("striped", "hyperbola", "arc"):
            x = results[method][i]
            cells += [f"{x.p95_error:.2f} ({x.p95_depth_error:.2f})", f"{x.visibility:.3f}"]
        print("| " + " | ".join(cells) + " |")
    for method, reps in results.items():
        print(f"{method}: worst false-glint share "
              f"{max(r.false_glints for r in reps):.4f}")


if __name__ == "__main__":
    main()

"""Throughput of the design pipeline and of the writers on the bundled bunny.

Usage: python benchmarks/bench_pipeline.py [--sizes 10000 100000] [--method striped]

Each size runs in a fresh process so its peak memory (max RSS) is its own.
Prints stipples per second for the design (stippling, occlusion, toolpaths)
and, separately, for writing the outputs.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "bunny.obj"


def run_one(n: int, method: str) -> dict[str, float]:
    from specholo.jobs.flat.folder import DesignConfig, design, write_design

    cfg = DesignConfig(stipples=n, method=method)
    t0 = time.perf_counter()
    d = design(MODEL, cfg)
    t_design = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        parts = write_design(d, Path(tmp) / "out").timings
        t_write = time.perf_counter() - t0
        size = sum(f.stat().st_size for f in (Path(tmp) / "out").iterdir())
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {"stipples": n, "design_s": t_design, "write_s": t_write,
            **{f"{k}_s": v for k, v in d.timings.items()},
            **{f"write_{k}_s": v for k, v in parts.items()},
            "paths": d.grooves.n_paths, "arcs": len(d.grooves.vertices),
            "output_mb": size / 1e6, "peak_rss_mb": peak}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--method", default="striped")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(args.one, args.method)))
        return
    print(f"{'stipples':>9} {'design/s':>10} {'write/s':>10} {'stipple s':>9} {'occl s':>7} "
          f"{'paths s':>7} {'gcode s':>7} {'svg s':>6} {'paths':>9} {'MB out':>7} {'peak MB':>8}")
    for n in args.sizes:
        out = subprocess.run([sys.executable, __file__, "--one", str(n), "--method", args.method],
                             check=True, capture_output=True, text=True).stdout
        r = json.loads(out.strip().splitlines()[-1])
        print(f"{n:>9} {n / r['design_s']:>10.0f} {n / r['write_s']:>10.0f} "
              f"{r['stippling_s']:>9.2f} {r['occlusion_s']:>7.2f} {r['toolpaths_s']:>7.2f} "
              f"{r['write_gcode_s']:>7.2f} {r['write_svg_s']:>6.2f} {r['paths']:>9} "
              f"{r['output_mb']:>7.1f} {r['peak_rss_mb']:>8.0f}")


if __name__ == "__main__":
    main()

"""Throughput of the cutting order and the G-code writer on designs of the bundled bunny.

Usage: python benchmarks/bench_gcode.py [--sizes 10000 100000] [--dialect grbl]

Each size runs in a fresh process (its peak memory is its own). The design is
made in-process and not timed; then order_paths and write_gcode are timed
separately (compiled code is warmed up on a small design first). Prints paths
per second for each, the air travel before and after ordering, and the
estimated machining time of both orders.
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


def run_one(n: int, dialect: str) -> dict[str, float]:
    from specholo.fabrication.programs.gcode import write_gcode
    from specholo.fabrication.programs.order import order_paths
    from specholo.fabrication.programs.program import GcodeOptions
    from specholo.fabrication.programs.timing import estimate_time
    from specholo.jobs.flat.folder import DesignConfig, design

    d = design(MODEL, DesignConfig(stipples=n))
    setup = d.config.setup()
    grooves = d.grooves
    options = GcodeOptions(dialect=dialect)  # type: ignore[arg-type]
    with tempfile.TemporaryDirectory() as tmp:
        # warm up the compiled kernels so their compilation is not timed
        small = type(grooves)(grooves.vertices[:grooves.offsets[50]],
                              grooves.bulges[:grooves.offsets[50]],
                              grooves.offsets[:51], grooves.stipple[:50])
        order_paths(small)
        write_gcode(Path(tmp) / "warm.ngc", small, setup.tool, setup.machining, options=options)

        t0 = time.perf_counter()
        ordered, stats = order_paths(grooves)
        t_order = time.perf_counter() - t0
        out = Path(tmp) / "hologram.ngc"
        t0 = time.perf_counter()
        written = write_gcode(out, ordered, setup.tool, setup.machining, options=options)
        t_write = time.perf_counter() - t0
        size = out.stat().st_size
    t0 = time.perf_counter()
    before = estimate_time(grooves, setup.tool.depth, setup.machining)
    after = estimate_time(ordered, setup.tool.depth, setup.machining)
    t_time = (time.perf_counter() - t0) / 2
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {"stipples": n, "paths": grooves.n_paths, "arcs": len(grooves.vertices),
            "order_s": t_order, "write_s": t_write, "estimate_s": t_time,
            "lines": written.lines, "mb": size / 1e6,
            "travel_before_m": stats.travel_before_mm / 1e3,
            "travel_after_m": stats.travel_after_mm / 1e3,
            "hours_before": before.total_s / 3600, "hours_after": after.total_s / 3600,
            "cutting_h": after.cutting_s / 3600, "rapid_h_before": before.rapid_s / 3600,
            "rapid_h_after": after.rapid_s / 3600, "plunge_h": after.plunge_s / 3600,
            "stipples_per_s": after.stipples_per_s, "peak_rss_mb": peak}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--dialect", default="grbl", choices=["grbl", "linuxcnc", "marlin"])
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(args.one, args.dialect)))
        return
    print(f"{'stipples':>9} {'paths':>9} {'order s':>8} {'order/s':>9} {'write s':>8} "
          f"{'write/s':>9} {'MB':>7} {'travel m':>17} {'saved':>6} {'machining h':>15} "
          f"{'stipples/s':>10} {'peak MB':>8}")
    for n in args.sizes:
        out = subprocess.run([sys.executable, __file__, "--one", str(n), "--dialect",
                              args.dialect], check=True, capture_output=True, text=True).stdout
        r = json.loads(out.strip().splitlines()[-1])
        p = r["paths"]
        saved = 1.0 - r["travel_after_m"] / r["travel_before_m"]
        print(f"{n:>9} {p:>9} {r['order_s']:>8.2f} {p / r['order_s']:>9.0f} "
              f"{r['write_s']:>8.2f} {p / r['write_s']:>9.0f} {r['mb']:>7.1f} "
              f"{r['travel_before_m']:>8.1f}->{r['travel_after_m']:<8.1f} {saved:>6.1%} "
              f"{r['hours_before']:>6.2f}->{r['hours_after']:<7.2f} "
              f"{r['stipples_per_s']:>10.3f} {r['peak_rss_mb']:>8.0f}")
        print("  machining after ordering: "
              f"cutting {r['cutting_h']:.2f} h, plunges {r['plunge_h']:.2f} h, rapids "
              f"{r['rapid_h_before']:.2f} -> {r['rapid_h_after']:.2f} h "
              f"(estimate {r['estimate_s']:.2f} s per call)")


if __name__ == "__main__":
    main()

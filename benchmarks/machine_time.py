"""The README example's machining time on every machine profile.

Usage: python benchmarks/machine_time.py [--methods striped arc] [--json out.json]

Designs the README's example (``specholo design examples/bunny.obj --size 60
--center-z -40 --light-elevation 45 --view-distance 600 --view-range 45
--stipples 2000``, default drag tip) by each method as ``specholo design
--machine NAME`` designs it (a machine whose strokes lift the tool widens the
striped band; one design serves every machine of the same band), puts its
paths in cutting order as ``write_design`` does, and estimates the program's
time as it does (:func:`specholo.fabrication.programs.timing.estimate_time`, a drag tip
in its default spring holder: each stroke plunges from the 0.05 mm lift to the
0.3 mm preload) with no machine (every axis at 250 mm/s^2, rapids at
3000 mm/min, the default 300 mm/min feed) and on every profile of
:data:`specholo.fabrication.programs.machines.MACHINES` at that profile's own feeds.
Each row gives the band, the strokes, the whole time and its parts; they add
up to it.

The estimates are the same on any computer; only the design's own run time
(printed first) depends on the one it runs on.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "bunny.obj"
#: The README example's settings.
EXAMPLE = {"size": 60.0, "center_z": -40.0, "light_elevation": 45.0, "view_distance": 600.0,
           "view_range": 45.0, "stipples": 2000}
#: The parts of an estimate, as TimeEstimate names them, with the table's headings.
PARTS = (("cutting_s", "cutting"), ("hop_s", "hops"), ("plunge_s", "plunges"),
         ("rapid_s", "rapids/travel"), ("lift_s", "pen lifts"), ("delay_s", "laser delays"),
         ("dwell_s", "dwell"))


def hours(seconds: float) -> str:
    """Seconds as hours and minutes, 'h:mm'."""
    minutes = round(seconds / 60.0)
    return f"{minutes // 60}:{minutes % 60:02d}"


def estimate(name: str | None, grooves: Any, depth: float) -> dict[str, Any]:
    """The grooves' time with no machine (None) or on the profile ``name``, at its feeds."""
    from specholo.fabrication.programs.timing import estimate_time
    from specholo.jobs.flat.settings import DesignConfig

    config = DesignConfig.from_dict({} if name is None else {"machine": name})
    profile = config.profile
    laser = config.dialect == "marlin"
    # timed as write_design times the program: a spring holder (a drag tip's
    # default) plunges from its lift to its preload on every stroke
    holder = None if laser else config.holder_setup()
    machining = config.setup().machining
    depth_z, machining = (holder.program(depth, machining) if holder is not None
                          else (depth, machining))
    est = estimate_time(grooves, depth_z, machining, laser=laser, machine=profile)
    row = {"machine": name or "none", "feed_mm_min": config.feed,
           "total_s": est.total_s, "stipples_per_s": est.stipples_per_s,
           "hops": est.hops, "paths": grooves.n_paths}
    row.update({key: getattr(est, key) for key, _ in PARTS})
    assert abs(sum(row[key] for key, _ in PARTS) - est.total_s) <= 1e-9 * est.total_s
    return row


def report(method: str, paths: int, length_m: float, rows: list[dict[str, Any]]) -> None:
    """A markdown table of one method's rows."""
    print(f"\n{method}: {paths:,} paths, {length_m:.1f} m of groove\n")
    print("| machine | band mm | strokes | feed mm/min | total h:mm | "
          + " | ".join(h for _, h in PARTS) + " | stipples/s |")
    print("|---|---:|---:|---:|---:|" + "---:|" * len(PARTS) + "---:|")
    for r in rows:
        print(f"| {r['machine']} | {r['band']} | {r['paths']:,} | {r['feed_mm_min']:g} | "
              f"{hours(r['total_s'])} | " + " | ".join(hours(r[key]) for key, _ in PARTS)
              + f" | {r['stipples_per_s']:.2f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", nargs="+", default=["striped", "arc"])
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT / "src"))
    from specholo.fabrication.programs.machines import MACHINES
    from specholo.fabrication.programs.order import order_paths
    from specholo.jobs.flat.folder import DesignConfig, design

    results = {}
    for method in args.methods:
        designs: dict[Any, Any] = {}  # by band share: one design a band
        rows = []
        seconds = 0.0
        for name in (None, *MACHINES):
            settings = {**EXAMPLE, "method": method, **({"machine": name} if name else {})}
            key = DesignConfig.from_dict(settings).band_share
            if key not in designs:
                t0 = time.perf_counter()
                d = design(MODEL, DesignConfig.from_dict(settings))
                grooves, _ = order_paths(d.grooves)  # the cutting order write_design writes
                seconds += time.perf_counter() - t0
                designs[key] = (d, grooves)
            d, grooves = designs[key]
            row = estimate(name, grooves, d.config.depth_mm)
            row["band"] = f"{d.config.band:g}" if method == "striped" else "-"
            rows.append(row)
        print(f"{method}: {len(designs)} designs, designed and ordered in {seconds:.1f} s",
              file=sys.stderr)
        d, grooves = designs[None]
        report(method, grooves.n_paths, grooves.total_length() / 1000.0, rows)
        results[method] = {"paths": grooves.n_paths, "groove_m": grooves.total_length() / 1000,
                           "design_s": seconds, "rows": rows}
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()

"""Machining time of the README example, as cut: striped against the classic arcs.

Usage: python benchmarks/bench_machining.py [--methods striped arc hyperbola]
       [--hop-max 0 3] [--set name=value ...] [--json out.json]

Designs the README's example (``specholo design examples/bunny.obj --size 60
--center-z -40 --light-elevation 45 --view-distance 600 --view-range 45
--stipples 2000``, default drag tip and feeds) by each method, writes its folder
with each longest hop given (``--hop-max``; 0 is the program without hops, as
every program was before hops; ``--set`` adds design settings, e.g.
``--set feed=600``), and reports for each:

- paths, groove length, hops and their travel;
- the *plain sum*: the written hologram.gcode read back, every move's length
  over its feed (G1/G2/G3 at their F, arcs along the arc; G0 at the rapid rate
  the estimate assumes, 3000 mm/min; G4 its time), split by what the move does:
  cut (in X/Y below the surface), hop (in X/Y above the surface, below the safe
  height), plunge (Z down at a feed), retract (Z up), rapid travel (in X/Y at
  the safe height), dwell;
- the design's own estimate (hologram.json machining: ``estimate_time`` with
  its acceleration, 250 mm/s^2) and its split (cutting, hop, rapid, plunge,
  dwell);
- the same estimate with the acceleration taken away (1e12 mm/s^2): the model
  of the program alone, which must equal the plain sum (to the written
  rounding); so the estimate minus the plain sum is the time the machine
  spends getting up to speed and braking, shown by kind of move;
- the ratio of each total to the classic arcs' (``--method arc``) with the same
  hops.

Nothing is timed on this machine; the figures are the same on any.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import re
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "bunny.obj"
#: The README example's settings.
EXAMPLE = {"size": 60.0, "center_z": -40.0, "light_elevation": 45.0, "view_distance": 600.0,
           "view_range": 45.0, "stipples": 2000}
#: The rapid (G0) rate estimate_time assumes, mm/min.
RAPID = 3000.0
#: An acceleration high enough that no move spends measurable time reaching its feed.
NO_ACCEL = 1e12

_WORD = re.compile(r"([A-Z])([-+]?\d*\.?\d+)")
KINDS = ("cut", "hop", "plunge", "retract", "rapid", "dwell")


def plain_sum(path: Path) -> dict[str, Any]:
    """Seconds (and mm) of every move of a program over its feed, by kind.

    The job starts above the origin at the first Z it is sent to (the writer's
    first move is ``G0 Z<safe>``).
    """
    seconds = dict.fromkeys(KINDS, 0.0)
    length = dict.fromkeys(KINDS, 0.0)
    count = dict.fromkeys(KINDS, 0)
    x = y = 0.0
    z = math.nan
    feed = math.nan
    motion = 0
    factor = 1.0
    with open(path, encoding="ascii") as fh:
        for raw in fh:
            # Parenthesised comments first: one may hold a ';' (the plate-zero note).
            line = re.sub(r"\(.*?\)", "", raw).split(";")[0].strip().upper()
            if not line:
                continue
            words = dict(_WORD.findall(line.replace(" ", "")))
            codes = [float(v) for k, v in _WORD.findall(line.replace(" ", "")) if k == "G"]
            if 20.0 in codes:
                factor = 25.4
            if 21.0 in codes:
                factor = 1.0
            if 4.0 in codes:
                seconds["dwell"] += float(words.get("P", 0.0))
                count["dwell"] += 1
                continue
            for g in codes:
                if g in (0.0, 1.0, 2.0, 3.0):
                    motion = int(g)
            if "F" in words:
                feed = float(words["F"]) * factor
            if not any(k in words for k in "XYZ"):
                continue
            nx = float(words["X"]) * factor if "X" in words else x
            ny = float(words["Y"]) * factor if "Y" in words else y
            nz = float(words["Z"]) * factor if "Z" in words else z
            if math.isnan(z):  # the first move: from above the origin at this height
                z = nz
            dz = nz - z
            if motion >= 2:
                cx = x + float(words.get("I", 0.0)) * factor
                cy = y + float(words.get("J", 0.0)) * factor
                a0 = math.atan2(y - cy, x - cx)
                turn = math.atan2(ny - cy, nx - cx) - a0
                sweep = turn % (2 * math.pi) if motion == 3 else (-turn) % (2 * math.pi)
                if nx == x and ny == y:
                    sweep = 2 * math.pi
                xy = math.hypot(x - cx, y - cy) * sweep
            else:
                xy = math.hypot(nx - x, ny - y)
            d = math.hypot(xy, dz)
            rate = RAPID if motion == 0 else feed
            if xy > 0:
                kind = "rapid" if motion == 0 else ("cut" if min(z, nz) < 0 else "hop")
            else:
                kind = "retract" if dz > 0 else ("rapid" if motion == 0 else "plunge")
            seconds[kind] += 60.0 * d / rate
            length[kind] += d
            count[kind] += 1
            x, y, z = nx, ny, nz
    return {"s": seconds, "mm": length, "moves": count, "total_s": sum(seconds.values())}


def run(d: Any, hop_max: float, out: Path) -> dict[str, Any]:
    """Write the design's folder with this longest hop; its figures."""
    from specholo.fabrication.programs.timing import estimate_time
    from specholo.jobs.flat.folder import write_design
    from specholo.toolpaths.grooves import Grooves

    config = dataclasses.replace(d.config, hop_max=hop_max)
    d = dataclasses.replace(d, config=config)
    written = write_design(d, out, formats=("gcode",))
    machining = written.machining
    plain = plain_sum(out / "hologram.gcode")
    setup = config.setup()
    ordered = Grooves.load(out / "grooves.npz")  # in cutting order
    bare = estimate_time(ordered, config.depth_mm, setup.machining, accel=NO_ACCEL,
                         dwell=plain["s"]["dwell"])
    estimate = {k: machining[f"{k}_hours"] * 3600.0 for k in
                ("cutting", "hop", "rapid", "plunge")}
    # the rest is the dwell (the sum rounds a hair either way of 0 without one)
    estimate["dwell"] = max(machining["estimated_hours"] * 3600.0 - sum(estimate.values()), 0.0)
    return {
        "method": config.method, "hop_max_mm": hop_max, "hop_mm": setup.machining.hop,
        "paths": ordered.n_paths, "groove_m": ordered.total_length() / 1e3,
        "hops": machining["hops"], "hop_m": plain["mm"]["hop"] / 1e3,
        "travel_m": plain["mm"]["rapid"] / 1e3,
        "plain_h": plain["total_s"] / 3600.0,
        "plain_split_h": {k: v / 3600.0 for k, v in plain["s"].items()},
        "plain_moves": plain["moves"],
        "estimate_h": machining["estimated_hours"],
        "estimate_split_h": {k: v / 3600.0 for k, v in estimate.items()},
        "no_accel_h": bare.total_s / 3600.0,
        "no_accel_split_h": {"cutting": bare.cutting_s / 3600.0, "hop": bare.hop_s / 3600.0,
                             "rapid": bare.rapid_s / 3600.0, "plunge": bare.plunge_s / 3600.0,
                             "dwell": bare.dwell_s / 3600.0},
    }


def budget(r: dict[str, Any], arcs: dict[str, Any], total: str, cut: float) -> str:
    """What a design would need to machine within 2x the arcs by one measure:
    its time is cutting (in proportion to the groove length) plus a time per
    path (plunge, retract and the move over); ``total`` names the measure's
    total, ``cut`` is its cutting hours."""
    target = 2.0 * arcs[total]
    per_path = (r[total] - cut) / r["paths"]
    length = (target - r[total] + cut) / cut * r["groove_m"]
    paths = (target - cut) / per_path
    return (f"2x arcs = {target:.2f} h: cutting alone {cut:.2f} h ({cut / arcs[total]:.2f}x), "
            f"{3600 * per_path:.3f} s a path besides; with {r['paths']} paths the grooves could "
            f"be {max(length, 0.0):.1f} m (not {r['groove_m']:.1f}), with {r['groove_m']:.1f} m "
            f"of groove {max(paths, 0.0):.0f} paths")


def report(rows: list[dict[str, Any]]) -> None:
    arcs = {r["hop_max_mm"]: r for r in rows if r["method"] == "arc"}
    print(f"rapids at {RAPID:g} mm/min (the estimate's); estimate's acceleration 250 mm/s^2")
    def ratio(r: dict[str, Any], a: dict[str, Any] | None) -> str:
        if a is None:
            return "-"
        return f"{r['plain_h'] / a['plain_h']:.2f}/{r['estimate_h'] / a['estimate_h']:.2f}"

    print(f"{'method':>10} {'hop max':>7} {'paths':>6} {'groove m':>8} {'hops':>6} "
          f"{'hop m':>6} {'plain h':>7} {'estim h':>7} {'no-acc h':>8} "
          f"{'x arcs':>10} {'x arcs 0':>10}")
    for r in rows:
        print(f"{r['method']:>10} {r['hop_max_mm']:>7g} {r['paths']:>6} {r['groove_m']:>8.2f} "
              f"{r['hops']:>6} {r['hop_m']:>6.2f} {r['plain_h']:>7.2f} {r['estimate_h']:>7.2f} "
              f"{r['no_accel_h']:>8.2f} {ratio(r, arcs.get(r['hop_max_mm'])):>10} "
              f"{ratio(r, arcs.get(0.0)):>10}")
    print("(x arcs: plain sum / estimate over the arcs' with the same hop max; x arcs 0: over "
          "the arcs' without hops, as cut before; no-acc: the estimate's model without "
          "acceleration, equal to the plain sum)")
    for r in rows:
        p, e, b = r["plain_split_h"], r["estimate_split_h"], r["no_accel_split_h"]
        print(f"\n{r['method']}, hop max {r['hop_max_mm']:g} mm (hop {r['hop_mm']:g} mm): "
              f"where the time goes, h")
        print("  plain sum:  " + ", ".join(f"{k} {p[k]:.2f}" for k in KINDS)
              + f"  (moves: {', '.join(f'{k} {v}' for k, v in r['plain_moves'].items())})")
        print("  estimate:   " + ", ".join(f"{k} {v:.2f}" for k, v in e.items()))
        print("  no accel:   " + ", ".join(f"{k} {v:.2f}" for k, v in b.items()))
        # rapid in the estimate = rapid travel + retracts of the plain sum
        print("  estimate - plain sum, by kind (acceleration): "
              f"cutting {e['cutting'] - p['cut']:+.2f}, hop {e['hop'] - p['hop']:+.2f}, "
              f"rapid and retract {e['rapid'] - p['rapid'] - p['retract']:+.2f}, "
              f"plunge {e['plunge'] - p['plunge']:+.2f}; total "
              f"{r['estimate_h'] - r['plain_h']:+.2f} over {r['paths']} paths "
              f"({3600 * (r['estimate_h'] - r['plain_h']) / max(r['paths'], 1):.3f} s a path)")
        a = arcs.get(r["hop_max_mm"])
        if a is not None and r["method"] != "arc":
            print("  within 2x the arcs by the plain sum: "
                  + budget(r, a, "plain_h", p["cut"]))
            print("  within 2x the arcs by the estimate:  "
                  + budget(r, a, "estimate_h", e["cutting"]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--methods", nargs="+", default=["striped", "arc", "hyperbola"])
    ap.add_argument("--hop-max", type=float, nargs="+", default=[0.0, 3.0],
                    help="longest hops to write, mm (0: no hops) [0 3]")
    ap.add_argument("--set", nargs="+", default=[], metavar="NAME=VALUE",
                    help="further design settings (numbers as numbers)")
    ap.add_argument("--json", type=Path, help="also write the rows here")
    args = ap.parse_args()
    extra: dict[str, Any] = {}
    for item in args.set:
        name, _, value = item.partition("=")
        try:
            extra[name] = json.loads(value)
        except json.JSONDecodeError:
            extra[name] = value

    from specholo.jobs.flat.folder import DesignConfig, design

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for method in args.methods:
            settings = {**EXAMPLE, **extra, "method": method}
            d = design(MODEL, DesignConfig.from_dict(settings))
            for k, hop_max in enumerate(args.hop_max):
                rows.append(run(d, hop_max, Path(tmp) / f"{method}{k}"))
                print(f"{method}, hop max {hop_max:g}: done", file=sys.stderr)
    report(rows)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()

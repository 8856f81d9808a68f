"""Stripes that end together: the README example placed three ways, under a
point light and under real ones (the table of docs/verification.md, "Stripes
that end together").

Designs the README example on the GRBL router with the band held at 0.2 mm,
placed by ``auto`` (the default: ``avoid`` at this size), ``phase`` and
``lock``, and verifies each: as points every 5 degrees, and every degree under
the sun on a mirror finish (ideal and as cut, ``--cut``) and under a lamp
0.25 deg across. Prints a Markdown table: strokes, the machining estimate on
the router, the worst p95 error (and, under the sun, its median over the
views) and lowest stereo visibility of each, and the false glints from stripe
ends per eye (mean over the views / most).

    python benchmarks/lock_figures.py [--out results/lock.json] [--stipples 2000]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = ["--size", "60", "--center-z", "-40", "--light-elevation", "45", "--view-distance",
         "600", "--view-range", "45", "--machine", "grbl-router", "--band", "0.2"]
PLACEMENTS = ("auto", "phase", "lock")


def _specholo(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "specholo_cli.cli", *args], check=True,
                   stdout=subprocess.DEVNULL)


def _verify(folder: Path, *options: str) -> tuple[dict, dict | None]:
    """verify.json (and verify_cut.json with --cut) of one run."""
    for name in ("verify.json", "verify_cut.json"):
        (folder / name).unlink(missing_ok=True)
    _specholo("verify", str(folder), *options)
    cut = folder / "verify_cut.json"
    return (json.loads((folder / "verify.json").read_text()),
            json.loads(cut.read_text()) if cut.is_file() else None)


def _median(values: list[float]) -> float:
    v = sorted(values)
    return 0.5 * (v[(len(v) - 1) // 2] + v[len(v) // 2])


def _spills(report: dict) -> tuple[float, float]:
    spills = [r.get("end_spills", 0.0) for r in report["azimuths"]]
    return sum(spills) / len(spills), max(spills)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="also write the rows as JSON")
    parser.add_argument("--stipples", default="2000")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for placement in PLACEMENTS:
            folder = Path(tmp) / placement
            _specholo("design", str(ROOT / "examples" / "bunny.obj"), "--out", str(folder),
                      *SCENE, "--stipples", args.stipples, "--placement", placement)
            info = json.loads((folder / "hologram.json").read_text())
            point, _ = _verify(folder)
            sun, sun_cut = _verify(folder, "--step", "1", "--cut", "--light-size", "0.53",
                                   "--roughness", "mirror")
            lamp, _ = _verify(folder, "--step", "1", "--light-size", "0.25",
                              "--roughness", "mirror")
            assert sun_cut is not None
            rows.append({
                "placement": placement, "used": info["stats"]["placement"],
                "strokes": info["stats"]["paths"],
                "hours": info["machining"]["estimated_hours"],
                "point_p95": point["summary"]["worst_p95_error"],
                "point_visibility": point["summary"]["min_visibility"],
                "sun_p95": sun["summary"]["worst_p95_error"],
                "sun_p95_median": _median([r["p95_error"] for r in sun["azimuths"]]),
                "sun_cut_p95": sun_cut["summary"]["worst_p95_error"],
                "sun_cut_p95_median": _median([r["p95_error"] for r in sun_cut["azimuths"]]),
                "sun_cut_visibility": sun_cut["summary"]["min_visibility"],
                "sun_spills": _spills(sun),
                "lamp_p95": lamp["summary"]["worst_p95_error"],
                "lamp_spills": _spills(lamp)})
    load = os.getloadavg()[0]
    print(f"README example on the GRBL router, band 0.2 mm; load {load:.1f}, "
          f"{os.cpu_count()} cores")
    print("| placement | strokes | hours | points: worst p95 mm / lowest visibility | "
          "the sun, mirror: worst p95 mm, ideal / as cut | median p95 over the views, "
          "ideal / as cut | "
          "as cut, lowest visibility | "
          "false glints per eye (mean / most) | a lamp 0.25 deg: worst p95 mm | false glints |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        name = r["placement"] + (f" ({r['used']})" if r["used"] != r["placement"] else "")
        print(f"| {name} | {r['strokes']:,} | {r['hours']:.1f} | {r['point_p95']:.3f} / "
              f"{r['point_visibility']:.3f} | {r['sun_p95']:.2f} / {r['sun_cut_p95']:.2f} | "
              f"{r['sun_p95_median']:.2f} / {r['sun_cut_p95_median']:.2f} | "
              f"{r['sun_cut_visibility']:.3f} | {r['sun_spills'][0]:,.0f} / "
              f"{r['sun_spills'][1]:,.0f} | {r['lamp_p95']:.2f} | "
              f"{r['lamp_spills'][0]:,.0f} / {r['lamp_spills'][1]:,.0f} |")
    if args.out is not None:
        args.out.write_text(json.dumps({"load": load, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()

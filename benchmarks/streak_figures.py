"""The README example's figures under named lights and glosses, beside the
classic arcs: the table of docs/verification.md ("A light of real size").

Designs the README example (striped) and the classic arcs on the same scene,
then runs ``specholo verify --cut`` on each under every light and gloss below,
timing each whole command, and prints a Markdown table: worst p95 error ideal
and as cut, the lowest stereo visibility ideal and as cut, false glints from stripe ends per
eye (mean over the views and most), and the wall time.

    python benchmarks/streak_figures.py [--out results/streaks.json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = ["--size", "60", "--center-z", "-40", "--light-elevation", "45", "--view-distance",
         "600", "--view-range", "45", "--stipples", "2000"]
#: (label, design method, verify options)
CASES = [
    ("a point, a perfect mirror", "striped", []),
    ("a lamp 0.25 deg across, mirror (0.003)", "striped",
     ["--light-size", "0.25", "--roughness", "mirror"]),
    ("the sun (0.53 deg), mirror (0.003)", "striped",
     ["--light-size", "0.53", "--roughness", "mirror"]),
    ("the sun, polished (0.01)", "striped", ["--light-size", "0.53", "--roughness", "polished"]),
    ("classic arcs, the sun, mirror", "arc", ["--light-size", "0.53", "--roughness", "mirror"]),
]


def _specholo(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "specholo_cli.cli", *args], check=True,
                   stdout=subprocess.DEVNULL)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="also write the rows as JSON")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        designs = {}
        for method in ("striped", "arc"):
            folder = Path(tmp) / method
            _specholo("design", str(ROOT / "examples" / "bunny.obj"), "--out", str(folder),
                      "--method", method, *SCENE)
            designs[method] = folder
        for label, method, options in CASES:
            folder = Path(tmp) / f"v{len(rows)}"
            shutil.copytree(designs[method], folder)
            t0 = time.perf_counter()
            _specholo("verify", str(folder), "--cut", *options)
            wall = time.perf_counter() - t0
            ideal = json.loads((folder / "verify.json").read_text())
            cut = json.loads((folder / "verify_cut.json").read_text())
            spills = [r.get("end_spills", 0.0) for r in ideal["azimuths"]]
            rows.append({"light": label, "worst_p95_mm": ideal["summary"]["worst_p95_error"],
                         "lowest_visibility": ideal["summary"]["min_visibility"],
                         "as_cut_lowest": cut["summary"]["min_visibility"],
                         "as_cut_p95_mm": cut["summary"]["worst_p95_error"],
                         "spills_mean": sum(spills) / len(spills), "spills_most": max(spills),
                         "seconds": wall})
    load = os.getloadavg()[0]
    print(f"README example, verify --cut every 5 degrees; load {load:.1f}, {os.cpu_count()} cores")
    print("| light, gloss | worst p95 mm | as cut | lowest visibility | as cut, lowest | "
          "false glints per eye (mean / most) | time |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['light']} | {r['worst_p95_mm']:.3g} | {r['as_cut_p95_mm']:.3g} | "
              f"{r['lowest_visibility']:.3f} | "
              f"{r['as_cut_lowest']:.3f} | {r['spills_mean']:,.0f} / {r['spills_most']:,.0f} | "
              f"{r['seconds']:.0f} s |")
    if args.out is not None:
        args.out.write_text(json.dumps({"load": load, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()

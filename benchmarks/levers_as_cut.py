"""As-cut stereo visibility of the README's example under each design lever.

Usage:
    python benchmarks/levers_as_cut.py [--stipples 2000] [--resolution 0.005]
        [--lever NAME ...] [--work DIR]

Each lever is the README's job (bunny, 60 mm, centre z -40 mm, sun at 45 deg,
eyes 600 mm away over +-45 deg, default drag tip) with some options changed. It
is designed with ``specholo design``, verified ideally and as cut with
``specholo verify FOLDER --cut --resolution R`` (the cut plate simulated from the
G-code at R mm), and a Markdown table of both per azimuth (every 5 deg) is
printed, with the groove length, path count and the area the grooves cover.
One design and one simulation run at a time.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

MODEL = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
BASE = ["--size", "60", "--center-z", "-40", "--light-elevation", "45",
        "--view-distance", "600", "--view-range", "45"]
#: Lever name -> extra ``specholo design`` options.
LEVERS: dict[str, list[str]] = {
    "today": ["--placement", "phase"],
    "band 0.3": ["--placement", "phase", "--band", "0.3"],
    "band 0.4": ["--placement", "phase", "--band", "0.4"],
    "avoid": ["--placement", "avoid"],
    "avoid band 0.3": ["--placement", "avoid", "--band", "0.3"],
    "avoid band 0.4": ["--placement", "avoid", "--band", "0.4"],
}


def run(cmd: list[str]) -> str:
    out = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return out.stdout + out.stderr


def measure(name: str, extra: list[str], stipples: int, resolution: float,
            work: Path) -> dict[str, object]:
    """Design and verify one lever; the per-azimuth figures and groove totals."""
    folder = work / name.replace(" ", "_")
    if folder.exists():
        subprocess.run(["rm", "-rf", str(folder)], check=True)
    log = run(["specholo", "design", str(MODEL), "--out", str(folder), *BASE,
               "--stipples", str(stipples), *extra])
    run(["specholo", "verify", str(folder), "--cut", "--resolution", str(resolution)])
    info = json.loads((folder / "hologram.json").read_text())
    ideal = json.loads((folder / "verify.json").read_text())
    cut = json.loads((folder / "verify_cut.json").read_text())
    return {"name": name, "log": log, "stats": info["stats"], "tool": info["tool"],
            "overlaps": info.get("overlaps"), "ideal": ideal, "cut": cut}


def table(results: list[dict[str, object]]) -> str:
    head = "| azimuth | " + " | ".join(
        f"{r['name']}: ideal vis / p95 | cut vis / p95" for r in results) + " |"
    rows = [head, "|" + "---|" * (1 + 2 * len(results))]
    azimuths = [a["azimuth"] for a in results[0]["ideal"]["azimuths"]]  # type: ignore[index]
    for i, az in enumerate(azimuths):
        cells = []
        for r in results:
            a = r["ideal"]["azimuths"][i]  # type: ignore[index]
            c = r["cut"]["azimuths"][i]  # type: ignore[index]
            cells.append(f"{a['visibility']:.3f} / {a['p95_error']:.3f} | "
                         f"{c['visibility']:.3f} / {c['p95_error']:.3f}")
        rows.append(f"| {az:+.0f} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--stipples", type=int, default=2000)
    ap.add_argument("--resolution", type=float, default=0.005)
    ap.add_argument("--lever", action="append", choices=sorted(LEVERS),
                    help="levers to measure (default: all)")
    ap.add_argument("--work", type=Path, default=Path("levers_out"))
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    results = []
    for name in args.lever or list(LEVERS):
        r = measure(name, LEVERS[name], args.stipples, args.resolution, args.work)
        results.append(r)
        cut = r["cut"]["summary"]  # type: ignore[index]
        ideal = r["ideal"]["summary"]  # type: ignore[index]
        print(f"{name}: {str(r['log']).splitlines()[0]}", file=sys.stderr)
        print(f"  ideal min vis {ideal['min_visibility']:.3f} worst p95 "
              f"{ideal['worst_p95_error']:.3f} mm; cut min vis {cut['min_visibility']:.3f} "
              f"worst p95 {cut['worst_p95_error']:.3f} mm", file=sys.stderr)
        (args.work / "levers.json").write_text(json.dumps(
            [{k: v for k, v in x.items() if k != "log"} for x in results], indent=1))
    print(table(results))


if __name__ == "__main__":
    main()

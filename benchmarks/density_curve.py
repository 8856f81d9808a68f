"""As-cut stereo visibility against stipple count: striped beside arc and hyperbola.

Usage: python benchmarks/density_curve.py [--scene readme|unseen]
       [--stipples 500 1000 2000 4000 8000]
       [--methods striped arc:off hyperbola:off arc] [--set KEY=VALUE ...]
       [--json out.json] [--plot out.png]

Designs a scene in-process at each stipple count with each method (the default
settings otherwise: the striped design places its stripes as ``--placement
auto`` does, and the design thins a crowded plate as ``--thin auto`` does; a
method written ``METHOD:off`` is designed with ``--thin off``, every stipple
cut, as other tools cut their arcs) and verifies it per head azimuth (every
5 deg), ideally and as cut by the survival test
(:func:`specholo.simulation.survival.verify_as_cut`, what ``specholo verify
--cut`` reports by default), with the model's occlusion.

Scenes:

- ``readme``: the README's example (bunny, 60 mm, centre z -40 mm, sun at 45
  deg, eyes 600 mm away at the plate's height over +-45 deg, drag tip);
- ``unseen``: a scene the design was not tuned on (the trefoil knot, 60 mm,
  centre z -30 mm, a point light 800 mm away at 35 deg, eyes 600 mm away and
  150 mm above the plate's centre over +-50 deg, a 60 deg drag tip, since the
  raised eyes need walls tilted up to 49 deg, more than a 90 deg cone offers).

``--set`` changes a design setting of the scene (``hologram.json``'s names),
e.g. ``--set tool_radius=0.05`` for the 0.05 mm drag tip.

For each design it prints the lowest and mean as-cut stereo visibility over the
azimuths, the mean number of stipples seen in stereo on the cut plate ("stereo
points": visibility times the stipples unoccluded at that azimuth), the worst
as-cut p95 error, the lowest ideal visibility, the groove length and paths, and
the placement the striped design used. ``--plot`` draws the curves (matplotlib).
One design runs at a time. Nothing is timed.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from specholo.jobs.flat.folder import DesignConfig, design
from specholo.simulation.survival import verify_as_cut
from specholo.simulation.verify import verify, view_azimuths
from specholo.visibility.occlusion import visible

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
#: Scene name -> (model, design settings).
SCENES: dict[str, tuple[Path, dict[str, Any]]] = {
    "readme": (EXAMPLES / "bunny.obj", {
        "size": 60.0, "center_z": -40.0, "light_elevation": 45.0, "view_distance": 600.0,
        "view_range": 45.0}),
    "unseen": (EXAMPLES / "knot.obj", {
        "size": 60.0, "center_z": -30.0, "light_elevation": 35.0, "light_distance": 800.0,
        "view_distance": 600.0, "view_range": 50.0, "eye_height": 150.0,
        "tool_angle": 60.0}),
}


def measure(scene: str, method: str, stipples: int,
            changes: dict[str, Any] | None = None) -> dict[str, Any]:
    """One design at one density: its as-cut and ideal figures per azimuth."""
    model, settings = SCENES[scene]
    name, _, thin = method.partition(":")
    config = DesignConfig.from_dict({**settings, **(changes or {}), "stipples": stipples,
                                     "method": name, **({"thin": thin} if thin else {})})
    d = design(model, config, check_overlaps=False)
    setup = d.config.setup()
    mesh, normals = d.model.mesh, d.normals

    def vis(points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        return visible(mesh, points, normals, eyes)

    az = view_azimuths(setup.viewer.half_range, math.radians(5.0))
    ideal = verify(d.grooves, d.points, setup, vis, az)
    cut = verify_as_cut(d.grooves, d.points, setup, d.config.cutter(), d.config.depth_mm,
                        vis, az).reports
    cut_vis = np.array([r.visibility for r in cut])
    points = np.array([r.visibility * r.stipples_seen for r in cut])
    p95 = [r.p95_error for r in cut if math.isfinite(r.p95_error)]
    return {
        "scene": scene, "method": method, "stipples": stipples,
        "placement": (d.placement or {}).get("placement", ""),
        "thinned": 0 if d.thinned is None else len(d.thinned),
        "paths": int(d.grooves.n_paths), "groove_m": d.grooves.total_length() / 1000.0,
        "azimuths_deg": [round(math.degrees(a), 3) for a in az],
        "ideal_visibility": [r.visibility for r in ideal],
        "cut_visibility": cut_vis.tolist(),
        "cut_stereo_points": points.tolist(),
        "cut_min": float(cut_vis.min()), "cut_mean": float(cut_vis.mean()),
        "ideal_min": float(min(r.visibility for r in ideal)),
        "stereo_points_mean": float(points.mean()),
        "cut_worst_p95_mm": max(p95) if p95 else math.nan,
    }


def label(method: str) -> str:
    """A method's name in the legend: "arc:off" is "arc, every stipple cut"."""
    name, _, thin = method.partition(":")
    return {"off": f"{name}, every stipple cut", "on": f"{name}, thinned (on)"}.get(
        thin, f"{name}, thinned (auto)")


def plot(rows: list[dict[str, Any]], path: Path, scene: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    counts = sorted({r["stipples"] for r in rows})
    for i, method in enumerate(dict.fromkeys(r["method"] for r in rows)):
        mine = [r for r in rows if r["method"] == method]
        n = [r["stipples"] for r in mine]
        colour = f"C{i}"
        name = label(method)
        a.plot(n, [r["cut_mean"] for r in mine], "o-", color=colour, label=f"{name}, mean")
        a.plot(n, [r["cut_min"] for r in mine], "x--", color=colour,
               label=f"{name}, lowest view")
        b.plot(n, [r["stereo_points_mean"] for r in mine], "o-", color=colour, label=name)
    for ax in (a, b):
        ax.set_xscale("log")
        ax.set_xticks(counts, [f"{c:,}" for c in counts])
        ax.minorticks_off()
        ax.set_xlabel("stipples")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    a.set_ylabel("stereo visibility as cut")
    a.set_ylim(0, 1)
    b.set_ylabel("stipples in both eyes as cut (mean)")
    fig.suptitle(f"As cut, by stipple count ({scene} scene)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _setting(text: str) -> tuple[str, Any]:
    key, sep, value = text.partition("=")
    if not sep:
        raise SystemExit(f"--set takes KEY=VALUE, got {text!r}")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value  # a word, e.g. placement=avoid


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", choices=sorted(SCENES), default="readme")
    ap.add_argument("--stipples", type=int, nargs="+", default=[500, 1000, 2000, 4000, 8000])
    ap.add_argument("--methods", nargs="+",
                    default=["striped", "arc:off", "hyperbola:off", "arc"],
                    choices=[f"{m}{t}" for m in ("striped", "arc", "hyperbola")
                             for t in ("", ":off", ":on")])
    ap.add_argument("--set", dest="changes", action="append", default=[],
                    metavar="KEY=VALUE", help="change a design setting of the scene")
    ap.add_argument("--json", type=Path, help="write every figure here")
    ap.add_argument("--plot", type=Path, help="draw the curves here (PNG)")
    args = ap.parse_args()
    changes = dict(_setting(c) for c in args.changes)
    rows = []
    print("| method | stipples | placement | thinned | as cut, lowest / mean "
          "| stereo points, mean | as cut p95 mm | ideal lowest | groove m | paths |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for method in args.methods:
        for n in args.stipples:
            r = measure(args.scene, method, n, changes)
            rows.append(r)
            print(f"| {method} | {n} | {r['placement']} | {r['thinned']} | {r['cut_min']:.3f} / "
                  f"{r['cut_mean']:.3f} | {r['stereo_points_mean']:.0f} | "
                  f"{r['cut_worst_p95_mm']:.3f} | {r['ideal_min']:.3f} | "
                  f"{r['groove_m']:.1f} | {r['paths']} |", flush=True)
            if args.json:
                args.json.write_text(json.dumps(rows, indent=1))
    if args.plot:
        plot(rows, args.plot, args.scene)
        print(f"plot: {args.plot}", file=sys.stderr)


if __name__ == "__main__":
    main()

"""Every stage at 10^4, 10^5 and 10^6 stipples: items per second and peak memory.

Usage: python benchmarks/bench_scale.py [--sizes 10000 100000 1000000]
       [--csv benchmarks/results/scale.csv] [--plot benchmarks/results/scale.png]

Each size runs in a fresh process on the bundled bunny (striped design with
occlusion, defaults), so its peak memory (max RSS) is its own. Stages:
stippling, occlusion and toolpaths (the design), verification at 19 head
azimuths, a 1024 x 1024 still, writing G-code, SVG and DXF, and simulating the
cut of a 100 x 100 mm plate at 0.02 mm. A size whose design the library's own
estimate says would not fit in this machine's memory is not run; its row says
so, with the estimate. Each run also verifies a fixed sample of 500 stipples
and prints its worst 95th-percentile error, so speed is never bought with
exactness unseen. Writes a CSV of all figures and a log-log plot of time
against size.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "bunny.obj"
STAGES = ("stippling", "occlusion", "toolpaths", "verify", "still", "gcode", "svg", "dxf",
          "cut")


def _timed(fn):  # type: ignore[no-untyped-def]
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _subset(grooves, stipples: np.ndarray, n: int):  # type: ignore[no-untyped-def]
    """The paths of some stipples, renumbered 0..k-1 in the order given."""
    from specholo.toolpaths.grooves import Grooves

    where = np.full(n, -1)
    where[stipples] = np.arange(len(stipples))
    keep = np.flatnonzero(where[grooves.stipple] >= 0)
    sizes = grooves.path_sizes[keep]
    idx = np.concatenate([np.arange(grooves.offsets[k], grooves.offsets[k + 1]) for k in keep])
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    return Grooves(grooves.vertices[idx], grooves.bulges[idx], offsets,
                   where[grooves.stipple[keep]].astype(np.int64))


def run_one(n: int) -> dict[str, float]:
    from specholo.fabrication.dxf import write_dxf
    from specholo.fabrication.gcode import GcodeOptions, write_gcode
    from specholo.fabrication.svg import write_svg
    from specholo.pipeline import DesignConfig, design
    from specholo.preview.render import Engraved, design_camera, render_still
    from specholo.simulation.cut import cut_surface
    from specholo.simulation.verify import summarise, verify, view_azimuths
    from specholo.visibility.occlusion import visible

    cfg = DesignConfig(stipples=n)
    d, _ = _timed(lambda: design(MODEL, cfg))
    setup = d.config.setup()
    row: dict[str, float] = {"stipples": n, "paths": d.grooves.n_paths,
                             "arcs": len(d.grooves.vertices)}
    for k in ("stippling", "occlusion", "toolpaths"):
        row[f"{k}_s"] = d.timings[f"{k}"] if k in d.timings else math.nan
    mesh, normals = d.model.mesh, d.normals

    def vis(points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        return visible(mesh, points, normals, eyes)

    az = view_azimuths(setup.viewer.half_range)  # 19 heads over +-45 degrees
    _, row["verify_s"] = _timed(lambda: verify(d.grooves, d.points, setup, vis, az))
    # A fixed sample's exactness: the grooves of its stipples only.
    sample = np.unique(np.linspace(0, len(d.points) - 1, min(500, len(d.points))).astype(int))
    sub_normals = normals[sample] if normals is not None else None

    def vis_sample(points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        return visible(mesh, points, sub_normals, eyes)

    s = summarise(verify(_subset(d.grooves, sample, len(d.points)), d.points[sample], setup,
                         vis_sample, az))
    row["sample_worst_p95_mm"] = s["worst_p95_error"]
    eng, row["still_prepare_s"] = _timed(lambda: Engraved.from_grooves(d.grooves, setup.tool))
    cam = design_camera(setup, d.grooves, width=1024, height=1024)
    _, row["still_s"] = _timed(lambda: render_still(d.grooves, setup, cam, engraved=eng))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        _, row["gcode_s"] = _timed(lambda: write_gcode(
            out / "h.gcode", d.grooves, setup.tool, setup.machining, options=GcodeOptions(),
            depth=d.config.depth_mm))
        _, row["svg_s"] = _timed(lambda: write_svg(out / "h.svg", d.grooves, setup.tool))
        _, row["dxf_s"] = _timed(lambda: write_dxf(out / "h.dxf", d.grooves, setup.tool))
    bounds = np.array([[-50.0, -50.0], [50.0, 50.0]])
    _, row["cut_s"] = _timed(lambda: cut_surface(d.grooves, setup.tool, setup.tool.depth,
                                                 bounds=bounds, resolution=0.02))
    row["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    ap.add_argument("--csv", type=Path, default=ROOT / "benchmarks" / "results" / "scale.csv")
    ap.add_argument("--plot", type=Path, default=ROOT / "benchmarks" / "results" / "scale.png")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(args.one)))
        return
    from specholo.scene.loading import available_memory, format_bytes, load_model
    from specholo.scene.stippling import estimate_memory

    model = load_model(MODEL)
    faces = len(model.mesh.faces) if model.mesh is not None else 0
    room = available_memory()
    rows = []
    head = " ".join(f"{s + '/s':>12}" for s in STAGES)
    print(f"{'stipples':>9} {head} {'peak MB':>8} {'sample p95':>10}")
    for n in args.sizes:
        need = estimate_memory(n, faces, len(model.points))
        if room is not None and need > room:
            print(f"{n:>9} not run: the design needs ~{format_bytes(need)}, "
                  f"{format_bytes(room)} available", flush=True)
            rows.append({"stipples": n, "skipped_need_bytes": need})
            continue
        run = subprocess.run([sys.executable, __file__, "--one", str(n)], capture_output=True,
                             text=True)
        if run.returncode != 0:
            print(f"{n:>9} failed: {run.stderr.strip().splitlines()[-1:]}", flush=True)
            rows.append({"stipples": n, "failed": 1})
            continue
        r = json.loads(run.stdout.strip().splitlines()[-1])
        rows.append(r)
        rates = " ".join(f"{n / r[f'{s}_s']:>12,.0f}" for s in STAGES)
        print(f"{n:>9} {rates} {r['peak_rss_mb']:>8,.0f} "
              f"{r.get('sample_worst_p95_mm', math.nan):>10.3f}", flush=True)
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    keys = sorted({k for r in rows for k in r})
    with open(args.csv, "w", newline="") as fh:
        w = csv.DictWriter(fh, keys)
        w.writeheader()
        w.writerows(rows)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    done = [r for r in rows if "toolpaths_s" in r]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for s in STAGES:
        ax.loglog([r["stipples"] for r in done], [r[f"{s}_s"] for r in done], "o-", label=s)
    ax.set_xlabel("stipples")
    ax.set_ylabel("seconds")
    ax.set_title("specholo: time per stage against size (2 cores)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=3)
    fig.tight_layout()
    fig.savefig(args.plot, dpi=110)
    print(f"wrote {args.csv} and {args.plot}")


if __name__ == "__main__":
    main()

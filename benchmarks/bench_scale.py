"""Every stage at 10^4, 10^5 and 10^6 stipples: items per second and peak memory.

Usage: python benchmarks/bench_scale.py [--sizes 10000 100000 1000000]
       [--stages stippling ... cut] [--csv benchmarks/results/scale.csv]
       [--plot benchmarks/results/scale.png] [--keep OLD.csv]

Each size is designed in a fresh process on the bundled bunny (striped design
with occlusion, defaults: stippling, occlusion and toolpaths are its stages,
"design" the whole, overlap figures included), saved, and every other stage
runs on it in a process of its own, so each peak memory (max RSS) is that
stage's: verification at 19 head azimuths, a 1024 x 1024 still, writing
G-code, SVG and DXF, and simulating the cut of a 100 x 100 mm plate at
0.02 mm. A size whose design the library's own estimate says would not fit
in this machine's memory is not run; its row says so, with the estimate.
Verification also checks a fixed sample of 500 stipples and prints its worst
95th-percentile error, so speed is never bought with exactness unseen.
Writes a CSV of all figures and a log-log plot of time against size.
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
STAGES = ("stippling", "occlusion", "toolpaths", "design", "verify", "still", "gcode", "svg",
          "dxf", "cut")
#: Peak memory per stipple of the stages that hold the grooves and per-arc
#: arrays, bytes (measured at 10^5 stipples, and the cut's own arrays bounded by
#: its field since it goes a chunk at a time); a size that would not fit is not
#: run for them.
STAGE_BYTES = {"verify": 9_000, "still": 9_000, "cut": 12_000}
#: Stages timed inside the design itself ("design" is the whole of it, overlaps included).
DESIGN_STAGES = ("stippling", "occlusion", "toolpaths", "design")


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


def _design(n: int, folder: Path) -> dict[str, float]:
    """Design n stipples (striped, occlusion) and keep what the other stages need."""
    import pickle

    from specholo.jobs.flat.folder import DesignConfig, design

    d, total = _timed(lambda: design(MODEL, DesignConfig(stipples=n)))
    row: dict[str, float] = {"stipples": n, "paths": d.grooves.n_paths,
                             "arcs": len(d.grooves.vertices), "design_s": total}
    for k in ("stippling", "occlusion", "tool check", "toolpaths", "overlaps"):
        row[f"{k.replace(' ', '_')}_s"] = d.timings.get(k, math.nan)
    g = d.grooves
    np.savez(folder / "grooves.npz", vertices=g.vertices, bulges=g.bulges, offsets=g.offsets,
             stipple=g.stipple)
    with open(folder / "rest.pkl", "wb") as fh:
        pickle.dump((d.config, d.points, d.normals), fh)
    row["design_peak_mb"] = _peak_mb()
    return row


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _stage(stage: str, folder: Path) -> dict[str, float]:
    """Run one stage on a saved design, in a process of its own (its own peak memory)."""
    import pickle

    from specholo.scene.loading import load_model
    from specholo.scene.placement import place
    from specholo.toolpaths.grooves import Grooves

    with np.load(folder / "grooves.npz") as z:
        grooves = Grooves(z["vertices"], z["bulges"], z["offsets"], z["stipple"])
    with open(folder / "rest.pkl", "rb") as fh:
        config, points, normals = pickle.load(fh)
    setup = config.setup()
    row: dict[str, float] = {}
    if stage == "verify":
        from specholo.simulation.verify import summarise, verify, view_azimuths
        from specholo.visibility.occlusion import visible

        mesh = place(load_model(MODEL), config.size, config.center_z).mesh

        def vis(p: np.ndarray, e: np.ndarray, nrm: np.ndarray | None = normals) -> np.ndarray:
            return visible(mesh, p, nrm, e)

        az = view_azimuths(setup.viewer.half_range)  # 19 heads over +-45 degrees
        _, row["verify_s"] = _timed(lambda: verify(grooves, points, setup, vis, az))
        # A fixed sample's exactness: the grooves of its stipples only.
        sample = np.unique(np.linspace(0, len(points) - 1, min(500, len(points))).astype(int))
        sub = normals[sample] if normals is not None else None
        s = summarise(verify(_subset(grooves, sample, len(points)), points[sample], setup,
                             lambda p, e: vis(p, e, sub), az))
        row["sample_worst_p95_mm"] = s["worst_p95_error"]
    elif stage == "still":
        from specholo.preview.render import Engraved, design_camera, render_still
        from specholo.simulation.verify import CHUNK_VERTICES

        cam = design_camera(setup, grooves, width=1024, height=1024)
        if len(grooves.vertices) > CHUNK_VERTICES:  # prepared a run of paths at a time
            _, row["still_s"] = _timed(lambda: render_still(grooves, setup, cam))
        else:
            eng, row["still_prepare_s"] = _timed(
                lambda: Engraved.from_grooves(grooves, setup.tool))
            _, row["still_s"] = _timed(lambda: render_still(grooves, setup, cam, engraved=eng))
    elif stage == "cut":
        from specholo.simulation.cut import cut_surface

        bounds = np.array([[-50.0, -50.0], [50.0, 50.0]])
        _, row["cut_s"] = _timed(lambda: cut_surface(grooves, setup.tool, setup.tool.depth,
                                                     bounds=bounds, resolution=0.02))
    else:
        with tempfile.TemporaryDirectory(dir=folder) as tmp:
            out = Path(tmp)
            if stage == "gcode":
                from specholo.fabrication.programs.gcode import write_gcode
                from specholo.fabrication.programs.program import GcodeOptions

                _, row["gcode_s"] = _timed(lambda: write_gcode(
                    out / "h.gcode", grooves, setup.tool, setup.machining,
                    options=GcodeOptions(), depth=config.depth_mm))
            elif stage == "svg":
                from specholo.fabrication.drawings.svg import write_svg

                _, row["svg_s"] = _timed(lambda: write_svg(out / "h.svg", grooves, setup.tool))
            else:
                from specholo.fabrication.drawings.dxf import write_dxf

                _, row["dxf_s"] = _timed(lambda: write_dxf(out / "h.dxf", grooves, setup.tool))
    row[f"{stage}_peak_mb"] = _peak_mb()
    return row


def _child(args: list[str]) -> tuple[dict[str, float] | None, str]:
    """Run this script with ``args`` in a fresh process: its JSON row, or the error."""
    run = subprocess.run([sys.executable, __file__, *args], capture_output=True, text=True)
    if run.returncode != 0:
        lines = (run.stderr.strip() or f"exit status {run.returncode}").splitlines()
        return None, lines[-1]
    return json.loads(run.stdout.strip().splitlines()[-1]), ""


def run_size(n: int, stages: tuple[str, ...], room: int | None) -> dict[str, float]:
    """Design n stipples, then time every other stage in a process of its own
    (those :data:`STAGE_BYTES` says would not fit in ``room`` bytes are skipped)."""
    from specholo.scene.loading import format_bytes

    with tempfile.TemporaryDirectory() as tmp:
        row, err = _child(["--design", str(n), "--dir", tmp])
        if row is None:
            print(f"{n:>9} design failed: {err}", flush=True)
            return {"stipples": n, "failed": 1}
        for stage in stages:
            if stage in DESIGN_STAGES:
                continue
            need = n * STAGE_BYTES.get(stage, 0)
            if room is not None and need > room:
                print(f"{n:>9} {stage} not run: needs ~{format_bytes(need)}, "
                      f"{format_bytes(room)} available", flush=True)
                row[f"{stage}_skipped_need_bytes"] = need
                continue
            got, err = _child(["--stage", stage, "--dir", tmp])
            if got is None:
                print(f"{n:>9} {stage} failed: {err}", flush=True)
                row[f"{stage}_failed"] = 1
            else:
                row.update(got)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="*", default=[10_000, 100_000, 1_000_000],
                    help="stipple counts to run (none: only write the CSV and plot of --keep)")
    ap.add_argument("--csv", type=Path, default=ROOT / "benchmarks" / "results" / "scale.csv")
    ap.add_argument("--plot", type=Path, default=ROOT / "benchmarks" / "results" / "scale.png")
    ap.add_argument("--stages", nargs="+", default=list(STAGES), choices=STAGES)
    ap.add_argument("--keep", type=Path, metavar="CSV",
                    help="start from this CSV's figures; those measured now replace theirs "
                         "(to rerun some sizes or stages)")
    ap.add_argument("--design", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--stage", help=argparse.SUPPRESS)
    ap.add_argument("--dir", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.design:
        print(json.dumps(_design(args.design, args.dir)))
        return
    if args.stage:
        print(json.dumps(_stage(args.stage, args.dir)))
        return
    from specholo.scene.loading import available_memory, format_bytes, load_model
    from specholo.scene.stippling import estimate_memory

    model = load_model(MODEL)
    faces = len(model.mesh.faces) if model.mesh is not None else 0
    room = available_memory()
    rows = []
    stages = tuple(args.stages)
    head = " ".join(f"{s:>10}" for s in stages)
    print("items per second (stipples/s), then the largest peak of any stage's process")
    print(f"{'stipples':>9} {head} {'peak MB':>8} {'sample p95':>10}")
    for n in args.sizes:
        need = estimate_memory(n, faces, len(model.points))
        if room is not None and need > room:
            print(f"{n:>9} not run: the design needs ~{format_bytes(need)}, "
                  f"{format_bytes(room)} available", flush=True)
            rows.append({"stipples": n, "skipped_need_bytes": need})
            continue
        r = run_size(n, stages, room)
        rows.append(r)
        if r.get("failed"):
            continue
        rates = " ".join(f"{n / r[f'{s}_s']:>10,.0f}" if f"{s}_s" in r else f"{'-':>10}"
                         for s in stages)
        peak = max(v for k, v in r.items() if k.endswith("_peak_mb"))
        print(f"{n:>9} {rates} {peak:>8,.0f} "
              f"{r.get('sample_worst_p95_mm', math.nan):>10.3f}", flush=True)
        print("          peak MB by stage: " + ", ".join(
            f"{k[:-8]} {v:,.0f}" for k, v in r.items() if k.endswith("_peak_mb")), flush=True)
    if args.keep is not None:
        with open(args.keep, newline="") as fh:
            merged = {int(float(r["stipples"])): {k: float(v) for k, v in r.items() if v != ""}
                      for r in csv.DictReader(fh)}
        for r in rows:
            merged.setdefault(int(r["stipples"]), {}).update(r)
        rows = [merged[n] for n in sorted(merged)]
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    keys = sorted({k for r in rows for k in r})
    with open(args.csv, "w", newline="") as fh:
        w = csv.DictWriter(fh, keys)
        w.writeheader()
        w.writerows(rows)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    done = [r for r in rows if "design_s" in r]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for s in STAGES:
        have = [r for r in done if f"{s}_s" in r]
        if have:
            ax.loglog([r["stipples"] for r in have], [r[f"{s}_s"] for r in have], "o-",
                      label=s)
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

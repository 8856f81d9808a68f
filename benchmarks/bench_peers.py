"""specholo beside another scratch-hologram generator, on the same model, in one run.

Usage: python benchmarks/bench_peers.py --peer PATH/scratch_pipeline.py
       [--runs "ARGS" ...] [--repeat 3] [--csv benchmarks/results/peers.csv]

The peer is a Python generator that turns an STL into HoloZens-style
semicircular arcs ("Arc-based scratch hologram generator", its script
`scratch_pipeline.py`): it samples every feature edge of the mesh at
`--line-resolution` points per model unit and draws one 180-degree arc per
distinct point, on a canvas of whole pixels scaled by `--current-scale`, into
an SVG. It is not part of specholo; pass the path of its script. Both tools
get the bundled bunny (the peer as an STL written here) and are timed as
whole commands in fresh processes, start-up included, from the model file to
the SVG on disk:

- the peer with each of `--runs` (its own options), giving N arcs;
- `specholo design --method arc --stipples N --formats svg`: the same classic
  arcs, with occlusion, the tool check, the overlap figures and a preview;
- `specholo design --stipples N --formats svg`: the exact striped design
  (up to `--striped-up-to` arcs).

Each command runs `--repeat` times and the fastest run counts (the machine's
noise only ever adds time). Prints seconds, optics per second, peak memory
and the peer's time over specholo's (above 1: specholo is faster), and writes
them to a CSV.
"""

from __future__ import annotations

import argparse
import csv
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "bunny.obj"
SPECHOLO = [str(Path(sys.executable).with_name("specholo"))]
_ARC = re.compile(rb"^A ", re.MULTILINE)
#: The peer's options for about 2 x 10^3, 2 x 10^4, 10^5 and 10^6 arcs on the
#: bunny: its defaults, a finer line resolution, then a larger canvas (its
#: whole pixels merge arcs past ~25,000 on the default one).
PEER_RUNS = ("", "--line-resolution 20", "--line-resolution 50 --current-scale 7.24",
             "--line-resolution 500 --current-scale 72.4")


def _run(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one command run to completion."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}): {err.strip()[-400:]}")
    return wall, usage.ru_maxrss / 1024.0


def _best(cmd: list[str], repeat: int) -> tuple[float, float]:
    runs = [_run(cmd) for _ in range(max(repeat, 1))]
    return min(w for w, _ in runs), max(m for _, m in runs)


def _peer_arcs(svg: Path) -> int:
    """Arcs in the peer's SVG: one `A` command per line of its single path."""
    return len(_ARC.findall(svg.read_bytes()))


def _stipples(out: Path) -> int:
    """Stipples a design got (its radius search lands near, not on, the count asked)."""
    import numpy as np

    with np.load(out / "stipples.npz") as z:
        return len(z["points"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--peer", type=Path, required=True,
                    help="the peer's scratch_pipeline.py")
    ap.add_argument("--runs", nargs="+", default=list(PEER_RUNS),
                    help="the peer's options for each size, one string each")
    ap.add_argument("--methods", nargs="+", default=["arc", "striped"],
                    choices=["arc", "hyperbola", "striped"])
    ap.add_argument("--striped-up-to", type=int, default=200_000,
                    help="skip the striped design past this many arcs (at 10^6 it writes "
                         "38 million paths: minutes)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--csv", type=Path, default=ROOT / "benchmarks" / "results" / "peers.csv")
    args = ap.parse_args()
    if not args.peer.is_file():
        raise SystemExit(f"error: no peer script at {args.peer}")
    import trimesh

    rows = []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        stl = tmp / "bunny.stl"
        trimesh.load(MODEL, force="mesh").export(stl)
        # One untimed run of each specholo design, so numba's cache is warm
        # (compiling happens once per install, not once per run).
        for method in args.methods:
            _run([*SPECHOLO, "design", str(MODEL), "--out", str(tmp / f"warm-{method}"),
                  "--method", method, "--stipples", "500", "--formats", "svg"])
        print(f"{'peer run':>8} {'arcs':>7} {'peer s':>7} {'peer /s':>8} {'MB':>5}"
              + "".join(f" {'stipples':>8} {m[:6] + ' s':>8} {m[:6] + ' /s':>8} {'MB':>5} "
                        f"{'ratio':>6}" for m in args.methods), flush=True)
        for k, run in enumerate(args.runs):
            svg = tmp / f"peer-{k}.svg"
            peer_s, peer_mb = _best([sys.executable, str(args.peer), "--stl", str(stl),
                                     "--svg", str(svg), *shlex.split(run)], args.repeat)
            n = _peer_arcs(svg)
            if n == 0:
                raise SystemExit(f"error: the peer drew no arcs with {run!r}")
            row: dict[str, object] = {"peer_options": run, "peer_arcs": n, "peer_s": peer_s,
                                      "peer_peak_mb": peer_mb}
            line = f"{k:>8} {n:>7} {peer_s:>7.2f} {n / peer_s:>8.0f} {peer_mb:>5.0f}"
            for method in args.methods:
                if method == "striped" and n > args.striped_up_to:
                    line += f" {'-':>8} {'-':>8} {'-':>8} {'-':>5} {'-':>6}"
                    continue
                out = tmp / f"{method}-{k}"
                secs, mb = _best([*SPECHOLO, "design", str(MODEL), "--out", str(out),
                                  "--method", method, "--stipples", str(n), "--formats", "svg"],
                                 args.repeat)
                got = _stipples(out)
                row.update({f"{method}_stipples": got, f"{method}_s": secs,
                            f"{method}_peak_mb": mb, f"{method}_ratio": peer_s / secs})
                line += (f" {got:>8} {secs:>8.2f} {got / secs:>8.0f} {mb:>5.0f} "
                         f"{peer_s / secs:>6.2f}")
            rows.append(row)
            print(line, flush=True)
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    with args.csv.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(max(rows, key=len)))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {args.csv}")


if __name__ == "__main__":
    main()

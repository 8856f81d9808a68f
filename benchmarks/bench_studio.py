"""The studio's fast preview at 1,000, 3,000 and 5,000 stipples, warm.

Usage: python benchmarks/bench_studio.py [--sizes 1000 3000 5000] [--repeat 5]

On the bundled bunny (60 mm, 40 mm behind the plate, the design's defaults),
with the model loaded and the compiled code warm, as while a maker drags:
the preview alone (place, stipple, occlusion, the estimates), and a whole
request to a running studio server (the preview, its JSON and the transfer).
Each figure is the median of ``--repeat`` runs, with the pose turned a little
each time so nothing is reused.
"""

from __future__ import annotations

import argparse
import json
import statistics
import threading
import time
import urllib.request
from pathlib import Path

from specholo.jobs.flat.folder import DesignConfig
from specholo.scene.loading import load_model
from specholo.studio.preview import fast_preview
from specholo.studio.server import make_server

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "bunny.obj"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 3000, 5000])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    model = load_model(MODEL)
    fast_preview(model, DesignConfig.from_dict({"stipples": 200}))  # compile, warm
    import tempfile

    server = make_server(MODEL, Path(tempfile.mkdtemp()), 0)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    print("| stipples | preview, s | request to the page, s | JSON, kB |")
    print("|---:|---:|---:|---:|")
    for n in args.sizes:
        alone, whole, size = [], [], 0
        for i in range(args.repeat):
            settings = {"stipples": n, "rotate_y": 2.0 * i}
            t0 = time.perf_counter()
            fast_preview(model, DesignConfig.from_dict(settings))
            alone.append(time.perf_counter() - t0)
            req = urllib.request.Request(
                server.origin + "/api/preview", data=json.dumps({"settings": settings}).encode(),
                headers={"X-Specholo-Token": server.token, "Content-Type": "application/json"})
            t0 = time.perf_counter()
            with urllib.request.urlopen(req) as reply:
                size = len(reply.read())
            whole.append(time.perf_counter() - t0)
        print(f"| {n:,} | {statistics.median(alone):.3f} | {statistics.median(whole):.3f} "
              f"| {size / 1000:.0f} |")
    server.shutdown()
    server.server_close()


if __name__ == "__main__":
    main()

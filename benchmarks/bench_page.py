"""Frame rate of the interactive page (``specholo view``) in headless Chromium.

Usage: python benchmarks/bench_page.py [--sizes 2000 10000 100000] [--seconds 5]

For each size the bunny is designed with the library (no G-code or SVG), the
page is built, and Chromium (software WebGL2: SwiftShader) keeps changing the
view every frame (the same sequence of views on every run) while
requestAnimationFrame intervals are recorded. Prints the arc count, the HTML
size, the load time, frames per second, the arcs the page drew per frame (the
narrow arcs its culling kept, plus the wide ones), the time per frame spent
culling and drawing (synchronised with the GPU; when splatting, from handing
the view to the page's workers to their last result, and the culling of the
slowest) and how the page drew the narrow glints ("splat" on a software
rasterizer, else "sprites"); pages too large for the browser to read are
reported as such, not measured.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "bunny.obj"
CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless=new", "--no-sandbox", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run",
        "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
#: V8 strings stop at about 2**29 characters; a base64 block beyond that cannot load.
MAX_LOADABLE_BYTES = 500_000_000


def measure(html: Path, seconds: float,
            size: tuple[int, int]) -> tuple[dict[str, float], str]:
    """Load the page and time frames while the view keeps changing; also returns
    how it drew the narrow glints."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": size[0], "height": size[1] + 40},
                                device_scale_factor=1)
        t0 = time.perf_counter()
        page.goto(f"{html.resolve().as_uri()}?w={size[0]}&h={size[1]}", timeout=600_000)
        page.wait_for_function("window.specholo && (window.specholo.ready"
                               " || window.specholo.error)", timeout=600_000)
        load = time.perf_counter() - t0
        error = page.evaluate("window.specholo.error")
        if error:
            raise RuntimeError(error)
        out: dict[str, float] = {"load_s": load}
        mode = str(page.evaluate("window.specholo.getView().mode"))
        for sync in (False, True):
            page.evaluate(f"window.specholo.jobs.spin.design(true, {str(sync).lower()})")
            page.wait_for_timeout(int(seconds * 1000))
            frames = page.evaluate("window.specholo.frameTimes()")
            draws = page.evaluate("window.specholo.drawTimes()")
            culls = page.evaluate("window.specholo.cullTimes()")
            drawn = page.evaluate("window.specholo.drawnArcs()")
            page.evaluate("window.specholo.jobs.spin.design(false)")
            if sync:
                out["draw_ms"] = statistics.median(draws) if draws else float("nan")
                out["cull_ms"] = statistics.median(culls) if culls else float("nan")
            else:
                out["frames"] = len(frames)
                out["fps"] = 1000.0 * len(frames) / sum(frames) if frames else 0.0
                out["drawn"] = statistics.mean(drawn) if drawn else float("nan")
        browser.close()
    return out, mode


def main() -> None:
    from specholo.jobs.flat.folder import DesignConfig, design
    from specholo.preview.page import build_page

    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--width", type=int, default=800)
    ap.add_argument("--height", type=int, default=600)
    args = ap.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average {load:.1f} on {os.cpu_count()} CPUs")
    print(f"{'stipples':>9} {'arcs':>10} {'drawn':>8} {'HTML MB':>8} {'build s':>8} "
          f"{'load s':>7} {'fps':>6} {'draw ms':>8} {'cull ms':>8}  note")
    for n in args.sizes:
        d = design(MODEL, DesignConfig(stipples=n))
        setup = d.config.setup()
        arcs = len(d.grooves.segments())
        with tempfile.TemporaryDirectory() as tmp:
            html = Path(tmp) / "view.html"
            t0 = time.perf_counter()
            html.write_text(build_page(d.grooves, setup), encoding="utf-8")
            build = time.perf_counter() - t0
            mb = html.stat().st_size / 1e6
            if html.stat().st_size > MAX_LOADABLE_BYTES:
                print(f"{n:>9} {arcs:>10} {'-':>8} {mb:>8.1f} {build:>8.1f} {'-':>7} {'-':>6} "
                      f"{'-':>8} {'-':>8}  too large for the browser to load (V8 string limit)",
                      flush=True)
                continue
            try:
                r, mode = measure(html, args.seconds, (args.width, args.height))
            except Exception as exc:  # noqa: BLE001 - a benchmark reports, never hides, failures
                print(f"{n:>9} {arcs:>10} {'-':>8} {mb:>8.1f} {build:>8.1f} {'-':>7} {'-':>6} "
                      f"{'-':>8} {'-':>8}  failed: {type(exc).__name__}: "
                      f"{str(exc).splitlines()[0]}", flush=True)
                continue
        print(f"{n:>9} {arcs:>10} {r['drawn']:>8.0f} {mb:>8.1f} {build:>8.1f} "
              f"{r['load_s']:>7.1f} {r['fps']:>6.1f} {r['draw_ms']:>8.1f} {r['cull_ms']:>8.1f}"
              f"  {int(r['frames'])} frames, {mode}", flush=True)


if __name__ == "__main__":
    main()

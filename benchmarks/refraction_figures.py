"""Figures of a refraction design: the paper's approximation's error, and the
verified error with either glint estimate.

Usage: python benchmarks/refraction_figures.py DIR [--every 1] [--step 5] [--verify]
       [--light-distance D --light-elevation A]

DIR is a refraction design (``specholo design ... --method ridged --optic refract``).

**The approximation.** For each of its stipples (every ``--every``-th), with
the design's light, plate and viewer,
:func:`specholo.optics.refraction.approximation_error` designs each eye's glint
where its sightline through the stipple crosses the front face, on the
Cartesian oval about a centre of divergence (paraxial, or fitted to the
in-plate rays), traces the real light (refracted at the planar back face, then
at that oval) and triangulates where each head sees the stipple. Heads every
``--step`` degrees over the design's azimuth and elevation ranges. Prints a
Markdown table of the errors over the stipples. ``--light-distance`` and
``--light-elevation`` (mm, degrees, as ``specholo design`` takes them) measure
it for another light behind the same plate instead of the design's.

**The design, verified** (``--verify``): what ``specholo verify DIR`` reports (the
light traced through the plate, each glint at its lit cells' centroid), and the
same with each glint where the fitted normal sends the light to the eye (the
``fit`` estimate, not biased by spots a riser crops).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from specholo.jobs.ridged.design import load_ridged_design, ridged_views
from specholo.optics.refraction import approximation_error
from specholo.optics.surfaces import Source
from specholo.setup import BackLight
from specholo.simulation.heightfield import head_eyes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("folder", type=Path)
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--step", type=float, default=5.0)
    ap.add_argument("--verify", action="store_true")
    ap.add_argument("--light-distance", type=float, default=None)
    ap.add_argument("--light-elevation", type=float, default=None)
    args = ap.parse_args()
    loaded = load_ridged_design(args.folder)
    setup = loaded.config.setup()
    light = setup.light
    if not isinstance(light, BackLight):
        raise SystemExit(f"{args.folder} is not a refraction design (--optic refract)")
    if args.light_distance is not None or args.light_elevation is not None:
        light = BackLight(math.radians(args.light_elevation if args.light_elevation is not None
                                       else loaded.config.light_elevation),
                          args.light_distance if args.light_distance is not None
                          else light.distance, light.thickness, light.index)
    az, el = ridged_views(loaded.config, args.step)
    pairs = [head_eyes(setup.viewer, float(a), float(e)) for a in az for e in el]
    left = np.array([p[0] for p in pairs])
    right = np.array([p[1] for p in pairs])
    source = Source.from_light(light)
    points = loaded.points[::args.every]
    print(f"{len(points)} stipples, {len(pairs)} heads ({len(az)} azimuths x {len(el)} "
          f"elevations), plate {light.thickness:g} mm of index {light.index:g}, light "
          + ("a sun" if light.position is None else
             "at (" + ", ".join(f"{v:.1f}" for v in light.position) + ") mm"))
    print("| centre | normal tilt, max (mrad) | exit ray off the eye, max (mrad) "
          "| glint moves p95 / max (mm) | apparent point p95 over stipples (mm) "
          "| worst (mm) |")
    print("|---|---:|---:|---:|---:|---:|")
    for centre in ("paraxial", "fitted"):
        rows = [approximation_error(p, source, light.plate, left, right, centre)
                for p in points]
        tilt = max(r.max_tilt for r in rows)
        angle = max(r.max_angle for r in rows)
        off95 = np.percentile([r.p95_offset for r in rows], 95)
        offmax = max(r.max_offset for r in rows)
        err95 = np.percentile([r.p95_error for r in rows], 95)
        worst = max(r.max_error for r in rows)
        print(f"| {centre} | {1e3 * tilt:.3f} | {1e3 * angle:.3f} | {off95:.3f} / "
              f"{offmax:.3f} | {err95:.3f} | {worst:.3f} |")
    if args.verify:
        if light is not setup.light:
            raise SystemExit("--verify checks the design's own light")
        from specholo.jobs.ridged.design import _occlusion
        from specholo.simulation.heightfield import verify_field

        print("| glint estimate | worst p95 (mm) | median p95 over heads (mm) | worst p95 depth "
              "(mm) | heads with glints | stipples per head | served that glint |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        for estimate in ("centroid", "fit"):
            reports = verify_field(loaded.heights, loaded.points, setup,
                                   _occlusion(loaded.mesh, loaded.normals), az, el,
                                   estimate=estimate, shell=float(loaded.config.shell))
            p95 = np.array([r.p95_error for r in reports])
            depth = np.array([r.p95_depth_error for r in reports])
            per_head = np.nansum([r.visibility * r.stipples_seen for r in reports]) / len(reports)
            served = np.nanmean([r.served_visibility for r in reports])
            print(f"| {estimate} | {np.nanmax(p95):.3f} | {np.nanmedian(p95):.3f} | "
                  f"{np.nanmax(depth):.3f} | {int(np.isfinite(p95).sum())} of {len(reports)} | "
                  f"{per_head:.1f} | {served:.2f} |")


if __name__ == "__main__":
    main()

"""Time to build a ridged full-parallax plate of the bunny and to verify it.

Usage: python benchmarks/bench_ridged.py [--stipples 300] [--delta 0.1]
       [--resolution 0.02] [--view-range 30] [--elevation-range 15] [--step 5]
       [--aspect 3] [--estimate centroid] [--no-shadows] [--milled RADIUS] [--refraction]
       [--out FOLDER]

Places the bundled bunny (60 mm, centre 40 mm behind the plate), stipples it,
designs the ridged plate (sun at 45 degrees, viewer at 600 mm, the given head
azimuth and elevation ranges), then simulates stereo heads every ``--step``
degrees over those ranges and prints tables by azimuth (columns) and elevation
(rows): the 95th-percentile error of the apparent points, how many unoccluded
stipples the regions serve to both eyes, the share of those that glint (the
rest fall in riser shadows or behind risers), and the share of all unoccluded
stipples that glint. ``--milled`` also simulates finishing the plate with a
ball-end raster of that radius (stepover one sample) and verifies the milled
surface; ``--refraction`` prints the error of the paper's refraction
approximation; ``--out`` writes the height map (PNG, TIFF, JSON), a STL and the
raster G-code.
"""

from __future__ import annotations

import argparse
import math
import resource
import time
from pathlib import Path

import numpy as np

from specholo.scene.loading import load_model
from specholo.scene.placement import place
from specholo.scene.stippling import stipple
from specholo.setup import Light, Machining, Setup, Viewer
from specholo.simulation.heightfield import FullViewReport, report_table, verify_field
from specholo.toolpaths.ridged import RidgeOptions, design_ridged
from specholo.visibility.occlusion import visible

MODEL = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


def _tables(reports: list[FullViewReport], title: str) -> None:
    print(f"\n== {title}")
    for key, label in (("p95_error", "p95 error of the apparent point, mm"),
                       ("max_error", "worst error, mm"),
                       ("served", "stipples served to both eyes (unoccluded)"),
                       ("served_visibility", "share of served stipples that glint"),
                       ("visibility", "share of unoccluded stipples that glint"),
                       ("false_glints", "share of occluded (stipple, eye) pairs glinting")):
        print(f"\n{label}:")
        print(report_table(reports, key))
    p95 = [r.p95_error for r in reports if not math.isnan(r.p95_error)]
    served = [r.served_visibility for r in reports if not math.isnan(r.served_visibility)]
    glinting = [r.visibility * r.stipples_seen for r in reports if not math.isnan(r.visibility)]
    print(f"\nworst p95 {max(p95):.3f} mm over {len(p95)} of {len(reports)} heads with glints; "
          f"mean served visibility {np.mean(served):.2f}; "
          f"stipples glinting for both eyes per head: mean {np.mean(glinting):.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--stipples", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--delta", type=float, default=0.1)
    ap.add_argument("--resolution", type=float, default=0.02)
    ap.add_argument("--view-range", type=float, default=30.0, help="head azimuth, degrees")
    ap.add_argument("--elevation-range", type=float, default=15.0, help="degrees")
    ap.add_argument("--aspect", type=float, default=RidgeOptions.aspect,
                    help="horizontal stretch of the stipples' regions")
    ap.add_argument("--step", type=float, default=5.0, help="head grid step, degrees")
    ap.add_argument("--estimate", choices=("centroid", "fit"), default="centroid")
    ap.add_argument("--no-shadows", action="store_true")
    ap.add_argument("--milled", type=float, default=None, help="ball radius, mm")
    ap.add_argument("--refraction", action="store_true")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()

    setup = Setup(light=Light(math.radians(45.0)),
                  viewer=Viewer(600.0, 0.0, math.radians(args.view_range)))
    model = place(load_model(MODEL), 60.0, -40.0)
    st = stipple(model, np.random.default_rng(args.seed), count=args.stipples)
    opts = RidgeOptions(delta=args.delta, resolution=args.resolution,
                        block=10 * args.resolution, aspect=args.aspect,
                        elevation_range=math.radians(args.elevation_range))
    # Compile (or load the cached kernels) on a tiny design first.
    design_ridged(st.points[:2], st.normals[:2], None, setup, RidgeOptions(
        delta=args.delta, resolution=0.1, block=0.2, elevation_range=0.05, view_step=0.05))

    t0 = time.perf_counter()
    plate = design_ridged(st.points, st.normals, model.mesh, setup, opts)
    t_build = time.perf_counter() - t0
    hm = plate.heights
    s = plate.summary()
    print(f"bunny 60 mm at z = -40 mm, {args.stipples} stipples; sun 45 deg, heads at 600 mm "
          f"over +-{args.view_range:g} deg azimuth, +-{args.elevation_range:g} deg elevation")
    print(f"plate {hm.bounds[1, 0] - hm.bounds[0, 0]:.1f} x {hm.bounds[1, 1] - hm.bounds[0, 1]:.1f}"
          f" mm at {hm.resolution:g} mm: {hm.shape[1]} x {hm.shape[0]} = {hm.z.size / 1e6:.1f} M "
          f"cells, deepest {s['deepest_mm']:.3f} mm")
    print(f"build: {t_build:.1f} s (" + ", ".join(f"{k} {v:.1f} s" for k, v in
                                               plate.timings.items()) + ")")
    print(f"stipples visible in range {s['visible_in_range']}, kept {s['kept_stipples']}, "
          f"dropped {len(s['dropped_stipples'])} (never visible in range); kept share of "
          f"visible views: median {s['median_kept_share']:.3f}, mean {s['mean_kept_share']:.3f}")
    print(f"patches' total area {s['patch_area_sum_mm2']:.0f} mm^2 on a plate of "
          f"{s['plate_area_mm2']:.0f} mm^2 ({s['used_area_mm2']:.0f} mm^2 used)")

    mesh, normals = model.mesh, st.normals

    def vis(points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        return visible(mesh, points, normals, eyes)

    az = np.radians(np.arange(-args.view_range, args.view_range + 1e-9, args.step))
    el = np.radians(np.arange(-args.elevation_range, args.elevation_range + 1e-9, args.step))
    t0 = time.perf_counter()
    reports = verify_field(hm, st.points, setup, vis, az, el, shadows=not args.no_shadows,
                           estimate=args.estimate, shell=plate.delta)
    t_verify = time.perf_counter() - t0
    print(f"verify: {t_verify:.1f} s for {len(reports)} heads "
          f"({t_verify / (2 * len(reports)) * 1e3:.0f} ms per eye, occlusion included)")
    _tables(reports, f"designed plate ({args.estimate}, "
                     f"{'no shadows' if args.no_shadows else 'shadows traced'})")

    if args.milled is not None:
        from specholo.fabrication.heightmap import milled

        t0 = time.perf_counter()
        cut = milled(hm, args.milled)
        print(f"\nmilled with a {args.milled:g} mm ball: {time.perf_counter() - t0:.1f} s; "
              f"largest height left {float(np.max(cut.z - hm.z)):.3f} mm")
        _tables(verify_field(cut, st.points, setup, vis, az, el, estimate=args.estimate,
                             shell=plate.delta), f"milled plate, ball {args.milled:g} mm")

    if args.refraction:
        from specholo.optics.refraction import approximation_table

        t0 = time.perf_counter()
        print("\n== refraction: paper's approximation vs exact planar-back solution "
              "(heads +-30 az, +-15 el at 600 mm; stipple at x 15, y 10 mm)")
        print(" light el  light mm  plate mm  p_z mm  centre     tilt deg  angle deg  "
              "p95 glint mm  p95 3D mm")
        for elevation in (0.0, 30.0):
            for r in approximation_table(distances=(300.0, 1000.0), thicknesses=(3.0, 10.0),
                                         elevation=math.radians(elevation)):
                print(f"{elevation:9.0f} {r.light_distance:9.0f} {r.thickness:9.0f} "
                      f"{r.depth:7.0f}  {r.centre:9s}{math.degrees(r.max_tilt):10.4f} "
                      f"{math.degrees(r.max_angle):10.4f} {r.p95_offset:13.3f} "
                      f"{r.p95_error:10.3f}")
        print(f"({time.perf_counter() - t0:.1f} s)")

    if args.out is not None:
        from specholo.fabrication.heightmap import (
            save_npz,
            write_images,
            write_raster_gcode,
            write_stl,
        )

        args.out.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        write_images(args.out / "heightmap", hm)
        save_npz(args.out / "plate.npz", hm)
        write_stl(args.out / "plate.stl", hm, thickness=3.0)
        stats = write_raster_gcode(args.out / "plate.gcode", hm, 0.05,
                                   Machining(feed=300.0, plunge=100.0, safe_z=1.0,
                                             spindle=20000.0), stepover=2 * hm.resolution)
        print(f"\nfiles: {time.perf_counter() - t0:.1f} s; G-code {stats.lines:,} lines, "
              f"{stats.passes} passes, {stats.cutting_length_mm / 1000:.1f} m, "
              f"{stats.minutes / 60:.1f} h at the feed")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak memory {peak:.0f} MB")


if __name__ == "__main__":
    main()

"""The plate as cut, two ways: glint survival against the height-field simulation.

Usage: python benchmarks/bench_survival.py [--stipples 2000] [--resolution 0.005]
       [--methods striped arc] [--step 5] [--set NAME=VALUE ...]

Designs the README's example in-process (bunny, 60 mm, centre z -40 mm, sun at
45 deg, eyes 600 mm away over +-45 deg, default drag tip) with each design
method, then verifies its grooves per head azimuth three ways, with the model's
occlusion: ideally (``verify``), as cut by the survival test
(``simulation.survival``: the designed glints no other groove's cut removes)
and as cut on a height field of the plate at ``--resolution`` mm
(``simulation.cut``, what ``verify --cut --cut-method field`` runs). Prints the
stereo visibility per azimuth side by side, the largest difference between the
two as-cut figures, and the seconds each took (the height field's includes its
sweep and the glint search on it). ``--set`` changes any other design setting
(e.g. ``--set band=0.3``). One thing runs at a time.
"""

from __future__ import annotations

import argparse
import math
import resource
import time
from pathlib import Path

import numpy as np

from specholo.jobs.flat.folder import DesignConfig, design
from specholo.simulation.cut import cut_surface, verify_cut
from specholo.simulation.survival import survivors, verify_as_cut
from specholo.simulation.verify import verify, view_azimuths
from specholo.visibility.occlusion import visible

MODEL = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
README = {"size": 60.0, "center_z": -40.0, "light_elevation": 45.0, "view_distance": 600.0,
          "view_range": 45.0}


def _timed(fn):  # type: ignore[no-untyped-def]
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def run(method: str, stipples: int, resolution: float, step: float,
        extra: dict[str, object]) -> None:
    config = DesignConfig.from_dict({**README, **extra, "stipples": stipples, "method": method})
    d, t_design = _timed(lambda: design(MODEL, config, check_overlaps=False,
                                        expect_as_cut=False))
    setup = d.config.setup()
    cutter, depth = d.config.cutter(), d.config.depth_mm
    mesh, normals = d.model.mesh, d.normals

    def vis(points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        return visible(mesh, points, normals, eyes)

    az = view_azimuths(setup.viewer.half_range, math.radians(step))
    # Load (or compile) the kernels on a tiny problem first.
    survivors(d.grooves, np.zeros((1, 3)), np.zeros(1, np.int64), cutter, depth)
    lo = d.grooves.extent()[0]
    cut_surface(d.grooves, cutter, depth, bounds=np.stack([lo, lo + 1.0]),
                resolution=resolution)

    ideal, t_ideal = _timed(lambda: verify(d.grooves, d.points, setup, vis, az))
    as_cut, t_survival = _timed(lambda: verify_as_cut(d.grooves, d.points, setup, cutter,
                                                      depth, vis, az))

    def by_field() -> list:  # type: ignore[type-arg]
        field = cut_surface(d.grooves, cutter, depth, resolution=resolution)
        return verify_cut(field, d.points, setup, vis, az)

    field, t_field = _timed(by_field)
    print(f"\n{method}: {len(d.points)} stipples, {d.grooves.n_paths} paths, "
          f"{len(d.grooves.vertices)} vertices, {cutter.describe()} {depth:g} mm deep "
          f"(designed in {t_design:.1f} s)")
    print(f"| azimuth | ideal | as cut, survival | as cut, height field {resolution:g} mm |")
    print("|---:|---:|---:|---:|")
    for a, b, c in zip(ideal, as_cut.reports, field, strict=True):
        print(f"| {a.azimuth:+.0f} | {a.visibility:.3f} | {b.visibility:.3f} | "
              f"{c.visibility:.3f} |")
    diff = [abs(b.visibility - c.visibility) for b, c in zip(as_cut.reports, field, strict=True)]
    print(f"largest |survival - height field|: {max(diff):.3f}; mean survival "
          f"{np.mean([r.visibility for r in as_cut.reports]):.3f}, height field "
          f"{np.mean([r.visibility for r in field]):.3f}")
    print(f"seconds: ideal {t_ideal:.1f}, survival {t_survival:.1f}, height field "
          f"{t_field:.1f}; peak memory "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--stipples", type=int, default=2000)
    ap.add_argument("--resolution", type=float, default=0.005)
    ap.add_argument("--methods", nargs="+", default=["striped", "arc"],
                    choices=["striped", "hyperbola", "arc"])
    ap.add_argument("--step", type=float, default=5.0, help="azimuth step, degrees")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="another design setting (a number or a word)")
    args = ap.parse_args()
    extra: dict[str, object] = {}
    for item in args.set:
        name, _, value = item.partition("=")
        try:
            extra[name] = float(value)
        except ValueError:
            extra[name] = value
    for method in args.methods:
        run(method, args.stipples, args.resolution, args.step, extra)


if __name__ == "__main__":
    main()

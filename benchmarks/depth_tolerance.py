"""How much depth error a plate tolerates, as cut: the README example's grooves
cut to other depths than designed.

Usage: python benchmarks/depth_tolerance.py [--scene readme|unseen] [--stipples 2000]
       [--errors 0.001 0.002 0.003 0.005 0.008] [--seed 0] [--set KEY=VALUE ...]
       [--tiers]

Designs the scene (the density curve's scenes, default settings: the depth is
what the steepest wall needs plus ``DEPTH_ALLOWANCE``) and verifies it as cut
by the survival test (every 5 deg, the model's occlusion) with every path cut
to a depth of its own:

- every groove deeper or shallower by the same amount (a Z offset);
- every groove at its own depth, drawn uniformly within +-e of the design's
  (neighbouring grooves at independent depths: the worst case for crossings,
  as a drag spring's force or a machine's Z wandering from groove to groove);
- the same about the depth the walls need, without the allowance;
- with ``--tiers``, two depth classes: a share of the stipples (drawn at
  random) has all its grooves cut some micrometres deeper. A deep groove's
  glints then sit below the shallow grooves' reach, at the price of its
  wider cut at the surface.

``--set`` changes a design setting as in ``density_curve.py`` (e.g.
``--set placement=avoid``).

A groove cut shallower than a glint's wall needs loses that glint; a deeper
crossing groove reaches further into its neighbours' walls. It prints the
lowest and mean stereo visibility over the views for each. Nothing is timed.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from density_curve import SCENES, _setting  # noqa: E402

from specholo.jobs.flat.folder import DesignConfig, design  # noqa: E402
from specholo.jobs.flat.settings import DEPTH_ALLOWANCE  # noqa: E402
from specholo.simulation.survival import verify_as_cut  # noqa: E402
from specholo.simulation.verify import view_azimuths  # noqa: E402
from specholo.visibility.occlusion import visible  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", choices=sorted(SCENES), default="readme")
    ap.add_argument("--stipples", type=int, default=2000)
    ap.add_argument("--errors", type=float, nargs="+",
                    default=[0.001, 0.002, 0.003, 0.005, 0.008])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--set", dest="changes", action="append", default=[],
                    metavar="KEY=VALUE", help="change a design setting of the scene")
    ap.add_argument("--tiers", action="store_true", help="also two depth classes")
    args = ap.parse_args()
    model, settings = SCENES[args.scene]
    changes = dict(_setting(c) for c in args.changes)
    d = design(model, DesignConfig.from_dict({**settings, **changes,
                                              "stipples": args.stipples}),
               check_overlaps=False, expect_as_cut=False)
    setup, cutter, depth = d.config.setup(), d.config.cutter(), d.config.depth_mm
    mesh, normals = d.model.mesh, d.normals
    az = view_azimuths(setup.viewer.half_range, math.radians(5.0))
    n = d.grooves.n_paths
    rng = np.random.default_rng(args.seed)

    def row(label: str, cut_to: np.ndarray) -> None:
        as_cut = verify_as_cut(d.grooves, d.points, setup, cutter, depth,
                               lambda p, e: visible(mesh, p, normals, e), az,
                               path_depths=cut_to)
        vis = as_cut.stereo_visibility
        print(f"| {label} | {1000 * cut_to.min():.1f}–{1000 * cut_to.max():.1f} | "
              f"{np.nanmin(vis):.3f} / {np.nanmean(vis):.3f} |", flush=True)

    print(f"{args.scene}, {args.stipples} stipples, {cutter.describe()}, designed "
          f"{1000 * depth:.0f} um deep ({1000 * DEPTH_ALLOWANCE:.0f} um of it allowance), "
          f"placed by {(d.placement or {}).get('placement', '')}")
    print("| grooves cut | depths, um | as cut, lowest / mean |")
    print("|---|---:|---:|")
    row("at the design's depth", np.full(n, depth))
    for shift in (-DEPTH_ALLOWANCE, DEPTH_ALLOWANCE, 2 * DEPTH_ALLOWANCE):
        row(f"all {1000 * shift:+.0f} um", np.full(n, depth + shift))
    for e in args.errors:
        row(f"each within ±{1000 * e:g} um", depth + rng.uniform(-e, e, n))
    need = depth - DEPTH_ALLOWANCE
    for e in args.errors:
        row(f"each within ±{1000 * e:g} um of the walls' need",
            np.maximum(need + rng.uniform(-e, e, n), 1e-6))
    if args.tiers:
        stipple = d.grooves.stipple
        for share in (0.3, 0.5):
            deep = np.random.default_rng(args.seed).random(len(d.points)) < share
            for step in (0.004, 0.006, 0.010):
                row(f"{share:.0%} of the stipples {1000 * step:g} um deeper",
                    np.where(deep[stipple], depth + step, depth))


if __name__ == "__main__":
    main()

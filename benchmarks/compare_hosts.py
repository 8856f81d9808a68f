"""Composed designs on every kind of host and motion, verified, side by side.

Usage: python benchmarks/compare_hosts.py [--stipples 400] [--step 5]

For each case a composition is written to a temporary folder (the height
field and mesh hosts get their files there too), designed and verified with
the library, as ``specholo compose`` does. Prints, per case, the stripes, the
groove length, the design and verification times, and the worst figures over
the viewer positions: 95th-percentile error of the triangulated point, its
depth part, the lowest visibility and the most stray glints.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from specholo.jobs.composition.design import (
    design_composition,
    parse_composition,
    verify_composition,
)
from specholo.simulation.conforming import summarise

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
SCENE = f'[[scene]]\nmodel = "{BUNNY}"\nsize = 40\ncenter_z = -30\n'


def relief(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """A gently rolling relief, 4 mm peak to peak, 0 at the origin."""
    return 2.0 * np.sin(x / 18.0) * np.cos(y / 25.0)


def cases(folder: Path) -> list[tuple[str, str]]:
    x = np.linspace(-70, 70, 141)
    y = np.linspace(-60, 60, 121)
    xx, yy = np.meshgrid(x, y)
    np.savez(folder / "relief.npz", x=x, y=y, z=relief(xx, yy))
    # The same relief as a triangle mesh (a scanned or modelled surface).
    verts = np.column_stack([xx.ravel(), yy.ravel(), relief(xx, yy).ravel()])
    nx = len(x)
    q = np.arange(len(y) - 1)[:, None] * nx + np.arange(nx - 1)[None, :]
    q = q.ravel()
    faces = np.concatenate([np.column_stack([q, q + 1, q + nx + 1]),
                            np.column_stack([q, q + nx + 1, q + nx])])
    trimesh.Trimesh(verts, faces, process=False).export(folder / "relief.stl")
    panels = ('[[host.panels]]\ncentre = [-26, 0, -4]\nnormal = [0.25, 0, 1]\nwidth = 50\n'
              'height = 100\n[[host.panels]]\ncentre = [26, 0, -4]\nnormal = [-0.25, 0, 1]\n'
              'width = 50\nheight = 100\n')
    return [
        ("plane, walk", '[host]\nkind = "plane"\n'),
        ("cylinder r 40, walk", '[host]\nkind = "cylinder"\nradius = 40\nheight = 100\n'),
        ("sphere r 80, walk", '[host]\nkind = "sphere"\nradius = 80\n'),
        ("height field, walk", '[host]\nkind = "heightfield"\nfile = "relief.npz"\n'),
        ("mesh (relief), walk", '[host]\nkind = "mesh"\nfile = "relief.stl"\n'),
        ("two panels, walk", '[host]\nkind = "panels"\n' + panels),
        ("plane, light 30-60 deg", 'mode = "light"\n[host]\nkind = "plane"\n'),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--stipples", type=int, default=400)
    ap.add_argument("--step", type=float, default=5.0)
    args = ap.parse_args()
    print(f"{'case':<24} {'stripes':>8} {'groove m':>9} {'design s':>9} {'verify s':>9} "
          f"{'p95 mm':>7} {'depth':>6} {'vis':>6} {'stray':>6}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name, host in cases(folder):
            mode, _, rest = host.partition("[host]")
            text = (f"{mode}stipples = {args.stipples}\nseed = 1\n[host]{rest}\n"
                    "[viewer]\nrange = 30\n[light]\nelevation = 30\nstop = 60\n"
                    if mode else f"stipples = {args.stipples}\nseed = 1\n{host}\n"
                    "[viewer]\nrange = 30\n[light]\nelevation = 45\n") + SCENE
            if "light" in name:
                text = text.replace(SCENE, SCENE + "turn = 0.5\n")
            comp = parse_composition(text, folder)
            t0 = time.perf_counter()
            d = design_composition(comp)
            t1 = time.perf_counter()
            s = summarise(verify_composition(d, math.radians(args.step)))
            t2 = time.perf_counter()
            print(f"{name:<24} {d.stats['stripes']:>8,} {d.stats['groove_length_mm'] / 1e3:>9.2f} "
                  f"{t1 - t0:>9.1f} {t2 - t1:>9.1f} {s['worst_p95_error']:>7.3f} "
                  f"{s['worst_p95_depth_error']:>6.3f} {s['min_visibility']:>6.3f} "
                  f"{s['max_stray']:>6.3f}", flush=True)


if __name__ == "__main__":
    main()

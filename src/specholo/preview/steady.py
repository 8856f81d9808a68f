"""The picture of a steady image: what the left eye sees as the light moves.

Three panels, the light at the low end, the middle and the high end of its
range: every glint the left eye sees on the scoops (white), over the plate's
cuts (grey). The image should stay put from panel to panel; that is the design's
whole point, shown rather than told.
"""

from __future__ import annotations

import math
import os

from specholo.setup import Tool
from specholo.simulation.steady import find_steady_glints
from specholo.toolpaths.steady import SteadyDesign


def steady_preview(design: SteadyDesign, tool: Tool, path: str | os.PathLike[str]) -> None:
    """Write the three-panel PNG of ``design``'s glints for the left eye (atomically)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from specholo.fabrication.atomic import atomic_open

    setup = design.setup
    eye = setup.eyes()[0]
    mid, half = setup.light_elevation, setup.light_sweep
    centres = design.centres
    lo, hi = centres[:, :2].min(axis=0), centres[:, :2].max(axis=0)
    pad = 0.05 * float(max(hi - lo)) + 1.0
    fig, axes = plt.subplots(1, 3, figsize=(10.5, 3.9), facecolor="black")
    for ax, el in zip(axes, (mid - half, mid, mid + half), strict=True):
        g = find_steady_glints(design, eye, setup.light(el), tool)
        own = design.eye[g.cut] == 0
        ax.set_facecolor("black")
        ax.plot(centres[:, 0], centres[:, 1], ",", color="0.35")
        ax.plot(g.point[own, 0], g.point[own, 1], "o", color="white", markersize=1.6)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"light at {math.degrees(el):.1f} deg: {int(own.sum())} glints",
                     color="white", fontsize=10)
    fig.suptitle("steady image: what the left eye sees as the light moves (grey: the cuts)",
                 color="white", fontsize=11)
    fig.tight_layout()
    with atomic_open(path, "wb", encoding=None) as fh:
        fig.savefig(fh, format="png", dpi=100, facecolor="black")
    plt.close(fig)

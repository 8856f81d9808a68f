"""Simulated views of the engraved plate under its light, and the chart of a
verification over azimuth and elevation (the flat one is :mod:`specholo.preview.chart`)."""

from __future__ import annotations

import io
import math
import os
from typing import Any

import numpy as np

from specholo.fabrication.atomic import atomic_open
from specholo.preview.render import glints_seen
from specholo.setup import Setup
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.heightmap import HeightMap


def project(points: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """Pinhole projection toward the plate centre.

    Args:
        points: (n, 3) points in mm.
        eye: (3,) camera position.

    Returns:
        (n, 2) image coordinates (tangent of the angle right and up from the axis).
    """
    forward = -eye / np.linalg.norm(eye)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    rel = points - eye
    depth = rel @ forward
    return np.stack([rel @ right / depth, rel @ up / depth], axis=1)


def render_preview(grooves: Grooves, setup: Setup, path: str | os.PathLike[str],
                   azimuths_deg: tuple[float, ...] = (-30.0, 0.0, 30.0),
                   plate: np.ndarray | None = None) -> None:
    """Write a PNG of the glints one eye sees from a few azimuths on the arc.

    Args:
        grooves: the engraved grooves.
        setup: light, viewer and tool.
        path: PNG file to write (atomically).
        azimuths_deg: eye azimuths, clipped to the view range.
        plate: (2, 2) the plate's corners, mm, outlined and framed (so an offset
            or a plate larger than the grooves shows); default the grooves' extent.
    """
    limit = math.degrees(setup.viewer.half_range)
    az = sorted({max(-limit, min(limit, a)) for a in azimuths_deg})
    eyes = setup.viewer.eye(np.radians(az))
    # A large design is searched a run of paths at a time, each run for every eye.
    seen = glints_seen(grooves, setup.tool, eyes, setup.light)
    lo, hi = grooves.bounds() if plate is None else np.asarray(plate, dtype=float)
    _draw_views(az, eyes, list(seen), lo, hi, path)


def render_field_preview(heights: HeightMap, setup: Setup, path: str | os.PathLike[str],
                         azimuths_deg: tuple[float, ...] = (-30.0, 0.0, 30.0)) -> None:
    """:func:`render_preview` for a plate given as a height field (a ridged design):
    the glints one eye sees on it from a few azimuths on the arc, found with the
    physics of ``verify`` (:func:`~specholo.simulation.heightfield.find_field_glints`).

    Args:
        heights: the labelled plate (a ``HeightMap``).
        setup: light and viewer.
        path: PNG file to write (atomically).
        azimuths_deg: eye azimuths, clipped to the view range.
    """
    from specholo.simulation.heightfield import SlopeIndex, find_field_glints

    limit = math.degrees(setup.viewer.half_range)
    az = sorted({max(-limit, min(limit, a)) for a in azimuths_deg})
    eyes = setup.viewer.eye(np.radians(az))
    index = SlopeIndex.build(heights)
    seen = [find_field_glints(index, eye, setup.light).glints.point for eye in eyes]
    lo, hi = np.asarray(heights.bounds, dtype=float)
    _draw_views(az, eyes, seen, lo, hi, path)


#: One panel of the preview, pixels: wide, high, and the title's band above the plate.
PANEL = (462, 484, 34)
#: Blank pixels around the plate's outline in its panel.
_PANEL_MARGIN = 12


def panel_transform(frame: np.ndarray, panel: int) -> tuple[np.ndarray, float]:
    """Where projected points go in the preview: pixel = offset + scale * (u, -v).

    Args:
        frame: (k, 2) the plate outline's projected corners (they set the scale,
            the same in u and v, so the plate keeps its shape).
        panel: the panel's index from the left.

    Returns:
        (2,) the pixel offset and the scale, pixels per projected unit.
    """
    w, h, title = PANEL
    lo, hi = frame.min(axis=0), frame.max(axis=0)
    span = np.maximum(hi - lo, 1e-12)
    scale = float(min((w - 2 * _PANEL_MARGIN) / span[0],
                      (h - title - 2 * _PANEL_MARGIN) / span[1]))
    mid = 0.5 * (lo + hi)
    centre = np.array([panel * w + 0.5 * w, title + 0.5 * (h - title)])
    return centre - scale * np.array([mid[0], -mid[1]]), scale


def _draw_views(az: list[float], eyes: np.ndarray, seen: list[np.ndarray],
                lo: np.ndarray, hi: np.ndarray, path: str | os.PathLike[str]) -> None:
    """One black panel per eye: the plate's outline and the glints it sees, in
    that eye's perspective. Drawn with Pillow: a design's first picture should
    not wait for a plotting library's import."""
    from PIL import Image, ImageDraw, ImageFont

    w, h, _ = PANEL
    img = Image.new("RGB", (w * len(az), h))
    draw = ImageDraw.Draw(img)
    try:
        font: Any = ImageFont.load_default(size=14)
    except TypeError:  # Pillow before 10.1: the bitmap font, one size
        font = ImageFont.load_default()
    corners = np.array([[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0],
                        [lo[0], hi[1], 0], [lo[0], lo[1], 0]])
    rows, cols = [], []
    for k, (a, eye, points) in enumerate(zip(az, eyes, seen, strict=True)):
        frame = project(corners, eye)
        offset, scale = panel_transform(frame, k)
        outline = offset + scale * frame * np.array([1.0, -1.0])
        draw.line([tuple(p) for p in outline], fill=(70, 70, 70), width=1)
        draw.text((k * w + 0.5 * w, 10), f"azimuth {a:+.0f}\u00b0  ({len(points)} glints)",
                  fill=(187, 187, 187), font=font, anchor="mt")
        if len(points):
            # each glint a 2 x 2 pixel dot, its top left at the glint, over the outline
            uv = offset + scale * project(points, eye) * np.array([1.0, -1.0])
            col = np.floor(uv[:, 0]).astype(np.int64)
            row = np.floor(uv[:, 1]).astype(np.int64)
            for dr in (0, 1):
                for dc in (0, 1):
                    r, c = row + dr, col + dc
                    ok = (r >= 0) & (r < h) & (c >= k * w) & (c < (k + 1) * w)
                    rows.append(r[ok])
                    cols.append(c[ok])
    pixels = np.array(img)
    if rows:
        pixels[np.concatenate(rows), np.concatenate(cols)] = 235
    img = Image.fromarray(pixels, "RGB")
    buf = io.BytesIO()
    img.save(buf, format="PNG", optimize=False)
    with atomic_open(path, "wb", encoding=None) as fh:
        fh.write(buf.getvalue())


def plot_field_verification(rows: list[dict[str, float]], path: str | os.PathLike[str],
                            title: str = "") -> None:
    """Write a PNG of error and visibility by azimuth, one line per elevation (rows
    from a verification over azimuth and elevation)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    elevations = sorted({r["elevation"] for r in rows})
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    cmap = plt.get_cmap("viridis")
    for k, el in enumerate(elevations):
        sel = sorted((r for r in rows if r["elevation"] == el), key=lambda r: r["azimuth"])
        colour = cmap(k / max(len(elevations) - 1, 1))
        az = [r["azimuth"] for r in sel]
        ax1.plot(az, [r["p95_error"] for r in sel], "o-", color=colour, ms=3,
                 label=f"elevation {el:+.0f}°")
        ax2.plot(az, [r["visibility"] for r in sel], "o-", color=colour, ms=3)
    ax1.set_ylabel("95th-percentile error (mm)")
    ax1.legend(fontsize=7, ncol=2)
    ax1.grid(alpha=0.3)
    ax2.set_ylabel("visibility")
    ax2.set_ylim(bottom=0.0)
    ax2.set_xlabel("head azimuth (degrees)")
    ax2.grid(alpha=0.3)
    if title:
        ax1.set_title(title)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    with atomic_open(path, "wb", encoding=None) as fh:
        fh.write(buf.getvalue())

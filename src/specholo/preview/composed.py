"""Pictures of composed designs (any host, any motion): what one eye sees along
the motion, from the same glints as their verification.

For a walking viewer the camera is the left eye walking the arc; for a moving
light it is the still left eye while the light rises. Each frame's glints come
from :func:`~specholo.simulation.conforming.find_conforming_glints` for that
camera and light; the backdrop is the host's extent as a dark plate.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from specholo.preview.motion import sweep
from specholo.preview.render import (
    REFERENCE_ROUGHNESS,
    Camera,
    draw_glints,
    fit_fov,
    plate_corners,
)
from specholo.setup import Light
from specholo.simulation.conforming import find_conforming_glints


def composed_bounds(grooves: Any, margin: float = 5.0) -> np.ndarray:
    """The rectangle (2, 2) the grooves span in x, y, plus a margin, mm."""
    if len(grooves.point) == 0:
        return np.array([[-10.0, -10.0], [10.0, 10.0]])
    lo = np.nanmin(grooves.point[:, :2], axis=0) - margin
    hi = np.nanmax(grooves.point[:, :2], axis=0) + margin
    return np.stack([lo, hi])


def composed_frames(d: Any, frames: int, size: tuple[int, int] = (512, 512),
                    roughness: float = REFERENCE_ROUGHNESS, loop: bool = True,
                    progress: Callable[[], None] | None = None) -> list[np.ndarray]:
    """Frames along the design's motion, as the left eye sees them.

    Args:
        d: a :class:`~specholo.jobs.composition.design.ComposedDesign`.
        frames: number of frames.
        size: (width, height) pixels.
        roughness: the specular lobe's width, radians.
        loop: there and back.
        progress: called after each frame.

    Returns:
        (H, W, 3) uint8 frames.
    """
    comp = d.comp
    motion = comp.motion
    width, height = size
    bounds = composed_bounds(d.grooves)
    half = motion.eye_half_angle
    if motion.mode == "walk":
        values = sweep(-motion.half_range, motion.half_range, frames, loop) - half
    else:
        lo, hi = sorted((motion.light_elevation, motion.light_stop))
        values = sweep(lo, hi, frames, loop)
    radius = motion.eye_radius

    def camera(v: float, fov: float = 0.5) -> Camera:
        az = float(v) if motion.mode == "walk" else -half
        return Camera(az, 0.0, radius, fov, width, height, motion.eye_height)

    probes = [camera(v) for v in (values.min(), values.max())]
    fov = fit_fov(plate_corners(bounds), probes)
    sigma = 0.5 * comp.tool.width * roughness / REFERENCE_ROUGHNESS
    point = motion.light_distance is not None
    out = []
    for v in values:
        cam = camera(v, fov)
        elev = motion.light_elevation if motion.mode == "walk" else float(v)
        light = Light(elev, motion.light_distance)
        vec = light.position if point else light.direction
        assert vec is not None

        def glints(cam: Camera = cam, vec: np.ndarray = vec) -> tuple[np.ndarray, float]:
            g = find_conforming_glints(d.grooves, comp.host, cam.position(), vec, point,
                                       comp.tool)
            return g.point, sigma

        out.append(draw_glints(cam, bounds, light, glints, roughness))
        if progress is not None:
            progress()
    return out


def contact_sheet(frames: list[np.ndarray]) -> np.ndarray:
    """Frames side by side, with a thin dark gap."""
    h = max(f.shape[0] for f in frames)
    gap = np.full((h, 6, 3), 8, dtype=np.uint8)
    parts: list[np.ndarray] = []
    for f in frames:
        if parts:
            parts.append(gap)
        parts.append(f)
    return np.concatenate(parts, axis=1)


def write_previews(d: Any, out: Any, frames: int,
                   progress: Callable[[], None] | None = None) -> None:
    """Write a composed design's preview.png (start, middle and end of the motion)
    and, with ``frames`` > 0, preview.gif, into the folder ``out``; ``progress`` is
    called once per animation frame."""
    from pathlib import Path

    from PIL import Image

    from specholo.fabrication.atomic import atomic_open
    from specholo.preview.motion import write_animation

    out = Path(out)
    still = composed_frames(d, 3, (480, 480), loop=False)
    with atomic_open(out / "preview.png", "wb", encoding=None) as fh:
        Image.fromarray(contact_sheet(still)).save(fh, format="PNG")
    if frames:
        shots = composed_frames(d, frames, (360, 360), progress=progress)
        write_animation(shots, out / "preview.gif", fps=12)

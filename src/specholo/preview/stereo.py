"""Stereo pairs of the lit plate: what each of a viewer's two eyes sees.

The eyes sit IPD apart along the horizontal tangent of the camera's orbit, like
:meth:`specholo.setup.Viewer.stereo`, and both look at the plate centre. Each
eye's picture comes from its own glints, so the pair carries the hologram's
real disparities: fused, the model floats at its designed depth.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.preview.render import Camera, design_camera, luminance, render_still
from specholo.setup import Setup
from specholo.simulation.glints import Engraved
from specholo.toolpaths.grooves import Grooves

MODES = ("parallel", "cross", "anaglyph")


def head_camera(setup: Setup, grooves: Grooves, azimuth: float = 0.0, width: int = 768,
                height: int = 768, fov: float | None = None,
                plate: np.ndarray | None = None) -> Camera:
    """The head of a viewer on the design's arc (radius ``viewer.distance``).

    The default fov frames the plate for both eyes of that head.

    Args:
        setup: the design's setup.
        grooves: the grooves.
        azimuth: head azimuth, radians.
        width: pixels per eye.
        height: pixels.
        fov: vertical field of view, radians; default frames the plate.
        plate: (2, 2) the plate's corners, mm; default the grooves' extent.
    """
    v = setup.viewer
    half = v.eye_half_angle
    return design_camera(setup, grooves, azimuth, 0.0, v.distance, fov, width, height,
                         frame_azimuths=(azimuth - half, azimuth + half), plate=plate)


def stereo_cameras(head: Camera, ipd: float) -> tuple[Camera, Camera]:
    """Left and right eye cameras of a head.

    Args:
        head: the head (the midpoint between the eyes) and the image settings.
        ipd: interocular distance, mm.

    Returns:
        Left and right cameras, ``ipd`` apart along the orbit's horizontal
        tangent, each looking at the plate centre.
    """
    if not (math.isfinite(ipd) and 0 < ipd < head.distance):
        raise SpecholoError(f"interocular distance must be in (0, {head.distance:g}) mm, "
                            f"got {ipd:g}")
    tangent = np.array([math.cos(head.azimuth), 0.0, -math.sin(head.azimuth)])
    centre = head.position()
    return tuple(  # type: ignore[return-value]
        Camera.at(centre + s * 0.5 * ipd * tangent, head.fov, head.width, head.height,
                  head.eye_height) for s in (-1.0, 1.0))


def stereo_pair(grooves: Grooves, setup: Setup, head: Camera, ipd: float | None = None,
                engraved: Engraved | None = None, **still: Any) -> tuple[np.ndarray, np.ndarray]:
    """Render the two eyes of a head.

    Args:
        grooves: the grooves.
        setup: the design's setup.
        head: the head camera (see :func:`head_camera`).
        ipd: interocular distance in mm; default the design's.
        engraved: prepared grooves, shared by both renders.
        **still: further :func:`~specholo.preview.render.render_still` options.

    Returns:
        Left and right (H, W, 3) uint8 images.
    """
    eng = engraved if engraved is not None else Engraved.from_grooves(grooves, setup.tool)
    left, right = stereo_cameras(head, setup.viewer.ipd if ipd is None else ipd)
    return (render_still(grooves, setup, left, engraved=eng, **still),
            render_still(grooves, setup, right, engraved=eng, **still))


def _check_pair(left: np.ndarray, right: np.ndarray) -> None:
    if left.shape != right.shape or left.ndim != 3 or left.shape[2] != 3:
        raise SpecholoError(f"stereo images must be two (H, W, 3) images of one size, "
                            f"got {left.shape} and {right.shape}")


def side_by_side(left: np.ndarray, right: np.ndarray, mode: str = "parallel",
                 gap: int = 0) -> np.ndarray:
    """Join a stereo pair for free viewing.

    Args:
        left: (H, W, 3) left-eye image.
        right: (H, W, 3) right-eye image.
        mode: ``"parallel"`` puts the left eye's image on the left (eyes look
            straight ahead); ``"cross"`` swaps them (eyes cross).
        gap: black columns between the two.

    Returns:
        (H, 2 W + gap, 3) uint8 image.
    """
    _check_pair(left, right)
    if mode not in ("parallel", "cross"):
        raise SpecholoError(f"side-by-side mode must be parallel or cross, got {mode!r}")
    if isinstance(gap, bool) or int(gap) != gap or gap < 0:
        raise SpecholoError(f"gap must be a non-negative integer, got {gap}")
    first, second = (left, right) if mode == "parallel" else (right, left)
    sep = np.zeros((left.shape[0], int(gap), 3), dtype=np.uint8)
    return np.concatenate([first, sep, second], axis=1)


def anaglyph(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Red-cyan anaglyph: red is the left eye's luminance, green and blue the right's.

    Args:
        left: (H, W, 3) uint8 left-eye image.
        right: (H, W, 3) uint8 right-eye image.

    Returns:
        (H, W, 3) uint8 image for red (left) / cyan (right) glasses.
    """
    _check_pair(left, right)
    yl, yr = luminance(left), luminance(right)
    return np.stack([yl, yr, yr], axis=-1)

"""Animations of the lit plate: the camera walking the viewing arc, or the light moving.

Every frame is a :func:`~specholo.preview.render.render_still`, so every glint
comes from the glint physics for that frame's camera and light.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.atomic import part_prefix, public_mode, scratch
from specholo.preview.render import REFERENCE_ROUGHNESS, Camera, design_camera, render_still
from specholo.setup import Light
from specholo.simulation.glints import Engraved

Progress = Callable[[int, int], None]
"""Called as ``progress(done, total)`` after each frame."""

FORMATS = (".gif", ".mp4")


def _check_frames(frames: int) -> None:
    if isinstance(frames, bool) or int(frames) != frames or frames <= 0:
        raise SpecholoError(f"frames must be a positive integer, got {frames}")


def sweep(lo: float, hi: float, frames: int, loop: bool = True) -> np.ndarray:
    """Values from lo to hi for each frame.

    Args:
        lo: first value.
        hi: far value.
        frames: number of frames.
        loop: go lo -> hi -> lo with eased turns (cosine), so a looping
            animation has no jump; otherwise evenly from lo to hi.

    Returns:
        (frames,) values. A loop of an odd number of frames is shifted by a
        quarter step, which keeps it symmetric without repeating a frame at
        the far turn.
    """
    _check_frames(frames)
    i = np.arange(frames)
    if loop:
        shift = 0.25 * (frames % 2)
        s = 0.5 - 0.5 * np.cos(2.0 * np.pi * (i + shift) / frames)
    else:
        s = i / max(frames - 1, 1)
    return lo + (hi - lo) * s


def _render_all(loaded: Any, cameras: Sequence[Camera], lights: Sequence[Light],
                progress: Progress | None, workers: int, **still: Any) -> list[np.ndarray]:
    setup = loaded.config.setup()
    eng = Engraved.from_grooves(loaded.grooves, setup.tool)
    total = len(cameras)

    def one(k: int) -> np.ndarray:
        return render_still(loaded.grooves, setup, cameras[k], light=lights[k], engraved=eng,
                            plate=getattr(loaded, "plate", None), **still)

    return draw_frames(one, total, workers, progress)


def draw_frames(one: Callable[[int], np.ndarray], count: int, workers: int,
                progress: Progress | None) -> list[np.ndarray]:
    """Frames 0 .. count - 1, each drawn by ``one``, on a few threads, in order."""
    frames: list[np.ndarray] = []
    # numpy releases the GIL in its loops, so a few threads render frames side by side.
    pool = ThreadPoolExecutor(max_workers=max(1, workers))
    try:
        for done, frame in enumerate(pool.map(one, range(count)), start=1):
            frames.append(frame)
            if progress is not None:
                progress(done, count)
    finally:
        # On Ctrl-C (or any error) the frames not started yet are dropped, not
        # rendered first: only the few in progress are waited for.
        pool.shutdown(wait=True, cancel_futures=True)
    return frames


def _ghost(loaded: Any, ghost: bool) -> Any:
    if not ghost:
        return None
    return loaded.mesh if loaded.mesh is not None else loaded.points


def turntable(loaded: Any, frames: int, size: tuple[int, int] = (512, 512),
              roughness: float = REFERENCE_ROUGHNESS, grooves_overlay: bool = False,
              ghost: bool = False, loop: bool = True, distance: float | None = None,
              progress: Progress | None = None, workers: int | None = None) -> list[np.ndarray]:
    """Frames of a camera walking the design's viewing arc.

    The camera sweeps the azimuth over the view range (+-``half_range``) at
    elevation 0 and the viewer's eye height; one fov frames the plate in every frame.

    Args:
        loaded: a design (:class:`specholo.jobs.flat.folder.Loaded`).
        frames: number of frames.
        size: (width, height) in pixels.
        roughness: specular lobe width, radians.
        grooves_overlay: draw the grooves faintly.
        ghost: draw the model's vertices (or stipples) faintly.
        loop: sweep there and back (see :func:`sweep`).
        distance: camera distance in mm; default the eyes' circle.
        progress: called after each frame.
        workers: render threads; default the number of CPUs.

    Returns:
        (H, W, 3) uint8 frames.
    """
    setup = loaded.config.setup()
    r = setup.viewer.half_range
    az = sweep(-r, r, frames, loop)
    width, height = size
    base = design_camera(setup, loaded.grooves, 0.0, 0.0, distance, None, width, height,
                         frame_azimuths=(-r, r), plate=getattr(loaded, "plate", None))
    cameras = [Camera(float(a), 0.0, base.distance, base.fov, width, height, base.eye_height)
               for a in az]
    return _render_all(loaded, cameras, [setup.light] * frames, progress,
                       workers or os.cpu_count() or 1, roughness=roughness,
                       grooves_overlay=grooves_overlay, ghost=_ghost(loaded, ghost))


def light_sweep(loaded: Any, frames: int, size: tuple[int, int] = (512, 512),
                span: float = math.radians(10.0), azimuth: float = 0.0,
                roughness: float = REFERENCE_ROUGHNESS, grooves_overlay: bool = False,
                ghost: bool = False, loop: bool = True, progress: Progress | None = None,
                workers: int | None = None) -> list[np.ndarray]:
    """Frames of the light's elevation moving +-span about the design's, camera fixed.

    A specular hologram is exact only for its own light: as the light rises or
    falls the glints slide along the grooves and the picture shifts and warps.

    Args:
        loaded: a design.
        frames: number of frames.
        size: (width, height) in pixels.
        span: largest change of elevation, radians.
        azimuth: camera azimuth, radians (on the eyes' circle, elevation 0).
        roughness: specular lobe width, radians.
        grooves_overlay: draw the grooves faintly.
        ghost: draw the model faintly.
        loop: sweep there and back.
        progress: called after each frame.
        workers: render threads; default the number of CPUs.

    Returns:
        (H, W, 3) uint8 frames.
    """
    setup = loaded.config.setup()
    if not (math.isfinite(span) and span >= 0):
        raise SpecholoError(f"light span must be >= 0 degrees, got {math.degrees(span):g}")
    a0 = setup.light.elevation
    elev = sweep(a0 - span, a0 + span, frames, loop)
    lights = [Light(float(a), setup.light.distance) for a in elev]
    width, height = size
    cam = design_camera(setup, loaded.grooves, azimuth, 0.0, None, None, width, height,
                        plate=getattr(loaded, "plate", None))
    return _render_all(loaded, [cam] * frames, lights, progress,
                       workers or os.cpu_count() or 1, roughness=roughness,
                       grooves_overlay=grooves_overlay, ghost=_ghost(loaded, ghost))


def _even(frame: np.ndarray) -> np.ndarray:
    """Pad to even width and height by repeating the last row/column (yuv420p needs it)."""
    h, w = frame.shape[:2]
    return np.pad(frame, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")


def _write_gif(frames: Sequence[np.ndarray], path: Path, fps: float) -> None:
    from PIL import Image

    images = [Image.fromarray(np.ascontiguousarray(f)) for f in frames]
    # One shared palette keeps the dark plate from flickering between frames.
    palette = images[len(images) // 2].quantize(colors=256, method=Image.Quantize.MEDIANCUT)
    quantised = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
    quantised[0].save(path, format="GIF", save_all=True, append_images=quantised[1:],
                      duration=round(1000.0 / fps), loop=0, optimize=False, disposal=1)


def _write_mp4(frames: Sequence[np.ndarray], path: Path, fps: float) -> None:
    try:
        import imageio_ffmpeg
    except ImportError as exc:
        raise SpecholoError("writing MP4 needs the imageio-ffmpeg package; "
                            "write a .gif instead") from exc

    first = _even(frames[0])
    h, w = first.shape[:2]
    writer = imageio_ffmpeg.write_frames(
        str(path), (w, h), fps=fps, codec="libx264", pix_fmt_in="rgb24",
        pix_fmt_out="yuv420p", quality=8, macro_block_size=2, ffmpeg_log_level="error",
        output_params=["-movflags", "+faststart"])
    writer.send(None)  # start the encoder
    try:
        for f in frames:
            writer.send(np.ascontiguousarray(_even(f)))
    finally:
        writer.close()


def write_animation(frames: Sequence[np.ndarray], path: str | os.PathLike[str],
                    fps: float = 30.0) -> None:
    """Write frames as a looping GIF or an H.264 MP4, chosen by the path's suffix.

    The file is written beside ``path`` under a temporary name and renamed over
    it only when complete. A GIF stores a run of identical frames as one longer
    frame (Pillow does), so its timing is kept but its frame count may drop.

    Args:
        frames: (H, W, 3) uint8 frames, all the same size.
        path: a ``.gif`` or ``.mp4`` file.
        fps: frames per second.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise SpecholoError(
            f"animation file must end in {' or '.join(FORMATS)}, got {path.name!r}")
    if not (math.isfinite(fps) and 0 < fps <= 240):
        raise SpecholoError(f"fps must be in (0, 240], got {fps:g}")
    if not frames:
        raise SpecholoError("no frames to write")
    if len({f.shape for f in frames}) != 1:
        raise SpecholoError("animation frames differ in size")
    if not path.parent.is_dir():
        raise SpecholoError(f"folder {path.parent} does not exist")
    with scratch():
        fd, name = tempfile.mkstemp(prefix=part_prefix(path), suffix=f".part{suffix}",
                                    dir=path.parent)
        os.close(fd)
        tmp = Path(name)
        try:
            if suffix == ".gif":
                _write_gif(frames, tmp, fps)
            else:
                _write_mp4(frames, tmp, fps)
            public_mode(tmp)
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
            raise

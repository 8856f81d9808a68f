"""Photographic stills of the engraved plate: the glints a camera sees, as light.

Every bright spot is a glint that :func:`~specholo.simulation.glints.find_glints`
finds for the camera's position (on a plate given as a height field, a ridged
design, :func:`~specholo.simulation.heightfield.find_field_glints`); nothing is
drawn from the model itself except the optional faint ghost. Both kinds of
plate are drawn by :func:`draw_glints`. Images are (H, W, 3) uint8, row 0 at
the top.

Spot model. A glint is a patch of groove wall whose normals fall within the
surface's specular lobe. We draw it as an isotropic Gaussian on the plate of
standard deviation ``sigma = (w / 2) * roughness / 1 deg`` (w the groove width
at the surface): a groove-wide spot at the reference roughness of 1 degree,
growing linearly with the lobe. Each glint reflects the same power whatever the
roughness, so its peak radiance falls as 1 / sigma^2: rougher plates give
bigger, dimmer spots.
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open
from specholo.setup import Light, Setup, Tool
from specholo.simulation.glints import Engraved, find_glints
from specholo.toolpaths.grooves import Grooves

REFERENCE_ROUGHNESS = math.radians(1.0)
#: What a picture draws: glint points (g, 3), mm; each one's spot's standard
#: deviation on the plate, mm (one for all, or (g,)); and optionally each
#: one's power as a share of a typical glint's (g,).
Spots = tuple[Any, ...]
MAX_SIDE = 8192  # pixels; larger images are refused rather than exhausting memory

_GAIN = 3.0  # exposure: a reference-roughness spot peaks at 1 - exp(-3) of full white
_MIN_SIGMA_PX = 0.5  # a spot never gets narrower than a pixel's own footprint
#: Groove width (mm) whose glints set the exposure: an unresolved glint of a finer
#: groove is drawn as bright as this one's, only no larger (the eye sees a point).
_EXPOSURE_WIDTH = 0.37
_STAMP_ENTRIES = 1 << 22  # splat weights held at once
_HALO = 5.0  # bloom halo width, in spot widths

# Linear-light colours (converted to sRGB at the end).
_BACKGROUND = np.array([0.0025, 0.0028, 0.0034])
_PLATE = np.array([0.011, 0.0125, 0.015])
_PLATE_SHEEN = np.array([0.010, 0.011, 0.013])
_RIM = np.array([0.05, 0.055, 0.06])
_GLINT = np.array([1.0, 0.96, 0.88])
_GROOVE = np.array([0.018, 0.022, 0.03])
_GHOST = np.array([0.05, 0.16, 0.50])
_OUTLINE = np.array([0.07, 0.075, 0.085])


class Projected(NamedTuple):
    """Points seen through a camera.

    Attributes:
        pixel: (n, 2) pixel coordinates (column, row); pixel centres are integers,
            row 0 at the top.
        depth: (n,) distance along the camera's axis, mm.
        valid: (n,) True where the point is in front of the camera.
    """

    pixel: np.ndarray
    depth: np.ndarray
    valid: np.ndarray


@dataclass(frozen=True)
class Camera:
    """A pinhole camera on a sphere about the plate, looking at the plate centre.

    Attributes:
        azimuth: angle right of straight-on about the vertical, radians.
        elevation: angle above the horizontal, radians.
        distance: distance from the orbit centre (0, eye_height, 0), mm.
        fov: vertical field of view, radians, in (0, pi).
        width: image width, pixels.
        height: image height, pixels.
        eye_height: height of the orbit centre above the plate centre, mm (the
            viewer's eye height).
    """

    azimuth: float
    elevation: float
    distance: float
    fov: float
    width: int = 1024
    height: int = 1024
    eye_height: float = 0.0

    def __post_init__(self) -> None:
        for name in ("azimuth", "elevation", "distance", "fov", "eye_height"):
            if not math.isfinite(getattr(self, name)):
                raise SpecholoError(f"camera {name} must be finite, got {getattr(self, name)}")
        if not 0.0 < self.fov < math.pi:
            raise SpecholoError(
                f"field of view must be in (0, 180) degrees, got {math.degrees(self.fov):g}")
        if self.distance <= 0:
            raise SpecholoError(f"camera distance must be positive, got {self.distance:g}")
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or not 0 < v <= MAX_SIDE:
                raise SpecholoError(f"image {name} must be an integer in [1, {MAX_SIDE}], got {v}")
        if self.position()[2] <= 0:
            raise SpecholoError(
                f"camera at azimuth {math.degrees(self.azimuth):g}, elevation "
                f"{math.degrees(self.elevation):g} degrees is not in front of the plate")

    @classmethod
    def at(cls, position: np.ndarray, fov: float, width: int = 1024, height: int = 1024,
           eye_height: float = 0.0) -> Camera:
        """The camera at a given position (3,), in mm, looking at the plate centre."""
        rel = np.asarray(position, dtype=float) - np.array([0.0, eye_height, 0.0])
        distance = float(np.linalg.norm(rel))
        if not distance > 0:
            raise SpecholoError("camera position coincides with its orbit centre")
        return cls(math.atan2(rel[0], rel[2]), math.asin(float(rel[1]) / distance), distance,
                   fov, width, height, eye_height)

    def position(self) -> np.ndarray:
        """Camera centre (3,) in mm."""
        ce, se = math.cos(self.elevation), math.sin(self.elevation)
        return np.array([self.distance * ce * math.sin(self.azimuth),
                         self.eye_height + self.distance * se,
                         self.distance * ce * math.cos(self.azimuth)])

    def basis(self) -> np.ndarray:
        """Rows right, up and forward (3, 3): the camera's unit axes in the plate frame."""
        forward = -self.position()
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        return np.stack([right, np.cross(right, forward), forward])

    @property
    def focal(self) -> float:
        """Focal length in pixels."""
        return 0.5 * self.height / math.tan(0.5 * self.fov)

    def tangents(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Image-plane tangents (n, 2) (right, up) and depths (n,) of points (n, 3)."""
        cam = (np.asarray(points, dtype=float) - self.position()) @ self.basis().T
        depth = cam[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            tan = cam[:, :2] / depth[:, None]
        return tan, depth

    def project(self, points: np.ndarray) -> Projected:
        """Project points into the image.

        Args:
            points: (n, 3) points in mm.

        Returns:
            Pixel coordinates (n, 2), depths (n,) and a validity mask (n,);
            points behind the camera are invalid and their pixels meaningless.
        """
        tan, depth = self.tangents(points)
        f = self.focal
        pixel = np.stack([0.5 * (self.width - 1) + f * tan[:, 0],
                          0.5 * (self.height - 1) - f * tan[:, 1]], axis=1)
        valid = depth > 1e-9
        return Projected(np.where(valid[:, None], pixel, 0.0), depth, valid)

    def rays(self) -> np.ndarray:
        """Unit directions (H, W, 3) through every pixel centre, plate frame."""
        f = self.focal
        u = (np.arange(self.width) - 0.5 * (self.width - 1)) / f
        v = (0.5 * (self.height - 1) - np.arange(self.height)) / f
        right, up, forward = self.basis()
        d = (u[None, :, None] * right + v[:, None, None] * up + forward)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)


def plate_bounds(grooves: Grooves, margin: float | None = None) -> np.ndarray:
    """The plate drawn in renders: the groove extent plus a margin.

    Args:
        grooves: the grooves.
        margin: border in mm; default 6% of the larger side (at least 3 mm).

    Returns:
        (2, 2) lower-left and upper-right corners, mm.
    """
    v = grooves.vertices
    if not len(v):
        lo = hi = np.zeros(2)
    else:
        # Per column: numpy's axis-0 reduction of an (m, 2) array is ~20x slower.
        lo = np.array([v[:, 0].min(), v[:, 1].min()])
        hi = np.array([v[:, 0].max(), v[:, 1].max()])
    if margin is None:
        margin = max(3.0, 0.06 * float(np.max(hi - lo)))
    return np.stack([lo - margin, hi + margin])


def plate_corners(bounds: np.ndarray) -> np.ndarray:
    """The four corners (4, 3) of a plate rectangle (2, 2) at z = 0."""
    (x0, y0), (x1, y1) = bounds
    return np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])


def fit_fov(points: np.ndarray, cameras: Sequence[Camera], fill: float = 0.92) -> float:
    """The vertical field of view that frames points in every one of some cameras.

    Args:
        points: (n, 3) points to keep in view (e.g. the plate's corners).
        cameras: camera placements (their own fov is ignored).
        fill: share of the image's half-size the farthest point may reach.

    Returns:
        The field of view in radians.
    """
    t = 1e-6
    for cam in cameras:
        tan, depth = cam.tangents(points)
        if np.any(depth <= 0):
            raise SpecholoError("the plate is not entirely in front of the camera")
        aspect = cam.width / cam.height
        t = max(t, float(np.max(np.abs(tan[:, 1]))), float(np.max(np.abs(tan[:, 0]))) / aspect)
    return 2.0 * math.atan(t / fill)


def design_camera(setup: Setup, grooves: Grooves, azimuth: float = 0.0, elevation: float = 0.0,
                  distance: float | None = None, fov: float | None = None, width: int = 1024,
                  height: int = 1024, frame_azimuths: Sequence[float] = (),
                  plate: np.ndarray | None = None) -> Camera:
    """A camera for a design, by default where the design's eyes are.

    Args:
        setup: the design's setup.
        grooves: the grooves (their extent frames the picture).
        azimuth: radians.
        elevation: radians.
        distance: mm; default the eyes' circle, ``setup.viewer.eye_radius``, so an
            elevation-0 camera sits exactly at ``setup.viewer.eye(azimuth)``.
        fov: vertical field of view in radians; default frames the plate.
        width: pixels.
        height: pixels.
        frame_azimuths: further azimuths (radians) the default fov must also frame,
            so every frame of an animation shares one fov.
        plate: (2, 2) the plate's corners, mm, that the default fov frames;
            default the grooves' extent with a margin (:func:`plate_bounds`).
    """
    bounds = plate_bounds(grooves) if plate is None else np.asarray(plate, dtype=float)
    return plate_camera(setup, bounds, azimuth, elevation, distance, fov,
                        width, height, frame_azimuths)


def plate_camera(setup: Setup, bounds: np.ndarray, azimuth: float = 0.0,
                 elevation: float = 0.0, distance: float | None = None,
                 fov: float | None = None, width: int = 1024, height: int = 1024,
                 frame_azimuths: Sequence[float] = ()) -> Camera:
    """A camera for a plate rectangle, by default where the design's eyes are.

    As :func:`design_camera`, with the plate given as its corners (2, 2), mm.
    """
    d = setup.viewer.eye_radius if distance is None else float(distance)
    h = setup.viewer.height
    if fov is None:
        corners = plate_corners(bounds)
        probes = [Camera(a, elevation, d, 1.0, width, height, h)
                  for a in (azimuth, *frame_azimuths)]
        fov = fit_fov(corners, probes)
    return Camera(azimuth, elevation, d, fov, width, height, h)


def _check_roughness(roughness: float) -> None:
    if not (math.isfinite(roughness) and 0.0 < roughness <= math.radians(30.0)):
        raise SpecholoError(
            f"roughness must be in (0, 30] degrees, got {math.degrees(roughness):g}")


def spot_sigma(setup: Setup, roughness: float) -> float:
    """Standard deviation of a glint spot on the plate, mm (see the module notes)."""
    _check_roughness(roughness)
    return 0.5 * setup.tool.width * roughness / REFERENCE_ROUGHNESS


def _splat(acc: np.ndarray, pixel: np.ndarray, sigma: np.ndarray, amp: np.ndarray,
           reach: float = 3.0) -> None:
    """Add Gaussian spots into an image in place.

    Args:
        acc: (H, W) float image.
        pixel: (g, 2) spot centres (column, row).
        sigma: (g,) standard deviations, pixels.
        amp: (g,) peak values.
        reach: stamp half-size in standard deviations.
    """
    if not len(pixel):
        return
    hgt, wid = acc.shape
    r = int(math.ceil(reach * float(sigma.max())))
    off = np.arange(-r, r + 1)
    k = off.size
    centre = np.rint(pixel).astype(np.int64)
    frac = pixel - centre
    flat = acc.reshape(-1)
    step = max(1, _STAMP_ENTRIES // (k * k))
    for lo in range(0, len(pixel), step):
        sl = slice(lo, lo + step)
        s2 = (2.0 * sigma[sl] ** 2)[:, None]
        # Separable: the stamp is the outer product of a row and a column profile.
        wx = np.exp(-(off[None, :] - frac[sl, 0:1]) ** 2 / s2)
        wy = np.exp(-(off[None, :] - frac[sl, 1:2]) ** 2 / s2) * amp[sl, None]
        cols = centre[sl, 0:1] + off[None, :]
        rows = centre[sl, 1:2] + off[None, :]
        w = wy[:, :, None] * wx[:, None, :]
        inside = (((rows >= 0) & (rows < hgt))[:, :, None]
                  & ((cols >= 0) & (cols < wid))[:, None, :])
        idx = rows[:, :, None] * wid + cols[:, None, :]
        flat += np.bincount(idx[inside], weights=w[inside], minlength=flat.size)


def _points_layer(shape: tuple[int, int], pixel: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Bilinear point splats (each of total ``weight``) into a new (H, W) image."""
    hgt, wid = shape
    base = np.floor(pixel).astype(np.int64)
    frac = pixel - base
    out = np.zeros(hgt * wid)
    for dy in (0, 1):
        for dx in (0, 1):
            w = weight * (frac[:, 0] if dx else 1 - frac[:, 0]) * (
                frac[:, 1] if dy else 1 - frac[:, 1])
            c, r = base[:, 0] + dx, base[:, 1] + dy
            ok = (c >= 0) & (c < wid) & (r >= 0) & (r < hgt)
            out += np.bincount(r[ok] * wid + c[ok], weights=w[ok], minlength=out.size)
    return out.reshape(hgt, wid)


def _plate_layer(camera: Camera, bounds: np.ndarray | None, light: Light) -> np.ndarray:
    """The plate as seen by the camera: (H, W, 3) linear radiance, background included.

    Each pixel's ray meets the plane z = 0 exactly, so the quad is
    perspective-correct; its edges are antialiased by the distance to them in
    pixels, and a faint sheen follows the light's mirror direction.

    Args:
        camera: the camera.
        bounds: the plate at z = 0: its corners (2, 2), a convex polygon (k, 2)
            counter-clockwise (a turned plate), or None for none (a curved host,
            drawn by its outline alone).
        light: the light (the sheen).
    """
    if bounds is None:
        return np.broadcast_to(_BACKGROUND, (camera.height, camera.width, 3)).copy()
    eye = camera.position()
    d = camera.rays().astype(np.float32)  # single precision: ample for shading, twice as fast
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -eye[2] / d[..., 2]
    hit = eye[:2] + t[..., None] * d[..., :2]
    hits = np.isfinite(t) & (t > 0)
    hit = np.where(hits[..., None], hit, 1e30)
    # Millimetres of plate per pixel along each ray (foreshortened by the incidence).
    mm_per_px = np.where(hits, t, 1.0) / camera.focal / np.maximum(np.abs(d[..., 2]), 1e-6)
    if np.shape(bounds) == (2, 2):
        (x0, y0), (x1, y1) = bounds
        inner = np.minimum.reduce([hit[..., 0] - x0, x1 - hit[..., 0],
                                   hit[..., 1] - y0, y1 - hit[..., 1]])
    else:
        inner = _polygon_inside(hit, np.asarray(bounds, dtype=float))
    inner_px = inner / mm_per_px
    cover = np.clip(inner_px + 0.5, 0.0, 1.0)
    # Mirror direction of the view ray; brighter the closer it points to the light.
    mirror = d * np.array([1.0, 1.0, -1.0])
    toward = light.towards(np.zeros((1, 3)))[0]
    sheen = np.clip(mirror @ toward, 0.0, 1.0) ** 8
    plate = _PLATE + sheen[..., None] * _PLATE_SHEEN
    rim = np.exp(-0.5 * (inner_px / 1.2) ** 2)  # a thin bevel catching light
    plate = plate + rim[..., None] * _RIM
    return _BACKGROUND + cover[..., None] * (plate - _BACKGROUND)


def _polygon_inside(hit: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Signed distance (H, W) of plate points (H, W, 2) inside a convex polygon
    (k, 2), counter-clockwise: the least over its edges, negative outside, mm."""
    inner = np.full(hit.shape[:-1], np.inf)
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        edge = b - a
        length = float(np.hypot(*edge))
        if length > 0:
            # the edge's left normal points inside a counter-clockwise polygon
            d = (edge[0] * (hit[..., 1] - a[1]) - edge[1] * (hit[..., 0] - a[0])) / length
            np.minimum(inner, d, out=inner)
    return inner


def line_coverage(camera: Camera, lines: Sequence[np.ndarray]) -> np.ndarray:
    """Polylines (each (k, 3), mm) as faint lines: (H, W) coverage in [0, 1)."""
    shape = (camera.height, camera.width)
    starts, ends = [], []
    for line in lines:
        q = np.asarray(line, dtype=float).reshape(-1, 3)
        if len(q) >= 2:
            starts.append(q[:-1])
            ends.append(q[1:])
    if not starts:
        return np.zeros(shape)
    a, b = np.concatenate(starts), np.concatenate(ends)
    pa, pb = camera.project(a), camera.project(b)
    ok = pa.valid & pb.valid  # a segment reaching behind the camera is left out
    a, b = a[ok], b[ok]
    px_len = np.linalg.norm(pb.pixel[ok] - pa.pixel[ok], axis=1)
    # Enough samples per segment that consecutive ones are under a pixel apart.
    n = np.clip(np.ceil(px_len / 0.8), 1, 4096).astype(np.int64)
    idx = np.repeat(np.arange(len(a)), n)
    first = np.cumsum(n) - n
    u = ((np.arange(idx.size) - np.repeat(first, n) + 0.5) / np.repeat(n, n))[:, None]
    pixel, _, valid = camera.project((1.0 - u) * a[idx] + u * b[idx])
    weight = (px_len / n)[idx]
    dens = _points_layer(shape, pixel[valid], weight[valid])
    return 1.0 - np.exp(-dens)


def _groove_layer(camera: Camera, eng: Engraved) -> np.ndarray:
    """Groove centrelines as faint lines: (H, W) coverage in [0, 1)."""
    k = len(eng.path)
    out_shape = (camera.height, camera.width)
    if not k:
        return np.zeros(out_shape)
    chord = np.linalg.norm(eng.end - eng.start, axis=1)
    length = np.where(eng.radius > 0, eng.radius * np.abs(eng.sweep), chord)
    mid, _ = eng.at(np.arange(k), np.full(k, 0.5))
    _, depth, valid = camera.project(mid)
    px_len = length * camera.focal / np.where(valid, depth, np.inf)
    # Enough samples per arc that consecutive ones are under a pixel apart.
    n = np.clip(np.ceil(px_len / 0.8), 1, 64).astype(np.int64)
    idx = np.repeat(np.arange(k), n)
    first = np.cumsum(n) - n
    u = (np.arange(idx.size) - np.repeat(first, n) + 0.5) / np.repeat(n, n)
    pts, _ = eng.at(idx, u)
    pixel, _, ok = camera.project(pts)
    weight = (px_len / n)[idx]
    dens = _points_layer(out_shape, pixel[ok], weight[ok])
    return 1.0 - np.exp(-dens)


def groove_coverage(camera: Camera, eng: Engraved) -> np.ndarray:
    """Engraved grooves' centrelines as the camera sees them: (H, W) coverage in
    [0, 1), the faint overlay of a still's ``--grooves``."""
    return _groove_layer(camera, eng)


def _ghost_points(ghost: Any) -> np.ndarray:
    pts = np.asarray(getattr(ghost, "vertices", ghost), dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise SpecholoError(f"ghost must be a mesh or (n, 3) points, got shape {pts.shape}")
    return pts[np.all(np.isfinite(pts), axis=1)]


def _to_srgb(linear: np.ndarray) -> np.ndarray:
    x = np.clip(linear, 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.rint(255.0 * s).astype(np.uint8)


def glint_pixels(grooves: Grooves, setup: Setup, camera: Camera, light: Light | None = None,
                 engraved: Engraved | None = None) -> Projected:
    """Where the glints the camera sees land in its image.

    Args:
        grooves: the grooves.
        setup: the design's setup.
        camera: the camera.
        light: the light; default the setup's.
        engraved: prepared grooves, to skip preparing them again.

    Returns:
        The projected glint points (g,).
    """
    eng = engraved if engraved is not None else Engraved.from_grooves(grooves, setup.tool)
    g = find_glints(eng, camera.position(), light if light is not None else setup.light)
    return camera.project(g.point)


def glints_seen(grooves: Grooves, tool: Tool, eyes: np.ndarray, light: Light) -> list[np.ndarray]:
    """The glints each eye sees on the grooves.

    A design of more than :data:`~specholo.simulation.verify.CHUNK_VERTICES`
    vertices is searched a run of paths at a time (each glint lies on one path),
    so its arc index stays a chunk's size; every chunk is indexed once for all
    the eyes.

    Args:
        grooves: the grooves.
        tool: the cutting tool.
        eyes: (e, 3) eye positions, mm.
        light: the light.

    Returns:
        (g_i, 3) glint points per eye.
    """
    from specholo.simulation.verify import CHUNK_VERTICES

    eyes = np.asarray(eyes, dtype=float).reshape(-1, 3)
    if len(grooves.vertices) <= CHUNK_VERTICES:
        eng = Engraved.from_grooves(grooves, tool)
        return [find_glints(eng, eye, light).point for eye in eyes]
    ends = grooves.offsets[1:] - grooves.offsets[0] if grooves.offsets[0] else grooves.offsets[1:]
    cuts = np.searchsorted(ends, np.arange(CHUNK_VERTICES, ends[-1], CHUNK_VERTICES))
    bounds = np.unique(np.concatenate([[0], cuts + 1, [grooves.n_paths]]))
    found: list[list[np.ndarray]] = [[] for _ in eyes]
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        part = Engraved.from_grooves(grooves.take(np.arange(a, b)), tool)
        for k, eye in enumerate(eyes):
            found[k].append(find_glints(part, eye, light).point)
        del part
    return [np.concatenate(f) for f in found]


def render_still(grooves: Grooves, setup: Setup, camera: Camera,
                 roughness: float = REFERENCE_ROUGHNESS, grooves_overlay: bool = False,
                 ghost: Any = None, light: Light | None = None,
                 engraved: Engraved | None = None, bloom: float = 0.006,
                 plate: np.ndarray | None = None) -> np.ndarray:
    """Render what the camera sees of the lit plate.

    Args:
        grooves: the grooves.
        setup: the design's setup (tool, light, viewer).
        camera: the camera.
        roughness: width of the surface's specular lobe, radians (see the module notes).
        grooves_overlay: draw the groove centrelines faintly.
        ghost: a mesh (anything with ``vertices``) or (n, 3) points to draw as
            faint dots where they are in space, or None.
        light: the light; default the setup's.
        engraved: prepared grooves (``Engraved.from_grooves``), reused across frames.
        bloom: peak of a faint halo, five spot widths wide, around each glint, as a
            fraction of the spot's peak (0 for none).
        plate: (2, 2) the plate's corners to draw, mm; default the grooves'
            extent with a margin (:func:`plate_bounds`).

    Returns:
        (H, W, 3) uint8 RGB image.
    """
    from specholo.simulation.verify import CHUNK_VERTICES

    _check_roughness(roughness)
    light = light if light is not None else setup.light
    chunked = engraved is None and not grooves_overlay and len(grooves.vertices) > CHUNK_VERTICES
    eng = engraved if engraved is not None or chunked else \
        Engraved.from_grooves(grooves, setup.tool)

    def glints() -> tuple[np.ndarray, float]:
        if eng is not None:
            return find_glints(eng, camera.position(), light).point, spot_sigma(setup, roughness)
        return glints_seen(grooves, setup.tool, camera.position()[None], light)[0], \
            spot_sigma(setup, roughness)

    def overlay() -> np.ndarray:
        assert eng is not None  # an overlay is never chunked
        return _groove_layer(camera, eng)

    bounds = plate_bounds(grooves) if plate is None else np.asarray(plate, dtype=float)
    return draw_glints(camera, bounds, light, glints, roughness, ghost, bloom,
                       overlay if grooves_overlay else None)


def draw_glints(camera: Camera, bounds: np.ndarray | None, light: Light,
                glints: Callable[[], Spots],
                roughness: float = REFERENCE_ROUGHNESS, ghost: Any = None,
                bloom: float = 0.006,
                overlay: Callable[[], np.ndarray] | None = None,
                lines: Sequence[np.ndarray] = ()) -> np.ndarray:
    """Draw the lit plate as the camera sees it, with a spot at each glint: the look
    of every still (see the module notes).

    Args:
        camera: the camera.
        bounds: the plate at z = 0, mm: its rectangle (2, 2), a convex polygon
            (k, 2) counter-clockwise, or None where there is no flat plate to
            draw (a curved host: its ``lines`` show it).
        light: the light.
        glints: returns the glint points (g, 3), mm, the standard deviation of
            each one's spot on the plate (mm; one for all, or (g,)) and, if it
            says, each one's power as a share of a typical glint's (g,) (every
            glint alike otherwise); called while the plate is drawn.
        roughness: width of the surface's specular lobe, radians: sets the spots'
            exposure.
        ghost: a mesh (anything with ``vertices``) or (n, 3) points to draw as
            faint dots where they are in space, or None.
        bloom: peak of a faint halo, five spot widths wide, around each glint, as a
            fraction of the spot's peak (0 for none).
        overlay: returns an (H, W) coverage in [0, 1) drawn faintly in the groove
            colour, or None.
        lines: polylines (each (k, 3), mm) drawn faintly: a plate's or a host's
            edges.

    Returns:
        (H, W, 3) uint8 RGB image.
    """
    _check_roughness(roughness)
    if not (math.isfinite(bloom) and bloom >= 0):
        raise SpecholoError(f"bloom must be >= 0, got {bloom}")
    shape = (camera.height, camera.width)
    ghost_pts = None if ghost is None else _ghost_points(ghost)

    def backdrop() -> np.ndarray:
        image = _plate_layer(camera, bounds, light)
        if len(lines):
            image += line_coverage(camera, lines)[..., None] * _OUTLINE
        if overlay is not None:
            image += overlay()[..., None] * _GROOVE
        if ghost_pts is not None:
            pixel, _, ok = camera.project(ghost_pts)
            dens = _points_layer(shape, pixel[ok], np.ones(int(ok.sum())))
            image += (1.0 - np.exp(-0.6 * dens))[..., None] * _GHOST
        return image

    # The backdrop does not depend on the glints: draw it on a second core
    # (numpy releases the GIL) while the glints are found.
    behind = _Background(backdrop)
    found = glints()
    points, sigma_mm = found[0], found[1]
    power = np.asarray(found[2], dtype=float) if len(found) > 2 else None
    proj = camera.project(points)
    pixel = proj.pixel[proj.valid]
    depth = proj.depth[proj.valid]
    if np.ndim(sigma_mm):
        sigma_mm = np.asarray(sigma_mm, dtype=float)[proj.valid]
    sigma_px = sigma_mm * camera.focal / depth
    sigma = np.hypot(sigma_px, _MIN_SIGMA_PX)
    # Fixed power per glint: peak radiance ~ 1 / sigma_mm^2, and an unresolved
    # spot spreads over the pixel footprint, lowering its peak by the same area.
    expo_px = np.maximum(sigma_px, 0.5 * _EXPOSURE_WIDTH * roughness
                         / REFERENCE_ROUGHNESS * camera.focal / depth)
    amp = (_GAIN * (REFERENCE_ROUGHNESS / roughness) ** 2
           * (expo_px / np.hypot(expo_px, _MIN_SIGMA_PX)) ** 2)
    if power is not None:
        amp = amp * power[proj.valid]
    glow = np.zeros(shape)
    _splat(glow, pixel, sigma, amp)
    if bloom > 0 and len(pixel):
        _splat(glow, pixel, _HALO * sigma, bloom * amp, reach=2.0)
    image = behind.result()
    image += (1.0 - np.exp(-glow))[..., None] * _GLINT
    return _to_srgb(image)


class _Background:
    """A function run on a daemon thread: a Ctrl-C in the main thread ends the
    process at once instead of waiting for a large backdrop to finish."""

    def __init__(self, fn: Any) -> None:
        self._value: Any = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, args=(fn,), daemon=True)
        self._thread.start()

    def _run(self, fn: Any) -> None:
        try:
            self._value = fn()
        except BaseException as exc:  # noqa: BLE001 - raised again in result()
            self._error = exc

    def result(self) -> Any:
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._value


def field_plate(field: Any) -> np.ndarray:
    """The plate rectangle (2, 2) of a height field (a ``HeightMap`` or its
    ``SlopeIndex``): its samples' cells, edge to edge, mm."""
    hm = getattr(field, "field", field)
    half = 0.5 * hm.resolution
    return np.asarray(hm.bounds, dtype=float) + np.array([[-half], [half]])


def field_glints(field: Any, setup: Setup, camera: Camera, light: Light | None = None) -> Any:
    """The glints the camera sees on a height field, with the physics of
    ``verify`` (:func:`~specholo.simulation.heightfield.find_field_glints`: the
    plate's specular lobe, riser shadows, the stipple of each cell).

    Args:
        field: the labelled plate (``HeightMap``) or its ``SlopeIndex`` (build it
            once for many cameras).
        setup: the design's setup.
        camera: the camera (its position is the eye).
        light: the light; default the setup's.

    Returns:
        The ``FieldGlints``.
    """
    from specholo.simulation.heightfield import find_field_glints

    return find_field_glints(field, camera.position(),
                             light if light is not None else setup.light)


def field_spot_sigma(glints: Any, resolution: float, roughness: float) -> np.ndarray:
    """Standard deviation (g,) of each glint's spot on a height field, mm: the
    spread of its lit cells (at least half a cell) at the reference roughness,
    growing linearly with the lobe as a groove's spot does."""
    _check_roughness(roughness)
    spread = np.maximum(np.asarray(glints.spread, dtype=float), 0.5 * float(resolution))
    return spread * (roughness / REFERENCE_ROUGHNESS)


def field_glint_pixels(field: Any, setup: Setup, camera: Camera,
                       light: Light | None = None) -> Projected:
    """Where the glints the camera sees on a height field land in its image."""
    return camera.project(field_glints(field, setup, camera, light).glints.point)


def render_field_still(field: Any, setup: Setup, camera: Camera,
                       roughness: float = REFERENCE_ROUGHNESS, ghost: Any = None,
                       light: Light | None = None, bloom: float = 0.006) -> np.ndarray:
    """Render what the camera sees of a plate given as a height field (a ridged design).

    The glints are those :func:`field_glints` finds for the camera's position,
    drawn as the stills of grooves are (:func:`draw_glints`).

    Args:
        field: the labelled plate (``HeightMap``) or its ``SlopeIndex``.
        setup: the design's setup (light, viewer).
        camera: the camera.
        roughness: width of the drawn spots' specular lobe, radians.
        ghost: a mesh or (n, 3) points to draw faintly, or None.
        light: the light; default the setup's.
        bloom: halo around each glint, as a fraction of its peak.

    Returns:
        (H, W, 3) uint8 RGB image.
    """
    _check_roughness(roughness)
    light = light if light is not None else setup.light
    resolution = getattr(field, "field", field).resolution

    def glints() -> tuple[np.ndarray, np.ndarray]:
        g = field_glints(field, setup, camera, light)
        return g.glints.point, field_spot_sigma(g, resolution, roughness)

    return draw_glints(camera, field_plate(field), light, glints, roughness, ghost, bloom)


def luminance(image: np.ndarray) -> np.ndarray:
    """Rec. 709 luma (H, W) uint8 of an (H, W, 3) uint8 image."""
    y = np.asarray(image, dtype=float) @ np.array([0.2126, 0.7152, 0.0722])
    return np.clip(np.rint(y), 0, 255).astype(np.uint8)


def save_png(image: np.ndarray, path: str | os.PathLike[str]) -> None:
    """Write an (H, W, 3) or (H, W) uint8 image as PNG, atomically."""
    from PIL import Image

    with atomic_open(path, "wb", encoding=None) as fh:
        Image.fromarray(np.ascontiguousarray(image)).save(fh, format="PNG")

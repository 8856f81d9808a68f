"""The fabrication files of a plate given as a height field
(:class:`~specholo.toolpaths.heightmap.HeightMap`):

- 16-bit greyscale PNG and TIFF images (white = the plate surface, black = the
  deepest cut; image row 0 is the plate's top edge, y max) whose scale (height
  range, mm per pixel, origin) is recorded in the PNG's text chunk, the TIFF's
  ImageDescription and a JSON sidecar, so :func:`read_image` gets millimetres
  back to within half a quantisation step;
- a watertight STL solid (:func:`specholo.fabrication.stl.write_stl`);
- G-code that finishes the surface with a ball-end mill: raster passes along x,
  one every ``stepover`` in y, alternating direction, the tool tip following the
  surface the ball can reach without gouging it (the height field dilated by
  the ball), points thinned to a chord tolerance; rapids at the safe height and
  a plunge at the plunge feed, in the conventions of
  :mod:`specholo.fabrication.programs.gcode` (GRBL-compatible words, 5 decimals in mm).
"""

from __future__ import annotations

import io
import json
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numba as nb
import numpy as np

from specholo._compiling import kernel
from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open
from specholo.fabrication.exporting import TextRows
from specholo.fabrication.plate import Plate
from specholo.fabrication.programs.program import Emitter, GcodeOptions
from specholo.setup import Machining
from specholo.toolpaths.heightmap import HeightMap as HeightMap
from specholo.toolpaths.ridged import RidgedPlate

#: Key of the scale record in the PNG text chunk.
PNG_KEY = "specholo-heightmap"
#: Tool-tip heights above this (mm below the surface) leave the plate uncut.
_UNCUT = 1e-6


def _check_suffix(path: str | os.PathLike[str], suffixes: tuple[str, ...]) -> Path:
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise SpecholoError(f"{p.name} must end in {' or '.join(suffixes)}")
    return p


def write_png(path: str | os.PathLike[str], hm: HeightMap) -> dict[str, Any]:
    """Write the height map as a 16-bit greyscale PNG, its scale in a text chunk.

    Args:
        path: destination ``.png`` file.
        hm: the height map.

    Returns:
        The scale record (see :meth:`HeightMap.scale`).
    """
    from PIL import Image, PngImagePlugin

    path = _check_suffix(path, (".png",))
    scale = hm.scale()
    info = PngImagePlugin.PngInfo()
    info.add_text(PNG_KEY, json.dumps(scale))
    image = Image.fromarray(hm.quantised())
    with atomic_open(path, "wb", encoding=None) as fh:
        image.save(fh, format="PNG", pnginfo=info)
    return scale


def write_tiff(path: str | os.PathLike[str], hm: HeightMap) -> dict[str, Any]:
    """Write the height map as a 16-bit greyscale TIFF (deflate), its scale in the
    ImageDescription tag.

    Args:
        path: destination ``.tif`` or ``.tiff`` file.
        hm: the height map.

    Returns:
        The scale record.
    """
    from PIL import Image

    path = _check_suffix(path, (".tif", ".tiff"))
    scale = hm.scale()
    image = Image.fromarray(hm.quantised())
    dpi = 25.4 / hm.resolution
    with atomic_open(path, "wb", encoding=None) as fh:
        image.save(fh, format="TIFF", description=json.dumps(scale),
                   compression="tiff_deflate", dpi=(dpi, dpi))
    return scale


def write_sidecar(path: str | os.PathLike[str], scale: dict[str, Any],
                  images: tuple[str, ...] = ()) -> None:
    """Write the scale record as JSON (``images`` names the files it describes)."""
    record = dict(scale)
    if images:
        record["images"] = list(images)
    with atomic_open(path) as fh:
        json.dump(record, fh, indent=1)


def write_images(stem: str | os.PathLike[str], hm: HeightMap) -> dict[str, Any]:
    """Write ``stem.png``, ``stem.tif`` and the sidecar ``stem.json``.

    Returns:
        The scale record.
    """
    stem = Path(stem)
    png, tif = stem.with_suffix(".png"), stem.with_suffix(".tif")
    write_png(png, hm)
    scale = write_tiff(tif, hm)
    write_sidecar(stem.with_suffix(".json"), scale, (png.name, tif.name))
    return scale


def read_image(path: str | os.PathLike[str]) -> HeightMap:
    """Read a height map written by :func:`write_png` or :func:`write_tiff`.

    The scale comes from the file itself (PNG text chunk or TIFF description),
    else from a sidecar ``.json`` with the same stem.

    Raises:
        SpecholoError: the file is unreadable or carries no scale.
    """
    from PIL import Image

    from specholo.readback import MAX_ARRAY_BYTES, MAX_JSON_BYTES, read_bytes, read_text

    path = Path(path)
    # The bytes through the safe reader (a regular file, of a size known first),
    # then decoded from memory.
    raw = read_bytes(path, MAX_ARRAY_BYTES, "height map")
    try:
        with Image.open(io.BytesIO(raw)) as image:
            data = np.asarray(image)
            text = None
            if image.format == "PNG":
                text = getattr(image, "text", {}).get(PNG_KEY)
            elif image.format == "TIFF":
                text = image.tag_v2.get(270)  # type: ignore[attr-defined]
    except OSError as exc:
        raise SpecholoError(f"cannot read height map {path}: {exc}") from exc
    try:
        if text is None:
            text = read_text(path.with_suffix(".json"), MAX_JSON_BYTES, "height-map scale")
        scale = json.loads(text)
        lo, hi = float(scale["z_min_mm"]), float(scale["z_max_mm"])
        levels = int(scale["levels"])
        res = float(scale["mm_per_px"])
        origin = np.asarray(scale["origin_mm"], dtype=float)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SpecholoError(f"{path} carries no readable height-map scale: {exc}") from exc
    if data.dtype != np.uint16:
        data = data.astype(np.uint16)
    z = lo + data[::-1].astype(np.float64) * ((hi - lo) / levels)
    return HeightMap(z.astype(np.float32), origin, res)


def save_npz(path: str | os.PathLike[str], hm: HeightMap) -> None:
    """Save the exact float heights and labels (for simulation), atomically."""
    labels = hm.labels if hm.labels is not None else np.zeros((0, 0), np.int32)
    with atomic_open(path, "wb", encoding=None) as fh:
        np.savez_compressed(fh, z=hm.z, origin=hm.origin, resolution=hm.resolution,
                            labels=labels)


def load_npz(path: str | os.PathLike[str]) -> HeightMap:
    """Read a height map saved by :func:`save_npz`, its arrays checked (finite
    heights, a finite origin and resolution, labels of the heights' shape or none).

    Raises:
        SpecholoError: an unreadable file or arrays unlike those :func:`save_npz` writes.
    """
    from specholo.readback import ArraySpec, load_arrays

    a = load_arrays(path, {"z": ArraySpec((None, None), np.float32, finite=True),
                           "origin": ArraySpec((2,), finite=True),
                           "resolution": ArraySpec((), finite=True),
                           "labels": ArraySpec((None, None), np.int32)})
    labels = a["labels"]
    try:
        return HeightMap(a["z"], a["origin"], float(a["resolution"]),
                         labels if labels.size else None)
    except SpecholoError as exc:
        raise SpecholoError(f"{os.fspath(path)}: {exc}") from exc


# ---------------------------------------------------------------------------
# STL


def write_stl(path: str | os.PathLike[str], hm: HeightMap, thickness: float,
              region: np.ndarray | None = None, step: int | None = None,
              max_faces: int | None = None) -> Any:
    """Write the plate as a watertight solid (binary STL), atomically: see
    :func:`specholo.fabrication.stl.write_stl`.

    Returns:
        The ``trimesh.Trimesh`` written.
    """
    from specholo.fabrication.stl import STL_FACES
    from specholo.fabrication.stl import write_stl as grid_stl

    return grid_stl(path, hm, thickness, region, step,
                    STL_FACES if max_faces is None else max_faces)


# ---------------------------------------------------------------------------
# Ball-end raster finishing


@kernel(parallel=True)
def _dilate_ball(z: np.ndarray, res: float, radius: float, rows: np.ndarray) -> np.ndarray:
    """Lowest tip height of a ball that touches but does not cut the surface,
    on the given rows (r,) of the grid: max over the ball's footprint of
    z - (R - sqrt(R^2 - d^2))."""
    ny, nx = z.shape
    m = int(radius / res)
    out = np.empty((rows.size, nx), np.float64)
    # The ball's height above its tip at each offset of the footprint.
    offs = np.empty((2 * m + 1, 2 * m + 1), np.float64)
    for a in range(-m, m + 1):
        for b in range(-m, m + 1):
            d2 = (a * res) ** 2 + (b * res) ** 2
            offs[a + m, b + m] = radius - math.sqrt(radius * radius - d2) if d2 <= radius * \
                radius else np.inf
    for k in nb.prange(rows.size):
        j = rows[k]
        for i in range(nx):
            best = -np.inf
            for a in range(-m, m + 1):
                jj = j + a
                if jj < 0 or jj >= ny:
                    continue
                for b in range(-m, m + 1):
                    ii = i + b
                    if ii < 0 or ii >= nx:
                        continue
                    v = z[jj, ii] - offs[a + m, b + m]
                    if v > best:
                        best = v
            out[k, i] = best
    return out


def tool_tip(hm: HeightMap, radius: float, rows: np.ndarray | None = None) -> np.ndarray:
    """Tip heights of a ball-end mill finishing the surface without gouging it.

    Args:
        hm: the surface.
        radius: ball radius, mm (at least one sample).
        rows: grid rows to compute (default all).

    Returns:
        (r, nx) tip heights, mm (>= the surface below the tip).
    """
    radius = float(radius)
    if not (math.isfinite(radius) and radius >= hm.resolution):
        raise SpecholoError(f"ball radius must be at least the resolution "
                            f"{hm.resolution:g} mm, got {radius:g}")
    rows = np.arange(hm.shape[0]) if rows is None else np.asarray(rows, dtype=np.int64)
    return _dilate_ball(np.ascontiguousarray(hm.z, dtype=np.float64), hm.resolution, radius,
                        rows)


@kernel(parallel=True)
def _erode_ball(tip: np.ndarray, rows: np.ndarray, ny: int, res: float,
                radius: float) -> np.ndarray:
    """The surface the ball leaves: min over passes and footprints of tip + ball height
    (rows (r,) sorted: the pass rows of tip (r, nx))."""
    nr, nx = tip.shape
    m = int(radius / res)
    out = np.zeros((ny, nx), np.float64)
    for j in nb.prange(ny):
        k0 = np.searchsorted(rows, j - m)
        k1 = np.searchsorted(rows, j + m, side="right")
        for i in range(nx):
            best = 0.0
            for k in range(k0, k1):
                dy = (rows[k] - j) * res
                for b in range(-m, m + 1):
                    ii = i + b
                    if ii < 0 or ii >= nx:
                        continue
                    d2 = dy * dy + (b * res) ** 2
                    if d2 > radius * radius:
                        continue
                    v = tip[k, ii] + radius - math.sqrt(radius * radius - d2)
                    if v < best:
                        best = v
            out[j, i] = best
    return out


def milled(hm: HeightMap, radius: float, stepover: float | None = None) -> HeightMap:
    """The surface a ball-end raster leaves (passes along x every ``stepover`` in y).

    Args:
        hm: the designed surface.
        radius: ball radius, mm.
        stepover: pass spacing, mm (a multiple of the resolution; default one sample).

    Returns:
        The milled surface, same grid and labels (at or above the design).
    """
    rows = _pass_rows(hm, stepover)
    tip = tool_tip(hm, radius, rows)
    z = _erode_ball(tip, rows, hm.shape[0], hm.resolution, float(radius))
    return HeightMap(np.minimum(z, 0.0).astype(np.float32), hm.origin, hm.resolution,
                     hm.labels)


def _pass_rows(hm: HeightMap, stepover: float | None) -> np.ndarray:
    res = hm.resolution
    k = 1 if stepover is None else round(float(stepover) / res)
    if stepover is not None and (not math.isfinite(stepover) or k < 1
                                 or abs(k * res - stepover) > 1e-6 * max(res, stepover)):
        raise SpecholoError(f"stepover must be a positive multiple of the resolution "
                            f"{res:g} mm, got {stepover}")
    ny = hm.shape[0]
    rows = np.arange(0, ny, k, dtype=np.int64)
    if rows[-1] != ny - 1:
        rows = np.append(rows, ny - 1)
    return rows


@kernel()
def _thin(z: np.ndarray, tol: float) -> np.ndarray:
    """Indices of the points of a profile to keep so every dropped point is within
    tol of the chord between its kept neighbours (greedy, first and last kept).

    From each kept point a the chord is extended while its slope stays inside
    every slope window the points passed so far allow (one pass per profile).
    """
    n = z.size
    keep = np.zeros(n, np.bool_)
    keep[0] = True
    keep[n - 1] = True
    a = 0
    while a < n - 1:
        lo = -np.inf
        hi = np.inf
        b = a + 1
        c = a + 1
        while c < n:
            slope = (z[c] - z[a]) / (c - a)
            if slope < lo or slope > hi:
                break
            b = c
            lo = max(lo, (z[c] - tol - z[a]) / (c - a))
            hi = min(hi, (z[c] + tol - z[a]) / (c - a))
            c += 1
        keep[b] = True
        a = b
    return np.flatnonzero(keep)


def _comment(text: str) -> str:
    # One line of printable ASCII; G-code comments cannot nest parentheses.
    clean = "".join(c if 32 <= ord(c) < 127 else "?" for c in text)[:200]
    return "(" + clean.replace("(", "[").replace(")", "]") + ")"


@dataclass(frozen=True)
class RasterStats:
    """What a raster finishing program does.

    Attributes:
        lines: lines written.
        passes: raster passes written (those that cut).
        points: cutting points written.
        cutting_length_mm: length of the feed moves, mm.
        deepest_tip_mm: lowest tool-tip height, mm.
        minutes: time at the feeds (rapids and accelerations not counted).
    """

    lines: int
    passes: int
    points: int
    cutting_length_mm: float
    deepest_tip_mm: float
    minutes: float


def write_raster_gcode(path: str | os.PathLike[str], hm: HeightMap, radius: float,
                       machining: Machining, stepover: float | None = None,
                       tolerance: float = 5e-4, dwell: float = 2.0,
                       header: dict[str, str] | None = None,
                       plate: Plate | None = None,
                       options: GcodeOptions | None = None) -> RasterStats:
    """Write a ball-end raster finishing program for the surface, atomically.

    Passes run along x, alternating direction, one every ``stepover`` in y,
    each over its cuts plus a ball radius (passes that cut nothing are left
    out); the tool centre stays at least one ball radius inside the height
    map's bounds (so keep a blank border of that width). From one pass to the
    next, one stepover on, the tool moves across above both passes' tips
    between their ends; after a skipped pass it retracts to the safe height,
    moves there at rapid and plunges at the plunge feed. The program: header
    comments, then the one emitter's set-up
    (:class:`~specholo.fabrication.programs.program.Emitter`: units, the spindle
    and a dwell, the safe height), the passes, a retract, ``M5 M2``.

    Args:
        path: destination file.
        hm: the surface.
        radius: ball radius, mm.
        machining: feeds (mm/min), safe height (mm), spindle (rpm).
        stepover: pass spacing, mm (a multiple of the resolution; default one sample).
        tolerance: largest height error of the thinned profile, mm.
        dwell: seconds to wait after starting the spindle.
        header: extra ``key: value`` comment lines.
        plate: the plate the header's plate block names (its size, corners
            and zero; a ridged design draws no marks), or None for no block.
        options: dialect and units (a mill's); default GRBL in mm. ``dwell``
            is taken from the argument, not the options.

    Returns:
        Counts, length, deepest tip and time.
    """
    radius = float(radius)
    res = hm.resolution
    if not (math.isfinite(tolerance) and tolerance >= 0):
        raise SpecholoError(f"tolerance must be a number of mm >= 0, got {tolerance}")
    m = math.ceil(radius / res - 1e-9)
    ny, nx = hm.shape
    if 2 * m >= min(nx, ny):
        raise SpecholoError(f"a {2 * radius:g} mm ball does not fit inside a "
                            f"{(nx - 1) * res:g} x {(ny - 1) * res:g} mm height map")
    rows = _pass_rows(hm, stepover)
    rows = rows[(rows >= m) & (rows <= ny - 1 - m)]
    if rows.size == 0 or rows[-1] != ny - 1 - m:
        rows = np.append(rows, ny - 1 - m)
    tip = tool_tip(hm, radius, rows)[:, m:nx - m]
    xs = hm.x[m:nx - m]
    safe = machining.safe_z

    em = Emitter(replace(options or GcodeOptions(), dwell=dwell), machining)
    em.require_mill("a ridged plate's raster")
    num = em.num
    scale = em.scale
    dec = em.decimals

    def q(v: np.ndarray) -> np.ndarray:
        return np.rint(np.asarray(v) * scale).astype(np.int64)

    step_mm = (rows[1] - rows[0]) * res if rows.size > 1 else 0.0
    unit = em.unit
    body = [f"tool: ball end, radius {num(radius)} {unit}",
            f"pass rows: {rows.size} along X, stepover {num(step_mm)} {unit}, "
            f"chord tolerance {num(tolerance)} {unit}",
            f"deepest tip: {num(float(tip.min()))} {unit}"]
    head = em.head("specholo height map, ball-end raster finishing", body, header, plate, None)
    n_lines = len(head)
    points = 0
    length = 0.0
    feed_text = f" F{num(machining.feed)}"
    written = 0
    plunge_text = f" F{num(machining.plunge)}"
    with atomic_open(path, "wb", encoding=None) as fh:
        fh.write(("\n".join(head) + "\n").encode("ascii"))
        prev: tuple[int, int, float, float] | None = None  # pass, column, y, z at its end
        for k, j in enumerate(rows):
            prof = tip[k]
            cut = np.flatnonzero(prof < -_UNCUT)
            if cut.size == 0:
                continue  # nothing to finish on this pass
            # The pass spans its cuts plus a ball radius, where the ball lifts clear.
            a = max(int(cut[0]) - m, 0)
            b = min(int(cut[-1]) + m, len(prof) - 1)
            keep = a + _thin(prof[a:b + 1], float(tolerance))
            if written % 2:
                keep = keep[::-1]
            written += 1
            x = xs[keep]
            z = prof[keep]
            y = float(hm.y[j])
            out = []
            first_feed = feed_text
            if prev is not None and prev[0] == k - 1:
                # The next pass, one stepover on: move across above both passes' tips.
                _, col, py, pz = prev
                lo, hi = sorted((col, int(keep[0])))
                lift = max(float(tip[k - 1, lo:hi + 1].max()), float(prof[lo:hi + 1].max()),
                           pz, float(z[0]))
                if lift > pz:
                    out.append(f"G1 Z{num(lift)}{feed_text}")
                out.append(f"G1 X{num(x[0])} Y{num(y)}{feed_text}")
                if z[0] < lift:
                    out.append(f"G1 Z{num(z[0])}")
                length += (lift - pz) + math.hypot(float(xs[col] - x[0]), y - py) \
                    + (lift - float(z[0]))
                first_feed = ""
            else:
                if prev is not None:
                    out.append(f"G0 Z{num(safe)}")
                out.append(f"G0 X{num(x[0])} Y{num(y)}")
                out.append(f"G1 Z{num(z[0])}{plunge_text}")
                length += safe - float(z[0])
            fh.write(("\n".join(out) + "\n").encode("ascii"))
            n_lines += len(out)
            t = TextRows(len(x) - 1)
            t.text("G1 X")
            t.number(q(x[1:]), dec)
            t.text(" Z")
            t.number(q(z[1:]), dec)
            if first_feed and len(x) > 1:
                first = np.zeros(len(x) - 1, dtype=bool)
                first[0] = True
                t.text(first_feed, first)
            t.text("\n")
            fh.write(t.tobytes())
            n_lines += len(x) - 1
            points += len(x)
            length += float(np.sum(np.hypot(np.diff(x), np.diff(z))))
            prev = (k, int(keep[-1]), y, float(z[-1]))
        tail = em.tail(safe)
        fh.write(("\n".join(tail) + "\n").encode("ascii"))
        n_lines += len(tail)
    return RasterStats(lines=n_lines, passes=written, points=points,
                       cutting_length_mm=length, deepest_tip_mm=float(tip.min()),
                       minutes=length / machining.feed)


# ---------------------------------------------------------------------------
# A ridged design's files

#: Files :func:`write_ridged_files` can write, by format name.
RIDGED_FILES = {"png": "heightmap.png", "tiff": "heightmap.tif", "stl": "hologram.stl",
                "gcode": "hologram.gcode"}
#: The exact heights and labels, for verification.
PLATE_FILE = "plate.npz"


def write_ridged_files(plate: RidgedPlate, folder: Any, machining: Any, ball_radius: float,
                       stock_thickness: float,
                       formats: tuple[str, ...] = ("png", "tiff", "gcode"),
                       stepover: float | None = None) -> dict[str, float]:
    """Write a ridged plate's files into a folder (each atomically).

    Always ``plate.npz`` (exact heights and labels) and, for ``png`` or
    ``tiff``, the sidecar ``heightmap.json``; then the formats asked for
    (:data:`RIDGED_FILES`).

    Args:
        plate: the design.
        folder: output folder (must exist).
        machining: feeds, safe height and spindle (:class:`~specholo.setup.Machining`).
        ball_radius: ball-end mill radius for the G-code, mm.
        stock_thickness: plate thickness for the STL, mm.
        formats: from :data:`RIDGED_FILES`.
        stepover: G-code pass spacing, mm (default one sample).

    Returns:
        Seconds spent per file.
    """
    import time
    from pathlib import Path

    for f in formats:
        if f not in RIDGED_FILES:
            raise SpecholoError(f"ridged formats must be among {', '.join(RIDGED_FILES)}, "
                                f"got {f!r}")
    folder = Path(folder)
    hm = plate.heights
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    save_npz(folder / PLATE_FILE, hm)
    timings["plate"] = time.perf_counter() - t0
    images = []
    scale = hm.scale()
    if "png" in formats:
        t0 = time.perf_counter()
        write_png(folder / RIDGED_FILES["png"], hm)
        images.append(RIDGED_FILES["png"])
        timings["png"] = time.perf_counter() - t0
    if "tiff" in formats:
        t0 = time.perf_counter()
        write_tiff(folder / RIDGED_FILES["tiff"], hm)
        images.append(RIDGED_FILES["tiff"])
        timings["tiff"] = time.perf_counter() - t0
    if images:
        write_sidecar(folder / "heightmap.json", scale, tuple(images))
    if "stl" in formats:
        t0 = time.perf_counter()
        write_stl(folder / RIDGED_FILES["stl"], hm, stock_thickness)
        timings["stl"] = time.perf_counter() - t0
    if "gcode" in formats:
        t0 = time.perf_counter()
        write_raster_gcode(folder / RIDGED_FILES["gcode"], hm, ball_radius, machining, stepover,
                           header={"design": "ridged", "stipples": str(len(plate.points))})
        timings["gcode"] = time.perf_counter() - t0
    return timings


def load_ridged(folder: Any) -> HeightMap:
    """The exact height map of a ridged design folder (``plate.npz``)."""
    from pathlib import Path

    path = Path(folder) / PLATE_FILE
    if not path.exists():  # anything else in its place is refused by its reader
        raise SpecholoError(f"{folder} holds no {PLATE_FILE}: not a ridged design folder")
    return load_npz(path)

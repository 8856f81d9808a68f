"""The ridged job: a full-parallax plate, a milled height field instead of grooves.

Load, place and stipple the model as the grooved designs do
(:mod:`specholo.jobs.plate_common`), design the facets (:mod:`specholo.toolpaths.ridged`),
write the folder (height maps, STL, raster G-code checked before it is kept,
the data and a preview), read it back and verify it with heads over azimuth
and elevation (:mod:`specholo.simulation.heightfield`).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from specholo import __version__
from specholo.errors import SpecholoError
from specholo.jobs.plate_common import (
    check_formats,
    design_json,
    load_stipples,
    settings_of,
    stipple_model,
)
from specholo.jobs.ridged.settings import RASTER_RANGE, RIDGED_BLOCK, RidgedConfig
from specholo.setup import BackLight
from specholo.toolpaths.grooves import MAX_COORDINATE

#: A ridged design's fabrication files by default (see
#: :data:`specholo.fabrication.heightmap.RIDGED_FILES`).
DEFAULT_RIDGED_FORMATS = ("png", "tiff", "stl", "gcode")
#: Peak memory per raster cell of a ridged design and its files, bytes: heights
#: and labels, the slope index, the ball's tip heights (float64) and the images.
RIDGED_BYTES_PER_CELL = 40


@dataclass
class RidgedDesign:
    """A ridged full-parallax design: the placed model, its stipples and the plate.

    Attributes:
        config: the options.
        model: the placed model (``scene.loading.Model``).
        points: (n, 3) stipples, mm.
        normals: (n, 3) their face normals, or None for a point cloud.
        plate: the plate (``toolpaths.ridged.RidgedPlate``).
        timings: seconds per stage.
        budget: how many stipples the plate's regions can show a head
            (``toolpaths.ridged.StereoBudget``).
    """

    config: RidgedConfig
    model: Any
    points: np.ndarray
    normals: np.ndarray | None
    plate: Any
    timings: dict[str, float]
    budget: Any = None


def ridge_options(config: RidgedConfig) -> Any:
    """The ridged construction's settings (``toolpaths.ridged.RidgeOptions``) of a config.

    The plate is shared out in blocks of about :data:`RIDGED_BLOCK` (a whole number
    of raster cells), with a blank border wide enough for the finishing ball.
    """
    from specholo.scene.loading import available_memory
    from specholo.toolpaths.ridged import RidgeOptions

    raster = float(config.raster)
    ratio = max(1, round(RIDGED_BLOCK / raster))
    room = available_memory()
    cells = RidgeOptions.max_cells
    if room is not None:
        cells = max(1, min(cells, int(room) // RIDGED_BYTES_PER_CELL))
    return RidgeOptions(delta=float(config.shell), resolution=raster, block=ratio * raster,
                        elevation_range=math.radians(float(config.elevation_range)),
                        margin=max(RidgeOptions.margin, 2.0 * config.ball_radius),
                        max_cells=cells)


def _ridged_plate_rect(config: RidgedConfig) -> np.ndarray | None:
    """The plate's corners (2, 2) from plate_width and plate_height, or None to fit."""
    if config.plate_width is None or config.plate_height is None:
        return None
    half = 0.5 * np.array([float(config.plate_width), float(config.plate_height)])
    return np.stack([-half, half])


def design_ridged_model(model_path: str | os.PathLike[str], config: RidgedConfig,
                        rng: np.random.Generator | None = None) -> RidgedDesign:
    """Load, place and stipple a model, then design its ridged full-parallax plate.

    Args:
        model_path: mesh or point-cloud file.
        config: the options.
        rng: random generator for stippling; default seeded from ``config.seed``.

    Raises:
        SpecholoError: on bad input, or a raster too large for the memory.
    """
    from specholo.toolpaths.ridged import design_ridged, stereo_budget

    if not isinstance(config, RidgedConfig):
        raise SpecholoError(f"design_ridged_model needs a ridged design's settings "
                            f"(RidgedConfig), got {type(config).__name__}")
    setup = config.setup()
    options = ridge_options(config)
    plate_rect = _ridged_plate_rect(config)
    timings: dict[str, float] = {}
    model, st, config = stipple_model(model_path, config, rng, timings)
    t0 = time.perf_counter()
    try:
        plate = design_ridged(st.points, st.normals, model.mesh, setup, options, plate_rect,
                              config.refraction if config.optic == "refract" else None)
    except SpecholoError as exc:
        if "raster is too large" not in str(exc):
            raise
        raise SpecholoError(f"the ridged plate would need more than {options.max_cells:,} "
                            f"raster cells: coarsen --raster {config.raster:g}, narrow the view "
                            "or elevation range, or make the model smaller") from exc
    timings["plate"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    budget = stereo_budget(plate, setup.viewer, math.radians(float(config.elevation_range)))
    timings["budget"] = time.perf_counter() - t0
    return RidgedDesign(config, model, st.points, st.normals, plate, timings, budget)


def plate_edges(heights: Any) -> np.ndarray:
    """The plate rectangle (2, 2) of a height map: its samples' cells, edge to edge, mm."""
    half = 0.5 * heights.resolution
    return np.asarray(heights.bounds, dtype=float) + np.array([[-half], [half]])


def ridged_json(d: RidgedDesign) -> dict[str, Any]:
    """A ridged design's settings, figures and stipples, for ``hologram.json``."""
    plate = d.plate
    hm = plate.heights
    summary = plate.summary()
    edges = plate_edges(hm)
    records = plate.stipple_records()
    dropped = np.zeros(len(d.points), dtype=bool)
    dropped[plate.dropped] = True
    visible_share = plate.visible.mean(axis=(1, 2)) if plate.visible.size else \
        np.zeros(len(d.points))
    stipples = []
    for i, p in enumerate(d.points.tolist()):
        rec = {"id": i, "x": p[0], "y": p[1], "z": p[2], "dropped": bool(dropped[i]),
               "visible_share": float(visible_share[i])}
        rec.update({k: v for k, v in records[i].items() if k != "id"})
        stipples.append(rec)
    return {
        "specholo_version": __version__,
        "design": "ridged",
        "settings": asdict(d.config),
        "frame": "plate mm: x right, y up, z toward the viewer, plate at z = 0",
        "tool": {"kind": "ball", "description": f"ball-end mill, radius "
                 f"{d.config.ball_radius:g} mm (raster finishing)",
                 "ball_radius_mm": d.config.ball_radius},
        "plate": {"plate_mm": edges.tolist(), "raster_mm": hm.resolution,
                  "cells": [int(hm.shape[1]), int(hm.shape[0])],
                  "shell_mm": [-2.0 * plate.delta, 0.0],
                  "stock_thickness_mm": d.config.stock_thickness},
        "ridged": {**summary, **({} if d.budget is None else
                                 {"stereo_budget": d.budget.as_dict()})},
        **({"refraction": refraction_json(d.config)} if d.config.optic == "refract" else {}),
        "stats": {"stipples": len(d.points), "kept_stipples": summary["kept_stipples"],
                  "dropped_stipples": summary["dropped_stipples"],
                  "median_kept_share": summary["median_kept_share"],
                  "seconds": d.timings},
        "stipples": stipples,
    }


def refraction_json(config: RidgedConfig) -> dict[str, Any]:
    """A refraction plate's optics, for ``hologram.json``."""
    light = config.setup().light
    assert isinstance(light, BackLight)
    what = {"exact": "two surfaces: the planar back face and the front facets, level sets "
                     "of the Fermat path from the light plus sigma |s - p|",
            "approx": "the paper's approximation: Cartesian ovals n |s - c| + sigma |s - p| "
                      "about a centre of divergence c fitted to each stipple's in-plate rays",
            "single": "single interface: Cartesian ovals n |s - i| + sigma |s - p|, the back "
                      "face ignored"}[config.refraction]
    return {"model": config.refraction, "description": what, "index": light.index,
            "front_face_z_mm": 0.0, "back_face_z_mm": -light.thickness,
            "light": ({"kind": "sun", "direction": light.direction.tolist()}
                      if light.position is None else
                      {"kind": "point", "position_mm": light.position.tolist()}),
            "elevation_deg": float(config.light_elevation)}


def ridged_limits(d: RidgedDesign) -> Any:
    """What a ridged plate's G-code may do (``fabrication.check.Limits``): the
    ball's centre inside the plate less its radius, no deeper than the shell,
    rapids only at the safe height, feeds and spindle as set (a spinning mill)."""
    from specholo.fabrication.check import Limits, Stock

    m = d.config.setup().machining
    r = d.config.ball_radius
    (x0, y0), (x1, y1) = plate_edges(d.plate.heights)
    stock = Stock(x0 + r, y0 + r, x1 - r, y1 - r, d.config.stock_thickness)
    return Limits(stock, 2.0 * d.plate.delta, m.safe_z, (min(m.feed, m.plunge),
                  max(m.feed, m.plunge)), (m.spindle, m.spindle), "mill")


def write_ridged_design(d: RidgedDesign, out: str | os.PathLike[str],
                        formats: tuple[str, ...] = DEFAULT_RIDGED_FORMATS,
                        inputs: Iterable[str | os.PathLike[str] | None] = ()
                        ) -> dict[str, Any]:
    """Write every output of a ridged design into ``out`` (all or nothing).

    Always ``hologram.json``, ``plate.npz`` (the exact heights and the stipple of
    each cell), ``stipples.npz`` and, for a mesh, ``model.ply``; then the
    formats asked for: ``png`` and ``tiff`` (16-bit height maps, with the sidecar
    ``heightmap.json``), ``stl`` and ``gcode`` (ball-end raster finishing, read
    back by the safety check before anything is kept). ``inputs`` are the model
    and config files, which ``out`` must not hold as files a design writes.

    Returns:
        Seconds spent per output (``timings``) and the G-code's figures
        (``machining``, empty without G-code).
    """
    from specholo.fabrication.heightmap import RIDGED_FILES, write_raster_gcode, write_ridged_files
    from specholo.fabrication.plate import Plate
    from specholo.fabrication.programs.program import GcodeOptions
    from specholo.preview.preview import render_field_preview
    from specholo.staging import stage_design

    check_formats(formats, "ridged")
    setup = d.config.setup()
    info = ridged_json(d)
    timings: dict[str, float] = {}
    machining: dict[str, Any] = {}
    with stage_design(out, inputs, kind="ridged") as stage:
        tmp = stage.path
        images = tuple(f for f in formats if f != "gcode")
        timings.update(write_ridged_files(d.plate, tmp, setup.machining, d.config.ball_radius,
                                          d.config.stock_thickness, images))
        if "gcode" in formats:
            t0 = time.perf_counter()
            path = tmp / RIDGED_FILES["gcode"]
            stats = write_raster_gcode(
                path, d.plate.heights, d.config.ball_radius, setup.machining,
                header={"design": "ridged", "stipples": str(len(d.points)),
                        "cutter": info["tool"]["description"], **ridged_limits(d).header()},
                plate=Plate.from_corners(plate_edges(d.plate.heights),
                                         d.config.stock_thickness),
                options=GcodeOptions(dialect=d.config.dialect,  # type: ignore[arg-type]
                                     units=d.config.units))  # type: ignore[arg-type]
            timings["gcode"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            safety = stage.check(path.name, ridged_limits(d))
            timings["gcode check"] = time.perf_counter() - t0
            machining = {"dialect": d.config.dialect, "units": d.config.units,
                         "ball_radius_mm": d.config.ball_radius,
                         "passes": stats.passes, "lines": stats.lines,
                         "cutting_length_mm": stats.cutting_length_mm,
                         "deepest_tip_mm": stats.deepest_tip_mm,
                         "estimated_hours": stats.minutes / 60.0,
                         "safety_check": {"moves": safety.moves, "violations": 0}}
            info["machining"] = machining
        t0 = time.perf_counter()
        stage.save_arrays("stipples.npz", points=d.points,
                          normals=d.normals if d.normals is not None else np.zeros((0, 3)))
        if d.model.mesh is not None:
            stage.save_model(d.model.mesh)
        timings["data"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        render_field_preview(d.plate.heights, d.config.setup(), tmp / "preview.png")
        timings["preview"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        info["files"] = sorted(p.name for p in tmp.iterdir()) + ["hologram.json"]
        stage.save_record("ridged", info, sort_keys=False)
        timings["data"] += time.perf_counter() - t0
    return {"timings": timings, "machining": machining, "files": info["files"]}


def is_ridged_folder(folder: str | os.PathLike[str]) -> bool:
    """Whether a design folder holds a ridged design (by its ``hologram.json``, else
    by its ``plate.npz``)."""
    from specholo.readback import read_json

    folder = Path(folder)
    try:
        info = read_json(folder / "hologram.json")
    except SpecholoError:
        return (folder / "plate.npz").is_file()
    if not isinstance(info, dict):
        return False
    settings = info.get("settings")
    return info.get("design") == "ridged" or (isinstance(settings, dict)
                                              and settings.get("method") == "ridged")


@dataclass
class LoadedRidged:
    """A ridged design read back from its output folder.

    Attributes:
        config: the options.
        points: (n, 3) stipples, mm.
        normals: (n, 3) their face normals, or None.
        heights: the plate (``fabrication.heightmap.HeightMap``, labelled).
        mesh: the placed model, or None for a point cloud.
    """

    config: RidgedConfig
    points: np.ndarray
    normals: np.ndarray | None
    heights: Any
    mesh: Any


def load_ridged_design(folder: str | os.PathLike[str]) -> LoadedRidged:
    """Read a ridged design folder written by :func:`write_ridged_design`."""
    from specholo.fabrication.heightmap import load_ridged
    from specholo.readback import within
    from specholo.scene.loading import read_mesh

    folder = Path(folder)
    info = design_json(folder)
    settings = info.get("settings")
    method = settings.get("method") if isinstance(settings, dict) else None
    if method is not None and method != "ridged":
        raise SpecholoError(f"{folder} holds a {method} design, not a ridged one")
    config = settings_of(folder, info, RidgedConfig.from_saved)
    heights = load_ridged(folder)
    # The raster's cells are found from positions by dividing by the spacing:
    # a spacing of 1e-300 mm, or heights of 1e300, would overflow the indices.
    if not RASTER_RANGE[0] <= heights.resolution <= RASTER_RANGE[1] or not (
            within(heights.origin, -MAX_COORDINATE, MAX_COORDINATE)
            and within(heights.z, -MAX_COORDINATE, MAX_COORDINATE)):
        raise SpecholoError(f"{folder / 'plate.npz'}: raster {heights.resolution:g} mm, origin "
                            "or heights beyond any plate")
    points, normals = load_stipples(folder / "stipples.npz")
    mesh = read_mesh(folder / "model.ply") if (folder / "model.ply").exists() else None
    if heights.labels is None:
        raise SpecholoError(f"{folder / 'plate.npz'} holds no stipple labels")
    # Labels index the stipples (-1: no stipple) in the compiled glint search.
    if not within(heights.labels, -1, len(points) - 1):
        raise SpecholoError(f"{folder / 'plate.npz'} does not match {folder / 'stipples.npz'}")
    return LoadedRidged(config, points, normals, heights, mesh)


def _occlusion(mesh: Any, normals: np.ndarray | None) -> Any:
    """The occlusion test of a placed model, or None for a point cloud."""
    from specholo.visibility.occlusion import visible

    if mesh is None or normals is None:
        return None

    def vis(points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        return visible(mesh, points, normals, eyes)

    return vis


def ridged_views(config: RidgedConfig, max_step_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Head azimuths and elevations (radians) over the design's ranges, at most
    ``max_step_deg`` apart."""
    from specholo.simulation.verify import view_azimuths

    step = math.radians(max_step_deg)
    setup = config.setup()
    return (view_azimuths(setup.viewer.half_range, step),
            view_azimuths(math.radians(float(config.elevation_range)), step))


def verify_ridged_design(loaded: LoadedRidged, max_step_deg: float = 5.0) -> list[Any]:
    """Stereo heads over azimuth and elevation on a ridged plate
    (``simulation.heightfield.FullViewReport`` per head, azimuth-major)."""
    from specholo.simulation.heightfield import verify_field

    setup = loaded.config.setup()
    az, el = ridged_views(loaded.config, max_step_deg)
    return verify_field(loaded.heights, loaded.points, setup,
                        _occlusion(loaded.mesh, loaded.normals), az, el,
                        shell=float(loaded.config.shell))

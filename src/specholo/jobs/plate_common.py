"""What a grooved (flat) and a ridged plate, both made by ``specholo design``,
share: the model loaded, placed and stippled (fitted to the plate where asked),
the fabrication files each may write, and a folder's ``hologram.json``, its
settings and its stipples read back. Each kind's settings are a
:class:`~specholo.jobs.plate_settings.PlateConfig`."""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.plate import PLATE_MARGIN
from specholo.jobs.plate_settings import DEFAULT_STIPPLES, PlateConfig
from specholo.setup import Setup
from specholo.toolpaths.grooves import MAX_COORDINATE

_Config = TypeVar("_Config", bound=PlateConfig)

#: Files a grooved design can add besides the design data, by format name.
FORMATS = {"gcode": "hologram.gcode", "svg": "hologram.svg", "dxf": "hologram.dxf",
           "pdf": "pattern.pdf"}
#: Designs ``pattern.pdf`` is drawn for: an `arc` design's compass pattern, the
#: others' stroke pattern.
PATTERN_METHODS = ("striped", "hyperbola", "arc")


def check_formats(formats: tuple[str, ...], method: str) -> None:
    """Refuse unknown formats, and a hand pattern of a design that has no grooves."""
    if method == "ridged":
        from specholo.fabrication.heightmap import RIDGED_FILES

        for f in formats:
            if f not in RIDGED_FILES:
                raise SpecholoError(f"a ridged design's formats are among "
                                    f"{', '.join(RIDGED_FILES)}, got {f!r}")
        return
    for f in formats:
        if f not in FORMATS:
            raise SpecholoError(f"format must be among {', '.join(FORMATS)}, got {f!r}")
    if "pdf" in formats and method not in PATTERN_METHODS:
        raise SpecholoError(f"the pdf pattern is for scribing by hand a design of "
                            f"{', '.join(PATTERN_METHODS)} (got {method!r})")


def check_points(points: np.ndarray, setup: Setup) -> None:
    """Refuse points the viewer could not look at through the plate."""
    v = setup.viewer
    nearest_eye = v.distance * math.cos(v.design_range)
    if len(points) and points[:, 2].max() >= 0.9 * nearest_eye:
        raise SpecholoError(
            f"model reaches z = {points[:, 2].max():.1f} mm, too close to the eyes "
            f"(nearest eye depth {nearest_eye:.1f} mm); move it back with --center-z")


def fitted_size(model: Any, config: PlateConfig) -> float:
    """The largest size (mm) at which the model's grooves, as posed, lie on the
    plate ``config`` gives, within its blank border (:mod:`specholo.scene.fit`)."""
    from specholo.scene.fit import fit_size
    from specholo.scene.placement import place

    pose = config.pose()
    unit = place(model, 1.0, 0.0, pose.rotation())  # size 1 about its box centre
    half_width = 0.5 * config.cutter().section(config.depth_mm).width
    reach = (half_width, half_width + config.fit_band())
    size = fit_size(unit.points, np.array([*pose.offset, config.center_z]),
                    (float(config.plate_width or 0.0), float(config.plate_height or 0.0)),
                    config.setup().viewer, reach, PLATE_MARGIN)
    # Recorded with the design, so rounded (down: the rounded size still fits).
    return math.floor(min(size, 10_000.0) * 1e3) / 1e3


def stipple_model(model_path: str | os.PathLike[str], config: _Config,
                  rng: np.random.Generator | None, timings: dict[str, float]
                  ) -> tuple[Any, Any, _Config]:
    """Load and place the model and stipple it; refuse what would not fit in memory or
    could not be seen through the plate.

    Returns:
        The placed model, its stipples (``timings["stippling"]`` is set) and the
        config, whose size is the fitted one with ``config.fit``.
    """
    from specholo.scene.loading import load_model
    from specholo.scene.placement import place
    from specholo.scene.stippling import check_memory, stipple

    setup = config.setup()
    rng = rng if rng is not None else np.random.default_rng(config.seed)
    count = None if config.spacing is not None else (config.stipples or DEFAULT_STIPPLES)
    if count is not None:
        check_memory(count)  # stipples = 10**9 is refused before any work
    t0 = time.perf_counter()
    pose = config.pose()
    loaded = load_model(model_path)
    if config.fit:
        config = dataclasses.replace(config, size=fitted_size(loaded, config))
    model = place(loaded, config.size, config.center_z, pose.rotation(), pose.offset)
    st = stipple(model, rng, count=count, spacing=config.spacing)
    check_points(st.points, setup)
    mesh = model.mesh
    check_memory(len(st.points), 0 if mesh is None else len(mesh.faces),
                 0 if mesh is None else len(mesh.vertices),
                 request=None if count is not None else
                 f"spacing = {config.spacing:g} mm ({len(st.points)} stipples)")
    timings["stippling"] = time.perf_counter() - t0
    return model, st, config


def design_json(folder: Path) -> dict[str, Any]:
    """A design folder's hologram.json, a JSON object."""
    from specholo.readback import read_json, table

    meta = folder / "hologram.json"
    if not meta.exists():
        raise SpecholoError(f"{folder} holds no hologram.json: not a design folder")
    return table(read_json(meta), str(meta))


def settings_of(folder: Path, info: dict[str, Any], read: Callable[[Any], _Config]) -> _Config:
    """The settings a design's hologram.json records, checked as any config is:
    ``read`` is the kind's reader (its config's ``from_saved``)."""
    meta = folder / "hologram.json"
    if "settings" not in info:
        raise SpecholoError(f"{meta} holds no settings: not a design folder")
    try:
        return read(info["settings"])
    except SpecholoError as exc:
        raise SpecholoError(f"{meta}: {exc}") from exc


def load_stipples(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """A design's stipples.npz: the points (n, 3) and their normals (n, 3), or None
    where the model was a point cloud (stored as (0, 3))."""
    from specholo.readback import ArraySpec, load_arrays, within

    a = load_arrays(path, {"points": ArraySpec((None, 3), finite=True),
                           "normals": ArraySpec((None, 3), finite=True)})
    points, normals = a["points"], a["normals"]
    if not within(points, -MAX_COORDINATE, MAX_COORDINATE):
        raise SpecholoError(f"{path}: points must lie within {MAX_COORDINATE:g} mm")
    if len(normals) not in (0, len(points)):
        raise SpecholoError(f"{path}: {len(normals)} normals for {len(points)} points")
    return points, normals if len(normals) else None

"""The whole job: model in, engraving files and a simulated preview out.

The library entry points behind the CLI. Settings arrive in the units users
speak (degrees, mm) and are converted once, here, to the library's radians.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import numbers
import os
import shutil
import tempfile
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from specholo import __version__
from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open, public_mode
from specholo.fabrication.tools import (
    Cutter,
    ViewCheck,
    check_views,
    depth_for,
    make_cutter,
    needed_tilts,
)
from specholo.setup import Light, Machining, Setup, Viewer
from specholo.toolpaths.common import Runs, make_runs
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.overlap import Overlaps, groove_overlaps

METHODS = ("striped", "hyperbola", "arc")
DEFAULT_STIPPLES = 2000
#: Fallback groove depth (mm) and spindle speed (rpm) by tool. A design without a
#: depth cuts just deep enough for the wall tilts its views need (see
#: :data:`TILT_MARGIN`); drag tips, scribers and lasers do not spin.
#: Extra wall tilt (radians) over the steepest a design needs, when choosing its depth.
TILT_MARGIN = math.radians(2.0)
TOOL_DEFAULTS = {"ball": (0.08, 12000.0), "drag": (0.012, 0.0), "scriber": (0.012, 0.0),
                 "vbit": (0.05, 12000.0), "laser": (0.04, 0.0)}


#: Largest magnitude of any length, angle, feed or speed setting: far beyond any
#: plate, light or machine, and small enough that squares and products stay finite.
MAX_SETTING = 1e12


def _check_setting(config: Any, name: str, kind: str) -> None:
    """Refuse a setting of the wrong type or size, naming it.

    A TOML string, list, table or date where a number is expected, a bool for a
    number, NaN, infinity or a number beyond :data:`MAX_SETTING`; a whole float
    where an int is expected becomes the int.
    """
    value = getattr(config, name)
    option = name.replace("_", "-")
    if value is None and "None" in kind:
        return
    if kind.startswith("bool"):
        if not isinstance(value, bool):
            raise SpecholoError(f"{option} must be true or false, got {value!r}")
    elif kind.startswith("str"):
        if not isinstance(value, str):
            raise SpecholoError(f"{option} must be a string, got {value!r}")
    elif kind.startswith(("int", "float")):
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise SpecholoError(f"{option} must be a number, got {value!r}")
        try:
            number = float(value)
        except OverflowError:  # an int beyond any float
            number = math.inf
        if not math.isfinite(number):
            raise SpecholoError(f"{option} must be a finite number, got {value!r}")
        if kind.startswith("int"):
            if not number.is_integer():
                raise SpecholoError(f"{option} must be a whole number, got {value!r}")
            whole = int(getattr(config, name))
            if whole < 0:
                raise SpecholoError(f"{option} must not be negative, got {value!r}")
            object.__setattr__(config, name, whole)
        elif abs(number) > MAX_SETTING:
            raise SpecholoError(f"{option} {value!r} is out of range (at most {MAX_SETTING:g})")


@dataclass(frozen=True)
class DesignConfig:
    """Every design option, in the units of the command line (mm, degrees).

    Attributes mirror the ``specholo design`` options of the same names.
    """

    size: float = 60.0
    center_z: float = -40.0
    light_elevation: float = 45.0
    light_distance: float | None = None
    view_distance: float = 600.0
    view_range: float = 45.0
    eye_height: float = 0.0
    ipd: float = 64.0
    stipples: int | None = None
    spacing: float | None = None
    seed: int = 0
    method: str = "striped"
    band: float = 0.2
    tool: str = "drag"
    tool_radius: float | None = None
    tool_angle: float | None = None
    tip_flat: float = 0.0
    spot: float | None = None
    depth: float | None = None
    strict: bool = False
    dialect: str = "grbl"
    units: str = "mm"
    order: bool = True
    plate_width: float | None = None
    plate_height: float | None = None
    stock_thickness: float = 3.0
    feed: float = 300.0
    plunge: float = 100.0
    safe_z: float = 1.0
    spindle: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            _check_setting(self, f.name, str(f.type))
        # The spindle defaults by tool (a frozen dataclass: filled in once here); the
        # depth is chosen by design() from the wall tilts the views need.
        _, spindle = TOOL_DEFAULTS.get(self.tool, (0.08, 0.0))
        if self.spindle is None:
            object.__setattr__(self, "spindle", spindle)
        if self.dialect not in ("grbl", "linuxcnc", "marlin"):
            raise SpecholoError(f"dialect must be grbl, linuxcnc or marlin, got {self.dialect!r}")
        if self.units not in ("mm", "inch"):
            raise SpecholoError(f"units must be mm or inch, got {self.units!r}")
        if self.method not in METHODS:
            raise SpecholoError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        if self.stipples is not None and self.spacing is not None:
            raise SpecholoError("give either stipples or spacing, not both")
        if self.stipples is not None and (isinstance(self.stipples, bool)
                                          or int(self.stipples) != self.stipples
                                          or self.stipples <= 0):
            raise SpecholoError(f"stipples must be a positive integer, got {self.stipples}")
        if self.spacing is not None and not (math.isfinite(self.spacing) and self.spacing > 0):
            raise SpecholoError(f"spacing must be a positive number of mm, got {self.spacing}")
        for name in ("size", "center_z", "band"):
            if not math.isfinite(getattr(self, name)):
                raise SpecholoError(f"{name.replace('_', '-')} must be finite, got "
                                    f"{getattr(self, name)}")
        if not self.band > 0:
            raise SpecholoError(f"band must be positive, got {self.band}")
        if not self.size > 0:
            raise SpecholoError(f"size must be a positive number of mm, got {self.size}")
        for name in ("plate_width", "plate_height"):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v)
                                      and v > 0):
                raise SpecholoError(f"{name.replace('_', '-')} must be a positive number of mm, "
                                    f"got {v}")
        if not (isinstance(self.stock_thickness, (int, float))
                and math.isfinite(self.stock_thickness) and self.stock_thickness > 0):
            raise SpecholoError(f"stock-thickness must be a positive number of mm, got "
                                f"{self.stock_thickness}")
        if isinstance(self.depth, (int, float)) and self.depth >= self.stock_thickness:
            raise SpecholoError(f"groove depth {self.depth:g} mm must be less than the stock "
                                f"thickness {self.stock_thickness:g} mm")
        self.setup()  # validates the physical settings

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> DesignConfig:
        """Build from a mapping with option names (dashes or underscores)."""
        if not isinstance(values, dict):
            raise SpecholoError(f"settings must be a table of options, got {values!r:.60}")
        known = {f.name for f in fields(cls)}
        clean: dict[str, Any] = {}
        for key, value in values.items():
            name = str(key).replace("-", "_")
            if name not in known:
                raise SpecholoError(f"unknown setting {key!r}")
            clean[name] = value
        try:
            return cls(**clean)
        except TypeError as exc:
            raise SpecholoError(f"bad setting: {exc}") from exc

    @property
    def depth_mm(self) -> float:
        """Groove depth, mm: as given, else the tool's fallback default."""
        if self.depth is not None:
            return float(self.depth)
        return TOOL_DEFAULTS.get(self.tool, (0.08, 0.0))[0]

    def cutter(self) -> Cutter:
        """The cutting tool."""
        try:
            return make_cutter(self.tool, self.tool_radius, self.tool_angle,
                               float(self.tip_flat), self.spot)
        except (TypeError, ValueError) as exc:
            if isinstance(exc, SpecholoError):
                raise
            raise SpecholoError(f"bad setting: {exc}") from exc

    def setup(self) -> Setup:
        """The physical setup in library units (radians)."""
        try:
            return Setup(
                light=Light(math.radians(float(self.light_elevation)),
                            None if self.light_distance is None else float(self.light_distance)),
                viewer=Viewer(float(self.view_distance), float(self.eye_height),
                              math.radians(float(self.view_range)), float(self.ipd)),
                tool=self.cutter().model(self.depth_mm),
                machining=Machining(float(self.feed), float(self.plunge), float(self.safe_z),
                                    float(self.spindle or 0.0)),
            )
        except (TypeError, ValueError) as exc:
            if isinstance(exc, SpecholoError):
                raise
            raise SpecholoError(f"bad setting: {exc}") from exc


@dataclass
class Design:
    """A designed hologram: the placed model, its stipples, and the grooves."""

    config: DesignConfig
    model: Any  # scene.loading.Model
    points: np.ndarray  # (n, 3)
    normals: np.ndarray | None  # (n, 3)
    runs: Runs
    grooves: Grooves
    dropped: np.ndarray  # stipple ids that could not be designed
    timings: dict[str, float]
    views: ViewCheck | None = None  # the tool's walls against the tilts needed
    overlaps: Overlaps | None = None  # where grooves cut into each other
    plate: np.ndarray | None = None  # (2, 2) plate corners, mm


#: Blank border around the grooves when the plate size is not given, mm.
PLATE_MARGIN = 5.0


def plate_rect(grooves: Grooves, width: float, config: DesignConfig) -> np.ndarray:
    """The plate's corners (2, 2), centred on the plate origin; refuse one too small.

    Args:
        grooves: the design's grooves.
        width: groove width, mm (grooves reach half of it past their centrelines).
        config: plate_width / plate_height, or None to fit the grooves with a margin.
    """
    lo, hi = grooves.bounds() if grooves.n_paths else (np.zeros(2), np.zeros(2))
    reach = np.maximum(np.abs(lo), np.abs(hi)) + 0.5 * width
    need = 2.0 * reach
    size = np.array([config.plate_width or 0.0, config.plate_height or 0.0])
    given = size > 0
    for axis, name in ((0, "width"), (1, "height")):
        if given[axis] and size[axis] < need[axis]:
            raise SpecholoError(
                f"plate {name} {size[axis]:g} mm is smaller than the design, which needs "
                f"{need[axis]:.1f} mm (grooves reach +-{reach[axis]:.1f} mm from the centre)")
    size = np.where(given, size, np.ceil(need + 2.0 * PLATE_MARGIN))
    return np.stack([-0.5 * size, 0.5 * size])


def check_points(points: np.ndarray, setup: Setup) -> None:
    """Refuse points the viewer could not look at through the plate."""
    v = setup.viewer
    nearest_eye = v.distance * math.cos(v.design_range)
    if len(points) and points[:, 2].max() >= 0.9 * nearest_eye:
        raise SpecholoError(
            f"model reaches z = {points[:, 2].max():.1f} mm, too close to the eyes "
            f"(nearest eye depth {nearest_eye:.1f} mm); move it back with --center-z")


def auto_depth(cutter: Cutter, config: DesignConfig, points: np.ndarray, runs: Runs) -> float:
    """Shallowest depth, to the micrometre above, whose walls serve every view, plus
    :data:`TILT_MARGIN`; the tool's fallback depth when no depth can (a V-bit)."""
    setup = config.setup()
    tilts, _ = needed_tilts(points, runs.stipple, runs.start, runs.end, setup.light,
                            setup.viewer)
    need = float(tilts.max()) + TILT_MARGIN if tilts.size else TILT_MARGIN
    depth = depth_for(cutter, min(need, 0.5 * math.pi - 1e-6))
    if depth is None:
        return config.depth_mm
    depth = math.ceil(depth * 1000.0) / 1000.0
    # A ball or round tip shallower than its reach: beyond it the walls stop at the shank.
    try:
        cutter.check_depth(depth)
    except SpecholoError:
        return config.depth_mm
    return depth


def design_runs(runs: Runs, config: DesignConfig) -> tuple[Grooves, np.ndarray]:
    """Grooves for the given view intervals with the configured method."""
    from specholo.toolpaths.classic import design_classic
    from specholo.toolpaths.hyperbola import design_hyperbola
    from specholo.toolpaths.striped import StripeOptions, design_striped

    setup = config.setup()
    if config.method == "striped":
        return design_striped(runs, setup, StripeOptions(band=config.band))
    if config.method == "hyperbola":
        return design_hyperbola(runs, setup), np.zeros(0, dtype=np.int64)
    return design_classic(runs, setup), np.zeros(0, dtype=np.int64)


def design(model_path: str | os.PathLike[str], config: DesignConfig,
           rng: np.random.Generator | None = None, check_overlaps: bool = True) -> Design:
    """Load, place, stipple, crop by occlusion, check the tool, design the grooves.

    Args:
        model_path: mesh or point-cloud file.
        config: the options.
        rng: random generator for stippling; default seeded from ``config.seed``.
        check_overlaps: measure where grooves cut into each other.

    Raises:
        SpecholoError: on bad input, a plate smaller than the design, or (with
            ``config.strict``) a tool whose walls lose views.
    """
    from specholo.scene.loading import load_model
    from specholo.scene.placement import place
    from specholo.scene.stippling import check_memory, stipple
    from specholo.visibility.occlusion import visible_intervals

    setup = config.setup()
    rng = rng if rng is not None else np.random.default_rng(config.seed)
    timings: dict[str, float] = {}
    count = None if config.spacing is not None else (config.stipples or DEFAULT_STIPPLES)
    if count is not None:
        check_memory(count)  # stipples = 10**9 is refused before any work
    t0 = time.perf_counter()
    model = place(load_model(model_path), config.size, config.center_z)
    st = stipple(model, rng, count=count, spacing=config.spacing)
    points = st.points
    check_points(points, setup)
    mesh = model.mesh
    check_memory(len(points), 0 if mesh is None else len(mesh.faces),
                 0 if mesh is None else len(mesh.vertices),
                 request=None if count is not None else
                 f"spacing = {config.spacing:g} mm ({len(points)} stipples)")
    timings["stippling"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    iv = visible_intervals(model.mesh, points, st.normals, setup.viewer)
    runs = make_runs(points, iv.stipple, iv.start, iv.end)
    timings["occlusion"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    cutter = config.cutter()
    if config.depth is None:
        config = dataclasses.replace(config, depth=auto_depth(cutter, config, points, runs))
        setup = config.setup()
    views = check_views(cutter, config.depth_mm, points, runs.stipple, runs.start, runs.end,
                        setup.light, setup.viewer)
    if config.strict and views.lost > 0:
        raise SpecholoError(
            f"the {cutter.describe()} at {config.depth_mm:g} mm loses {100 * views.lost:.1f}% "
            f"of the views ({views.stipples_losing} stipples); {views.suggestion}")
    timings["tool check"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    grooves, dropped = design_runs(runs, config)
    timings["toolpaths"] = time.perf_counter() - t0
    section = cutter.section(config.depth_mm)
    plate = plate_rect(grooves, section.width, config)
    t0 = time.perf_counter()
    overlaps = groove_overlaps(grooves, section.width) if check_overlaps else None
    timings["overlaps"] = time.perf_counter() - t0
    return Design(config, model, points, st.normals, runs, grooves, dropped, timings,
                  views, overlaps, plate)


def _intervals_deg(runs: Runs, n: int) -> list[list[list[float]]]:
    out: list[list[list[float]]] = [[] for _ in range(n)]
    for s, a, b in zip(runs.stipple.tolist(), np.degrees(runs.start).tolist(),
                       np.degrees(runs.end).tolist(), strict=True):
        out[s].append([round(a, 4), round(b, 4)])
    return out


def hologram_json(d: Design) -> dict[str, Any]:
    """The design's settings, figures and stipples, for ``hologram.json``."""
    setup = d.config.setup()
    lo, hi = d.grooves.bounds()
    iv = _intervals_deg(d.runs, len(d.points))
    return {
        "specholo_version": __version__,
        "settings": asdict(d.config),
        "frame": "plate mm: x right, y up, z toward the viewer, plate at z = 0",
        "tool": {"kind": d.config.tool, "description": d.config.cutter().describe(),
                 "depth_mm": d.config.depth_mm,
                 "groove_width_mm": d.config.cutter().section(d.config.depth_mm).width,
                 "round_model": {"radius_mm": setup.tool.radius, "depth_mm": setup.tool.depth,
                                 "max_wall_tilt_deg": math.degrees(setup.tool.max_tilt)}},
        "views": d.views.as_dict() if d.views is not None else None,
        "overlaps": d.overlaps.as_dict() if d.overlaps is not None else None,
        "plate": {"groove_extent_mm": [lo.tolist(), hi.tolist()],
                  "plate_mm": d.plate.tolist() if d.plate is not None else None,
                  "stock_thickness_mm": d.config.stock_thickness},
        "stats": {"stipples": len(d.points), "paths": d.grooves.n_paths,
                  "dots": int(d.grooves.is_dot.sum()),
                  "groove_length_mm": d.grooves.total_length(),
                  "dropped_stipples": d.dropped.tolist(),
                  "seconds": d.timings},
        "stipples": [{"id": i, "x": float(p[0]), "y": float(p[1]), "z": float(p[2]),
                      "visible_deg": iv[i]} for i, p in enumerate(d.points.tolist())],
    }


@contextlib.contextmanager
def staged_output(out: str | os.PathLike[str],  # type: ignore[no-untyped-def]
                  stale: tuple[str, ...] = ()):
    """A scratch folder whose files move into ``out`` only if the block succeeds.

    Args:
        out: the output folder (created if missing).
        stale: names in ``out`` that describe an older run and go once the new
            files are in place (a new design's folder must not keep an old
            verification).
    """
    out = Path(out)
    try:
        if out.exists() and not out.is_dir():
            raise SpecholoError(f"{out} exists and is not a folder")
        parent = out.resolve().parent
        made = [d for d in (parent, *parent.parents) if not d.exists()]
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        raise SpecholoError(f"cannot create output folder {out}: "
                            f"{getattr(exc, 'strerror', None) or exc}") from exc
    public_mode(tmp, directory=True)
    done = False
    try:
        yield tmp
        if not out.exists():
            os.rename(tmp, out)
        else:
            fresh = {f.name for f in tmp.iterdir()}
            for name in fresh:
                os.replace(tmp / name, out / name)
            for name in set(stale) - fresh:
                with contextlib.suppress(FileNotFoundError):
                    (out / name).unlink()
        done = True
    except OSError as exc:  # a full disk, a folder turned read-only
        raise SpecholoError(f"cannot write {out}: {exc.strerror or exc}") from exc
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        if not done:  # leave no folder behind that this run created
            for d in made:
                with contextlib.suppress(OSError):
                    d.rmdir()


#: Files ``write_design`` can add besides the design data, by format name.
FORMATS = {"gcode": "hologram.gcode", "svg": "hologram.svg", "dxf": "hologram.dxf",
           "pdf": "pattern.pdf"}
DEFAULT_FORMATS = ("gcode", "svg")


def check_written_gcode(path: str | os.PathLike[str], d: Design) -> Any:
    """The independent safety check of a design's G-code: inside the plate (less half
    a groove, as the tool centre is checked), no deeper than the groove, rapids only
    at the safe height, feeds and spindle as set."""
    from specholo.fabrication.check import Stock, check_gcode

    setup = d.config.setup()
    m = setup.machining
    plate = d.plate if d.plate is not None else plate_rect(
        d.grooves, d.config.cutter().section(d.config.depth_mm).width, d.config)
    half = 0.5 * d.config.cutter().section(d.config.depth_mm).width
    scale = 25.4 if d.config.units == "inch" else 1.0
    laser = d.config.dialect == "marlin"
    stock = Stock(plate[0, 0] + half, plate[0, 1] + half, plate[1, 0] - half,
                  plate[1, 1] - half, d.config.stock_thickness)
    if scale != 1.0:
        stock = Stock(*(v / scale for v in (stock.x0, stock.y0, stock.x1, stock.y1,
                                            stock.thickness)))
    feeds = (min(m.feed, m.plunge) / scale, max(m.feed, m.plunge) / scale)
    power = (0.0, 1e9) if laser else (m.spindle, m.spindle)
    return check_gcode(path, stock, d.config.depth_mm / scale, m.safe_z / scale, feeds, power,
                       laser=laser, spindle=m.spindle > 0)


def check_formats(formats: tuple[str, ...], method: str) -> None:
    """Refuse unknown formats, and a compass pattern of grooves that are not arcs."""
    for f in formats:
        if f not in FORMATS:
            raise SpecholoError(f"format must be among {', '.join(FORMATS)}, got {f!r}")
    if "pdf" in formats and method != "arc":
        raise SpecholoError("the pdf pattern is for scratching circular arcs by hand: "
                            f"design with --method arc (got {method!r})")


def write_design(d: Design, out: str | os.PathLike[str],
                 formats: tuple[str, ...] = DEFAULT_FORMATS) -> dict[str, float]:
    """Write every output of a design into ``out`` (all or nothing).

    Args:
        d: the design.
        out: output folder.
        formats: fabrication files to write, from :data:`FORMATS`.

    Returns:
        Seconds spent per output.
    """
    from specholo.fabrication.dxf import write_dxf
    from specholo.fabrication.gcode import GcodeOptions, write_gcode
    from specholo.fabrication.order import order_paths
    from specholo.fabrication.pattern import write_pattern
    from specholo.fabrication.svg import write_svg
    from specholo.fabrication.timing import estimate_time
    from specholo.preview.preview import render_preview
    from specholo.scene.stippling import check_disk

    check_formats(formats, d.config.method)
    check_disk(len(d.points), out)
    setup = d.config.setup()
    timings: dict[str, float] = {}
    grooves = d.grooves
    if d.config.order:
        t0 = time.perf_counter()
        grooves, order_stats = order_paths(d.grooves)
        d = dataclasses.replace(d, grooves=grooves)
        timings["ordering"] = time.perf_counter() - t0
    info = hologram_json(d)
    estimate = estimate_time(grooves, d.config.depth_mm, setup.machining,
                             laser=d.config.dialect == "marlin")
    info["machining"] = {
        "dialect": d.config.dialect, "units": d.config.units,
        "estimated_hours": estimate.total_s / 3600.0,
        "cutting_hours": estimate.cutting_s / 3600.0, "rapid_hours": estimate.rapid_s / 3600.0,
        "plunge_hours": estimate.plunge_s / 3600.0,
        "stipples_per_second": estimate.stipples_per_s,
    }
    if d.config.order:
        info["machining"]["travel_unordered_mm"] = order_stats.travel_before_mm
        info["machining"]["travel_mm"] = order_stats.travel_after_mm
    stale = ("verify.json", "verify.png", "model.ply", *FORMATS.values())
    with staged_output(out, stale=stale) as tmp:
        if "gcode" in formats:
            t0 = time.perf_counter()
            path = tmp / "hologram.gcode"
            write_gcode(path, grooves, setup.tool, setup.machining,
                        header={"design": d.config.method, "stipples": str(len(d.points)),
                                "cutter": d.config.cutter().describe()},
                        options=GcodeOptions(dialect=d.config.dialect,  # type: ignore[arg-type]
                                             units=d.config.units))  # type: ignore[arg-type]
            timings["gcode"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            safety = check_written_gcode(path, d)
            if not safety.ok:
                raise SpecholoError("the G-code failed its safety check, nothing written: "
                                    + safety.summary().splitlines()[1].strip())
            info["machining"]["safety_check"] = {"moves": safety.moves, "violations": 0}
            timings["gcode check"] = time.perf_counter() - t0
        if "svg" in formats:
            t0 = time.perf_counter()
            write_svg(tmp / "hologram.svg", grooves, setup.tool)
            timings["svg"] = time.perf_counter() - t0
        if "dxf" in formats:
            t0 = time.perf_counter()
            write_dxf(tmp / "hologram.dxf", grooves, setup.tool)
            timings["dxf"] = time.perf_counter() - t0
        if "pdf" in formats:
            t0 = time.perf_counter()
            write_pattern(tmp / "pattern.pdf", grooves)
            timings["pdf"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        d.grooves.save(str(tmp / "grooves.npz"))
        with atomic_open(tmp / "stipples.npz", "wb", encoding=None) as fh:
            np.savez_compressed(fh, points=d.points,
                                normals=d.normals if d.normals is not None else np.zeros((0, 3)))
        if d.model.mesh is not None:
            d.model.mesh.export(tmp / "model.ply")
        with atomic_open(tmp / "hologram.json") as fh:
            json.dump(info, fh, indent=1)
        timings["data"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        render_preview(d.grooves, setup, tmp / "preview.png")
        timings["preview"] = time.perf_counter() - t0
    return timings


@dataclass
class Loaded:
    """A design read back from its output folder."""

    config: DesignConfig
    points: np.ndarray
    normals: np.ndarray | None
    grooves: Grooves
    mesh: Any


def load_design(folder: str | os.PathLike[str], from_gcode: bool = False) -> Loaded:
    """Read a design folder written by :func:`write_design`.

    Args:
        folder: the output folder.
        from_gcode: read the grooves from ``hologram.gcode`` (the file that will be
            cut) instead of ``grooves.npz``.
    """
    import trimesh

    folder = Path(folder)
    meta = folder / "hologram.json"
    if not meta.is_file():
        raise SpecholoError(f"{folder} holds no hologram.json: not a design folder")
    try:
        info = json.loads(meta.read_text())
        config = DesignConfig.from_dict(info["settings"])
        with np.load(folder / "stipples.npz") as data:
            points = data["points"]
            normals = data["normals"] if len(data["normals"]) else None
        if from_gcode:
            from specholo.fabrication.gcode import read_gcode
            grooves = read_gcode(folder / "hologram.gcode")
        else:
            grooves = Grooves.load(str(folder / "grooves.npz"))
        mesh = None
        if (folder / "model.ply").is_file():
            mesh = trimesh.load(folder / "model.ply", force="mesh", process=False)
    except SpecholoError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise SpecholoError(f"cannot read design in {folder}: {exc}") from exc
    return Loaded(config, points, normals, grooves, mesh)


def _visibility(loaded: Loaded) -> Any:
    """The occlusion test of a loaded design's model, or None for point clouds."""
    from specholo.visibility.occlusion import visible

    vis = None
    if loaded.mesh is not None and loaded.normals is not None:
        mesh, normals = loaded.mesh, loaded.normals

        def vis(points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
            return visible(mesh, points, normals, eyes)

    return vis


def verify_design(loaded: Loaded, max_step_deg: float = 5.0) -> list[Any]:
    """Run the stereo verification on a loaded design."""
    from specholo.simulation.verify import verify, view_azimuths

    setup = loaded.config.setup()
    az = view_azimuths(setup.viewer.half_range, math.radians(max_step_deg))
    return verify(loaded.grooves, loaded.points, setup, _visibility(loaded), az)


def verify_cut_design(loaded: Loaded, max_step_deg: float = 5.0, resolution: float = 0.02,
                      stl: str | os.PathLike[str] | None = None) -> tuple[list[Any], Any]:
    """Cut the design's grooves into a simulated plate and verify on that surface.

    Args:
        loaded: the design (grooves read back from its G-code, usually).
        max_step_deg: largest azimuth step between eye pairs, degrees.
        resolution: height-field sample spacing, mm.
        stl: also write the cut plate here as a watertight STL.

    Returns:
        The per-azimuth reports on the cut plate, and the height field.
    """
    from specholo.simulation.cut import cut_design, verify_cut, write_stl
    from specholo.simulation.verify import view_azimuths

    if not (math.isfinite(resolution) and 0.001 <= resolution <= 1.0):
        raise SpecholoError(f"resolution must be in [0.001, 1] mm, got {resolution}")
    setup = loaded.config.setup()
    field = cut_design(loaded, resolution)
    if stl is not None:
        write_stl(stl, field, loaded.config.stock_thickness)
    az = view_azimuths(setup.viewer.half_range, math.radians(max_step_deg))
    return verify_cut(field, loaded.points, setup, _visibility(loaded), az), field

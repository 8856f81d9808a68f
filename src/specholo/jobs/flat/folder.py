"""A flat plate's folder: the design written whole (G-code checked, SVG, DXF,
pattern, data, preview), read back, and verified.

The library entry points behind the CLI's ``design`` and ``verify`` for a flat
plate. The settings (:mod:`specholo.jobs.flat.settings`) and the design itself
(:mod:`specholo.jobs.flat.design`) are re-exported here, so ``from specholo.jobs.flat.folder
import DesignConfig, design, write_design`` keeps working.
"""


from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open
from specholo.fabrication.plate import Plate
from specholo.jobs.flat.design import (
    AS_CUT_MAX_STIPPLES,
    AS_CUT_SKIPPED,
    AS_CUT_STEP_DEG,
    Coverage,
    Design,
    StippleRows,
    as_cut_json,
    auto_depth,
    coverage,
    design,
    design_runs,
    drop_reasons,
    expected_as_cut,
    groove_extent,
    hologram_json,
    plate_rect,
    run_record,
)
from specholo.jobs.flat.settings import (
    BAND,
    DEPTH_ALLOWANCE,
    HAND_BAND,
    METHODS,
    SETTING_BOUNDS,
    TILT_MARGIN,
    DesignConfig,
)
from specholo.jobs.plate_common import (
    FORMATS,
    check_formats,
    design_json,
    load_stipples,
    settings_of,
)
from specholo.jobs.plate_settings import DEFAULT_STIPPLES, MAX_SETTING, TOOL_DEFAULTS
from specholo.optics.spread import Spread
from specholo.toolpaths.grooves import Grooves

#: The settings and the design are re-exported: callers import them from here.
__all__ = [
    "AS_CUT_MAX_STIPPLES",
    "AS_CUT_SKIPPED",
    "AS_CUT_STEP_DEG",
    "BAND",
    "CUT_METHODS",
    "Coverage",
    "DEFAULT_FORMATS",
    "default_resolution",
    "DEFAULT_STIPPLES",
    "Design",
    "DesignConfig",
    "FORMATS",
    "HAND_BAND",
    "Loaded",
    "MAX_SETTING",
    "METHODS",
    "SETTING_BOUNDS",
    "StippleRows",
    "TILT_MARGIN",
    "TOOL_DEFAULTS",
    "Written",
    "as_cut_json",
    "auto_depth",
    "check_written_gcode",
    "coverage",
    "cut_method",
    "design",
    "design_limits",
    "design_runs",
    "drop_reasons",
    "dump_design_json",
    "expected_as_cut",
    "groove_extent",
    "hologram_json",
    "load_design",
    "plate_rect",
    "run_record",
    "verify_cut_design",
    "verify_design",
    "write_design",
]


#: The files ``write_design`` adds besides the design data by default
#: (:data:`~specholo.jobs.plate_common.FORMATS`).
DEFAULT_FORMATS = ("gcode", "svg")


def design_limits(d: Design) -> Any:
    """What a design's G-code may do (``fabrication.check.Limits``), from its
    settings: cut inside the plate (less half a groove, as the tool centre is
    checked), every cut in X/Y at the groove's depth, rapids only at the safe
    height, feed moves between the surface and the safe height (hops) no longer
    than the longest hop nor lower than the hop height, feeds, spindle and
    laser power as set. A tip in a spring holder cuts at its preload below the
    touch-off, and no feed move in X/Y that is not such a cut runs below its
    lift (there the tip drags on the plate). In mm whatever the program's
    units: the check reads a G20 program in mm."""
    from specholo.fabrication.check import Limits, Stock, tool_kind
    from specholo.fabrication.programs.program import GcodeOptions

    m = d.config.setup().machining
    width = d.config.cutter().section(d.config.depth_mm).width
    plate = d.plate if d.plate is not None else plate_rect(d.grooves, width, d.config)
    half = 0.5 * width
    stock = Stock(plate[0, 0] + half, plate[0, 1] + half, plate[1, 0] - half,
                  plate[1, 1] - half, d.config.stock_thickness)
    kind = tool_kind(d.config.tool, m.spindle)
    power = GcodeOptions(dialect="marlin").laser_power if kind == "laser" else m.spindle
    # a laser has no Z: no hops, and its depth is set by power and feed
    milled = kind != "laser"
    holder = d.config.holder_setup() if milled else None
    spring = holder is not None and holder.spring
    # the Z the cuts run at and the hop height, as the program has them
    depth, m = holder.program(d.config.depth_mm, m) if holder is not None \
        else (d.config.depth_mm, m)
    return Limits(stock, depth, m.safe_z, (min(m.feed, m.plunge),
                  max(m.feed, m.plunge)), (power, power), kind,
                  hop_max=m.hop_max if milled else None, hop=m.hop,
                  groove_depth=depth if milled else None,
                  holder="spring" if spring else "rigid", lift=m.hop if spring else None)


def flatness_line(grooves: Grooves, holder: Any) -> dict[str, str]:
    """The header line of a rigid holder's program saying how well the plate's Z
    must be known (``flatness``), or none: the grooves keep their glints cut
    within :data:`~specholo.jobs.flat.settings.DEPTH_ALLOWANCE` of their depth, and a
    rigid holder cuts at the Z it is given, so the plate's height over the
    grooves must be known that well: on a hobby machine, by probing it."""
    from specholo.fabrication.exporting import drawn_extent

    if holder is None or holder.spring:
        return {}
    (x0, y0), (x1, y1) = drawn_extent(grooves)

    def mm(v: float, up: bool) -> str:  # to 0.1 mm, outward
        return f"{(math.ceil(v * 10.0) if up else math.floor(v * 10.0)) / 10.0:.1f}"

    return {"flatness": f"the plate's Z must be known to {DEPTH_ALLOWANCE:g} mm over "
                        f"X{mm(x0, False)}..{mm(x1, True)} Y{mm(y0, False)}..{mm(y1, True)} "
                        "(the depth allowance): specholo probe, then specholo level"}


def check_written_gcode(path: str | os.PathLike[str], d: Design) -> Any:
    """The independent safety check of a design's G-code (:func:`design_limits`).

    Raises:
        SpecholoError: on any violation, in one line.
    """
    from specholo.fabrication.check import check_program

    return check_program(path, design_limits(d))


@dataclass(frozen=True)
class Written:
    """What :func:`write_design` did.

    Attributes:
        timings: seconds spent per output.
        machining: the machining estimate written to ``hologram.json``.
        plate: the plate the files name (its size is what the maker cuts).
    """

    timings: dict[str, float]
    machining: dict[str, Any]
    plate: Plate | None = None


def dump_design_json(info: dict[str, Any], fh: Any) -> None:
    """``hologram.json``: indented, but its stipples one to a line.

    json writes an indented file in pure Python (15 s for a million
    stipples); the stipples' list goes through its C encoder instead, the same
    values in the same order, a block at a time when they are
    :class:`StippleRows`.
    """
    stipples = info.get("stipples")
    if not stipples:
        json.dump({**info, "stipples": []} if isinstance(stipples, StippleRows) else info, fh,
                  indent=1)
        return
    mark = json.dumps("\x00stipples\x00")  # a string no JSON value of a design holds
    head, tail = json.dumps({**info, "stipples": json.loads(mark)}, indent=1).split(mark)
    fh.write(head)
    fh.write("[\n  ")
    blocks = stipples.blocks() if isinstance(stipples, StippleRows) else [stipples]
    for k, block in enumerate(blocks):
        fh.write(",\n  " if k else "")
        fh.write(json.dumps(block, separators=(", ", ": "))[1:-1].replace("}, {", "},\n  {"))
    fh.write("\n ]")
    fh.write(tail)


def program_options_of(config: DesignConfig) -> Any:
    """The program's dialect and units (``GcodeOptions``) a design's settings ask for."""
    from specholo.fabrication.programs.program import GcodeOptions

    return GcodeOptions(dialect=config.dialect,  # type: ignore[arg-type]
                        units=config.units)  # type: ignore[arg-type]


def machining_estimate(config: DesignConfig, grooves: Grooves) -> tuple[Any, Any, Any]:
    """How long the program of ``grooves`` (in cutting order) takes: (the tip's
    ``Holder`` or None for a laser, the machining it runs with, the
    ``TimeEstimate``), timed as the program runs: a spring holder lowers from
    its lift to its preload and lifts back on every stroke (``Holder.program``,
    as the writer), and a mill's program waits after starting its spindle."""
    from specholo.fabrication.programs.timing import estimate_time

    setup = config.setup()
    options = program_options_of(config)
    laser = config.dialect == "marlin"
    holder = None if laser else config.holder_setup()
    depth, machining = holder.program(config.depth_mm, setup.machining) \
        if holder is not None else (config.depth_mm, setup.machining)
    estimate = estimate_time(grooves, depth, machining, laser=laser,
                             dwell=options.dwell if options.mill and setup.machining.spindle > 0
                             else 0.0, machine=config.profile)
    return holder, machining, estimate


def write_design(d: Design, out: str | os.PathLike[str],
                 formats: tuple[str, ...] = DEFAULT_FORMATS,
                 command: list[str] | None = None,
                 inputs: Iterable[str | os.PathLike[str] | None] = ()) -> Written:
    """Write every output of a design into ``out`` (all or nothing).

    Every file but ``run.json`` is the same byte for byte for the same model,
    settings and software; ``run.json`` records this run (see :func:`run_record`).
    Grooves of over a GB (:data:`~specholo.fabrication.programs.order.IN_PLACE_BYTES`)
    are put in cutting order in place: ``d.grooves`` is then in that order.

    Args:
        d: the design.
        out: output folder.
        formats: fabrication files to write, from :data:`FORMATS`.
        command: the command line, for ``run.json`` (default ``sys.argv``).
        inputs: the model and config files, which ``out`` must not hold as
            files a design writes (:func:`specholo.folders.publish`).

    Returns:
        Seconds spent per output, and the machining estimate.
    """
    from specholo.fabrication.drawings.svg import write_svg
    from specholo.fabrication.exporting import check_grooves
    from specholo.fabrication.programs.gcode import write_gcode
    from specholo.fabrication.programs.order import order_paths
    from specholo.folders import check_out
    from specholo.preview.preview import render_preview
    from specholo.scene.stippling import check_disk
    from specholo.staging import stage_design

    check_formats(formats, d.config.method)
    inputs = list(inputs)
    check_out(out, inputs)  # before the ordering and the estimate
    check_disk(len(d.points), out)
    check_grooves(d.grooves)  # e.g. grooves beyond any machine, before ordering them
    setup = d.config.setup()
    timings: dict[str, float] = {}
    grooves = d.grooves
    if d.config.order:
        t0 = time.perf_counter()
        # Grooves of over a GB are put in order in place, through a scratch file
        # beside the output, so that memory never holds two copies of them.
        near = Path(out).absolute().parent
        while not near.is_dir() and near != near.parent:
            near = near.parent
        grooves, order_stats = order_paths(d.grooves, scratch=near)
        d = dataclasses.replace(d, grooves=grooves)
        timings["ordering"] = time.perf_counter() - t0
    info = hologram_json(d)
    options = program_options_of(d.config)
    holder, est_machining, estimate = machining_estimate(d.config, grooves)
    info["machining"] = {
        "dialect": d.config.dialect, "units": d.config.units,
        "estimated_hours": estimate.total_s / 3600.0,
        "cutting_hours": estimate.cutting_s / 3600.0, "rapid_hours": estimate.rapid_s / 3600.0,
        "plunge_hours": estimate.plunge_s / 3600.0, "hop_hours": estimate.hop_s / 3600.0,
        "hops": estimate.hops, "stipples_per_second": estimate.stipples_per_s,
    }
    if holder is not None:
        info["machining"]["holder"] = holder.kind
        if holder.spring:
            info["machining"]["preload_mm"] = holder.preload
            info["machining"]["spring_lift_mm"] = est_machining.hop
    profile = d.config.profile
    if profile is not None:  # the machine timed on, and where its figures come from
        info["machining"].update({
            "machine": {"name": profile.name, "title": profile.title, "kind": profile.kind,
                        "source": profile.source},
            "lift_hours": estimate.lift_s / 3600.0, "delay_hours": estimate.delay_s / 3600.0})
    if d.config.order:
        info["machining"]["travel_unordered_mm"] = order_stats.travel_before_mm
        info["machining"]["travel_mm"] = order_stats.travel_after_mm
    width = d.config.cutter().section(d.config.depth_mm).width
    plate = Plate.from_corners(d.plate if d.plate is not None else
                               plate_rect(d.grooves, width, d.config),
                               d.config.stock_thickness)
    with stage_design(out, inputs, kind="flat") as stage:
        tmp = stage.path
        if "gcode" in formats:
            t0 = time.perf_counter()
            path = tmp / "hologram.gcode"
            write_gcode(path, grooves, setup.tool, setup.machining,
                        header={"design": d.config.method, "stipples": str(len(d.points)),
                                "cutter": d.config.cutter().describe(),
                                **flatness_line(grooves, holder),
                                # the limits `specholo check FILE` checks it against, mm
                                **design_limits(d).header()},
                        options=options, depth=d.config.depth_mm, plate=plate,
                        width=width,
                        drawings=tuple(f.upper() for f in ("svg", "dxf") if f in formats),
                        holder=holder)
            timings["gcode"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            safety = stage.check(path.name, design_limits(d))
            info["machining"]["safety_check"] = {"moves": safety.moves, "violations": 0}
            timings["gcode check"] = time.perf_counter() - t0
        if "svg" in formats:
            t0 = time.perf_counter()
            write_svg(tmp / "hologram.svg", grooves, setup.tool, plate=plate,
                      cut=(d.config.depth_mm, width))
            timings["svg"] = time.perf_counter() - t0
        if "dxf" in formats:
            from specholo.fabrication.drawings.dxf import write_dxf  # ezdxf: only when asked for

            t0 = time.perf_counter()
            write_dxf(tmp / "hologram.dxf", grooves, setup.tool, plate=plate,
                      cut=(d.config.depth_mm, width))
            timings["dxf"] = time.perf_counter() - t0
        if "pdf" in formats:
            # matplotlib's PDF: an arc design's compass pattern, else its strokes
            from specholo.fabrication.drawings.pattern import write_pattern
            from specholo.fabrication.drawings.stroke_pattern import write_stroke_pattern

            t0 = time.perf_counter()
            write = write_pattern if d.config.method == "arc" else write_stroke_pattern
            write(tmp / "pattern.pdf", grooves)
            timings["pdf"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        stage.save_grooves(d.grooves)
        stage.save_arrays("stipples.npz", points=d.points,
                          normals=d.normals if d.normals is not None else np.zeros((0, 3)))
        if d.model.mesh is not None:
            stage.save_model(d.model.mesh)
        stage.save_record("flat", info, dump=dump_design_json)
        timings["data"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        render_preview(d.grooves, setup, tmp / "preview.png",
                       plate=np.array([[plate.x0, plate.y0], [plate.x1, plate.y1]]))
        timings["preview"] = time.perf_counter() - t0
        with atomic_open(tmp / "run.json") as fh:
            json.dump(run_record(d.config, command, {"design": d.timings, "writing": timings}),
                      fh, indent=1)
    return Written(timings, info["machining"], plate)


def write_paper_pattern(folder: str | os.PathLike[str]) -> Path:
    """Write a design folder's printable pattern (``pattern.pdf``) from the folder,
    atomically, as ``--formats pdf`` writes it with the design: an arc design's
    compass pattern, else its strokes. Returns its path."""
    from specholo.fabrication.drawings.pattern import write_pattern
    from specholo.fabrication.drawings.stroke_pattern import write_stroke_pattern

    loaded = load_design(folder)
    path = Path(folder) / "pattern.pdf"
    write = write_pattern if loaded.config.method == "arc" else write_stroke_pattern
    write(path, loaded.grooves)
    return path


@dataclass
class Loaded:
    """A design read back from its output folder."""

    config: DesignConfig
    points: np.ndarray
    normals: np.ndarray | None
    grooves: Grooves
    mesh: Any
    thinned: int = 0  # stipples the design left uncut (thinning)
    plate: np.ndarray | None = None  # (2, 2) the plate's corners the files name, mm


def load_design(folder: str | os.PathLike[str], from_gcode: bool = False) -> Loaded:
    """Read a design folder written by :func:`write_design`.

    Args:
        folder: the output folder.
        from_gcode: read the grooves from ``hologram.gcode`` (the file that will be
            cut) instead of ``grooves.npz``.
    """
    from specholo.scene.loading import read_mesh

    folder = Path(folder)
    info = design_json(folder)
    if info.get("design") in ("composition", "conforming"):
        raise SpecholoError(f"{folder} holds a composed design (specholo compose): verify "
                            "reads it, and its pictures are preview.png and preview.gif")
    settings = info.get("settings")
    if info.get("design") == "ridged" or (isinstance(settings, dict)
                                          and settings.get("method") == "ridged"):
        raise SpecholoError(f"{folder} holds a ridged design (a height field, no "
                            "grooves): render, verify and view read it")
    config = settings_of(folder, info, DesignConfig.from_saved)
    points, normals = load_stipples(folder / "stipples.npz")
    if from_gcode:
        from specholo.fabrication.programs.gcode_reader import read_gcode

        grooves = read_gcode(folder / "hologram.gcode")
        grooves.validate(len(points), str(folder / "hologram.gcode"))
    else:
        grooves = Grooves.load(folder / "grooves.npz", len(points))
    # A model.ply that exists is read (or refused): skipping one that cannot be
    # read would verify without the occlusion the design had.
    mesh = read_mesh(folder / "model.ply") if (folder / "model.ply").exists() else None
    stats = info.get("stats")
    thinned = stats.get("thinned_stipples") if isinstance(stats, dict) else None
    return Loaded(config, points, normals, grooves, mesh,
                  len(thinned) if isinstance(thinned, list) else 0, plate_of(info))


def plate_of(info: dict[str, Any]) -> np.ndarray | None:
    """The plate's corners (2, 2) a hologram.json names, mm; None where it names
    none or a malformed one (an older folder: pictures then frame the grooves)."""
    plate = info.get("plate")
    corners = plate.get("plate_mm") if isinstance(plate, dict) else None
    try:
        got = np.asarray(corners, dtype=float)
    except (TypeError, ValueError):
        return None
    if got.shape != (2, 2) or not np.isfinite(got).all() or not (got[0] < got[1]).all():
        return None
    return got


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


def verify_streak_design(loaded: Loaded, max_step_deg: float, spread: Spread,
                         cut: bool = False) -> tuple[list[Any], list[Any] | None]:
    """The stereo verification with each glint a streak under ``spread``
    (:func:`~specholo.simulation.streak_verify.verify_streaks_both`): on the
    ideal grooves and, with ``cut``, on the plate as cut, from the same streaks."""
    from specholo.simulation.streak_verify import verify_streaks_both
    from specholo.simulation.verify import view_azimuths

    setup = loaded.config.setup()
    az = view_azimuths(setup.viewer.half_range, math.radians(max_step_deg))
    as_cut = (loaded.config.cutter(), loaded.config.depth_mm) if cut else None
    ideal, cut_reports = verify_streaks_both(loaded.grooves, loaded.points, setup, spread,
                                             _visibility(loaded), az, as_cut)
    return list(ideal), None if cut_reports is None else list(cut_reports)


#: How ``verify --cut`` finds what the cutting leaves (:func:`cut_method`).
CUT_METHODS = ("survival", "field")
#: Height-field samples across a tool radius when no spacing is given: the
#: wall's normal turns by spacing / R from one sample to the next, so a finer
#: tip needs finer samples (at 0.02 mm a 0.025 mm tip's groove is one sample wide).
SAMPLES_PER_RADIUS = 5
#: Coarsest height-field sample spacing when none is given, mm.
MAX_DEFAULT_RESOLUTION = 0.02


def default_resolution(config: DesignConfig) -> float:
    """Height-field sample spacing for a design when none is given, mm: the
    tool's (round model's) radius over :data:`SAMPLES_PER_RADIUS`, to the
    micrometre below, at most :data:`MAX_DEFAULT_RESOLUTION`."""
    radius = config.setup().tool.radius
    return max(0.001, min(MAX_DEFAULT_RESOLUTION,
                          math.floor(radius / SAMPLES_PER_RADIUS * 1000.0) / 1000.0))


def cut_method(method: str | None, resolution: float | None, stl: object | None) -> str:
    """How to check the plate as cut: ``survival`` (exact, from the grooves) unless
    the height field is asked for, by name or by its own settings (a resolution,
    an STL of the cut plate).

    Raises:
        SpecholoError: a method not in :data:`CUT_METHODS`, or the survival test
            with a height field's setting.
    """
    if method is None:
        return "field" if resolution is not None or stl is not None else "survival"
    if method not in CUT_METHODS:
        raise SpecholoError(f"cut method must be one of {', '.join(CUT_METHODS)}, got "
                            f"{method!r}")
    if method == "survival" and (resolution is not None or stl is not None):
        raise SpecholoError("--resolution and --stl are the height field's: use --cut-method "
                            "field, or leave them out for the exact survival test")
    return method


def verify_cut_design(loaded: Loaded, max_step_deg: float = 5.0,
                      resolution: float | None = None,
                      stl: str | os.PathLike[str] | None = None,
                      method: str | None = None) -> tuple[list[Any], Any]:
    """Verify the design on the plate as cut.

    By default (``survival``) each eye's designed glints are kept where no other
    path's cut removes them (:mod:`specholo.simulation.survival`): exact, with
    no resolution to converge. ``field`` cuts the grooves into a simulated
    height field and finds the glints on that surface (:mod:`specholo.simulation.cut`).

    Args:
        loaded: the design (grooves read back from its G-code, usually).
        max_step_deg: largest azimuth step between eye pairs, degrees.
        resolution: height-field sample spacing, mm (default :func:`default_resolution`).
        stl: also write the cut plate here as a watertight STL (height field only).
        method: ``survival`` or ``field`` (default: see :func:`cut_method`).

    Returns:
        The per-azimuth reports on the cut plate, and the height field (None
        for the survival test).
    """
    from specholo.simulation.verify import view_azimuths

    method = cut_method(method, resolution, stl)
    setup = loaded.config.setup()
    az = view_azimuths(setup.viewer.half_range, math.radians(max_step_deg))
    if method == "survival":
        from specholo.simulation.survival import verify_as_cut

        as_cut = verify_as_cut(loaded.grooves, loaded.points, setup, loaded.config.cutter(),
                               loaded.config.depth_mm, _visibility(loaded), az)
        return as_cut.reports, None
    from specholo.simulation.cut import cut_design, verify_cut, write_stl

    resolution = default_resolution(loaded.config) if resolution is None else resolution
    if not (math.isfinite(resolution) and 0.001 <= resolution <= 1.0):
        raise SpecholoError(f"resolution must be in [0.001, 1] mm, got {resolution}")
    field = cut_design(loaded, resolution)
    if stl is not None:
        write_stl(stl, field, loaded.config.stock_thickness)
    return verify_cut(field, loaded.points, setup, _visibility(loaded), az), field

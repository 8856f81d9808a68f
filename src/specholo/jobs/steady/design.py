"""The whole job for a still viewer under a sun that moves a little: a model in;
scoops, G-code and a verification over the light's range out.

See :mod:`specholo.toolpaths.steady` for the optics and the README's "A steady
image under a moving light" for the figures.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.plate import STOCK_THICKNESS
from specholo.scene.pose import Pose
from specholo.setup import Machining, Tool
from specholo.simulation.steady import SteadyReport, verify_steady
from specholo.toolpaths.steady import SteadyDesign, SteadySetup, design_steady, tool_tips

#: The setup's angles, radians inside, saved in degrees.
STEADY_ANGLES = ("light_elevation", "light_sweep")
#: The names older folders saved the light's angles under.
LEGACY_ANGLES = {"elevation_deg": "light_elevation_deg", "half_range_deg": "light_sweep_deg"}


@dataclass(frozen=True)
class SteadyConfig:
    """Placement, stippling, optics and tool of a steady-image hologram.

    Attributes:
        size: largest side of the model's bounding box, mm.
        center_z: depth of the box centre, mm (negative: behind the plate).
        stipples: number of stipples (those hidden from either eye are dropped).
        seed: stippling seed.
        pose: how the model is turned and moved onto the plate.
        shape: "scoop" (steady) or "flat" (plain grooves, for comparison).
        setup: the viewer and the light's range.
        tool: the ball-end cutter.
        machining: feeds and heights.
        plate_width, plate_height: the plate, mm, centred on the origin (both or
            neither); without them the plate fitted to the cuts.
        fit: ``size`` is the largest whose cuts lie on the plate, 5 mm in from
            its edges (:func:`design_steady_sized`).
        stock_thickness: the blank's thickness, mm: no cut may reach its back.
        dialect: the program's G-code dialect, ``"grbl"`` or ``"linuxcnc"`` (a
            laser cannot cut it).
        units: the program's units, ``"mm"`` or ``"inch"``.
    """

    size: float = 40.0
    center_z: float = -20.0
    stipples: int = 300
    seed: int = 0
    shape: str = "scoop"
    pose: Pose = field(default_factory=Pose)
    setup: SteadySetup = field(default_factory=SteadySetup)
    tool: Tool = field(default_factory=lambda: Tool(0.05, 0.02))
    machining: Machining = field(default_factory=Machining)
    # after the rest: folders written before plates were settings lack them
    plate_width: float | None = None
    plate_height: float | None = None
    fit: bool = False
    stock_thickness: float = STOCK_THICKNESS
    # after the rest: folders written before they were settings lack them (GRBL in mm)
    dialect: str = "grbl"
    units: str = "mm"

    def __post_init__(self) -> None:
        from specholo.fabrication.plate import check_plate_options
        from specholo.fabrication.programs.program import check_program_options
        from specholo.folder import check_job_bounds

        check_plate_options(self.plate_width, self.plate_height, self.fit)
        check_job_bounds(self)
        check_program_options(self.dialect, self.units)
        if not 1 <= self.stipples <= 200_000:
            raise SpecholoError(f"stipples must be in [1, 200000], got {self.stipples}")

    @classmethod
    def from_options(cls, size: float = 40.0, center_z: float = -20.0, stipples: int = 300,
                     seed: int = 0, view_distance: float = 600.0, ipd: float = 64.0,
                     light_elevation: float = 45.0, light_sweep: float = 5.0,
                     shape: str = "scoop", tool_radius: float = 0.05, depth: float = 0.02,
                     pose: Pose | None = None, plate_width: float | None = None,
                     plate_height: float | None = None, fit: bool = False,
                     stock_thickness: float = STOCK_THICKNESS, dialect: str = "grbl",
                     units: str = "mm") -> SteadyConfig:
        """The settings from the command's names and units (degrees, converted here once)."""
        setup = SteadySetup(distance=view_distance, ipd=ipd,
                            light_elevation=math.radians(light_elevation),
                            light_sweep=math.radians(light_sweep))
        return cls(size=size, center_z=center_z, stipples=stipples, seed=seed,
                   pose=pose or Pose(), shape=shape, setup=setup, tool=Tool(tool_radius, depth),
                   plate_width=plate_width, plate_height=plate_height, fit=fit,
                   stock_thickness=stock_thickness, dialect=dialect, units=units)

    @property
    def plate(self) -> tuple[float, float] | None:
        """The given plate's width and height, mm, or None."""
        if self.plate_width is None or self.plate_height is None:
            return None
        return (float(self.plate_width), float(self.plate_height))

    def settings(self) -> dict[str, Any]:
        """The settings as ``hologram.json`` records them: by ``specholo steady``'s
        option names, in its units (mm, degrees), as every kind's."""
        from specholo.folder import shared_settings

        s = self.setup
        return {**shared_settings(self), "shape": self.shape, "view_distance": s.distance,
                "eye_height": s.height, "ipd": s.ipd,
                "light_elevation": math.degrees(s.light_elevation),
                "light_sweep": math.degrees(s.light_sweep), "samples": s.samples}

    @classmethod
    def from_settings(cls, saved: Any) -> SteadyConfig:
        """The settings :meth:`settings` recorded (inside
        :func:`~specholo.readback.settings_from`)."""
        from specholo.folder import from_settings

        config, machining, own = from_settings(saved, cls.from_options, ("eye_height", "samples"))
        if "eye_height" in own:
            own["height"] = own.pop("eye_height")
        return dataclasses.replace(config, machining=machining,
                                   setup=dataclasses.replace(config.setup, **own))


@dataclass(frozen=True)
class Stippling:
    """What became of the stipples asked for before any was given its scoops
    (those left out after, for want of a scoop, are ``SteadyDesign.dropped``).

    Attributes:
        asked: stipples asked for (``SteadyConfig.stipples``).
        placed: stipples placed on the model (a point cloud gives no more than
            its distinct points).
        hidden_both: placed stipples hidden from both eyes (facing away, or
            behind another part of the model).
        hidden_one: placed stipples hidden from one eye only: a stipple needs a
            scoop for each eye, so these are left out too.
    """

    asked: int
    placed: int
    hidden_both: int
    hidden_one: int

    def as_dict(self) -> dict[str, int]:
        """As ``hologram.json`` records it."""
        return {"asked": self.asked, "placed": self.placed, "hidden_both_eyes": self.hidden_both,
                "hidden_one_eye": self.hidden_one}


def design_steady_job(model_path: str | os.PathLike[str], config: SteadyConfig,
                      rng: np.random.Generator | None = None) -> SteadyDesign:
    """Stipple the model, keep the stipples both eyes see, and design their cuts
    (at ``config.size``: :func:`design_steady_sized` fits it to the plate)."""
    from specholo.scene.loading import load_model

    return _design_loaded(load_model(model_path), config, rng)[0]


def design_steady_sized(model_path: str | os.PathLike[str], config: SteadyConfig,
                        rng: np.random.Generator | None = None
                        ) -> tuple[SteadyDesign, SteadyConfig, Stippling]:
    """:func:`design_steady_job`, and with ``config.fit`` first the size: the
    largest whose cuts lie on the given plate, 5 mm in from its edges.

    The viewer stands still, so the cuts' crossings are those of the two eyes
    straight in front (the light's motion slides no glint: that is what the
    scoops are for). A scoop runs a few mm along the plate past its crossing,
    which no formula gives beforehand: :func:`specholo.scene.fit.fit_design`
    measures it on a first design and fits again.

    Returns:
        The design, its settings (whose size is the fitted one with ``fit``) and
        what became of the stipples asked for.
    """
    import copy
    import dataclasses

    from specholo.fabrication.plate import PLATE_MARGIN
    from specholo.scene.fit import (
        crossing_extent_from,
        fit_design,
        fit_size_from,
        plate_room,
        round_size,
    )
    from specholo.scene.loading import load_model
    from specholo.scene.placement import place

    loaded = load_model(model_path)
    plate = config.plate
    if not config.fit or plate is None:
        design, stippling = _design_loaded(loaded, config, rng)
        return design, config, stippling
    eyes = config.setup.eyes()
    unit = place(loaded, 1.0, 0.0, config.pose.rotation()).points  # size 1 about its box centre
    center = np.array([*config.pose.offset, config.center_z])
    half = 0.5 * config.tool.width

    def size_with(reach: np.ndarray) -> float:
        # the design refuses stipples this near the eyes (design_steady)
        return round_size(fit_size_from(unit, center, plate, eyes, reach, PLATE_MARGIN,
                                        0.9 * config.setup.distance))

    stippled: dict[float, Stippling] = {}  # by size: the kept design's is said with it

    def design_at(size: float) -> SteadyDesign:
        # each try from the same stippling seed: the kept design is the one a
        # design at the recorded size gives
        fresh = copy.deepcopy(rng) if rng is not None else None
        design, stippled[size] = _design_loaded(loaded, dataclasses.replace(config, size=size),
                                                fresh)
        return design

    def spread(d: SteadyDesign) -> tuple[np.ndarray, np.ndarray]:
        if not len(d.points):
            return np.zeros(2), np.zeros(2)
        cuts = np.abs(tool_tips(d, config.tool)[:, :2]).max(axis=0) + half
        return cuts, np.abs(crossing_extent_from(d.points, eyes)).max(axis=0)

    size, design = fit_design(size_with, design_at, spread, plate_room(plate, PLATE_MARGIN),
                              np.array([half, half]))
    return design, dataclasses.replace(config, size=size), stippled[size]


def _design_loaded(loaded: Any, config: SteadyConfig, rng: np.random.Generator | None
                   ) -> tuple[SteadyDesign, Stippling]:
    """:func:`design_steady_job` for a model already loaded, and what became of
    the stipples asked for on the way."""
    from specholo.scene.placement import place
    from specholo.scene.stippling import stipple
    from specholo.visibility.occlusion import visible

    model = place(loaded, config.size, config.center_z, config.pose.rotation(),
                  config.pose.offset)
    rng = rng if rng is not None else np.random.default_rng(config.seed)
    st = stipple(model, rng, count=config.stipples)
    seen = np.zeros(len(st.points), dtype=np.int64)  # by how many eyes
    for eye in config.setup.eyes():
        seen += visible(model.mesh, st.points, st.normals, eye)
    keep = seen == 2
    if not keep.any():
        raise SpecholoError("no stipple is visible to both eyes: nothing to cut")
    stippling = Stippling(config.stipples, len(st.points), int(np.sum(seen == 0)),
                          int(np.sum(seen == 1)))
    return design_steady(st.points[keep], config.setup, config.tool, config.shape), stippling


def light_steps(setup: SteadySetup, step_deg: float) -> np.ndarray:
    """Light elevations (degrees) over the range, every ``step_deg``, ends included."""
    mid, half = math.degrees(setup.light_elevation), math.degrees(setup.light_sweep)
    k = max(int(round(2 * half / step_deg)), 1)
    return np.linspace(mid - half, mid + half, k + 1)


def summarise(reports: list[SteadyReport]) -> dict[str, float]:
    """Worst figures over the light's range."""
    def worst(key: str) -> float:
        vals = [getattr(r, key) for r in reports if not math.isnan(getattr(r, key))]
        return max(vals) if vals else math.nan

    return {"worst_p95_mm": worst("p95_mm"), "worst_depth_p95_mm": worst("depth_p95_mm"),
            "worst_drift_p95_mm": worst("drift_p95_mm"),
            "lowest_visibility": min((r.visibility for r in reports), default=math.nan),
            "stray": int(sum(r.stray for r in reports))}


def steady_plate(design: SteadyDesign, config: SteadyConfig) -> Any:
    """The plate (``fabrication.plate.Plate``) the program names: the one given,
    or the one fitted to the cuts' tool tips with a 5 mm border.

    Raises:
        SpecholoError: a given plate is smaller than the cuts.
    """
    from specholo.fabrication.plate import job_plate

    tips = tool_tips(design, config.tool)[:, :2] if len(design.centres) else np.zeros((1, 2))
    return job_plate(np.stack([tips.min(axis=0), tips.max(axis=0)]), config.tool.width,
                     config.plate)


def steady_machining(design: SteadyDesign, config: SteadyConfig) -> dict[str, float]:
    """How long :func:`write_path_gcode`'s program takes, as a flat design's
    ``machining`` figures (hours; :func:`specholo.fabrication.programs.timing.describe_machining`
    words them), from the same timing model
    (:func:`~specholo.fabrication.programs.timing.estimate_time`).

    The program rapids to each cut's start at the safe height, plunges to it,
    feeds along the cut in X, Y and Z and retracts: never a hop. A scoop starts
    and ends at the surface (it rises out of the plate at both ends), a flat
    groove at its depth: the plunges and retracts run the safe height and the
    cuts' mean depth at their starts; the travel between cuts runs between their
    real ends. Along a cut the planner sees only the lengths of
    its moves and the turns between them, so the cut is timed unrolled into
    the plane with the same lengths and turns (its Z moves counted, not dropped).
    """
    import dataclasses

    from specholo.fabrication.programs.timing import estimate_time
    from specholo.toolpaths.grooves import Grooves

    n = design.n_cuts
    if n == 0:
        return {"estimated_hours": 0.0, "cutting_hours": 0.0, "rapid_hours": 0.0,
                "plunge_hours": 0.0, "hop_hours": 0.0, "hops": 0, "stipples_per_second": 0.0}
    machining = dataclasses.replace(config.machining, hop_max=0.0)
    tips = tool_tips(design, config.tool)
    offsets = np.asarray(design.offsets, dtype=np.int64)
    ids = np.asarray(design.stipple, dtype=np.int64)
    ends = np.stack([tips[offsets[:-1], :2], tips[offsets[1:] - 1, :2]], axis=1).reshape(-1, 2)
    depth = max(0.0, -float(np.mean(tips[offsets[:-1], 2])))
    travel = estimate_time(Grooves(ends, np.zeros(2 * n), 2 * np.arange(n + 1, dtype=np.int64),
                                   ids), depth, machining)
    cutting = estimate_time(Grooves(_unrolled(tips, offsets), np.zeros(len(tips)), offsets, ids),
                            0.0, machining).cutting_s
    total = travel.rapid_s + travel.plunge_s + cutting
    return {"estimated_hours": total / 3600.0, "cutting_hours": cutting / 3600.0,
            "rapid_hours": travel.rapid_s / 3600.0, "plunge_hours": travel.plunge_s / 3600.0,
            "hop_hours": 0.0, "hops": 0,
            "stipples_per_second": len(design.points) / total if total > 0 else 0.0}


def _unrolled(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(m, 2) paths in the plane whose moves have the lengths of the 3D paths
    ``points`` (m, 3) (path j is ``points[offsets[j]:offsets[j + 1]]``) and turn
    by the same angles between them."""
    step = np.diff(points, axis=0)
    length = np.linalg.norm(step, axis=1)
    path = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))
    within = path[1:] == path[:-1]  # the moves inside a path, not those between two
    unit = step / np.where(length > 0, length, 1.0)[:, None]
    turn = np.zeros(len(step))
    turn[1:] = np.arccos(np.clip(np.sum(unit[1:] * unit[:-1], axis=1), -1.0, 1.0))
    turn[1:][~within[:-1]] = 0.0  # a path's first move turns from nothing
    turn[~within] = 0.0
    heading = np.cumsum(turn)
    first = offsets[:-1][path[:-1]]  # each move's path's first move
    heading -= heading[np.minimum(first, len(step) - 1)]
    flat = np.where(within, length, 0.0)[:, None] * np.stack([np.cos(heading),
                                                              np.sin(heading)], axis=1)
    return np.concatenate([np.zeros((1, 2)), np.cumsum(flat, axis=0)])


def write_path_gcode(path: Path, design: SteadyDesign, tool: Tool, machining: Machining,
                     header: dict[str, str], plate: Any = None, options: Any = None) -> int:
    """G-code for the cuts, atomically, through the one emitter
    (``fabrication.programs.program.Emitter``): a vertical ball-end tool whose tip follows
    each cut's centre path R lower, in X, Y and Z; ``plate``
    (``fabrication.plate.Plate``), if given, named in the header: its size,
    thickness and corners and how to set the origin (no registration marks: a
    steady design draws no SVG or DXF to carry them); ``options``
    (``fabrication.programs.program.GcodeOptions``) the dialect and units, a mill's
    (default GRBL in mm). Returns the number of lines."""
    from specholo.fabrication.atomic import atomic_open
    from specholo.fabrication.programs.program import Emitter, GcodeOptions

    em = Emitter(options or GcodeOptions(), machining)
    em.require_mill("a steady design's program")
    tips = tool_tips(design, tool)
    lines = em.head("specholo: scoops for a steady image under a moving light", (), header,
                    plate, None)
    for c in range(design.n_cuts):
        tip = tips[design.offsets[c]:design.offsets[c + 1]]
        lines += em.polyline(tip, f"stipple {int(design.stipple[c])} eye "
                                  f"{'LR'[int(design.eye[c])]}")
    lines += em.tail()
    with atomic_open(path) as fh:
        fh.write("\n".join(lines) + "\n")
    return len(lines)


def steady_limits(design: SteadyDesign, config: SteadyConfig) -> Any:
    """What a steady design's G-code may do (``fabrication.check.Limits``), from its
    settings: the tip inside the cuts' extent plus a blank border (within the plate,
    given or fitted to the cuts, :func:`steady_plate`), no deeper than the depth, rapids
    at the safe height, feeds and spindle as set."""
    from specholo.fabrication.check import Limits, Stock, tool_kind
    from specholo.fabrication.plate import PLATE_MARGIN

    m, tool = config.machining, config.tool
    tips = tool_tips(design, tool)[:, :2] if len(design.centres) else np.zeros((1, 2))
    (x0, y0), (x1, y1) = tips.min(axis=0) - PLATE_MARGIN, tips.max(axis=0) + PLATE_MARGIN
    return Limits(Stock(float(x0), float(y0), float(x1), float(y1), config.stock_thickness),
                  tool.depth,
                  m.safe_z, (min(m.feed, m.plunge), max(m.feed, m.plunge)),
                  (m.spindle, m.spindle), tool_kind("ball", m.spindle))


def write_steady(design: SteadyDesign, config: SteadyConfig, out: str | os.PathLike[str],
                 step_deg: float = 1.0, inputs: Iterable[str | os.PathLike[str] | None] = (),
                 stippling: Stippling | None = None) -> dict[str, Any]:
    """Write the folder atomically: hologram.gcode, stipples.npz, verify.json,
    preview.png and hologram.json. Returns the verification summary. ``inputs`` are the model
    file, which ``out`` must not hold as a file a design writes. The G-code is
    read back by the safety check (:func:`steady_limits`) before anything is kept.
    hologram.json records the program's machining time (:func:`steady_machining`)
    and, given ``stippling``, what became of the stipples asked for."""
    from specholo.fabrication.programs.program import program_options
    from specholo.folder import json_ready, stock_line
    from specholo.folders import check_out
    from specholo.preview.steady import steady_preview
    from specholo.staging import stage_design

    inputs = list(inputs)
    check_out(out, inputs)  # before the verification
    plate = steady_plate(design, config)  # a plate too small is refused before it too
    reports = verify_steady(design, config.tool, light_steps(config.setup, step_deg))
    summary = summarise(reports)
    if design.n_cuts == 0:
        raise SpecholoError("no stipple can be given a scoop: nothing to cut")
    with stage_design(out, inputs, kind="steady") as stage:
        tmp = stage.path
        limits = steady_limits(design, config)
        lines = write_path_gcode(tmp / "hologram.gcode", design, config.tool, config.machining,
                                 {"design": f"{design.shape}s, one per stipple and eye",
                                  "tool": f"ball end, round tip radius "
                                          f"{config.tool.radius:g} mm",
                                  "depth": f"{config.tool.depth:g} mm at most: each cut "
                                           "rises out of the plate at its ends",
                                  "stock": stock_line(config),
                                  **limits.header()}, plate=plate,
                                 options=program_options(config))
        safety = stage.check("hologram.gcode", limits)
        stage.save_arrays("stipples.npz", points=design.points, centres=design.centres,
                          offsets=design.offsets, stipple=design.stipple, eye=design.eye,
                          radius=design.radius, dropped=np.array(design.dropped))
        write_verification(reports, tmp, step_deg)
        steady_preview(design, config.tool, tmp / "preview.png")
        meta: dict[str, Any] = {
            "design": "steady", "settings": config.settings(), "cuts": design.n_cuts,
            "stipples": len(design.points), "stipples_dropped": design.dropped,
            "gcode_lines": lines, "verify": json_ready(summary),
            "machining": steady_machining(design, config),
            "plate_mm": plate.box.tolist(),
            "safety_check": {"moves": safety.moves, "violations": 0,
                             "deepest_cut_mm": safety.deepest},
            "scoop_radius_mm": {"median": float(np.median(design.radius))}
            if design.shape == "scoop" else None}
        if stippling is not None:
            meta["stippling"] = stippling.as_dict()
        stage.save_record("steady", meta)
    return summary


def write_verification(reports: list[SteadyReport], folder: Path, step_deg: float
                       ) -> dict[str, Any]:
    """Write ``verify.json`` atomically into ``folder``; returns the summary."""
    from specholo.folder import json_ready, row_json, write_verify_json

    summary = summarise(reports)
    write_verify_json(folder, "steady", step_deg, json_ready(summary), "elevations",
                      [row_json(r.as_dict()) for r in reports])
    return summary


def is_steady_folder(folder: str | os.PathLike[str]) -> bool:
    """True if ``folder`` holds a design written by :func:`write_steady`."""
    from specholo.folder import design_kind

    return design_kind(folder) == "steady"


def load_steady_folder(folder: str | os.PathLike[str]) -> tuple[SteadyDesign, SteadyConfig]:
    """Read a folder written by :func:`write_steady` back.

    Raises:
        SpecholoError: a file is unreadable, unlike what :func:`write_steady`
            writes, or the files disagree.
    """
    from specholo.folder import config_arguments
    from specholo.readback import (
        ArraySpec,
        check_offsets,
        load_arrays,
        read_json,
        settings_from,
        table,
        whole,
        within,
    )
    from specholo.toolpaths.grooves import MAX_COORDINATE

    folder = Path(folder)
    path = folder / "hologram.json"
    meta = table(read_json(path), str(path))
    with settings_from(path):
        if "settings" in meta:
            c = dict(table(meta["settings"], "settings"))
            for key in ("stipples", "seed", "samples"):
                if key in c:
                    whole(c[key], key)
        else:  # a folder written before every kind recorded its settings by option names
            saved = meta["config"]
            setup = saved.get("setup") if isinstance(saved, dict) else None
            if isinstance(setup, dict) and any(k in setup for k in LEGACY_ANGLES):
                # a folder written when the light's angles shared the viewer's names
                setup = {LEGACY_ANGLES.get(k, k): v for k, v in setup.items()}
                saved = {**saved, "setup": setup}
            c = config_arguments(saved, SteadySetup, STEADY_ANGLES,
                                 ("stipples", "seed", "samples"))
        if c.get("shape", "scoop") not in ("scoop", "flat"):
            raise SpecholoError(f"shape must be scoop or flat, got {str(c['shape'])[:40]!r}")
        config = (SteadyConfig.from_settings(c) if "settings" in meta
                  else SteadyConfig(**c))
    stipples = folder / "stipples.npz"
    a = load_arrays(stipples, {
        "points": ArraySpec((None, 3), finite=True), "centres": ArraySpec((None, 3), finite=True),
        "offsets": ArraySpec((None,), np.int64), "stipple": ArraySpec((None,), np.int64),
        "eye": ArraySpec((None,), np.int64), "radius": ArraySpec((None,)),
        "dropped": ArraySpec((), np.int64)})
    check_offsets(a["offsets"], len(a["centres"]), str(stipples))
    cuts = len(a["offsets"]) - 1
    n = len(a["points"])
    # The cuts index the stipples and the two eyes; a flat cut's radius is infinite.
    if any(len(a[k]) != cuts for k in ("stipple", "eye", "radius")) \
            or (cuts and not (within(a["stipple"], 0, n - 1) and within(a["eye"], 0, 1))) \
            or np.any(np.isnan(a["radius"])) or np.any(a["radius"] <= 0) \
            or int(a["dropped"]) < 0 or not within(a["points"], -MAX_COORDINATE, MAX_COORDINATE) \
            or not within(a["centres"], -MAX_COORDINATE, MAX_COORDINATE):
        raise SpecholoError(f"cannot read steady-image design in {folder}: files disagree")
    design = SteadyDesign(config.setup, a["points"], a["centres"], a["offsets"], a["stipple"],
                          a["eye"], a["radius"], config.shape, int(a["dropped"]))
    return design, config

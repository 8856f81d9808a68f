"""The whole job for a plate turning about its normal: a model in; closed grooves,
G-code, SVG, a verification over the turn and a preview out.

The scene turns with the plate, so a viewer standing still sees it turn rigidly
through 360 degrees. See :mod:`specholo.toolpaths.spinning` for the optics and
the README's "Rotating plates" for the figures.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.plate import STOCK_THICKNESS
from specholo.fabrication.programs.program import check_program_options, program_options
from specholo.folder import check_job_bounds, json_ready, row_json, stock_line
from specholo.scene.pose import Pose
from specholo.setup import Machining, Tool
from specholo.simulation.spinning import SpinReport, find_spin_glints, verify_spinning
from specholo.toolpaths.spinning import (
    RELIEF_ANGLE,
    SpinDesign,
    SpinSetup,
    design_spinning,
    fit_grooves,
    relief_grooves,
    rotate_z,
    vertex_angles,
)

if TYPE_CHECKING:
    pass

#: The setup's angles, radians inside, saved in degrees.
SPIN_ANGLES = ("elevation",)
#: The fit's own settings, which the command leaves at their defaults.
SPIN_FIT = ("harmonics", "angles", "samples")


#: The drawings a turning plate writes beside its programs (hologram.svg; no
#: DXF), which carry the plate's marks: the programs' headers name these alone.
SPIN_DRAWINGS = ("SVG",)




@dataclass(frozen=True)
class SpinConfig:
    """A turning-plate hologram: the model's placement, stippling, optics and tool.

    Attributes:
        size: largest side of the model's bounding box, mm.
        center_z: depth of the box centre, mm (0 straddles the plate).
        stipples: number of stipples.
        seed: stippling seed.
        pose: how the model is turned and moved onto the plate.
        occlusion: crop each groove to the plate angles where its point is not
            hidden by the model.
        turns: circuits of the view about the scene per plate turn. 1: the
            scene turns with the plate (closed grooves); 2 or more: the scene
            turns faster and the stipples slide over it (open grooves, see
            :mod:`specholo.toolpaths.sliding`), one model for all the circuits or
            one model per circuit.
        setup: the viewer, light and groove shape.
        tool: the ball-end cutter.
        machining: feeds and heights.
        plate_width, plate_height: the plate, mm, centred on the turning axis
            (both or neither); without them the plate fitted to the grooves.
        fit: ``size`` is the largest whose grooves lie on the plate, 5 mm in
            from its edges, for eyes all round the axis (:func:`design_spin`).
        stock_thickness: the blank's thickness, mm: no cut (the relief's
            included) may reach its back.
        dialect: the programs' G-code dialect, ``"grbl"`` or ``"linuxcnc"``
            (a laser cannot cut them).
        units: the programs' units, ``"mm"`` or ``"inch"``.
    """

    size: float = 40.0
    center_z: float = 0.0
    stipples: int = 800
    seed: int = 0
    occlusion: bool = True
    turns: int = 1
    pose: Pose = field(default_factory=Pose)
    setup: SpinSetup = field(default_factory=SpinSetup)
    tool: Tool = field(default_factory=Tool)
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

        check_plate_options(self.plate_width, self.plate_height, self.fit)
        check_job_bounds(self)
        check_program_options(self.dialect, self.units)
        if not 1 <= self.stipples <= 200_000:
            raise SpecholoError(f"stipples must be in [1, 200000], got {self.stipples}")
        if not 1 <= self.turns <= 8:
            raise SpecholoError(f"turns must be in [1, 8], got {self.turns}")

    @classmethod
    def from_options(cls, models: int = 1, size: float = 40.0, center_z: float = 0.0,
                     turns: int | None = None, stipples: int = 800, seed: int = 0,
                     view_distance: float = 600.0, view_elevation: float = 45.0,
                     ipd: float = 64.0, light_height: float | None = None, walls: str = "one",
                     occlusion: bool = True, tool_radius: float = 0.25, depth: float = 0.08,
                     pose: Pose | None = None, plate_width: float | None = None,
                     plate_height: float | None = None, fit: bool = False,
                     stock_thickness: float = STOCK_THICKNESS, dialect: str = "grbl",
                     units: str = "mm") -> SpinConfig:
        """The settings from the command's names and units (degrees, converted here
        once); ``turns`` defaults to the number of models."""
        setup = SpinSetup(distance=view_distance, elevation=math.radians(view_elevation),
                          ipd=ipd, light_height=light_height, walls=walls)
        return cls(size=size, center_z=center_z, stipples=stipples, seed=seed,
                   pose=pose or Pose(), occlusion=occlusion,
                   turns=models if turns is None else turns, setup=setup,
                   tool=Tool(tool_radius, depth), plate_width=plate_width,
                   plate_height=plate_height, fit=fit, stock_thickness=stock_thickness,
                   dialect=dialect, units=units)

    @property
    def plate(self) -> tuple[float, float] | None:
        """The given plate's width and height, mm, or None."""
        if self.plate_width is None or self.plate_height is None:
            return None
        return (float(self.plate_width), float(self.plate_height))

    def settings(self) -> dict[str, Any]:
        """The settings as ``hologram.json`` records them: by ``specholo spin``'s
        option names, in its units (mm, degrees), as every kind's."""
        from specholo.folder import shared_settings

        s = self.setup
        return {**shared_settings(self), "turns": self.turns, "occlusion": self.occlusion,
                "view_distance": s.distance, "view_elevation": math.degrees(s.elevation),
                "ipd": s.ipd, "light_height": s.light_height, "walls": s.walls,
                **{k: getattr(s, k) for k in SPIN_FIT}}

    @classmethod
    def from_settings(cls, saved: Any) -> SpinConfig:
        """The settings :meth:`settings` recorded (inside
        :func:`~specholo.readback.settings_from`)."""
        from specholo.folder import from_settings

        config, machining, fit = from_settings(saved, cls.from_options, SPIN_FIT)
        return dataclasses.replace(config, machining=machining,
                                   setup=dataclasses.replace(config.setup, **fit))


@dataclass(frozen=True)
class SpinPlate:
    """A designed turning-plate hologram and what is needed to check it.

    Attributes:
        config: the settings.
        design: the grooves.
        mesh: the placed model (None for a point cloud), which hides stipples.
        normals: (n, 3) the stipples' face normals, or None.
        keep: (n, samples) the groove vertices kept by the occlusion crop, or None.
    """

    config: SpinConfig
    design: SpinDesign
    mesh: Any
    normals: np.ndarray | None
    keep: np.ndarray | None = None


def shown_at(config: SpinConfig, mesh: Any, normals: np.ndarray | None, points: np.ndarray,
             phi: np.ndarray) -> np.ndarray:
    """(2, n, k) bool: stipple i (points (n, 3), their face normals) is not hidden
    by ``mesh`` from the left (0) or right (1) eye at plate angle phi_j (k,)."""
    from specholo.visibility.occlusion import visible

    n, k = len(points), len(phi)
    if mesh is None or not config.occlusion or n == 0:
        return np.ones((2, n, k), dtype=bool)
    pts = np.repeat(points, k, axis=0)
    nrm = None if normals is None else np.repeat(normals, k, axis=0)
    return np.stack([visible(mesh, pts, nrm, np.tile(e, (n, 1))).reshape(n, k)
                     for e in config.setup.eyes(phi)])


def design_spin(model_path: str | os.PathLike[str] | list[str | os.PathLike[str]],
                config: SpinConfig, rng: np.random.Generator | None = None) -> SpinPlate:
    """Stipple the model, crop to its visible views, and design the grooves.

    With ``config.turns`` > 1, ``model_path`` may list one model per circuit of
    the view; the stipples then slide over the turning scenes.

    With ``config.fit`` the size is first fitted to the plate: the largest whose
    grooves lie on it, 5 mm in from its edges. Over a turn the eyes go all round
    the axis, so the crossings are those of both eyes at every plate angle
    (:data:`FIT_STEP_DEG` apart); a closed groove is a curve fitted through
    them that strays a little past them, which
    :func:`specholo.scene.fit.fit_design` measures on a first design and fits
    again. The job's config then holds the fitted size.
    """
    from specholo.scene.loading import load_model

    paths = list(model_path) if isinstance(model_path, list | tuple) else [model_path]
    if config.turns == 1 and len(paths) != 1:
        raise SpecholoError(f"one model for a single turn of the view, got {len(paths)}; "
                            "several models need --turns equal to their number")
    if config.turns > 1 and len(paths) not in (1, config.turns):
        raise SpecholoError(f"give one model, or one per turn of the view ({config.turns}); "
                            f"got {len(paths)}")
    models = [load_model(p) for p in paths]
    plate = config.plate
    if config.fit and plate is not None:
        return _design_fitted(models, config, plate, rng)
    return _design_loaded(models, config, rng)


#: Plate angles between the eyes a fit to the plate samples, degrees: a groove's
#: crossings run round a curve, whose extent the samples miss by under a
#: thousandth of its size at this step.
FIT_STEP_DEG = 2.0


def _design_fitted(models: list[Any], config: SpinConfig, plate: tuple[float, float],
                   rng: np.random.Generator | None) -> SpinPlate:
    """:func:`design_spin` with the size fitted to the given plate."""
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
    from specholo.scene.placement import place

    phi = np.radians(np.arange(0.0, 360.0, FIT_STEP_DEG))
    eyes = config.setup.eyes(phi).reshape(-1, 3)  # both eyes all round the axis
    # every model at size 1 about its box centre: one size serves them all
    unit = np.vstack([place(m, 1.0, 0.0, config.pose.rotation()).points for m in models])
    center = np.array([*config.pose.offset, config.center_z])
    half = 0.5 * config.tool.width

    def size_with(reach: np.ndarray) -> float:
        return round_size(fit_size_from(unit, center, plate, eyes, reach, PLATE_MARGIN))

    def design_at(size: float) -> SpinPlate:
        # each try from the same stippling seed: the kept design is the one a
        # design at the recorded size gives
        fresh = copy.deepcopy(rng) if rng is not None else None
        return _design_loaded(models, dataclasses.replace(config, size=size), fresh)

    def spread(job: SpinPlate) -> tuple[np.ndarray, np.ndarray]:
        d = job.design
        if d.grooves.n_paths == 0:
            return np.zeros(2), np.zeros(2)
        cuts = np.abs(d.grooves.extent()).max(axis=0) + half
        return cuts, np.abs(crossing_extent_from(d.points, eyes)).max(axis=0)

    size, job = fit_design(size_with, design_at, spread, plate_room(plate, PLATE_MARGIN),
                           np.array([half, half]))
    return dataclasses.replace(job, config=dataclasses.replace(config, size=size))


def _design_loaded(models: list[Any], config: SpinConfig,
                   rng: np.random.Generator | None) -> SpinPlate:
    """:func:`design_spin` for models already loaded, at ``config.size``."""
    from specholo.scene.placement import place
    from specholo.scene.stippling import stipple

    rng = rng if rng is not None else np.random.default_rng(config.seed)
    if config.turns > 1:
        return _design_sliding(models, config, rng)
    model = place(models[0], config.size, config.center_z,
                  config.pose.rotation(), config.pose.offset)
    st = stipple(model, rng, count=config.stipples)
    setup = config.setup
    fitted = fit_grooves(st.points, setup)
    keep = None
    if model.mesh is not None and config.occlusion:
        phi = np.linspace(0.0, 2.0 * np.pi, setup.angles, endpoint=False)
        vis = shown_at(config, model.mesh, st.normals, st.points, phi)
        # a vertex serves each eye at its own angle; keep it only where neither
        # eye would see a hidden point there
        keep = np.ones((len(st.points), setup.samples), dtype=bool)
        for e in range(2):
            j = np.rint(vertex_angles(fitted[0], setup, e) / (2.0 * np.pi / setup.angles))
            keep &= np.take_along_axis(vis[e], j.astype(int) % setup.angles, axis=1)
    design = design_spinning(st.points, setup, config.tool, visible=keep, fitted=fitted)
    return SpinPlate(config, design, model.mesh, st.normals, keep)


def _design_sliding(models: list[Any], config: SpinConfig,
                    rng: np.random.Generator) -> SpinPlate:
    from specholo.scene.placement import place
    from specholo.toolpaths.sliding import design_sliding, slide_tracks

    meshes = [place(m, config.size, config.center_z, config.pose.rotation(),
                    config.pose.offset).mesh for m in models]
    tracks = slide_tracks(meshes, config.setup, config.turns, config.stipples, rng,
                          occlusion=config.occlusion)
    if not len(tracks):
        raise SpecholoError("no stipple stays in view long enough to be served: nothing to cut")
    design = design_sliding(tracks, config.setup, config.tool)
    return SpinPlate(config, design, None, None)


def verify_spin(job: SpinPlate, step_deg: float = 5.0) -> list[SpinReport]:
    """Verify over a whole turn every ``step_deg`` degrees."""
    angles = np.arange(0.0, 360.0, step_deg)
    if job.design.tracks is not None:  # sliding stipples carry when they are shown
        return verify_spinning(job.design, job.config.tool, angles)
    shown = shown_at(job.config, job.mesh, job.normals, job.design.points, np.radians(angles))
    return verify_spinning(job.design, job.config.tool, angles, shown)


def summarise(reports: list[SpinReport]) -> dict[str, float]:
    """Worst figures over the turn."""
    def worst(key: str) -> float:
        vals = [getattr(r, key) for r in reports if not math.isnan(getattr(r, key))]
        return max(vals) if vals else math.nan

    return {"worst_p95_mm": worst("p95_mm"), "worst_depth_p95_mm": worst("depth_p95_mm"),
            "worst_median_mm": worst("median_mm"),
            "lowest_visibility": min((r.visibility for r in reports
                                      if not math.isnan(r.visibility)), default=math.nan),
            "stray": int(sum(r.stray for r in reports))}


def preview_frames(job: SpinPlate, frames: int, size: tuple[int, int] = (360, 360)
                   ) -> list[np.ndarray]:
    """Frames of one turn as the left eye sees it (glints found on the grooves).

    Returns:
        (H, W, 3) uint8 frames.
    """
    from PIL import Image, ImageDraw, ImageFilter

    d = job.design
    setup = d.setup
    eye_w = setup.world_eyes()[0]
    fwd = -eye_w / np.linalg.norm(eye_w)
    right = np.array([1.0, 0.0, 0.0]) - fwd[0] * fwd
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    verts = d.grooves.vertices
    rad = float(np.abs(verts).max()) + 5.0 if len(verts) else 20.0
    w, h = size
    f = 0.45 * min(w, h) / math.atan(rad / np.linalg.norm(eye_w))

    def project(p: np.ndarray) -> np.ndarray:
        v = p - eye_w
        z = v @ fwd
        return np.stack([w / 2 + f * (v @ right) / z, h / 2 - f * (v @ up) / z], axis=-1)

    ring = np.linspace(0, 2 * np.pi, 97)
    out = []
    for phi in np.linspace(0.0, 2.0 * np.pi, frames, endpoint=False):
        eye_p = rotate_z(eye_w, -phi)
        gl = find_spin_glints(d, eye_p, job.config.tool)
        world = rotate_z(gl.point, phi)
        img = Image.new("RGB", size, (10, 11, 14))
        draw = ImageDraw.Draw(img)
        edge = project(np.stack([rad * np.cos(ring), rad * np.sin(ring), 0 * ring], -1))
        draw.polygon([tuple(q) for q in edge], fill=(24, 26, 31), outline=(60, 64, 72))
        mark = project(rotate_z(np.array([[0.0, rad - 3.0, 0.0], [0.0, rad, 0.0]]), phi))
        draw.line([tuple(q) for q in mark], fill=(120, 120, 130), width=2)
        spots = Image.new("L", size, 0)
        sd = ImageDraw.Draw(spots)
        for x, y in project(world):
            sd.ellipse([x - 1.2, y - 1.2, x + 1.2, y + 1.2], fill=255)
        glow = spots.filter(ImageFilter.GaussianBlur(1.2))
        base = np.asarray(img, dtype=np.float32)
        s = np.asarray(glow, dtype=np.float32)[..., None] / 255.0
        s = np.minimum(1.0, 2.5 * s)
        pix = base * (1 - s) + s * np.array([255.0, 244.0, 214.0])
        out.append(pix.clip(0, 255).astype(np.uint8))
    return out


def spin_limits(grooves: Any, depth: float, machining: Machining,
                thickness: float = STOCK_THICKNESS) -> Any:
    """What a turning plate's program of ``grooves`` cut ``depth`` mm deep may do
    (``fabrication.check.Limits``), from the design's settings: the tool centre
    inside the grooves' extent plus a blank border (within the plate, given or
    fitted to the grooves, :func:`spin_plate`) of ``thickness`` mm, no deeper
    than the cut, rapids at the safe height, hops as set, every cut in X/Y at
    the cut's depth, feeds and spindle as set."""
    from specholo.fabrication.check import Limits, Stock, tool_kind
    from specholo.fabrication.plate import PLATE_MARGIN

    m = machining
    (x0, y0), (x1, y1) = grooves.extent() + np.array([[-PLATE_MARGIN], [PLATE_MARGIN]])
    return Limits(Stock(float(x0), float(y0), float(x1), float(y1), thickness), depth, m.safe_z,
                  (min(m.feed, m.plunge), max(m.feed, m.plunge)), (m.spindle, m.spindle),
                  tool_kind("ball", m.spindle), hop_max=m.hop_max, hop=m.hop, groove_depth=depth)


def spin_plate(job: SpinPlate) -> Any:
    """The plate (``fabrication.plate.Plate``) a turning plate's files name: the
    one given, centred on the axis, or the grooves' with a 5 mm border.

    Raises:
        SpecholoError: a given plate is smaller than the grooves.
    """
    from specholo.fabrication.plate import job_plate

    return job_plate(job.design.grooves.extent(), job.config.tool.width, job.config.plate)


def write_spin(job: SpinPlate, out: str | os.PathLike[str], step_deg: float = 5.0,
               frames: int = 48, inputs: Iterable[str | os.PathLike[str] | None] = ()
               ) -> dict[str, Any]:
    """Write the folder atomically: hologram.json, grooves.npz, stipples.npz,
    hologram.gcode (and relief.gcode for one-sided walls), hologram.svg,
    verify.json and preview.gif. ``inputs`` are the model files, which ``out``
    must not hold as files a design writes.

    Returns:
        The summary of the verification.
    """
    from specholo.fabrication.drawings.svg import write_svg
    from specholo.fabrication.programs.gcode import write_gcode
    from specholo.folders import check_out
    from specholo.optics.cutters import VBit
    from specholo.preview.motion import write_animation
    from specholo.staging import stage_design

    d, cfg = job.design, job.config
    if d.grooves.n_paths == 0:
        raise SpecholoError("no stipple is visible at any plate angle: nothing to cut")
    inputs = list(inputs)
    check_out(out, inputs)  # before the verification
    # one plate for the program, the relief cut and the drawing: the one given,
    # centred on the axis, or the grooves' (a plate too small refused here)
    plate = spin_plate(job)
    relief, relief_depth = relief_grooves(d, cfg.tool) if cfg.setup.walls == "one" else \
        (None, 0.0)
    if relief is not None and relief.n_paths and not relief_depth < cfg.stock_thickness:
        raise SpecholoError(f"the relief cut goes {relief_depth:.3g} mm deep, through the "
                            f"{cfg.stock_thickness:g} mm plate: give a larger --stock-thickness "
                            "or use --walls both")
    reports = verify_spin(job, step_deg)
    summary = summarise(reports)
    with stage_design(out, inputs, kind="spin") as stage:
        tmp = stage.path
        stage.save_grooves(d.grooves)
        extra: dict[str, Any] = {}
        if d.tracks is not None:
            t = d.tracks
            extra = {"track_phi": t.phi, "track_position": t.position,
                     "track_alive": t.alive, "track_scene": t.scene,
                     "track_shown": t.alive if t.shown is None else t.shown,
                     "window": d.window if d.window is not None else np.zeros((0, 2))}
        stage.save_arrays("stipples.npz", **extra, points=d.points, coef=d.coef, side=d.side,
                          path_side=d.path_side, normals=np.zeros((0, 3))
                          if job.normals is None else job.normals)
        if job.mesh is not None:
            stage.save_model(job.mesh)
        header = {"design": "turning plate, closed grooves" if d.tracks is None else
                  f"turning plate, open grooves: the view circles the scene {cfg.turns} "
                  "times per turn", "walls": cfg.setup.walls, "stock": stock_line(cfg)}
        limits = spin_limits(d.grooves, cfg.tool.depth, cfg.machining, cfg.stock_thickness)
        options = program_options(cfg)
        gstats = write_gcode(tmp / "hologram.gcode", d.grooves, cfg.tool, cfg.machining,
                             header={**header, **limits.header()}, options=options,
                             plate=plate, drawings=SPIN_DRAWINGS)
        safety = stage.check("hologram.gcode", limits)
        meta: dict[str, Any] = {
            "design": "spin", "settings": cfg.settings(),
            "tilts_deg": [math.degrees(t) for t in d.tilts],
            "relief_tilt_deg": math.degrees(d.relief_tilt),
            "paths": d.grooves.n_paths, "groove_length_mm": d.grooves.total_length(),
            "gcode": {"lines": gstats.lines, "paths": gstats.paths,
                      "safety_check": {"moves": safety.moves, "violations": 0}},
            "verify": json_ready(summary), "plate_mm": plate.box.tolist(),
        }
        if d.tracks is not None:
            per = d.tracks.shown.sum(axis=0) if d.tracks.shown is not None else \
                d.tracks.alive.sum(axis=0)
            meta["sliding"] = {"tracks": len(d.tracks), "turns": cfg.turns,
                               "scenes": int(d.tracks.scene.max()) + 1 if len(d.tracks) else 0,
                               "shown_per_angle": {"min": int(per.min()),
                                                   "mean": float(per.mean()),
                                                   "max": int(per.max())}}
        if relief is not None:
            depth = relief_depth
            if relief.n_paths:
                # one tool named, the V-bit that cuts it: as a flat design's V-bit
                # program, the header gives the bit, its round-tip model and the
                # groove the V cuts (its width at the surface, not the model's)
                vbit = VBit(RELIEF_ANGLE, max_depth=max(depth, VBit.max_depth))
                rhead = {"design": "relief cut: takes away each groove's other wall",
                         "stock": stock_line(cfg),
                         "cutter": f"{vbit.describe()} included angle, its tip on the "
                                   "groove's edge"}
                rlimits = spin_limits(relief, depth, cfg.machining, cfg.stock_thickness)
                write_gcode(tmp / "relief.gcode", relief, vbit.model(depth), cfg.machining,
                            header={**rhead, **rlimits.header()}, options=options,
                            depth=depth, plate=plate, width=vbit.section(depth).width,
                            drawings=SPIN_DRAWINGS)
                stage.check("relief.gcode", rlimits)
            meta["relief"] = {"depth_mm": depth, "v_bit_included_deg": 30.0,
                              "other_wall_keeps_tilts_below_deg":
                                  math.degrees(d.relief_tilt)}
        write_svg(tmp / "hologram.svg", d.grooves, cfg.tool, plate=plate)
        write_spin_verification(reports, tmp, step_deg)
        stage.save_record("spin", meta)
        if frames:
            write_animation(preview_frames(job, frames), tmp / "preview.gif", fps=12)
    return summary


def write_spin_verification(reports: list[SpinReport], folder: str | os.PathLike[str],
                            step_deg: float) -> dict[str, Any]:
    """Write ``verify.json`` atomically; returns the summary."""
    from specholo.folder import write_verify_json

    summary = summarise(reports)
    write_verify_json(folder, "spin", step_deg, json_ready(summary), "angles",
                      [row_json(r.as_dict()) for r in reports])
    return summary


def is_spin_folder(folder: str | os.PathLike[str]) -> bool:
    """True if ``folder`` holds a turning-plate design written by :func:`write_spin`."""
    from specholo.folder import design_kind

    # "spinning": the name folders written before the job names were one
    return design_kind(folder) in ("spin", "spinning")


def load_spin_folder(folder: str | os.PathLike[str]) -> SpinPlate:
    """Read a folder written by :func:`write_spin` back into a job.

    Raises:
        SpecholoError: a file is unreadable, unlike what :func:`write_spin` writes,
            or the files disagree.
    """
    from specholo.folder import config_arguments
    from specholo.readback import (
        ArraySpec,
        load_arrays,
        number,
        read_json,
        settings_from,
        table,
        whole,
    )
    from specholo.scene.loading import read_mesh
    from specholo.toolpaths.grooves import MAX_COORDINATE, Grooves

    folder = Path(folder)
    path = folder / "hologram.json"
    meta = table(read_json(path), str(path))
    with settings_from(path):
        if "settings" in meta:
            saved = table(meta["settings"], "settings")
            for key in ("stipples", "seed", "turns", *SPIN_FIT):
                if key in saved:
                    whole(saved[key], key)
            cfg = SpinConfig.from_settings(saved)
        else:  # a folder written before every kind recorded its settings by option names
            cfg = SpinConfig(**config_arguments(meta["config"], SpinSetup, SPIN_ANGLES,
                                                ("stipples", "seed", "turns", *SPIN_FIT)))
        tilts = meta["tilts_deg"]
        if not (isinstance(tilts, list) and len(tilts) == 2):
            raise SpecholoError("tilts_deg must be 2 numbers")
        lo, hi = (math.radians(number(t, "tilts_deg")) for t in tilts)
        relief = math.radians(number(meta["relief_tilt_deg"], "relief_tilt_deg"))
    sliding = {"track_phi": ArraySpec((None,), finite=True),
               "track_position": ArraySpec((None, None, 3)),  # NaN where not alive
               "track_alive": ArraySpec((None, None), np.bool_),
               "track_scene": ArraySpec((None,), np.int64),
               "track_shown": ArraySpec((None, None), np.bool_),
               "window": ArraySpec((None, 2), finite=True)}
    a = load_arrays(folder / "stipples.npz", {
        "points": ArraySpec((None, 3), finite=True), "coef": ArraySpec((None, None), finite=True),
        "side": ArraySpec((None,), np.int64), "path_side": ArraySpec((None,), np.int64),
        "normals": ArraySpec((None, 3), finite=True),
        **{k: ArraySpec(s.shape, s.dtype, s.finite, optional=True) for k, s in sliding.items()}})
    points, coef, side, path_side = a["points"], a["coef"], a["side"], a["path_side"]
    n = len(points)
    grooves = Grooves.load(folder / "grooves.npz", n)
    normals = a["normals"] if len(a["normals"]) else None
    disagree = SpecholoError(f"cannot read turning-plate design in {folder}: files disagree")
    if grooves.n_paths != len(path_side) or len(coef) != n or len(side) != n \
            or (normals is not None and len(normals) != n) \
            or not np.all(np.abs(side) == 1) or not np.all(np.abs(path_side) == 1) \
            or not np.all(np.abs(points) <= MAX_COORDINATE):
        raise disagree
    tracks = window = None
    present = [k for k in sliding if k in a]
    if present:
        from specholo.toolpaths.sliding import Tracks

        if len(present) < len(sliding) or cfg.turns < 2:
            raise disagree
        phi, position = a["track_phi"], a["track_position"]
        grid = (n, len(phi))
        # Positions are looked up on the grid of plate angles by index.
        if len(phi) == 0 or position.shape[:2] != grid or a["track_alive"].shape != grid \
                or a["track_shown"].shape != grid or a["track_scene"].shape != (n,) \
                or a["window"].shape != (n, 2) or np.any(a["track_scene"] < 0) \
                or np.any(np.isinf(position)):
            raise disagree
        tracks = Tracks(cfg.turns, phi, position, a["track_alive"], a["track_scene"],
                        a["track_shown"])
        window = a["window"]
    elif cfg.turns != 1:
        raise disagree
    design = SpinDesign(cfg.setup, points, coef, side, grooves, path_side, (lo, hi), relief,
                        tracks=tracks, window=window)
    mesh = read_mesh(folder / "model.ply") if (folder / "model.ply").exists() else None
    return SpinPlate(cfg, design, mesh, normals)

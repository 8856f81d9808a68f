"""The whole job for holograms on any host and with motion: a TOML composition
in, grooves, G-code and a verification out.

A composition names a host (plane, cylinder, sphere, height field, mesh or
panels), a motion (the viewer walking past, or the light moving while the
viewer stands still), the light, the viewer, the tool and one or more scenes,
each shown over its own interval of the driver (azimuth or light elevation),
optionally turning or shifting within it. See the README's "Curved hosts,
animation and moving lights".
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.hosts.surfaces import (
    Cylinder,
    HeightField,
    Host,
    MeshHost,
    Panel,
    Panels,
    Plane,
    Sphere,
)
from specholo.scene.motion import Family, MotionSpec, Position, SceneKey, rot_z
from specholo.setup import Machining, Tool

#: Keys each table of a composition may hold (anything else is refused).
_KEYS: dict[str, set[str]] = {
    "": {"mode", "stipples", "seed", "band", "step", "host", "light", "viewer", "tool",
         "machining", "scene"},
    "host": {"kind", "radius", "height", "width", "file", "panels"},
    "light": {"elevation", "distance", "stop"},
    "viewer": {"distance", "range", "height", "ipd"},
    "tool": {"radius", "depth"},
    "machining": {"feed", "plunge", "safe_z", "spindle", "axes"},
    "scene": {"model", "frames", "size", "center_z", "from", "to", "turn", "shift", "yaw",
              "stipples"},
}


def _table(data: Any, name: str) -> dict[str, Any]:
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise SpecholoError(f"composition: [{name}] must be a table")
    unknown = set(data) - _KEYS[name]
    if unknown:
        raise SpecholoError(f"composition: unknown key {sorted(unknown)[0]!r} in "
                            f"[{name or 'top level'}]")
    return data


def _num(table: dict[str, Any], key: str, default: float | None, where: str,
         lo: float = -math.inf, hi: float = math.inf, positive: bool = False) -> float | None:
    v = table.get(key, default)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise SpecholoError(f"composition: {where}.{key} must be a number, got {v!r}")
    v = float(v)
    if not math.isfinite(v) or v < lo or v > hi or (positive and v <= 0):
        raise SpecholoError(f"composition: {where}.{key} = {v:g} is out of range")
    return v


@dataclass
class SceneSpec:
    """One scene of a composition (lengths mm, angles radians)."""

    model: Path
    size: float
    center_z: float
    start: float
    stop: float
    turn: float
    shift: tuple[float, float, float]
    stipples: int
    yaw: float = 0.0


@dataclass
class Composition:
    """A parsed composition."""

    motion: MotionSpec
    host: Host
    tool: Tool
    machining: Machining
    axes: int
    band: float
    seed: int
    scenes: list[SceneSpec]
    settings: dict[str, Any] = field(default_factory=dict)


def _host(t: dict[str, Any], base: Path) -> Host:
    kind = t.get("kind", "plane")
    if kind == "plane":
        return Plane(_num(t, "width", None, "host", positive=True) or math.inf,
                     _num(t, "height", None, "host", positive=True) or math.inf)
    if kind == "cylinder":
        return Cylinder(_num(t, "radius", 40.0, "host", positive=True) or 40.0,
                        _num(t, "height", 80.0, "host", positive=True) or 80.0)
    if kind == "sphere":
        return Sphere(_num(t, "radius", 50.0, "host", positive=True) or 50.0)
    if kind in ("heightfield", "mesh"):
        if "file" not in t or not isinstance(t["file"], str):
            raise SpecholoError(f"composition: a {kind} host needs host.file")
        path = (base / t["file"]).resolve()
        if kind == "heightfield":
            try:
                with np.load(path) as z:
                    return HeightField(z["x"], z["y"], z["z"])
            except (OSError, KeyError, ValueError) as exc:
                raise SpecholoError(f"composition: cannot read height field {path}: "
                                    "need an .npz with arrays x, y, z") from exc
        from specholo.scene.loading import load_model

        model = load_model(path)
        if model.mesh is None:
            raise SpecholoError(f"composition: mesh host {path} has no faces")
        return MeshHost(model.mesh)
    if kind == "panels":
        rows = t.get("panels")
        if not isinstance(rows, list) or not rows:
            raise SpecholoError("composition: a panels host needs [[host.panels]] entries")
        panels = []
        for r in rows:
            if not isinstance(r, dict) or set(r) - {"centre", "normal", "up", "width", "height"}:
                raise SpecholoError("composition: each panel has centre, normal, up, width, "
                                    "height")
            try:
                panels.append(Panel(tuple(float(v) for v in r["centre"]),  # type: ignore[arg-type]
                                    tuple(float(v) for v in r["normal"]),  # type: ignore[arg-type]
                                    float(r["width"]), float(r["height"]),
                                    tuple(float(v) for v in r.get("up", (0, 1, 0)))))  # type: ignore[arg-type]
            except (KeyError, TypeError, ValueError) as exc:
                raise SpecholoError(f"composition: bad panel {r!r}") from exc
            if len(panels[-1].centre) != 3 or len(panels[-1].normal) != 3:
                raise SpecholoError("composition: panel centre and normal need 3 numbers")
        return Panels(panels)
    raise SpecholoError(f"composition: unknown host kind {kind!r} (plane, cylinder, sphere, "
                        "heightfield, mesh, panels)")


def read_composition(path: str | os.PathLike[str]) -> Composition:
    """Read and check a TOML composition.

    Raises:
        SpecholoError: unreadable file, unknown keys, wrong types, values out of range.
    """

    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError as exc:
        raise SpecholoError(f"composition {p} not found") from exc
    except UnicodeDecodeError as exc:
        raise SpecholoError(f"composition {p} is not valid TOML: {exc}") from exc
    except OSError as exc:
        raise SpecholoError(f"cannot read composition {p}: {exc.strerror or exc}") from exc
    return parse_composition(text, p.resolve().parent)


def parse_composition(text: str, base: Path) -> Composition:
    """Parse a composition's TOML text; model and host files are relative to ``base``."""
    import tomllib

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecholoError(f"composition is not valid TOML: {exc}") from exc
    top = _table(data, "")
    mode = top.get("mode", "walk")
    light = _table(top.get("light"), "light")
    viewer = _table(top.get("viewer"), "viewer")
    tool_t = _table(top.get("tool"), "tool")
    mach = _table(top.get("machining"), "machining")
    host = _host(_table(top.get("host"), "host"), base)
    deg = math.radians
    motion = MotionSpec(
        mode=str(mode),
        view_distance=_num(viewer, "distance", 600.0, "viewer", 10, 1e7) or 600.0,
        eye_height=_num(viewer, "height", 0.0, "viewer", -1e5, 1e5) or 0.0,
        ipd=_num(viewer, "ipd", 64.0, "viewer", 1, 1000) or 64.0,
        half_range=deg(_num(viewer, "range", 30.0, "viewer", 0, 79) or 0.0),
        light_elevation=deg(_num(light, "elevation", 45.0, "light", 0, 180) or 45.0),
        light_distance=_num(light, "distance", None, "light", positive=True),
        light_stop=deg(_num(light, "stop", 60.0, "light", 0, 180) or 60.0),
        step=deg(_num(top, "step", 0.25, "top", 0.01, 2.0) or 0.25),
    )
    tool = Tool(_num(tool_t, "radius", 0.05, "tool", 0.001, 25) or 0.05,
                _num(tool_t, "depth", 0.02, "tool", 1e-4, 25) or 0.02)
    axes = int(_num(mach, "axes", 3, "machining", 3, 4) or 3)
    machining = Machining(_num(mach, "feed", 300.0, "machining", positive=True) or 300.0,
                          _num(mach, "plunge", 100.0, "machining", positive=True) or 100.0,
                          _num(mach, "safe_z", 1.0, "machining", positive=True) or 1.0,
                          _num(mach, "spindle", 0.0, "machining", 0, 1e6) or 0.0)
    count = int(_num(top, "stipples", 400, "top", 1, 1e6) or 400)
    rows = top.get("scene")
    if not isinstance(rows, list) or not rows:
        raise SpecholoError("composition: needs at least one [[scene]] with a model")
    a, b = (-motion.half_range, motion.half_range) if motion.mode == "walk" else sorted(
        (motion.light_elevation, motion.light_stop))
    lo, hi = motion.driver()
    scenes = []
    for k, raw in enumerate(rows):
        s = _table(raw, "scene")
        if isinstance(s.get("frames"), str) == isinstance(s.get("model"), str):
            raise SpecholoError(f"composition: scene {k + 1} needs model = \"file\" or "
                                "frames = \"pattern*.obj\" (one of them)")
        if isinstance(s.get("frames"), str):
            files = sorted(base.glob(s["frames"]))
            if not files:
                raise SpecholoError(f"composition: scene {k + 1}: no file matches "
                                    f"{s['frames']!r}")
        else:
            files = [(base / s["model"]).resolve()]
        start = _num(s, "from", None, "scene")
        stop = _num(s, "to", None, "scene")
        first = a if start is None else max(deg(start), a)
        last = b if stop is None else min(deg(stop), b)
        if not last > first:
            raise SpecholoError(f"composition: scene {k + 1} shows over an empty interval")
        shift = s.get("shift", [0.0, 0.0, 0.0])
        if not (isinstance(shift, list) and len(shift) == 3
                and all(isinstance(v, int | float) and math.isfinite(v) for v in shift)):
            raise SpecholoError(f"composition: scene {k + 1} shift must be 3 numbers (mm/deg)")
        # A numbered sequence shares the scene's interval out evenly, in name order.
        edges = np.linspace(first, last, len(files) + 1)
        for i, f in enumerate(files):
            # An interval open at the driver's ends covers the design margin beyond them.
            start_r = lo - 1.0 if edges[i] <= a + 1e-9 else float(edges[i])
            stop_r = hi + 1.0 if edges[i + 1] >= b - 1e-9 else float(edges[i + 1])
            scenes.append(SceneSpec(
                model=f.resolve(),
                size=_num(s, "size", 40.0, "scene", positive=True) or 40.0,
                center_z=_num(s, "center_z", -30.0, "scene", -1e4, 1e4) or 0.0,
                start=start_r, stop=stop_r,
                # Turn in degrees per degree, shift in mm per degree of the driver.
                turn=_num(s, "turn", 0.0, "scene", -100, 100) or 0.0,
                shift=tuple(float(v) * 180.0 / math.pi for v in shift),  # type: ignore[arg-type]
                stipples=int(_num(s, "stipples", count, "scene", 1, 1e6) or count),
                yaw=deg(_num(s, "yaw", 0.0, "scene", -360, 360) or 0.0)))
    band = _num(top, "band", max(0.2, tool.width), "top", positive=True) or 0.2
    seed = int(_num(top, "seed", 0, "top", 0, 2**32) or 0)
    settings = {"text": text, "base": str(base)}
    return Composition(motion, host, tool, machining, axes, band, seed, scenes, settings)


@dataclass
class ComposedScene:
    """A placed and stippled scene."""

    key: SceneKey
    mesh: Any
    points: np.ndarray
    normals: np.ndarray | None


def prepare_scenes(comp: Composition) -> list[ComposedScene]:
    """Load, place and stipple every scene."""
    from specholo.scene.loading import load_model
    from specholo.scene.placement import place
    from specholo.scene.stippling import stipple

    rng = np.random.default_rng(comp.seed)
    out = []
    for s in comp.scenes:
        model = place(load_model(s.model), s.size, s.center_z)
        st = stipple(model, rng, count=s.stipples)
        origin = 0.5 * (max(s.start, comp.motion.driver()[0])
                        + min(s.stop, comp.motion.driver()[1]))
        key = SceneKey(s.start, s.stop, s.turn, s.shift, (0.0, 0.0, s.center_z), origin, s.yaw)
        out.append(ComposedScene(key, model.mesh, st.points, st.normals))
    return out


def _shown(scene: ComposedScene, world_eyes: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """(n, m) bool: each stipple is keyed in and unoccluded from each eye."""
    from specholo.visibility.occlusion import visible

    n, m = len(scene.points), len(keys)
    out = np.zeros((n, m), dtype=bool)
    inside = (keys >= scene.key.start) & (keys < scene.key.stop)
    eyes = scene.key.eye_in_scene(world_eyes, keys)
    for j in np.flatnonzero(inside):
        out[:, j] = visible(scene.mesh, scene.points, scene.normals, eyes[j])
    return out


def _targets(scene: ComposedScene, keys: np.ndarray, plate_angle: np.ndarray) -> np.ndarray:
    """(n, m, 3) the scene's points in the plate frame at each state."""
    world = scene.key.pose(scene.points, keys)
    return np.einsum("mij,nmj->nmi", rot_z(-plate_angle), world)


@dataclass
class ComposedDesign:
    """A designed composition."""

    comp: Composition
    scenes: list[ComposedScene]
    grooves: Any
    stats: dict[str, Any]


def design_composition(comp: Composition) -> ComposedDesign:
    """Stipple the scenes and stripe their grooves along every family of states."""
    from specholo.toolpaths.conforming import ConformingGrooves, ConformingOptions, design_family

    scenes = prepare_scenes(comp)
    parts = []
    next_id = 0
    offset = 0
    stats: dict[str, Any] = {"families": []}
    families: list[Family] = comp.motion.families()
    for fi, fam in enumerate(families):
        for scene in scenes:
            targets = _targets(scene, fam.key, fam.plate_angle)
            active = _shown(scene, fam.world_eye, fam.key)
            g = design_family(comp.host, fam.eye, fam.light, fam.baseline, fam.point_light,
                              targets, active, comp.tool, ConformingOptions(comp.band),
                              next_id, fi)
            g.stipple = g.stipple + offset
            next_id = g.stats["next_stripe"]
            parts.append(g)
            stats["families"].append({"family": fam.name, **g.stats})
            offset += len(scene.points)
        offset = 0
    keys = ("point", "tangent", "normal", "stripe", "stipple", "state", "family")
    cat = {k: np.concatenate([getattr(g, k) for g in parts]) for k in keys}
    grooves = ConformingGrooves(cat["point"], cat["tangent"], cat["normal"], cat["stripe"],
                                cat["stipple"], cat["state"], cat["family"])
    if len(grooves.stripe) == 0:
        missed = sum(f["states_missing_the_host"] for f in stats["families"])
        tilt = sum(f["states_lost_to_tilt"] for f in stats["families"])
        raise SpecholoError(
            "no groove could be designed: every view of every stipple is hidden, misses the "
            f"host ({missed} stipple-views) or needs a wall steeper than the tool's "
            f"({tilt}); enlarge the host, move the scene or use a deeper cut")
    stats["stripes"] = int(np.unique(grooves.stripe).size)
    stats["samples"] = int(len(grooves.stripe))
    stats["groove_length_mm"] = grooves.length()
    return ComposedDesign(comp, scenes, grooves, stats)


def all_points(scenes: list[ComposedScene]) -> np.ndarray:
    return np.concatenate([s.points for s in scenes])


def verify_composition(d: ComposedDesign, step: float) -> list[Any]:
    """What stereo viewers see at each position along the motion.

    Args:
        d: the design.
        step: largest driver step between positions, radians.
    """
    from specholo.simulation.conforming import find_conforming_glints, position_report

    comp = d.comp
    reports = []
    point = comp.motion.light_distance is not None
    positions: list[Position] = comp.motion.positions(step)
    for pos in positions:
        targets, shown, glints = [], [], []
        for k in range(2):
            tgt = np.concatenate([_targets(s, pos.keys[k:k + 1], np.array([pos.plate_angle]))
                                  [:, 0] for s in d.scenes])
            sh = np.concatenate([_shown(s, pos.world_eyes[k:k + 1], pos.keys[k:k + 1])[:, 0]
                                 for s in d.scenes])
            targets.append(tgt)
            shown.append(sh)
            glints.append(find_conforming_glints(d.grooves, comp.host, pos.eyes[k], pos.light,
                                                 point, comp.tool))
        reports.append(position_report(math.degrees(pos.tau), (targets[0], targets[1]),
                                       (shown[0], shown[1]), pos.eyes, (glints[0], glints[1])))
    return reports


def write_composition(d: ComposedDesign, out: str | os.PathLike[str]) -> dict[str, Any]:
    """Write the design folder atomically: hologram.json, grooves.npz, stipples.npz,
    each scene's placed mesh, and hologram.gcode (checked before it is kept).

    Returns:
        The G-code check's figures.
    """
    from specholo.fabrication.atomic import atomic_open
    from specholo.fabrication.surface_gcode import check_surface_gcode, write_surface_gcode
    from specholo.pipeline import FORMATS, RIDGED_STALE, staged_output

    comp = d.comp
    program = write_surface_gcode(d.grooves, comp.host, comp.tool, comp.machining, comp.axes)
    check = check_surface_gcode(program.text, comp.host, comp.tool, comp.machining, comp.axes)
    # A folder that held another design keeps none of its files.
    stale = ("verify.json", "verify.png", "verify_cut.json", "model.ply", "preview.png",
             "preview.gif", "run.json", "grooves.npz", *FORMATS.values(), *RIDGED_STALE,
             *(f"scene_{k}.ply" for k in range(len(d.scenes), len(d.scenes) + 64)))
    with staged_output(out, stale=stale) as tmp:
        tmp = Path(tmp)
        with atomic_open(tmp / "grooves.npz", "wb", encoding=None) as fh:
            d.grooves.save(fh)
        with atomic_open(tmp / "stipples.npz", "wb", encoding=None) as fh:
            np.savez_compressed(fh, points=all_points(d.scenes), scene=np.concatenate(
                [np.full(len(s.points), k) for k, s in enumerate(d.scenes)]))
        for k, s in enumerate(d.scenes):
            if s.mesh is not None:
                with atomic_open(tmp / f"scene_{k}.ply", "wb", encoding=None) as fh:
                    fh.write(s.mesh.export(file_type="ply"))
        with atomic_open(tmp / "hologram.gcode") as fh:
            fh.write(program.text)
        meta = {"design": "conforming", "composition": comp.settings,
                "host": comp.host.describe(), "mode": comp.motion.mode,
                "tool": {"radius": comp.tool.radius, "depth": comp.tool.depth,
                         "width": comp.tool.width},
                "band_mm": comp.band, "stats": d.stats,
                "gcode": {"axes": comp.axes, "paths": program.paths,
                          "samples_beyond_3axis_reach": program.dropped_samples,
                          "cut_length_mm": program.cut_length, "check": check}}
        with atomic_open(tmp / "hologram.json") as fh:
            json.dump(meta, fh, indent=1, sort_keys=True)
    return check


def is_composed_folder(folder: str | os.PathLike[str]) -> bool:
    from specholo.folder import design_kind

    return design_kind(folder) == "conforming"


def load_composition_folder(folder: str | os.PathLike[str]) -> ComposedDesign:
    """The design in a folder, with its composition (scenes re-stippled identically)."""
    from specholo.toolpaths.conforming import ConformingGrooves

    folder = Path(folder)
    try:
        meta = json.loads((folder / "hologram.json").read_text())
        composition = parse_composition(meta["composition"]["text"],
                                        Path(meta["composition"]["base"]))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SpecholoError(f"{folder}: not a composed design folder") from exc
    scenes = prepare_scenes(composition)
    grooves = ConformingGrooves.load(folder / "grooves.npz")
    with np.load(folder / "stipples.npz") as z:
        if not np.array_equal(z["points"], all_points(scenes)):
            raise SpecholoError(f"{folder}: the composition no longer matches this design")
    return ComposedDesign(composition, scenes, grooves, {})

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

import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.plate import STOCK_THICKNESS
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
from specholo.scene.motion import MODES, Family, MotionSpec, Position, SceneKey, rot_z
from specholo.scene.pose import UP_AXES, Pose
from specholo.setup import MAX_FEED, MAX_SPINDLE, MIN_SAFE_Z, Machining, Tool

if TYPE_CHECKING:
    from specholo.fabrication.programs.program import GcodeOptions

#: Ranges of a composition's machining numbers (lowest, highest, unit): those
#: of real machines. Feeds from a crawl to beyond the fastest routers (60 m/min);
#: a safe height from a clearance above a flat blank's unevenness (see
#: :data:`specholo.setup.MIN_SAFE_Z`) to a retract no machine's Z travel
#: exceeds by much; a spindle off (a drag tip) or turning from 100 rpm (a
#: slow mill) to an air-bearing spindle's 1,000,000; the stock from a
#: 0.1 mm foil to a 1 m block.
MACHINING_RANGES: dict[str, tuple[float, float, str]] = {
    "feed": (1.0, MAX_FEED, "mm/min"),
    "plunge": (1.0, MAX_FEED, "mm/min"),
    "safe_z": (MIN_SAFE_Z, 100.0, "mm"),
    "spindle": (100.0, MAX_SPINDLE, "rpm"),
    "thickness": (0.1, 1000.0, "mm"),
}

#: Keys each table of a composition may hold (anything else is refused).
_KEYS: dict[str, set[str]] = {
    "": {"mode", "stipples", "seed", "band", "step", "host", "light", "viewer", "tool",
         "machining", "scene"},
    "host": {"kind", "radius", "height", "width", "file", "panels"},
    "light": {"elevation", "distance", "stop"},
    "viewer": {"distance", "range", "height", "ipd"},
    "tool": {"radius", "depth"},
    "machining": {"feed", "plunge", "safe_z", "spindle", "axes", "thickness", "dialect",
                  "units"},
    "scene": {"model", "frames", "size", "center_z", "from", "to", "turn", "shift", "yaw",
              "stipples", "up", "rotate_x", "rotate_y", "rotate_z", "offset_x", "offset_y",
              "fit"},
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


def _name(where: str, key: str) -> str:
    """A setting as the composition spells it: "stipples", "light.elevation", "scene 2: size"."""
    if where == "top":
        return key
    return f"{where}: {key}" if where.startswith("scene ") else f"{where}.{key}"


def _opt(table: dict[str, Any], key: str, where: str, lo: float = -math.inf,
         hi: float = math.inf, positive: bool = False, open_ends: bool = False,
         why: str = "") -> float | None:
    """``table[key]`` as a float within its range, or None when the key is absent.

    Absent is the only "no value": 0 is a value like any other (a default is never
    put in place of a setting that was given).
    """
    if key not in table:
        return None
    v = table[key]
    name = _name(where, key)
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise SpecholoError(f"composition: {name} must be a number, got {v!r}")
    try:
        x = float(v)
    except OverflowError:  # an integer beyond any float
        x = math.inf
    inside = (lo < x < hi) if open_ends else (lo <= x <= hi)
    if not (math.isfinite(x) and inside and (x > 0 or not positive)):
        if positive and math.isinf(hi):
            need = "it must be positive"
        else:
            need = (f"it must be in {'(' if open_ends else '['}{lo:g}, {hi:g}"
                    f"{')' if open_ends else ']'}")
        raise SpecholoError(f"composition: {name} = {v!r} is out of range: {need}{why}")
    return x


def _num(table: dict[str, Any], key: str, default: float, where: str,
         lo: float = -math.inf, hi: float = math.inf, positive: bool = False,
         open_ends: bool = False, why: str = "") -> float:
    """``table[key]`` as a float within its range, ``default`` when absent."""
    v = _opt(table, key, where, lo, hi, positive, open_ends, why)
    return default if v is None else v


def _int(table: dict[str, Any], key: str, default: int, where: str, lo: int, hi: int) -> int:
    """``table[key]`` as a whole number in [lo, hi], ``default`` when absent.

    A float with a fraction is refused rather than truncated (1.9 stipples is a
    mistake, not a request for one); 3.0 is the whole number it spells.
    """
    if key not in table:
        return default
    v = table[key]
    name = _name(where, key)
    if isinstance(v, bool) or not isinstance(v, int | float) or (
            isinstance(v, float) and not v.is_integer()):
        raise SpecholoError(f"composition: {name} must be a whole number, got {v!r}")
    n = int(v)
    if not lo <= n <= hi:
        raise SpecholoError(f"composition: {name} = {v!r} is out of range: it must be in "
                            f"[{lo}, {hi}]")
    return n


def _str(table: dict[str, Any], key: str, default: str, where: str,
         choices: tuple[str, ...]) -> str:
    """``table[key]`` as one of ``choices``, ``default`` when absent."""
    v = table.get(key, default)
    if not isinstance(v, str) or v not in choices:
        raise SpecholoError(f"composition: {_name(where, key)} must be one of "
                            f"{', '.join(repr(c) for c in choices)}, got {v!r}")
    return v


def _vector(row: dict[str, Any], key: str, default: tuple[float, ...] | None,
            what: str) -> tuple[float, float, float]:
    """``row[key]`` as 3 finite numbers (not strings or booleans)."""
    v = row.get(key, default)
    if not (isinstance(v, list | tuple) and len(v) == 3 and all(
            isinstance(c, int | float) and not isinstance(c, bool) and math.isfinite(c)
            for c in v)):
        raise SpecholoError(f"composition: {what} {key} must be 3 numbers, got {v!r}")
    return (float(v[0]), float(v[1]), float(v[2]))


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
    pose: Pose = field(default_factory=Pose)
    fit: bool = False


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
    #: The material under the host's surface, mm: no cut may reach it.
    thickness: float = STOCK_THICKNESS
    #: The program's G-code dialect (a mill's: "grbl" or "linuxcnc") and units.
    dialect: str = "grbl"
    units: str = "mm"

    def gcode_options(self) -> GcodeOptions:
        """The ``fabrication.programs.program.GcodeOptions`` its program is written with."""
        from specholo.fabrication.programs.program import program_options

        return program_options(self)


#: Range of a host's sides and lengths (a plane's width and height, a cylinder's
#: height, a panel's sides) and of its radii, mm, for ``_opt``: from a
#: millimetre to the largest plate a design takes (100 m), and radii to 10 m.
SIDE = (1.0, 100_000.0, False, False, " mm")
RADIUS = (1.0, 10_000.0, False, False, " mm")

#: Host kinds a composition may name.
HOST_KINDS = ("plane", "cylinder", "sphere", "heightfield", "mesh", "panels")


#: The [host] keys each kind reads besides ``kind``: any other is refused, not
#: ignored (a cylinder's width would be a mistake, never a setting).
HOST_KEYS: dict[str, tuple[str, ...]] = {
    "plane": ("width", "height"), "cylinder": ("radius", "height"), "sphere": ("radius",),
    "heightfield": ("file",), "mesh": ("file",), "panels": ("panels",)}


def _host(t: dict[str, Any], base: Path) -> Host:
    kind = t.get("kind", "plane")
    if not isinstance(kind, str) or kind not in HOST_KINDS:
        raise SpecholoError(f"composition: unknown host kind {kind!r} "
                            f"({', '.join(HOST_KINDS)})")
    stray = sorted(set(t) - {"kind", *HOST_KEYS[kind]})
    if stray:
        raise SpecholoError(f"composition: host.{stray[0]} does not apply to a {kind} host "
                            f"(it takes {', '.join(HOST_KEYS[kind])})")
    if kind == "plane":
        width = _opt(t, "width", "host", *SIDE)
        height = _opt(t, "height", "host", *SIDE)
        return Plane(math.inf if width is None else width,
                     math.inf if height is None else height)
    if kind == "cylinder":
        return Cylinder(_num(t, "radius", 40.0, "host", *RADIUS),
                        _num(t, "height", 80.0, "host", *SIDE))
    if kind == "sphere":
        return Sphere(_num(t, "radius", 50.0, "host", *RADIUS))
    if kind in ("heightfield", "mesh"):
        if "file" not in t or not isinstance(t["file"], str) or not t["file"]:
            raise SpecholoError(f"composition: a {kind} host needs host.file")
        path = (base / t["file"]).resolve()
        if kind == "heightfield":
            return _height_field(path)
        from specholo.scene.loading import load_model

        model = load_model(path)
        if model.mesh is None:
            raise SpecholoError(f"composition: mesh host {path} has no faces")
        return MeshHost(model.mesh.to_trimesh())
    rows = t.get("panels")
    if not isinstance(rows, list) or not rows:
        raise SpecholoError("composition: a panels host needs [[host.panels]] entries")
    panels = []
    for k, r in enumerate(rows):
        if not isinstance(r, dict) or set(r) - {"centre", "normal", "up", "width", "height"}:
            raise SpecholoError("composition: each panel has centre, normal, up, width, "
                                "height")
        where = f"host.panels[{k}]"
        width = _opt(r, "width", where, *SIDE)
        height = _opt(r, "height", where, *SIDE)
        if width is None or height is None:
            raise SpecholoError(f"composition: {where} needs a width and a height")
        panels.append(Panel(_vector(r, "centre", None, where), _vector(r, "normal", None, where),
                            width, height, _vector(r, "up", (0.0, 1.0, 0.0), where)))
    return Panels(panels)


def _height_field(path: Path) -> HeightField:
    """A height-field host from an .npz of arrays x (nx,), y (ny,) and z (ny, nx)."""
    from specholo.readback import ArraySpec, load_arrays

    try:
        a = load_arrays(path, {"x": ArraySpec((None,), finite=True),
                               "y": ArraySpec((None,), finite=True),
                               "z": ArraySpec((None, None), finite=True)})
    except SpecholoError as exc:
        # A .npy (one bare array, no x and y to place it) is not an archive.
        raise SpecholoError(f"composition: cannot read height field: {exc}; need an .npz "
                            "with arrays x, y, z") from exc
    return HeightField(a["x"], a["y"], a["z"])


def read_composition(path: str | os.PathLike[str]) -> Composition:
    """Read and check a TOML composition.

    Raises:
        SpecholoError: unreadable file, unknown keys, wrong types, values out of range.
    """

    from specholo.readback import MAX_TOML_BYTES, read_text

    p = Path(path)
    # A regular file only: a FIFO would wait for a writer, /dev/zero never end.
    text = read_text(p, MAX_TOML_BYTES, "composition")
    return parse_composition(text, p.resolve().parent)


#: Why a light elevation of 0 or 180 degrees is refused.
GRAZING = "; a light in the plate's plane only grazes it and lights none of it"


def _frames(pattern: Any, base: Path, k: int) -> list[Path]:
    """The files a scene's ``frames`` pattern matches, in name order."""
    if not isinstance(pattern, str) or not pattern.strip():
        raise SpecholoError(f"composition: scene {k}: frames must be a file pattern such as "
                            f"\"frame_*.obj\", got {pattern!r}")
    # A pattern walks folders and takes whatever it matches, so it is kept to the
    # composition's own folder: a shared composition cannot sweep up files from
    # elsewhere on the disk, or walk the whole file system with "/**" (a file
    # outside is named on its own, with model = "...").
    if Path(pattern).is_absolute() or ".." in Path(pattern).parts:
        raise SpecholoError(f"composition: scene {k}: frames {pattern!r} must match files in "
                            "the composition's folder (a relative pattern without '..')")
    try:
        root = base.resolve()
        files = sorted(base.glob(pattern))
        outside = next((f for f in files if not f.resolve().is_relative_to(root)), None)
    except (OSError, ValueError, NotImplementedError, RuntimeError) as exc:
        # ValueError: a malformed pattern ("**x") or a NUL byte; RuntimeError: a
        # symbolic link loop (Python 3.11's resolve).
        raise SpecholoError(f"composition: scene {k}: cannot use frames {pattern!r}: "
                            f"{' '.join(str(exc).split()) or type(exc).__name__}") from exc
    if outside is not None:
        raise SpecholoError(f"composition: scene {k}: frames {pattern!r} matches {outside}, "
                            f"a link to a file outside the composition's folder {root}")
    if not files:
        raise SpecholoError(f"composition: scene {k}: no file matches {pattern!r}")
    return files


def parse_composition(text: str, base: Path) -> Composition:
    """Parse a composition's TOML text; model and host files are relative to ``base``.

    Every setting is checked for its type and range: a whole number where one is
    meant (1.9 stipples is refused, not truncated), and a setting that is given is
    never replaced by its default (0 is a value).
    """
    import tomllib

    from specholo.fabrication.programs.program import check_program_options

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecholoError(f"composition is not valid TOML: {exc}") from exc
    except RecursionError as exc:  # tomllib parses nested arrays and tables recursively
        raise SpecholoError("composition is not valid TOML: nested too deeply") from exc
    top = _table(data, "")
    light = _table(top.get("light"), "light")
    viewer = _table(top.get("viewer"), "viewer")
    tool_t = _table(top.get("tool"), "tool")
    mach = _table(top.get("machining"), "machining")
    host = _host(_table(top.get("host"), "host"), base)
    deg = math.radians
    motion = MotionSpec(
        mode=_str(top, "mode", "walk", "top", MODES),
        view_distance=_num(viewer, "distance", 600.0, "viewer", 10, 1e7),
        eye_height=_num(viewer, "height", 0.0, "viewer", -1e5, 1e5),
        ipd=_num(viewer, "ipd", 64.0, "viewer", 1, 1000),
        half_range=deg(_num(viewer, "range", 30.0, "viewer", 0, 79)),
        # Elevations 0 and 180 put the light in the plate's plane, where it grazes
        # the plate and lights none of it: the ends are refused, not replaced.
        light_elevation=deg(_num(light, "elevation", 45.0, "light", 0, 180, open_ends=True,
                                 why=GRAZING)),
        light_distance=_opt(light, "distance", "light", 1, 1e7, why=" mm"),
        light_stop=deg(_num(light, "stop", 60.0, "light", 0, 180, open_ends=True,
                            why=GRAZING)),
        step=deg(_num(top, "step", 0.25, "top", 0.01, 2.0)),
    )
    radius = _num(tool_t, "radius", 0.05, "tool", 0.001, 25, why=" mm")
    tool = Tool(radius, _num(tool_t, "depth", 0.02, "tool", 1e-4, radius,
                             why=" mm (up to the tool's radius)"))
    axes = _int(mach, "axes", 3, "machining", 3, 4)
    machining = Machining(*(_machining(mach, key, default)
                            for key, default in (("feed", 300.0), ("plunge", 100.0),
                                                 ("safe_z", 1.0), ("spindle", 0.0))))
    thickness = _machining(mach, "thickness", STOCK_THICKNESS)
    dialect, units = mach.get("dialect", "grbl"), mach.get("units", "mm")
    check_program_options(dialect, units, ("composition: machining.dialect",
                                           "composition: machining.units"))
    if not tool.depth < thickness:
        raise SpecholoError(f"composition: tool.depth = {tool.depth:g} mm would cut through "
                            f"the {thickness:g} mm of material under the surface "
                            "(machining.thickness): it must be less")
    count = _int(top, "stipples", 400, "top", 1, 1_000_000)
    band = _num(top, "band", max(0.2, tool.width), "top", 0.001, 1000, why=" mm")
    seed = _int(top, "seed", 0, "top", 0, 2**32)
    rows = top.get("scene")
    if not isinstance(rows, list) or not rows:
        raise SpecholoError("composition: needs at least one [[scene]] with a model")
    a, b = (-motion.half_range, motion.half_range) if motion.mode == "walk" else sorted(
        (motion.light_elevation, motion.light_stop))
    lo, hi = motion.driver()
    scenes = []
    for k, raw in enumerate(rows):
        s = _table(raw, "scene")
        if ("frames" in s) == ("model" in s):
            raise SpecholoError(f"composition: scene {k + 1} needs model = \"file\" or "
                                "frames = \"pattern*.obj\" (one of them)")
        if "frames" in s:
            files = _frames(s["frames"], base, k + 1)
        else:
            if not isinstance(s["model"], str) or not s["model"]:
                raise SpecholoError(f"composition: scene {k + 1}: model must be a file name, "
                                    f"got {s['model']!r}")
            files = [base / s["model"]]
        where = f"scene {k + 1}"
        start = _opt(s, "from", where)
        stop = _opt(s, "to", where)
        first = a if start is None else max(deg(start), a)
        last = b if stop is None else min(deg(stop), b)
        if not last > first:
            raise SpecholoError(f"composition: scene {k + 1} shows over an empty interval")
        shift = _vector(s, "shift", (0.0, 0.0, 0.0), where)
        size = _num(s, "size", 40.0, where, 0.01, 10_000, why=" mm")
        center_z = _num(s, "center_z", -30.0, where, -1e4, 1e4)
        # Turn in degrees per degree, shift in mm per degree of the driver.
        turn = _num(s, "turn", 0.0, where, -100, 100)
        stipples = _int(s, "stipples", count, where, 1, 1_000_000)
        yaw = deg(_num(s, "yaw", 0.0, where, -360, 360))
        up = s.get("up", "y")
        if up not in UP_AXES:
            raise SpecholoError(f"composition: {where}: up must be one of {', '.join(UP_AXES)}, "
                                f"got {str(up)[:40]!r}")
        rx, ry, rz = (_num(s, f"rotate_{a}", 0.0, where, -360, 360) for a in "xyz")
        pose = Pose(up, (rx, ry, rz),
                    (_num(s, "offset_x", 0.0, where, -1e4, 1e4),
                     _num(s, "offset_y", 0.0, where, -1e4, 1e4)))
        fit = s.get("fit", False)
        if not isinstance(fit, bool):
            raise SpecholoError(f"composition: {where}: fit must be true or false")
        if fit and not (isinstance(host, Plane) and math.isfinite(host.width)
                        and math.isfinite(host.height)):
            raise SpecholoError(f"composition: {where}: fit scales the scene to a plate: give "
                                "[host] kind = \"plane\" a width and a height")
        # A numbered sequence shares the scene's interval out evenly, in name order.
        edges = np.linspace(first, last, len(files) + 1)
        for i, f in enumerate(files):
            # An interval open at the driver's ends covers the design margin beyond them.
            start_r = lo - 1.0 if edges[i] <= a + 1e-9 else float(edges[i])
            stop_r = hi + 1.0 if edges[i + 1] >= b - 1e-9 else float(edges[i + 1])
            scenes.append(SceneSpec(
                model=_resolved(f, k + 1), size=size, center_z=center_z,
                start=start_r, stop=stop_r, turn=turn,
                shift=(shift[0] * 180.0 / math.pi, shift[1] * 180.0 / math.pi,
                       shift[2] * 180.0 / math.pi),
                stipples=stipples, yaw=yaw, pose=pose, fit=fit))
    settings = {"text": text, "base": str(base)}
    return Composition(motion, host, tool, machining, axes, band, seed, scenes, settings,
                       thickness, dialect, units)


def _machining(table: dict[str, Any], key: str, default: float) -> float:
    """A machining number in its range (:data:`MACHINING_RANGES`), ``default`` when
    absent; a spindle may also be 0, off (a drag tip cuts without one)."""
    lo, hi, unit = MACHINING_RANGES[key]
    if key not in table:
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise SpecholoError(f"composition: machining.{key} must be a number, got {v!r}")
    try:
        x = float(v)
    except OverflowError:  # an integer beyond any float
        x = math.inf
    if key == "spindle" and x == 0:
        return 0.0
    if not lo <= x <= hi:  # NaN too
        off = " (or 0: no spindle, a drag tip)" if key == "spindle" else ""
        raise SpecholoError(f"composition: machining.{key}: {key.replace('_', ' ')} {x:g} "
                            f"{unit} is out of range: it must be in [{lo:g}, {hi:g}] "
                            f"{unit}{off}")
    return x


def _resolved(path: Path, k: int) -> Path:
    try:
        return path.resolve()
    except (OSError, ValueError, RuntimeError) as exc:  # RuntimeError: a link loop (3.11)
        raise SpecholoError(f"composition: scene {k}: cannot use {path}: "
                            f"{' '.join(str(exc).split()) or type(exc).__name__}") from exc


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
        loaded = load_model(s.model)
        origin = 0.5 * (max(s.start, comp.motion.driver()[0])
                        + min(s.stop, comp.motion.driver()[1]))
        # the scene turns about its own box centre, wherever it was moved
        pivot = (*s.pose.offset, s.center_z)
        key = SceneKey(s.start, s.stop, s.turn, s.shift, pivot, origin, s.yaw)
        size = fitted_scene_size(comp, s, key, loaded) if s.fit else s.size
        model = place(loaded, size, s.center_z, s.pose.rotation(), s.pose.offset)
        st = stipple(model, rng, count=s.stipples)
        out.append(ComposedScene(key, model.mesh, st.points, st.normals))
    return out


def fitted_scene_size(comp: Composition, spec: SceneSpec, key: SceneKey, model: Any) -> float:
    """The largest size (mm) at which a scene's grooves lie on the composition's
    plane host, 5 mm in from its edges, at every state it shows in.

    The conforming grooves pass where the sightline from each state's eye to
    the scene's point, as the motion moves and turns it, crosses the plate
    (within the band); the scene's convex hull bounds those crossings.

    Raises:
        SpecholoError: the host cannot hold even a tiny scene there.
    """
    from specholo.fabrication.plate import PLATE_MARGIN
    from specholo.scene.fit import hull_points, largest_size, moving_crossings_fit, round_size
    from specholo.scene.placement import place

    host = comp.host
    if not isinstance(host, Plane):  # parse_composition refuses fit on any other host
        raise SpecholoError("composition: fit needs a plane host")
    unit = hull_points(place(model, 1.0, 0.0, spec.pose.rotation()).points)
    centre = np.array(key.centre)
    reach = 0.5 * comp.tool.width + np.array([0.0, comp.band])
    room = np.array([host.width, host.height]) / 2.0 - PLATE_MARGIN - reach
    families = comp.motion.families()

    def targets(size: float) -> list[tuple[np.ndarray, np.ndarray]]:
        sets = []
        for fam in families:
            inside = (fam.key >= spec.start) & (fam.key < spec.stop)
            if inside.any():
                world = key.pose(centre + size * unit, fam.key[inside])
                points = np.einsum("mij,nmj->nmi", rot_z(-fam.plate_angle[inside]), world)
                sets.append((points, fam.eye[inside]))
        return sets

    fits = moving_crossings_fit(targets, room)
    if np.any(room <= 0) or not fits(0.1):
        raise SpecholoError(
            f"composition: a {host.width:g} x {host.height:g} mm plane cannot hold the scene "
            f"{spec.model.name} at depth {spec.center_z:g} mm: its grooves would leave it at "
            "any size; move it nearer the plane's middle and surface")
    return round_size(largest_size(fits))


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
    from specholo.readback import bounded
    from specholo.toolpaths.grooves import MAX_COORDINATE

    # What verify would refuse to read back (beyond any plate: a scene shifted far
    # off an unbounded plane) is refused before anything is written.
    if not bounded(grooves.point, MAX_COORDINATE):
        raise SpecholoError(f"the grooves reach {float(np.abs(grooves.point).max()):.3g} mm "
                            "from the host's centre, beyond any plate: bring the scenes "
                            "(center_z, shift) closer")
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


def composition_files(comp: Composition) -> list[Path]:
    """The files a composition reads: each scene's model, and a height-field or
    mesh host's file."""
    import tomllib

    files = [s.model for s in comp.scenes]
    try:
        host = tomllib.loads(comp.settings["text"]).get("host")
        if isinstance(host, dict) and isinstance(host.get("file"), str):
            files.append(Path(comp.settings["base"]) / host["file"])
    except (KeyError, TypeError, ValueError):
        pass  # a composition built in code names no host file
    return files


def write_composition(d: ComposedDesign, out: str | os.PathLike[str],
                      inputs: Iterable[str | os.PathLike[str] | None] = (),
                      then: Callable[[Path, dict[str, Any]], None] | None = None
                      ) -> dict[str, Any]:
    """Write the design folder atomically: hologram.json, grooves.npz, stipples.npz,
    each scene's placed mesh, and hologram.gcode (checked before it is kept).

    Args:
        d: the design.
        out: the output folder.
        inputs: the composition file; with the files it names, none may be a
            file a design writes in ``out``.
        then: called with the new folder, before it is published, and the
            G-code check's figures, to add files published with the design's
            (its verification, its previews).

    Returns:
        The G-code check's figures.
    """
    from specholo.fabrication.atomic import atomic_open
    from specholo.fabrication.programs.surface_gcode import (
        check_surface_program,
        write_surface_gcode,
    )
    from specholo.folders import check_out
    from specholo.staging import stage_design

    comp = d.comp
    inputs = [*inputs, *composition_files(comp)]
    check_out(out, inputs)  # before the G-code is made and checked
    program = write_surface_gcode(d.grooves, comp.host, comp.tool, comp.machining, comp.axes,
                                  comp.thickness, comp.gcode_options())
    with stage_design(out, inputs, kind="composition") as stage:
        tmp = stage.path
        stage.save_grooves(d.grooves)
        stage.save_arrays("stipples.npz", points=all_points(d.scenes), scene=np.concatenate(
            [np.full(len(s.points), k) for k, s in enumerate(d.scenes)]))
        for k, s in enumerate(d.scenes):
            if s.mesh is not None:
                stage.save_model(s.mesh, f"scene_{k}.ply")
        with atomic_open(tmp / "hologram.gcode") as fh:
            fh.write(program.text)
        # read back by the safety check every program passes, before it is kept
        check = stage.check("hologram.gcode", check=lambda path: check_surface_program(
            path, d.grooves, comp.host, comp.tool, comp.machining, comp.axes, comp.thickness))
        # its settings are what the command took: the composition's TOML text
        meta = {"design": "composition", "settings": comp.settings,
                "host": comp.host.describe(), "mode": comp.motion.mode,
                "tool": {"radius": comp.tool.radius, "depth": comp.tool.depth,
                         "width": comp.tool.width},
                "band_mm": comp.band, "stats": d.stats,
                "gcode": {"axes": comp.axes, "dialect": comp.dialect, "units": comp.units,
                          "paths": program.paths,
                          "samples_beyond_3axis_reach": program.dropped_samples,
                          "cut_length_mm": program.cut_length, "check": check}}
        stage.save_record("composition", meta)
        if then is not None:
            then(tmp, check)
    return check


def is_composed_folder(folder: str | os.PathLike[str]) -> bool:
    from specholo.folder import design_kind

    # "conforming": the name folders written before the job names were one
    return design_kind(folder) in ("composition", "conforming")


def load_composition_folder(folder: str | os.PathLike[str]) -> ComposedDesign:
    """The design in a folder, with its composition (scenes re-stippled identically).

    Raises:
        SpecholoError: a file is unreadable or unlike what :func:`write_composition`
            writes, or the composition no longer makes the stipples it made.
    """
    from specholo.readback import ArraySpec, load_arrays, read_json, settings_from, table
    from specholo.toolpaths.conforming import ConformingGrooves

    folder = Path(folder)
    path = folder / "hologram.json"
    meta = table(read_json(path), str(path))
    with settings_from(path):
        # "composition": where folders written before every kind's "settings" kept it
        key = "settings" if "settings" in meta else "composition"
        comp = table(meta[key], key)
        text, base = comp["text"], comp["base"]
        if not (isinstance(text, str) and isinstance(base, str)):
            raise SpecholoError("composition text and base must be strings")
        composition = parse_composition(text, Path(base))
    scenes = prepare_scenes(composition)
    points = all_points(scenes)
    stipples = load_arrays(folder / "stipples.npz", {"points": ArraySpec((None, 3))})
    if not np.array_equal(stipples["points"], points):
        raise SpecholoError(f"{folder}: the composition no longer matches this design")
    grooves = ConformingGrooves.load(folder / "grooves.npz", len(points))
    return ComposedDesign(composition, scenes, grooves, {})

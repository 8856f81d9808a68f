"""Rendered glints (Mitsuba 3): what a viewer meets on a plate as cut, beside verify.

Usage: python benchmarks/render_judge.py [--work DIR] [--azimuths -20 0 20]
       [--spp 16] [--spp-fine 1024] [--pixel 0.003] [--plates bunny knot] [--quick]
       [--lights sun point] [--alphas 0.003 0.01] [--stipples N]

Designs two small plates with the default tool (``specholo design`` on the
bundled bunny and knot; ``--plates`` adds a deeper bunny placed by default and
with ``--placement lock``), cuts each folder's ``hologram.gcode`` into a
height field at 2.5 um (``specholo.simulation.cut.cut_surface``), and renders
it with the physically based renderer Mitsuba 3: a triangle mesh of the field
with the cut's exact normals at its vertices (where two cuts meet, the
triangles across the crease are remade on each cut's own surface, finer where
a wall there may glint, so no normal between the two walls is rendered),
a rough conductor (Beckmann,
alpha 0.003 and 0.01, a perfect reflector otherwise), lit by a disc far
along the design's light direction (angular diameter 0.53 deg, the sun, and
0.05 deg, nearly a point), seen by a pinhole at each eye of the design's
viewer. Mitsuba's ``direct`` integrator samples both the light and the BSDF
(multiple importance sampling), on the pixels that see a groove, and again
far more densely about every pixel that lit up.

In each picture the bright spots are grouped by the path whose cut made the
surface they lie on (each lit pixel's ray is followed to the height field):
pieces of one path's streak closer than the eye resolves (1 arcmin) are one
glint, whose place is its brightness-weighted centroid followed back to the
cut surface. A glint is *designed* where the point model (``find_glints`` on
the folder's grooves, as verify uses them) has a glint of the same path
within 0.25 mm, or, given verify's streak model, where it lies on that
model's designed streak of its path (within 0.02 mm); it counts when it
passes verify's image rule (1/20 of its stipple's brightest, 1/100 of the
typical stipple's), before and after the
bright stripe ends beside it join it, as in verify. Any other glint counts
when it is bright enough to be a glint of its own, verify's rule for end
spills (1/20 of the typical stipple's and of its stipple's brightest
designed glint): these are the ends of stripes whose glint lies just past
them. Per view: stereo visibility, each stipple's apparent point
triangulated from both eyes' glints (the pairs verify would fuse) and its
error, the streaks' lengths and how far their centres lie from the point
glints, the stripe ends that glint (matched with the streak model's end
streaks) and among them the end spills, those more than 0.25 mm from every
glint of the point model. Beside them, ``specholo verify`` on the same
folders: the point model and, where verify has ``--light-size`` and
``--roughness``, the streak model, each on the design's grooves and as cut.

Writes benchmarks/results/render_judge.json and prints two markdown tables.
Renders with Mitsuba's ``llvm_ad_rgb`` variant on one CPU thread, which needs
LLVM 19 or later (Debian: ``apt-get install libllvm19``; or set
DRJIT_LIBLLVM_PATH to a libLLVM).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import functools
import glob
import importlib.util
import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.sparse.csgraph import connected_components

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "render_judge.json"

#: The plates: small enough to render at a few um a pixel, with 30-50 stipples cut.
PLATES: dict[str, tuple[str, list[str]]] = {
    "bunny": ("bunny.obj", ["--size", "4", "--center-z", "-3", "--stipples", "80"]),
    "knot": ("knot.obj", ["--size", "4", "--center-z", "-3", "--stipples", "60"]),
    # Deeper, so the stripes drift a band within the eyes' separation: placed
    # by default and with --placement lock, whose grid ends the stripes of 51
    # of its 52 stipples (the plates above: a few).
    "bunny-deep": ("bunny.obj", ["--size", "4", "--center-z", "-8", "--stipples", "80"]),
    "bunny-lock": ("bunny.obj", ["--size", "4", "--center-z", "-8", "--stipples", "80",
                                 "--placement", "lock"]),
}
#: The plates rendered unless --plates names others.
DEFAULT_PLATES = ("bunny", "knot")
#: Lights: name and angular diameter seen from the plate, degrees.
LIGHTS = (("sun", 0.53), ("point", 0.05))
#: Beckmann roughness (Mitsuba's alpha).
ALPHAS = (0.003, 0.01)
#: Height-field spacing, mm: the 0.025 mm tip's wall turns 0.1 rad a sample.
RESOLUTION = 0.0025
#: Flat plate kept around the grooves, in samples: a ray toward a light 20 deg up
#: leaves an 11 um deep groove within 30 um, so nothing further can shadow it.
RING = 12
#: Distance of a sun's disc, mm: across a 12 mm plate its direction turns by
#: 1e-5 rad, far below the 0.05 deg light's radius.
SUN_DISTANCE = 1.0e6
#: Glints farther than this from every point-model glint are spills, mm.
SPILL = 0.25
#: Verify's image rule (specholo.simulation.glints.FAINT_RATIO, INVISIBLE_RATIO).
FAINT_RATIO = 20.0
INVISIBLE_RATIO = 100.0
#: A rendered end streak is the model's when on its path and this near, mm.
END_MATCH = 0.05
#: A rendered glint is its path's designed streak when this near the streak
#: model's lit stretch of it, mm (their centres agree within micrometres, their
#: lengths within 10%).
STREAK_MATCH = 0.02
#: What the eye resolves, radians: streak pieces closer than this are one glint.
EYE_RESOLUTION = math.radians(1.0 / 60.0)
#: Lit pixels: above this share of the picture's brightest (a few samples'
#: worth of a glint; Monte Carlo dust is orders of magnitude fainter).
LIT = 1e-4
#: Normals further apart than this across a triangle on two cuts are a crease, radians
#: (across the 0.025 mm tip's wall they turn 0.1 rad a sample).
CREASE = math.radians(20.0)
#: A crease triangle is cut finer where a corner's normal is this near an eye's
#: half vector, radians: a sample's turn across the tip's wall (0.1) and the
#: widest lobe rendered (about 0.035 at alpha 0.01), with room.
NEAR_HALF = 0.2
#: Pieces along each side of a crease triangle cut finer (0.6 um at 2.5 um).
SUBDIVIDE = 4
#: Sub-rays along each side of a lit pixel that say which path its light came
#: from: a pixel 3 um across can straddle a crease, and the light of a streak
#: cut short there lies within a few micrometres of it.
SUB_RAYS = 4
#: Samples a pixel where a groove glints as a point (a cap a stripe's end
#: leaves, a dot): a sphere of the tip lights a spot about 0.1 um across, which
#: the fine pass hits about once in four at 256; at 8,192 a stratum is a
#: fraction of that spot.
SPP_POINTS = 8192
#: Oldest LLVM the vectorised variant is known to compile with (15 fails).
MIN_LLVM = 19


# ---------------------------------------------------------------------------
# Mitsuba


def _find_llvm() -> str | None:
    """A libLLVM of MIN_LLVM or later in the usual places, newest first."""
    found: list[tuple[int, str]] = []
    for pattern in ("/usr/lib/x86_64-linux-gnu/libLLVM*.so*", "/usr/lib/aarch64-linux-gnu/"
                    "libLLVM*.so*", "/usr/lib/libLLVM*.so*", "/usr/local/lib/libLLVM*.so*",
                    "/usr/lib/llvm-*/lib/libLLVM*.so*", "/opt/homebrew/opt/llvm/lib/libLLVM.dylib"):
        for path in glob.glob(pattern):
            m = re.search(r"libLLVM[-.]?(?:so\.)?(\d+)", os.path.basename(path))
            if m is None:
                m = re.search(r"llvm-(\d+)", path)
            if m is not None and int(m.group(1)) >= MIN_LLVM:
                found.append((int(m.group(1)), path))
    return max(found)[1] if found else None


def import_mitsuba() -> tuple[Any, Any]:
    """Mitsuba and Dr.Jit, vectorised (llvm_ad_rgb) on one thread. Exits in one
    line without Mitsuba or a recent enough LLVM."""
    try:
        missing = importlib.util.find_spec("mitsuba") is None
    except (ImportError, ValueError):
        missing = True
    if missing:
        sys.exit("error: render_judge.py needs Mitsuba 3: pip install -e '.[render]'")
    # Dr.Jit finds LLVM when the variant is set: the library is chosen before.
    if not os.environ.get("DRJIT_LIBLLVM_PATH"):
        llvm = _find_llvm()
        # An older LLVM aborts the process while compiling, beyond any except.
        if llvm is None:
            sys.exit(f"error: render_judge.py renders with Mitsuba's llvm_ad_rgb, which needs "
                     f"LLVM {MIN_LLVM} or later: apt-get install libllvm{MIN_LLVM}, or set "
                     "DRJIT_LIBLLVM_PATH to a libLLVM")
        os.environ["DRJIT_LIBLLVM_PATH"] = llvm
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError:
        sys.exit("error: render_judge.py needs Mitsuba 3: pip install -e '.[render]'")
    try:
        mi.set_variant("llvm_ad_rgb")
    except (ImportError, AttributeError, ValueError) as e:
        sys.exit(f"error: Mitsuba's llvm_ad_rgb variant is not available here: {e}")
    # The machine has other work: one core renders.
    dr.set_thread_count(1)
    return mi, dr


@dataclass
class Camera:
    """A pinhole at an eye, aimed at the plate's grooved region (Mitsuba's look_at)."""

    eye: np.ndarray
    target: np.ndarray
    width: int
    height: int
    tan_x: float

    @classmethod
    def framing(cls, eye: np.ndarray, target: np.ndarray, box: np.ndarray,
                pixel: float) -> Camera:
        """Just covering the plate rectangle ``box`` (2, 2) with pixels of about
        ``pixel`` mm where the sightline meets the plate."""
        f, right, up = cls._frame(eye, target)
        corners = np.array([[x, y, 0.0] for x in box[:, 0] for y in box[:, 1]]) - eye
        depth = corners @ f
        tx = float(np.max(np.abs(corners @ right) / depth))
        ty = float(np.max(np.abs(corners @ up) / depth))
        step = pixel / float(np.linalg.norm(target - eye))
        w, h = int(math.ceil(2 * tx / step)), int(math.ceil(2 * ty / step))
        return cls(eye, target, w, h, 0.5 * w * step)

    @staticmethod
    def _frame(eye: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, ...]:
        f = target - eye
        f = f / np.linalg.norm(f)
        right = np.cross(f, [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        return f, right, np.cross(right, f)

    @property
    def fov(self) -> float:
        """Horizontal field of view, degrees."""
        return math.degrees(2.0 * math.atan(self.tan_x))

    def rays(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Unit directions (n, 3) through film positions in pixels (x right, y down)."""
        f, right, up = self._frame(self.eye, self.target)
        tan_y = self.tan_x * self.height / self.width
        u = 2.0 * np.asarray(px) / self.width - 1.0
        v = 1.0 - 2.0 * np.asarray(py) / self.height
        d = f + u[:, None] * self.tan_x * right + v[:, None] * tan_y * up
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Film positions in pixels (x right, y down) of points (n, 3)."""
        f, right, up = self._frame(self.eye, self.target)
        tan_y = self.tan_x * self.height / self.width
        d = points - self.eye
        depth = d @ f
        u = (d @ right) / depth / self.tan_x
        v = (d @ up) / depth / tan_y
        return 0.5 * (u + 1.0) * self.width, 0.5 * (1.0 - v) * self.height

    def sensor(self, mi: Any, spp: int, seed: int) -> Any:
        """Mitsuba's own camera at this eye (to check the rays against)."""
        return mi.load_dict({
            "type": "perspective", "fov": self.fov, "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=self.eye.tolist(), target=self.target.tolist(), up=[0.0, 1.0, 0.0]),
            "near_clip": 1.0, "far_clip": 1.0e4,
            "sampler": {"type": "stratified", "sample_count": spp, "seed": seed},
            "film": {"type": "hdrfilm", "width": self.width, "height": self.height,
                     "rfilter": {"type": "box"}, "pixel_format": "luminance"},
        })


def check_camera(mi: Any, cam: Camera) -> float:
    """Largest angle (rad) between Mitsuba's rays and ours at the film's corners
    and centre: the spots are followed back with ours."""
    sensor = cam.sensor(mi, 1, 0)
    pos = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 0.5], [0.25, 0.75]])
    ours = cam.rays(pos[:, 0] * cam.width, pos[:, 1] * cam.height)
    worst = 0.0
    for (u, v), d in zip(pos, ours, strict=True):
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(float(u), float(v)),
                                   mi.Point2f(0.5, 0.5))
        theirs = np.array(ray.d, dtype=float).ravel()[:3]
        worst = max(worst, float(np.arccos(np.clip(theirs @ d / np.linalg.norm(theirs), -1, 1))))
    return worst


# ---------------------------------------------------------------------------
# The plate as cut


@dataclass
class Plate:
    """A designed folder, its cut height field and its mesh."""

    name: str
    folder: Path
    loaded: Any  # the design, grooves as designed (verify's)
    cut_grooves: Any  # the grooves read back from hologram.gcode (the field's paths)
    field: Any  # HeightField
    box: np.ndarray  # (2, 2) the rendered region
    mesh: Path
    cut_seconds: float
    vertices: int = 0
    faces: int = 0
    ends: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    engraved: Any = None  # the point model's grooves, prepared on first use
    cut_engraved: Any = None  # the program's grooves, prepared on first use

    @property
    def setup(self) -> Any:
        return self.loaded.config.setup()

    @property
    def r_cut(self) -> float:
        """Half the groove's width at the surface, mm."""
        cfg = self.loaded.config
        return float(cfg.cutter().section(cfg.depth_mm).width) / 2.0

    @property
    def same_paths(self) -> bool:
        """Whether the G-code's paths are the design's, one for one."""
        a, b = self.loaded.grooves, self.cut_grooves
        return bool(a.n_paths == b.n_paths and np.array_equal(a.stipple, b.stipple)
                    and np.array_equal(a.offsets, b.offsets))


def plate_options(name: str, stipples: int | None) -> list[str]:
    """The design options of plate NAME, with ``stipples`` stipples if given."""
    options = list(PLATES[name][1])
    if stipples is not None:
        options[options.index("--stipples") + 1] = str(stipples)
    return options


def design_plate(name: str, work: Path, redesign: bool, stipples: int | None = None) -> Path:
    """``specholo design`` into work/NAME (kept between runs unless asked; a
    folder of its own for another stipple count)."""
    folder = work / (name if stipples is None else f"{name}-{stipples}")
    if (folder / "hologram.json").is_file() and not redesign:
        return folder
    model = PLATES[name][0]
    options = plate_options(name, stipples)
    cmd = [sys.executable, "-m", "specholo_cli.cli", "design", str(ROOT / "examples" / model),
           "--out", str(folder), *options]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return folder


def cut_plate(name: str, folder: Path, work: Path, azimuths: list[float]) -> Plate:
    """The height field of the folder's G-code, cropped to its grooves, as a PLY
    mesh (its creases cut finer where they may glint for the eyes of the heads
    at ``azimuths``, degrees)."""
    from specholo.jobs.flat.folder import load_design
    from specholo.simulation.cut import cut_surface

    loaded = load_design(folder)
    cut = load_design(folder, from_gcode=True)
    cfg = cut.config
    t0 = time.perf_counter()
    ext = cut.grooves.extent()
    r_cut = cfg.cutter().section(cfg.depth_mm).width / 2.0
    box = np.stack([ext[0] - r_cut - RING * RESOLUTION, ext[1] + r_cut + RING * RESOLUTION])
    hf = cut_surface(cut.grooves, cfg.cutter(), cfg.depth_mm, box, RESOLUTION)
    seconds = time.perf_counter() - t0
    g = cut.grooves
    first = g.vertices[g.offsets[:-1]]
    last = g.vertices[g.offsets[1:] - 1]
    plate = Plate(name, folder, loaded, g, hf, hf.bounds.copy(), work / f"{folder.name}.ply",
                  seconds, ends=np.stack([first, last], axis=1))
    setup = loaded.config.setup()
    centre = np.array([*hf.bounds.mean(axis=0), 0.0])
    light = (np.asarray(setup.light.direction, dtype=float) if setup.light.distance is None
             else np.asarray(setup.light.position, dtype=float) - centre)
    halves = []
    for a in azimuths:
        for eye in setup.viewer.stereo(np.array([math.radians(a)])):
            h = light / np.linalg.norm(light) + (eye[0] - centre) / np.linalg.norm(eye[0] - centre)
            halves.append(h / np.linalg.norm(h))
    # where each stripe's cap meets its walls, and which way is out of the groove
    more = np.diff(g.offsets) > 1
    starts, stops = g.offsets[:-1][more], g.offsets[1:][more] - 1
    out = np.concatenate([g.vertices[starts] - g.vertices[starts + 1],
                          g.vertices[stops] - g.vertices[stops - 1]])
    out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
    caps = (np.concatenate([g.vertices[starts], g.vertices[stops]]), out, float(r_cut))
    plate.vertices, plate.faces = write_mesh(hf, plate.mesh, np.array(halves), caps)
    return plate


def write_mesh(hf: Any, path: Path, halves: np.ndarray,
               caps: tuple[np.ndarray, np.ndarray, float] | None = None) -> tuple[int, int]:
    """The cut samples and a ring of flat plate about them as a binary PLY.

    The flat plate mirrors the light away from every eye, so beyond the ring
    (which shadows the grooves as the whole plate would) it is left out: a
    miss is as dark as it. Vertex normals are the cut's own, exact at every
    sample (``HeightField.surface``), not differences of the samples.
    """
    keep = ndimage.binary_dilation(hf.z < 0, iterations=RING)
    cell = keep[:-1, :-1] & keep[1:, :-1] & keep[:-1, 1:] & keep[1:, 1:]
    jj, ii = np.nonzero(keep)
    index = np.full(keep.shape, -1, np.int64)
    index[jj, ii] = np.arange(len(jj))
    xy = np.stack([hf.origin[0] + ii * hf.resolution, hf.origin[1] + jj * hf.resolution], 1)
    _, normal = hf.surface(xy)
    cj, ci = np.nonzero(cell)
    a, b = index[cj, ci], index[cj, ci + 1]
    c, d = index[cj + 1, ci + 1], index[cj + 1, ci]
    # Each cell is split along its diagonal of least height change: along a
    # groove, not across it, where the wall bends.
    z = hf.z
    ac = np.abs(z[cj, ci] - z[cj + 1, ci + 1]) <= np.abs(z[cj, ci + 1] - z[cj + 1, ci])
    tri = np.concatenate([np.stack([a, b, c], 1)[ac], np.stack([a, c, d], 1)[ac],
                          np.stack([a, b, d], 1)[~ac], np.stack([b, c, d], 1)[~ac]])
    pos = np.concatenate([xy, z[jj, ii][:, None]], axis=1)
    joins = (_at_cap_joins(pos[tri].mean(axis=1)[:, :2], *caps, hf.resolution)
             if caps is not None else np.zeros(len(tri), bool))
    pos, normal, tri = _split_creases(hf, pos, normal, hf.moves[jj, ii], tri, halves, joins)
    vert = np.empty(len(pos), dtype=[(k, "<f4") for k in ("x", "y", "z", "nx", "ny", "nz")])
    vert["x"], vert["y"], vert["z"] = pos.T
    vert["nx"], vert["ny"], vert["nz"] = normal.T
    faces = np.empty(len(tri), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"], faces["i"] = 3, tri
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(vert)}\n"
              + "".join(f"property float {k}\n" for k in ("x", "y", "z", "nx", "ny", "nz"))
              + f"element face {len(faces)}\nproperty list uchar int vertex_indices\n"
              "end_header\n")
    with open(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(vert.tobytes())
        fh.write(faces.tobytes())
    return len(vert), len(faces)


def _at_cap_joins(centre: np.ndarray, ends: np.ndarray, out: np.ndarray, reach: float,
                  res: float) -> np.ndarray:
    """(t,) whether each triangle (centroid (t, 2)) lies across the line where a
    stripe's cap meets its walls: within ``reach`` of an end (k, 2), less than
    1.5 samples from it along the stripe (``out`` (k, 2) its unit direction
    out of the groove)."""
    from scipy.spatial import cKDTree

    hit = np.zeros(len(centre), bool)
    if not len(ends) or not len(centre):
        return hit
    tree = cKDTree(centre)
    for e, o, idx in zip(ends, out, tree.query_ball_point(ends, reach + res), strict=True):
        idx = np.asarray(idx, dtype=np.int64)
        if len(idx):
            hit[idx[np.abs((centre[idx] - e) @ o) <= 1.5 * res]] = True
    return hit


def _split_creases(hf: Any, pos: np.ndarray, normal: np.ndarray, move: np.ndarray,
                   tri: np.ndarray, halves: np.ndarray,
                   joins: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """The mesh with every triangle across a crease remade on the cuts' own surfaces.

    Where two cuts meet (a groove crossing another, a wall meeting the plate)
    the surface folds sharply: no normal between the two walls' exists there.
    A triangle whose corners lie on different moves with normals more than
    CREASE apart would blend them across its width, and a crease would glint
    like a cylinder of the sample spacing's radius, brighter the coarser the
    field: on a 200-stipple plate such lines, up to 0.27 mm long, moved three
    stipples' rendered glints by 0.2-2 mm. Such a triangle is cut into
    SUBDIVIDE^2 smaller ones where a wall about it may glint for some eye
    (a corner's normal within NEAR_HALF of an eye's half vector), else left
    whole, and each piece takes the surface of the cut deepest at its centre:
    heights of the deepest cut at its corners, normals of its own cut there
    (continued past where it cuts, so they vary across the piece as on that
    wall; one normal for a whole piece would glint over its whole area where
    the wall does over a strip a micrometre wide). A crease then falls within
    a fraction of a micrometre of its place, and a piece of streak another
    cut leaves keeps its own light.

    A triangle across the line where a stripe's cap meets its walls
    (``joins``) is cut finer the same way where it may glint: the wall's
    curvature along the stripe jumps there from the tip's to the stripe's,
    and normals blended across a whole triangle spread the cap's turn over
    it, so a cap glinting within a sample of the line came out up to twice
    as bright as its sphere.

    Args:
        pos: (v, 3) and normal: (v, 3) the vertices; move: (v,) the move that
            cut each (-1 the plate); tri: (t, 3) vertex indices;
        halves: (e, 3) the half vector of the light and each eye at the plate's
            centre; joins: (t,) the triangles across a cap's join.

    Returns:
        pos, normal and tri of the new mesh.
    """
    m = move[tri]
    n = normal[tri]
    cos = np.minimum(np.minimum(np.einsum("ij,ij->i", n[:, 0], n[:, 1]),
                                np.einsum("ij,ij->i", n[:, 1], n[:, 2])),
                     np.einsum("ij,ij->i", n[:, 0], n[:, 2]))
    # two paths' cuts always fold where they meet, however near their walls'
    # normals there (a crossing at a shallow angle folds by a few degrees, and
    # blending across the fold passes the normals between: the crease glints)
    p = np.where(m >= 0, hf.program.path[np.maximum(m, 0)], -1)
    crease = (((m[:, 0] != m[:, 1]) | (m[:, 1] != m[:, 2])) & (cos < math.cos(CREASE))) | (
        (p[:, 0] != p[:, 1]) | (p[:, 1] != p[:, 2]))
    if joins is not None:
        j = np.flatnonzero(joins & ~crease)
        crease[j[(n[j] @ halves.T).max(axis=(1, 2)) > math.cos(NEAR_HALF)]] = True
    t = np.flatnonzero(crease)
    if not t.size:
        return pos, normal, tri
    near = (n[t] @ halves.T).max(axis=(1, 2)) > math.cos(NEAR_HALF)
    # the others whole (cut in 1): each piece's corners, 3 a piece
    parts = [_remade(hf, pos[tri[t[near]]], m[t[near]], SUBDIVIDE),
             _remade(hf, pos[tri[t[~near]]], m[t[~near]], 1)]
    new_pos = np.concatenate([q for q, _ in parts])
    keep = np.ones(len(tri), bool)
    keep[t] = False
    added = len(pos) + np.arange(len(new_pos)).reshape(-1, 3)
    return (np.concatenate([pos, new_pos]),
            np.concatenate([normal] + [q for _, q in parts]),
            np.concatenate([tri[keep], added]))


def _remade(hf: Any, corner: np.ndarray, moves: np.ndarray,
            k: int) -> tuple[np.ndarray, np.ndarray]:
    """Triangles (s, 3, 3) whose corners lie on the cuts ``moves`` (s, 3), each
    cut into k^2 pieces on the cut deepest at the piece's centre: the pieces'
    corners (s k^2 3, 3), heights of the deepest cut, and unit normals there of
    the piece's own cut."""
    # barycentric grid of a triangle cut in k^2: its points and pieces
    ij = np.array([(i, j) for i in range(k + 1) for j in range(k + 1 - i)], dtype=float)
    at = {(int(i), int(j)): q for q, (i, j) in enumerate(ij)}
    pieces = [(at[i, j], at[i + 1, j], at[i, j + 1]) for i in range(k) for j in range(k - i)]
    pieces += [(at[i + 1, j], at[i + 1, j + 1], at[i, j + 1])
               for i in range(k) for j in range(k - 1 - i)]
    sub = np.array(pieces)
    grid = (corner[:, :1, :2] + (ij[None, :, :1] / k) * (corner[:, 1:2, :2] - corner[:, :1, :2])
            + (ij[None, :, 1:] / k) * (corner[:, 2:3, :2] - corner[:, :1, :2]))  # (s, g, 2)
    xy = grid[:, sub]  # (s, p, 3, 2)
    owner = _deepest(hf, xy.mean(axis=2), moves)  # (s, p)
    z = np.minimum(_surfaces(hf, grid, moves[:, None, :]).min(axis=2), 0.0)[:, sub]
    grad = _gradients(hf, xy.reshape(-1, 2), np.repeat(owner.ravel(), 3))
    normal = np.concatenate([-grad, np.ones((len(grad), 1))], axis=1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return np.concatenate([xy.reshape(-1, 2), z.reshape(-1, 1)], axis=1), normal


def _surfaces(hf: Any, xy: np.ndarray, moves: np.ndarray) -> np.ndarray:
    """(..., c) heights of each candidate move's cut (c moves per point; 0 where
    it does not cut) at points xy (..., 2)."""
    from specholo.simulation import _cut_kernel as kernel

    g, p = hf.program, hf.profile
    pts = np.ascontiguousarray(np.broadcast_to(xy[..., None, :], (*xy.shape[:-1],
                                                                    moves.shape[-1], 2)))
    mm = np.ascontiguousarray(np.broadcast_to(moves, pts.shape[:-1]), dtype=np.int64)
    z, _ = kernel.surface_at(pts.reshape(-1, 2), mm.ravel(), g.geo, g.kind, g.flags, hf.depth,
                             p.step, p.height, p.slope)
    return z.reshape(pts.shape[:-1])


def _deepest(hf: Any, xy: np.ndarray, moves: np.ndarray) -> np.ndarray:
    """The move of ``moves`` ((s, 3), -1 the plate) deepest at each point
    ((s, q, 2)): (s, q), -1 where none cuts."""
    z = _surfaces(hf, xy, moves[:, None, :])  # (s, q, 3)
    pick = np.take_along_axis(np.broadcast_to(moves[:, None, :], z.shape),
                              np.argmin(z, axis=2)[..., None], axis=2)[..., 0]
    return np.where(z.min(axis=2) < 0.0, pick, -1)


def _gradients(hf: Any, xy: np.ndarray, moves: np.ndarray) -> np.ndarray:
    """(n, 2) the gradient of each move's cut surface at xy (n, 2), continued
    past where it cuts (0 for move -1, the plate)."""
    g, p = hf.program, hf.profile
    return _gradient_kernel()(np.ascontiguousarray(xy, dtype=float),
                              np.ascontiguousarray(moves, dtype=np.int64), g.geo, g.kind,
                              g.flags, float(hf.depth), float(p.step), p.height, p.slope)


@functools.cache
def _gradient_kernel() -> Any:
    import numba

    from specholo.simulation import _cut_kernel as kernel

    mode_of, surface = kernel.mode_of, kernel.surface

    @numba.njit
    def run(xy: np.ndarray, moves: np.ndarray, geo: np.ndarray, kind: np.ndarray,
            flags: np.ndarray, depth: float, step: float, height: np.ndarray,
            slope: np.ndarray) -> np.ndarray:
        out = np.zeros((xy.shape[0], 2))
        for i in range(xy.shape[0]):
            m = moves[i]
            if m >= 0:
                mode, qx, qy = mode_of(geo, kind, flags, m, xy[i, 0], xy[i, 1])
                r = surface(geo, kind, m, mode, qx, qy, xy[i, 0], xy[i, 1], depth, step,
                            height, slope)
                out[i, 0] = r[1]
                out[i, 1] = r[2]
        return out

    return run


def lobe_width(diameter_deg: float, alpha: float) -> float:
    """How far a wall's normal may stray from the half vector and still glint,
    radians: the rms of the Beckmann slopes along a direction (alpha / sqrt 2)
    and of the half vector over the light's disc (a quarter of its diameter)."""
    return math.hypot(alpha / math.sqrt(2.0), 0.25 * math.radians(diameter_deg))


def point_glints(plate: Plate, eye: np.ndarray, size_deg: float, alpha: float) -> np.ndarray:
    """(m, 3) where the program's grooves glint as points for an eye (the caps
    a stripe's ends leave and the dots, in verify's streak model), on the
    real tool's wall: the pixels to sample finer."""
    from specholo.optics.spread import Spread
    from specholo.simulation.glints import Engraved, Glints
    from specholo.simulation.streaks import find_streaks
    from specholo.simulation.survival import on_real_wall

    setup, cfg = plate.setup, plate.loaded.config
    if plate.cut_engraved is None:
        plate.cut_engraved = Engraved.from_grooves(plate.cut_grooves, setup.tool)
    st = find_streaks(plate.cut_engraved, eye, setup.light,
                      Spread(math.radians(size_deg), alpha))
    at = np.flatnonzero(st.length == 0.0)
    cells = Glints(st.path[st.run[at]], st.stipple[st.run[at]], st.point[at])
    return on_real_wall(cells, setup.tool, cfg.cutter(), cfg.depth_mm, setup.light, eye)


def light_position(plate: Plate) -> tuple[np.ndarray, float]:
    """Where the light's disc sits and its distance from the plate centre: the
    folder's point light, or a sun's direction far out."""
    light = plate.loaded.config.setup().light
    if light.distance is not None:
        return np.asarray(light.position, dtype=float), float(light.distance)
    return SUN_DISTANCE * np.asarray(light.direction, dtype=float), SUN_DISTANCE


def load_scene(mi: Any, plate: Plate, diameter_deg: float, alpha: float) -> Any:
    """The plate lit by a disc facing it, of the given angular diameter, whose
    radiance gives unit irradiance facing it (so glints compare across light sizes).

    A disc, not a sphere: Mitsuba samples a sphere by the cone it subtends,
    whose 1 - cos(half angle) is 9.5e-8 for the 0.05 deg light, below float32's
    resolution at 1 (6e-8): its glints came out 22% too bright. A disc is
    sampled by area, exact at any size.
    """
    centre, dist = light_position(plate)
    half = math.radians(0.5 * diameter_deg)
    solid = 2.0 * math.pi * (1.0 - math.cos(half))
    radius = dist * math.tan(half)
    aim = np.array([*plate.box.mean(axis=0), 0.0])
    up = [1.0, 0.0, 0.0] if abs(centre[0]) < 0.5 * dist else [0.0, 0.0, 1.0]
    to_world = mi.ScalarTransform4f().look_at(origin=centre.tolist(), target=aim.tolist(),
                                              up=up) @ mi.ScalarTransform4f().scale(radius)
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "direct"},
        "plate": {"type": "ply", "filename": str(plate.mesh),
                  "bsdf": {"type": "roughconductor", "material": "none",
                           "distribution": "beckmann", "alpha": alpha}},
        "light": {"type": "disk", "to_world": to_world,
                  "emitter": {"type": "area", "radiance": {"type": "rgb",
                                                           "value": 1.0 / solid}}},
    })


class Renderer:
    """Mitsuba's integrator on the pixels that can glint, at two sample counts.

    Mitsuba's own film would spend samples on every pixel; here each picture is
    sampled where the camera sees a groove (its cut samples, two pixels more),
    then again, much more densely, about every pixel the first pass lit. A
    glint's lit strip is a fraction of a micrometre across the groove, so a
    pixel's value is a rare hit: the second pass makes the glints' fluxes and
    centroids steady, the first only finds where to look. A cap at a
    stripe's end, a sphere of the tip, lights a spot far smaller still, which
    :meth:`refine` samples at many more (see :data:`SPP_POINTS`).
    """

    #: Samples traced per kernel launch (bounds the memory of one launch).
    CHUNK = 1 << 23

    def __init__(self, mi: Any, dr: Any, scene: Any) -> None:
        self.mi, self.dr, self.scene = mi, dr, scene
        self.integrator = scene.integrator()

    def sample(self, cam: Camera, xs: np.ndarray, ys: np.ndarray, spp: int,
               seed: int) -> np.ndarray:
        """Mean luminance of the pixels (xs, ys), ``spp`` stratified samples each."""
        mi, dr = self.mi, self.dr
        k = max(1, int(round(math.sqrt(spp))))
        spp = k * k
        f, right, up = Camera._frame(cam.eye, cam.target)
        tan_y = cam.tan_x * cam.height / cam.width
        eye = mi.Point3f(*(float(c) for c in cam.eye))
        out = np.empty(len(xs))
        per = max(1, self.CHUNK // spp)
        for lo in range(0, len(xs), per):
            hi = min(lo + per, len(xs))
            n = (hi - lo) * spp
            idx = dr.arange(mi.UInt32, n)
            pix = idx // spp
            s = idx - pix * spp
            sampler = mi.load_dict({"type": "independent"})
            sampler.seed(seed * 7919 + lo, n)
            jitter = sampler.next_2d()
            fx = dr.gather(mi.Float, mi.Float(xs[lo:hi].astype(np.float32)), pix) \
                + (mi.Float(s % k) + jitter.x) / k
            fy = dr.gather(mi.Float, mi.Float(ys[lo:hi].astype(np.float32)), pix) \
                + (mi.Float(s // k) + jitter.y) / k
            a = (2.0 * fx / cam.width - 1.0) * cam.tan_x
            b = (1.0 - 2.0 * fy / cam.height) * tan_y
            d = dr.normalize(mi.Vector3f(*(float(c) for c in f))
                             + a * mi.Vector3f(*(float(c) for c in right))
                             + b * mi.Vector3f(*(float(c) for c in up)))
            spec, _, _ = self.integrator.sample(self.scene, sampler, mi.Ray3f(eye, d))
            lum = np.asarray(mi.luminance(spec), dtype=np.float64)
            out[lo:hi] = lum.reshape(hi - lo, spp).mean(axis=1)
        return out

    def refine(self, cam: Camera, img: np.ndarray, points: np.ndarray, spp: int,
               seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pixels (xs, ys) that see ``points`` (m, 3) sampled again at
        ``spp``, written into ``img``; returns them and their values."""
        px, py = cam.project(points)
        inside = (px >= 0) & (px < cam.width) & (py >= 0) & (py < cam.height)
        flat = np.unique(py[inside].astype(np.int64) * cam.width + px[inside].astype(np.int64))
        ys, xs = np.divmod(flat, cam.width)
        values = self.sample(cam, xs, ys, spp, seed) if len(flat) else np.zeros(0)
        img[ys, xs] = values
        return xs, ys, values

    def picture(self, cam: Camera, plate: Plate, spp: int, spp_fine: int,
                seed: int) -> tuple[np.ndarray, dict[str, int]]:
        """The picture's luminance (height, width), and how many pixels each pass sampled."""
        hf = plate.field
        jj, ii = np.nonzero(hf.z < 0)
        pts = np.stack([hf.origin[0] + ii * hf.resolution, hf.origin[1] + jj * hf.resolution,
                        hf.z[jj, ii]], axis=1)
        px, py = cam.project(pts)
        inside = (px >= 0) & (px < cam.width) & (py >= 0) & (py < cam.height)
        seen = np.zeros((cam.height, cam.width), bool)
        seen[py[inside].astype(np.int64), px[inside].astype(np.int64)] = True
        seen = ndimage.binary_dilation(seen, iterations=2)
        img = np.zeros((cam.height, cam.width))
        ys, xs = np.nonzero(seen)
        img[ys, xs] = self.sample(cam, xs, ys, spp, 2 * seed)
        peak = float(img.max())
        if peak <= 0:
            return img, {"coarse": len(xs), "fine": 0}
        # A pixel above a millionth of the brightest was hit on a lit strip
        # (the Beckmann lobe's tail a few widths out is far fainter): its
        # neighbourhood is sampled again.
        near = ndimage.binary_dilation(img > 1e-6 * peak, iterations=3)
        fy, fx = np.nonzero(near)
        img[fy, fx] = self.sample(cam, fx, fy, spp_fine, 2 * seed + 1)
        return img, {"coarse": len(xs), "fine": len(fx)}


# ---------------------------------------------------------------------------
# Spots


def hit_field(hf: Any, eye: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where rays from the eye meet the cut surface: points (n, 3) and the path
    (n,) whose cut is deepest at each (-1 on the uncut plate)."""
    p, move = _hits(hf, eye, d)
    path = np.where(move >= 0, hf.program.path[np.maximum(move, 0)], -1)
    return p, path.astype(np.int64)


def _hits(hf: Any, eye: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hit_field`'s points (n, 3) and the move (n,) deepest at each.

    Fixed-point steps on the exact surface: sightlines within 30 deg of the
    plate normal against walls of at most 45 deg contract by 0.6 a step.
    """
    t = -eye[2] / d[:, 2]
    for _ in range(40):
        p = eye + t[:, None] * d
        z, _ = hf.surface(p[:, :2])
        t = (z - eye[2]) / d[:, 2]
    p = eye + t[:, None] * d
    # the move whose cut is deepest there, of the four samples' about it (the
    # nearest sample's may be across a crease)
    ny, nx = hf.shape
    ij = np.floor((p[:, :2] - hf.origin) / hf.resolution).astype(np.int64)
    moves = np.stack([hf.moves[np.clip(ij[:, 1] + dj, 0, ny - 1), np.clip(ij[:, 0] + di, 0, nx - 1)]
                      for di in (0, 1) for dj in (0, 1)], axis=1)
    return p, _deepest(hf, p[:, None, :2], moves)[:, 0]


@dataclass
class Sources:
    """Lit pixels' light, shared out among the paths it came from: one row per
    pixel and path (a pixel across a crease gives a row to each side)."""

    pixel: np.ndarray  # (e,) the lit pixel (index into the pixels given)
    path: np.ndarray  # (e,) the path, -1 the uncut plate
    light: np.ndarray  # (e,) the pixel's light from that path
    point: np.ndarray  # (e, 3) where on the cut surface, the glinting sub-rays' mean
    film: np.ndarray  # (e, 2) the same on the film, pixels


def pixel_sources(hf: Any, cam: Camera, px: np.ndarray, py: np.ndarray, w: np.ndarray,
                  light: np.ndarray, width: float) -> Sources:
    """Which paths each lit pixel's light (w, (n,)) came from.

    Each pixel is crossed by :data:`SUB_RAYS` squared sub-rays; each meets the
    cut surface on one path's cut, whose wall there glints by how near its
    normal is to the half vector toward the eye and ``light`` (3,): a Gaussian
    of ``width`` radians (the gloss's and the light's spread together). The
    pixel's light goes to the paths by their sub-rays' glints.
    """
    k = SUB_RAYS
    off = (np.arange(k) + 0.5) / k
    ox, oy = (a.ravel() for a in np.meshgrid(off, off))
    fx = (px[:, None] + ox[None]).ravel()
    fy = (py[:, None] + oy[None]).ravel()
    p, move = _hits(hf, cam.eye, cam.rays(fx, fy))
    grad = _gradients(hf, p[:, :2], move)
    n = np.concatenate([-grad, np.ones((len(p), 1))], axis=1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    v = cam.eye - p
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    to_light = light - p
    h = v + to_light / np.linalg.norm(to_light, axis=1, keepdims=True)
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    angle = np.arccos(np.clip(np.sum(n * h, axis=1), -1.0, 1.0))
    # each pixel's sub-rays against its best one (no underflow where all are dim)
    log = -0.5 * (angle.reshape(-1, k * k) / width) ** 2
    glint = np.exp(log - log.max(axis=1, keepdims=True))
    share = (glint / glint.sum(axis=1, keepdims=True)).ravel()
    pixel = np.repeat(np.arange(len(px)), k * k)
    path = np.where(move >= 0, hf.program.path[np.maximum(move, 0)], -1).astype(np.int64)
    key, row = np.unique(pixel * (int(hf.program.path.max(initial=0)) + 2) + path + 1,
                         return_inverse=True)
    total = np.bincount(row, weights=share)
    sums = [np.bincount(row, weights=share * c) for c in (p[:, 0], p[:, 1], p[:, 2], fx, fy)]
    first = np.zeros(len(key), np.int64)
    first[row[::-1]] = np.arange(len(row))[::-1]
    some = total > 0.0  # a path none of whose sub-rays glints gets none of the light
    first, total = first[some], total[some]
    return Sources(pixel[first], path[first], w[pixel[first]] * total,
                   np.stack([c[some] for c in sums[:3]], axis=1) / total[:, None],
                   np.stack([c[some] for c in sums[3:]], axis=1) / total[:, None])


@dataclass
class Glint:
    """One path's streak in one eye's picture (pieces the eye cannot resolve apart)."""

    path: int
    stipple: int
    flux: float
    point: np.ndarray  # (3,) the centroid followed back to the cut surface
    length: float  # along its principal axis on the plate, rms as a uniform streak's, mm
    extent: float  # lit pixels' full extent along that axis, mm
    fwhm: float  # length where it is at least half as bright per mm as at its brightest, mm
    pieces: int
    pixels: int
    end_distance: float  # from its lit pixels to the nearer end of its path, mm
    axis: np.ndarray  # (2,) unit direction of the streak on the plate
    piece_points: np.ndarray | None = None  # (k, 3) each piece's centroid on the plate
    model_distance: float = math.inf  # to the nearest point-model glint, mm
    own_distance: float = math.inf  # to the point-model glint of its own path, mm
    own_offset: np.ndarray | None = None  # (3,) from that glint to this one, mm
    designed: bool = False  # the streak about its path's point glint


def find_spots(img: np.ndarray, cam: Camera, plate: Plate, pixel: float, light: np.ndarray,
               width: float) -> list[Glint]:
    """Every path's glints in a picture of pixels about ``pixel`` mm on the plate,
    the light (3,) the centre of the rendered light's disc, ``width`` its lobe's
    (see :func:`pixel_sources`)."""
    peak = float(img.max())
    if peak <= 0:
        return []
    lit = img > LIT * peak
    # Lit pixels along one streak are sparse where the wall's lit strip is
    # narrower than a pixel: two pixels' reach joins them.
    lab, n = ndimage.label(ndimage.binary_dilation(lit, iterations=2))
    py, px = np.nonzero(lit)
    src = pixel_sources(plate.field, cam, px, py, img[py, px], light, width)
    # a path's share of a pixel counts where it alone would light one
    some = src.light > LIT * peak
    w, path, points, film = src.light[some], src.path[some], src.point[some], src.film[some]
    comp = lab[py[src.pixel[some]], px[src.pixel[some]]]
    dist = float(np.linalg.norm(cam.target - cam.eye))
    join = EYE_RESOLUTION * dist
    out: list[Glint] = []
    stipple_of = plate.cut_grooves.stipple
    for p in np.unique(path[path >= 0]):
        mine = np.flatnonzero(path == p)
        pieces = np.unique(comp[mine])
        # pieces of one path closer than the eye resolves are one glint
        centres = np.array([np.average(points[mine[comp[mine] == c]], axis=0,
                                       weights=w[mine[comp[mine] == c]]) for c in pieces])
        group = _single_link(centres[:, :2], join)
        for gid in np.unique(group):
            sel = mine[np.isin(comp[mine], pieces[group == gid])]
            ww = w[sel]
            flux = float(ww.sum())
            cx, cy = np.average(film[sel], axis=0, weights=ww)
            centre, _ = hit_field(plate.field, cam.eye, cam.rays(np.array([cx]), np.array([cy])))
            xy = points[sel, :2]
            mu = np.average(xy, axis=0, weights=ww)
            cov = np.cov((xy - mu).T, aweights=ww) if len(sel) > 1 else np.zeros((2, 2))
            vals, vecs = np.linalg.eigh(np.atleast_2d(cov))
            along = (xy - mu) @ vecs[:, -1]
            ends = plate.ends[p]
            end_d = float(np.min(np.linalg.norm(xy[:, None, :] - ends[None], axis=2)))
            out.append(Glint(int(p), int(stipple_of[p]), flux, centre[0],
                             math.sqrt(12.0 * max(float(vals[-1]), 0.0)),
                             float(along.max() - along.min()) + plate.field.resolution,
                             _fwhm(along, ww, pixel), int((group == gid).sum()), len(sel),
                             end_d, vecs[:, -1], centres[group == gid]))
    return out


def _fwhm(along: np.ndarray, weight: np.ndarray, pixel: float) -> float:
    """Length (mm) over which light per mm along a streak is at least half its
    peak. The pixels' centres fall unevenly along an oblique streak, so the
    light per mm is a sum of Gaussians a pixel wide about them, and their
    width is taken back out in quadrature (exact for a Gaussian streak)."""
    h = pixel
    grid = np.arange(along.min() - 3 * h, along.max() + 3 * h, 0.1 * h)
    density = np.zeros(len(grid))
    for lo in range(0, len(along), 256):
        a, w = along[lo:lo + 256], weight[lo:lo + 256]
        density += (w[None, :] * np.exp(-0.5 * ((grid[:, None] - a[None, :]) / h) ** 2)).sum(1)
    half = np.flatnonzero(density >= 0.5 * density.max())
    measured = float(grid[half[-1]] - grid[half[0]]) + 0.1 * h
    kernel = 2.0 * math.sqrt(2.0 * math.log(2.0)) * h
    return math.sqrt(max(measured**2 - kernel**2, 0.0))


def _single_link(xy: np.ndarray, reach: float) -> np.ndarray:
    """Cluster labels of points joined by links shorter than reach."""
    if len(xy) < 2:
        return np.zeros(len(xy), np.int64)
    d = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    return np.asarray(connected_components(d < reach, directed=False)[1])


def typical_flux(glints: list[Glint]) -> float:
    """The typical stipple's flux: the median of the stipples' brightest, weighted
    by their light (as verify's Glints.image takes it)."""
    top: dict[int, float] = {}
    for g in glints:
        top[g.stipple] = max(top.get(g.stipple, 0.0), g.flux)
    lit = np.sort(np.array(list(top.values())))
    if not len(lit):
        return math.nan
    light = np.cumsum(lit)
    return float(lit[np.searchsorted(light, 0.5 * light[-1])])


def image_rule(glints: list[Glint], typical: float) -> list[Glint]:
    """The glints that make the stipples' image (verify's Glints.image on fluxes)."""
    top: dict[int, float] = {}
    for g in glints:
        top[g.stipple] = max(top.get(g.stipple, 0.0), g.flux)
    return [g for g in glints
            if g.flux * FAINT_RATIO >= top[g.stipple] and g.flux * INVISIBLE_RATIO >= typical]


# ---------------------------------------------------------------------------
# One view


def point_model(plate: Plate, eye: np.ndarray) -> Any:
    """The point model's glints for an eye, as verify counts them (its image)."""
    from specholo.simulation.glints import Engraved, find_glints

    if plate.engraved is None:
        plate.engraved = Engraved.from_grooves(plate.loaded.grooves, plate.setup.tool)
    return find_glints(plate.engraved, eye, plate.setup.light).image()


@dataclass
class ModelStreaks:
    """The streak model's view of one head, per eye.

    Attributes:
        ends: the end streaks bright enough to be glints of their own (as its
            end spills, at any distance): path, centre, and brightness over the
            typical stipple's.
        designed: each path's designed streak, as the points (k, 2) of its lit
            cells on the plate (those giving more than a thousandth of its light).
    """

    ends: list[list[tuple[int, np.ndarray, float]]]
    designed: list[dict[int, np.ndarray]]


def model_streaks(plate: Plate, size_deg: float, alpha: float,
                  theta: float) -> ModelStreaks | None:
    """Both eyes' :class:`ModelStreaks` at head azimuth ``theta``; None where the
    library has no streak model."""
    try:
        from specholo.optics.spread import Spread
        from specholo.simulation.streak_verify import eye_streaks
    except ImportError:
        return None
    # the program's grooves, as cut and rendered: where a glint falls at a
    # stripe's very end, the program's rounding decides which side it is on
    found = eye_streaks(plate.cut_grooves, len(plate.loaded.points), plate.setup,
                        Spread(math.radians(size_deg), alpha), np.array([theta]))
    out = []
    cells: list[dict[int, np.ndarray]] = []
    for st in found.streaks:
        lit = np.flatnonzero(st.designed[st.run] & (st.weight > 1e-3 * st.brightness[st.run]))
        order = lit[np.argsort(st.path[st.run[lit]], kind="stable")]
        keys, first = np.unique(st.path[st.run[order]], return_index=True)
        cells.append({int(k): st.point[part, :2] for k, part in
                      zip(keys, np.split(order, first[1:]), strict=True)})
        designed = st.glints()
        top: dict[int, float] = {}
        for stipple, b in zip(designed.stipple.tolist(), designed.brightness.tolist(),
                              strict=True):
            top[stipple] = max(top.get(stipple, 0.0), b)
        lit = np.sort(np.array(list(top.values())))
        typical = float(lit[np.searchsorted(np.cumsum(lit), 0.5 * lit.sum())]) if len(lit) \
            else math.nan
        bright = st.brightness
        keep = [i for i in range(st.count) if not st.designed[i] and bright[i] > 0
                and bright[i] * FAINT_RATIO >= max(typical, top.get(int(st.stipple[i]), typical))]
        out.append([(int(st.path[i]), st.centre[i], float(bright[i] / typical)) for i in keep])
    return ModelStreaks(out, cells)


def _pct(vals: list[float] | np.ndarray, q: float) -> float:
    vals = [v for v in vals if math.isfinite(v)]
    return float(np.percentile(vals, q)) if vals else math.nan


def judge_view(plate: Plate, theta: float, eyes: tuple[np.ndarray, np.ndarray],
               spots: tuple[list[Glint], list[Glint]], pixel: float,
               streak_model: ModelStreaks | None = None) -> dict[str, Any]:
    """What the two eyes meet at one head azimuth, in verify's terms.

    A glint is *designed* where it lies on its path's designed streak in the
    streak model (within STREAK_MATCH of its lit stretch), or without the
    streak model, where the point model has a glint of the same path (the
    same stipple, if the G-code's paths differ from the design's) within
    SPILL of it. Light elsewhere on the path, a cap where the tool lifts or a
    faint piece beyond the lobe, is not the designed glint even where the
    crossings took that away (nearer it than the eye resolves it is part of
    its spot, as in verify); two pieces of a designed streak a crossing
    parts farther than the eye resolves are two designed glints. The rest
    are caps, the ends of stripes whose glint lies just past them, and the
    like. A *spill* is a bright one farther than SPILL from every designed
    glint.
    """
    from specholo.simulation.verify import stereo_errors
    from specholo.visibility.occlusion import visible

    loaded = plate.loaded
    points = np.asarray(loaded.points, dtype=float)
    n = len(points)
    same_paths = plate.same_paths
    kept: list[list[Glint]] = []
    typical: list[float] = []
    model_ends = streak_model.ends if streak_model is not None else None
    for side, (eye, found) in enumerate(zip(eyes, spots, strict=True)):
        model = point_model(plate, eye)
        for g in found:
            if len(model.point):
                d = np.linalg.norm(model.point - g.point, axis=1)
                g.model_distance = float(d.min())
                own = np.flatnonzero(model.path == g.path if same_paths
                                     else model.stipple == g.stipple)
                if len(own):
                    k = own[np.argmin(d[own])]
                    g.own_distance = float(d[k])
                    g.own_offset = g.point - model.point[k]
            if streak_model is not None and same_paths:
                # a piece of it on its path's designed streak, however long the
                # streak: the rest of the path's light nearer than the eye
                # resolves is part of the same spot, as verify gathers it
                cells = streak_model.designed[side].get(g.path)
                at = g.piece_points if g.piece_points is not None else g.point[None]
                g.designed = cells is not None and bool(np.min(np.linalg.norm(
                    cells[:, None, :] - at[None, :, :2], axis=2)) <= STREAK_MATCH)
            else:
                g.designed = g.own_distance <= SPILL
        # the typical stipple's light is its designed glints' (verify's image of them)
        t = typical_flux([g for g in found if g.designed])
        t = t if math.isfinite(t) else typical_flux(found)
        typical.append(t)
        # verify's image of the stipples: the designed glints by its rule among
        # themselves (a bright stripe end of the same stipple does not dim
        # them; it joins them or is a glint of its own, below), the others by
        # the same rule among all, counted apart
        kept.append(image_rule([g for g in found if g.designed], t)
                    + [g for g in image_rule(found, t) if not g.designed])
    if loaded.mesh is not None and loaded.normals is not None:
        vis = [visible(loaded.mesh, points, loaded.normals, e) for e in eyes]
    else:
        vis = [np.ones(n, bool), np.ones(n, bool)]
    seen = vis[0] & vis[1]

    def shown(glints: list[list[Glint]]) -> tuple[float, np.ndarray, np.ndarray]:
        lit = [np.bincount(np.array([g.stipple for g in k], np.int64), minlength=n) > 0
               for k in glints]
        both = np.flatnonzero(seen & lit[0] & lit[1])
        err = np.zeros(0)
        if both.size:
            err, _ = stereo_errors(points, _as_glints(glints[0]), _as_glints(glints[1]),
                                   eyes[0], eyes[1], both)
        return (float(both.size / seen.sum()) if seen.any() else math.nan), err, both

    modelled = [[g for g in k if g.designed] for k in kept]
    # Stripe ends bright enough to be glints of their own (verify's rule for
    # end spills: 1/20 of the typical stipple's light and of their own
    # stipple's brightest designed glint), near designed glints or far. Every
    # glint that bright is found at the default sample counts (sampling every
    # pixel at 256 found none more).
    ends: list[list[Glint]] = []
    for side in range(2):
        best: dict[int, float] = {}
        for g in modelled[side]:
            best[g.stipple] = max(best.get(g.stipple, 0.0), g.flux)
        t = typical[side]
        ends.append([g for g in kept[side] if not g.designed
                     and g.flux * FAINT_RATIO >= max(t, best.get(g.stipple, t))])
    # near or far from the designed glints the eye sees, as verify measures it
    # (a streak's centre may lie well off its point glint)
    gap = [[_nearest_distance(modelled[side], g) for g in ends[side]] for side in range(2)]
    spills = [[g for g, d in zip(k, dk, strict=True) if d > SPILL] for k, dk in zip(ends, gap,
                                                                                   strict=True)]
    near = [[g for g, d in zip(k, dk, strict=True) if d <= SPILL] for k, dk in zip(ends, gap,
                                                                                  strict=True)]
    # What a viewer meets of each stipple: its designed glints and the bright
    # stripe ends beside them (within SPILL of a designed glint, as verify
    # takes them into a stipple's image); the spills farther off are points
    # of their own, counted apart.
    # Fainter glints of their own (mostly the caps a stripe's ends leave,
    # about 1/250 of the typical glint) are counted apart, with verify's own
    # image rule.
    # ... and, as verify does, the image rule again on the merged spots: a
    # stipple's second streak piece past the eye's resolution may be 1/20 of
    # the designed glint alone, and far fainter than the spot it makes.
    image = [image_rule(k, typical_flux(k))
             for k in (_merged(modelled[0], near[0]), _merged(modelled[1], near[1]))]
    visibility, err, both = shown(image)
    visibility_modelled, err_modelled, _ = shown(modelled)
    # the stipples both eyes see whose designed glint one eye's picture lacks
    lacking = [sorted(set(np.flatnonzero(seen).tolist())
                      - {g.stipple for g in modelled[side]}) for side in range(2)]
    visibility_faint, err_faint, _ = shown(kept)
    r_cut = plate.r_cut
    designed = modelled[0] + modelled[1]
    faint = [g for k in kept for g in k if not g.designed]
    tflux = float(np.nanmean(typical)) if any(np.isfinite(typical)) else math.nan

    def at_end(g: Glint) -> bool:
        return g.end_distance <= r_cut + 2.0 * pixel

    matched: int | None = None
    model_only: int | None = None
    if model_ends is not None:
        matched = model_only = 0
        for side in range(2):
            for path, centre, _ in model_ends[side]:
                hit = any(g.path == path and np.linalg.norm(g.point[:2] - centre[:2]) <= END_MATCH
                          for g in ends[side])
                matched += int(hit)
                model_only += int(not hit)
    offsets = [g.own_offset for g in designed if g.own_offset is not None]
    axes = [g.axis for g in designed if g.own_offset is not None]

    return {
        "azimuth": math.degrees(theta),
        "stipples_seen": int(seen.sum()),
        "lacking_designed": {"left": lacking[0], "right": lacking[1]},
        "visibility": visibility,
        "median_error": _pct(err, 50),
        "p95_error": _pct(err, 95),
        "max_error": float(err.max()) if err.size else math.nan,
        # the stipples seen farthest off, to hold against verify's own
        "worst_stipples": [[int(both[k]), float(err[k])] for k in np.argsort(-err)[:10]],
        # and what each eye's picture shows of them: path, flux, place
        "worst_glints": {str(both[k]): [[[g.path, g.flux, g.point.tolist()] for g in side
                                         if g.stipple == both[k]] for side in image]
                         for k in np.argsort(-err)[:10]},
        "visibility_modelled": visibility_modelled,
        "median_error_modelled": _pct(err_modelled, 50),
        "p95_error_modelled": _pct(err_modelled, 95),
        "visibility_faint": visibility_faint,
        "p95_error_faint": _pct(err_faint, 95),
        "glints": [len(k) for k in modelled],
        # verify's end spills: those far from every designed glint, the mean of the eyes
        "end_spills": 0.5 * (len(spills[0]) + len(spills[1])),
        "end_spills_at_end": 0.5 * sum(at_end(g) for k in spills for g in k),
        "end_streaks": len(ends[0]) + len(ends[1]),
        "end_streaks_at_end": sum(at_end(g) for k in ends for g in k),
        "end_streaks_model": None if model_ends is None
        else len(model_ends[0]) + len(model_ends[1]),
        "end_streaks_matched": matched,
        "end_streaks_model_only": model_only,
        "faint_unmodelled": len(faint) - len(ends[0]) - len(ends[1]),
        "split_streaks": sum(g.pieces > 1 for g in designed),
        "median_streak_mm": _pct([g.length for g in designed], 50),
        "median_fwhm_mm": _pct([g.fwhm for g in designed], 50),
        "p95_fwhm_mm": _pct([g.fwhm for g in designed], 95),
        "median_extent_mm": _pct([g.extent for g in designed], 50),
        "median_offset_mm": _pct([g.own_distance for g in designed], 50),
        "p95_offset_mm": _pct([g.own_distance for g in designed], 95),
        # The offset in the plate's plane, along the streak, across it, and in
        # depth: verify's wall is the tool's round model at its own depth
        # (0.007 mm for the default tip, cut 0.011 mm deep), so its glints sit
        # higher on the same normals; in the plate's plane is where a streak's
        # centre moves.
        "median_offset_plate_mm": _pct([float(np.hypot(*o[:2])) for o in offsets], 50),
        "median_offset_along_mm": _pct([abs(float(o[:2] @ a))
                                        for o, a in zip(offsets, axes, strict=True)], 50),
        "median_offset_across_mm": _pct([abs(float(o[0] * a[1] - o[1] * a[0]))
                                         for o, a in zip(offsets, axes, strict=True)], 50),
        "median_offset_depth_mm": _pct([abs(float(o[2])) for o in offsets], 50),
        "designed_flux_p5": _pct([g.flux / tflux for g in designed], 5),
        "unmodelled_list": [
            {"stipple": g.stipple, "path": g.path, "flux_over_typical": g.flux / tflux,
             "from_model_mm": g.model_distance, "from_own_model_mm": g.own_distance,
             "from_path_end_mm": g.end_distance, "length_mm": g.length,
             "end_streak": any(g is e for k in ends for e in k),
             "point": g.point.tolist()} for g in faint],
    }


def _nearest_distance(glints: list[Glint], g: Glint) -> float:
    """How far ``g`` lies from the nearest of ``glints``, mm (inf: none)."""
    if not glints:
        return math.inf
    return float(np.min(np.linalg.norm(np.array([k.point for k in glints]) - g.point, axis=1)))


def _merged(designed: list[Glint], beside: list[Glint]) -> list[Glint]:
    """Each designed glint with the light of the bright stripe ends within SPILL
    of it (nearer it than any other) at their flux-weighted centre: a viewer
    sees one spot there, as verify's image of the stipples has it."""
    if not designed or not beside:
        return designed
    pts = np.array([g.point for g in designed])
    flux = np.array([g.flux for g in designed], dtype=float)
    moment = pts * flux[:, None]
    for g in beside:
        d = np.linalg.norm(pts - g.point, axis=1)
        i = int(np.argmin(d))
        if d[i] <= SPILL:
            flux[i] += g.flux
            moment[i] += g.point * g.flux
    return [dataclasses.replace(g, point=moment[i] / flux[i], flux=float(flux[i]))
            for i, g in enumerate(designed)]


def _as_glints(k: list[Glint]) -> Any:
    from specholo.simulation.glints import Glints

    order = sorted(range(len(k)), key=lambda i: k[i].stipple)
    return Glints(np.array([k[i].path for i in order], np.int64),
                  np.array([k[i].stipple for i in order], np.int64),
                  np.array([k[i].point for i in order]).reshape(-1, 3))


# ---------------------------------------------------------------------------
# verify


def verify_rows(folder: Path, azimuths: list[float], step: float,
                light_size: float | None = None, alpha: float | None = None) -> dict[str, Any]:
    """``specholo verify`` on the folder: its figures at the rendered azimuths,
    ideal and as cut.

    Each model is verified as verify does by default (the design's grooves)
    and with ``--cut``, which reads the grooves back from the G-code and
    verifies them as cut (``ideal_gcode``: the G-code's grooves uncut).
    """
    base = [sys.executable, "-m", "specholo_cli.cli", "verify", str(folder), "--step", f"{step:g}"]
    spread = [] if light_size is None else ["--light-size", f"{light_size:g}",
                                            "--roughness", f"{alpha:g}"]
    runs = [(spread, {"ideal": "verify.json"}),
            (["--cut", *spread], {"ideal_gcode": "verify.json", "cut": "verify_cut.json"})]
    out: dict[str, Any] = {}
    for extra, files in runs:
        subprocess.run(base + extra, check=True, stdout=subprocess.DEVNULL)
        for key, name in files.items():
            rows = json.loads((folder / name).read_text()).get("azimuths") or []
            out[key] = {f"{a:g}": next((r for r in rows if abs(r["azimuth"] - a) < 1e-6), {})
                        for a in azimuths}
    return out


def has_streak_model() -> bool:
    """Whether this specholo's verify takes a light's size and a roughness."""
    help_text = subprocess.run([sys.executable, "-m", "specholo_cli.cli", "verify", "--help"],
                               check=True, capture_output=True, text=True).stdout
    return "--light-size" in help_text and "--roughness" in help_text


def common_step(azimuths: list[float], half_range: float) -> float:
    """A verify step whose views include every rendered azimuth."""
    for step in (5.0, 2.5, 1.0, 0.5, 0.25, 0.1):
        n = int(math.ceil(2.0 * half_range / step - 1e-9)) + 1
        grid = np.linspace(-half_range, half_range, max(n, 1))
        if all(np.min(np.abs(grid - a)) < 1e-6 for a in azimuths):
            return step
    raise SystemExit(f"error: no verify step of at least 0.1 deg puts views at {azimuths}")


# ---------------------------------------------------------------------------
# Main


def _fmt(v: Any, fmt: str = ".2f") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return format(v, fmt)


def _verify(row: dict[str, Any], model: str, kind: str, key: str) -> Any:
    figures = row["verify"].get(model) or {}
    return (figures.get(kind) or {}).get(key)


def _beside(row: dict[str, Any], key: str, fmt: str) -> str:
    """A figure as rendered (every glint, the modelled ones) and as verified."""
    v = row["render"]
    return " / ".join([_fmt(v[key], fmt), _fmt(v[key + "_modelled"], fmt)]
                      + [_fmt(_verify(row, m, k, key), fmt) for m in ("point", "streak")
                         for k in ("ideal", "cut")])


def markdown(rows: list[dict[str, Any]]) -> str:
    """Two tables, one row per plate, light, roughness and view: what the
    stereo pairs see, then the streaks and spills."""
    head = "| plate | light | alpha | azimuth | "
    stereo = [head + "visibility: render / render, designed glints / point / point as cut / "
              "streak / streak as cut | p95 error mm: render / render, designed glints / point / "
              "point as cut / streak / streak as cut |", "|---|---|---|---|---|---|"]
    streaks = [head + "end spills an eye: render (at an end) / streak / streak on the G-code / "
               "streak as cut | "
               "streak mm (median FWHM): render / streak | centre from point glint mm "
               "(median): render in the plate's plane / render / streak / streak as cut | "
               "bright stripe ends, both eyes: render (at an end) / streak / both | "
               "streaks split |",
               "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        v = r["render"]
        lead = f"| {r['plate']} | {r['light']} | {r['alpha']:g} | {r['azimuth']:+.0f} | "

        stereo.append(lead + _beside(r, "visibility", ".2f") + " | "
                      + _beside(r, "p95_error", ".3f") + " |")
        streaks.append(
            lead + f"{v['end_spills']:g} ({v['end_spills_at_end']:g}) / "
            f"{_fmt(_verify(r, 'streak', 'ideal', 'end_spills'), 'g')} / "
            f"{_fmt(_verify(r, 'streak', 'ideal_gcode', 'end_spills'), 'g')} / "
            f"{_fmt(_verify(r, 'streak', 'cut', 'end_spills'), 'g')} | "
            f"{_fmt(v['median_fwhm_mm'], '.3f')} / "
            f"{_fmt(_verify(r, 'streak', 'ideal', 'streak_length'), '.3f')} | "
            f"{_fmt(v['median_offset_plate_mm'], '.4f')} / {_fmt(v['median_offset_mm'], '.4f')} / "
            f"{_fmt(_verify(r, 'streak', 'ideal', 'centre_shift'), '.4f')} / "
            f"{_fmt(_verify(r, 'streak', 'cut', 'centre_shift'), '.4f')} | "
            f"{v['end_streaks']} ({v['end_streaks_at_end']}) / "
            f"{_fmt(v['end_streaks_model'], 'd')} / "
            f"{_fmt(v['end_streaks_matched'], 'd')} | "
            f"{v['split_streaks']} |")
    return "\n".join(stereo) + "\n\n" + "\n".join(streaks)


def _rounded(obj: Any) -> Any:
    """Floats to 6 significant digits (far below what the pictures resolve), for
    a file that reads and diffs."""
    if isinstance(obj, dict):
        return {k: _rounded(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_rounded(v) for v in obj]
    if isinstance(obj, float | np.floating):
        v = float(obj)
        return float(f"{v:.6g}") if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", type=Path, default=None,
                    help="folder for the designs and meshes [a temporary one]")
    ap.add_argument("--redesign", action="store_true", help="design again over --work's folders")
    ap.add_argument("--plates", nargs="+", default=list(DEFAULT_PLATES), choices=list(PLATES))
    ap.add_argument("--lights", nargs="+", default=[n for n, _ in LIGHTS],
                    choices=[n for n, _ in LIGHTS])
    ap.add_argument("--alphas", nargs="+", type=float, default=list(ALPHAS),
                    help="Beckmann roughness of the plate")
    ap.add_argument("--azimuths", nargs="+", type=float, default=[-20.0, 0.0, 20.0],
                    help="head azimuths, degrees")
    ap.add_argument("--spp", type=int, default=16,
                    help="samples per pixel, first pass (a square number)")
    ap.add_argument("--spp-fine", type=int, default=1024,
                    help="samples per pixel about what the first pass lit (a square number)")
    ap.add_argument("--spp-points", type=int, default=SPP_POINTS,
                    help="samples per pixel where the grooves glint as points (caps, dots); "
                         "0: as the rest")
    ap.add_argument("--pixel", type=float, default=0.003, help="pixel on the plate, mm")
    ap.add_argument("--quick", action="store_true",
                    help="one plate, the sun, alpha 0.003, azimuth 0 (a smoke run)")
    ap.add_argument("--stipples", type=int, default=None,
                    help="stipples of every plate (denser plates resolve visibility finer: "
                         "one stipple of 32 seen is 0.031)")
    ap.add_argument("--reuse-pictures", action="store_true",
                    help="take each view's picture from --work where an earlier run kept it "
                         "at the same sample counts (to judge again without rendering; the "
                         "pictures are of the plates as that run cut and meshed them)")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    # specholo's kernels (and the designs and verifications it runs) keep to one
    # core too, unless asked otherwise.
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    mi, dr = import_mitsuba()
    plates: list[str] = args.plates
    lights: list[tuple[str, float]] = [(n, d) for n, d in LIGHTS if n in args.lights]
    alphas: list[float] = list(args.alphas)
    azimuths: list[float] = args.azimuths
    if args.quick:
        plates, lights, alphas, azimuths = plates[:1], lights[:1], alphas[:1], [0.0]
    load0 = os.getloadavg()
    started = datetime.datetime.now().astimezone()
    t_all = time.perf_counter()
    tmp = None
    if args.work is None:
        tmp = tempfile.TemporaryDirectory(prefix="render_judge-")
        work = Path(tmp.name)
    else:
        work = args.work
        work.mkdir(parents=True, exist_ok=True)
    streaks = has_streak_model()
    rows: list[dict[str, Any]] = []
    plates_out: dict[str, Any] = {}
    render_seconds: list[float] = []
    reused = 0  # pictures taken from an earlier run (their seconds are not a render's)
    for name in plates:
        folder = design_plate(name, work, args.redesign, args.stipples)
        plate = cut_plate(name, folder, work, azimuths)
        setup = plate.loaded.config.setup()
        step = common_step(azimuths, math.degrees(setup.viewer.half_range))
        t0 = time.perf_counter()
        point_verify = verify_rows(folder, azimuths, step)
        info = json.loads((folder / "hologram.json").read_text())
        plates_out[name] = {
            "design": plate_options(name, args.stipples),
            "stipples": int(len(plate.loaded.points)),
            "stipples_with_grooves": info["stats"].get("stipples_with_grooves"),
            "paths": int(plate.cut_grooves.n_paths),
            "groove_mm": float(info["stats"].get("groove_length_mm", math.nan)),
            "rendered_region_mm": plate.box.tolist(),
            "field_samples": list(plate.field.shape), "mesh_vertices": plate.vertices,
            "mesh_faces": plate.faces, "cut_seconds": plate.cut_seconds,
            "verify_seconds": time.perf_counter() - t0,
        }
        target = np.array([*plate.box.mean(axis=0), 0.0])
        cams: dict[float, tuple[Camera, Camera]] = {}
        for a in azimuths:
            left, right = setup.viewer.stereo(np.array([math.radians(a)]))
            cams[a] = (Camera.framing(left[0], target, plate.box, args.pixel),
                       Camera.framing(right[0], target, plate.box, args.pixel))
        plates_out[name]["camera_check_rad"] = check_camera(mi, cams[azimuths[0]][0])
        for light_name, size in lights:
            for alpha in alphas:
                t0 = time.perf_counter()
                scene = load_scene(mi, plate, size, alpha)
                light_at, _ = light_position(plate)
                renderer = Renderer(mi, dr, scene)
                scene_s = time.perf_counter() - t0
                streak_verify = (verify_rows(folder, azimuths, step, size, alpha)
                                 if streaks else None)
                for a in azimuths:
                    found, sampled = [], []
                    for side, cam in zip(("left", "right"), cams[a], strict=True):
                        t0 = time.perf_counter()
                        kept = folder / (f"picture-{light_name}-{alpha:g}-{a:g}-{side}-"
                                         f"{args.spp}-{args.spp_fine}.npz")
                        if args.reuse_pictures and kept.exists():
                            reused += 1
                            with np.load(kept) as f:
                                img = f["img"]
                                counts = dict(zip(("coarse", "fine"),
                                                  (int(c) for c in f["counts"]), strict=True))
                        else:
                            img, counts = renderer.picture(cam, plate, args.spp,
                                                           args.spp_fine,
                                                           seed=len(render_seconds))
                            if tmp is None:
                                np.savez_compressed(kept, img=img, counts=np.array(
                                    [counts["coarse"], counts["fine"]]))
                        # the point glints, sampled finer (kept apart, so a
                        # picture kept from before is refined the same way)
                        caps = kept.with_name(kept.stem.replace("picture-", "points-")
                                              + f"-{args.spp_points}.npz")
                        if args.reuse_pictures and caps.exists():
                            with np.load(caps) as f:
                                xs, ys, values = f["xs"], f["ys"], f["values"]
                            img[ys, xs] = values
                        elif args.spp_points > 0:
                            xs, ys, values = renderer.refine(
                                cam, img, point_glints(plate, cam.eye, size, alpha),
                                args.spp_points, seed=len(render_seconds) + 10_000)
                            if tmp is None:
                                np.savez_compressed(caps, xs=xs, ys=ys, values=values)
                        counts["points"] = len(xs) if args.spp_points > 0 else 0
                        render_seconds.append(time.perf_counter() - t0)
                        found.append(find_spots(img, cam, plate, args.pixel, light_at,
                                                lobe_width(size, alpha)))
                        sampled.append(counts)
                    model = (model_streaks(plate, size, alpha, math.radians(a))
                             if streaks else None)
                    view = judge_view(plate, math.radians(a), (cams[a][0].eye, cams[a][1].eye),
                                      (found[0], found[1]), args.pixel, model)
                    key = f"{a:g}"
                    if tmp is None:
                        # each eye's glints, kept with the folder to study one stipple
                        dump = folder / f"render-{light_name}-{alpha:g}-{key}.json"
                        dump.write_text(json.dumps(_rounded({
                            side: [{"stipple": g.stipple, "path": g.path, "flux": g.flux,
                                    "point": g.point.tolist(), "length": g.length,
                                    "from_own_model_mm": g.own_distance}
                                   for g in k]
                            for side, k in zip(("left", "right"), found, strict=True)})))
                    verified = {"point": {k: point_verify[k][key] for k in point_verify}}
                    if streak_verify is not None:
                        verified["streak"] = {k: streak_verify[k][key] for k in streak_verify}
                    row: dict[str, Any] = {
                        "plate": name, "light": light_name, "light_diameter_deg": size,
                        "alpha": alpha, "azimuth": a, "render": view, "verify": verified,
                        "film": [cams[a][0].width, cams[a][0].height],
                        "scene_seconds": scene_s,
                        "render_seconds": render_seconds[-2:], "pixels_sampled": sampled,
                    }
                    rows.append(row)
                    text = markdown([row]).split("\n\n")
                    print(text[0].splitlines()[-1] + "\n" + text[1].splitlines()[-1], flush=True)
                del scene
    total = time.perf_counter() - t_all
    result = {
        "what": "glints of small plates as cut, rendered with Mitsuba 3, against specholo verify",
        "date": started.isoformat(timespec="seconds"),
        "machine": {"cores": os.cpu_count(), "load_before": load0,
                    "load_after": os.getloadavg(), "platform": platform.platform(),
                    "python": platform.python_version()},
        "mitsuba": {"version": mi.__version__, "drjit": dr.__version__, "variant": "llvm_ad_rgb",
                    "threads": 1, "integrator": "direct", "spp": args.spp,
                    "spp_fine": args.spp_fine, "spp_points": args.spp_points,
                    "pixel_mm": args.pixel, "field_mm": RESOLUTION,
                    "sun_distance_mm": SUN_DISTANCE},
        "rules": {"spill_mm": SPILL, "faint_ratio": FAINT_RATIO,
                  "invisible_ratio": INVISIBLE_RATIO,
                  "join_arcmin": 1.0, "lit": LIT},
        "streak_model_in_verify": streaks,
        "pictures_reused": reused,
        "seconds": {"total": total, "render_total": sum(render_seconds),
                    "render_median": float(np.median(render_seconds)) if render_seconds
                    else math.nan},
        "plates": plates_out,
        "views": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(_rounded(result), indent=1) + "\n")
    print()
    print(markdown(rows))
    median = float(np.median(render_seconds)) if render_seconds else math.nan
    from_before = f", {reused} of them kept from an earlier run" if reused else ""
    print(f"\n{len(render_seconds)} pictures{from_before} in {sum(render_seconds):.0f} s of "
          f"rendering (median {median:.1f} s, llvm_ad_rgb, 1 thread, "
          f"{args.spp}/{args.spp_fine} spp); whole run {total:.0f} s; load {load0[0]:.2f} before, "
          f"{os.getloadavg()[0]:.2f} after -> {args.out}")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()

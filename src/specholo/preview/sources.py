"""Each kind of design as a :class:`~specholo.preview.source.PictureSource`.

Every source finds its glints with its kind's own finder, the one its
verification uses: a flat plate's :func:`~specholo.simulation.glints.find_glints`,
a ridged plate's :func:`~specholo.simulation.heightfield.find_field_glints`, a
composition's :func:`~specholo.simulation.conforming.find_conforming_glints`, a
turning plate's :func:`~specholo.simulation.spinning.find_spin_glints` and a
steady image's :func:`~specholo.simulation.steady.find_steady_glints`. Each is
built by its job from the folder's files (``Job.picture_source``).

Frames. Every source speaks in the frame its kind is designed in, and a
:class:`~specholo.preview.render.Camera` placed by the source's viewer lands on
the design's own eyes: a flat plate, a ridged plate, a composition and a steady
image face +z with y up, their eyes on a circle about (0, eye height, 0). A
turning plate lies in z = 0 with its viewer at (0, -D cos e, D sin e) (D the
distance, e the elevation above the plate); its viewer's circle is drawn about
(0, -D cos e, 0) with radius about D sin e, so that azimuth 0 is the design's
head and the camera's up is the world's (toward +z, seen from the front), and
its glints, found in the turned plate's frame, are turned back into the world.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import threading
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.hosts.surfaces import Cylinder, HeightField, Host, MeshHost, Panels, Plane, Sphere
from specholo.preview.render import Camera, Spots, line_coverage
from specholo.preview.source import BaseSource, Motion, PictureSource
from specholo.setup import Light, Setup, Tool, Viewer


class FlatSource(BaseSource):
    """A flat plate of grooves (``specholo design``): glints on its engraved arcs,
    along the head's azimuth; its page recomputes them live in the browser.

    Args:
        grooves: the grooves (``Grooves``).
        setup: the design's setup.
        plate: (2, 2) the plate's corners the files name, mm; default the
            grooves' extent with a margin.
        model: the model (a mesh, or (n, 3) points) for ``--ghost``, or None.
    """

    title = "a flat-plate design"
    grooves = True

    def __init__(self, grooves: Any, setup: Setup, plate: np.ndarray | None = None,
                 model: Any = None) -> None:
        from specholo.preview.render import plate_bounds

        self.groove_set = grooves
        self.setup = setup
        self.bounds = plate_bounds(grooves) if plate is None else np.asarray(plate, dtype=float)
        r = setup.viewer.half_range
        self.motion = Motion("turntable", "head azimuth", -r, r)
        self.model = model
        self.spread: Any = None
        self._eng: Any = None
        self._lock = threading.Lock()

    def lit_by(self, spread: Any) -> FlatSource:
        """The same plate drawn under a light of real size on a surface of real gloss
        (a :class:`~specholo.optics.spread.Spread`): each glint the streak it makes
        along its groove, end spills and all."""
        other = copy.copy(self)
        other.spread = spread
        other._eng, other._lock = self.engraved(), threading.Lock()  # one index for both
        return other

    def spots(self, eye: np.ndarray, state: float | None, roughness: float) -> Spots:
        if self.spread is None:
            return super().spots(eye, state, roughness)
        from specholo.preview.render import spot_sigma
        from specholo.simulation.streaks import find_streaks

        st = find_streaks(self.engraved(), eye, self.setup.light, self.spread)
        designed = st.brightness[st.designed & (st.brightness > 0)]
        # a typical streak draws as one glint does; each cell its share of that
        typical = float(np.median(designed)) if len(designed) else 1.0
        return st.point, spot_sigma(self.setup, roughness), st.weight / typical

    def engraved(self) -> Any:
        """The grooves prepared for the glint search (built once, shared)."""
        from specholo.simulation.glints import Engraved

        with self._lock:
            if self._eng is None:
                self._eng = Engraved.from_grooves(self.groove_set, self.setup.tool)
            return self._eng

    def prepare(self) -> None:
        self.engraved()

    def glints(self, eye: np.ndarray, state: float | None) -> np.ndarray:
        from specholo.preview.render import glints_seen
        from specholo.simulation.glints import find_glints
        from specholo.simulation.verify import CHUNK_VERTICES

        if self._eng is None and len(self.groove_set.vertices) > CHUNK_VERTICES:
            # a large design is searched a run of paths at a time (its index whole
            # would not fit); each glint lies on one path, so the glints are the same
            return glints_seen(self.groove_set, self.setup.tool, np.asarray(eye)[None],
                               self.setup.light)[0]
        return find_glints(self.engraved(), eye, self.setup.light).point

    def ghost(self, state: float | None) -> Any:
        return self.model

    def overlay(self, camera: Camera, state: float | None) -> np.ndarray | None:
        from specholo.preview.render import groove_coverage

        return groove_coverage(camera, self.engraved())

    def relit(self, elevation: float) -> PictureSource:
        other = copy.copy(self)
        other.setup = _relit(self.setup, elevation)
        other._eng, other._lock = self.engraved(), threading.Lock()  # one index for both
        return other

    def page(self, title: str, size: tuple[int, int] | None) -> str | None:
        from specholo.preview.page import build_page

        return build_page(self.groove_set, self.setup, title, size)


class FieldSource(BaseSource):
    """A ridged plate (a height field, no grooves): glints on its exact heights,
    over the head's azimuth and elevation ranges.

    Args:
        heights: the labelled plate (``HeightMap``).
        setup: the design's setup (a clear plate's light behind it).
        elevation_range: the heads' elevation range, radians.
        model: the model for ``--ghost``, or None.
        facts: the design in rows, for the report.
    """

    title = "a ridged design"

    def __init__(self, heights: Any, setup: Setup, elevation_range: float, model: Any = None,
                 facts: list[tuple[str, str]] | None = None) -> None:
        from specholo.preview.render import field_plate

        self.heights = heights
        self.setup = setup
        self.bounds = field_plate(heights)
        self.elevation_range = float(elevation_range)
        r = setup.viewer.half_range
        self.motion = Motion("turntable", "head azimuth", -r, r)
        self.model = model
        self.facts = facts or []
        self._index: Any = None
        self._lock = threading.Lock()

    def prepare(self) -> None:
        from specholo.simulation.heightfield import SlopeIndex

        with self._lock:
            if self._index is None:
                self._index = SlopeIndex.build(self.heights)

    def _found(self, eye: np.ndarray) -> Any:
        from specholo.simulation.heightfield import find_field_glints

        field = self.heights if self._index is None else self._index
        return find_field_glints(field, eye, self.setup.light)

    def glints(self, eye: np.ndarray, state: float | None) -> np.ndarray:
        return np.asarray(self._found(eye).glints.point)

    def spots(self, eye: np.ndarray, state: float | None,
              roughness: float) -> Spots:
        from specholo.preview.render import field_spot_sigma

        g = self._found(eye)
        # a glint's spot spreads over its lit cells, as the still of a ridged plate draws it
        return g.glints.point, field_spot_sigma(g, self.heights.resolution, roughness)

    def ghost(self, state: float | None) -> Any:
        return self.model

    def relit(self, elevation: float) -> PictureSource:
        self.prepare()
        other = copy.copy(self)
        other.setup = _relit(self.setup, elevation)
        other._index, other._lock = self._index, threading.Lock()  # one index for both
        return other


def _relit(setup: Setup, elevation: float) -> Setup:
    """``setup`` with its light (a sun, a point light, a light behind a clear
    plate) moved to ``elevation``, radians."""
    return dataclasses.replace(setup, light=dataclasses.replace(setup.light,
                                                                elevation=elevation))


def host_box(host: Host, grooves: Any, reach: float = 0.0, margin: float = 5.0) -> np.ndarray:
    """(2, 2) the host's box seen from the front (x, y), mm: a plane's own size,
    or its grooves' extent plus ``margin`` where it is unbounded. A cylinder's or
    a sphere's is widened for eyes up to ``reach`` (radians) to either side:
    its silhouette, a radius behind the front, moves sideways by the radius
    times the sine of the eye's azimuth."""
    if isinstance(host, Cylinder | Sphere):
        r = host.radius
        w = r * (1.0 + math.sin(min(abs(reach), 0.5 * math.pi)))
        h = 0.5 * host.height if isinstance(host, Cylinder) else r
        return np.array([[-w, -h], [w, h]])
    if isinstance(host, HeightField):
        return np.array([[host.x[0], host.y[0]], [host.x[-1], host.y[-1]]])
    if isinstance(host, MeshHost):
        return np.asarray(host.mesh.bounds, dtype=float)[:, :2].copy()
    if isinstance(host, Panels):
        corners = np.concatenate([_panel_corners(p) for p in host.panels])
        return np.stack([corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)])
    if isinstance(host, Plane) and math.isfinite(host.width) and math.isfinite(host.height):
        return np.array([[-0.5 * host.width, -0.5 * host.height],
                         [0.5 * host.width, 0.5 * host.height]])
    point = np.asarray(grooves.point, dtype=float)
    if len(point) == 0:
        return np.array([[-10.0, -10.0], [10.0, 10.0]])
    lo = np.nanmin(point[:, :2], axis=0) - margin
    hi = np.nanmax(point[:, :2], axis=0) + margin
    return np.stack([lo, hi])


def _panel_corners(panel: Any) -> np.ndarray:
    """The four corners (4, 3) of a panel, counter-clockwise seen from its front."""
    c, right, up, _ = panel.frame()
    w, h = 0.5 * panel.width, 0.5 * panel.height
    return np.stack([c - w * right - h * up, c + w * right - h * up,
                     c + w * right + h * up, c - w * right + h * up])


def host_lines(host: Host, eye: np.ndarray) -> list[np.ndarray]:
    """A host's edges as polylines (each (k, 3), mm), as an eye (3,) sees them: a
    cylinder's silhouette and the near halves of its rims, a sphere's
    silhouette, a height field's and each panel's border, a mesh's silhouette
    and open borders; none for a plane (it is drawn as the plate)."""
    eye = np.asarray(eye, dtype=float)
    if isinstance(host, Cylinder):
        r, h, zc = host.radius, 0.5 * host.height, host.axis_z
        # the sightlines from the eye touch the cylinder acos(r / d) either side
        # of the eye's direction from the axis (angles from +z toward +x)
        vx, vz = eye[0], eye[2] - zc
        d = math.hypot(vx, vz)
        mid = math.atan2(vx, vz)
        reach = math.acos(r / d) if d > r else math.pi
        t = np.linspace(mid - reach, mid + reach, 97)
        rims = [np.stack([r * np.sin(t), np.full_like(t, y), zc + r * np.cos(t)], axis=1)
                for y in (-h, h)]
        sides = [np.array([[r * math.sin(a), -h, zc + r * math.cos(a)],
                           [r * math.sin(a), h, zc + r * math.cos(a)]])
                 for a in (mid - reach, mid + reach)] if d > r else []
        return rims + sides
    if isinstance(host, Sphere):
        # the circle where the sightlines from the eye touch the sphere
        v = eye - host.centre
        d = float(np.linalg.norm(v))
        r = host.radius
        if d <= r:
            return []
        w = v / d
        u = np.cross(w, [0.0, 1.0, 0.0]) if abs(w[1]) < 0.9 else np.cross(w, [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        up = np.cross(w, u)
        a = np.linspace(0.0, 2.0 * math.pi, 97)[:, None]
        centre = host.centre + (r * r / d) * w
        radius = r * math.sqrt(1.0 - (r / d) ** 2)
        return [centre + radius * (np.cos(a) * u + np.sin(a) * up)]
    if isinstance(host, HeightField):
        x, y, z = host.x, host.y, host.z
        return [np.stack([x, np.full_like(x, y[0]), z[0]], axis=1),
                np.stack([np.full_like(y, x[-1]), y, z[:, -1]], axis=1),
                np.stack([x, np.full_like(x, y[-1]), z[-1]], axis=1),
                np.stack([np.full_like(y, x[0]), y, z[:, 0]], axis=1)]
    if isinstance(host, Panels):
        return [np.concatenate([q, q[:1]]) for q in map(_panel_corners, host.panels)]
    if isinstance(host, MeshHost):
        return _mesh_edges(host.mesh, eye)
    return []


def _mesh_edges(mesh: Any, eye: np.ndarray) -> list[np.ndarray]:
    """A mesh's silhouette from an eye (3,) (edges between a face turned toward
    it and one turned away) and its open borders, each edge a polyline."""
    v = np.asarray(mesh.vertices, dtype=float)
    centres = np.asarray(mesh.triangles_center, dtype=float)
    toward = np.einsum("ij,ij->i", np.asarray(mesh.face_normals, dtype=float),
                       eye - centres) > 0
    pairs = np.asarray(mesh.face_adjacency).reshape(-1, 2)
    edges = np.asarray(mesh.face_adjacency_edges).reshape(-1, 2)
    turn = edges[toward[pairs[:, 0]] != toward[pairs[:, 1]]]
    # an edge of one face only is a border
    unique, count = np.unique(np.sort(np.asarray(mesh.edges), axis=1), axis=0,
                              return_counts=True)
    every = np.concatenate([turn, unique[count == 1]])
    return [v[e] for e in every]


class ComposedSource(BaseSource):
    """A composition (``specholo compose``): glints on grooves that follow any
    host, along its motion (the head walking past, or the light moving while
    the viewer stands still).

    Args:
        grooves: the ``ConformingGrooves``.
        host: their host.
        tool: the tool that cuts them.
        motion: the composition's ``MotionSpec``.
        scenes: (``SceneKey``, points (n, 3)) of each scene, for ``--ghost``.
        facts: the design in rows, for the report.
    """

    title = "a composition"
    grooves = True

    def __init__(self, grooves: Any, host: Host, tool: Tool, motion: Any,
                 scenes: list[tuple[Any, np.ndarray]] | None = None,
                 facts: list[tuple[str, str]] | None = None) -> None:
        self.conforming = grooves
        self.host = host
        self.spec = motion
        self.scenes = scenes or []
        self.facts = facts or []
        self.setup = Setup(Light(motion.light_elevation, motion.light_distance),
                           Viewer(motion.view_distance, motion.eye_height, motion.half_range,
                                  motion.ipd), tool)
        self.bounds = host_box(host, grooves, motion.half_range + motion.eye_half_angle)
        if motion.mode == "walk":
            r = motion.half_range
            self.motion = Motion("turntable", "head azimuth", -r, r)
        else:
            lo, hi = sorted((motion.light_elevation, motion.light_stop))
            self.motion = Motion("light", "light elevation", lo, hi,
                                 own=motion.light_elevation)
            half = motion.eye_half_angle
            self.eyes = (-half, half)  # the still viewer's two eyes

    def plate(self, state: float | None) -> np.ndarray | None:
        return self.bounds if isinstance(self.host, Plane) else None

    def outline(self, state: float | None) -> list[np.ndarray]:
        # as the eye on the eyes' circle at the state's azimuth sees the host
        # (a walk's state is the eye's azimuth; a still viewer is at azimuth 0)
        azimuth = state if self.motion.moves_eye and state is not None else 0.0
        v = self.setup.viewer
        eye = Camera(azimuth, 0.0, v.eye_radius, 1.0, 2, 2, v.height).position()
        return host_lines(self.host, eye)

    def glints(self, eye: np.ndarray, state: float | None) -> np.ndarray:
        from specholo.simulation.conforming import find_conforming_glints

        m = self.spec
        elevation = m.light_elevation if m.mode == "walk" or state is None else state
        light = Light(float(elevation), m.light_distance)
        position = light.position
        vec = light.direction if position is None else position
        return find_conforming_glints(self.conforming, self.host, np.asarray(eye, dtype=float),
                                      vec, position is not None, self.setup.tool).point

    def ghost(self, state: float | None) -> Any:
        # scenes are keyed to the driver: the head's azimuth, or the light's elevation
        key = self.motion.own if state is None else state
        if key is None:
            key = 0.0
        shown = [k.pose(p, np.array([key]))[:, 0] for k, p in self.scenes
                 if k.start <= key < k.stop]
        return np.concatenate(shown) if shown else np.zeros((0, 3))

    def overlay(self, camera: Camera, state: float | None) -> np.ndarray | None:
        return line_coverage(camera, self.conforming.paths())

    def relit(self, elevation: float) -> PictureSource:
        if self.spec.mode != "walk":
            return super().relit(elevation)
        return ComposedSource(self.conforming, self.host, self.setup.tool,
                              dataclasses.replace(self.spec, light_elevation=elevation),
                              self.scenes, self.facts)


class SpinSource(BaseSource):
    """A turning plate (``specholo spin``): glints on its closed (or sliding)
    grooves, along the plate's angle over a whole turn, seen from the design's
    still eyes (see the module's notes on the frame).

    Args:
        design: the ``SpinDesign``.
        tool: the ball that cut it.
        plate: (2, 2) the blank's corners in the plate's frame, mm.
        model: the model in the plate's frame (a mesh, or (n, 3) points), or None.
        facts: the design in rows, for the report.
    """

    title = "a turning-plate design"
    grooves = True

    def __init__(self, design: Any, tool: Tool, plate: np.ndarray, model: Any = None,
                 facts: list[tuple[str, str]] | None = None) -> None:
        s = design.setup
        self.design = design
        self.tool = tool
        self.blank = np.asarray(plate, dtype=float)
        self.model = model
        self.facts = facts or []
        across = s.distance * math.sin(s.elevation)  # the eyes' height over the plate
        if not across > s.ipd:
            raise SpecholoError(
                f"{self.title} seen from {math.degrees(s.elevation):g} deg at "
                f"{s.distance:g} mm has its eyes too near the plate's plane to place a camera")
        viewer = Viewer(across, -s.distance * math.cos(s.elevation), 0.0, s.ipd)
        half = viewer.eye_half_angle
        # the head's own azimuth range: from one eye to the other
        self.setup = Setup(Light(0.5 * math.pi, s.light_height),
                           dataclasses.replace(viewer, half_range=half), tool)
        self.eyes = (-half, half)
        self.motion = Motion("turn", "plate angle", 0.0, 2.0 * math.pi, own=0.0, closed=True)
        # the disc the turning blank sweeps
        reach = float(np.max(np.linalg.norm(_corners(self.blank), axis=1)))
        self.bounds = np.array([[-reach, -reach], [reach, reach]])

    def plate(self, state: float | None) -> np.ndarray | None:
        from specholo.toolpaths.spinning import rotate_z

        c = np.concatenate([_corners(self.blank), np.zeros((4, 1))], axis=1)
        return rotate_z(c, state or 0.0)[:, :2]

    def outline(self, state: float | None) -> list[np.ndarray]:
        from specholo.toolpaths.spinning import rotate_z

        # a mark on the blank's top edge, turning with it
        top = float(self.blank[1, 1])
        mark = np.array([[0.0, top - 0.08 * (top - self.blank[0, 1]), 0.0], [0.0, top, 0.0]])
        return [rotate_z(mark, state or 0.0)]

    def glints(self, eye: np.ndarray, state: float | None) -> np.ndarray:
        from specholo.simulation.spinning import find_spin_glints
        from specholo.toolpaths.spinning import rotate_z

        phi = state or 0.0
        # the eye in the turned plate's frame, its glints back in the world
        found = find_spin_glints(self.design, rotate_z(np.asarray(eye, dtype=float), -phi),
                                 self.tool)
        return rotate_z(found.point, phi)

    def ghost(self, state: float | None) -> Any:
        from specholo.toolpaths.spinning import rotate_z

        phi = state or 0.0
        tracks = self.design.tracks
        if tracks is not None:  # sliding stipples: where each is at this angle
            where, alive, _ = tracks.at(np.array([phi]))
            return rotate_z(where[alive[:, 0], 0], phi)
        pts = self.design.points if self.model is None else getattr(
            self.model, "vertices", self.model)
        return rotate_z(np.asarray(pts, dtype=float), phi)

    def overlay(self, camera: Camera, state: float | None) -> np.ndarray | None:
        from specholo.toolpaths.spinning import rotate_z

        g = self.design.grooves
        v = np.concatenate([g.vertices, np.zeros((len(g.vertices), 1))], axis=1)
        v = rotate_z(v, state or 0.0)
        return line_coverage(camera, np.split(v, g.offsets[1:-1]))


def _corners(bounds: np.ndarray) -> np.ndarray:
    """The four corners (4, 2) of a rectangle (2, 2), counter-clockwise."""
    (x0, y0), (x1, y1) = bounds
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


class SteadySource(BaseSource):
    """A steady image (``specholo steady``): glints on its scoops, seen from the
    design's still eyes, along the light's elevation.

    Args:
        design: the ``SteadyDesign``.
        tool: the ball that cuts the scoops.
        plate: (2, 2) the plate's corners, mm.
        facts: the design in rows, for the report.
    """

    title = "a steady-image design"
    grooves = True

    def __init__(self, design: Any, tool: Tool, plate: np.ndarray,
                 facts: list[tuple[str, str]] | None = None) -> None:
        s = design.setup
        self.design = design
        self.tool = tool
        self.facts = facts or []
        viewer = Viewer(s.distance, s.height, 0.0, s.ipd)
        half = viewer.eye_half_angle
        self.setup = Setup(Light(s.light_elevation), dataclasses.replace(viewer, half_range=half),
                           tool)
        self.eyes = (-half, half)
        self.motion = Motion("light", "light elevation", s.light_elevation - s.light_sweep,
                             s.light_elevation + s.light_sweep, own=s.light_elevation)
        self.bounds = np.asarray(plate, dtype=float)

    def glints(self, eye: np.ndarray, state: float | None) -> np.ndarray:
        from specholo.simulation.steady import find_steady_glints

        s = self.design.setup
        if state is not None:
            Light(float(state))  # a light in the plate's plane, or behind it, is refused
        light = s.light(s.light_elevation if state is None else float(state))  # as verify moves it
        return find_steady_glints(self.design, np.asarray(eye, dtype=float), light,
                                  self.tool).point

    def ghost(self, state: float | None) -> Any:
        return self.design.points

    def overlay(self, camera: Camera, state: float | None) -> np.ndarray | None:
        # each scoop's trace on the plate: its ball centres' path, seen from above
        c = np.array(self.design.centres, dtype=float)
        c[:, 2] = 0.0
        return line_coverage(camera, np.split(c, self.design.offsets[1:-1]))

"""Motions of viewer, light, scene and plate, as one-parameter families of states.

A hologram with motion is designed along one driver tau, swept in small steps:

- ``walk``: tau is the eye azimuth on the eyes' circle (the viewer walks past a
  still plate under a still light). Both eyes of every head lie on that one
  circle, so one family of states serves both.
- ``light``: tau is the light's elevation along a path while the viewer stands
  still at azimuth 0. Each eye is its own family.

Scenes are keyed to the driver: each has an interval of tau in which it shows,
and may move within it (a turn about its own vertical axis and a shift, each in
proportion to tau), so viewpoint-keyed animation, points that move as the viewer
moves, and light-keyed animation are the same construction. Everything is in
the plate frame (``plate_angle`` is kept for a plate that turns; both modes
here hold it still).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from specholo.errors import SpecholoError

MODES = ("walk", "light")


def rot_z(angle: np.ndarray) -> np.ndarray:
    """Rotations (m, 3, 3) about z by angle (m,) radians."""
    c, s = np.cos(angle), np.sin(angle)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1),
                     np.stack([z, z, o], -1)], -2)


def rot_y(angle: np.ndarray) -> np.ndarray:
    """Rotations (m, 3, 3) about y by angle (m,) radians (+x toward -z... right-handed)."""
    c, s = np.cos(angle), np.sin(angle)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1),
                     np.stack([-s, z, c], -1)], -2)


@dataclass(frozen=True)
class SceneKey:
    """One scene's place in the driver and its motion there.

    Attributes:
        start, stop: the driver interval [start, stop) in which the scene shows, radians.
        turn: the scene's turn about its own vertical axis per radian of driver.
        shift: (3,) the scene's shift per radian of driver, mm.
        centre: (3,) the point it turns about, mm (its box centre).
        origin: driver value at which the scene is in its placed pose, radians.
        yaw: a fixed turn of the placed scene about its vertical axis, radians.
    """

    start: float
    stop: float
    turn: float = 0.0
    shift: tuple[float, float, float] = (0.0, 0.0, 0.0)
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)
    origin: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start) and math.isfinite(self.stop)
                and self.stop > self.start):
            raise SpecholoError(
                f"a scene's interval must be increasing, got [{math.degrees(self.start):g}, "
                f"{math.degrees(self.stop):g}) degrees")
        if not (math.isfinite(self.turn) and math.isfinite(self.yaw)
                and np.isfinite(self.shift).all()):
            raise SpecholoError("a scene's turn and shift must be finite")

    def angle(self, tau: np.ndarray) -> np.ndarray:
        """The scene's turn (m,) at driver values tau, radians."""
        return self.yaw + self.turn * (np.asarray(tau, dtype=float) - self.origin)

    def pose(self, points: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The scene's points (n, 3) in the world at each tau (m,): (n, m, 3)."""
        tau = np.asarray(tau, dtype=float)
        c = np.asarray(self.centre, dtype=float)
        r = rot_y(self.angle(tau))  # (m, 3, 3)
        moved = np.einsum("mij,nj->nmi", r, np.asarray(points, dtype=float) - c) + c
        return moved + (tau - self.origin)[None, :, None] * np.asarray(self.shift)

    def eye_in_scene(self, eyes: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """World eyes (m, 3) carried into the scene's own placed pose at each tau."""
        tau = np.asarray(tau, dtype=float)
        c = np.asarray(self.centre, dtype=float)
        back = eyes - (tau - self.origin)[:, None] * np.asarray(self.shift) - c
        r = rot_y(-self.angle(tau))
        return np.einsum("mij,mj->mi", r, back) + c


@dataclass(frozen=True)
class Family:
    """States a set of grooves is designed along, in the plate frame.

    Attributes:
        name: "eyes" (both eyes share the family), "left" or "right".
        tau: (m,) driver values, increasing, radians.
        eye: (m, 3) the eye at each state (plate frame).
        light: (m, 3) the light: a position, or a unit direction for a sun.
        point_light: whether ``light`` holds positions.
        plate_angle: (m,) the plate's turn about its normal at each state (radians).
        world_eye: (m, 3) the eye in the world frame (for occlusion in the scene).
        key: (m,) the driver value scenes are keyed on at each state.
        baseline: (m, 3) unit direction from the left eye to the right (plate frame).
    """

    name: str
    tau: np.ndarray
    eye: np.ndarray
    light: np.ndarray
    point_light: bool
    plate_angle: np.ndarray
    world_eye: np.ndarray
    key: np.ndarray
    baseline: np.ndarray


@dataclass(frozen=True)
class Position:
    """One place of the viewer (and light, and plate) that verification checks.

    Attributes:
        tau: driver value of the head (radians).
        eyes: (2, 3) left and right eyes in the plate frame.
        light: (3,) light in the plate frame (position or direction).
        keys: (2,) driver values each eye's scene is keyed on.
        world_eyes: (2, 3) the eyes in the world frame.
        plate_angle: the plate's turn, radians.
    """

    tau: float
    eyes: np.ndarray
    light: np.ndarray
    keys: np.ndarray
    world_eyes: np.ndarray
    plate_angle: float


@dataclass(frozen=True)
class MotionSpec:
    """How the viewer, light and plate move (lengths mm, angles radians).

    Attributes:
        mode: "walk" or "light".
        view_distance: eyes' distance D from the plate centre (head on its arc).
        eye_height: eye height, mm.
        ipd: interocular distance, mm.
        half_range: walk: largest head azimuth.
        light_elevation: light elevation (walk; the start of a light path).
        light_distance: point-light distance, or None for a sun.
        light_stop: light mode: the elevation the light moves to.
        step: driver step between design states, radians.
    """

    mode: str = "walk"
    view_distance: float = 600.0
    eye_height: float = 0.0
    ipd: float = 64.0
    half_range: float = math.radians(30.0)
    light_elevation: float = math.radians(45.0)
    light_distance: float | None = None
    light_stop: float = math.radians(60.0)
    step: float = math.radians(0.25)

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise SpecholoError(f"motion mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        for name in ("view_distance", "ipd", "step"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise SpecholoError(f"{name.replace('_', ' ')} must be positive, got {v!r}")
        if not 0 < self.light_elevation < math.pi:
            raise SpecholoError("light elevation must be in (0, 180) degrees")
        if not 0 <= self.half_range < math.radians(80):
            raise SpecholoError("view range must be in [0, 80) degrees")
        if self.mode == "light" and not 0 < self.light_stop < math.pi:
            raise SpecholoError("the light path's end elevation must be in (0, 180) degrees")
        if self.light_distance is not None and not (
                math.isfinite(self.light_distance) and self.light_distance > 0):
            raise SpecholoError(f"light distance must be positive, got {self.light_distance}")

    @property
    def eye_radius(self) -> float:
        return math.hypot(self.view_distance, 0.5 * self.ipd)

    @property
    def eye_half_angle(self) -> float:
        return math.atan2(0.5 * self.ipd, self.view_distance)

    def _light_world(self, elevation: np.ndarray) -> np.ndarray:
        e = np.asarray(elevation, dtype=float)
        d = np.stack([np.zeros_like(e), np.cos(e), np.sin(e)], -1)
        return d * self.light_distance if self.light_distance is not None else d

    def _eyes_world(self, azimuth: np.ndarray) -> np.ndarray:
        r = self.eye_radius
        a = np.asarray(azimuth, dtype=float)
        return np.stack([r * np.sin(a), np.full_like(a, self.eye_height), r * np.cos(a)], -1)

    def driver(self) -> tuple[float, float]:
        """The driver's range of the design states, radians."""
        if self.mode == "walk":
            # The eyes of heads at the edge reach half an IPD angle beyond it.
            edge = self.half_range + self.eye_half_angle + math.radians(0.5)
            return -edge, edge
        margin = math.radians(0.5)
        return (min(self.light_elevation, self.light_stop) - margin,
                max(self.light_elevation, self.light_stop) + margin)

    def states(self) -> np.ndarray:
        """Design states tau (m,), at most ``step`` apart, over the driver's range."""
        a, b = self.driver()
        n = max(int(math.ceil((b - a) / self.step - 1e-9)), 1)
        return np.linspace(a, b, n + 1)

    def families(self) -> list[Family]:
        """The families of states the grooves are designed along."""
        tau = self.states()
        zero = np.zeros_like(tau)
        point = self.light_distance is not None
        if self.mode == "walk":
            eye = self._eyes_world(tau)
            light = np.broadcast_to(self._light_world(np.array(self.light_elevation)),
                                    eye.shape).copy()
            base = np.stack([np.cos(tau), zero, -np.sin(tau)], -1)
            return [Family("eyes", tau, eye, light, point, zero, eye, tau, base)]
        half = self.eye_half_angle
        out = []
        for name, az in (("left", -half), ("right", half)):
            world = np.broadcast_to(self._eyes_world(np.array(az)), (len(tau), 3)).copy()
            light = self._light_world(tau)
            base = np.broadcast_to(np.array([1.0, 0.0, 0.0]), world.shape).copy()
            out.append(Family(name, tau, world, light, point, zero, world, tau, base))
        return out

    def positions(self, step: float) -> list[Position]:
        """Viewer positions to verify, at most ``step`` apart over the range."""
        if self.mode == "walk":
            a, b = -self.half_range, self.half_range
        else:
            a, b = sorted((self.light_elevation, self.light_stop))
        n = max(int(math.ceil((b - a) / step - 1e-9)), 1)
        taus = np.linspace(a, b, n + 1)
        half = self.eye_half_angle
        out = []
        for tau in taus:
            if self.mode == "walk":
                az = np.array([tau - half, tau + half])
                world = self._eyes_world(az)
                # Heads on the arc of radius D: eyes on the tangent, IPD apart.
                head = np.array([self.view_distance * math.sin(tau), self.eye_height,
                                 self.view_distance * math.cos(tau)])
                tangent = np.array([math.cos(tau), 0.0, -math.sin(tau)])
                world = np.stack([head - 0.5 * self.ipd * tangent,
                                  head + 0.5 * self.ipd * tangent])
                light = self._light_world(np.array(self.light_elevation))
                out.append(Position(float(tau), world, light, az, world, 0.0))
                continue
            world = self._eyes_world(np.array([-half, half]))
            out.append(Position(float(tau), world, self._light_world(np.array(tau)),
                                np.array([tau, tau]), world, 0.0))
        return out

"""Pictures of any kind of design through one interface, :class:`PictureSource`.

Every picture command (``render``, ``stereo``, ``animate``, ``report``, ``view``)
draws a design through what its kind says of it: the setup whose viewer and
light place the default cameras, the plate (or a curved host's box seen from
the front) that the default field of view frames, the lines that outline it,
the glints an eye sees at a state of the kind's motion, and that motion (a
flat plate's head azimuth, a turning plate's angle, a moving light's
elevation). The kinds' adapters are in :mod:`specholo.preview.sources`; the
pictures are drawn here, one way for every kind: :func:`still`,
:func:`stereo_stills`, :func:`frames` and :func:`page`.

States are radians inside, as every angle is; the commands speak degrees. A
motion that is the eye's own azimuth (a flat plate, a ridged plate, a
composition the viewer walks past) has no state of its own: the glints take it
through the eye, and the pictures pass the camera's azimuth as the state (a
composition's scenes, keyed to the azimuth, are posed by it).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from specholo.errors import SpecholoError
from specholo.preview.render import (
    REFERENCE_ROUGHNESS,
    Camera,
    Spots,
    draw_glints,
    plate_camera,
)
from specholo.setup import Setup

#: Called as ``progress(done, total)`` after each frame or view.
Progress = Callable[[int, int], None]

#: What ``animate`` may move: the head along the viewing arc, a turning plate,
#: or the light's elevation.
ALONG = ("turntable", "turn", "light")


@dataclass(frozen=True)
class Motion:
    """What a kind's pictures move along by default (``animate``, ``view``).

    Attributes:
        key: ``"turntable"`` (the head's azimuth), ``"turn"`` (a turning plate's
            angle) or ``"light"`` (the light's elevation): ``animate --kind`` and
            its default file's name.
        name: in words ("plate angle").
        low, high: its range, radians.
        own: the design's own state, radians (a still's default); None where
            the motion is the eye's azimuth, which the glints take through the eye.
        closed: a whole turn: ``high`` wraps onto ``low``, swept one way.
        unit: the unit the commands give and print it in.
    """

    key: str
    name: str
    low: float
    high: float
    own: float | None = None
    closed: bool = False
    unit: str = "deg"

    @property
    def moves_eye(self) -> bool:
        """Whether the motion is the eye's own azimuth (no state of its own)."""
        return self.own is None

    def degrees(self) -> tuple[float, float]:
        """``low`` and ``high`` in degrees."""
        return math.degrees(self.low), math.degrees(self.high)

    def sweep(self, frames: int, loop: bool = True) -> np.ndarray:
        """States (frames,) of an animation along the motion, radians: a whole
        turn one way round (no frame repeated), else there and back (``loop``)
        or once from ``low`` to ``high``."""
        from specholo.preview.motion import sweep

        if self.closed:
            return self.low + (self.high - self.low) * np.arange(frames) / frames
        return sweep(self.low, self.high, frames, loop)

    def states(self, step: float) -> np.ndarray:
        """States (k,) at most ``step`` (radians) apart over the range: a whole
        turn without its far end (the same as its start)."""
        span = self.high - self.low
        n = max(int(math.ceil(span / step - 1e-9)), 1)
        if self.closed:
            return self.low + span * np.arange(n) / n
        return np.linspace(self.low, self.high, n + 1)


class PictureSource(Protocol):
    """What a kind of design shows the picture commands.

    Attributes:
        title: the kind in a phrase ("a turning-plate design"), for messages.
        setup: the viewer (its eyes' circle and height place the default
            cameras: a camera at azimuth a and elevation 0 sits on the eyes'
            circle), the light (the plate's sheen) and the tool (a groove's
            width sizes a glint's spot).
        bounds: (2, 2) the corners (x, y at z = 0, mm) the default field of view
            frames: the plate, or a curved host's box seen from the front.
        motion: what ``animate`` and ``view`` sweep by default.
        eyes: the azimuths (radians) on the eyes' circle of the eyes the design
            serves: a still's default camera is the first; a design that serves
            every azimuth gives (0,); one seen from still eyes, its left and right.
        elevation_range: the eyes' elevation range the design serves (radians;
            0: the eyes' height alone), for the views a page holds.
        grooves: whether it has grooves to draw faintly (``overlay``).
        facts: the design in rows (label, value) for the report; None for the
            flat plate, whose report reads its own hologram.json.
    """

    title: str
    setup: Setup
    bounds: np.ndarray
    motion: Motion
    eyes: tuple[float, ...]
    elevation_range: float
    grooves: bool
    facts: list[tuple[str, str]] | None

    def plate(self, state: float | None) -> np.ndarray | None:
        """The plate at z = 0 at a state, mm: its corners (2, 2) or a convex
        polygon (k, 2) counter-clockwise (a turned plate); None where the
        design is not on a flat plate at z = 0 (a curved host)."""
        ...

    def outline(self, state: float | None) -> list[np.ndarray]:
        """Polylines (each (k, 3), mm) drawn faintly at a state: a host's edges,
        a turning plate's mark."""
        ...

    def glints(self, eye: np.ndarray, state: float | None) -> np.ndarray:
        """The glint points (m, 3), mm, that an eye (3,) sees with the motion at
        ``state`` (radians; None: the design's own), found by the kind's own
        glint finder."""
        ...

    def spots(self, eye: np.ndarray, state: float | None,
              roughness: float) -> Spots:
        """:meth:`glints` and each one's spot on the plate: its standard
        deviation, mm, at the specular lobe ``roughness`` (radians), one for all
        or (m,); and, where glints differ in power (a flat plate's streaks), each
        one's power as a share of a typical glint's (m,)."""
        ...

    def ghost(self, state: float | None) -> Any:
        """The model where it is at a state (a mesh, or (n, 3) points), or None."""
        ...

    def overlay(self, camera: Camera, state: float | None) -> np.ndarray | None:
        """The grooves as the camera sees them, (H, W) coverage in [0, 1), or None
        where the design has no grooves."""
        ...

    def relit(self, elevation: float) -> PictureSource:
        """The same design under its light moved to ``elevation`` (radians).

        Raises:
            SpecholoError: the kind's light does not move that way.
        """
        ...

    def prepare(self) -> None:
        """Build what many pictures share (a glint index), before they are drawn
        on several threads."""
        ...

    def page(self, title: str, size: tuple[int, int] | None) -> str | None:
        """The kind's own interactive page (HTML), or None for the page of
        glints precomputed per view (:func:`page`)."""
        ...


class BaseSource:
    """What a source has unless its kind says otherwise: a flat plate at z = 0
    (``bounds``), no lines, one spot size (the groove's width at the reference
    roughness), no model, no grooves, a light that stays, no page of its own."""

    title = "a design"
    setup: Setup
    bounds: np.ndarray
    motion: Motion
    eyes: tuple[float, ...] = (0.0,)
    elevation_range = 0.0
    grooves = False
    facts: list[tuple[str, str]] | None = None

    def plate(self, state: float | None) -> np.ndarray | None:
        return self.bounds

    def outline(self, state: float | None) -> list[np.ndarray]:
        return []

    def glints(self, eye: np.ndarray, state: float | None) -> np.ndarray:
        raise NotImplementedError

    def spots(self, eye: np.ndarray, state: float | None,
              roughness: float) -> Spots:
        from specholo.preview.render import spot_sigma

        return self.glints(eye, state), spot_sigma(self.setup, roughness)

    def ghost(self, state: float | None) -> Any:
        return None

    def overlay(self, camera: Camera, state: float | None) -> np.ndarray | None:
        return None

    def relit(self, elevation: float) -> PictureSource:
        raise SpecholoError(f"{self.title} is lit as it was designed: the light does not "
                            "move apart from its motion")

    def prepare(self) -> None:
        return None

    def page(self, title: str, size: tuple[int, int] | None) -> str | None:
        return None


def state_at(source: PictureSource, at: float | None, azimuth: float) -> float | None:
    """The state a picture from a camera at ``azimuth`` (radians) is drawn at:
    ``at`` (radians) where given, else the design's own; where the motion is
    the eye's azimuth, the camera's.

    Raises:
        SpecholoError: ``at`` given for a motion that is the eye's azimuth.
    """
    m = source.motion
    if m.moves_eye:
        if at is not None:
            raise SpecholoError(f"{source.title} moves only with the eye: place the camera "
                                "with --azimuth instead of --at")
        return azimuth
    if at is not None and not math.isfinite(at):
        raise SpecholoError(f"--at must be a finite number, got {at}")
    return m.own if at is None else at


def camera(source: PictureSource, azimuth: float | None = None, elevation: float = 0.0,
           distance: float | None = None, fov: float | None = None, width: int = 1024,
           height: int = 1024, frame_azimuths: Sequence[float] = ()) -> Camera:
    """A camera for a design: by default on its eyes' circle at its first eye
    (:attr:`PictureSource.eyes`), the field of view framing its bounds.

    Args:
        source: the design.
        azimuth, elevation: radians (azimuth None: the first eye's).
        distance: mm from the orbit centre; default the eyes' circle.
        fov: vertical field of view, radians; default frames the bounds.
        width, height: pixels.
        frame_azimuths: further azimuths (radians) the default fov frames.
    """
    az = source.eyes[0] if azimuth is None else azimuth
    return plate_camera(source.setup, source.bounds, az, elevation, distance, fov, width,
                        height, frame_azimuths)


def head(source: PictureSource, azimuth: float = 0.0, width: int = 768, height: int = 768,
         fov: float | None = None) -> Camera:
    """A viewer's head on the design's arc (radius ``viewer.distance``), its fov
    framing the bounds for both eyes (:func:`~specholo.preview.stereo.stereo_cameras`
    places them). At azimuth 0 the eyes of a design seen from still eyes are its
    own."""
    v = source.setup.viewer
    half = v.eye_half_angle
    return plate_camera(source.setup, source.bounds, azimuth, 0.0, v.distance, fov, width,
                        height, frame_azimuths=(azimuth - half, azimuth + half))


def still(source: PictureSource, cam: Camera, state: float | None,
          roughness: float = REFERENCE_ROUGHNESS, grooves: bool = False,
          ghost: bool = False, bloom: float = 0.006) -> np.ndarray:
    """What a camera sees of a design at a state of its motion: a spot at each
    glint the kind's own finder gives for the camera's position, over the plate
    (or the host's edges).

    Args:
        source: the design.
        cam: the camera.
        state: the motion's state, radians (see :func:`state_at`).
        roughness: the specular lobe's width, radians.
        grooves: draw the grooves faintly.
        ghost: draw the model faintly where it is.
        bloom: a faint halo around each glint, as a fraction of its peak.

    Returns:
        (H, W, 3) uint8 RGB image.
    """
    if grooves:
        if not source.grooves:
            raise SpecholoError(f"{source.title} has no grooves to draw: leave out --grooves")
        source.prepare()  # the glints and the overlay share one index, on two threads

    def glints() -> Spots:
        return source.spots(cam.position(), state, roughness)

    def overlay() -> np.ndarray:
        cover = source.overlay(cam, state)
        return np.zeros((cam.height, cam.width)) if cover is None else cover

    return draw_glints(cam, source.plate(state), source.setup.light, glints, roughness,
                       source.ghost(state) if ghost else None, bloom,
                       overlay if grooves else None, source.outline(state))


def stereo_stills(source: PictureSource, head_cam: Camera, at: float | None = None,
                  ipd: float | None = None, **options: Any) -> tuple[np.ndarray, np.ndarray]:
    """The two eyes of a head (see :func:`head`), each from its own glints.

    Args:
        source: the design.
        head_cam: the head (the midpoint between the eyes) and the image settings.
        at: the motion's state, radians (None: the design's own; where the
            motion is the eye's azimuth, each eye's own).
        ipd: interocular distance, mm; default the design's.
        **options: further :func:`still` options.

    Returns:
        Left and right (H, W, 3) uint8 images.
    """
    from specholo.preview.stereo import stereo_cameras

    source.prepare()
    left, right = stereo_cameras(head_cam, source.setup.viewer.ipd if ipd is None else ipd)
    return (still(source, left, state_at(source, at, left.azimuth), **options),
            still(source, right, state_at(source, at, right.azimuth), **options))


def along_options(source: PictureSource) -> tuple[str, ...]:
    """What ``animate`` may move for this design: its motion, the head's azimuth,
    and the light where it moves (a motion of its own, or a light that may be
    moved about the design's)."""
    out = [source.motion.key, "turntable"]
    try:
        source.relit(source.setup.light.elevation)
        out.append("light")
    except SpecholoError:
        pass
    return tuple(dict.fromkeys(out))


def frames(source: PictureSource, count: int, size: tuple[int, int] = (512, 512),
           along: str | None = None, roughness: float = REFERENCE_ROUGHNESS,
           grooves: bool = False, ghost: bool = False, loop: bool = True,
           azimuth: float | None = None, at: float | None = None,
           span: float = math.radians(10.0), distance: float | None = None,
           progress: Progress | None = None, workers: int | None = None) -> list[np.ndarray]:
    """Frames of an animation, each a :func:`still`.

    Args:
        source: the design.
        count: number of frames.
        size: (width, height) in pixels.
        along: ``"turntable"``: the camera walks the eyes' circle over the
            viewer's range (the motion's state held at ``at``); ``"turn"`` or
            ``"light"``: the motion, if it is that, the camera still at
            ``azimuth``; ``"light"`` otherwise: the light's elevation moves
            +-``span`` about the design's. None: the design's motion.
        roughness: the specular lobe's width, radians.
        grooves: draw the grooves faintly.
        ghost: draw the model faintly.
        loop: there and back (see :func:`~specholo.preview.motion.sweep`); a
            whole turn goes one way round.
        azimuth: a still camera's azimuth, radians; default the first eye's.
        at: the motion's state while the head walks, radians (None: the design's).
        span: how far a light that is not the motion moves, radians.
        distance: camera distance, mm; default the eyes' circle.
        progress: called after each frame.
        workers: render threads; default the number of CPUs.

    Returns:
        (H, W, 3) uint8 frames.

    Raises:
        SpecholoError: the design does not move that way.
    """
    from specholo.preview.motion import _check_frames, draw_frames, sweep

    _check_frames(count)
    m = source.motion
    along = m.key if along is None else along
    allowed = along_options(source)
    if along not in allowed:
        raise SpecholoError(f"{source.title} does not move along {along!r}: its animations "
                            f"are {', '.join(allowed)}")
    width, height = size
    sources: list[PictureSource] = [source] * count
    if along == "turntable":
        r = source.setup.viewer.half_range
        az = sweep(-r, r, count, loop)
        base = camera(source, 0.0, 0.0, distance, None, width, height, frame_azimuths=(-r, r))
        cams = [Camera(float(a), 0.0, base.distance, base.fov, width, height, base.eye_height)
                for a in az]
        states = [state_at(source, at, float(a)) for a in az]
    else:
        cam = camera(source, azimuth, 0.0, distance, None, width, height)
        cams = [cam] * count
        if along == m.key:
            states = [float(s) for s in m.sweep(count, loop)]
        else:  # a light that is not the motion, moved about the design's
            if not (math.isfinite(span) and span >= 0):
                raise SpecholoError(
                    f"light span must be >= 0 degrees, got {math.degrees(span):g}")
            a0 = source.setup.light.elevation
            sources = [source.relit(float(a)) for a in sweep(a0 - span, a0 + span, count, loop)]
            states = [state_at(source, at, cam.azimuth)] * count
    for each in {id(x): x for x in sources}.values():
        each.prepare()

    def one(k: int) -> np.ndarray:
        return still(sources[k], cams[k], states[k], roughness, grooves, ghost)

    return draw_frames(one, count, workers or os.cpu_count() or 1, progress)


def views(source: PictureSource, step: float, progress: Progress | None = None) -> Any:
    """The glints of the views a page holds (a :class:`~specholo.preview.page.FieldViews`):
    where the motion is the eye's azimuth, a grid over the viewer's azimuth
    range (and elevation range), else the design's eyes along the motion's
    states, at most ``step`` degrees apart.

    Raises:
        SpecholoError: the step is outside [0.1, 10] degrees, or the views too many.
    """
    from specholo.preview.page import FieldViews, check_view_count, check_view_step
    from specholo.simulation.verify import view_azimuths

    check_view_step(step)
    m = source.motion
    if m.moves_eye:
        az = np.degrees(view_azimuths(source.setup.viewer.half_range, math.radians(step)))
        el = (np.degrees(view_azimuths(source.elevation_range, math.radians(step)))
              if source.elevation_range > 0 else np.zeros(1))
        states = np.zeros(0)
    else:
        az, el = np.degrees(np.asarray(source.eyes, dtype=float)), np.zeros(1)
        states = np.degrees(m.states(math.radians(step)))
    check_view_count(len(az) * len(el) * max(len(states), 1))
    source.prepare()
    return FieldViews.collect(source.glints, source.setup, az, el, states, progress=progress)


def _shape(source: PictureSource, state: float | None) -> dict[str, Any]:
    """What a page draws under the glints at a state: the plate polygon (mm,
    counter-clockwise) or None, and the outline's polylines."""
    plate = source.plate(state)
    if plate is not None and np.shape(plate) == (2, 2):
        (x0, y0), (x1, y1) = np.asarray(plate, dtype=float)
        plate = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])

    def mm(a: np.ndarray) -> list[Any]:
        # a micrometre is finer than any pixel of the page; the JSON stays small
        return np.round(np.asarray(a, dtype=float), 3).tolist()

    return {"plate": None if plate is None else mm(plate),
            "lines": [mm(line) for line in source.outline(state)]}


def page(source: PictureSource, title: str, size: tuple[int, int] | None = None,
         step: float | None = None, progress: Progress | None = None) -> str:
    """The interactive page of a design, as one HTML string: the kind's own
    (:meth:`PictureSource.page`), or its glints precomputed per view
    (:func:`views`), shown for the view nearest the pointer.

    Args:
        source: the design.
        title: the page's title.
        size: fixed canvas (width, height) in CSS pixels, or None to fill the window.
        step: the views' spacing, degrees (default
            :data:`~specholo.preview.page.FIELD_VIEW_STEP`).
        progress: called with (views done, views), or None.
    """
    from specholo.preview.page import FIELD_VIEW_STEP, PageMotion, build_views_page

    own = source.page(title, size)
    if own is not None:
        return own
    found = views(source, FIELD_VIEW_STEP if step is None else step, progress)
    m = source.motion
    if m.moves_eye:  # a host's outline may change with the eye's azimuth
        shapes = [_shape(source, math.radians(a)) for a in found.azimuths]
        if all(s == shapes[0] for s in shapes):
            shapes = shapes[:1]
        motion = None
        frame = None
    else:
        shapes = [_shape(source, math.radians(s)) for s in found.states]
        if all(s == shapes[0] for s in shapes):
            shapes = shapes[:1]
        low, high = m.degrees()
        assert m.own is not None
        motion = PageMotion(m.name, low, high, m.closed, math.degrees(m.own))
        frame = tuple(source.eyes)
    return build_views_page(found, source.setup, source.bounds, title, size, motion, shapes,
                            frame, (math.degrees(source.eyes[0]), 0.0))

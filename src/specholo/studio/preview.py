"""The studio's fast preview: the design's own stipples and views, without grooves.

A design spends most of its time walking the grooves; what an eye sees of an
exact design needs none of that. The preview places the model with the pose,
stipples it with the design's seed (the same points the design gets) and finds
each stipple's visible azimuths with the design's occlusion code (the same
intervals); an exact design puts each visible stipple's glint where the eye's
sightline through the stipple crosses the plate, so the page draws it there.

The plate comes with it, as an estimate until the exact design names it: the
plate the design would fit to the grooves (:func:`plate_estimate`), or the
plate the settings give.

Beside it come figures the grooves would give, as estimates that say what they
are: the groove length the views need, in closed form (see
:func:`groove_length_bound`), and a lower bound on the cutting time; the
plate's whole machining time and its as-cut visibility depend on how the
stripes are cut and placed, and are left to the exact design (which the page
runs by itself once the settings rest, and shows beside these).
"""

from __future__ import annotations

import inspect
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.plate import Plate, fit_plate
from specholo.fabrication.programs.timing import estimate_time, plain_duration, trapezoid_time
from specholo.hosts.flat import sightline_crossing
from specholo.jobs.flat.settings import DesignConfig
from specholo.jobs.plate_common import check_points
from specholo.jobs.plate_settings import DEFAULT_STIPPLES
from specholo.jobs.ridged.settings import RidgedConfig
from specholo.scene.loading import Model
from specholo.scene.placement import place
from specholo.scene.stippling import check_memory, stipple
from specholo.setup import Light, Viewer
from specholo.studio.cut import plate_json
from specholo.visibility.occlusion import visible_intervals

#: Most stipples a preview takes: the page redraws within about a second up to
#: a few thousand, and a larger count is the exact design's business.
MAX_PREVIEW_STIPPLES = 20_000
#: Samples along each visible interval for the groove-length bound.
BOUND_SAMPLES = 64
#: Samples along each visible interval for the plate's estimate.
PLATE_SAMPLES = 17
#: The acceleration the machining estimate assumes (its own default), mm/s^2:
#: one machine model for the bound and for the design's figure.
ACCEL = float(inspect.signature(estimate_time).parameters["accel"].default)
#: Why the as-cut visibility waits for the exact design.
AS_CUT_WHY = ("which glints the other grooves cut away depends on where the stripes are "
              "placed in their band; only the exact design's grooves tell")


@dataclass(frozen=True)
class Estimates:
    """What the preview can say about the grooves before they exist.

    Attributes:
        hidden: stipples no eye in the range sees (exact: the design's own
            stipples and occlusion; they get no groove).
        groove_length_mm: the total groove length the views need, mm (the
            exact grooves measure within about 1% above it; see
            :func:`groove_length_bound`).
        cutting_s: a lower bound on the time spent cutting at the feed, s:
            each stipple's length cut in one move from rest to rest.
    """

    hidden: int
    groove_length_mm: float
    cutting_s: float

    def as_dict(self) -> dict[str, Any]:
        """Plain numbers and words for the page."""
        return {"hidden": self.hidden, "groove_length_mm": self.groove_length_mm,
                "cutting_hours_at_least": self.cutting_s / 3600.0,
                "cutting_at_least": plain_duration(self.cutting_s),
                "as_cut_visibility": None, "as_cut_why": AS_CUT_WHY}


@dataclass(frozen=True)
class Preview:
    """A placed, stippled model and the azimuths each stipple is seen from.

    Attributes:
        points: (n, 3) stipples, mm, plate frame.
        stipple: (k,) stipple of each visible interval, sorted.
        start: (k,) interval starts, eye azimuth on the eyes' circle, radians.
        end: (k,) interval ends, radians.
        viewer: the eyes.
        estimates: figures of the grooves to come.
        seconds: time the preview took.
        plate: (2, 2) the plate's corners, mm: given by the settings, or the
            one the design would fit (:func:`plate_estimate`).
        plate_given: whether the settings give the plate.
    """

    points: np.ndarray
    stipple: np.ndarray
    start: np.ndarray
    end: np.ndarray
    viewer: Viewer
    estimates: Estimates
    seconds: float
    plate: np.ndarray
    plate_given: bool = False

    def glints(self, azimuth: float) -> tuple[np.ndarray, np.ndarray]:
        """Where one eye sees the glints of an exact design.

        Args:
            azimuth: the eye's azimuth on the eyes' circle, radians.

        Returns:
            ids (m,) of the stipples the eye sees, and (m, 2) their glints on
            the plate: the crossing of the sightline eye -> stipple with z = 0.
        """
        inside = (self.start <= azimuth) & (azimuth <= self.end)
        ids = np.unique(self.stipple[inside])
        eye = self.viewer.eye(np.array([azimuth]))[0]
        cross = sightline_crossing(np.broadcast_to(eye, (len(ids), 3)), self.points[ids])
        return ids, cross[:, :2]

    def as_json(self) -> dict[str, Any]:
        """The page's data: points to the micrometre, intervals in degrees."""
        v = self.viewer
        return {
            "stipples": len(self.points),
            "points": np.round(self.points, 3).ravel().tolist(),
            "runs": {"stipple": self.stipple.tolist(),
                     "start": np.round(np.degrees(self.start), 4).tolist(),
                     "end": np.round(np.degrees(self.end), 4).tolist()},
            "eye": {"radius": v.eye_radius, "height": v.height,
                    "range_deg": math.degrees(v.half_range),
                    "design_range_deg": math.degrees(v.design_range),
                    "distance": v.distance, "ipd": v.ipd,
                    # each eye's azimuth on the eyes' circle is the head's -/+ this
                    "eye_half_angle_deg": math.degrees(v.eye_half_angle)},
            "plate": {**plate_json(Plate.from_corners(self.plate)), "given": self.plate_given},
            "estimates": self.estimates.as_dict(),
            "seconds": self.seconds,
        }


#: Why the studio makes no ridged plate.
NO_RIDGED = ("the studio designs grooved plates; a ridged plate is made by "
             "`specholo design --method ridged`")


def fast_preview(model: Model, config: DesignConfig | RidgedConfig) -> Preview:
    """Place, stipple and crop a model as :func:`specholo.jobs.flat.folder.design` does.

    Args:
        model: the loaded model, in its own units (placed here with the pose).
        config: the settings; stipple count, seed, pose, light and viewer are used.

    Raises:
        SpecholoError: settings the design would refuse (a model too close to
            the eyes, a count over :data:`MAX_PREVIEW_STIPPLES`, a spacing).
    """
    if isinstance(config, RidgedConfig):
        raise SpecholoError(NO_RIDGED)
    if config.spacing is not None:
        raise SpecholoError("the studio counts stipples: give stipples, not spacing")
    count = int(config.stipples or DEFAULT_STIPPLES)
    if count > MAX_PREVIEW_STIPPLES:
        raise SpecholoError(f"{count} stipples is more than the preview draws "
                            f"({MAX_PREVIEW_STIPPLES:,}); design it with `specholo design`")
    check_memory(count)
    t0 = time.perf_counter()
    setup = config.setup()
    pose = config.pose()
    placed = place(model, config.size, config.center_z, pose.rotation(), pose.offset)
    # The design's seed and stippling: the preview's stipples are the design's.
    st = stipple(placed, np.random.default_rng(config.seed), count=count)
    check_points(st.points, setup)
    iv = visible_intervals(placed.mesh, st.points, st.normals, setup.viewer)
    stip = np.asarray(iv.stipple, dtype=np.int64)
    start = np.asarray(iv.start, dtype=float)
    end = np.asarray(iv.end, dtype=float)
    hidden = len(st.points) - len(np.unique(stip))
    per_stipple = groove_length_bound(st.points, stip, start, end, setup.light, setup.viewer)
    moving = per_stipple[per_stipple > 0]
    cutting = float(trapezoid_time(moving, config.feed / 60.0, ACCEL).sum())
    estimates = Estimates(hidden, float(per_stipple.sum()), cutting)
    given = config.plate_width is not None and config.plate_height is not None
    if given:
        half = 0.5 * np.array([config.plate_width, config.plate_height], dtype=float)
        plate = np.stack([-half, half])
    else:
        width = config.cutter().section(config.depth_mm).width
        plate = plate_estimate(st.points, stip, start, end, setup.viewer, width)
    return Preview(st.points, stip, start, end, setup.viewer, estimates,
                   time.perf_counter() - t0, plate, given)


def plate_estimate(points: np.ndarray, stip: np.ndarray, start: np.ndarray, end: np.ndarray,
                   viewer: Viewer, width: float, samples: int = PLATE_SAMPLES) -> np.ndarray:
    """The plate the design would fit to its grooves (:func:`fit_plate`), from
    the glints' tracks: each groove follows the crossings of its stipple's
    sightlines over the views that see it.

    The grooves reach past the tracks by the wall's offset and their stripes'
    band (0.01 mm across and 0.2 mm up and down on the 2,000-stipple bunny),
    and the groove width is the tool's at its fallback depth, not the depth
    the design chooses: the whole-millimetre plate can come out 1 mm smaller
    than the design's.

    Args:
        points: (n, 3) stipples; stip, start, end: (k,) visible intervals.
        viewer: the eyes.
        width: the groove width, mm.
        samples: samples per interval.

    Returns:
        (2, 2) lower-left and upper-right corners, mm (a plate of the margin
        alone when no stipple is seen).
    """
    if len(stip) == 0:
        return fit_plate(np.zeros((2, 2)), width)
    u = np.linspace(0.0, 1.0, samples)
    theta = (start[:, None] + (end - start)[:, None] * u[None, :]).ravel()
    cross = sightline_crossing(viewer.eye(theta), np.repeat(points[stip], samples, axis=0))
    xy = cross[:, :2]
    return fit_plate(np.stack([xy.min(axis=0), xy.max(axis=0)]), width)


def groove_length_bound(points: np.ndarray, stip: np.ndarray, start: np.ndarray,
                        end: np.ndarray, light: Light, viewer: Viewer,
                        samples: int = BOUND_SAMPLES) -> np.ndarray:
    """The groove length each stipple's views need, mm: a lower bound on the
    glint's track, which the exact groove's centreline follows to within the
    wall's offset (measured within about 0.01 mm a stipple).

    An exact groove glints for the eye at azimuth theta at the sightline's
    crossing x(theta) (exact horizontally), and there its tangent is
    perpendicular to the half vector h's in-plane part (c'(theta) . h = 0).
    Over every visible interval it must therefore cover the crossings' x
    with a tangent at angle phi to the horizontal, cos phi = |h_y| / |(h_x, h_y)|:
    length >= integral of |dx| / cos phi (striping cuts the groove into pieces
    but keeps this length). Each sampled step counts |dx| times the smaller
    secant at its two ends, so the sum stays below the integral.

    Args:
        points: (n, 3) stipples.
        stip, start, end: (k,) visible intervals (eye azimuths, radians).
        light: the light; viewer: the eyes.
        samples: samples per interval.

    Returns:
        (n,) lengths, mm (0 for stipples never seen).
    """
    out = np.zeros(len(points))
    if len(stip) == 0:
        return out
    u = np.linspace(0.0, 1.0, samples)
    theta = start[:, None] + (end - start)[:, None] * u[None, :]  # (k, s)
    eyes = viewer.eye(theta.ravel())
    p = np.repeat(points[stip], samples, axis=0)
    cross = sightline_crossing(eyes, p)
    to_eye = eyes - cross
    to_eye /= np.linalg.norm(to_eye, axis=1, keepdims=True)
    h = light.towards(cross) + to_eye
    with np.errstate(divide="ignore", invalid="ignore"):
        # secant of the tangent's angle: |(h_x, h_y)| / |h_y| (inf where h_y = 0)
        sec = (np.hypot(h[:, 0], h[:, 1]) / np.abs(h[:, 1])).reshape(theta.shape)
    x = cross[:, 0].reshape(theta.shape)
    step = np.abs(np.diff(x, axis=1)) * np.minimum(sec[:, 1:], sec[:, :-1])
    step = np.where(np.isfinite(step), step, 0.0)
    np.add.at(out, stip, step.sum(axis=1))
    return out

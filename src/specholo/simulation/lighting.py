"""The light to use: the size of light that gives a plate its sharpest image.

A light of real size makes each glint a streak along its groove
(:mod:`specholo.simulation.streaks`): a bigger light, a longer streak, whose
centre a stripe's end pulls in, and more light spilled onto stripe ends for
the views past them. Below some size the plate's own gloss sets the streaks
and a smaller light no longer helps. :func:`choose_light` verifies the plate
under lights of a few sizes, on a sample of its stipples at a few head
azimuths, and picks the largest (the easiest to find, and the brightest)
within a tenth of the sharpest p95 error and, among those, of the fewest
false glints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo.optics.spread import GLOSS, Spread
from specholo.setup import Setup
from specholo.simulation.streak_verify import verify_streaks
from specholo.simulation.verify import VisibilityFn
from specholo.toolpaths.grooves import Grooves

#: Light sizes tried, degrees: the sun, then smaller lamps down to where a
#: mirror finish's own lobe (alpha 0.003: 0.1 deg wide) sets the streaks.
SIZES_DEG = (0.53, 0.25, 0.1, 0.03)
#: Stipples verified at most (evenly through the design): on the README
#: example 200 give the p95 error within 10% of all 2,000 stipples', the end
#: spills within 2%, and the same choice, in a fifth of the time (1.1 s).
SAMPLE = 200
#: A size within this share of the best figures is as good.
WITHIN = 0.1


@dataclass(frozen=True)
class LightTrial:
    """A light size's figures on the sample.

    Attributes:
        size_deg: the light's angular diameter, degrees.
        p95_mm: the worst 95th-percentile stereo error over the azimuths tried, mm.
        visibility: the lowest share of stipples shown in both eyes.
        spills_per_100: false glints from stripe ends per eye, per 100 stipples
            seen, the mean over the azimuths.
    """

    size_deg: float
    p95_mm: float
    visibility: float
    spills_per_100: float


@dataclass(frozen=True)
class LightChoice:
    """The light that gives the plate its sharpest image, and why.

    Attributes:
        size_deg: the largest light size (degrees) within a tenth of the
            sharpest and, among those, of the fewest false glints.
        roughness: the gloss the trials assumed (Beckmann alpha).
        trials: every size's figures, largest first.
        sampled: stipples verified; azimuths_deg: the head azimuths tried.
        distance: the design's point light's distance, mm (None: a sun).
    """

    size_deg: float
    roughness: float
    trials: list[LightTrial]
    sampled: int
    azimuths_deg: list[float]
    distance: float | None

    def describe(self) -> str:
        """The light to use, in words, with the sun's figures beside it."""
        best = next(t for t in self.trials if t.size_deg == self.size_deg)
        sun = next((t for t in self.trials if t.size_deg == SIZES_DEG[0]), None)
        lamp = _lamp(self.size_deg, self.distance)
        words = (f"light it with {lamp}: about {best.p95_mm:.1f} mm p95 error and "
                 f"{best.spills_per_100:.0f} false glints per 100 stipples")
        if sun is not None and sun is not best:
            words += (f" (the sun's 0.53 deg: {sun.p95_mm:.1f} mm, "
                      f"{sun.spills_per_100:.0f})")
        views = ", ".join(f"{a:+.0f}" for a in self.azimuths_deg)
        return words + (f", on a mirror-finish plate (alpha {self.roughness:g}; {self.sampled} "
                        f"stipples at {views} deg; `specholo verify --light-size` gives "
                        "every view)")

    def as_dict(self) -> dict[str, Any]:
        return {"size_deg": self.size_deg, "lamp": _lamp(self.size_deg, self.distance),
                "roughness": self.roughness, "sampled_stipples": self.sampled,
                "azimuths_deg": self.azimuths_deg,
                "trials": [t.__dict__ for t in self.trials]}


def _lamp(size_deg: float, distance: float | None) -> str:
    """A lamp of that angular size, in words, where the design puts its light."""
    size = math.radians(size_deg)
    if distance is None:
        lamp = (f"a small lamp far along the light's direction, at most {size_deg:g} deg "
                f"across (e.g. {3000.0 * size:.1f} mm across at 3 m)")
        # the sun is as large a light as any tried, and the one most at hand
        return f"the sun, or {lamp}" if size_deg >= SIZES_DEG[0] else lamp
    return f"a lamp at most {distance * size:.1f} mm across at the design's {distance:g} mm"


def choose_light(grooves: Grooves, points: np.ndarray, setup: Setup,
                 visible: VisibilityFn | None = None, roughness: float = GLOSS["mirror"],
                 sample: int = SAMPLE,
                 sizes_deg: tuple[float, ...] = SIZES_DEG) -> LightChoice | None:
    """Verify the plate under each light size and choose one.

    Args:
        grooves: the grooves; points: (n, 3) the stipples they show.
        setup: the design's light, viewer and tool.
        visible: which of all the stipples an eye sees past the model (as
            :func:`~specholo.simulation.verify.verify` takes it), or None.
        roughness: the plate's gloss, Beckmann alpha.
        sample: stipples verified at most, evenly among those with grooves.
        sizes_deg: light sizes tried, degrees.

    Returns:
        The choice, or None for a plate with no grooves to light.
    """
    n = len(points)
    if n == 0 or grooves.n_paths == 0:
        return None
    cut = np.unique(grooves.stipple)
    keep = cut[np.unique(np.linspace(0, len(cut) - 1, min(len(cut), sample)).round()
                         .astype(np.int64))]
    paths = np.flatnonzero(np.isin(grooves.stipple, keep))
    if len(paths) == 0:
        return None
    part = grooves.take(paths)
    part = Grooves(part.vertices, part.bulges, part.offsets,
                   np.searchsorted(keep, part.stipple))
    r = setup.viewer.half_range
    azimuths = np.array([-2.0 * r / 3.0, 0.0, 2.0 * r / 3.0])
    sub = None
    if visible is not None:
        see = visible

        def sub(p: np.ndarray, eyes: np.ndarray) -> np.ndarray:
            return see(points, np.broadcast_to(eyes[0], (n, 3)))[keep]

    trials = []
    for size in sorted(sizes_deg, reverse=True):
        reports = verify_streaks(part, points[keep], setup,
                                 Spread(math.radians(size), roughness), sub, azimuths)
        p95 = [x.p95_error for x in reports if not math.isnan(x.p95_error)]
        vis = [x.visibility for x in reports if not math.isnan(x.visibility)]
        spills = [100.0 * x.end_spills / max(x.stipples_seen, 1) for x in reports]
        trials.append(LightTrial(size, max(p95) if p95 else math.nan,
                                 min(vis) if vis else math.nan, float(np.mean(spills))))
    if any(math.isnan(t.p95_mm) for t in trials):
        return None
    # The sharpest first, then the fewest false glints among them: a smaller
    # light is not always sharper (stripes ending together blur least under
    # a large one), and one fewer in false glints but blurrier is no better.
    good_p95 = min(t.p95_mm for t in trials)
    sharp = [t for t in trials if t.p95_mm <= (1.0 + WITHIN) * good_p95]
    good_spills = min(t.spills_per_100 for t in sharp)
    fine = [t for t in sharp if t.spills_per_100 <= (1.0 + WITHIN) * good_spills + 1.0]
    chosen = max(t.size_deg for t in fine)
    return LightChoice(chosen, roughness, trials, len(keep),
                       [math.degrees(a) for a in azimuths], setup.light.distance)




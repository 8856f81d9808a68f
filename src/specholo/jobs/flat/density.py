"""How many stipples a plate can hold: the most that reach a visibility as cut.

Every groove cut takes glints away from the grooves it crosses, so the share of
stipples both eyes see on the cut plate falls as stipples are added (on the
README's example, lowest over the views: 0.97 at 500 stipples, 0.87 at 2,000,
0.64 at 4,000 and 0.36 at 8,000, thinned; ``benchmarks/density_curve.py``). A maker asking for a
visibility gets the most stipples whose design reaches it at every view.

Each try is a whole design, its as-cut figures found from its own grooves
(:func:`~specholo.jobs.flat.folder.expected_as_cut`). The search models the lowest
visibility v(n) as exp(-(n / n0)^k), a straight line in log n against
log(-log v) (k was 1.5-1.9 on the README's example), takes the line through the
two closest tries (k = 1.6 before there are two) and stops when the largest
count that reaches the target and the smallest that does not are within
:data:`CLOSE` of each other, or after :data:`MAX_TRIES` designs.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable

from specholo.errors import SpecholoError
from specholo.jobs.flat.folder import (
    AS_CUT_MAX_STIPPLES,
    DEFAULT_STIPPLES,
    Design,
    DesignConfig,
    design,
)

#: The fewest stipples tried.
MIN_STIPPLES = 50
#: The most stipples tried: the designs whose as-cut figures the design finds.
MAX_STIPPLES = AS_CUT_MAX_STIPPLES
#: Stop when the smallest failing count is within this factor of the largest passing one.
CLOSE = 1.1
#: Most designs tried.
MAX_TRIES = 7
#: log(-log v) grows with log n at about this slope before two tries measure it.
SLOPE = 1.6
#: Largest factor between one try and the next.
STRIDE = 4.0

#: Told each try's stipple count and its lowest as-cut visibility.
Progress = Callable[[int, float], None]


def lowest_as_cut(d: Design) -> float:
    """The lowest stereo visibility of the plate as cut over the views (0 when no
    view sees a stipple, or the figures were not found)."""
    figures = d.as_cut.mean_and_lowest() if d.as_cut is not None else None
    return 0.0 if figures is None else figures[1]


def _loglog(v: float) -> float:
    """log(-log v), clamped: visibility 1 and 0 are the line's ends at infinity."""
    v = min(max(v, 1e-6), 1.0 - 1e-6)
    return math.log(-math.log(v))


def _next(tries: dict[int, float], target: float, n: int) -> int:
    """The next count to try after n, from the line through the two tries nearest the target."""
    passing = [m for m, v in tries.items() if v >= target]
    failing = [m for m, v in tries.items() if v < target]
    lo = max(passing) if passing else None
    hi = min(failing) if failing else None
    near = sorted(tries, key=lambda m: abs(_loglog(tries[m]) - _loglog(target)))[:2]
    slope = SLOPE
    if len(near) == 2 and near[0] != near[1]:
        a, b = near
        measured = (_loglog(tries[b]) - _loglog(tries[a])) / (math.log(b) - math.log(a))
        if 0.3 <= measured <= 5.0:
            slope = measured
    step = math.exp((_loglog(target) - _loglog(tries[n])) / slope)
    guess = n * min(max(step, 1.0 / STRIDE), STRIDE)
    if lo is not None and hi is not None:
        # stay strictly inside the bracket; halve it (geometrically) if the
        # line points outside
        if not lo < guess < hi:
            guess = math.sqrt(lo * hi)
        guess = min(max(guess, lo * 1.02), hi / 1.02)
    return int(min(max(round(guess), MIN_STIPPLES), MAX_STIPPLES))


def design_for_visibility(model_path: str | os.PathLike[str], config: DesignConfig,
                          progress: Progress | None = None) -> Design:
    """The design with the most stipples whose plate, as cut, shows at least
    ``config.visibility`` of them in both eyes at every view.

    The search starts from ``config.stipples`` (2,000 when not given).

    Raises:
        SpecholoError: if ``config.visibility`` is not set, or even the fewest
            stipples tried do not reach it (the tool may lose views: the ideal
            grooves' figures bound the cut plate's).
    """
    target = config.visibility
    if target is None:
        raise SpecholoError("no visibility to design for")
    n = int(min(max(config.stipples or DEFAULT_STIPPLES, MIN_STIPPLES), MAX_STIPPLES))
    tries: dict[int, float] = {}
    best: Design | None = None
    best_n = 0
    for _ in range(MAX_TRIES):
        d = design(model_path, dataclasses.replace(config, stipples=n),
                   expect_as_cut=True)
        v = tries[n] = lowest_as_cut(d)
        if progress is not None:
            progress(n, v)
        if v >= target and n > best_n:
            best, best_n = d, n
        passing = [m for m, w in tries.items() if w >= target]
        failing = [m for m, w in tries.items() if w < target]
        if passing and failing and min(failing) <= CLOSE * max(passing):
            break
        if passing and max(passing) >= MAX_STIPPLES:
            break
        if failing and min(failing) <= MIN_STIPPLES:
            break
        nxt = _next(tries, target, n)
        if nxt in tries:
            break
        n = nxt
    if best is None:
        m = min(tries)
        raise SpecholoError(
            f"no stipple count reaches {target:.0%} in both eyes at every view as cut: "
            f"{m} stipples give {tries[m]:.0%} at the lowest view (check the tool's "
            "walls, or ask for less)")
    return best

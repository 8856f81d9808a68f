"""Thinning a crowded plate: leave uncut the stipples whose grooves take more
glints from the others than they show themselves.

Brand's criterion is to "select a subset of discrete hyperbolic arcs that can
be machined without destructive overlap". On a crowded plate some stipples'
glints are cut away in every view by the grooves crossing them, while their
own grooves still cut away the glints of others: cutting them costs the
image points and gains none. Which glint each cut removes is known exactly
(:func:`~specholo.simulation.survival.conflicts`), so the choice is made on
the figure the viewer sees, the stereo points of the plate as cut: the sum
over the head azimuths of the stipples whose left and right glints both
survive.

The choice is greedy. In each round every stipple still cut is scored by
what leaving it uncut alone would change: the (azimuth, stipple) pairs of
others it alone keeps from showing (each eye's glint of the pair survives,
or its only remaining cutter is this stipple), less the pairs it shows
itself. A share of the stipples with the best positive scores is left uncut, and the
scores are found again; when no stipple gains alone, those that show in no
view at all are left uncut together, until nothing changes. Leaving one
stipple uncut raises the stereo points by its score; a share at once may
restore one pair twice over, so a round that would lower them leaves only
its best stipple uncut instead. Stereo points never fall from round to round.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo.simulation.survival import EyeGlints, conflicts
from specholo.toolpaths.grooves import Grooves

#: Share of the stipples that would gain left uncut in one round: smaller
#: shares rescore more often (a removal changes its neighbours' scores) for
#: little more (README example at 8,000 stipples: 0.05 and 0.03 within 1%).
ROUND_SHARE = 0.05
#: Most rounds (each is a few passes over the glints and their cutters).
MAX_ROUNDS = 400


@dataclass(frozen=True)
class Thinned:
    """Which stipples to cut, and what the plate as cut then shows.

    Attributes:
        keep: (n,) the stipples left to cut.
        alive: (m,) the glints (of :class:`EyeGlints`) that survive when only
            the kept stipples are cut; alive_all: when every stipple is.
        shown_all: stereo (azimuth, stipple) pairs of the plate as cut with every
            stipple cut; shown: with the kept ones.
        left_uncut: ids of the stipples with grooves that thinning leaves uncut.
    """

    keep: np.ndarray
    alive: np.ndarray
    alive_all: np.ndarray
    shown_all: int
    shown: int

    left_uncut: np.ndarray


def thin(grooves: Grooves, glints: EyeGlints, unoccluded: np.ndarray, cutter: Any,
         depth: float) -> Thinned:
    """The subset of stipples whose cut plate shows the most stereo points.

    Args:
        grooves: the designed grooves (their ``stipple`` ids index ``unoccluded``).
        glints: every eye's designed glints on them.
        unoccluded: (k, n) whether both eyes of azimuth j see stipple t.
        cutter: the tool; depth: groove depth, mm.
    """
    k, n = unoccluded.shape
    g_st, slot = glints.stipple, glints.slot
    view, side = slot // 2, slot % 2
    g_pt, g_path = conflicts(grooves, glints.point, glints.path, cutter, depth)
    ids = np.asarray(grooves.stipple, dtype=np.int64)
    cutter_st = ids[g_path]
    # A glint under another stripe of its own stipple goes with that stipple,
    # and one under a path of no stipple stays gone.
    fixed = (cutter_st == g_st[g_pt]) | (cutter_st < 0) | (cutter_st >= n)
    dead = np.zeros(len(g_st), dtype=bool)
    dead[g_pt[fixed]] = True
    other = ~fixed
    pairs = np.unique(g_pt[other] * n + cutter_st[other])
    pg, ps = pairs // n, pairs % n
    keep = np.zeros(n, dtype=bool)
    keep[ids[(ids >= 0) & (ids < n)]] = True
    has_groove = keep.copy()

    def by_eye(alive: np.ndarray) -> np.ndarray:
        """(2 k, n) whether each eye has a standing glint of each stipple."""
        seen = np.zeros((2 * k, n), dtype=bool)
        seen[slot[alive], g_st[alive]] = True
        return seen

    def shown(alive: np.ndarray) -> np.ndarray:
        seen = by_eye(alive)
        return seen[0::2] & seen[1::2] & unoccluded

    def state() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        live = keep[ps]
        count = np.bincount(pg[live], minlength=len(g_st))
        mine = ~dead & keep[g_st]
        return (count == 0) & mine, count, mine

    alive, count, mine = state()
    alive_all = alive
    stereo = shown(alive)
    shown_all = int(stereo.sum())
    for _ in range(MAX_ROUNDS):
        own = stereo.sum(axis=0)
        # Glints only one cut stipple keeps from showing, and which one.
        lone = (count == 1) & mine
        at = lone[pg] & keep[ps]
        g1, s1 = pg[at], ps[at]
        # (azimuth, stipple, remover) with the eyes each removal restores.
        key = (view[g1] * n + g_st[g1]) * n + s1
        key = np.unique(key * 2 + side[g1])
        jt, s_, eye = key // 2 // n, key // 2 % n, key % 2
        trio, where = np.unique(jt * n + s_, return_inverse=True)
        ok_l = np.zeros(len(trio), dtype=bool)
        ok_r = np.zeros(len(trio), dtype=bool)
        np.logical_or.at(ok_l, where, eye == 0)
        np.logical_or.at(ok_r, where, eye == 1)
        j, t, s = trio // n // n, trio // n % n, trio % n
        seen = by_eye(alive)
        restored = ((ok_l | seen[2 * j, t]) & (ok_r | seen[2 * j + 1, t])
                    & unoccluded[j, t] & ~stereo[j, t])
        gain = np.bincount(s[restored], minlength=n) - own
        best = np.flatnonzero(keep & (gain > 0))
        before = keep.copy()
        if best.size:
            # The best share of those that gain (ties by id).
            best = best[np.argsort(-gain[best], kind="stable")]
            keep[best[:max(1, int(ROUND_SHARE * best.size))]] = False
        else:
            # None gains alone: those that show in no view go together (what
            # several of them take from one glint comes back only so).
            idle = keep & (own == 0)  # the kept all have grooves
            if not idle.any():
                break
            keep[idle] = False
        alive, count, mine = state()
        now = shown(alive)
        if best.size and now.sum() < stereo.sum():
            keep = before
            keep[best[0]] = False
            alive, count, mine = state()
            now = shown(alive)
        stereo = now
    return Thinned(keep, alive, alive_all, shown_all, int(stereo.sum()),
                   np.flatnonzero(has_groove & ~keep))

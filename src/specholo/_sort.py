"""A stable argsort for compiled kernels.

numba's own ``np.argsort(kind="mergesort")`` is a generic implementation that
takes seconds to compile for each key type (on a first run, more than most
kernels that call it); this one is a plain bottom-up merge sort. Any stable
sort gives the one order numpy's stable argsort gives: ascending, equal keys in
their order, NaN after every number.
"""

from __future__ import annotations

import numpy as np

from specholo._compiling import kernel


@kernel(nogil=True)
def stable_argsort(keys: np.ndarray) -> np.ndarray:
    """Indices (n,) that sort ``keys`` (n,) as ``np.argsort(keys, kind="stable")``."""
    n = keys.size
    order = np.empty(n, np.int64)
    for i in range(n):
        order[i] = i
    spare = np.empty(n, np.int64)
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid, hi = min(lo + width, n), min(lo + 2 * width, n)
            i, j = lo, mid
            for k in range(lo, hi):
                # The right run's item first only if strictly before: stable.
                if j < hi and (i >= mid or _before(keys[order[j]], keys[order[i]])):
                    spare[k] = order[j]
                    j += 1
                else:
                    spare[k] = order[i]
                    i += 1
        order, spare = spare, order
        width *= 2
    return order


@kernel(helper=True)
def _before(a: float, b: float) -> bool:
    """numpy's sort order: a before b, NaN after every number."""
    return a < b or (b != b and a == a)

"""Whether compiled parallel kernels may be called from several threads at once.

numba runs ``parallel=True`` kernels on a threading layer: with OpenMP or TBB
present, kernels launched from two Python threads at the same time each get
their workers; the fallback ``workqueue`` layer (neither library on the system)
aborts the whole process when that happens. Work split over Python threads
that calls parallel kernels asks :func:`concurrent_kernels_safe` first.
"""

from __future__ import annotations

import functools

import numba as nb
import numpy as np


@nb.njit(parallel=True, cache=True)
def _start_layer(a: np.ndarray) -> None:
    for i in nb.prange(a.size):
        a[i] = i


@functools.cache
def concurrent_kernels_safe() -> bool:
    """True when numba's threading layer allows concurrent parallel kernels."""
    try:
        layer = nb.threading_layer()
    except ValueError:  # no parallel kernel has run yet: the layer is chosen at the first
        _start_layer(np.zeros(2))
        layer = nb.threading_layer()
    return layer != "workqueue"

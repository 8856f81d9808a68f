"""Whether compiled parallel kernels may be called from several threads at once.

numba runs ``parallel=True`` kernels on a threading layer: with OpenMP or TBB
present, kernels launched from two Python threads at the same time each get
their workers; the fallback ``workqueue`` layer (neither library on the system)
aborts the whole process when that happens. Work split over Python threads
that calls parallel kernels asks :func:`concurrent_kernels_safe` first.

:func:`chunked` runs a serial kernel over chunks of a range on threads: what
many kernels do instead of ``parallel=True``, which costs far more to compile.
"""

from __future__ import annotations

import functools
import itertools
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numba as nb
import numpy as np

from specholo._compiling import kernel


@kernel(parallel=True)
def _start_layer(a: np.ndarray) -> None:
    for i in nb.prange(a.size):
        a[i] = i


@functools.cache
def concurrent_kernels_safe() -> bool:
    """True when numba's threading layer allows concurrent parallel kernels."""
    try:
        layer = nb.threading_layer()
    except ValueError:  # no parallel kernel has run yet: the layer is chosen at the first
        _choose_layer()
        layer = nb.threading_layer()
    return layer != "workqueue"


def _choose_layer() -> None:
    """Have numba choose its threading layer, as the first parallel kernel run does.

    numba's own starter when it has one: running :func:`_start_layer` instead
    would compile a parallel kernel on a first run (a second or more), and most
    commands run no other parallel kernel.
    """
    try:
        from numba.np.ufunc.parallel import _launch_threads
    except ImportError:  # another numba: a parallel kernel starts the layer as well
        _start_layer(np.zeros(2))
    else:
        _launch_threads()


#: Threads that run chunks of a serial kernel together (see :func:`chunked`),
#: made at the first use and kept for the process.
_POOLS: dict[int, ThreadPoolExecutor] = {}
_POOL_LOCK = threading.Lock()


def _pool(workers: int) -> ThreadPoolExecutor:
    with _POOL_LOCK:
        if workers not in _POOLS:
            _POOLS[workers] = ThreadPoolExecutor(workers, thread_name_prefix="specholo-chunk")
        return _POOLS[workers]


def chunked(kernel: Callable[..., None], start: int, stop: int, *args: Any,
            grain: int = 1) -> None:
    """``kernel(lo, hi, *args)`` over chunks [lo, hi) of [start, stop), on as
    many threads as numba's (``numba.get_num_threads()``).

    Why not ``parallel=True`` and ``prange``: numba's parallel transform is
    what compiling costs most on a first run (tens of seconds over the
    project's kernels); a serial ``nogil=True`` kernel over a chunk compiles in
    a fraction of that and, run on threads, is as fast. ``kernel`` must write
    only its own items' outputs, so the result cannot depend on the chunks.
    Serial kernels never touch numba's threading layer: any thread may run
    them, whatever :func:`concurrent_kernels_safe` says.

    The calling thread works too, and takes any chunk no pool thread has
    started, so a call from inside the pool (or with the pool busy) never
    waits on work that is not running. Ranges shorter than ``grain`` per
    thread run in the calling thread alone.
    """
    n = stop - start
    if n <= 0:
        return
    workers = min(nb.get_num_threads(), max(1, n // max(grain, 1)))
    if workers <= 1:
        kernel(start, stop, *args)
        return
    # A few chunks per thread even out kernels whose items cost unequally.
    count = min(n, 4 * workers)
    bounds = [start + n * c // count for c in range(count + 1)]
    claim = itertools.count()

    def work() -> None:
        while (c := next(claim)) < count:
            kernel(bounds[c], bounds[c + 1], *args)

    helpers = [_pool(workers - 1).submit(work) for _ in range(workers - 1)]
    try:
        work()
    finally:
        for f in helpers:
            if not f.cancel():
                f.result()

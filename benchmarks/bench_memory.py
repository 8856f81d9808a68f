"""How fast this machine hands out fresh memory: the first write to new pages.

Usage: python benchmarks/bench_memory.py [--gb 2] [--repeat 3]

A design of a million stipples writes ~6 GB of grooves once, and on some
machines (virtual ones above all) the first touch of a fresh page costs far
more than the write itself; its speed then varies from hour to hour and sets
much of the design's time. This prints, per way of touching, the seconds and
GB/s of writing --gb of fresh memory: in small pages from one thread and from
two (as the biarc pass writes the grooves), and in the huge pages numpy
advises for large arrays; and the same write to memory already touched, for
the cost of the write alone. Run it beside a timing to tell the machine's
state from the code's. A trial after the first may be given the pages the
one before it freed, which is cheaper where the memory has not gone back to
a virtual machine's host: the first trial of each way is what a fresh
process sees.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numba as nb
import numpy as np

from specholo._pages import small_pages


@nb.njit(parallel=True, cache=True)
def _fill(a: np.ndarray) -> None:
    """Write every element, on all of numba's threads."""
    for i in nb.prange(a.size):
        a[i] = 1.0


def _timed(make: Callable[[], np.ndarray], threads: int) -> float:
    """Seconds to write a fresh array from ``make`` on ``threads`` threads."""
    a = make()
    before = nb.get_num_threads()
    nb.set_num_threads(threads)
    try:
        t0 = time.perf_counter()
        _fill(a)
        return time.perf_counter() - t0
    finally:
        nb.set_num_threads(before)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--gb", type=float, default=2.0, help="fresh memory per trial, GB")
    ap.add_argument("--repeat", type=int, default=3, help="trials per way of touching")
    args = ap.parse_args()
    if not (args.gb > 0 and args.repeat >= 1):
        raise SystemExit("error: --gb must be positive and --repeat at least 1")
    n = int(args.gb * 2**30) // 8
    _fill(np.empty(16))  # compiled before any trial
    threads = nb.get_num_threads()

    def small() -> np.ndarray:
        with small_pages():
            return np.empty(n)

    touched = np.empty(n)
    _fill(touched)
    ways: list[tuple[str, Callable[[], float]]] = [
        ("small pages, 1 thread", lambda: _timed(small, 1)),
        (f"small pages, {threads} threads", lambda: _timed(small, threads)),
        (f"huge pages (numpy's advice), {threads} threads",
         lambda: _timed(lambda: np.empty(n), threads)),
        (f"already touched, {threads} threads", lambda: _timed(lambda: touched, threads)),
    ]
    print(f"writing {args.gb:g} GB, {args.repeat} trials each: seconds (GB/s)")
    for name, trial in ways:
        times = [trial() for _ in range(args.repeat)]
        shown = ", ".join(f"{t:.2f} ({args.gb / t:.1f})" for t in times)
        print(f"  {name:<40} {shown}")


if __name__ == "__main__":
    main()

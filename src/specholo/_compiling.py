"""Telling the user while numba compiles a kernel.

The compiled kernels are built for the machine they run on the first time each
is called, then loaded from numba's cache (``cache=True``). A first run spends
tens of seconds compiling with nothing else to show: :func:`compiling_shown`
calls back as each kernel starts compiling, so a display can say so. numba
raises its ``numba:compile`` event only on a cache miss: a run whose kernels are
all cached never calls back.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from typing import Any

from numba.core import event

#: ``callback(count, name)``: ``count`` of the project's kernels have started
#: compiling in this process, the newest ``name``; ``name`` is None once compiling has stopped
#: (the outermost kernel is done) and the run goes on.
CompileCallback = Callable[[int, "str | None"], None]


def kernel_name(dispatcher: Any) -> str:
    """A readable name for a compiled function: ``toolpaths stripe integrate``
    for ``specholo.toolpaths._stripe_kernel.integrate``."""
    fn = getattr(dispatcher, "py_func", None)
    module = getattr(fn, "__module__", "") or ""
    parts = [p.strip("_").removesuffix("_kernel").replace("_", " ")
             for p in module.split(".")[1:]]
    qualname = getattr(fn, "__qualname__", "") or getattr(fn, "__name__", "kernel")
    words = [p for p in parts if p] + [qualname.strip("_").replace("_", " ")]
    return " ".join(dict.fromkeys(words))  # a package named again by its module once


#: The project's kernels compiled so far in this process.
_COUNT = [0]
_LOCK = threading.Lock()


def _ours(ev: event.Event) -> bool:
    """Whether the compile is one of the project's kernels, not one of numba's
    own helpers (``min``, sorting, numpy functions) compiled for it."""
    fn = getattr(ev.data["dispatcher"], "py_func", None)
    return (getattr(fn, "__module__", "") or "").startswith("specholo")


class _Listener(event.Listener):
    """Hands each start and each end of an outermost compile to the callback.
    numba compiles under one global lock, so the events arrive one at a time,
    from whichever thread compiles."""

    def __init__(self, callback: CompileCallback) -> None:
        self.callback = callback
        self.depth = 0

    def on_start(self, ev: event.Event) -> None:
        if not _ours(ev):
            return
        with _LOCK:
            _COUNT[0] += 1
            self.depth += 1
            count = _COUNT[0]
        self.callback(count, kernel_name(ev.data["dispatcher"]))

    def on_end(self, ev: event.Event) -> None:
        if not _ours(ev):
            return
        with _LOCK:
            self.depth -= 1
            done = self.depth == 0
            count = _COUNT[0]
        if done:
            self.callback(count, None)


@contextlib.contextmanager
def compiling_shown(callback: CompileCallback) -> Iterator[None]:
    """Within the block, ``callback(count, name)`` as each kernel starts
    compiling and ``callback(count, None)`` when compiling stops (see
    :data:`CompileCallback`)."""
    listener = _Listener(callback)
    event.register("numba:compile", listener)
    try:
        yield
    finally:
        event.unregister("numba:compile", listener)

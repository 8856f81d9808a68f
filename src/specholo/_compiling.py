"""Compiling the project's kernels, and telling the user while numba does.

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
from typing import Any, TypeVar

import numba as nb
from numba.core import event

_Function = TypeVar("_Function", bound=Callable[..., Any])


def kernel(*, helper: bool = False, **options: Any) -> Callable[[_Function], _Function]:
    """``numba.njit`` as every kernel of the project is compiled: cached on disk
    (``cache=True``), with ``options`` (``nogil``, ``parallel``, ``fastmath``,
    ``inline``) passed on.

    numba gives each compiled function two wrappers besides its own code, one
    for calls from Python and one for calls through a C function pointer, and
    has LLVM optimise and emit each. Nothing here takes a kernel's address, so
    no kernel gets the second; a ``helper``, called only from other kernels,
    gets neither (calling one from Python fails). On a first run that spares
    about 0.03 s per kernel and 0.07 s per helper, several seconds in all.
    """
    jit: Any = nb.njit  # (numba's hints name no wrapper options)
    decorator: Callable[[_Function], _Function] = jit(
        cache=True, no_cfunc_wrapper=True, no_cpython_wrapper=helper, **options)
    return decorator


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

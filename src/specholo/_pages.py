"""Fresh memory for large outputs, mapped in small pages.

numpy asks the kernel for transparent huge pages on every large array
(``madvise(MADV_HUGEPAGE)``). Where the kernel compacts memory to find them
on the first touch (``defrag`` set to ``madvise``, the common default) and on
virtual machines whose host backs memory lazily, the first write to such an
array runs at well under 1 GB/s, several times slower than in small pages
(measured here: 2 GB in 4.0-4.6 s against 0.7-2.2 s). The grooves of a million
stipples are ~6 GB written once and read a few times, so they are allocated in
small pages: :func:`small_pages` turns numpy's request off while they are.
"""

from __future__ import annotations

import contextlib
import importlib
from collections.abc import Callable, Iterator


def _setter() -> Callable[[bool], bool] | None:
    for name in ("numpy._core.multiarray", "numpy.core.multiarray"):  # numpy 2, then 1
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        fn = getattr(module, "_set_madvise_hugepage", None)
        if fn is not None:
            return fn  # type: ignore[no-any-return]
    return None


_set_madvise_hugepage = _setter()


@contextlib.contextmanager
def small_pages() -> Iterator[None]:
    """Arrays allocated inside are not advised to use huge pages (numpy's
    setting is restored after; a numpy without the setting is left alone)."""
    if _set_madvise_hugepage is None:
        yield
        return
    before = _set_madvise_hugepage(False)
    try:
        yield
    finally:
        _set_madvise_hugepage(before)

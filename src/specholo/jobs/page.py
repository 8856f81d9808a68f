"""The interactive page of a designed folder of any kind (``specholo view``): a
flat plate's grooves are redrawn in the browser for every viewpoint; every other
kind's glints are found beforehand for a grid of views, along its motion
(:func:`specholo.preview.source.page`)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from specholo.errors import SpecholoError


def write_page(folder: str | os.PathLike[str], out: str | os.PathLike[str] | None = None,
               size: tuple[int, int] | None = None, step: float | None = None,
               progress: Any = None) -> Path:
    """Write the interactive page of the design in ``folder``.

    Args:
        folder: a design folder of any kind.
        out: the HTML file; default ``folder/view.html``.
        size: fixed canvas (width, height) in CSS pixels, or None to fill the window.
        step: for a page of precomputed views (every kind but the flat plate),
            their spacing, degrees (default
            :data:`specholo.preview.page.FIELD_VIEW_STEP`).
        progress: for a page of precomputed views, called with (views done,
            views), or None.

    Returns:
        The path written.
    """
    from specholo.fabrication.atomic import atomic_open
    from specholo.jobs import job_of
    from specholo.preview.source import page

    path = Path(folder) / "view.html" if out is None else Path(out)
    if path.suffix.lower() not in (".html", ".htm"):
        raise SpecholoError(f"page must be an .html file, got {path.name!r}")
    if not path.parent.is_dir():
        raise SpecholoError(f"folder {path.parent} does not exist")
    if size is not None and not all(0 < v <= 8192 for v in size):
        raise SpecholoError(f"canvas size must be in [1, 8192] pixels, got {size}")
    title = f"specholo: {Path(folder).resolve().name}"
    source = job_of(Path(folder)).picture_source(Path(folder))
    text = page(source, title, size, step, progress)
    with atomic_open(path) as fh:
        fh.write(text)
    return path

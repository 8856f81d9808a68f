"""The interactive page of a designed folder (``specholo view``): grooves are
redrawn in the browser for every viewpoint; a ridged plate's glints are found
beforehand for a grid of views."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from specholo.errors import SpecholoError
from specholo.ridged import is_ridged_folder, load_ridged_design


def write_page(folder: str | os.PathLike[str], out: str | os.PathLike[str] | None = None,
               size: tuple[int, int] | None = None, step: float | None = None,
               progress: Any = None) -> Path:
    """Write the interactive page of the design in ``folder``.

    Args:
        folder: a design folder written by ``specholo design``.
        out: the HTML file; default ``folder/view.html``.
        size: fixed canvas (width, height) in CSS pixels, or None to fill the window.
        step: for a ridged design (a height field), the spacing of the views whose
            glints the page holds, degrees (default
            :data:`specholo.preview.page.FIELD_VIEW_STEP`).
        progress: for a ridged design, called with (views done, views), or None.

    Returns:
        The path written.
    """
    from specholo.fabrication.atomic import atomic_open
    from specholo.pipeline import load_design
    from specholo.preview.page import (
        FIELD_VIEW_STEP,
        FieldViews,
        build_field_page,
        build_page,
        field_page_views,
    )

    step = FIELD_VIEW_STEP if step is None else step
    path = Path(folder) / "view.html" if out is None else Path(out)
    if path.suffix.lower() not in (".html", ".htm"):
        raise SpecholoError(f"page must be an .html file, got {path.name!r}")
    if not path.parent.is_dir():
        raise SpecholoError(f"folder {path.parent} does not exist")
    if size is not None and not all(0 < v <= 8192 for v in size):
        raise SpecholoError(f"canvas size must be in [1, 8192] pixels, got {size}")
    title = f"specholo: {Path(folder).resolve().name}"
    if is_ridged_folder(folder):
        ridged = load_ridged_design(folder)
        setup = ridged.config.setup()
        az, el = field_page_views(setup, float(ridged.config.elevation_range), step)
        views = FieldViews.build(ridged.heights, setup, az, el, progress=progress)
        text = build_field_page(views, ridged.heights, setup, title, size)
    else:
        loaded = load_design(folder)
        text = build_page(loaded.grooves, loaded.config.setup(), title, size)
    with atomic_open(path) as fh:
        fh.write(text)
    return path

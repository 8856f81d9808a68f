"""The page's quick figures: a sample of the exact design, in about a second.

What a maker decides on (the share of stipples both eyes see on the plate as
cut, the hours on the machine, the strokes) comes only from designing the
grooves: which glints the other grooves' cuts take away depends on how dense
the plate is where they lie. So the estimate designs, exactly, a part of the
plate at the whole design's density: the stipples whose glint lies in one
horizontal strip across the plate's middle, seen straight on, a fifth of them
(:data:`SAMPLE_SHARE`, at most :data:`SAMPLE_MOST`). A stipple's glint moves
across the plate, not up it, as the eyes walk the arc, so its grooves stay in
its strip among the neighbours they would cross on the whole plate. The
strip's as-cut shares stand for the plate's; its strokes and hours, scaled by
the groove length the views need, for the job's. ``benchmarks/studio_estimates.py`` measures how
far they fall from the exact design's (docs/studio.md states the margin).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from specholo.jobs.flat.folder import DesignConfig

#: The share of the stipples the estimate designs, and the most and fewest it
#: designs; a design of at most :data:`WHOLE` stipples is designed whole.
SAMPLE_SHARE = 0.2
SAMPLE_MOST = 400
SAMPLE_FEWEST = 100
WHOLE = 300


def middle_strip(config: DesignConfig, share: float) -> Callable[[np.ndarray], np.ndarray]:
    """Which stipples (n, 3) the estimate designs: the ``share`` of them whose
    glint, seen from straight in front, lies nearest the plate's middle height
    (the median glint height)."""
    from specholo.hosts.flat import sightline_crossing

    viewer = config.setup().viewer
    head = np.array([0.0, viewer.height, viewer.distance])  # straight in front

    def keep(points: np.ndarray) -> np.ndarray:
        y = sightline_crossing(np.broadcast_to(head, points.shape), points)[:, 1]
        rank = np.argsort(np.argsort(y, kind="stable"), kind="stable")
        middle = 0.5 * (len(y) - 1)
        return np.abs(rank - middle) <= 0.5 * share * len(y)

    return keep


def estimate(model: Path, config: DesignConfig, loaded: Any = None) -> dict[str, Any]:
    """The design's figures from a sample of it (:func:`middle_strip`).

    The strip's as-cut shares stand for the plate's. Its strokes and hours
    are scaled by the groove length the whole design's views need over the
    strip's (the preview's closed form, :func:`~specholo.studio.preview.groove_length_bound`):
    a strip whose stipples lie nearer the plate than the rest has shorter
    grooves, and fewer strokes, than its share of the stipples.

    Args:
        model: the model's file.
        config: the settings.
        loaded: the model as :func:`specholo.scene.loading.load_model` read it
            (read from ``model`` when not given).

    Returns:
        ``as_cut_mean``, ``as_cut_lowest`` (shares of the stipples both eyes
        see, the plate as cut), ``strokes``, ``machining_hours`` and
        ``machining`` (in words), ``sample`` (stipples designed), ``of``
        (stipples in all), ``seconds``; or ``why`` alone where no estimate is
        made (a count chosen by visibility or spacing).
    """
    from specholo.fabrication.programs.order import order_paths
    from specholo.fabrication.programs.timing import plain_duration
    from specholo.jobs.flat.design import design
    from specholo.jobs.flat.folder import machining_estimate
    from specholo.scene.loading import load_model
    from specholo.studio.preview import fast_preview, groove_length_bound

    if config.stipples is None:
        return {"why": "the stipple count is chosen by the design (--visibility or "
                       "--spacing): its figures come with it"}
    t0 = time.perf_counter()
    total = int(config.stipples)
    share = 1.0 if total <= WHOLE else \
        min(max(SAMPLE_SHARE, SAMPLE_FEWEST / total), SAMPLE_MOST / total)
    strip = None if share >= 1.0 else middle_strip(config, share)
    d = design(model, config, sample=strip)
    n = len(d.points)
    scale = 1.0
    if strip is not None:
        # the whole design's stipples and the views each needs, as the preview has them
        preview = fast_preview(loaded if loaded is not None else load_model(model), config)
        setup = config.setup()
        need = groove_length_bound(preview.points, preview.stipple, preview.start,
                                   preview.end, setup.light, setup.viewer)
        kept = need[strip(preview.points)].sum()
        scale = float(need.sum() / kept) if kept > 0 else total / max(n, 1)
    vis = d.as_cut.stereo_visibility if d.as_cut is not None else np.array([math.nan])
    seen = vis[~np.isnan(vis)]
    grooves = order_paths(d.grooves)[0] if d.config.order else d.grooves
    hours = machining_estimate(d.config, grooves)[2].total_s / 3600.0 * scale
    return {"as_cut_mean": float(seen.mean()) if seen.size else None,
            "as_cut_lowest": float(seen.min()) if seen.size else None,
            "strokes": round(d.grooves.n_paths * scale), "machining_hours": hours,
            "machining": plain_duration(3600.0 * hours), "sample": n, "of": total,
            "seconds": time.perf_counter() - t0}

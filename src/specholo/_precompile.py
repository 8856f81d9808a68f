"""Compiling a design's later kernels in a second process on a first run.

On a fresh install a design spends most of its time having numba compile
kernels, one after another in one thread: the stipples', occlusion's and
toolpaths' first, then those of the as-cut estimate (or the overlap figure),
the ordering, the G-code and its check. :func:`start` runs the later stages on a
tiny made-up design in a process of its own while the design's own first stages
compile and run, so the later kernels are compiled on another core and written
to numba's on-disk cache, which the design then loads instead of compiling them.
The grooves' last step, chaining the walked samples into biarcs, is among
them: the design reaches it only after its placement, long after this process
has compiled it.

Only when the cache is cold (:func:`cache_is_cold`); a run whose kernels are
cached starts nothing. The second process runs at a lower priority, so the
design's own threads keep the cores when both want them, and it writes nothing
but numba's cache (each file written whole, as numba writes it).
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
import sys
import tempfile
from pathlib import Path
from typing import Any


def cache_is_cold() -> bool:
    """Whether numba's cache holds no text writer yet (the G-code's and the
    drawings'), one of the last kernels a design compiles: a fresh install, or
    a cache emptied since."""
    from specholo.fabrication import exporting

    writer: Any = exporting._write_rows
    try:
        index = writer._cache._cache_file._index_path
    except AttributeError:  # another numba, or caching off: nothing to share
        return False
    return not os.path.exists(index)


def start(config: Any) -> multiprocessing.process.BaseProcess | None:
    """A process compiling the later kernels of a design with ``config`` (a
    ``pipeline.DesignConfig``), started when the cache is cold; None otherwise.
    :func:`stop` it when the design is done."""
    if os.environ.get("SPECHOLO_NO_PRECOMPILE") or not cache_is_cold():
        return None
    # spawn: a fork would copy the design's threads and locks mid-use.
    process = multiprocessing.get_context("spawn").Process(
        target=_later_stages, args=(config,), name="specholo-precompile", daemon=True)
    try:
        process.start()
    except OSError:  # no room for a process: the design compiles them itself
        return None
    return process


def stop(process: multiprocessing.process.BaseProcess | None) -> None:
    """End the process :func:`start` started, if it still runs (what it has
    compiled is in the cache; the rest the design compiled itself)."""
    if process is None:
        return
    if process.is_alive():
        process.terminate()
    process.join(timeout=5.0)


def _later_stages(config: Any) -> None:
    """The stages after the toolpaths, on a few made-up grooves: what calls the
    kernels with the very types a design calls them with."""
    with contextlib.suppress(OSError, AttributeError):
        os.nice(10)
    # Nothing to the design's terminal, nor its pipes held open.
    devnull = os.open(os.devnull, os.O_RDWR)
    for fd in (0, 1, 2):
        os.dup2(devnull, fd)
    sys.stdout = sys.stderr = open(os.devnull, "w")  # noqa: SIM115  (the process's life)
    try:
        _run(config)
    except Exception:  # noqa: BLE001  a kernel not compiled here is compiled by the design
        pass


def _run(config: Any) -> None:
    import dataclasses

    import numpy as np

    from specholo.jobs.flat.folder import AS_CUT_MAX_STIPPLES, Design, expected_as_cut, write_design
    from specholo.toolpaths.common import make_runs
    from specholo.toolpaths.overlap import groove_overlaps

    if config.depth is None:
        config = dataclasses.replace(config, depth=0.05)
    points, grooves = _tiny(config)
    n = len(points)
    half = math.radians(config.view_range)
    runs = make_runs(points, np.arange(n, dtype=np.int64), np.full(n, -half),
                     np.full(n, half))
    # What the design finds after its grooves, as it decides (see design()):
    # the as-cut estimate, or past it the overlap tallies.
    overlaps = as_cut = None
    if (config.stipples or 0) > AS_CUT_MAX_STIPPLES:
        width = config.cutter().section(config.depth_mm).width
        extent, total = grooves.extent_and_length()
        overlaps = groove_overlaps(grooves, width, extent=extent, total_length=total)
    else:
        from specholo.simulation.lighting import choose_light

        as_cut = expected_as_cut(config, points, runs, grooves)
        choose_light(grooves, points, config.setup(), sizes_deg=(0.53,))  # its streak walk
    _chains()
    model = _Model()
    d = Design(config, model, points, None, runs, grooves, np.zeros(0, np.int64), {},
               overlaps=overlaps, as_cut=as_cut)
    with tempfile.TemporaryDirectory(prefix="specholo-precompile-") as tmp:
        write_design(d, Path(tmp) / "out", command=["specholo"])


def _chains() -> None:
    """The striped design's last step, biarc chains through walked samples,
    on two made-up runs of a stripe each: the design compiles its walks and
    placement itself, early, but reaches this step only after them."""
    import numpy as np

    from specholo.toolpaths.grooves import GroovesBuilder
    from specholo.toolpaths.striped import chain_samples

    count = np.array([4, 3], dtype=np.int64)
    slots = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    m = int(slots[-1])
    x = np.arange(m, dtype=float)
    point = np.ascontiguousarray(np.stack([0.3 * x, 0.01 * x * x], axis=1))
    tangent = np.ascontiguousarray(np.stack([np.full(m, 0.3), 0.02 * x], axis=1))
    samples = (slots[:-1], count, np.zeros(m, dtype=np.int64), point, tangent,
               np.empty(m, dtype=np.uint8))
    chain_samples(GroovesBuilder(), samples, np.arange(2, dtype=np.int64))


class _Model:
    """A model with no mesh (nothing to export)."""

    mesh = None


def _tiny(config: Any) -> tuple[Any, Any]:
    """A few stipples below the plate and, for each, a path of half circles
    about the point under it (every direction of groove, so each eye finds
    glints), two stipples' paths crossing; a path of nearly straight arcs;
    dots for two more. The half circles
    turn one way and the other along a line, so the path's direction never
    jumps, as a design's never does: a corner would compile the corners'
    glint kernel, which no design of the README's kind needs."""
    import numpy as np

    from specholo.toolpaths.grooves import Grooves

    points = np.array([[0.0, 0.0, -5.0], [0.6, 0.2, -6.0], [3.0, -2.0, -4.0],
                       [-3.0, 2.0, -5.0], [5.0, 5.0, -3.0], [-5.0, -4.0, -4.0]])
    vertices: list[list[float]] = []
    bulges: list[float] = []
    offsets = [0]
    stipple: list[int] = []
    for s, (x, y, _) in enumerate(points[:4]):
        for r in (0.4, 0.8):
            start = len(vertices)
            for k in range(5):  # a wave of half circles
                vertices.append([x - r + 0.5 * r * k, y])
                bulges.append(1.0 if k % 2 else -1.0)
            bulges[-1] = 0.0
            offsets.append(offsets[-1] + len(vertices) - start)
            stipple.append(s)
    # Nearly straight arcs along a line, bending one way and the other (as a
    # striped design's biarcs do): the glint index sorts such arcs by cell
    # and direction, kernels the half circles above never reach.
    start = len(vertices)
    for k in range(6):
        vertices.append([-4.0 + 0.7 * k, 1.0])
        bulges.append(0.002 if k % 2 else -0.002)
    bulges[-1] = 0.0
    offsets.append(offsets[-1] + len(vertices) - start)
    stipple.append(1)
    for s in (4, 5):  # dots: one vertex each
        vertices.append([float(points[s, 0]), float(points[s, 1])])
        bulges.append(0.0)
        offsets.append(offsets[-1] + 1)
        stipple.append(s)
    grooves = Grooves(np.array(vertices), np.array(bulges), np.array(offsets, np.int64),
                      np.array(stipple, np.int64))
    return points, grooves

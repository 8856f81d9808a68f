"""The verification chart: error and visibility by azimuth (``verify.png``).

Drawn with matplotlib on an Agg figure. Importing matplotlib takes about half
a second, a quarter of a verification; :class:`ChartDrawer` imports it in a
process of its own while the verification runs, then draws there. This module
imports neither numba nor the glint physics, so that process starts light.
"""

from __future__ import annotations

import contextlib
import io
import multiprocessing
import os
from multiprocessing.connection import Connection
from typing import Any

from specholo.fabrication.atomic import atomic_open

Rows = list[dict[str, float]]


def _figure(**kwargs: Any) -> Any:
    """A matplotlib figure drawn by Agg, without pyplot: pyplot's import (its
    backends and state) costs more than drawing a small chart."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def verification_png(rows: Rows, title: str = "") -> bytes:
    """PNG bytes of error and visibility by azimuth (rows from verification)."""
    az = [r["azimuth"] for r in rows]
    fig = _figure(figsize=(7, 6))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(az, [r["median_error"] for r in rows], "o-", label="median")
    ax1.plot(az, [r["p95_error"] for r in rows], "s-", label="95th percentile")
    ax1.plot(az, [r["p95_depth_error"] for r in rows], "^--", label="95th pct, depth only")
    ax1.set_ylabel("apparent-point error (mm)")
    ax1.legend()
    ax1.grid(alpha=0.3)
    ax2.plot(az, [r["visibility"] for r in rows], "o-", label="visibility")
    ax2.plot(az, [r["false_glints"] for r in rows], "s-", label="false glints")
    ax2.set_ylim(-0.02, 1.02)
    ax2.set_xlabel("head azimuth (degrees)")
    ax2.legend()
    ax2.grid(alpha=0.3)
    if title:
        ax1.set_title(title)
    # Margins set, not fitted: the figure's size and labels never change, and
    # fitting them measures every text (a tenth of a second of a verify).
    fig.subplots_adjust(left=0.1, right=0.975, bottom=0.08, top=0.94 if title else 0.975,
                        hspace=0.06)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    return buf.getvalue()


class ChartDrawer:
    """Draws verification charts in a second process, which imports matplotlib
    as soon as it starts: start one before a verification, hand it the rows
    after. Where no process can be started, or it fails, the chart is drawn
    here instead; the bytes are the same either way. Use as a context manager
    (the process ends with the block, or when its caller's process ends)."""

    def __init__(self) -> None:
        # spawn: a fork would copy the caller's threads and locks mid-use.
        context = multiprocessing.get_context("spawn")
        self._conn: Connection | None = None
        self._process: Any = None
        try:
            self._conn, child = context.Pipe()
            self._process = context.Process(target=_serve, args=(child,),
                                            name="specholo-chart", daemon=True)
            self._process.start()
            child.close()
        except OSError:  # no room for a process: drawn here
            self._conn = self._process = None

    def __enter__(self) -> ChartDrawer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def verification_png(self, rows: Rows, title: str = "") -> bytes:
        """:func:`verification_png`, drawn by the second process when it runs."""
        if self._conn is not None:
            try:
                self._conn.send((rows, title))
                png = self._conn.recv()
                if isinstance(png, bytes):
                    return png
            except (EOFError, OSError):  # the process died: drawn here
                pass
            self.close()
        return verification_png(rows, title)

    def plot_verification(self, rows: Rows, path: str | os.PathLike[str],
                          title: str = "") -> None:
        """Write the chart of :func:`verification_png` to ``path`` (atomically)."""
        png = self.verification_png(rows, title)
        with atomic_open(path, "wb", encoding=None) as fh:
            fh.write(png)

    def close(self) -> None:
        """End the second process (a chart asked for later is drawn here)."""
        conn, process, self._conn, self._process = self._conn, self._process, None, None
        if conn is not None:
            with contextlib.suppress(OSError):
                conn.send(None)
            conn.close()
        if process is not None:
            process.join(timeout=2.0)
            if process.is_alive():
                process.terminate()


def _serve(conn: Connection) -> None:
    """The second process: import matplotlib, then draw each chart asked for
    until told to stop or its caller is gone."""
    _figure()  # the import, before the first chart is asked for
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return
        if job is None:
            return
        try:
            png: bytes | None = verification_png(*job)
        except Exception:  # noqa: BLE001  the caller draws it itself
            png = None
        try:
            conn.send(png)
        except (BrokenPipeError, OSError):
            return

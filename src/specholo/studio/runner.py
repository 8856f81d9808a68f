"""The studio's exact design: one at a time, in a background thread.

The page asks for a design and polls :meth:`Runner.status`; the design and its
files are the command line's own (:func:`specholo.jobs.flat.folder.design`,
:func:`specholo.jobs.flat.folder.write_design`), written into a folder published whole,
so a folder the page offers is always a complete design.
"""

from __future__ import annotations

import io
import math
import threading
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from specholo.errors import SpecholoError
from specholo.jobs.flat.folder import DesignConfig, design, write_design

#: The stages of a design, as the page shows them.
STAGES = ("designing: stipples, occlusion, grooves and their as-cut figures",
          "writing the G-code, SVG, DXF and data",
          "comparing with the classic arcs of the same settings")


#: The files the studio's designs write (the PDF pattern is made when asked for:
#: :meth:`Runner.export`).
STUDIO_FORMATS = ("gcode", "svg", "dxf")
#: The files the page exports one by one: file name -> (its ``--formats`` name,
#: its media type).
EXPORTS = {"hologram.gcode": ("gcode", "text/plain"),
           "hologram.svg": ("svg", "image/svg+xml"),
           "hologram.dxf": ("dxf", "application/dxf"),
           "pattern.pdf": ("pdf", "application/pdf")}


def one_line(exc: BaseException) -> str:
    """An error as the one line the page shows (never a traceback)."""
    if isinstance(exc, MemoryError):
        return "out of memory; try fewer stipples"
    text = str(exc).splitlines()[0] if str(exc).strip() else ""
    if isinstance(exc, SpecholoError):
        return text or "bad input"
    if isinstance(exc, OSError):
        name = f"{exc.filename}: " if exc.filename else ""
        return f"{name}{exc.strerror or text or type(exc).__name__}"
    return f"internal error ({type(exc).__name__}: {text})"


def summary_figures(d: Any, written: Any, out: Path) -> dict[str, Any]:
    """The design's own figures for the page: as cut, machining, hidden stipples."""
    from specholo.fabrication.programs.timing import plain_duration
    from specholo.jobs.flat.job import design_summary

    figures = d.as_cut.mean_and_lowest() if d.as_cut is not None else None
    mach = written.machining
    summary = design_summary(d, written, out)
    return {
        "stipples": int(len(d.points)),
        "paths": int(d.grooves.n_paths),
        "groove_length_mm": float(d.grooves.total_length()),
        "as_cut_mean": None if figures is None else float(figures[0]),
        "as_cut_lowest": None if figures is None else float(figures[1]),
        "machining_hours": float(mach["estimated_hours"]),
        "machining": plain_duration(3600.0 * float(mach["estimated_hours"])),
        "cutting_hours": float(mach.get("cutting_hours", math.nan)),
        "hidden": None if d.coverage is None else int(d.coverage.hidden),
        # the light that gives this plate its sharpest image, as the design names it
        "light": None if getattr(d, "light", None) is None else d.light.describe(),
        "depth_mm": float(d.config.depth_mm),
        "lines": list(summary.lines),
        "warnings": list(summary.warnings),
    }


#: The views the comparison with the classic arcs verifies, at most this far apart.
COMPARE_STEP = math.radians(5.0)


def design_figures(d: Any, label: str) -> dict[str, Any]:
    """What a maker weighs a design by, on the same scene: its strokes and
    groove length, its worst 95th-percentile error and lowest share of
    stipples shown to both eyes on the ideal grooves (both eyes simulated at
    every view at most :data:`COMPARE_STEP` apart, as ``specholo verify``), and
    the share it expects to show as cut."""
    from specholo.simulation.verify import summarise, verify, view_azimuths
    from specholo.visibility.occlusion import visible

    setup = d.config.setup()
    mesh, normals = d.model.mesh, d.normals
    shown = None
    if mesh is not None and normals is not None:
        def shown(points: Any, eyes: Any) -> Any:
            return visible(mesh, points, normals, eyes)

    reports = verify(d.grooves, d.points, setup, shown,
                     view_azimuths(setup.viewer.half_range, COMPARE_STEP))
    worst = summarise(reports)
    figures = d.as_cut.mean_and_lowest() if d.as_cut is not None else None

    def number(v: float) -> float | None:
        return None if math.isnan(v) else float(v)

    return {"label": label, "strokes": int(d.grooves.n_paths),
            "groove_length_mm": float(d.grooves.total_length()),
            "worst_p95_mm": number(worst["worst_p95_error"]),
            "lowest_visibility": number(worst["min_visibility"]),
            "as_cut_mean": None if figures is None else float(figures[0]),
            "as_cut_lowest": None if figures is None else float(figures[1])}


def compare_with_arcs(model: Path, d: Any) -> list[dict[str, Any]]:
    """The design beside the classic arcs of the same settings (``--method arc``:
    one circular arc a stipple, right only near the straight-on view), each by
    :func:`design_figures`; an arc design alone is itself the arcs."""
    import dataclasses

    method = d.config.method
    rows = [design_figures(d, "classic arcs" if method == "arc" else f"exact ({method})")]
    if method != "arc":
        arcs = design(model, dataclasses.replace(d.config, method="arc"))
        rows.append(design_figures(arcs, "classic arcs"))
    return rows


class Runner:
    """At most one exact design at a time, its stage and its result.

    Args:
        out_root: the folder designs are written under (one subfolder a model).
        compare: set each design beside the classic arcs of its settings
            (:func:`compare_with_arcs`) before it is done.
    """

    def __init__(self, out_root: Path, compare: bool = True) -> None:
        self.out_root = Path(out_root)
        # each design is set beside the classic arcs (compare_with_arcs)
        self.compare = compare
        self._lock = threading.Lock()
        self._state: dict[str, Any] = {"state": "idle"}
        self._started = 0.0
        self._thread: threading.Thread | None = None
        self._export_lock = threading.Lock()
        # every folder a design of this run finished into -> its model's number:
        # a page may still draw one after the next design has started
        self._finished: dict[str, int] = {}

    def start(self, model: Path, name: str, config: DesignConfig,
              on_done: Callable[[], None] | None = None, model_id: int = 0) -> bool:
        """Start a design of ``model`` into ``out_root/name``; False if one is running.

        ``model_id`` names the model the design is of: :meth:`status` and
        :meth:`zip_bytes` asked for another model do not give this design's.
        """
        with self._lock:
            if self._state["state"] == "running":
                return False
            out = (self.out_root / name).resolve()
            self._state = {"state": "running", "stage": STAGES[0], "folder": str(out),
                           "stipples": config.stipples, "model_id": model_id}
            self._started = time.monotonic()
            # A daemon: Ctrl-C ends the studio at once; a design cut short leaves
            # its folder as it was (published whole or not at all).
            self._thread = threading.Thread(target=self._run, args=(model, out, config, on_done),
                                            name="specholo-studio-design", daemon=True)
            self._thread.start()
            return True

    def _set(self, **values: Any) -> None:
        with self._lock:
            self._state.update(values)

    def _run(self, model: Path, out: Path, config: DesignConfig,
             on_done: Callable[[], None] | None) -> None:
        from specholo._compiling import compiling_shown

        stage = [STAGES[0]]

        def compiling(count: int, name: str | None) -> None:
            # A first run compiles the kernels for tens of seconds: say so.
            self._set(stage=stage[0] if name is None else
                      f"{stage[0]} (compiling for this machine, once: kernel {count}, {name})")

        try:
            with compiling_shown(compiling):
                d = design(model, config)
                stage[0] = STAGES[1]
                self._set(stage=STAGES[1])
                out.parent.mkdir(parents=True, exist_ok=True)
                written = write_design(d, out, command=["specholo", "studio", str(model)],
                                       inputs=[model], formats=STUDIO_FORMATS)
                summary = summary_figures(d, written, out)
                if self.compare:
                    stage[0] = STAGES[2]
                    self._set(stage=STAGES[2])
                    summary["compared"] = compare_with_arcs(model, d)
            with self._lock:
                self._state.update(state="done", stage="done", summary=summary)
                self._finished[str(out)] = int(self._state.get("model_id", 0))
        except BaseException as exc:  # noqa: BLE001 - the page shows one line, never a trace
            self._set(state="failed", stage="failed", error=one_line(exc))
        finally:
            with self._lock:
                self._state["seconds"] = time.monotonic() - self._started
            if on_done is not None:
                on_done()

    def status(self, model_id: int | None = None) -> dict[str, Any]:
        """The state (idle, running, done, failed), stage, seconds, figures or error.

        Asked for ``model_id`` (None: whatever model), a design of another model
        is none of its own: idle once finished; while it runs (one design at a
        time) it stays running, its stage saying whose it is.
        """
        with self._lock:
            state = dict(self._state)
            if state["state"] == "running":
                state["seconds"] = time.monotonic() - self._started
        if model_id is None or state.get("model_id", model_id) == model_id:
            return state
        if state["state"] == "running":
            return {"state": "running", "model_id": state["model_id"],
                    "stage": "finishing the previous model's design",
                    "seconds": state["seconds"]}
        return {"state": "idle"}

    def wait(self, timeout: float | None = None) -> None:
        """Wait for the running design, if any (tests, and a clean exit)."""
        thread = self._thread
        if thread is not None:
            thread.join(timeout)

    def finished_folder(self, model_id: int | None = None) -> Path:
        """The finished design's folder (of ``model_id``'s model; None: any).

        Raises:
            SpecholoError: no finished design (of that model), or its folder is gone.
        """
        state = self.status(model_id)
        if state["state"] != "done":
            raise SpecholoError("no finished design of this model to download yet")
        folder = Path(state["folder"])
        if not folder.is_dir():
            raise SpecholoError(f"the design folder {folder} is gone")
        return folder

    def finished_into(self, folder: str) -> int:
        """The number of the model whose design this run finished into ``folder``
        (the folder a status named), even if another design has started since.

        Raises:
            SpecholoError: no design of this run finished into that folder (the
                page names only folders the studio wrote, never another path).
        """
        with self._lock:
            model_id = self._finished.get(folder)
        if model_id is None:
            raise SpecholoError("no finished design of this studio is in that folder")
        return model_id

    def export(self, name: str, model_id: int | None = None) -> Path:
        """One file of the finished design (:data:`EXPORTS`). The paper pattern
        takes about a minute at 100,000 strokes, so it is made only when asked
        for: written atomically into the design's folder from the folder
        itself, as ``specholo design --formats pdf`` would have written it.

        Raises:
            SpecholoError: an unknown file, or no finished design.
        """
        if name not in EXPORTS:
            raise SpecholoError(f"no such file to export: {name[:40]!r} "
                                f"(one of {', '.join(EXPORTS)})")
        folder = self.finished_folder(model_id)
        path = folder / name
        if not path.exists():
            if name != "pattern.pdf":
                raise SpecholoError(f"this design was written without {name}")
            with self._export_lock:  # two clicks write it once
                if not path.exists():
                    from specholo.jobs.flat.folder import write_paper_pattern

                    write_paper_pattern(folder)
        return path

    def zip_bytes(self, model_id: int | None = None) -> tuple[str, bytes]:
        """The finished design's folder as a zip, made in memory: (file name, bytes).

        Args:
            model_id: the model the design must be of (None: whatever model).

        Raises:
            SpecholoError: no finished design (of that model), or its folder is gone.
        """
        folder = self.finished_folder(model_id)
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
            for f in sorted(folder.rglob("*")):
                if f.is_file():
                    zf.write(f, Path(folder.name) / f.relative_to(folder))
        return f"{folder.name}.zip", buf.getvalue()

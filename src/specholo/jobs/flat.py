"""The flat plate of grooves (``specholo design`` with a striped, hyperbola or arc
method): verified by stereo eye pairs along the arc, ideally and as cut."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from specholo.jobs.base import Status, Table, Verification, VerifyOptions


class FlatJob:
    """A flat plate of grooves (the folders no other kind holds)."""

    kind = "flat"
    title = "a flat-plate design"
    verified_on = "its grooves"
    pictures = frozenset({"render", "animate", "stereo", "report", "view"})
    own_pictures = "preview.png"

    def holds(self, folder: Path) -> bool:
        return True

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.fabrication.atomic import atomic_open
        from specholo.pipeline import (
            DEFAULT_RESOLUTION,
            cut_method,
            load_design,
            verify_cut_design,
            verify_design,
        )
        from specholo.preview.preview import plot_verification
        from specholo.simulation.verify import reports_to_dicts, summarise

        cut = options.cut
        method = cut_method(options.cut_method, options.resolution, options.stl) if cut else None
        resolution = options.resolution
        if method == "field" and resolution is None:
            resolution = DEFAULT_RESOLUTION
        loaded = load_design(folder, from_gcode=options.from_gcode or cut)
        status("simulating eye pairs...")
        reports = verify_design(loaded, options.step_deg)
        rows = reports_to_dicts(reports)
        summary = summarise(reports)
        cut_rows: list[dict[str, Any]] = []
        cut_summary: dict[str, Any] = {}
        if cut:
            status("finding which glints the other grooves' cuts leave..." if method == "survival"
                   else "cutting the plate and simulating eye pairs...")
            cut_reports, _ = verify_cut_design(loaded, options.step_deg, resolution, options.stl,
                                               method)
            cut_rows = reports_to_dicts(cut_reports)
            cut_summary = dict(summarise(cut_reports))
        columns = ["azimuth", "median mm", "p95 mm", "p95 depth mm", "max mm", "visibility",
                   "false"] + (["cut p95 mm", "cut visibility"] if cut else [])
        table_rows = []
        for i, r in enumerate(rows):
            extra = [] if not cut else [f"{cut_rows[i]['p95_error']:.3f}",
                                        f"{cut_rows[i]['visibility']:.3f}"]
            table_rows.append([f"{r['azimuth']:+.1f}", f"{r['median_error']:.3f}",
                               f"{r['p95_error']:.3f}", f"{r['p95_depth_error']:.3f}",
                               f"{r['max_error']:.3f}", f"{r['visibility']:.3f}",
                               f"{r['false_glints']:.3f}", *extra])
        name = loaded.config.method
        lines = [f"worst p95 error {summary['worst_p95_error']:.3f} mm, "
                 f"min visibility {summary['min_visibility']:.3f}, "
                 f"max false glints {summary['max_false_glints']:.3f}"]
        if cut:
            how = ("the glints no other groove's cut removes" if method == "survival"
                   else f"height field at {resolution:g} mm")
            lines.append(f"cut plate ({how}): worst p95 error "
                         f"{cut_summary['worst_p95_error']:.3f} mm, min visibility "
                         f"{cut_summary['min_visibility']:.3f} (other grooves cut away the rest)")
        source = "hologram.gcode" if options.from_gcode or cut else "grooves.npz"

        def verify_json(into: Path) -> None:
            with atomic_open(into / "verify.json") as fh:
                json.dump({"method": name, "source": source, "summary": summary,
                           "azimuths": rows}, fh, indent=1)

        def verify_cut_json(into: Path) -> None:
            with atomic_open(into / "verify_cut.json") as fh:
                json.dump({"method": name, "source": source, "cut_method": method,
                           "resolution_mm": resolution if method == "field" else None,
                           "summary": cut_summary, "azimuths": cut_rows}, fh, indent=1)

        def verify_png(into: Path) -> None:
            plot_verification(rows, into / "verify.png", f"{name}: stereo verification")

        files: dict[str, Callable[[Path], object]] = {"verify.json": verify_json,
                                                      "verify.png": verify_png}
        if cut:
            files["verify_cut.json"] = verify_cut_json
        return Verification(lines, Table(f"{name} design, {len(loaded.points)} stipples",
                                         columns, table_rows), files)

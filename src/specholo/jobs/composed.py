"""A composition (curved hosts, animation, moving lights): verified by eye pairs,
or the light, along its motion."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from specholo.jobs.base import (
    Status,
    Summary,
    Table,
    Verification,
    VerifyOptions,
    refuse_cut_options,
)


def design_summary(d: Any, check: dict[str, Any]) -> Summary:
    """What a composed design (``compose.ComposedDesign``) says once its G-code is
    checked: its stripes and groove, and the stipple-views it could not serve."""
    lines = [f"{d.stats['stripes']} stripes, {d.stats['groove_length_mm'] / 1000:.2f} m of "
             f"groove; G-code checked: {check['cutting_moves']} cutting moves, deepest "
             f"{check['deepest_cut_mm']:.4f} mm"]
    fams = d.stats["families"]
    missed = sum(f["states_missing_the_host"] for f in fams)
    tilt = sum(f["states_lost_to_tilt"] for f in fams)
    warnings = []
    if missed or tilt:
        warnings.append(f"of {sum(f['states_served'] for f in fams) + missed + tilt} "
                        f"stipple-views, {missed} miss the host and {tilt} need a wall steeper "
                        "than the tool's")
    return Summary(lines, warnings)


class ComposedJob:
    """A composed design (``specholo compose``)."""

    kind = "composed"
    title = "a composed design"
    verified_on = "its grooves"
    pictures: frozenset[str] = frozenset()
    own_pictures = "preview.png and preview.gif"

    def holds(self, folder: Path) -> bool:
        from specholo.compose import is_composed_folder

        return is_composed_folder(folder)

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.compose import load_composition_folder, verify_composition
        from specholo.fabrication.atomic import atomic_open
        from specholo.simulation.conforming import reports_to_dicts, summarise

        refuse_cut_options(self, options)
        d = load_composition_folder(folder)
        status("simulating eye pairs along the motion...")
        reports = verify_composition(d, math.radians(options.step_deg))
        label = "azimuth" if d.comp.motion.mode == "walk" else "light elev."
        table = Table(f"verification ({d.comp.host.kind} host, {d.comp.motion.mode})",
                      [label, "shown", "median mm", "p95 mm", "p95 depth mm", "visibility",
                       "stray"],
                      [[f"{r.position:+.1f}", str(r.shown), f"{r.median_error:.3f}",
                        f"{r.p95_error:.3f}", f"{r.p95_depth_error:.3f}",
                        f"{r.visibility:.3f}", f"{r.stray:.3f}"] for r in reports])
        summary = summarise(reports)

        def verify_json(into: Path) -> None:
            with atomic_open(into / "verify.json") as fh:
                json.dump({"positions": reports_to_dicts(reports), "summary": summary}, fh,
                          indent=1, sort_keys=True)

        line = (f"worst p95 error {summary['worst_p95_error']:.3f} mm, lowest visibility "
                f"{summary['min_visibility']:.3f}, most stray glints {summary['max_stray']:.3f}")
        return Verification([line], table, {"verify.json": verify_json})

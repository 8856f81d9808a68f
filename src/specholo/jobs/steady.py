"""A steady image under a moving light (``specholo steady``): verified over the
light's range."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from specholo.jobs.base import (
    Status,
    Summary,
    Verification,
    VerifyOptions,
    refuse_cut_options,
)


def design_summary(design: Any, config: Any, s: dict[str, Any], out: Path) -> Summary:
    """What a steady image (``toolpaths.steady.SteadyDesign`` with its
    ``steady.SteadyConfig``) and its verification over the light's range say."""
    mid = math.degrees(config.setup.elevation)
    half = math.degrees(config.setup.half_range)
    return Summary([
        f"{len(design.points)} stipples, {design.n_cuts} {config.shape}s -> {out}",
        f"light {mid - half:g} to {mid + half:g} deg: worst p95 {s['worst_p95_mm']:.3f} mm, "
        f"image drift p95 {s['worst_drift_p95_mm']:.3f} mm, lowest visibility "
        f"{s['lowest_visibility']:.3f}, stray glints {s['stray']}"], [])


class SteadyJob:
    """A steady-image design (scoops)."""

    kind = "steady"
    title = "a steady-image design"
    verified_on = "its cuts"
    pictures: frozenset[str] = frozenset()
    own_pictures = "preview.png"

    def holds(self, folder: Path) -> bool:
        from specholo.steady import is_steady_folder

        return is_steady_folder(folder)

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.steady import (
            light_steps,
            load_steady_folder,
            summarise,
            verify_steady,
            write_verification,
        )

        refuse_cut_options(self, options)
        design, config = load_steady_folder(folder)
        status("moving the light...")
        reports = verify_steady(design, config.tool, light_steps(config.setup, options.step_deg))
        s = summarise(reports)
        lines = [f"light {r.elevation_deg:5.1f} deg: p95 {r.p95_mm:.3f} mm, drift "
                 f"{r.drift_p95_mm:.3f} mm, visibility {r.visibility:.3f}, stray {r.stray}"
                 for r in reports[::max(1, len(reports) // 8)]]
        lines.append(f"worst p95 {s['worst_p95_mm']:.3f} mm, drift "
                     f"{s['worst_drift_p95_mm']:.3f} mm, lowest visibility "
                     f"{s['lowest_visibility']:.3f}, stray glints {s['stray']} "
                     f"-> {folder / 'verify.json'}")
        return Verification(lines, None, {"verify.json": lambda into: write_verification(
            reports, into, options.step_deg)})

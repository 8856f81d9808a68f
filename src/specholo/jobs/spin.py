"""A turning plate (``specholo spin``): verified over one turn of the plate."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from specholo.jobs.base import (
    Status,
    Summary,
    Verification,
    VerifyOptions,
    refuse_cut_options,
)


def design_summary(job: Any, summary: dict[str, Any], out: Path, step_deg: float) -> Summary:
    """What a turning-plate design (``spin.SpinJob``) and its verification over the
    turn say."""
    g = job.design.grooves
    tracks = job.design.tracks
    shown = "" if tracks is None else \
        f" (about {tracks.shown.sum(axis=0).mean():.0f} shown at once)"
    return Summary([
        f"{len(job.design.points)} stipples{shown}, {g.n_paths} paths, "
        f"{g.total_length() / 1000:.2f} m of groove -> {out}",
        f"over the turn (every {step_deg:g} deg): worst p95 {summary['worst_p95_mm']:.3f} mm, "
        f"depth p95 {summary['worst_depth_p95_mm']:.3f} mm, lowest visibility "
        f"{summary['lowest_visibility']:.3f}, stray glints {summary['stray']}"], [])


class SpinJob:
    """A turning-plate design."""

    kind = "spinning"
    title = "a turning-plate design"
    verified_on = "its grooves"
    pictures: frozenset[str] = frozenset()
    own_pictures = "preview.gif"

    def holds(self, folder: Path) -> bool:
        from specholo.spin import is_spin_folder

        return is_spin_folder(folder)

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.spin import load_spin_folder, summarise, verify_spin, write_spin_verification

        refuse_cut_options(self, options)
        job = load_spin_folder(folder)
        status("turning the plate...")
        reports = verify_spin(job, options.step_deg)
        s = summarise(reports)
        lines = [f"plate {r.angle_deg:6.1f} deg: p95 {r.p95_mm:.3f} mm (depth "
                 f"{r.depth_p95_mm:.3f}), visibility {r.visibility:.3f}, stray {r.stray}"
                 for r in reports[::max(1, len(reports) // 8)]]
        lines.append(f"worst p95 {s['worst_p95_mm']:.3f} mm, depth "
                     f"{s['worst_depth_p95_mm']:.3f} mm, lowest visibility "
                     f"{s['lowest_visibility']:.3f}, stray glints {s['stray']} "
                     f"-> {folder / 'verify.json'}")
        return Verification(lines, None, {"verify.json": lambda into: write_spin_verification(
            reports, into, options.step_deg)})

"""A turning plate (``specholo spin``): verified over one turn of the plate."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from specholo.jobs.base import (
    PICTURE_COMMANDS,
    Designed,
    Status,
    Summary,
    Verification,
    VerifyOptions,
    WriteOptions,
    refuse_cut_options,
    refuse_formats,
)

if TYPE_CHECKING:
    from specholo.preview.source import PictureSource


def _fig(v: float) -> str:
    """A figure as printed: '-' where there was nothing to measure (NaN: no
    stipple glinted for both eyes)."""
    return "-" if math.isnan(v) else f"{v:.3f}"


def design_summary(job: Any, summary: dict[str, Any], out: Path, step_deg: float) -> Summary:
    """What a turning-plate design (``spin.design.SpinPlate``) and its verification over the
    turn say."""
    g = job.design.grooves
    tracks = job.design.tracks
    shown = "" if tracks is None else \
        f" (about {tracks.shown.sum(axis=0).mean():.0f} shown at once)"
    return Summary([
        f"{len(job.design.points)} stipples{shown}, {g.n_paths} paths, "
        f"{g.total_length() / 1000:.2f} m of groove -> {out}",
        f"over the turn (every {step_deg:g} deg): worst p95 {_fig(summary['worst_p95_mm'])} mm, "
        f"depth p95 {_fig(summary['worst_depth_p95_mm'])} mm, lowest visibility "
        f"{_fig(summary['lowest_visibility'])}, stray glints {summary['stray']}"], [])


class SpinJob:
    """A turning-plate design."""

    kind = "spin"
    title = "a turning-plate design"
    verified_on = "its grooves"
    pictures: frozenset[str] = PICTURE_COMMANDS
    own_pictures = "preview.gif"
    design_step: tuple[float, float, float] | None = (5.0, 0.5, 90.0)
    preview_frames: int | None = 48
    files: frozenset[str] = frozenset({
        "hologram.json", "grooves.npz", "stipples.npz", "model.ply", "run.json",
        "hologram.gcode", "relief.gcode", "hologram.svg", "verify.json", "preview.gif"})

    def configure(self, values: Mapping[str, Any], inputs: Sequence[Path]) -> Any:
        from specholo.jobs.spin.design import SpinConfig
        from specholo.scene.pose import split_pose

        pose, given = split_pose(values)
        return SpinConfig.from_options(models=len(inputs), pose=pose, **given)

    def check_options(self, config: Any, options: WriteOptions) -> None:
        refuse_formats(self, options)

    def design(self, inputs: Sequence[Path], config: Any, status: Status) -> Designed:
        from specholo.jobs.spin.design import design_spin

        if config.fit:
            status("fitting the model to the plate and designing its grooves...")
        else:
            status("designing closed grooves..." if config.turns == 1 else
                   "designing stipples sliding over the turning scene...")
        return Designed(design_spin(list(inputs), config))

    def write(self, designed: Designed, out: Path, inputs: Sequence[Path | None],
              options: WriteOptions, status: Status) -> Summary:
        from specholo.jobs.spin.design import write_spin

        step, frames = options.step_deg or 5.0, options.frames or 0
        status("verifying the turn and writing...")
        summary = write_spin(designed.design, out, step, frames, inputs=inputs)
        return design_summary(designed.design, summary, out, step)

    def holds(self, folder: Path) -> bool:
        from specholo.jobs.spin.design import is_spin_folder

        return is_spin_folder(folder)

    def load(self, folder: Path) -> Any:
        from specholo.jobs.spin.design import load_spin_folder

        return load_spin_folder(folder)

    def preview(self, folder: Path, status: Status) -> dict[str, Callable[[Path], object]]:
        from specholo.jobs.spin.design import preview_frames
        from specholo.preview.motion import write_animation

        job = self.load(folder)

        def gif(into: Path) -> None:
            status("turning the plate for preview.gif...")
            write_animation(preview_frames(job, self.preview_frames or 48),
                            into / "preview.gif", fps=12)

        return {"preview.gif": gif}

    def picture_source(self, folder: Path) -> PictureSource:
        """Its grooves turning under the still eyes (glints found per plate angle,
        as verify finds them), the blank its files name turning with them."""
        from specholo.jobs.spin.design import spin_plate
        from specholo.preview.sources import SpinSource

        job = self.load(folder)
        c, d = job.config, job.design
        s = c.setup
        light = "a sun on the axis" if s.light_height is None else \
            f"a point light on the axis, {s.light_height:g} mm above the plate"
        plate = spin_plate(job)
        (x0, y0), (x1, y1) = plate.box
        scene = ("turning with the plate (closed grooves)" if c.turns == 1 else
                 f"circling {c.turns} times a turn (stipples sliding on open grooves)")
        facts = [
            ("kind", "turning plate (specholo spin)"),
            ("stipples", f"{len(d.points):,}, the scene {scene}"),
            ("grooves", f"{d.grooves.n_paths:,} paths, {d.grooves.total_length() / 1000:.2f} m"),
            ("viewer", f"{s.distance:g} mm away, {math.degrees(s.elevation):g} deg above the "
                       f"plate, IPD {s.ipd:g} mm"),
            ("light", light),
            ("tool", f"ball radius {c.tool.radius:g} mm, {c.tool.depth:g} mm deep, grooves "
                     f"{c.tool.width:.3f} mm wide, walls: {s.walls}"),
            ("plate", f"{x1 - x0:.1f} x {y1 - y0:.1f} mm, {c.stock_thickness:g} mm thick"),
        ]
        model = job.mesh if job.mesh is not None else d.points
        return SpinSource(d, c.tool, plate.box, model, facts)

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.jobs.spin.design import (
            load_spin_folder,
            summarise,
            verify_spin,
            write_spin_verification,
        )

        refuse_cut_options(self, options)
        job = load_spin_folder(folder)
        status("turning the plate...")
        reports = verify_spin(job, options.step_deg)
        s = summarise(reports)
        lines = [f"plate {r.angle_deg:6.1f} deg: p95 {_fig(r.p95_mm)} mm (depth "
                 f"{_fig(r.depth_p95_mm)}), visibility {_fig(r.visibility)}, stray {r.stray}"
                 for r in reports[::max(1, len(reports) // 8)]]
        lines.append(f"worst p95 {_fig(s['worst_p95_mm'])} mm, depth "
                     f"{_fig(s['worst_depth_p95_mm'])} mm, lowest visibility "
                     f"{_fig(s['lowest_visibility'])}, stray glints {s['stray']} "
                     f"-> {folder / 'verify.json'}")
        return Verification(lines, None, {"verify.json": lambda into: write_spin_verification(
            reports, into, options.step_deg)})

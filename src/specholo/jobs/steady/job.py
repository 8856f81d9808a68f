"""A steady image under a moving light (``specholo steady``): verified over the
light's range."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from specholo.errors import SpecholoError
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


def design_summary(design: Any, config: Any, s: dict[str, Any], out: Path,
                   stippling: Any = None, machining: dict[str, float] | None = None
                   ) -> Summary:
    """What a steady image (``toolpaths.steady.SteadyDesign`` with its
    ``steady.SteadyConfig``) and its verification over the light's range say, in
    a flat design's words (:func:`specholo.jobs.flat.job.design_summary`): how many of
    the stipples asked for got scoops and why the rest did not
    (``steady.Stippling``, when known), the plate, the tool, the machining time
    (``machining``: hologram.json's figures, when known) and the verification."""
    from specholo.fabrication.programs.timing import describe_machining
    from specholo.jobs.steady.design import steady_plate

    noun = "scoop" if config.shape == "scoop" else "flat groove"
    kept = len(design.points)
    mid = math.degrees(config.setup.light_elevation)
    half = math.degrees(config.setup.light_sweep)
    if stippling is None:
        lines = [f"{kept} stipples, {design.n_cuts} {noun}s -> {out}"]
    else:
        lines = [f"{kept} of the {stippling.asked} stipples asked for got {noun}s "
                 f"({design.n_cuts}, one for each eye) -> {out}"]
        if kept < stippling.asked:
            lines.append(f"not cut: {stippling.asked - kept} of the {stippling.asked}: "
                         + "; ".join(_left_out(design, stippling, noun)))
    lines.append(_plate_line(steady_plate(design, config), config))
    tool = config.tool
    lines.append(f"tool: ball end, radius {tool.radius:g} mm, {tool.depth:g} mm deep at most, "
                 f"{noun}s {tool.width:.3f} mm wide at the surface"
                 + (" (each rises out of the plate at both ends)" if noun == "scoop" else ""))
    if machining is not None:
        lines.append(describe_machining(machining, config.machining.feed))
    lines.append(f"light {mid - half:g} to {mid + half:g} deg: worst p95 "
                 f"{_fig(s['worst_p95_mm'])} mm, image drift p95 "
                 f"{_fig(s['worst_drift_p95_mm'])} mm, lowest visibility "
                 f"{_fig(s['lowest_visibility'])}, stray glints {s['stray']}")
    return Summary(lines, [])


def _left_out(design: Any, stippling: Any, noun: str) -> list[str]:
    """Why the stipples asked for and not cut were left out, a clause a reason
    (those with none left out say nothing)."""
    from specholo.toolpaths.steady import RADIUS_RANGE

    why = []
    if stippling.placed < stippling.asked:
        why.append(f"{stippling.asked - stippling.placed} never placed (the model has only "
                   f"{stippling.placed} distinct points)")
    if stippling.hidden_both:
        why.append(f"{stippling.hidden_both} hidden from both eyes (on the model's far side "
                   "or behind another part of it)")
    if stippling.hidden_one:
        why.append(f"{stippling.hidden_one} hidden from one eye (a stipple needs a {noun} for "
                   "each eye)")
    if design.dropped:
        why.append(f"{design.dropped} with no {noun} of radius up to {RADIUS_RANGE[1]:g} mm "
                   "that keeps the other eye's glint off it and its own inside the cut over "
                   "the light's range (a narrower --light-sweep keeps more)")
    return why


def _plate_line(plate: Any, config: Any) -> str:
    """The plate a maker prepares, in one line, as a flat design's summary words
    it (:func:`specholo.jobs.flat.job.plate_line`)."""
    from specholo.fabrication.plate import PLATE_MARGIN

    thick = f", {config.stock_thickness:g} mm thick"
    how = ("as given" if config.plate is not None
           else f"fitted to the cuts with a {PLATE_MARGIN:g} mm border")
    line = f"plate: {plate.width:.0f} x {plate.height:.0f} mm{thick} ({how})"
    if config.fit:
        line += f"; --fit sized the model {config.size:g} mm"
    return line


class SteadyJob:
    """A steady-image design (scoops)."""

    kind = "steady"
    title = "a steady-image design"
    verified_on = "its cuts"
    pictures: frozenset[str] = PICTURE_COMMANDS
    own_pictures = "preview.png"
    design_step: tuple[float, float, float] | None = (1.0, 0.05, 10.0)
    preview_frames: int | None = None
    files: frozenset[str] = frozenset({
        "hologram.json", "stipples.npz", "run.json", "hologram.gcode", "verify.json",
        "preview.png"})

    def configure(self, values: Mapping[str, Any], inputs: Sequence[Path]) -> Any:
        from specholo.jobs.steady.design import SteadyConfig
        from specholo.scene.pose import split_pose

        pose, given = split_pose(values)
        return SteadyConfig.from_options(pose=pose, **given)

    def check_options(self, config: Any, options: WriteOptions) -> None:
        refuse_formats(self, options)

    def design(self, inputs: Sequence[Path], config: Any, status: Status) -> Designed:
        from specholo.jobs.steady.design import design_steady_sized

        if len(inputs) != 1:
            raise SpecholoError(f"a steady image is of one model, got {len(inputs)}")
        status("fitting the model to the plate and designing its scoops..." if config.fit
               else "designing a scoop for each stipple and eye...")
        # with fit the size is the plate's: the config that says so is the one written
        return Designed(design_steady_sized(inputs[0], config))

    def write(self, designed: Designed, out: Path, inputs: Sequence[Path | None],
              options: WriteOptions, status: Status) -> Summary:
        import json

        from specholo.jobs.steady.design import write_steady

        design, config, stippling = designed.design
        step = options.step_deg or 1.0
        status("moving the light and writing...")
        s = write_steady(design, config, out, step, inputs=inputs, stippling=stippling)
        # the machining time as the folder records it
        written = json.loads((out / "hologram.json").read_text(encoding="utf-8"))
        return design_summary(design, config, s, out, stippling, written["machining"])

    def holds(self, folder: Path) -> bool:
        from specholo.jobs.steady.design import is_steady_folder

        return is_steady_folder(folder)

    def load(self, folder: Path) -> Any:
        from specholo.jobs.steady.design import load_steady_folder

        return load_steady_folder(folder)

    def preview(self, folder: Path, status: Status) -> dict[str, Callable[[Path], object]]:
        from specholo.preview.steady import steady_preview

        design, config = self.load(folder)
        return {"preview.png": lambda into: steady_preview(design, config.tool,
                                                           into / "preview.png")}

    def picture_source(self, folder: Path) -> PictureSource:
        """Its scoops seen from the still eyes as the light moves (glints found per
        light elevation, as verify finds them), on the plate its files name."""
        from specholo.jobs.steady.design import steady_plate
        from specholo.preview.sources import SteadySource

        design, config = self.load(folder)
        s = config.setup
        plate = steady_plate(design, config)
        (x0, y0), (x1, y1) = plate.box
        mid, half = math.degrees(s.light_elevation), math.degrees(s.light_sweep)
        facts = [
            ("kind", "steady image under a moving light (specholo steady)"),
            ("stipples", f"{len(design.points):,} ({design.dropped} dropped)"),
            ("cuts", f"{design.n_cuts:,} {design.shape}s, one per stipple and eye"),
            ("viewer", f"{s.distance:g} mm away, still, eye height {s.height:g} mm, IPD "
                       f"{s.ipd:g} mm"),
            ("light", f"a sun from {mid - half:g} to {mid + half:g} deg elevation"),
            ("tool", f"ball radius {config.tool.radius:g} mm, {config.tool.depth:g} mm deep"),
            ("plate", f"{x1 - x0:.1f} x {y1 - y0:.1f} mm, {config.stock_thickness:g} mm thick"),
        ]
        return SteadySource(design, config.tool, plate.box, facts)

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.jobs.steady.design import (
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
        lines = [f"light {r.elevation_deg:5.1f} deg: p95 {_fig(r.p95_mm)} mm, drift "
                 f"{_fig(r.drift_p95_mm)} mm, visibility {_fig(r.visibility)}, stray {r.stray}"
                 for r in reports[::max(1, len(reports) // 8)]]
        lines.append(f"worst p95 {_fig(s['worst_p95_mm'])} mm, drift "
                     f"{_fig(s['worst_drift_p95_mm'])} mm, lowest visibility "
                     f"{_fig(s['lowest_visibility'])}, stray glints {s['stray']} "
                     f"-> {folder / 'verify.json'}")
        return Verification(lines, None, {"verify.json": lambda into: write_verification(
            reports, into, options.step_deg)})

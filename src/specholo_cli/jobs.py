"""The other jobs' commands: ``compose``, ``spin``, ``steady``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import click

from specholo.errors import SpecholoError
from specholo_cli.app import (
    _check_out,
    _Folder,
    _pose,
    _pose_options,
    _print_summary,
    _print_verification,
    cli,
)


@cli.command()
@click.argument("composition", type=click.Path(path_type=Path))
@click.option("--out", type=_Folder(path_type=Path), required=True,
              help="Output folder (written atomically).")
@click.option("--step", type=float, default=5.0, show_default=True,
              help="Largest step between verified viewer positions, degrees.")
@click.option("--frames", type=int, default=48, show_default=True,
              help="Frames of preview.gif along the motion (0 for none).")
def compose(composition: Path, out: Path, step: float, frames: int) -> None:
    """Design a hologram from a TOML composition: any host (plane, cylinder, sphere,
    height field, mesh, panels), a walking viewer or a moving light, one or more
    scenes keyed to the motion; then verify it."""
    from rich.console import Console

    from specholo.compose import (
        composition_files,
        design_composition,
        read_composition,
        write_composition,
    )
    from specholo.jobs import VerifyOptions
    from specholo.jobs.composed import ComposedJob, design_summary

    if not (math.isfinite(step) and 0.1 <= step <= 30.0):
        raise SpecholoError(f"step must be in [0.1, 30] degrees, got {step}")
    if not 0 <= frames <= 1000:
        raise SpecholoError(f"frames must be in [0, 1000], got {frames}")
    _check_out(out, [composition])
    comp = read_composition(composition)
    _check_out(out, [composition, *composition_files(comp)])
    with Console(stderr=True).status("designing grooves along the motion...") as status:

        def finish(stage: Path, check: dict[str, Any]) -> None:
            """The verification and previews, published with the design's files."""
            status.stop()
            _print_summary(design_summary(d, check))
            with Console(stderr=True).status("simulating eye pairs along the motion...") as s:
                result = ComposedJob().verify(stage, VerifyOptions(step), s.update)
            _print_verification(result)
            result.write(stage)  # joins the new design's files, published with them
            _preview_composed(d, stage, frames)

        d = design_composition(comp)
        write_composition(d, out, [composition], then=finish)


@cli.command()
@click.argument("model", type=click.Path(path_type=Path), nargs=-1, required=True)
@click.option("--out", type=_Folder(path_type=Path), required=True,
              help="Output folder (written atomically).")
@click.option("--size", type=float, default=40.0, show_default=True,
              help="Largest side of the model's bounding box, mm.")
@click.option("--center-z", type=float, default=0.0, show_default=True,
              help="Depth of the model's box centre, mm (0 straddles the plate).")
@click.option("--turns", type=int, default=None,
              help="Circuits of the view about the scene per plate turn [the number of "
              "models]. 2 with two models: a different scene on each circuit.")
@click.option("--stipples", type=int, default=800, show_default=True,
              help="Number of stipples (with --turns 2 or more: shown at once).")
@click.option("--seed", type=int, default=0, show_default=True, help="Stippling seed.")
@click.option("--view-distance", type=float, default=600.0, show_default=True,
              help="From the plate centre to the viewer's eyes, mm.")
@click.option("--view-elevation", type=float, default=45.0, show_default=True,
              help="The eyes' angle above the plate's plane, degrees.")
@click.option("--ipd", type=float, default=64.0, show_default=True,
              help="Interocular distance, mm.")
@click.option("--light-height", type=float, default=None,
              help="A point light on the turning axis this far in front, mm [distant].")
@click.option("--walls", type=click.Choice(["one", "both"]), default="one", show_default=True,
              help="one: a relief cut takes away each groove's other wall (no twin image); "
              "both: plain grooves, which also show the scene mirrored through the plate.")
@click.option("--no-occlusion", is_flag=True, help="Keep every groove whole.")
@click.option("--tool-radius", type=float, default=0.25, show_default=True,
              help="Ball radius, mm.")
@click.option("--depth", type=float, default=0.08, show_default=True, help="Groove depth, mm.")
@click.option("--step", type=float, default=5.0, show_default=True,
              help="Step between verified plate angles, degrees.")
@click.option("--frames", type=int, default=48, show_default=True,
              help="Frames of preview.gif over one turn (0 for none).")
@_pose_options
def spin(model: tuple[Path, ...], out: Path, size: float, center_z: float, turns: int | None,
         stipples: int, seed: int,
         view_distance: float, view_elevation: float, ipd: float, light_height: float | None,
         walls: str, no_occlusion: bool, tool_radius: float, depth: float, step: float,
         frames: int, **pose: Any) -> None:
    """Design a hologram of MODEL for a plate turning about its normal (a turntable or
    wall spinner) under a light on the axis, then verify it over the turn.

    One model: one closed groove per stipple, the scene turning rigidly with the
    plate through 360 degrees. Several models (or --turns N): the view circles the
    scene N times per plate turn, each model on its own circuit (720 degrees for
    two), with stipples sliding over the turning scene on open grooves."""
    from rich.console import Console

    from specholo.setup import Tool
    from specholo.spin import SpinConfig, design_spin, write_spin
    from specholo.toolpaths.spinning import SpinSetup

    if not (math.isfinite(step) and 0.5 <= step <= 90.0):
        raise SpecholoError(f"step must be in [0.5, 90] degrees, got {step}")
    if not 0 <= frames <= 1000:
        raise SpecholoError(f"frames must be in [0, 1000], got {frames}")
    _check_out(out, model)
    setup = SpinSetup(distance=view_distance, elevation=math.radians(view_elevation), ipd=ipd,
                      light_height=light_height, walls=walls)
    turns = len(model) if turns is None else turns
    config = SpinConfig(size=size, center_z=center_z, stipples=stipples, seed=seed,
                        pose=_pose(**pose),
                        occlusion=not no_occlusion, turns=turns, setup=setup,
                        tool=Tool(tool_radius, depth))
    what = "closed grooves" if turns == 1 else "stipples sliding over the turning scene"
    with Console(stderr=True).status(f"designing {what} and verifying the turn..."):
        job = design_spin(list(model), config)
        summary = write_spin(job, out, step, frames, inputs=list(model))
    from specholo.jobs.spin import design_summary

    _print_summary(design_summary(job, summary, out, step))


@cli.command()
@click.argument("model", type=click.Path(path_type=Path))
@click.option("--out", type=_Folder(path_type=Path), required=True,
              help="Output folder (written atomically).")
@click.option("--size", type=float, default=40.0, show_default=True,
              help="Largest side of the model's bounding box, mm.")
@click.option("--center-z", type=float, default=-20.0, show_default=True,
              help="Depth of the model's box centre, mm (negative: behind the plate).")
@click.option("--stipples", type=int, default=300, show_default=True,
              help="Number of stipples (those hidden from an eye are dropped).")
@click.option("--seed", type=int, default=0, show_default=True, help="Stippling seed.")
@click.option("--view-distance", type=float, default=600.0, show_default=True,
              help="From the plate centre to the viewer's eyes, mm (straight in front).")
@click.option("--ipd", type=float, default=64.0, show_default=True,
              help="Interocular distance, mm.")
@click.option("--light-elevation", type=float, default=45.0, show_default=True,
              help="The sun's middle elevation, degrees.")
@click.option("--light-range", type=float, default=5.0, show_default=True,
              help="The sun moves this far either way, degrees.")
@click.option("--shape", type=click.Choice(["scoop", "flat"]), default="scoop",
              show_default=True, help="scoop: steady; flat: plain grooves, to compare.")
@click.option("--tool-radius", type=float, default=0.05, show_default=True,
              help="Ball radius, mm.")
@click.option("--depth", type=float, default=0.02, show_default=True, help="Cut depth, mm.")
@click.option("--step", type=float, default=1.0, show_default=True,
              help="Step between verified light elevations, degrees.")
@_pose_options
def steady(model: Path, out: Path, size: float, center_z: float, stipples: int, seed: int,
           view_distance: float, ipd: float, light_elevation: float, light_range: float,
           shape: str, tool_radius: float, depth: float, step: float, **pose: Any) -> None:
    """Design a hologram of MODEL for a viewer standing still whose image stays put
    while the sun moves a little in elevation: for each stipple and eye, a scoop
    whose glint does not move with the light. Then verify it over the range."""
    from specholo.setup import Tool
    from specholo.steady import SteadyConfig, design_steady_job, write_steady
    from specholo.toolpaths.steady import SteadySetup

    if not (math.isfinite(step) and 0.05 <= step <= 10.0):
        raise SpecholoError(f"step must be in [0.05, 10] degrees, got {step}")
    _check_out(out, [model])
    setup = SteadySetup(distance=view_distance, ipd=ipd,
                        elevation=math.radians(light_elevation),
                        half_range=math.radians(light_range))
    config = SteadyConfig(size=size, center_z=center_z, stipples=stipples, seed=seed,
                          pose=_pose(**pose),
                          shape=shape, setup=setup, tool=Tool(tool_radius, depth))
    design = design_steady_job(model, config)
    s = write_steady(design, config, out, step, inputs=[model])
    from specholo.jobs.steady import design_summary

    _print_summary(design_summary(design, config, s, out))


def _preview_composed(d: Any, out: Path, frames: int) -> None:
    """preview.png and preview.gif, with a progress bar over the animation's frames."""
    from rich.progress import Progress

    from specholo.preview.composed import write_previews

    with Progress(transient=True, console=None) as bar:
        task = bar.add_task("rendering preview.gif", total=frames)
        write_previews(d, out, frames, progress=lambda: bar.advance(task))

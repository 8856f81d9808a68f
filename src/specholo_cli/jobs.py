"""The other jobs' commands: ``compose``, ``spin``, ``steady`` and ``coupon``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from specholo.jobs.base import WriteOptions
from specholo_cli.app import (
    _DESIGN_OPTIONS,
    _command_line,
    _Folder,
    _plate_options,
    _pose_options,
    _print_summary,
    _print_verification,
    _status,
    cli,
)


def _program_options(fn: Any) -> Any:
    """--dialect and --units, for the jobs whose programs plunge a cutter (no
    laser): the library checks them again, and says why a laser cannot."""
    fn = click.option("--units", type=click.Choice(["mm", "inch"]), default="mm",
                      help="G-code units: every coordinate and feed in mm or inches [mm].")(fn)
    return click.option("--dialect", type=click.Choice(["grbl", "linuxcnc"]), default="grbl",
                        help="G-code for GRBL or LinuxCNC; no laser: these programs plunge a "
                             "cutter [grbl].")(fn)


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
    from specholo.jobs.composition.job import CompositionJob

    _run(CompositionJob(), [composition], {}, out, WriteOptions(step_deg=step, frames=frames))


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
@click.option("--stock-thickness", type=float, default=3.0, show_default=True,
              help="Thickness of the plate blank, mm: no cut may reach its back.")
@_program_options
@_plate_options
@_pose_options
def spin(model: tuple[Path, ...], out: Path, size: float, center_z: float, turns: int | None,
         stipples: int, seed: int,
         view_distance: float, view_elevation: float, ipd: float, light_height: float | None,
         walls: str, no_occlusion: bool, tool_radius: float, depth: float, step: float,
         frames: int, stock_thickness: float, dialect: str, units: str,
         plate_width: float | None, plate_height: float | None, fit: bool,
         **pose: Any) -> None:
    """Design a hologram of MODEL for a plate turning about its normal (a turntable or
    wall spinner) under a light on the axis, then verify it over the turn.

    One model: one closed groove per stipple, the scene turning rigidly with the
    plate through 360 degrees. Several models (or --turns N): the view circles the
    scene N times per plate turn, each model on its own circuit (720 degrees for
    two), with stipples sliding over the turning scene on open grooves."""
    from specholo.jobs.spin.job import SpinJob

    _run(SpinJob(), list(model), {
        "size": size, "center_z": center_z, "turns": turns, "stipples": stipples, "seed": seed,
        "view_distance": view_distance, "view_elevation": view_elevation, "ipd": ipd,
        "light_height": light_height, "walls": walls, "occlusion": not no_occlusion,
        "tool_radius": tool_radius, "depth": depth, "plate_width": plate_width,
        "plate_height": plate_height, "fit": fit, "stock_thickness": stock_thickness,
        "dialect": dialect, "units": units, **pose}, out,
        WriteOptions(step_deg=step, frames=frames))


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
@click.option("--light-sweep", "--light-range", "light_sweep", type=float, default=5.0,
              show_default=True, help="The sun moves this far either way, degrees "
              "(--light-range: its older name).")
@click.option("--shape", type=click.Choice(["scoop", "flat"]), default="scoop",
              show_default=True, help="scoop: steady; flat: plain grooves, to compare.")
@click.option("--tool-radius", type=float, default=0.05, show_default=True,
              help="Ball radius, mm.")
@click.option("--depth", type=float, default=0.02, show_default=True, help="Cut depth, mm.")
@click.option("--step", type=float, default=1.0, show_default=True,
              help="Step between verified light elevations, degrees.")
@click.option("--stock-thickness", type=float, default=3.0, show_default=True,
              help="Thickness of the plate blank, mm: no cut may reach its back.")
@_program_options
@_plate_options
@_pose_options
def steady(model: Path, out: Path, size: float, center_z: float, stipples: int, seed: int,
           view_distance: float, ipd: float, light_elevation: float, light_sweep: float,
           shape: str, tool_radius: float, depth: float, step: float, stock_thickness: float,
           dialect: str, units: str, plate_width: float | None, plate_height: float | None,
           fit: bool, **pose: Any) -> None:
    """Design a hologram of MODEL for a viewer standing still whose image stays put
    while the sun moves a little in elevation: for each stipple and eye, a scoop
    whose glint does not move with the light. Then verify it over the range."""
    from specholo.jobs.steady.job import SteadyJob

    _run(SteadyJob(), [model], {
        "size": size, "center_z": center_z, "stipples": stipples, "seed": seed,
        "view_distance": view_distance, "ipd": ipd, "light_elevation": light_elevation,
        "light_sweep": light_sweep, "shape": shape, "tool_radius": tool_radius,
        "depth": depth, "plate_width": plate_width, "plate_height": plate_height, "fit": fit,
        "stock_thickness": stock_thickness, "dialect": dialect, "units": units, **pose}, out,
        WriteOptions(step_deg=step))


#: ``specholo design``'s options a coupon takes as they are: the long job's
#: light, views, tool, program and machine.
_COUPON_DESIGN = ("light-elevation", "light-distance", "view-distance", "view-range",
                  "eye-height", "ipd", "band", "placement", "tool", "tool-radius",
                  "tool-angle", "tip-flat", "dialect", "units", "stock-thickness", "feed",
                  "plunge", "safe-z", "hop", "hop-max", "spindle", "machine")


def _coupon_options(fn: Any) -> Any:
    for name, kind, text in reversed([r for r in _DESIGN_OPTIONS if r[0] in _COUPON_DESIGN]):
        fn = click.option(f"--{name}", type=kind, default=None, help=text)(fn)
    return fn


@cli.command()
@click.option("--out", type=_Folder(path_type=Path), required=True,
              help="Output folder (written atomically).")
@click.option("--holder", type=click.Choice(["rigid", "spring"]), default=None,
              help="How the tip is held, as for design: spring rungs ladder the preload, "
                   "rigid rungs the depth [spring for drag and scriber, rigid for ball and "
                   "vbit].")
@click.option("--depths", default=None,
              help="Rigid holder: every rung's depth, mm, comma-separated [--rungs of them "
                   "--step apart about --depth].")
@click.option("--preloads", default=None,
              help="Spring holder: every rung's preload, mm, comma-separated [--rungs of "
                   "them --step apart about --preload].")
@click.option("--rungs", type=int, default=None, help="Rungs on the card, 2 to 9 [5].")
@click.option("--step", type=float, default=None,
              help="Between two rungs' settings, mm [0.002 of depth, 0.1 of preload].")
@click.option("--depth", type=float, default=None,
              help="Rigid: the ladder's middle depth; spring: the depth the grooves are "
                   "expected to have, mm [what design chooses for these views].")
@click.option("--preload", type=float, default=None,
              help="Spring holder: the ladder's middle preload, mm [0.3].")
@click.option("--stipples", type=int, default=None,
              help="Stipples a rung, 3 to 5, each its own window of the view range [5].")
@click.option("--window", type=float, default=None,
              help="Each stipple's window of eye azimuths, degrees [10].")
@click.option("--behind", type=float, default=None,
              help="How far the target points lie behind the card, mm [10].")
@_coupon_options
def coupon(out: Path, **options: Any) -> None:
    """Design a test coupon: a card of at most 60 x 40 mm cut in at most 15 minutes,
    rungs side by side at a ladder of depths (rigid holder) or preloads (spring
    holder), each a few stipples of a simple target needing no model; its sheet
    (sheet.pdf) says from where each glint must show and where, so the setting
    for the long job can be chosen before it is cut."""
    from specholo.jobs.flat.coupon_job import CouponJob

    values = {k: v for k, v in options.items() if v is not None}
    _run(CouponJob(), [], values, out, WriteOptions(command=_command_line()))


def _run(job: Any, inputs: list[Path], values: dict[str, Any], out: Path,
         options: WriteOptions) -> None:
    """Run a job with a status line, then print what it says."""
    from specholo.folders import check_out
    from specholo.jobs.base import run

    check_out(out, inputs)  # before any input is read (a composition's TOML)
    with _status("starting...") as status:
        summary = run(job, inputs, values, out, options, status.update)
    if summary.table is not None:
        _print_verification(summary)
        summary = type(summary)([], summary.warnings)
    _print_summary(summary)

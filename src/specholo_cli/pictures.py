"""The picture commands: ``render``, ``animate``, ``stereo``, ``report``, ``view``."""

from __future__ import annotations

import math
from pathlib import Path

import click

from specholo.errors import SpecholoError
from specholo_cli.app import (
    _SIZE_HELP,
    MAX_FRAMES,
    _check_folder,
    _design_folder,
    _distance,
    _finite_option,
    _fov,
    _look_options,
    _png_out,
    _stderr_console,
    cli,
)


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--azimuth", type=float, default=0.0, show_default=True,
              help="Camera azimuth, degrees right of straight-on.")
@click.option("--elevation", type=float, default=0.0, show_default=True,
              help="Camera elevation above the eyes' plane, degrees.")
@click.option("--width", type=int, default=1024, help=_SIZE_HELP.format("width", 1024))
@click.option("--height", type=int, default=1024, help=_SIZE_HELP.format("height", 1024))
@click.option("--distance", type=float, default=None,
              help="Camera distance, mm [the design's eyes' distance].")
@click.option("--fov", type=float, default=None,
              help="Vertical field of view, degrees [frames the plate].")
@_look_options
@click.option("--out", "-o", type=click.Path(path_type=Path), default=None,
              help="PNG file [FOLDER/render.png].")
def render(folder: Path, azimuth: float, elevation: float, width: int, height: int,
           distance: float | None, fov: float | None, roughness: float, grooves: bool,
           ghost: bool, out: Path | None) -> None:
    """Render the lit plate of the design in FOLDER as a camera sees it (glints only)."""
    from specholo.preview.render import design_camera, render_still, save_png
    from specholo.ridged import is_ridged_folder

    out = _png_out(out, folder, "render.png", "render")
    if is_ridged_folder(folder):
        if grooves:
            raise SpecholoError("a ridged plate has no grooves to draw: leave out --grooves")
        _render_ridged(folder, azimuth, elevation, width, height, distance, fov, roughness,
                       ghost, out)
        return
    loaded = _design_folder(folder, "render")
    setup = loaded.config.setup()
    camera = design_camera(
        setup, loaded.grooves, math.radians(_finite_option("azimuth", azimuth)),
        math.radians(_finite_option("elevation", elevation)),
        None if distance is None else _distance(distance), _fov(fov),
        width, height, plate=loaded.plate)
    model = (loaded.mesh if loaded.mesh is not None else loaded.points) if ghost else None
    image = render_still(loaded.grooves, setup, camera,
                         math.radians(_finite_option("roughness", roughness)),
                         grooves_overlay=grooves, ghost=model, plate=loaded.plate)
    save_png(image, out)
    click.echo(f"{width}x{height} render at azimuth {azimuth:+g} -> {out}")


def _render_ridged(folder: Path, azimuth: float, elevation: float, width: int, height: int,
                   distance: float | None, fov: float | None, roughness: float, ghost: bool,
                   out: Path) -> None:
    """The render command for a ridged plate: the glints on its height field."""
    from specholo.preview.render import field_plate, plate_camera, render_field_still, save_png
    from specholo.ridged import load_ridged_design

    loaded = load_ridged_design(folder)
    setup = loaded.config.setup()
    camera = plate_camera(
        setup, field_plate(loaded.heights), math.radians(_finite_option("azimuth", azimuth)),
        math.radians(_finite_option("elevation", elevation)),
        None if distance is None else _distance(distance), _fov(fov), width, height)
    model = (loaded.mesh if loaded.mesh is not None else loaded.points) if ghost else None
    image = render_field_still(loaded.heights, setup, camera,
                               math.radians(_finite_option("roughness", roughness)), ghost=model)
    save_png(image, out)
    click.echo(f"{width}x{height} render of the ridged plate at azimuth {azimuth:+g}, "
               f"elevation {elevation:+g} -> {out}")


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--kind", type=click.Choice(["turntable", "light"]), default="turntable",
              show_default=True,
              help="Camera walking the viewing arc, or the light's elevation moving.")
@click.option("--frames", type=int, default=90, show_default=True, help="Number of frames.")
@click.option("--width", type=int, default=512, help=_SIZE_HELP.format("width", 512))
@click.option("--height", type=int, default=512, help=_SIZE_HELP.format("height", 512))
@click.option("--fps", type=float, default=30.0, show_default=True, help="Frames per second.")
@click.option("--light-span", type=float, default=10.0, show_default=True,
              help="--kind light: the light moves +- this many degrees about the design's.")
@click.option("--azimuth", type=float, default=0.0, show_default=True,
              help="--kind light: camera azimuth, degrees.")
@_look_options
@click.option("--out", "-o", type=click.Path(path_type=Path), default=None,
              help="GIF or MP4 file, by suffix [FOLDER/turntable.gif or FOLDER/light.gif].")
def animate(folder: Path, kind: str, frames: int, width: int, height: int, fps: float,
            light_span: float, azimuth: float, roughness: float, grooves: bool, ghost: bool,
            out: Path | None) -> None:
    """Animate the design in FOLDER: a walk along the viewing arc, or a moving light."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn

    from specholo.preview.motion import FORMATS, light_sweep, turntable, write_animation

    _check_folder(folder, "animate")
    out = folder / f"{kind}.gif" if out is None else out
    if out.suffix.lower() not in FORMATS:
        raise SpecholoError(f"animation file must end in .gif or .mp4, got {out.name!r}")
    if not out.parent.is_dir():
        raise SpecholoError(f"folder {out.parent} does not exist")
    if out.is_dir():  # found now, not once every frame is rendered
        raise SpecholoError(f"{out} is a folder: name a .gif or .mp4 file")
    if not 0 < frames <= MAX_FRAMES:
        raise SpecholoError(f"--frames must be in [1, {MAX_FRAMES}], got {frames}")
    if not (math.isfinite(fps) and 0.01 <= fps <= 240):
        raise SpecholoError(f"--fps must be in [0.01, 240], got {fps:g}")
    loaded = _design_folder(folder, "animate")
    rough = math.radians(_finite_option("roughness", roughness))
    console = _stderr_console()
    # Off a terminal the bar would only leave an empty line on stderr.
    with Progress("[progress.description]{task.description}", BarColumn(),
                  MofNCompleteColumn(), TimeRemainingColumn(),
                  console=console, transient=True, disable=not console.is_terminal) as bar:
        task = bar.add_task(f"rendering {kind}", total=frames)

        def advance(done: int, total: int) -> None:
            bar.update(task, completed=done)

        if kind == "turntable":
            images = turntable(loaded, frames, (width, height), rough, grooves, ghost,
                               progress=advance)
        else:
            images = light_sweep(loaded, frames, (width, height),
                                 math.radians(_finite_option("light-span", light_span)),
                                 math.radians(_finite_option("azimuth", azimuth)), rough,
                                 grooves, ghost, progress=advance)
        bar.update(task, description="encoding")
        write_animation(images, out, fps)
    click.echo(f"{frames} frames {width}x{height} at {fps:g} fps -> {out}")


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--azimuth", type=float, default=0.0, show_default=True,
              help="Head azimuth on the viewing arc, degrees.")
@click.option("--mode", type=click.Choice(["parallel", "cross", "anaglyph"]),
              default="anaglyph", show_default=True,
              help="Side by side for parallel or cross-eyed viewing, or red-cyan anaglyph.")
@click.option("--width", type=int, default=768, help=_SIZE_HELP.format("width per eye", 768))
@click.option("--height", type=int, default=768, help=_SIZE_HELP.format("height", 768))
@click.option("--fov", type=float, default=None,
              help="Vertical field of view, degrees [frames the plate].")
@click.option("--roughness", type=float, default=1.0, show_default=True,
              help="Width of the plate's specular lobe, degrees.")
@click.option("--out", "-o", type=click.Path(path_type=Path), default=None,
              help="PNG file [FOLDER/stereo.png].")
def stereo(folder: Path, azimuth: float, mode: str, width: int, height: int,
           fov: float | None, roughness: float, out: Path | None) -> None:
    """Render what both eyes of a viewer see of the design in FOLDER, as one picture."""
    from specholo.preview.render import save_png
    from specholo.preview.stereo import anaglyph, head_camera, side_by_side, stereo_pair

    out = _png_out(out, folder, "stereo.png", "stereo")
    loaded = _design_folder(folder, "stereo")
    setup = loaded.config.setup()
    head = head_camera(setup, loaded.grooves, math.radians(_finite_option("azimuth", azimuth)),
                       width, height, _fov(fov), plate=loaded.plate)
    left, right = stereo_pair(loaded.grooves, setup, head,
                              roughness=math.radians(_finite_option("roughness", roughness)),
                              plate=loaded.plate)
    image = anaglyph(left, right) if mode == "anaglyph" else side_by_side(
        left, right, mode, gap=max(2, width // 32))
    save_png(image, out)
    click.echo(f"{mode} stereo at azimuth {azimuth:+g}, IPD {setup.viewer.ipd:g} mm -> {out}")

@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
def report(folder: Path) -> None:
    """Write FOLDER/report.html: settings, fabrication figures, accuracy and pictures.

    Uses FOLDER/verify.json when present; run `specholo verify` first to include it.
    """
    from specholo.pipeline import load_design
    from specholo.preview.report import write_report
    from specholo.readback import read_json

    if Path(folder).is_dir():
        _check_folder(folder, "report")  # another kind of design gets its own message
    load_design(folder)  # a clear error if this is not a design folder
    verify_file = Path(folder) / "verify.json"
    verify = read_json(verify_file) if verify_file.exists() else None
    click.echo(f"report -> {write_report(folder, verify)}")


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--out", "-o", type=click.Path(path_type=Path), default=None,
              help="HTML file [FOLDER/view.html].")
@click.option("--width", type=int, default=None,
              help="Fixed canvas width in pixels [fills the window].")
@click.option("--height", type=int, default=None,
              help="Fixed canvas height in pixels [fills the window].")
@click.option("--step", type=float, default=2.0, show_default=True,
              help="Ridged design: spacing of the views whose glints the page holds, degrees.")
def view(folder: Path, out: Path | None, width: int | None, height: int | None,
         step: float) -> None:
    """Write an interactive page of the design in FOLDER: drag to move the eye (WebGL2).

    One self-contained HTML file: the glints are recomputed in the browser for
    every viewpoint with the same physics as `verify`. Shift+drag moves the light.
    For a ridged design the glints of a grid of views (every --step degrees) are
    found beforehand with the physics of `verify`, and the page shows the view
    nearest the pointer's.
    """
    from specholo.jobs.page import write_page

    _check_folder(folder, "view")
    if (width is None) != (height is None):
        raise SpecholoError("give both --width and --height, or neither")
    size = None if width is None or height is None else (width, height)
    with _stderr_console().status("writing the page...") as status:

        def progress(done: int, total: int) -> None:
            status.update(f"finding the glints of view {done} of {total}...")

        path = write_page(folder, out, size, step, progress)
    click.echo(f"interactive page ({path.stat().st_size / 1e6:.1f} MB) -> {path}")

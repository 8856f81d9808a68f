"""The picture commands: ``render``, ``animate``, ``stereo``, ``report``, ``view``.

Each serves every kind of design through its ``PictureSource``
(:mod:`specholo.preview.source`): one path, whatever the folder holds.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import click

from specholo.errors import SpecholoError
from specholo_cli.app import (
    _SIZE_HELP,
    LIGHT_SIZE_HELP,
    MAX_FRAMES,
    ROUGHNESS_HELP,
    _check_folder,
    _distance,
    _finite_option,
    _fov,
    _lighting,
    _look_options,
    _picture_source,
    _png_out,
    _stderr_console,
    cli,
)

#: ``--at``'s help, the same for every picture of one state.
_AT_HELP = ("The state of the design's motion, degrees: a turning plate's angle, a steady "
            "image's or a moving-light composition's light elevation [the design's own]. A "
            "design that moves only with the eye (a flat or ridged plate, a composition the "
            "viewer walks past) takes --azimuth instead.")


def _at(at: float | None) -> float | None:
    """``--at`` in radians (None: not given)."""
    return None if at is None else math.radians(_finite_option("at", at))


def _state_words(source: Any, state: float | None) -> str:
    """', plate angle 30 deg' for a picture at a state of a motion of its own."""
    if source.motion.moves_eye or state is None:
        return ""
    return f", {source.motion.name} {math.degrees(state):g} deg"


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--azimuth", type=float, default=None,
              help="Camera azimuth, degrees right of straight-on [0; for a design seen from "
                   "still eyes (spin, steady, a moving-light composition) its left eye's].")
@click.option("--elevation", type=float, default=0.0, show_default=True,
              help="Camera elevation above the eyes' plane, degrees.")
@click.option("--at", "at", type=float, default=None, help=_AT_HELP)
@click.option("--width", type=int, default=1024, help=_SIZE_HELP.format("width", 1024))
@click.option("--height", type=int, default=1024, help=_SIZE_HELP.format("height", 1024))
@click.option("--distance", type=float, default=None,
              help="Camera distance, mm [the design's eyes' distance].")
@click.option("--fov", type=float, default=None,
              help="Vertical field of view, degrees [frames the plate].")
@_look_options
@click.option("--out", "-o", type=click.Path(path_type=Path), default=None,
              help="PNG file [FOLDER/render.png].")
def render(folder: Path, azimuth: float | None, elevation: float, at: float | None,
           width: int, height: int, distance: float | None, fov: float | None,
           roughness: str | None, light_size: float | None, grooves: bool, ghost: bool,
           out: Path | None) -> None:
    """Render the lit design in FOLDER as a camera sees it (glints only), any kind."""
    from specholo.preview.render import save_png
    from specholo.preview.source import camera, state_at, still

    out = _png_out(out, folder, "render.png", "render")
    source, lobe = _lighting(_picture_source(folder, "render"), roughness, light_size)
    if grooves and not source.grooves:  # said before anything is drawn
        raise SpecholoError(f"{source.title} has no grooves to draw: leave out --grooves")
    az = None if azimuth is None else math.radians(_finite_option("azimuth", azimuth))
    cam = camera(source, az, math.radians(_finite_option("elevation", elevation)),
                 None if distance is None else _distance(distance), _fov(fov), width, height)
    state = state_at(source, _at(at), cam.azimuth)
    image = still(source, cam, state, lobe, grooves, ghost)
    save_png(image, out)
    where = f"azimuth {math.degrees(cam.azimuth):+g}" + (
        f", elevation {elevation:+g}" if elevation else "")
    click.echo(f"{width}x{height} render at {where}{_state_words(source, state)} -> {out}")


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--kind", type=click.Choice(["turntable", "turn", "light"]), default=None,
              help="What moves: turntable, the camera walking the viewing arc; turn, a "
                   "turning plate's angle over a whole turn; light, the light's elevation "
                   "(over a steady image's or a composition's range, else +-"
                   "--light-span about the design's) [the design's own motion: turn for "
                   "spin, light for steady and moving-light compositions, else turntable].")
@click.option("--frames", type=int, default=90, show_default=True, help="Number of frames.")
@click.option("--width", type=int, default=512, help=_SIZE_HELP.format("width", 512))
@click.option("--height", type=int, default=512, help=_SIZE_HELP.format("height", 512))
@click.option("--fps", type=float, default=30.0, show_default=True, help="Frames per second.")
@click.option("--light-span", type=float, default=10.0, show_default=True,
              help="--kind light on a design whose light has no motion of its own: the light "
                   "moves +- this many degrees about the design's.")
@click.option("--azimuth", type=float, default=None,
              help="A still camera's azimuth (--kind turn or light), degrees [0; the left "
                   "eye's for a design seen from still eyes].")
@click.option("--at", "at", type=float, default=None,
              help="--kind turntable: the state the design's motion is held at while the "
                   "camera walks, degrees [the design's own].")
@_look_options
@click.option("--out", "-o", type=click.Path(path_type=Path), default=None,
              help="GIF or MP4 file, by suffix [FOLDER/<kind>.gif].")
def animate(folder: Path, kind: str | None, frames: int, width: int, height: int, fps: float,
            light_span: float, azimuth: float | None, at: float | None, roughness: str | None,
            light_size: float | None, grooves: bool, ghost: bool, out: Path | None) -> None:
    """Animate the design in FOLDER, any kind: along its motion (a walk past, a
    turning plate, a moving light), or along another with --kind."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn

    from specholo.preview.motion import write_animation
    from specholo.preview.source import along_options
    from specholo.preview.source import frames as draw_frames

    _check_folder(folder, "animate")
    if out is not None:
        _check_animation_out(out)
    if not 0 < frames <= MAX_FRAMES:
        raise SpecholoError(f"--frames must be in [1, {MAX_FRAMES}], got {frames}")
    if not (math.isfinite(fps) and 0.01 <= fps <= 240):
        raise SpecholoError(f"--fps must be in [0.01, 240], got {fps:g}")
    source, rough = _lighting(_picture_source(folder, "animate"), roughness, light_size)
    kind = source.motion.key if kind is None else kind
    allowed = along_options(source)
    if kind not in allowed:
        raise SpecholoError(f"{source.title} does not move along --kind {kind}: its "
                            f"animations are --kind {', '.join(allowed)}")
    if grooves and not source.grooves:
        raise SpecholoError(f"{source.title} has no grooves to draw: leave out --grooves")
    if at is not None and kind != "turntable":
        raise SpecholoError("--at holds the design's motion while the camera walks: it is "
                            "for --kind turntable")
    if out is None:
        out = folder / f"{kind}.gif"
        _check_animation_out(out)
    az = None if azimuth is None else math.radians(_finite_option("azimuth", azimuth))
    console = _stderr_console()
    # Off a terminal the bar would only leave an empty line on stderr.
    with Progress("[progress.description]{task.description}", BarColumn(),
                  MofNCompleteColumn(), TimeRemainingColumn(),
                  console=console, transient=True, disable=not console.is_terminal) as bar:
        task = bar.add_task(f"rendering {kind}", total=frames)

        def advance(done: int, total: int) -> None:
            bar.update(task, completed=done)

        images = draw_frames(source, frames, (width, height), kind, rough, grooves, ghost,
                             azimuth=az, at=_at(at),
                             span=math.radians(_finite_option("light-span", light_span)),
                             progress=advance)
        bar.update(task, description="encoding")
        write_animation(images, out, fps)
    click.echo(f"{frames} frames {width}x{height} at {fps:g} fps -> {out}")


def _check_animation_out(out: Path) -> None:
    """Refuse an animation file that cannot be written, before any frame is drawn."""
    from specholo.preview.motion import FORMATS

    if out.suffix.lower() not in FORMATS:
        raise SpecholoError(f"animation file must end in .gif or .mp4, got {out.name!r}")
    if not out.parent.is_dir():
        raise SpecholoError(f"folder {out.parent} does not exist")
    if out.is_dir():  # found now, not once every frame is rendered
        raise SpecholoError(f"{out} is a folder: name a .gif or .mp4 file")


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--azimuth", type=float, default=0.0, show_default=True,
              help="Head azimuth on the viewing arc, degrees (0: a design seen from still "
                   "eyes is seen from its own).")
@click.option("--at", "at", type=float, default=None, help=_AT_HELP)
@click.option("--mode", type=click.Choice(["parallel", "cross", "anaglyph"]),
              default="anaglyph", show_default=True,
              help="Side by side for parallel or cross-eyed viewing, or red-cyan anaglyph.")
@click.option("--width", type=int, default=768, help=_SIZE_HELP.format("width per eye", 768))
@click.option("--height", type=int, default=768, help=_SIZE_HELP.format("height", 768))
@click.option("--fov", type=float, default=None,
              help="Vertical field of view, degrees [frames the plate].")
@click.option("--roughness", default=None, help=ROUGHNESS_HELP)
@click.option("--light-size", type=float, default=None, help=LIGHT_SIZE_HELP)
@click.option("--out", "-o", type=click.Path(path_type=Path), default=None,
              help="PNG file [FOLDER/stereo.png].")
def stereo(folder: Path, azimuth: float, at: float | None, mode: str, width: int, height: int,
           fov: float | None, roughness: str | None, light_size: float | None,
           out: Path | None) -> None:
    """Render what both eyes of a viewer see of the design in FOLDER (any kind), as one
    picture."""
    from specholo.preview.render import save_png
    from specholo.preview.source import head, state_at, stereo_stills
    from specholo.preview.stereo import anaglyph, side_by_side

    out = _png_out(out, folder, "stereo.png", "stereo")
    source, lobe = _lighting(_picture_source(folder, "stereo"), roughness, light_size)
    az = math.radians(_finite_option("azimuth", azimuth))
    state = state_at(source, _at(at), az)  # refuses --at where the motion is the eye
    head_cam = head(source, az, width, height, _fov(fov))
    left, right = stereo_stills(source, head_cam, _at(at), roughness=lobe)
    image = anaglyph(left, right) if mode == "anaglyph" else side_by_side(
        left, right, mode, gap=max(2, width // 32))
    save_png(image, out)
    click.echo(f"{mode} stereo at azimuth {azimuth:+g}{_state_words(source, state)}, IPD "
               f"{source.setup.viewer.ipd:g} mm -> {out}")


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
def report(folder: Path) -> None:
    """Write FOLDER/report.html (any kind): settings, fabrication figures, accuracy and
    pictures.

    Uses FOLDER/verify.json when present; run `specholo verify` first to include it.
    """
    from specholo.preview.report import write_report
    from specholo.readback import read_json

    source = _picture_source(folder, "report")  # a clear error if this is not a design
    verify_file = Path(folder) / "verify.json"
    verify = read_json(verify_file) if verify_file.exists() else None
    click.echo(f"report -> {write_report(folder, verify, source)}")


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--out", "-o", type=click.Path(path_type=Path), default=None,
              help="HTML file [FOLDER/view.html].")
@click.option("--width", type=int, default=None,
              help="Fixed canvas width in pixels [fills the window].")
@click.option("--height", type=int, default=None,
              help="Fixed canvas height in pixels [fills the window].")
@click.option("--step", type=float, default=2.0, show_default=True,
              help="Spacing of the views whose glints the page holds, degrees: along the "
                   "design's motion, or over its azimuth (and elevation) range. A flat "
                   "plate's page recomputes its glints live and takes none.")
def view(folder: Path, out: Path | None, width: int | None, height: int | None,
         step: float) -> None:
    """Write an interactive page of the design in FOLDER (any kind): drag to move the eye.

    One self-contained HTML file. A flat plate's glints are recomputed in the
    browser (WebGL2) for every viewpoint with the same physics as `verify`;
    shift+drag moves the light. Every other kind's glints are found beforehand,
    with its own physics, for views every --step degrees (over the eye's
    azimuth and elevation ranges, or along its motion: a turning plate's
    angle, a moving light), and the page shows the view nearest the pointer's;
    along a motion, drag moves the motion and shift+drag the eye.
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

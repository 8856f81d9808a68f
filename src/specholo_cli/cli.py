"""``specholo`` commands. Options are parsed here; the work happens in the library."""

from __future__ import annotations

import contextlib
import math
import os
import signal
import sys
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import click

from specholo import __version__
from specholo.errors import SpecholoError
from specholo_cli import INTERRUPTED, early_sigint, exit_interrupted

_DESIGN_OPTIONS: list[tuple[str, Any, str]] = [
    ("size", float, "Largest side of the model's bounding box, mm [60]."),
    ("center-z", float, "Depth of the model's box centre, mm; negative is behind the plate [-40]."),
    ("light-elevation", float, "Light elevation a in degrees: direction (0, cos a, sin a) [45]; "
     "behind the plate, in (-180, 0), for --optic refract [-90: straight behind]."),
    ("light-distance", float, "Point light this far from the plate centre, mm [sun]."),
    ("view-distance", float, "Radius of the viewing arc, mm [600]."),
    ("view-range", float, "Eyes' azimuth within +- this many degrees [45]."),
    ("eye-height", float, "Eye height above the plate centre, mm [0]."),
    ("ipd", float, "Interocular distance, mm [64]."),
    ("stipples", int, "Number of stipples [2000]."),
    ("spacing", float, "Minimum stipple spacing in mm (instead of --stipples)."),
    ("visibility", float, "Design with the most stipples that show in both eyes at every "
     "view on the plate as cut at least this share of the time (e.g. 0.8): several designs "
     "are tried, from --stipples [off]."),
    ("seed", int, "Random seed for stippling [0]."),
    ("band", float, "Striped design: half-height of the band, bounds vertical error, mm [0.2]."),
    ("placement", click.Choice(["auto", "avoid", "phase"]),
     "Striped design: avoid places each stipple's stripes in turn out of the grooves placed "
     "before (jumping between the band's paths where a crossing would cut glints away); "
     "phase designs each stipple alone, one stripe family; auto is avoid where its plan fits "
     "in memory and time, else phase [auto]."),
    ("tool", click.Choice(["ball", "vbit", "drag", "scriber", "laser"]),
     "Cutting tool: ball-end mill, V-bit, diamond drag tip, hand scriber or laser [drag]."),
    ("tool-radius", float, "Ball or tip radius, mm [ball 0.25, drag 0.05, scriber 0.05]."),
    ("tool-angle", float, "Included angle of a V-bit or tip cone, degrees "
     "[vbit 60, drag 90, scriber 60]."),
    ("tip-flat", float, "Width of a V-bit's tip flat, mm [0]."),
    ("spot", float, "Laser spot diameter (1/e^2), mm [0.1]."),
    ("depth", float, "Groove depth, mm [ball 0.08, vbit 0.05, laser 0.04, else 0.012]."),
    ("dialect", click.Choice(["grbl", "linuxcnc", "marlin"]),
     "G-code for GRBL, LinuxCNC, or Marlin driving a laser [grbl]."),
    ("units", click.Choice(["mm", "inch"]), "G-code units [mm]."),
    ("plate-width", float, "Plate width, mm [the grooves' extent plus 5 mm each side]."),
    ("plate-height", float, "Plate height, mm [the grooves' extent plus 5 mm each side]."),
    ("stock-thickness", float, "Plate thickness, mm [3]."),
    ("feed", float, "Cutting feed, mm/min [300]."),
    ("plunge", float, "Plunge feed, mm/min [100]."),
    ("safe-z", float, "Rapid (safe) height, mm [1]."),
    ("hop", float, "Hop height: between grooves at most --hop-max apart the tool lifts only "
     "this far above the surface and moves over at the cutting feed, mm [0.03]."),
    ("hop-max", float, "Longest hop, mm; 0 retracts to --safe-z between all grooves [3]."),
    ("spindle", float, "Spindle speed, rpm; 0 for none [12000 for ball and vbit, else 0]."),
    ("elevation-range", float, "Ridged design: heads' elevation within +- this many degrees "
     "[15]."),
    ("shell", float, "Ridged design: half-thickness Delta of the shell; the facets lie within "
     "2 Delta of the surface, mm [0.1]."),
    ("raster", float, "Ridged design: height-field sample spacing, mm [0.02]."),
    ("optic", click.Choice(["reflect", "refract"]),
     "Ridged design: a mirror lit from the front [reflect], or a clear plate "
     "--stock-thickness thick lit from behind, its front face ridged (refract)."),
    ("refraction", click.Choice(["exact", "approx", "single"]),
     "--optic refract: the front optic: exact (through the planar back face) [exact], "
     "approx (the paper's centre of divergence) or single (the back face ignored)."),
    ("index", float, "--optic refract: the plate's refractive index [1.49, acrylic]."),
]


#: Largest config file read, bytes (a config is a few lines; /dev/zero never ends).
MAX_CONFIG_BYTES = 1 << 20


def _read_config(path: Path | None) -> dict[str, Any]:
    from specholo.readback import read_bytes

    if path is None:
        return {}
    # A regular file only: a FIFO would wait for a writer, /dev/zero never end.
    raw = read_bytes(path, MAX_CONFIG_BYTES, "config file")
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SpecholoError(f"config file {path} is not valid TOML: {exc}") from exc
    except RecursionError as exc:
        raise SpecholoError(f"config file {path} is not valid TOML: nested too deeply") from exc
    return data


def _command_line() -> list[str]:
    """The command line this run was given (recorded in the design's run.json)."""
    obj = click.get_current_context().find_root().obj
    argv = obj.get("argv") if isinstance(obj, dict) else None
    return [str(a) for a in (argv if argv is not None else sys.argv)]


class _Folder(click.Path):
    """An output folder's path: an empty one is refused, where pathlib would
    read it as the current folder."""

    def convert(self, value: Any, param: Any, ctx: Any) -> Any:
        if isinstance(value, str | bytes) and not value:
            raise SpecholoError("--out is empty: name a folder (. for the current one)")
        return super().convert(value, param, ctx)


def _check_out(out: Path, inputs: Sequence[Path | None] = ()) -> None:
    """Refuse an output folder that cannot be made or is not specholo's to
    replace, or that holds an input where the job writes, before the (long)
    design runs."""
    from specholo.folders import check_out

    check_out(out, inputs)
    try:
        above = out.resolve().parent
        while not above.exists() and above != above.parent:
            above = above.parent
        if not above.is_dir():
            raise SpecholoError(f"cannot create output folder {out}: {above} is not a folder")
        if not os.access(above, os.W_OK | os.X_OK):
            raise SpecholoError(f"cannot create output folder {out}: {above} is not writable")
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        if isinstance(exc, SpecholoError):
            raise
        raise SpecholoError(f"bad output folder {str(out)!r}: {exc}") from exc


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="specholo")
def cli() -> None:
    """Exact specular holograms: design grooves from a 3D model and verify them."""


def _design_options(fn: Any) -> Any:
    for name, kind, text in reversed(_DESIGN_OPTIONS):
        fn = click.option(f"--{name}", type=kind, default=None, help=text)(fn)
    return fn


@cli.command()
@click.argument("model", type=click.Path(path_type=Path))
@click.option("--out", "-o", type=_Folder(path_type=Path), required=True,
              help="Output folder.")
@click.option("--method", type=click.Choice(["striped", "hyperbola", "arc", "ridged"]),
              default=None,
              help="Design: exact striped [default], the paper's closed-form hyperbola, "
                   "the classic circular arc, or ridged (full parallax, a milled height "
                   "field; with a ball-end mill, --tool-radius [0.05]).")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="TOML file with any of these options (same names).")
@click.option("--strict", is_flag=True,
              help="Refuse a design whose tool cannot serve every view.")
@click.option("--no-order", is_flag=True,
              help="Keep the paths in design order (default: ordered to cut air travel).")
@click.option("--formats", default=None,
              help="Fabrication files, comma-separated: gcode, svg, dxf, pdf (the compass "
                   "pattern of an arc design) [gcode,svg]; for a ridged design png, tiff "
                   "(16-bit height maps), stl, gcode [all four].")
@_design_options
def design(model: Path, out: Path, method: str | None, config_path: Path | None,
           strict: bool, no_order: bool, formats: str | None, **options: Any) -> None:
    """Design a hologram of MODEL (OBJ, STL, PLY, OFF, GLB; PLY/XYZ/CSV point clouds)."""
    from rich.console import Console

    from specholo.pipeline import (
        DEFAULT_FORMATS,
        DesignConfig,
        check_formats,
        write_design,
    )
    from specholo.pipeline import design as run_design
    from specholo.ridged import DEFAULT_RIDGED_FORMATS

    _check_out(out, [model, config_path])
    values = _read_config(config_path)
    if method is not None:
        options["method"] = method
    if strict:
        options["strict"] = True
    if no_order:
        options["order"] = False
    values.update({k: v for k, v in options.items() if v is not None})
    config = DesignConfig.from_dict(values)
    ridged = config.method == "ridged"
    wanted: tuple[str, ...]
    if formats is None:
        wanted = DEFAULT_RIDGED_FORMATS if ridged else DEFAULT_FORMATS
    else:
        wanted = tuple(f.strip().lower() for f in formats.split(",") if f.strip())
    check_formats(wanted, config.method)
    if ridged:
        _design_ridged(model, out, config, wanted, [model, config_path])
        return
    console = Console(stderr=True)
    if config.visibility is not None:
        from specholo.density import design_for_visibility

        def tried(n: int, v: float) -> None:
            console.print(f"{n} stipples: as cut, {v:.0%} in both eyes at the lowest view")

        with console.status(f"finding the most stipples that keep {config.visibility:.0%} "
                            "as cut..."):
            d = design_for_visibility(model, config, tried)
    else:
        with console.status("designing..."):
            d = run_design(model, config)
    with console.status("writing..."):
        written = write_design(d, out, wanted, command=_command_line(),
                               inputs=[model, config_path])
    from specholo.jobs.flat import design_summary

    _print_summary(design_summary(d, written, out))


def _print_summary(summary: Any) -> None:
    """A design's lines on stdout and its warnings on stderr."""
    for line in summary.lines:
        click.echo(line)
    for line in summary.warnings:
        click.echo(f"warning: {line}", err=True)


def _design_ridged(model: Path, out: Path, config: Any, formats: tuple[str, ...],
                   inputs: Sequence[Path | None]) -> None:
    """The design command for a ridged (full-parallax) plate."""
    from rich.console import Console

    from specholo.ridged import design_ridged_model, write_ridged_design

    console = Console(stderr=True)
    with console.status("designing the ridged plate..."):
        d = design_ridged_model(model, config)
    with console.status("writing..."):
        written = write_ridged_design(d, out, formats, inputs)
    from specholo.jobs.ridged import design_summary

    _print_summary(design_summary(d, written, out))


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--step", type=float, default=5.0, show_default=True,
              help="Largest azimuth step between simulated eye pairs, degrees.")
@click.option("--from-gcode", is_flag=True,
              help="Verify the grooves parsed from hologram.gcode, the file that will be cut.")
@click.option("--cut", is_flag=True,
              help="Also verify the plate as hologram.gcode cuts it: each eye's glints that "
                   "no other groove's cut removes (writes verify_cut.json).")
@click.option("--cut-method", type=click.Choice(["survival", "field"]), default=None,
              help="How --cut finds what the cutting leaves: survival, exact from the "
                   "grooves [default], or field, a simulated height field of the plate "
                   "[the default with --resolution or --stl].")
@click.option("--resolution", type=float, default=None,
              help="Height-field cut: sample spacing, mm [0.02].")
@click.option("--stl", type=click.Path(path_type=Path), default=None,
              help="Height-field cut: write the cut plate as a watertight STL here.")
def verify(folder: Path, step: float, from_gcode: bool, cut: bool, cut_method: str | None,
           resolution: float | None, stl: Path | None) -> None:
    """Simulate stereo eye pairs along the arc and measure where each stipple appears."""
    from specholo.jobs import VerifyOptions, job_of, publish_verification
    from specholo.pipeline import cut_method as choose_cut_method

    if not (math.isfinite(step) and 0.01 <= step <= 5.0):
        raise SpecholoError(f"step must be in [0.01, 5] degrees, got {step}")
    if stl is not None and not cut:
        raise SpecholoError("--stl needs --cut")
    if cut_method is not None and not cut:
        raise SpecholoError("--cut-method needs --cut")
    if stl is not None and stl.suffix.lower() != ".stl":
        raise SpecholoError(f"--stl must name an .stl file, got {stl.name!r}")
    # Checked before the cut is simulated (minutes), not when the file is written.
    if stl is not None and not stl.parent.is_dir():
        raise SpecholoError(f"--stl {stl}: folder {stl.parent} does not exist")
    if stl is not None and stl.is_dir():
        raise SpecholoError(f"--stl {stl} is a folder: name an .stl file")
    if resolution is not None and not (math.isfinite(resolution) and 0.001 <= resolution <= 1.0):
        raise SpecholoError(f"resolution must be in [0.001, 1] mm, got {resolution}")
    options = VerifyOptions(step, from_gcode, cut, cut_method, resolution, stl)
    if cut:
        choose_cut_method(cut_method, resolution, stl)  # refused before the folder is read
    with _stderr_console().status("verifying...") as status:
        result = job_of(folder).verify(folder, options, status.update)
    _print_verification(result)
    # The verification's files appear together or not at all.
    publish_verification(folder, result)


def _print_verification(result: Any) -> None:
    """A verification's table (rich) and lines."""
    from rich.console import Console
    from rich.table import Table

    if result.table is not None:
        table = Table(title=result.table.title)
        for col in result.table.columns:
            table.add_column(col, justify="right")
        for row in result.table.rows:
            table.add_row(*row)
        Console().print(table)
    for line in result.lines:
        click.echo(line)


@cli.command()
@click.argument("gcode", type=click.Path(path_type=Path))
@click.option("--plate-width", type=float, required=True, help="Plate width, mm.")
@click.option("--plate-height", type=float, required=True, help="Plate height, mm.")
@click.option("--stock-thickness", type=float, default=3.0, show_default=True,
              help="Plate thickness, mm.")
@click.option("--max-depth", type=float, required=True,
              help="Deepest cut allowed below the surface, mm (any tool).")
@click.option("--safe-z", type=float, default=1.0, show_default=True,
              help="Lowest height for X/Y rapids, mm.")
@click.option("--feed", type=(float, float), default=(1.0, 5000.0), show_default=True,
              help="Lowest and highest feed allowed, mm/min.")
@click.option("--spindle", type=(float, float), default=(0.0, 30000.0), show_default=True,
              help="Lowest and highest spindle speed (or laser power) allowed.")
@click.option("--tool", type=click.Choice(["ball", "vbit", "drag", "scriber", "laser"]),
              default=None,
              help="The tool: a ball or V-bit spins to cut, a drag tip or scriber cuts with "
                   "the spindle off, a laser cuts where it is on and never goes below the "
                   "surface [ball].")
@click.option("--laser", is_flag=True, help="As --tool laser.")
@click.option("--no-spindle", is_flag=True, help="As --tool drag.")
@click.option("--hop-max", type=float, default=None,
              help="Longest feed move in X/Y between the surface and --safe-z (a hop between "
                   "grooves), mm; 0 allows none [not checked].")
@click.option("--hop", type=float, default=0.0, show_default=True,
              help="Lowest height of those moves above the surface, mm.")
def check(gcode: Path, plate_width: float, plate_height: float, stock_thickness: float,
          max_depth: float, safe_z: float, feed: tuple[float, float],
          spindle: tuple[float, float], tool: str | None, laser: bool,
          no_spindle: bool, hop_max: float | None, hop: float) -> None:
    """Check any G-code file (G20 programs are read in mm) against limits in mm.

    Every cut stays inside the plate (origin at its centre, Z = 0 on its surface),
    arcs over their whole sweep, and no deeper than --max-depth (or the stock)
    below the surface, whatever the tool; a laser never goes below the surface.
    Rapids move in X/Y only at --safe-z or above and never plunge below it (a
    laser's only with the beam off); with --hop-max, feed moves in X/Y above
    the surface and below --safe-z run no further than that, no lower than
    --hop and over the plate. Feed moves run within --feed, the spindle
    (laser power) within --spindle when on, and a ball or V-bit only cuts while
    it spins. Unknown words, moves from unknown positions, arcs off their circle
    and moves after the program's end are reported. Exits with status 1 if
    anything is wrong."""
    from specholo.fabrication.check import CUTTER_KINDS, Limits, Stock, check_limits

    aliases = {name for name, given in (("laser", laser), ("drag", no_spindle)) if given}
    if len(aliases) > 1 or (tool is not None and aliases
                            and {CUTTER_KINDS[tool]} != {CUTTER_KINDS[a] for a in aliases}):
        raise SpecholoError("give one tool: --tool, --laser (as --tool laser) or --no-spindle "
                            "(as --tool drag)")
    kind = CUTTER_KINDS[tool or (aliases.pop() if aliases else "ball")]
    for name, v in (("plate width", plate_width), ("plate height", plate_height),
                    ("stock thickness", stock_thickness)):
        if not (math.isfinite(v) and v > 0):
            raise SpecholoError(f"{name} must be a positive number of mm, got {v}")
    if not gcode.is_file():
        raise SpecholoError(f"G-code file {gcode} not found")
    limits = Limits(Stock.centred(plate_width, plate_height, stock_thickness), max_depth,
                    safe_z, feed, spindle, kind, hop_max=hop_max, hop=hop)
    report = check_limits(gcode, limits)
    click.echo(report.summary())
    if not report.ok:
        sys.exit(1)


def _check_folder(folder: Path, command: str) -> None:
    """Refuse a missing folder, and a kind of design ``command`` does not draw."""
    from specholo.jobs import job_of
    from specholo.jobs.base import refuse_picture

    if not folder.exists():
        raise SpecholoError(f"design folder {folder} does not exist")
    if not folder.is_dir():
        raise SpecholoError(f"{folder} is not a folder")
    refuse_picture(job_of(folder), folder, command)


def _design_folder(folder: Path, command: str) -> Any:
    from specholo.pipeline import load_design

    _check_folder(folder, command)
    return load_design(folder)


def _finite_option(name: str, value: float) -> float:
    if not math.isfinite(value):
        raise SpecholoError(f"--{name} must be a finite number, got {value}")
    return value


def _distance(distance: float) -> float:
    if not (math.isfinite(distance) and 1.0 <= distance <= 1e6):
        raise SpecholoError(f"--distance must be in [1, 1e6] mm, got {distance:g}")
    return distance


def _fov(fov: float | None) -> float | None:
    if fov is None:
        return None
    if not (math.isfinite(fov) and 0.1 <= fov <= 170):
        raise SpecholoError(f"--fov must be in [0.1, 170] degrees, got {fov:g}")
    return math.radians(fov)


def _png_out(out: Path | None, folder: Path, default: str, command: str) -> Path:
    _check_folder(folder, command)
    out = folder / default if out is None else out
    if out.suffix.lower() != ".png":
        raise SpecholoError(f"output must be a .png file, got {out.name!r}")
    if not out.parent.is_dir():
        raise SpecholoError(f"folder {out.parent} does not exist")
    if out.is_dir():  # found now, not once the picture is made
        raise SpecholoError(f"{out} is a folder: name a .png file")
    return out


_SIZE_HELP = "Image {} in pixels [{}]."


def _look_options(fn: Any) -> Any:
    """The options every picture shares: surface roughness and faint overlays."""
    fn = click.option("--ghost/--no-ghost", default=False, show_default=True,
                      help="Draw the model faintly where it is in space.")(fn)
    fn = click.option("--grooves/--no-grooves", default=False, show_default=True,
                      help="Draw the grooves faintly.")(fn)
    return click.option("--roughness", type=float, default=1.0, show_default=True,
                        help="Width of the plate's specular lobe, degrees: rougher, "
                             "bigger dimmer glints.")(fn)


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
        width, height)
    model = (loaded.mesh if loaded.mesh is not None else loaded.points) if ghost else None
    image = render_still(loaded.grooves, setup, camera,
                         math.radians(_finite_option("roughness", roughness)),
                         grooves_overlay=grooves, ghost=model)
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


#: Most frames of an animation (an hour at 30 fps); every frame is held in memory.
MAX_FRAMES = 108_000


def _stderr_console() -> Any:
    from rich.console import Console

    return Console(stderr=True)


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
                       width, height, _fov(fov))
    left, right = stereo_pair(loaded.grooves, setup, head,
                              roughness=math.radians(_finite_option("roughness", roughness)))
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


#: SIGINTs received by the running command (see :func:`main`).
_SIGINTS: list[int] = []
#: Whether a Ctrl-C may end the process at once (the ``specholo`` command).
_END_AT_ONCE = [False]


def _on_sigint(signum: int, frame: Any) -> None:
    """Ctrl-C: end at once where nothing needs cleaning up (a library that was
    importing an optional module cannot swallow it then), else unwind, so the
    scratch files go."""
    from specholo.fabrication.atomic import scratch_open

    _SIGINTS.append(signum)
    if _END_AT_ONCE[0] and not scratch_open():
        exit_interrupted()
    raise KeyboardInterrupt


def _interrupted(exc: BaseException) -> bool:
    """Whether an error stands for a Ctrl-C: compiled (numba) code that was
    running when it came returns with the KeyboardInterrupt set, and Python
    reports a SystemError caused by it; a library that was importing an
    optional module keeps the KeyboardInterrupt as that module's import error
    and fails later in some other way. Any error after a SIGINT counts."""
    if _SIGINTS:
        return True
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


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
def spin(model: tuple[Path, ...], out: Path, size: float, center_z: float, turns: int | None,
         stipples: int, seed: int,
         view_distance: float, view_elevation: float, ipd: float, light_height: float | None,
         walls: str, no_occlusion: bool, tool_radius: float, depth: float, step: float,
         frames: int) -> None:
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
def steady(model: Path, out: Path, size: float, center_z: float, stipples: int, seed: int,
           view_distance: float, ipd: float, light_elevation: float, light_range: float,
           shape: str, tool_radius: float, depth: float, step: float) -> None:
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


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; every failure is one line on stderr and a non-zero exit.

    Run as the ``specholo`` command (no ``argv``), the process ends as soon as
    the command is done (:func:`_end`).
    """
    args = [str(a) for a in (sys.argv[1:] if argv is None else argv)]
    command = argv is None  # the command itself, not a caller in Python
    _SIGINTS.clear()
    _END_AT_ONCE[0] = command
    previous = None
    with contextlib.suppress(ValueError):  # ValueError: not the main thread
        if signal.getsignal(signal.SIGINT) in (signal.default_int_handler, early_sigint):
            previous = signal.signal(signal.SIGINT, _on_sigint)
    try:
        code = _main(args)
    except SystemExit as exc:  # a command that ends with sys.exit (check)
        if not command:
            raise
        code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    finally:
        if previous is not None and not command:
            signal.signal(signal.SIGINT, previous)
    if command:
        _end(code, previous is not None)
    return code


#: The exit status of the command that has just ended (see :func:`_end`).
_RESULT = [0]


def _end(code: int, handle_sigint: bool) -> NoReturn:
    """End the ``specholo`` command now that its work is done, with status ``code``.

    Python's own exit spends a few tenths of a second more tearing down the
    modules, with Ctrl-C already handed back to the system: a Ctrl-C then
    ended the process without a word. Here every file is closed, written
    whole or removed, and nothing registered to run at exit is needed.
    """
    _RESULT[0] = code
    if handle_sigint:
        with contextlib.suppress(ValueError):
            signal.signal(signal.SIGINT, _sigint_after_run)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe
            stream.flush()
    os._exit(code)


def _sigint_after_run(signum: int, frame: Any) -> None:
    """Ctrl-C while the command exits: its outputs are complete (a run that
    failed has said so in its own one line, and keeps its status)."""
    code = _RESULT[0]
    err = sys.__stderr__
    if code == 0 and err is not None:
        with contextlib.suppress(OSError, ValueError):
            err.write(FINISHED_INTERRUPTED + "\n")
            err.flush()
    os._exit(130 if code == 0 else code)


#: What a Ctrl-C prints once the command has done its work.
FINISHED_INTERRUPTED = ("error: interrupted as it exited; the run had finished and its "
                        "outputs are complete")


def _os_error(exc: OSError) -> str:
    """An operating-system error as one line naming the file, if it names one."""
    what = exc.strerror or " ".join(str(exc).split()) or type(exc).__name__
    # os.replace(scratch, destination) names the destination second.
    name = exc.filename2 if exc.filename2 is not None else exc.filename
    if name is None:
        return what[:1].lower() + what[1:]
    path = Path(os.fsdecode(name))
    if path.name.startswith(".") and ".part" in path.name:
        # a scratch file beside the real one: the folder is what the user knows
        return f"cannot write in {path.parent}: {what}"
    return f"{path}: {what}"


def _main(args: list[str]) -> int:
    try:
        # click's own main() would print an empty line on Ctrl-C: a second line.
        with cli.make_context("specholo", list(args), obj={"argv": ["specholo", *args]}) as ctx:
            cli.invoke(ctx)
    except click.exceptions.Exit as exc:
        return int(exc.exit_code)
    except click.Abort:
        click.echo("error: aborted", err=True)
        return 130
    except click.ClickException as exc:
        click.echo(f"error: {exc.format_message()}", err=True)
        return exc.exit_code
    except SpecholoError as exc:
        if _interrupted(exc):
            click.echo(INTERRUPTED, err=True)
            return 130
        click.echo(f"error: {str(exc).splitlines()[0] if str(exc) else 'bad input'}", err=True)
        return 1
    except KeyboardInterrupt:
        click.echo(INTERRUPTED, err=True)
        return 130
    except MemoryError as exc:
        if _interrupted(exc):
            click.echo(INTERRUPTED, err=True)
            return 130
        click.echo("error: out of memory; try fewer stipples", err=True)
        return 1
    except OSError as exc:
        # The system refused a read or a write (a full disk, a folder gone or
        # read-only, a link loop): the user's to fix, not a fault of the program.
        if _interrupted(exc):
            click.echo(INTERRUPTED, err=True)
            return 130
        click.echo(f"error: {_os_error(exc)}", err=True)
        return 1
    except Exception as exc:  # noqa: BLE001 - the promise is one line, never a traceback
        if _interrupted(exc):
            click.echo(INTERRUPTED, err=True)
            return 130
        if os.environ.get("SPECHOLO_DEBUG"):
            raise
        if isinstance(exc, ValueError) and "null byte" in str(exc):
            # click.Path stats its argument, and a NUL byte makes os.stat raise
            click.echo("error: a path holds a NUL byte", err=True)
            return 2
        click.echo(f"error: internal error ({type(exc).__name__}: {exc}); "
                   "set SPECHOLO_DEBUG=1 for details", err=True)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())

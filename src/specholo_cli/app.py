"""What the commands share: the command group, option tables, folder and
output checks, and printing a library result."""

from __future__ import annotations

import contextlib
import math
import sys
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import click

from specholo import __version__
from specholo.errors import SpecholoError
from specholo.fabrication.programs.machines import MACHINES

_DESIGN_OPTIONS: list[tuple[str, Any, str]] = [
    ("size", float, "Largest side of the model's bounding box, mm [60]."),
    ("center-z", float, "Depth of the model's box centre, mm; negative is behind the plate [-40]."),
    ("up", click.Choice(["y", "-y", "z", "-z", "x", "-x"]),
     "The model's axis that points up on the plate [y]; z for most CAD and slicer files "
     "(z-up, front facing -y)."),
    ("rotate-x", float, "Turn the model about the plate's x axis (right), degrees [0]."),
    ("rotate-y", float, "Turn the model about the plate's y axis (up), degrees [0]."),
    ("rotate-z", float, "Turn the model about the plate's z axis (toward you), degrees [0]."),
    ("offset-x", float, "Move the model's box centre right on the plate, mm [0]."),
    ("offset-y", float, "Move the model's box centre up on the plate, mm [0]."),
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
    ("band", float, "Striped design: half-height of the band, bounds vertical error, mm "
     "[0.2; 1 with --tool scriber, for fewer, longer strokes by hand]."),
    ("band-share", float, "Striped design: choose the band so that, seen from the viewing "
     "distance, it is this share of the neighbouring stipples' spacing (never finer than "
     "0.2 mm) [0.2 with a --machine whose strokes lift the tool: a router, mill or plotter; "
     "else off; --band wins]."),
    ("placement", click.Choice(["auto", "avoid", "phase", "lock"]),
     "Striped design: avoid places each stipple's stripes in turn out of the grooves placed "
     "before (jumping between the band's paths where a crossing would cut glints away); "
     "phase designs each stipple alone, one stripe family; auto is avoid where its plan fits "
     "in memory and time, else phase; lock is auto with every stipple's stripes ending at "
     "view angles a whole fraction of the eyes' separation apart, so both eyes meet stripe "
     "ends alike (a sharper image under a light of real size) [auto]."),
    ("thin", click.Choice(["auto", "on", "off"]),
     "Leave uncut the stipples whose grooves, on the plate as cut, would take more glints "
     "from the others than they show (the stereo points every 5 deg decide); auto where that "
     "shows 2% more points, on wherever it shows more, off never [auto]."),
    ("tool", click.Choice(["ball", "vbit", "drag", "scriber", "laser"]),
     "Cutting tool: ball-end mill, V-bit, diamond drag tip, hand scriber or laser [drag]."),
    ("tool-radius", float, "Ball or tip radius, mm [ball 0.25, drag 0.025, scriber 0.05]."),
    ("tool-angle", float, "Included angle of a V-bit or tip cone, degrees "
     "[vbit 60, drag 90, scriber 60]."),
    ("tip-flat", float, "Width of a V-bit's tip flat, mm [0]."),
    ("spot", float, "Laser spot diameter (1/e^2), mm [0.1]."),
    ("depth", float, "Groove depth, mm [deep enough for the steepest wall the views "
     "need, plus 0.005; a V-bit 0.05]."),
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
    ("holder", click.Choice(["rigid", "spring"]),
     "How the tip is held: spring (a spring-loaded drag engraver: touched off on the plate, "
     "it cuts --preload below it and lifts at least 0.05 mm between strokes) or rigid (cuts "
     "at the depth: probe the plate, specholo probe and level) [spring for a drag tip or "
     "scriber the spindle does not turn, else rigid]."),
    ("preload", float, "Spring holder: spring compression while cutting, mm; the spring's "
     "force sets the depth [0.3]."),
    ("machine", click.Choice(list(MACHINES)),
     "Time the design on this machine (its accelerations, rates, corners, pen lifts or laser "
     "delays; docs/machines.md) and take its feeds, which --feed and --plunge override up to "
     "its rates; a laser profile cuts with --tool laser [none: every axis at 250 mm/s^2, rapids at "
     "3000 mm/min]."),
    ("elevation-range", float, "Ridged design: heads' elevation within +- this many degrees "
     "[8]."),
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


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="specholo")
def cli() -> None:
    """Exact specular holograms: design grooves from a 3D model and verify them."""


def _design_options(fn: Any) -> Any:
    for name, kind, text in reversed(_DESIGN_OPTIONS):
        fn = click.option(f"--{name}", type=kind, default=None, help=text)(fn)
    return fn


def _print_summary(summary: Any) -> None:
    """A design's lines on stdout and its warnings on stderr."""
    for line in summary.lines:
        click.echo(line)
    for line in summary.warnings:
        click.echo(f"warning: {line}", err=True)


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


def _check_folder(folder: Path, command: str) -> None:
    """Refuse a missing folder, and a kind of design ``command`` does not draw."""
    from specholo.jobs import job_of
    from specholo.jobs.base import refuse_picture

    if not folder.exists():
        raise SpecholoError(f"design folder {folder} does not exist")
    if not folder.is_dir():
        raise SpecholoError(f"{folder} is not a folder")
    refuse_picture(job_of(folder), folder, command)


def _picture_source(folder: Path, command: str) -> Any:
    """The design in ``folder``, of any kind, as the picture commands draw it
    (``Job.picture_source``), read back and checked."""
    from specholo.jobs import job_of

    _check_folder(folder, command)
    return job_of(folder).picture_source(folder)


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
    fn = click.option("--light-size", type=float, default=None,
                      help=LIGHT_SIZE_HELP)(fn)
    return click.option("--roughness", default=None, help=ROUGHNESS_HELP)(fn)


LIGHT_SIZE_HELP = ("A flat plate: draw each glint as the streak a light this many degrees "
                   "across makes along its groove (the sun 0.53), end spills and all "
                   "[a spot per glint].")
ROUGHNESS_HELP = ("The plate's gloss: mirror, polished, satin or a Beckmann alpha; rougher, "
                  "bigger dimmer glints [0.0247: a lobe of 1 degree].")


def _lighting(source: Any, roughness: str | None, light_size: float | None) -> tuple[Any, float]:
    """The picture source and its spots' lobe (radians) for ``--roughness`` and
    ``--light-size``: with a light size, a flat plate drawn as its streaks."""
    from specholo.optics.spread import Spread
    from specholo.preview.render import REFERENCE_ROUGHNESS

    # without --roughness the pictures keep their lobe of 1 degree
    gloss = roughness if roughness is not None else str(math.sqrt(2.0) * REFERENCE_ROUGHNESS)
    spread = Spread.of(light_size, gloss)
    assert spread is not None
    if spread.roughness == 0.0:
        raise SpecholoError("roughness 0 is a perfect mirror, whose glints have no size to "
                            "draw: give a roughness above 0")
    if light_size is None:
        return source, spread.sigma
    lit = getattr(source, "lit_by", None)
    if lit is None:
        raise SpecholoError(f"--light-size draws each glint as its streak along a groove: "
                            f"{source.title} has none (for flat-plate designs)")
    return lit(spread), spread.sigma


#: Most frames of an animation (an hour at 30 fps); every frame is held in memory.
MAX_FRAMES = 108_000


def _stderr_console() -> Any:
    from rich.console import Console

    return Console(stderr=True)


#: About how many kernels a command compiles on a fresh install (counted on
#: the README's design by ``benchmarks/first_run.py``, with the later stages'
#: compiled beside it by :mod:`specholo._precompile`, about 70 without; its
#: verify then compiles one more): the progress line's "of ~N", only ever
#: shown while compiling.
KERNELS = {"design": 24}


class _Status:
    """A status line (rich) that also says when kernels compile.

    On a terminal the line is replaced while compiling and restored after. To
    a file or a pipe nothing is added: there every line stays, and a command
    that fails says so in exactly one line.
    """

    def __init__(self, console: Any, status: Any, text: str, expected: int | None) -> None:
        self.console, self.status, self.text, self.expected = console, status, text, expected
        self.compiling = False

    def update(self, text: str) -> None:
        self.text = text
        if not self.compiling:
            self.status.update(text)

    def compiled(self, count: int, name: str | None) -> None:
        if name is None:
            self.compiling = False
            self.status.update(self.text)
            return
        self.compiling = True
        of = f" of ~{self.expected}" if self.expected and count <= self.expected else ""
        line = f"compiling kernels for this machine (first run only): {count}{of}, {name}..."
        if self.console.is_terminal:
            self.status.update(_escape(line))


@contextlib.contextmanager
def _status(text: str, command: str | None = None) -> Iterator[_Status]:
    """``rich``'s status line on stderr showing ``text``, saying also when the
    kernels compile (a first run); ``command`` names the estimate in
    :data:`KERNELS`."""
    from specholo._compiling import compiling_shown

    console = _stderr_console()
    with console.status(text) as status:
        shown = _Status(console, status, text, KERNELS.get(command or ""))
        with compiling_shown(shown.compiled):
            yield shown


def _escape(text: str) -> str:
    """``text`` shown as is by rich (no markup)."""
    from rich.markup import escape as rich_escape

    return str(rich_escape(text))


def _pose_options(fn: Any) -> Any:
    """--up, --rotate-x/-y/-z and --offset-x/-y, as for ``design``."""
    for name, kind, text in reversed([row for row in _DESIGN_OPTIONS if row[0] in _POSE]):
        fn = click.option(f"--{name}", type=kind, default=None, help=text)(fn)
    return fn


#: The options that turn and move the model onto the plate.
_POSE = ("up", "rotate-x", "rotate-y", "rotate-z", "offset-x", "offset-y")


#: ``--fit``'s help, the same for every job that fits a model to a plate.
FIT_HELP = ("Scale the model (instead of --size) to the largest whose grooves lie on the "
            "plate given by --plate-width and --plate-height, 5 mm in from its edges.")


def _plate_options(fn: Any) -> Any:
    """--plate-width, --plate-height (as for ``design``) and --fit, for the jobs
    whose options are not ``design``'s."""
    fn = click.option("--fit", is_flag=True, help=FIT_HELP)(fn)
    for name, kind, text in reversed([row for row in _DESIGN_OPTIONS
                                      if row[0] in ("plate-width", "plate-height")]):
        fn = click.option(f"--{name}", type=kind, default=None, help=text)(fn)
    return fn

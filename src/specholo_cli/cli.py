"""``specholo`` commands. Options are parsed here; the work happens in the library."""

from __future__ import annotations

import json
import math
import os
import sys
import tomllib
from pathlib import Path
from typing import Any

import click

from specholo import __version__
from specholo.errors import SpecholoError

_DESIGN_OPTIONS: list[tuple[str, Any, str]] = [
    ("size", float, "Largest side of the model's bounding box, mm [60]."),
    ("center-z", float, "Depth of the model's box centre, mm; negative is behind the plate [-40]."),
    ("light-elevation", float, "Light elevation a in degrees: direction (0, cos a, sin a) [45]."),
    ("light-distance", float, "Point light this far from the plate centre, mm [sun]."),
    ("view-distance", float, "Radius of the viewing arc, mm [600]."),
    ("view-range", float, "Eyes' azimuth within +- this many degrees [45]."),
    ("eye-height", float, "Eye height above the plate centre, mm [0]."),
    ("ipd", float, "Interocular distance, mm [64]."),
    ("stipples", int, "Number of stipples [2000]."),
    ("spacing", float, "Minimum stipple spacing in mm (instead of --stipples)."),
    ("seed", int, "Random seed for stippling [0]."),
    ("band", float, "Striped design: half-height of the band, bounds vertical error, mm [0.2]."),
    ("tool-radius", float, "Ball-end tool radius, mm [0.25]."),
    ("depth", float, "Groove depth, mm [0.08]."),
    ("feed", float, "Cutting feed, mm/min [300]."),
    ("plunge", float, "Plunge feed, mm/min [100]."),
    ("safe-z", float, "Rapid (safe) height, mm [1]."),
    ("spindle", float, "Spindle speed, rpm; 0 for none [12000]."),
]


def _read_config(path: Path | None) -> dict[str, Any]:
    if path is None:
        return {}
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError as exc:
        raise SpecholoError(f"config file {path} not found") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SpecholoError(f"config file {path} is not valid TOML: {exc}") from exc
    except OSError as exc:
        raise SpecholoError(f"cannot read config file {path}: {exc.strerror}") from exc
    return data


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
@click.option("--out", "-o", type=click.Path(path_type=Path), required=True,
              help="Output folder.")
@click.option("--method", type=click.Choice(["striped", "hyperbola", "arc"]), default=None,
              help="Design: exact striped [default], the paper's closed-form hyperbola, "
                   "or the classic circular arc.")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="TOML file with any of these options (same names).")
@_design_options
def design(model: Path, out: Path, method: str | None, config_path: Path | None,
           **options: Any) -> None:
    """Design a hologram of MODEL (OBJ, STL, PLY, OFF, GLB; PLY/XYZ/CSV point clouds)."""
    from rich.console import Console

    from specholo.pipeline import DesignConfig, write_design
    from specholo.pipeline import design as run_design

    values = _read_config(config_path)
    if method is not None:
        options["method"] = method
    values.update({k: v for k, v in options.items() if v is not None})
    config = DesignConfig.from_dict(values)
    console = Console(stderr=True)
    with console.status("designing..."):
        d = run_design(model, config)
    with console.status("writing..."):
        write_design(d, out)
    stats = (f"{len(d.points)} stipples, {d.grooves.n_paths} paths, "
             f"{d.grooves.total_length() / 1000:.2f} m of groove")
    click.echo(f"{config.method}: {stats} -> {out}")
    if len(d.dropped):
        click.echo(f"warning: {len(d.dropped)} stipples could not be designed "
                   "(light in the eyes' plane)", err=True)


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--step", type=float, default=5.0, show_default=True,
              help="Largest azimuth step between simulated eye pairs, degrees.")
@click.option("--from-gcode", is_flag=True,
              help="Verify the grooves parsed from hologram.gcode, the file that will be cut.")
def verify(folder: Path, step: float, from_gcode: bool) -> None:
    """Simulate stereo eye pairs along the arc and measure where each stipple appears."""
    from rich.console import Console
    from rich.table import Table

    from specholo.fabrication.atomic import atomic_open
    from specholo.pipeline import load_design, verify_design
    from specholo.preview.preview import plot_verification
    from specholo.simulation.verify import reports_to_dicts, summarise

    if not (math.isfinite(step) and 0 < step <= 5.0):
        raise SpecholoError(f"step must be in (0, 5] degrees, got {step}")
    loaded = load_design(folder, from_gcode=from_gcode)
    with Console(stderr=True).status("simulating eye pairs..."):
        reports = verify_design(loaded, step)
    rows = reports_to_dicts(reports)
    summary = summarise(reports)
    table = Table(title=f"{loaded.config.method} design, {len(loaded.points)} stipples")
    for col in ("azimuth", "median mm", "p95 mm", "p95 depth mm", "max mm", "visibility",
                "false"):
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(f"{r['azimuth']:+.1f}", f"{r['median_error']:.3f}",
                      f"{r['p95_error']:.3f}", f"{r['p95_depth_error']:.3f}",
                      f"{r['max_error']:.3f}",
                      f"{r['visibility']:.3f}", f"{r['false_glints']:.3f}")
    Console().print(table)
    click.echo(f"worst p95 error {summary['worst_p95_error']:.3f} mm, "
               f"min visibility {summary['min_visibility']:.3f}, "
               f"max false glints {summary['max_false_glints']:.3f}")
    with atomic_open(Path(folder) / "verify.json") as fh:
        json.dump({"method": loaded.config.method, "source":
                   "hologram.gcode" if from_gcode else "grooves.npz",
                   "summary": summary, "azimuths": rows}, fh, indent=1)
    plot_verification(rows, Path(folder) / "verify.png",
                      f"{loaded.config.method}: stereo verification")


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; every failure is one line on stderr and a non-zero exit."""
    try:
        cli.main(args=argv, prog_name="specholo", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return int(exc.exit_code)
    except click.Abort:
        click.echo("error: aborted", err=True)
        return 130
    except click.ClickException as exc:
        click.echo(f"error: {exc.format_message()}", err=True)
        return exc.exit_code
    except SpecholoError as exc:
        click.echo(f"error: {str(exc).splitlines()[0] if str(exc) else 'bad input'}", err=True)
        return 1
    except KeyboardInterrupt:
        click.echo("error: interrupted; no output was written", err=True)
        return 130
    except MemoryError:
        click.echo("error: out of memory; try fewer stipples", err=True)
        return 1
    except Exception as exc:  # noqa: BLE001 - the promise is one line, never a traceback
        if os.environ.get("SPECHOLO_DEBUG"):
            raise
        click.echo(f"error: internal error ({type(exc).__name__}: {exc}); "
                   "set SPECHOLO_DEBUG=1 for details", err=True)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``specholo design``: a grooved or ridged plate from a model."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from specholo_cli.app import (
    FIT_HELP,
    _command_line,
    _design_options,
    _Folder,
    _print_summary,
    _read_config,
    _status,
    cli,
)


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
@click.option("--fit", is_flag=True, help=FIT_HELP)
@click.option("--no-order", is_flag=True,
              help="Keep the paths in design order (default: ordered to cut air travel).")
@click.option("--formats", default=None,
              help="Fabrication files, comma-separated: gcode, svg, dxf, pdf (a 1:1 "
                   "pattern to scribe by hand: each stroke of a striped or hyperbola design, "
                   "an arc design's compass arcs) [gcode,svg]; for a ridged design png, tiff "
                   "(16-bit height maps), stl, gcode [all four].")
@_design_options
def design(model: Path, out: Path, method: str | None, config_path: Path | None,
           strict: bool, fit: bool, no_order: bool, formats: str | None, **options: Any) -> None:
    """Design a hologram of MODEL (OBJ, STL, PLY, OFF, GLB; PLY/XYZ/CSV point clouds)."""
    from specholo.folders import check_out
    from specholo.jobs.base import WriteOptions, run
    from specholo.jobs.flat.job import FlatJob
    from specholo.jobs.ridged.job import RidgedJob

    # before any input is read: a config file that is the folder's own output is
    # refused as such, not read as bad TOML
    check_out(out, [model, config_path])
    values = _read_config(config_path)
    if method is not None:
        options["method"] = method
    if strict:
        options["strict"] = True
    if no_order:
        options["order"] = False
    if fit:
        options["fit"] = True
    values.update({k: v for k, v in options.items() if v is not None})
    job = RidgedJob() if values.get("method") == "ridged" else FlatJob()
    wanted = None if formats is None else \
        tuple(f.strip().lower() for f in formats.split(",") if f.strip())
    # The later kernels compiled beside a first run only for the specholo
    # command itself: the process that compiles them is spawned, and would
    # import a Python caller's own script again.
    from specholo_cli import END_AT_ONCE

    with _status("designing...", "design") as status:
        summary = run(job, [model], values, out,
                      WriteOptions(formats=wanted, command=_command_line()), status.update,
                      other_inputs=[config_path], precompile=END_AT_ONCE[0])
    _print_summary(summary)

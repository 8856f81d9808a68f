"""``specholo design``: a grooved or ridged plate from a model."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import click

from specholo_cli.app import (
    _check_out,
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
@click.option("--no-order", is_flag=True,
              help="Keep the paths in design order (default: ordered to cut air travel).")
@click.option("--formats", default=None,
              help="Fabrication files, comma-separated: gcode, svg, dxf, pdf (a 1:1 "
                   "pattern to scribe by hand: each stroke of a striped or hyperbola design, "
                   "an arc design's compass arcs) [gcode,svg]; for a ridged design png, tiff "
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

        with _status(f"finding the most stipples that keep {config.visibility:.0%} "
                     "as cut...", "design"):
            d = design_for_visibility(model, config, tried)
    else:
        with _status("designing...", "design"):
            d = run_design(model, config)
    with _status("writing...", "design"):
        written = write_design(d, out, wanted, command=_command_line(),
                               inputs=[model, config_path])
    from specholo.jobs.flat import design_summary

    _print_summary(design_summary(d, written, out))


def _design_ridged(model: Path, out: Path, config: Any, formats: tuple[str, ...],
                   inputs: Sequence[Path | None]) -> None:
    """The design command for a ridged (full-parallax) plate."""
    from specholo.ridged import design_ridged_model, write_ridged_design

    with _status("designing the ridged plate..."):
        d = design_ridged_model(model, config)
    with _status("writing..."):
        written = write_ridged_design(d, out, formats, inputs)
    from specholo.jobs.ridged import design_summary

    _print_summary(design_summary(d, written, out))

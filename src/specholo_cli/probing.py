"""``specholo probe`` and ``specholo level``: a rigid holder's plate, probed and
levelled to (:mod:`specholo.fabrication.programs.leveling`)."""

from __future__ import annotations

from pathlib import Path

import click

from specholo.errors import SpecholoError
from specholo_cli.app import cli


def _program(folder: Path) -> Path:
    """The design's program in ``folder``, which must exist."""
    if not folder.is_dir():
        raise SpecholoError(f"design folder {folder} does not exist" if not folder.exists()
                            else f"{folder} is not a folder")
    program = folder / "hologram.gcode"
    if not program.is_file():
        raise SpecholoError(f"{folder} holds no hologram.gcode: probing and levelling read a "
                            "flat design's program")
    return program


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--spacing", type=float, default=10.0, show_default=True,
              help="Largest distance between probe points, mm.")
@click.option("--dialect", type=click.Choice(["grbl", "linuxcnc"]), default=None,
              help="Probe program for GRBL ([PRB:...] reports) or LinuxCNC (PROBEOPEN "
                   "file) [the design's dialect].")
def probe(folder: Path, spacing: float, dialect: str | None) -> None:
    """Write FOLDER/probe.gcode: a G38.2 grid over the grooves of a rigid
    holder's design, first at the plate zero X0 Y0, for `specholo level`.

    A rigid holder cuts at the Z it is given, so the plate's height over the
    grooves must be known to the depth's allowance (0.005 mm): run the program
    with a touch probe and keep its log (GRBL's console, or LinuxCNC's
    probe_results.txt)."""
    from specholo.fabrication.programs.leveling import (
        PROBE_PROGRAM,
        probe_area,
        read_program,
        rigid_limits,
        write_probe,
    )

    program = _program(folder)
    limits = rigid_limits(program)
    info = read_program(program)
    area = probe_area(info.cuts, limits.stock)
    stats = write_probe(folder / PROBE_PROGRAM, area, dialect or info.dialect, limits.safe_z,
                        spacing)
    rows, cols = stats.shape
    click.echo(f"{folder / PROBE_PROGRAM}: {stats.points} points (X0 Y0, then {rows} rows of "
               f"{cols}, {stats.spacing[0]:.2f} x {stats.spacing[1]:.2f} mm apart) over "
               f"X{area[0, 0]:.2f}..{area[1, 0]:.2f} Y{area[0, 1]:.2f}..{area[1, 1]:.2f} mm, "
               f"about {max(1, round(stats.seconds / 60.0))} min; then `specholo level "
               f"{folder} LOG` with its log")


@cli.command()
@click.argument("folder", type=click.Path(path_type=Path))
@click.argument("log", type=click.Path(path_type=Path))
def level(folder: Path, log: Path) -> None:
    """Write FOLDER/hologram_leveled.gcode: hologram.gcode with every Z offset
    by the plate's height probed under it (LOG: GRBL's [PRB:x,y,z:1] lines or
    LinuxCNC's probe file, first point at X0 Y0), bilinear between the probed
    points, long moves split so that the Z follows them within 0.001 mm. It is
    kept only once the safety check passes it against the probed plate."""
    from specholo.fabrication.check import check_program
    from specholo.fabrication.programs.leveling import (
        LEVELED_PROGRAM,
        level_program,
        leveled_limits,
        read_probe_log,
        rigid_limits,
    )

    program = _program(folder)
    limits = rigid_limits(program)
    pmap = read_probe_log(log)
    checked = leveled_limits(limits, pmap)
    done = level_program(program, folder / LEVELED_PROGRAM, pmap, log.name,
                         check=lambda path: check_program(path, checked))
    rows, cols = pmap.z.shape
    click.echo(f"{folder / LEVELED_PROGRAM}: levelled to {rows} x {cols} probed points "
               f"(heights {done.low:+.4f} to {done.high:+.4f} mm from X0 Y0), "
               f"{done.split:,} lines added to follow the plate within 0.001 mm; it passed the "
               "safety check against the probed plate. Set Z0 on the plate at X0 Y0 with the "
               "cutting tool")

"""``specholo verify`` (any kind of folder, through the job registry) and
``specholo check`` (any G-code program against a plate)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import click

from specholo.errors import SpecholoError
from specholo_cli.app import (
    _print_verification,
    _status,
    cli,
)


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
              help="Height-field cut: sample spacing, mm [the tool radius / 5, at most 0.02].")
@click.option("--stl", type=click.Path(path_type=Path), default=None,
              help="Height-field cut: write the cut plate as a watertight STL here.")
@click.option("--light-size", type=float, default=None,
              help="The light's angular diameter seen from the plate, degrees (the sun 0.53; "
                   "an LED its diameter over its distance): each glint becomes a streak along "
                   "its groove [a point].")
@click.option("--roughness", default=None,
              help="The plate's gloss: mirror (Beckmann alpha 0.003), polished (0.01), satin "
                   "(0.05), or an alpha [a perfect mirror].")
def verify(folder: Path, step: float, from_gcode: bool, cut: bool, cut_method: str | None,
           resolution: float | None, stl: Path | None, light_size: float | None,
           roughness: str | None) -> None:
    """Simulate stereo eye pairs along the arc and measure where each stipple appears.

    With --light-size or --roughness every glint is a streak along its groove:
    each eye sees a stipple at its streaks' brightness-weighted centres, a cut
    through a streak leaves the rest shining, and the stripe ends that spill
    light far from every designed glint are counted per view (flat plates)."""
    from specholo.jobs import VerifyOptions, job_of, publish_verification
    from specholo.jobs.flat.folder import cut_method as choose_cut_method
    from specholo.optics.spread import Spread

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
    spread = Spread.of(light_size, roughness)
    if spread is not None and spread.is_point:
        spread = None  # a point light on a perfect mirror: the point model exactly
    options = VerifyOptions(step, from_gcode, cut, cut_method, resolution, stl, spread)
    if cut:
        choose_cut_method(cut_method, resolution, stl)  # refused before the folder is read
    with _status("verifying...", "verify") as status:
        result = job_of(folder).verify(folder, options, status.update)
    _print_verification(result)
    # The verification's files appear together or not at all.
    publish_verification(folder, result)


@cli.command()
@click.argument("gcode", type=click.Path(path_type=Path))
@click.option("--plate-width", type=float, default=None,
              help="Plate width, mm [with no limits given: the program's own check lines].")
@click.option("--plate-height", type=float, default=None, help="Plate height, mm.")
@click.option("--stock-thickness", type=float, default=3.0, show_default=True,
              help="Plate thickness, mm.")
@click.option("--max-depth", type=float, default=None,
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
def check(gcode: Path, plate_width: float | None, plate_height: float | None,
          stock_thickness: float, max_depth: float | None, safe_z: float, feed: tuple[float, float],
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
    from specholo.fabrication.check import (
        CUTTER_KINDS,
        Limits,
        Stock,
        check_limits,
        limits_from_header,
    )

    given = [v is not None for v in (plate_width, plate_height, max_depth)]
    if not any(given):
        # a specholo program names the limits it was checked against
        if not gcode.is_file():
            raise SpecholoError(f"G-code file {gcode} not found")
        own = limits_from_header(gcode)
        if own is None:
            raise SpecholoError(_no_limits(gcode))
        report = check_limits(gcode, own)
        click.echo(report.summary() + " (against the limits in its header)")
        if not report.ok:
            sys.exit(1)
        return
    if not all(given):
        raise SpecholoError("give --plate-width, --plate-height and --max-depth together, or "
                            "none to use the program's own check lines")
    assert plate_width is not None and plate_height is not None and max_depth is not None

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


#: Header lines read for what a program says it was made for (a specholo header
#: is a dozen or so).
_HEADER_LINES = 40
#: The header line of a program on a curved host, whose limits no line can name
#: (``fabrication.surface_gcode``).
_SURFACE_LIMITS = "limits: not in this header"
#: The header lines of a program levelled to a probed plate
#: (``fabrication.leveling``), whose limits follow the probed surface.
_LEVELLED = "levelled:"


def _header_comments(gcode: Path) -> list[str]:
    """The texts of the comments heading a program, up to its first command."""
    import os

    from specholo.readback import open_regular

    fd, _ = open_regular(gcode, "G-code file")
    texts: list[str] = []
    with os.fdopen(fd, "r", encoding="ascii", errors="replace") as fh:
        for _ in range(_HEADER_LINES):
            # a line longer than any header line is read in part: no comment, the end
            line = fh.readline(1000).strip()
            if not (line.startswith("(") and line.endswith(")")):
                break
            texts.append(line[1:-1])
    return texts


def _no_limits(gcode: Path) -> str:
    """Why ``specholo check`` without options has no limits for a program, and what
    to do, in one line. A program for a curved host says its limits follow the
    host's surface: it was checked against them when it was written, as its
    folder's hologram.json records (``gcode.check``), and the options check it as
    a flat plate instead."""
    head = _header_comments(gcode)
    if any(t.startswith(_LEVELLED) for t in head):
        return (f"{gcode} names no limits to check: it is levelled to a probed plate, and its "
                "limits follow that plate, which no header line can name; specholo level "
                "checked it against them when it wrote it (check the design's hologram.gcode, "
                "or run specholo level again)")
    if not any(t.startswith(_SURFACE_LIMITS) for t in head):
        return (f"{gcode} names no limits (no check lines in its header): give "
                "--plate-width, --plate-height and --max-depth")
    made = next((t.removeprefix("specholo: grooves on ") for t in head
                 if t.startswith("specholo: grooves on ")), "a curved host")
    rotary = made.endswith("4-axis")
    flat = ("--plate-width, --plate-height and --max-depth check it as a flat plate instead, "
            + ("which cannot follow its A turns (every A word is flagged)" if rotary
               else "with the plane Z = 0 for the host's surface"))
    surface = "panels" if made.startswith("a panels host") else "curved surface"
    return (f"{gcode} names no limits to check: it cuts grooves on {made}, and its limits follow "
            f"the host's {surface}, which no header line can name; it passed them when it was "
            f"written: {_check_record(gcode)}; {flat}")


def _check_record(gcode: Path) -> str:
    """Where the check a composition's program passed when it was written is
    recorded, with its figures when hologram.json beside it holds them."""
    from specholo.readback import read_json

    record = gcode.parent / "hologram.json"
    general = "its design folder's hologram.json records that check (gcode.check)"
    if gcode.name != "hologram.gcode" or not record.is_file():
        return general
    try:
        meta = read_json(record)
        check = meta["gcode"]["check"]
        figures = (f"{int(check['cutting_moves'])} cutting moves, deepest "
                   f"{float(check['deepest_cut_mm']):.4g} mm below the surface, "
                   f"{int(check['violations'])} violations")
    except (SpecholoError, KeyError, TypeError, ValueError):
        return general  # not a composition's record: the program was moved or is older
    if meta.get("design") not in ("composition", "conforming"):
        return general
    return f"{record} records that check (gcode.check: {figures})"

"""A composition (curved hosts, animation, moving lights): verified by eye pairs,
or the light, along its motion."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from specholo.errors import SpecholoError
from specholo.jobs.base import (
    PICTURE_COMMANDS,
    Designed,
    Status,
    Summary,
    Table,
    Verification,
    VerifyOptions,
    WriteOptions,
    refuse_cut_options,
    refuse_formats,
)

if TYPE_CHECKING:
    from specholo.preview.source import PictureSource


def design_summary(d: Any, check: dict[str, Any]) -> Summary:
    """What a composition (``compose.ComposedDesign``) says once its G-code is
    checked: its stripes and groove, and the stipple-views it could not serve."""
    lines = [f"{d.stats['stripes']} stripes, {d.stats['groove_length_mm'] / 1000:.2f} m of "
             f"groove; G-code checked: {check['cutting_moves']} cutting moves, deepest "
             f"{check['deepest_cut_mm']:.4f} mm"]
    fams = d.stats["families"]
    missed = sum(f["states_missing_the_host"] for f in fams)
    tilt = sum(f["states_lost_to_tilt"] for f in fams)
    warnings = []
    if missed or tilt:
        warnings.append(f"of {sum(f['states_served'] for f in fams) + missed + tilt} "
                        f"stipple-views, {missed} miss the host and {tilt} need a wall steeper "
                        "than the tool's")
    return Summary(lines, warnings)


class CompositionJob:
    """A composition (``specholo compose``): a host, a motion and scenes from a TOML file."""

    kind = "composition"
    title = "a composition"
    verified_on = "its grooves"
    pictures: frozenset[str] = PICTURE_COMMANDS
    own_pictures = "preview.png and preview.gif"
    design_step: tuple[float, float, float] | None = (5.0, 0.1, 30.0)
    preview_frames: int | None = 48
    files: frozenset[str] = frozenset({
        "hologram.json", "grooves.npz", "stipples.npz", "run.json", "hologram.gcode",
        "verify.json", "preview.png", "preview.gif"})

    def configure(self, values: Mapping[str, Any], inputs: Sequence[Path]) -> Any:
        """The composition file's settings (a composition is all in its TOML)."""
        from specholo.jobs.composition.design import read_composition

        if len(inputs) != 1:
            raise SpecholoError(f"a design is composed from one TOML file, got {len(inputs)}")
        return read_composition(inputs[0])

    def check_options(self, config: Any, options: WriteOptions) -> None:
        refuse_formats(self, options)

    def design(self, inputs: Sequence[Path], config: Any, status: Status) -> Designed:
        from specholo.jobs.composition.design import design_composition

        status("designing grooves along the motion...")
        return Designed(design_composition(config))

    def write(self, designed: Designed, out: Path, inputs: Sequence[Path | None],
              options: WriteOptions, status: Status) -> Summary:
        """The folder with its verification and previews, published together."""
        from specholo.jobs.composition.design import write_composition
        from specholo.preview.composed import write_previews

        d = designed.design
        step, frames = options.step_deg or 5.0, options.frames or 0
        found: list[Summary] = []

        def finish(stage: Path, check: dict[str, Any]) -> None:
            summary = design_summary(d, check)
            status("simulating eye pairs along the motion...")
            result = self.verify(stage, VerifyOptions(step), status)
            result.write(stage)  # joins the new design's files, published with them
            done = [0]

            def frame() -> None:
                done[0] += 1
                status(f"rendering preview.gif: frame {done[0]} of {frames}")

            status("rendering the previews...")
            write_previews(d, stage, frames, progress=frame)
            found.append(Summary(summary.lines + result.lines, summary.warnings, result.table))

        status("writing...")
        write_composition(d, out, inputs, then=finish)
        return found[0]

    def holds(self, folder: Path) -> bool:
        from specholo.jobs.composition.design import is_composed_folder

        return is_composed_folder(folder)

    def load(self, folder: Path) -> Any:
        from specholo.jobs.composition.design import load_composition_folder

        return load_composition_folder(folder)

    def preview(self, folder: Path, status: Status) -> dict[str, Callable[[Path], object]]:
        """preview.png, and preview.gif if the folder had one (its default frames)."""
        from specholo.preview.composed import write_previews

        d = self.load(folder)
        frames = (self.preview_frames or 48) if (folder / "preview.gif").is_file() else 0

        def both(into: Path) -> None:
            status("rendering the previews...")
            write_previews(d, into, frames)

        files: dict[str, Callable[[Path], object]] = {"preview.png": both}
        if frames:
            files["preview.gif"] = lambda into: None  # written with preview.png
        return files

    def picture_source(self, folder: Path) -> PictureSource:
        """Its grooves on their host along its motion (glints found per position,
        as verify finds them), its scenes posed for ``--ghost``."""
        from specholo.preview.sources import ComposedSource

        d = self.load(folder)
        comp, m = d.comp, d.comp.motion
        host = comp.host.describe()
        shape = ", ".join(f"{k} {v:g} mm" for k, v in host.items()
                          if isinstance(v, int | float) and k not in ("kind", "axis_z"))
        if m.mode == "walk":
            motion = f"the viewer walks past: head azimuth +-{math.degrees(m.half_range):g} deg"
        else:
            motion = (f"the light moves from {math.degrees(m.light_elevation):g} to "
                      f"{math.degrees(m.light_stop):g} deg, the viewer still")
        light = (f"elevation {math.degrees(m.light_elevation):g} deg, " +
                 ("sun" if m.light_distance is None else f"point at {m.light_distance:g} mm"))
        facts = [
            ("kind", "composition (specholo compose)"),
            ("host", comp.host.kind + (f": {shape}" if shape else "")),
            ("motion", motion),
            ("scenes", f"{len(d.scenes)}, {sum(len(s.points) for s in d.scenes):,} stipples"),
            ("grooves", f"{len(set(d.grooves.stripe.tolist())):,} stripes, "
                        f"{d.grooves.length() / 1000:.2f} m"),
            ("light", light),
            ("viewer", f"{m.view_distance:g} mm away, eye height {m.eye_height:g} mm, IPD "
                       f"{m.ipd:g} mm"),
            ("tool", f"ball radius {comp.tool.radius:g} mm, {comp.tool.depth:g} mm deep, "
                     f"grooves {comp.tool.width:.3f} mm wide; {comp.axes}-axis program"),
        ]
        return ComposedSource(d.grooves, comp.host, comp.tool, m,
                              [(s.key, s.points) for s in d.scenes], facts)

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.folder import write_verify_json
        from specholo.jobs.composition.design import load_composition_folder, verify_composition
        from specholo.simulation.conforming import reports_to_dicts, summarise

        refuse_cut_options(self, options)
        d = load_composition_folder(folder)
        status("simulating eye pairs along the motion...")
        reports = verify_composition(d, math.radians(options.step_deg))
        label = "azimuth" if d.comp.motion.mode == "walk" else "light elev."
        table = Table(f"verification ({d.comp.host.kind} host, {d.comp.motion.mode})",
                      [label, "shown", "median mm", "p95 mm", "p95 depth mm", "visibility",
                       "stray"],
                      [[f"{r.position:+.1f}", str(r.shown), _figure(r.median_error),
                        _figure(r.p95_error), _figure(r.p95_depth_error),
                        _figure(r.visibility), _figure(r.stray)] for r in reports])
        summary = summarise(reports)
        rows = [_honest_row(row) for row in reports_to_dicts(reports)]

        def verify_json(into: Path) -> None:
            write_verify_json(into, self.kind, options.step_deg, _no_nan(summary), "positions",
                              rows, {"motion": d.comp.motion.mode, "host": d.comp.host.kind})

        lines = [f"worst p95 error {_figure(summary['worst_p95_error'])} mm, lowest visibility "
                 f"{_figure(summary['min_visibility'])}, most stray glints "
                 f"{_figure(summary['max_stray'])}"]
        for note in (NO_STIPPLE_SHOWN, NO_GLINTS):
            at = [f"{r['position']:+.1f}" for r in rows if r.get("note") == note]
            if at:
                lines.append(f"'-': nothing to measure at {', '.join(at[:6])}"
                             f"{' ...' if len(at) > 6 else ''} ({note})")
        return Verification(lines, table, {"verify.json": verify_json})


#: Why a position's errors are not numbers: nothing to triangulate there.
NO_STIPPLE_SHOWN = "no stipple is shown to both eyes"
NO_GLINTS = "no stipple shown to both eyes glints for both"


def _figure(v: float) -> str:
    """A figure of the table: '-' where there was nothing to measure (NaN)."""
    return "-" if math.isnan(v) else f"{v:.3f}"


def _no_nan(values: dict[str, Any]) -> dict[str, Any]:
    """``values`` with None for each NaN: JSON has no NaN (``json.dump`` would
    write a bare ``NaN`` that strict readers refuse)."""
    return {k: None if isinstance(v, float) and math.isnan(v) else v
            for k, v in values.items()}


def _honest_row(row: dict[str, Any]) -> dict[str, Any]:
    """A position's row for ``verify.json``: a figure with nothing to measure is
    null, and a note says why (a hand-over between scenes shows no stipple to
    both eyes; a view may show some that glint for one eye only)."""
    out = _no_nan(row)
    if out != row:
        out["note"] = NO_STIPPLE_SHOWN if row["shown"] == 0 else NO_GLINTS
    return out

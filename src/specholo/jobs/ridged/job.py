"""The ridged plate (full parallax, a milled height field; mirror or clear plate):
verified by heads over azimuth and elevation on its exact heights."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from specholo.jobs.base import (
    PICTURE_COMMANDS,
    Designed,
    Status,
    Summary,
    Verification,
    VerifyOptions,
    WriteOptions,
    refuse_cut_options,
)

if TYPE_CHECKING:
    from specholo.preview.source import PictureSource


def design_summary(d: Any, written: dict[str, Any], out: Path) -> Summary:
    """What a ridged design (``ridged.RidgedDesign``) and its written folder say."""
    from specholo.jobs.ridged.design import plate_edges

    config = d.config
    s = d.plate.summary()
    hm = d.plate.heights
    (x0, y0), (x1, y1) = plate_edges(hm)
    lines = [f"ridged: {len(d.points)} stipples, {s['kept_stipples']} kept, "
             f"{len(s['dropped_stipples'])} dropped (no view within the ranges, or no plate "
             f"area left); median kept share of views {s['median_kept_share']:.3f} -> {out}",
             f"plate {x1 - x0:.1f} x {y1 - y0:.1f} mm, raster {hm.resolution:g} mm "
             f"({hm.shape[1]} x {hm.shape[0]} cells); shell {-2 * d.plate.delta:g} to 0 mm, "
             f"deepest {s['deepest_mm']:.3f} mm"]
    if getattr(d, "budget", None) is not None:
        lines.append(budget_line(d.budget, len(d.points)))
    if config.optic == "refract":
        light = config.setup().light
        where = ("a sun" if light.position is None else
                 "a point light at (" + ", ".join(f"{v:.1f}" for v in light.position) + ") mm")
        lines.append(f"refraction ({config.refraction}): clear plate of index "
                     f"{config.index:g}, {config.stock_thickness:g} mm thick (back face z = "
                     f"{-config.stock_thickness:g} mm), lit from behind by {where}")
    mach = written["machining"]
    if mach:
        from specholo.fabrication.programs.timing import plain_duration

        lines.append(f"machining: ball-end mill radius {mach['ball_radius_mm']:g} mm, "
                     f"{mach['passes']} raster passes, about "
                     f"{plain_duration(3600.0 * mach['estimated_hours'])} at the feed; safety "
                     f"check passed ({mach['lines']:,} lines)")
    lines.append("files: " + ", ".join(written["files"]))
    return Summary(lines, [])


#: Below this many stipples a head, the summary says how to show more.
FEW_PER_HEAD = 50.0


def budget_line(budget: Any, stipples: int) -> str:
    """What the plate can show one head, in words (a ``StereoBudget``)."""
    line = (f"per head: the plate's regions hold both eyes' sightlines for about "
            f"{budget.per_head:.0f} of the {stipples} stipples ({budget.per_eye:.0f} for each "
            f"eye; `specholo verify` counts those that glint). Each cell sends one ray, so "
            f"a plate shows each eye about its area over one stipple's patch "
            f"({budget.ceiling:.0f} here) whatever the count")
    if budget.per_head < FEW_PER_HEAD:
        line += ("; a narrower --view-range or --elevation-range, or a model nearer the "
                 "plate (--center-z), shows more")
    return line


def stated_budget(folder: Path) -> str:
    """The per-head figure a ridged folder's hologram.json states ('' if none)."""
    from specholo.jobs.plate_common import design_json

    ridged = design_json(folder).get("ridged")
    budget = ridged.get("stereo_budget") if isinstance(ridged, dict) else None
    if not isinstance(budget, dict):
        return ""
    try:
        return f"{float(budget['stipples_per_head_both_eyes']):.0f}"
    except (KeyError, TypeError, ValueError):
        return ""


class RidgedJob:
    """A ridged design: its exact heights in plate.npz."""

    kind = "ridged"
    title = "a ridged design"
    verified_on = "its height field (plate.npz)"
    pictures = PICTURE_COMMANDS
    own_pictures = "preview.png"
    design_step: tuple[float, float, float] | None = None
    preview_frames: int | None = None
    files: frozenset[str] = frozenset({
        "hologram.json", "plate.npz", "stipples.npz", "model.ply", "run.json", "heightmap.png",
        "heightmap.tif", "heightmap.json", "hologram.stl", "hologram.gcode", "preview.png"})

    def configure(self, values: Mapping[str, Any], inputs: Sequence[Path]) -> Any:
        from specholo.jobs.ridged.settings import RidgedConfig

        return RidgedConfig.from_dict({**values, "method": "ridged"})

    def check_options(self, config: Any, options: WriteOptions) -> None:
        from specholo.jobs.plate_common import check_formats

        if options.formats is not None:
            check_formats(options.formats, "ridged")

    def design(self, inputs: Sequence[Path], config: Any, status: Status) -> Designed:
        from specholo.jobs.ridged.design import design_ridged_model

        status("designing the ridged plate...")
        return Designed(design_ridged_model(inputs[0], config))

    def write(self, designed: Designed, out: Path, inputs: Sequence[Path | None],
              options: WriteOptions, status: Status) -> Summary:
        from specholo.jobs.ridged.design import DEFAULT_RIDGED_FORMATS, write_ridged_design

        status("writing...")
        written = write_ridged_design(designed.design, out,
                                      options.formats or DEFAULT_RIDGED_FORMATS, inputs)
        return design_summary(designed.design, written, out)

    def holds(self, folder: Path) -> bool:
        from specholo.jobs.ridged.design import is_ridged_folder

        return is_ridged_folder(folder)

    def load(self, folder: Path) -> Any:
        from specholo.jobs.ridged.design import load_ridged_design

        return load_ridged_design(folder)

    def picture_source(self, folder: Path) -> PictureSource:
        """Its exact heights (glints found on the height field, as verify finds
        them), over the heads' azimuth and elevation ranges."""
        from specholo.jobs.ridged.design import plate_edges
        from specholo.preview.sources import FieldSource

        loaded = self.load(folder)
        c = loaded.config
        setup = c.setup()
        model = loaded.mesh if loaded.mesh is not None else loaded.points
        (x0, y0), (x1, y1) = plate_edges(loaded.heights)
        light = (f"a clear plate {c.stock_thickness:g} mm thick (index {c.index:g}) lit from "
                 f"behind at {c.light_elevation:g} deg" if c.optic == "refract" else
                 f"elevation {c.light_elevation:g} deg")
        facts = [
            ("kind", "ridged plate: full parallax from a milled height field "
                     "(specholo design --method ridged)"),
            ("stipples", f"{len(loaded.points):,}"),
            ("plate", f"{x1 - x0:.1f} x {y1 - y0:.1f} mm, raster {loaded.heights.resolution:g} "
                      f"mm, deepest {-float(loaded.heights.z.min()):.3f} mm"),
            ("light", light + (", sun" if c.light_distance is None
                               else f", point at {c.light_distance:g} mm")),
            ("viewer", f"{c.view_distance:g} mm away, azimuth +-{c.view_range:g} deg, "
                       f"elevation +-{c.elevation_range:g} deg, IPD {c.ipd:g} mm"),
            ("tool", f"ball-end mill, radius {c.ball_radius:g} mm (raster finishing)"),
        ]
        return FieldSource(loaded.heights, setup, math.radians(c.elevation_range), model,
                           facts)

    def preview(self, folder: Path, status: Status) -> dict[str, Callable[[Path], object]]:
        from specholo.preview.preview import render_field_preview

        loaded = self.load(folder)
        status("finding the glints of the preview's eyes...")
        return {"preview.png": lambda into: render_field_preview(
            loaded.heights, loaded.config.setup(), into / "preview.png")}

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.folder import write_verify_json
        from specholo.jobs.ridged.design import load_ridged_design, verify_ridged_design
        from specholo.preview.preview import plot_field_verification
        from specholo.simulation.heightfield import report_table
        from specholo.simulation.verify import reports_to_dicts, summarise

        refuse_cut_options(self, options)
        step = options.step_deg
        loaded = load_ridged_design(folder)
        status("simulating eye pairs over azimuth and elevation...")
        reports = verify_ridged_design(loaded, step)
        rows = reports_to_dicts(reports)
        summary: dict[str, Any] = dict(summarise(reports))

        def mean(key: str) -> float:
            vals = [getattr(r, key) for r in reports if not math.isnan(getattr(r, key))]
            return float(sum(vals) / len(vals)) if vals else math.nan

        summary["mean_visibility"] = mean("visibility")
        summary["mean_served_visibility"] = mean("served_visibility")
        summary["mean_glinting_per_head"] = float(sum(
            r.visibility * r.stipples_seen for r in reports if not math.isnan(r.visibility))
            / max(len(reports), 1))
        summary["heads"] = len(reports)
        summary["heads_with_glints"] = sum(not math.isnan(r.p95_error) for r in reports)
        refract = loaded.config.optic == "refract"
        kind = (f"ridged refraction design ({loaded.config.refraction}; light traced through "
                "the plate)" if refract else "ridged design")
        lines = [f"{kind}, {len(loaded.points)} stipples; heads every <= {step:g} deg "
                 "(rows: elevation, columns: azimuth; nan: no stipple glints for both eyes)"]
        for key, label in (("p95_error", "p95 error of the apparent point, mm"),
                           ("visibility", "visibility: share of unoccluded stipples glinting "
                                          "for both eyes"),
                           ("served_visibility", "share of the stipples the plate serves to "
                                                 "both eyes that glint")):
            lines.append(f"\n{label}:\n{report_table(reports, key)}")
        lines.append(f"\nworst p95 error {summary['worst_p95_error']:.3f} mm over "
                     f"{summary['heads_with_glints']} of {len(reports)} heads with glints; "
                     f"mean visibility {summary['mean_visibility']:.3f} "
                     f"({summary['mean_glinting_per_head']:.1f} stipples per head), "
                     f"max false glints {summary['max_false_glints']:.3f}")
        stated = stated_budget(folder)
        if stated:
            lines.append(f"per head: {summary['mean_glinting_per_head']:.0f} stipples glint "
                         f"for both eyes, of the {stated} whose regions hold both eyes' "
                         "sightlines (the design's budget; riser shadows and region edges "
                         "take the rest)")

        def verify_json(into: Path) -> None:
            write_verify_json(into, self.kind, step, summary, "views", rows,
                              {"method": "ridged", "optic": loaded.config.optic,
                               **({"refraction": loaded.config.refraction} if refract else {}),
                               "source": "plate.npz"})

        def verify_png(into: Path) -> None:
            plot_field_verification(rows, into / "verify.png",
                                    f"ridged{' refraction' if refract else ''}: stereo "
                                    "verification")

        return Verification(lines, None, {"verify.json": verify_json, "verify.png": verify_png})

"""The flat plate of grooves (``specholo design`` with a striped, hyperbola or arc
method): verified by stereo eye pairs along the arc, ideally and as cut."""

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
)

if TYPE_CHECKING:
    from specholo.preview.chart import ChartDrawer
    from specholo.preview.source import PictureSource


def design_summary(d: Any, written: Any, out: Path) -> Summary:
    """What a grooved design (``pipeline.Design``) and its written folder
    (``pipeline.Written``) say: the grooves, the tool, what survives the
    cutting, the machining time in plain words and the stipples hidden."""
    from collections import Counter

    from specholo.fabrication.programs.timing import describe_machining
    from specholo.jobs.flat.folder import AS_CUT_SKIPPED, drop_reasons

    lines: list[str] = []
    warnings: list[str] = []
    lines.append(f"{d.config.method}: {len(d.points)} stipples cut as {d.grooves.n_paths:,} "
                 f"strokes, {d.grooves.total_length() / 1000:.2f} m of groove -> {out}")
    plate = getattr(written, "plate", None)
    if plate is not None:
        lines.append(plate_line(plate, d.config))
    if d.config.method == "striped":
        lines.append(band_line(d))
    if d.placement and "fallback" in d.placement:
        how = ("phase, ending on the grid" if d.placement.get("placement") == "lock"
               else "phase")
        lines.append(f"placement: {d.placement['fallback']}; stripes placed by {how} instead")
    if d.views is not None:
        lo, hi = (math.degrees(v) for v in d.views.needed)
        lines.append(f"tool: {d.config.cutter().describe()}, {d.config.depth_mm:g} mm deep, "
                     f"grooves {d.views.offered.width:.3f} mm wide; to catch the light, the "
                     f"groove walls must slope {lo:.1f}-{hi:.1f} deg from flat, and these "
                     f"slope up to {math.degrees(d.views.offered.max_tilt):.1f} deg")
        if d.views.lost > 0:
            warnings.append(d.views.lost_views())
    if d.overlaps is not None:
        o = d.overlaps
        lines.append(f"grooves: {o.neighbours} overlapping stripe pairs within a stipple; "
                     f"{o.crossings} crossings between stipples, "
                     f"{o.crossed_length / max(o.total_length, 1e-9):.0%} of the groove length "
                     "within a groove width of another stipple's")
    if getattr(d, "light", None) is not None:
        lines.append(d.light.describe())
    # What survives the cutting: from the grooves themselves where the design
    # found it, else the rough share from the grooves' coverage.
    figures = d.as_cut.mean_and_lowest() if d.as_cut is not None else None
    if figures is not None:
        lines.append(d.as_cut.describe())
        surviving = figures[0]
    elif d.overlaps is not None:
        o = d.overlaps
        lines.append(f"grooves cover {o.coverage:.2f}x their area (roughly {o.surviving:.0%} "
                     "of each eye's glints survive the other grooves' cuts); " + AS_CUT_SKIPPED)
        surviving = o.surviving
    else:
        surviving = math.nan
    if d.thinned is not None and d.thinning is not None:
        t = d.thinning
        lines.append(f"thinned: {len(d.thinned)} of {d.coverage.grooved + len(d.thinned)} "
                     "grooved stipples left uncut, whose glints the crossing grooves would "
                     "take: the plate as cut shows "
                     f"{t['stereo_points_thinned']:.0f} stipples in both eyes per view instead "
                     f"of {t['stereo_points_all_cut']:.0f} (--thin off keeps them)")
    if surviving < 0.5:
        warnings.append("most stipples will not show in both eyes on the cut plate; use "
                        "fewer stipples (`--visibility 0.6` finds how many), a finer tip or a "
                        "larger model (check with `specholo verify --cut`)")
    mach = written.machining
    travel = (f"; between grooves the tool travels {mach['travel_mm'] / 1000:.1f} m in the "
              f"air (ordered; {mach['travel_unordered_mm'] / 1000:.1f} m in design order)"
              if "travel_mm" in mach else "")
    if (out / "hologram.gcode").is_file() or not (out / "pattern.pdf").is_file():
        lines.append(describe_machining(mach, d.config.feed) + "; "
                     + stipple_rate(mach['stipples_per_second']) + travel)
    if (out / "pattern.pdf").is_file():
        lines.append(hand_line(d))
    if len(d.dropped):
        why = Counter(r.split(":")[0] for r in
                      drop_reasons(d.points, d.dropped, d.config.setup()).values())
        warnings.append(f"{len(d.dropped)} stipples could not be designed ("
                        + ", ".join(f"{n}: {r}" for r, n in sorted(why.items())) + ")")
    if d.coverage is not None and d.coverage.mostly_ungrooved:
        line = d.coverage.describe()
        if d.config.up == "y" and not getattr(d, "up_hint", "") and \
                d.coverage.hidden > HIDDEN_HINT * d.coverage.stipples:
            # A z-up file read y-up turns its front (-y in CAD) to the floor.
            line += ("; if the model file is z-up (as CAD and slicer files are), add --up z "
                     "(--rotate-x and --rotate-y turn it further)")
        warnings.append(line)
    elif d.coverage is not None:
        lines.append(f"hidden: {d.coverage.hidden} of {d.coverage.stipples} stipples are "
                     "hidden from every view (no groove)")
    if getattr(d, "up_hint", ""):
        warnings.append(d.up_hint)
    lines.append(next_steps(out, d.config.holder))
    return Summary(lines, warnings)


#: Share of the stipples hidden from every view past which the summary asks
#: whether the model lies on its side (a model facing the viewer hides its back,
#: about a third to a half).
HIDDEN_HINT = 0.6


def band_line(d: Any) -> str:
    """The stripes' band as the eye sees it: each glint may sit up to a band off
    its place vertically, against how far apart neighbouring stipples look."""
    from specholo.jobs.flat.design import stipple_spacing
    from specholo.jobs.flat.settings import BAND

    band = float(d.config.band or BAND)
    distance = d.config.setup().viewer.distance
    within = "about a band"
    if getattr(d.config, "placement", None) == "lock":
        from specholo.toolpaths.striped import LOCK_SLACK

        # the stripes end on the common grid, most before the band's edge
        reach = LOCK_SLACK * band
        within, head = f"{reach:g} mm", "stripes: ending together (lock), band"
    else:
        reach, head = band, "stripes: band"
    arcmin = math.degrees(reach / distance) * 60.0
    line = (f"{head} {band:g} mm, so each glint sits within {within} of its place "
            f"vertically, {arcmin:.1f} arcmin seen from {distance:g} mm")
    spacing = stipple_spacing(d.points, distance)
    if spacing is not None:
        line += f", where neighbouring stipples look {spacing:.1f} arcmin apart"
        note = getattr(d, "band_note", "")
        line += (f" ({note}; --band sets it)" if note else
                 " (a wider --band cuts fewer, longer stripes)")
    return line


def plate_line(plate: Any, config: Any) -> str:
    """The plate a maker prepares, in one line: its size, thickness and where it
    came from, and the model's size where ``--fit`` chose it."""
    thick = f", {plate.thickness:g} mm thick" if plate.thickness else ""
    given = config.plate_width is not None or config.plate_height is not None
    how = ("as given" if config.plate_width is not None and config.plate_height is not None
           else "fitted to the grooves with a border" if not given
           else "the given side, the other fitted to the grooves")
    line = f"plate: {plate.width:.0f} x {plate.height:.0f} mm{thick} ({how})"
    if config.fit:
        line += f"; --fit sized the model {config.size:g} mm"
        if config.size < 0.25 * min(plate.width, plate.height):
            # What limits the size is the grooves' sideways spread, not the model.
            line += (f" (a point {abs(config.center_z):g} mm behind the plate draws grooves "
                     "spreading with the view range: a model nearer the plate, --center-z, "
                     "fits larger)")
    return line


def hand_line(d: Any) -> str:
    """The time to scribe a design by hand from its pattern, in one line."""
    from specholo.fabrication.drawings.stroke_pattern import SECONDS_PER_STROKE
    from specholo.fabrication.programs.timing import plain_duration

    strokes = int(d.grooves.n_paths - d.grooves.is_dot.sum())
    line = (f"by hand: {strokes:,} strokes to scribe from pattern.pdf, about "
            f"{plain_duration(strokes * SECONDS_PER_STROKE)} at {SECONDS_PER_STROKE:g} s a "
            "stroke")
    if d.config.method != "arc":
        line += ("; a wider --band makes fewer, longer strokes, and --method arc one compass "
                 "arc a stipple (right only near the straight-on view)")
    return line


def stipple_rate(per_second: float) -> str:
    """The machining speed in stipples, as a maker reads it, beside the rate
    Brand's paper reports for 90 degree holograms (about 4 stipples a second)."""
    if not (math.isfinite(per_second) and per_second > 0):
        return "no stipple is cut"
    if per_second >= 1.0:
        rate = f"{per_second:.1f} stipples a second"
    elif per_second * 60 >= 1.0:
        rate = f"{per_second * 60:.1f} stipples a minute"
    else:
        rate = f"{per_second * 3600:.0f} stipples an hour"
    return f"{rate} (Brand's paper reports about 4 a second)"


def next_steps(out: Path, holder: str | None = None) -> str:
    """What a maker does with a written flat-plate folder, in one line: look,
    check by simulation, then cut or scribe what the folder holds. A rigid
    holder's plate is probed and its program levelled first (``holder``: the
    design's, None for a laser)."""
    steps = [f"open {out / 'preview.png'}",
             f"`specholo verify {out}` simulates both eyes (`--cut`: the plate as cut)"]
    if (out / "hologram.gcode").is_file():
        if holder == "rigid":
            steps.append(f"held rigid, its depth needs the plate's Z to 0.005 mm: `specholo "
                         f"probe {out}`, run probe.gcode, `specholo level {out} LOG`, cut "
                         f"{out / 'hologram_leveled.gcode'}")
        else:
            how = ("; touch the spring holder off on the plate as it says" if holder == "spring"
                   else "")
            steps.append(f"cut {out / 'hologram.gcode'} (its header names the plate, the zero "
                         f"and the limits `specholo check` reads{how})")
    if (out / "pattern.pdf").is_file():
        steps.append(f"print {out / 'pattern.pdf'} at 100% to scribe by hand")
    return "next: " + "; ".join(steps)


class FlatJob:
    """A flat plate of grooves."""

    kind = "flat"
    title = "a flat-plate design"
    verified_on = "its grooves"
    pictures = PICTURE_COMMANDS
    own_pictures = "preview.png"
    design_step: tuple[float, float, float] | None = None
    preview_frames: int | None = None
    files: frozenset[str] = frozenset({
        "hologram.json", "grooves.npz", "stipples.npz", "model.ply", "run.json",
        "hologram.gcode", "hologram.svg", "hologram.dxf", "pattern.pdf", "preview.png"})

    def configure(self, values: Mapping[str, Any], inputs: Sequence[Path]) -> Any:
        from specholo.jobs.flat.folder import DesignConfig

        return DesignConfig.from_dict(dict(values))

    def check_options(self, config: Any, options: WriteOptions) -> None:
        from specholo.jobs.plate_common import check_formats

        if options.formats is not None:
            check_formats(options.formats, config.method)

    def design(self, inputs: Sequence[Path], config: Any, status: Status) -> Designed:
        from specholo.jobs.flat.folder import design

        if config.visibility is None:
            status("designing...")
            return Designed(design(inputs[0], config))
        from specholo.jobs.flat.density import design_for_visibility

        notes: list[str] = []

        def tried(n: int, v: float) -> None:
            notes.append(f"{n} stipples: as cut, {v:.0%} in both eyes at the lowest view")
            status(f"finding the most stipples that keep {config.visibility:.0%} as cut... "
                   + notes[-1])

        status(f"finding the most stipples that keep {config.visibility:.0%} as cut...")
        return Designed(design_for_visibility(inputs[0], config, tried), notes)

    def write(self, designed: Designed, out: Path, inputs: Sequence[Path | None],
              options: WriteOptions, status: Status) -> Summary:
        from specholo.jobs.flat.folder import DEFAULT_FORMATS, write_design

        status("writing...")
        written = write_design(designed.design, out, options.formats or DEFAULT_FORMATS,
                               command=options.command, inputs=inputs)
        summary = design_summary(designed.design, written, out)
        return Summary(designed.notes + summary.lines, summary.warnings)

    def holds(self, folder: Path) -> bool:
        # a flat plate written before run.json named its kind: the kind every
        # other one's files leave (its loader says what else is missing)
        return (Path(folder) / "hologram.json").is_file()

    def load(self, folder: Path) -> Any:
        from specholo.jobs.flat.folder import load_design

        return load_design(folder)

    def preview(self, folder: Path, status: Status) -> dict[str, Callable[[Path], object]]:
        from specholo.preview.preview import render_preview

        loaded = self.load(folder)
        status("finding the glints of the preview's eyes...")
        return {"preview.png": lambda into: render_preview(
            loaded.grooves, loaded.config.setup(), into / "preview.png", plate=loaded.plate)}

    def picture_source(self, folder: Path) -> PictureSource:
        """Its grooves (glints found on the engraved arcs), the plate its files
        name, and the model for ``--ghost``."""
        from specholo.preview.sources import FlatSource

        loaded = self.load(folder)
        model = loaded.mesh if loaded.mesh is not None else loaded.points
        return FlatSource(loaded.grooves, loaded.config.setup(), loaded.plate, model)

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.preview.chart import ChartDrawer

        # matplotlib is imported in a second process while the eyes are simulated.
        chart = ChartDrawer()
        try:
            return self._verify(folder, options, status, chart)
        except BaseException:
            chart.close()
            raise

    def _verify(self, folder: Path, options: VerifyOptions, status: Status,
                chart: ChartDrawer) -> Verification:
        from specholo.folder import write_verify_json
        from specholo.jobs.flat.folder import (
            cut_method,
            default_resolution,
            load_design,
            verify_cut_design,
            verify_design,
            verify_streak_design,
        )
        from specholo.simulation.verify import reports_to_dicts

        cut = options.cut
        spread = options.spread
        method = cut_method(options.cut_method, options.resolution, options.stl) if cut else None
        if spread is not None and method == "field":
            raise SpecholoError("--light-size and --roughness follow each streak along its "
                                "groove: verify them on the cut plate with --cut-method "
                                "survival (the height field finds point glints)")
        resolution = options.resolution
        loaded = load_design(folder, from_gcode=options.from_gcode or cut)
        if method == "field" and resolution is None:
            resolution = default_resolution(loaded.config)
        status("simulating eye pairs..." if spread is None else
               "following each glint's streak for every eye...")
        streak_cut = None
        if spread is None:
            reports = verify_design(loaded, options.step_deg)
        else:
            reports, streak_cut = verify_streak_design(loaded, options.step_deg, spread, cut)
        rows = reports_to_dicts(reports)
        summary = _summary(reports)
        cut_rows: list[dict[str, Any]] = []
        cut_summary: dict[str, Any] = {}
        if cut:
            status("finding which glints the other grooves' cuts leave..." if method == "survival"
                   else "cutting the plate and simulating eye pairs...")
            if streak_cut is None:
                cut_reports, _ = verify_cut_design(loaded, options.step_deg, resolution,
                                                   options.stl, method)
            else:
                cut_reports = streak_cut
            cut_rows = reports_to_dicts(cut_reports)
            cut_summary = _summary(cut_reports)
        table_rows, columns = _table(rows, cut_rows, spread is not None)
        name = loaded.config.method
        under = "" if spread is None else f" under {spread.describe()}"
        # The design stated what shows as cut; these are the ideal grooves'
        # figures, which no cut disturbs: each is named, so neither reads as the other.
        lines = [f"ideal grooves (no cut removes a glint){under}: worst p95 error "
                 f"{summary['worst_p95_error']:.3f} mm, "
                 f"min visibility {summary['min_visibility']:.3f}, "
                 f"max false glints {summary['max_false_glints']:.3f}"]
        if spread is not None:
            lines.append(_spills_line(rows))
        if not cut:
            estimate = _as_cut_estimate(folder)
            if estimate and spread is None:
                lines.append(estimate)
        if cut:
            how = ("the glints no other groove's cut removes" if method == "survival"
                   else f"height field at {resolution:g} mm")
            if spread is not None:
                how = "each streak's pieces no other groove's cut removes"
            lines.append(f"cut plate ({how}): worst p95 error "
                         f"{cut_summary['worst_p95_error']:.3f} mm, min visibility "
                         f"{cut_summary['min_visibility']:.3f} (other grooves cut away the rest)")
        if loaded.thinned:
            lines.append(f"{loaded.thinned} stipples were left uncut by thinning (their glints "
                         "would be cut away) and count as not shown")
        source = "hologram.gcode" if options.from_gcode or cut else "grooves.npz"

        light = {} if spread is None else {"light": spread.to_dict()}

        def verify_json(into: Path) -> None:
            write_verify_json(into, self.kind, options.step_deg, dict(summary), "azimuths", rows,
                              {"method": name, "source": source, **light})

        def verify_cut_json(into: Path) -> None:
            write_verify_json(into, self.kind, options.step_deg, cut_summary, "azimuths",
                              cut_rows, {"method": name, "source": source, "cut_method": method,
                                         "resolution_mm": resolution if method == "field"
                                         else None, **light}, name="verify_cut.json")

        def verify_png(into: Path) -> None:
            chart.plot_verification(rows, into / "verify.png", f"{name}: stereo verification")
            chart.close()

        files: dict[str, Callable[[Path], object]] = {"verify.json": verify_json,
                                                      "verify.png": verify_png}
        if cut:
            files["verify_cut.json"] = verify_cut_json
        title = f"ideal grooves: {name} design, {len(loaded.points)} stipples"
        return Verification(lines, Table(title, columns, table_rows), files)


def _summary(reports: list[Any]) -> dict[str, Any]:
    """The worst figures over the views (:func:`~specholo.simulation.verify.summarise`),
    and with streaks the most end spills an eye sees."""
    from specholo.simulation.verify import summarise

    summary: dict[str, Any] = dict(summarise(reports))
    spills = [r.end_spills for r in reports if hasattr(r, "end_spills")]
    if spills:
        summary["max_end_spills"] = float(max(spills))
    return summary


def _table(rows: list[dict[str, Any]], cut_rows: list[dict[str, Any]],
           streaks: bool) -> tuple[list[list[str]], list[str]]:
    """The verification's rows and columns as text."""
    columns = ["azimuth", "median mm", "p95 mm", "p95 depth mm", "max mm", "visibility",
               "false"] + (["spills", "streak mm"] if streaks else []) + (
                   ["cut p95 mm", "cut visibility"] if cut_rows else [])
    table_rows = []
    for i, r in enumerate(rows):
        extra = [] if not streaks else [f"{r['end_spills']:.0f}", f"{r['streak_length']:.3f}"]
        if cut_rows:
            extra += [f"{cut_rows[i]['p95_error']:.3f}", f"{cut_rows[i]['visibility']:.3f}"]
        table_rows.append([f"{r['azimuth']:+.1f}", f"{r['median_error']:.3f}",
                           f"{r['p95_error']:.3f}", f"{r['p95_depth_error']:.3f}",
                           f"{r['max_error']:.3f}", f"{r['visibility']:.3f}",
                           f"{r['false_glints']:.3f}", *extra])
    return table_rows, columns


def _spills_line(rows: list[dict[str, Any]]) -> str:
    """The end spills over the views, in words."""
    worst = max(rows, key=lambda r: r["end_spills"])
    mean = sum(r["end_spills"] for r in rows) / len(rows)
    seen = worst["stipples_seen"]
    return (f"false glints from stripe ends (streaks whose glint lies past their stripe's end): "
            f"{mean:.0f} per eye on average over the views, most {worst['end_spills']:.0f} at "
            f"{worst['azimuth']:+.0f} deg (beside {seen} stipples seen)")


def _as_cut_estimate(folder: Path) -> str:
    """The design's as-cut stereo visibility from its hologram.json, in words
    ('' where the design made none: a large design, or an older folder)."""
    from specholo.jobs.plate_common import design_json

    got = design_json(folder).get("expected", {})
    vis = got.get("as_cut_stereo_visibility") if isinstance(got, dict) else None
    if not isinstance(vis, dict):
        return ""
    try:
        mean, low, at = (float(vis[k]) for k in ("mean", "lowest", "lowest_azimuth_deg"))
    except (KeyError, TypeError, ValueError):
        return ""
    return (f"as cut (the design's estimate; --cut simulates hologram.gcode): about "
            f"{mean:.0%} of the stipples show in both eyes, lowest {low:.0%} at {at:+.0f} deg")

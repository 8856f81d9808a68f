"""A test coupon (``specholo coupon``): a card of rungs, each at one depth or
preload, verified against its own sheet: each glint where and from where the
sheet says, and nowhere else."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from specholo.jobs.base import (
    Designed,
    Status,
    Summary,
    Table,
    Verification,
    VerifyOptions,
    WriteOptions,
    refuse_formats,
    refuse_spread,
)

if TYPE_CHECKING:
    from specholo.preview.source import PictureSource


def coupon_summary(coupon: Any, checks: list[Any], out: Path) -> Summary:
    """What a written coupon says: the card, its ladder, the machining time,
    what simulated eyes found against its sheet, and what to do next."""
    from specholo.fabrication.programs.timing import describe_machining

    c = coupon.config
    ladder = ", ".join(f"{v:g}" for v in c.ladder)
    lines = [f"test coupon: {c.rungs} rungs of {c.setting_name} {ladder} mm "
             f"({c.holder} holder), {c.stipples} stipples each, "
             f"{coupon.grooves.n_paths:,} strokes and dots -> {out}",
             f"card: {coupon.plate.width:g} x {coupon.plate.height:g} mm, "
             f"{coupon.plate.thickness:g} mm thick; points {c.behind:g} mm behind it, each "
             f"glint seen from a {c.window:g} deg window of the +-{c.design.view_range:g} deg "
             "range",
             describe_machining(coupon.machining, c.design.feed),
             check_line(checks),
             f"next: print {out / 'sheet.pdf'} at 100%; cut {out / 'hologram.gcode'} "
             + ("(touch the spring holder off on the card as its header says)"
                if c.holder == "spring" else
                f"after `specholo probe {out}` and `specholo level {out} LOG` (a rigid "
                "holder's depths need the card's Z)")
             + f"; look from where the sheet says and design the long job with the passing "
               f"rung's {c.setting_name}"]
    return Summary(lines, [])


def check_line(checks: list[Any]) -> str:
    """What simulated eyes found against the sheet, in one line."""
    from specholo.jobs.flat.coupon import ON_THE_SHEET

    inside = sum(k.inside for k in checks)
    found = sum(k.found for k in checks)
    handover = sum(k.handover for k in checks)
    outside = sum(k.outside for k in checks)
    stray = sum(k.stray for k in checks)
    worst = max((k.worst_mm for k in checks), default=0.0)
    gaps = (f" ({handover} more, within a few hundredths of a degree of a hand-over between "
            "two strokes, found none, as the sheet allows)" if handover else "")
    worst_text = "-" if not math.isfinite(worst) else f"{worst:.3f}"
    return (f"simulated: {found} of {inside} eyes inside the sheet's windows found their glint "
            f"within {ON_THE_SHEET:g} mm of where it says (worst {worst_text} mm){gaps}; "
            f"{stray} of {outside} eyes outside them saw one")


class CouponJob:
    """A test coupon: rungs at a ladder of depths or preloads."""

    kind = "coupon"
    title = "a test coupon"
    verified_on = "its grooves against its sheet"
    pictures: frozenset[str] = frozenset({"render", "animate", "stereo", "view"})
    own_pictures = "sheet.pdf"
    design_step: tuple[float, float, float] | None = None
    preview_frames: int | None = None
    files: frozenset[str] = frozenset({"coupon.json", "sheet.pdf", "hologram.gcode",
                                       "hologram.svg", "grooves.npz", "run.json"})

    def configure(self, values: Mapping[str, Any], inputs: Sequence[Path]) -> Any:
        from specholo.jobs.flat.coupon import CouponConfig

        return CouponConfig.from_options(values)

    def check_options(self, config: Any, options: WriteOptions) -> None:
        refuse_formats(self, options)

    def design(self, inputs: Sequence[Path], config: Any, status: Status) -> Designed:
        from specholo.jobs.flat.coupon import design_coupon

        status("designing the rungs...")
        return Designed(design_coupon(config))

    def write(self, designed: Designed, out: Path, inputs: Sequence[Path | None],
              options: WriteOptions, status: Status) -> Summary:
        from specholo.jobs.flat.coupon import load_coupon, verify_coupon, write_coupon

        status("writing the card and its sheet...")
        write_coupon(designed.design, out, inputs, options.command)
        status("looking from where the sheet says...")
        checks = verify_coupon(load_coupon(out, from_gcode=True))
        return coupon_summary(designed.design, checks, out)

    def holds(self, folder: Path) -> bool:
        from specholo.jobs.flat.coupon import is_coupon_folder

        return is_coupon_folder(folder)

    def load(self, folder: Path) -> Any:
        from specholo.jobs.flat.coupon import load_coupon

        return load_coupon(folder)

    def preview(self, folder: Path, status: Status) -> dict[str, Callable[[Path], object]]:
        from specholo.fabrication.drawings.sheet import write_sheet

        loaded = self.load(folder)
        return {"sheet.pdf": lambda into: write_sheet(into / "sheet.pdf", loaded.info,
                                                      loaded.grooves)}

    def picture_source(self, folder: Path) -> PictureSource:
        """Its grooves and card, with the middle rung's groove (a rigid card's
        other rungs' walls differ in depth, their glints hardly in place)."""
        from specholo.preview.sources import FlatSource

        loaded = self.load(folder)
        middle = loaded.rungs[len(loaded.rungs) // 2]
        return FlatSource(loaded.grooves, middle.setup(), loaded.layout.corners,
                          loaded.points)

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.folder import write_verify_json
        from specholo.jobs.flat.coupon import LETTERS, load_coupon, verify_coupon

        if options.cut:
            from specholo.errors import SpecholoError

            raise SpecholoError(f"{self.title} is verified on {self.verified_on} (with "
                                "--from-gcode, as its program cuts them): --cut and its "
                                "methods are for flat-plate designs")
        refuse_spread(self, options)
        loaded = load_coupon(folder, from_gcode=options.from_gcode)
        status("looking from where the sheet says...")
        step = min(options.step_deg, 1.0)
        checks = verify_coupon(loaded, step)
        n = loaded.config.stipples
        name = loaded.config.setting_name
        rows: list[dict[str, Any]] = []
        for k in checks:
            rows.append({"rung": k.rung + 1, name + "_mm": loaded.config.ladder[k.rung],
                         "stipple": LETTERS[k.stipple % n], "inside": k.inside,
                         "found": k.found, "handover": k.handover,
                         "worst_mm": k.worst_mm if math.isfinite(k.worst_mm) else None,
                         "outside": k.outside, "stray": k.stray, "ok": k.ok})
        table = Table(f"test coupon: each glint against its sheet ({name} by rung)",
                      ["rung", name, "glint", "found", "hand-over", "worst mm", "stray"],
                      [[str(r["rung"]), f"{r[name + '_mm']:g}", r["stipple"],
                        f"{r['found']}/{r['inside']}", str(r["handover"]),
                        "-" if r["worst_mm"] is None else f"{r['worst_mm']:.4f}",
                        f"{r['stray']}/{r['outside']}"] for r in rows])
        source = "hologram.gcode" if options.from_gcode else "grooves.npz"
        ok = all(k.ok for k in checks)
        summary = {"glints_as_the_sheet_says": ok,
                   "found": sum(k.found for k in checks),
                   "inside": sum(k.inside for k in checks),
                   "handover": sum(k.handover for k in checks),
                   "stray": sum(k.stray for k in checks),
                   "outside": sum(k.outside for k in checks),
                   "worst_mm": max((r["worst_mm"] or 0.0) for r in rows)}
        lines = [check_line(checks) + (f" ({source})"),
                 "every glint shows where and from where the sheet says" if ok else
                 "some glints do not show as the sheet says: see the table"]

        def verify_json(into: Path) -> None:
            write_verify_json(into, self.kind, step, summary, "glints", rows,
                              {"source": source})

        return Verification(lines, table, {"verify.json": verify_json})

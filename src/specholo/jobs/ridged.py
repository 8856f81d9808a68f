"""The ridged plate (full parallax, a milled height field; mirror or clear plate):
verified by heads over azimuth and elevation on its exact heights."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from specholo.jobs.base import Status, Verification, VerifyOptions, refuse_cut_options


class RidgedJob:
    """A ridged design: its exact heights in plate.npz."""

    kind = "ridged"
    title = "a ridged design"
    verified_on = "its height field (plate.npz)"
    pictures = frozenset({"render", "view"})
    own_pictures = "preview.png"

    def holds(self, folder: Path) -> bool:
        from specholo.ridged import is_ridged_folder

        return is_ridged_folder(folder)

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        from specholo.fabrication.atomic import atomic_open
        from specholo.preview.preview import plot_field_verification
        from specholo.ridged import load_ridged_design, verify_ridged_design
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

        def verify_json(into: Path) -> None:
            with atomic_open(into / "verify.json") as fh:
                json.dump({"method": "ridged", "optic": loaded.config.optic,
                           **({"refraction": loaded.config.refraction} if refract else {}),
                           "source": "plate.npz", "summary": summary,
                           "views": rows}, fh, indent=1)

        def verify_png(into: Path) -> None:
            plot_field_verification(rows, into / "verify.png",
                                    f"ridged{' refraction' if refract else ''}: stereo "
                                    "verification")

        return Verification(lines, None, {"verify.json": verify_json, "verify.png": verify_png})

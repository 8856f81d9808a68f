"""A one-page, self-contained HTML report of a design: settings, fabrication, accuracy.

A flat plate's report reads its own ``hologram.json``; every other kind's
(:func:`write_report` with its :class:`~specholo.preview.source.PictureSource`)
shows the facts its source gives, every figure its ``verify.json`` holds, and
the pictures in its folder, animations included.
"""

from __future__ import annotations

import base64
import html
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open

if TYPE_CHECKING:
    from specholo.preview.source import PictureSource

#: Pictures shown when present in the design folder, with their captions.
PICTURES = (
    ("preview.png", "What one eye sees from three places on the viewing arc."),
    ("verify.png", "Stereo verification: apparent-point error and visibility by azimuth."),
    ("render.png", "Rendered still."),
    ("stereo.png", "Stereo pair."),
)


#: Pictures and animations shown when present in a folder of any other kind.
KIND_PICTURES = (
    ("preview.png", "The design's own preview."),
    ("preview.gif", "The design's own animation."),
    ("verify.png", "Verification by view."),
    ("render.png", "Rendered still (specholo render)."),
    ("stereo.png", "Stereo pair (specholo stereo)."),
    ("turntable.gif", "Walking past (specholo animate --kind turntable)."),
    ("turn.gif", "The plate turning (specholo animate --kind turn)."),
    ("light.gif", "The light moving (specholo animate --kind light)."),
)


def _img(path: Path) -> str:
    from specholo.readback import MAX_PICTURE_BYTES, read_bytes

    data = base64.b64encode(read_bytes(path, MAX_PICTURE_BYTES)).decode("ascii")
    kind = "gif" if path.suffix.lower() == ".gif" else "png"
    return f'<img alt="{html.escape(path.name)}" src="data:image/{kind};base64,{data}">'


def _rows(pairs: list[tuple[str, str]]) -> str:
    return "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>"
                   for k, v in pairs)


def fabrication_figures(info: dict[str, Any]) -> list[tuple[str, str]]:
    """Groove length, path count, extent and a cutting-time floor from hologram.json."""
    stats, settings = info["stats"], info["settings"]
    (x0, y0), (x1, y1) = info["plate"]["groove_extent_mm"]
    length = float(stats["groove_length_mm"])
    paths = int(stats["paths"])
    rows = [
        ("grooves (paths)", f"{paths:,}"),
        ("dimples", f"{int(stats['dots']):,}"),
        ("groove length", f"{length / 1000:.2f} m"),
        ("groove extent", f"{x1 - x0:.1f} × {y1 - y0:.1f} mm"),
    ]
    mach = info.get("machining")
    if isinstance(mach, dict) and "estimated_hours" in mach:
        # the design's own estimate, as its summary and hologram.json give it
        from specholo.fabrication.programs.timing import describe_machining

        # the row's label says machining; a machine, if any, stays ("on NAME (...): about ...")
        rows.append(("machining", describe_machining(mach, settings["feed"])
                     .removeprefix("machining").removeprefix(":").strip()))
    else:  # a folder written before the estimate was recorded: a floor
        minutes = length / settings["feed"] + paths * settings["depth"] / settings["plunge"]
        rows.append(("cutting time, feeds only", f"{minutes / 60:.1f} h"))
    expected = (info.get("expected") or {}).get("as_cut_stereo_visibility")
    if isinstance(expected, dict) and "mean" in expected:
        rows.append(("in both eyes as cut", f"about {expected['mean']:.0%} of the stipples "
                     f"(lowest {expected['lowest']:.0%})"))
    if "hidden_stipples" in stats:
        rows.append(("hidden from every view", f"{int(stats['hidden_stipples']):,} stipples "
                     "(no groove)"))
    thinned = stats.get("thinned_stipples")
    if thinned:
        # the thinning's own figures, as the design's summary gives them
        t = stats["thinning"]
        rows.append(("left uncut (thinned)", f"{len(thinned):,} stipples whose glints the "
                     "crossing grooves would take: "
                     f"{float(t['stereo_points_thinned']):.0f} stipples in both eyes per view "
                     f"as cut, not {float(t['stereo_points_all_cut']):.0f}"))
    plate = info["plate"].get("plate_mm")
    if plate:
        (px0, py0), (px1, py1) = plate
        rows.append(("plate", f"{px1 - px0:.0f} × {py1 - py0:.0f} × "
                              f"{info['plate']['stock_thickness_mm']} mm"))
    views = info.get("views")
    if views:
        lo, hi = views["needed_tilt_deg"]
        rows.append(("wall tilts needed", f"{lo:.1f}–{hi:.1f}°, views lost "
                                          f"{100 * views['views_lost']:.1f}%"))
    over = info.get("overlaps")
    if over:
        rows.append(("stripes cutting into each other", f"{over['neighbour_overlaps']:,}"))
        rows.append(("crossings between stipples", f"{over['crossings']:,}"))
    return rows


def write_report(folder: str | os.PathLike[str], verify: dict[str, Any] | None,
                 source: PictureSource | None = None) -> Path:
    """Write ``folder/report.html`` from the design's files.

    Args:
        folder: a design folder (with hologram.json).
        verify: the contents of verify.json, or None if not verified.
        source: the design as the picture commands see it; None (or a source
            without facts, the flat plate's) for the flat plate's report, read
            from its hologram.json.

    Returns:
        The report's path.

    Raises:
        SpecholoError: hologram.json or verify.json is unreadable, or lacks a
            figure the report shows (or holds one of the wrong type).
    """
    from specholo.readback import one_line, read_json

    folder = Path(folder)
    info = read_json(folder / "hologram.json")
    # The files may have been edited since they were written: whatever the page
    # cannot show is refused in one line, naming the key or the value.
    try:
        if source is None or source.facts is None:
            page = _page(folder, info, verify)
        else:
            page = _kind_page(folder, source.title, source.facts, verify)
    except KeyError as exc:
        raise SpecholoError(f"{folder}: hologram.json or verify.json lacks {exc.args[0]!r}, "
                            "which the report shows") from exc
    except (TypeError, ValueError, IndexError, AttributeError, ArithmeticError) as exc:
        raise SpecholoError(f"{folder}: hologram.json or verify.json holds a value the report "
                            f"cannot show: {one_line(exc)}") from exc
    out = folder / "report.html"
    with atomic_open(out) as fh:
        fh.write(page)
    return out


def _next_steps(folder: Path, info: Any, verify: Any) -> str:
    """The steps from this folder to a plate, as a list: verify if not yet,
    fewer stipples if little survives the cutting, then cut or scribe."""
    steps = []
    if verify is None:
        steps.append("Check it by simulating both eyes: <code>specholo verify "
                     f"{html.escape(str(folder))}</code> (<code>--cut</code> for the plate as "
                     "cut).")
    expected = (info.get("expected") or {}).get("as_cut_stereo_visibility")
    if isinstance(expected, dict) and expected.get("lowest", 1.0) < 0.6:
        steps.append(f"Only about {expected['lowest']:.0%} of the stipples survive the cutting "
                     "at the worst view: design again with <code>--visibility 0.6</code> (or "
                     "more) for the most stipples that keep that share.")
    if (folder / "hologram.gcode").is_file():
        steps.append("Fix the plate, zero the machine on it as the comment block at the top "
                     "of <code>hologram.gcode</code> says, and run the program (already read "
                     "back by the safety check; <code>specholo check "
                     f"{html.escape(str(folder / 'hologram.gcode'))}</code> re-checks it "
                     "against its own header).")
    if (folder / "hologram.svg").is_file():
        steps.append("For a laser or plotter: <code>hologram.svg</code> at 1:1, its PLATE "
                     "layer's outline and marks to align the plate.")
    if (folder / "pattern.pdf").is_file():
        steps.append("By hand: print <code>pattern.pdf</code> at 100% (its 50 mm bars check "
                     "the scale) and scribe each stroke or arc.")
    steps.append("Light the plate with one small light from the design's elevation and "
                 "walk past it.")
    return "<ol>" + "".join(f"<li>{s}</li>" for s in steps) + "</ol>"


def _page(folder: Path, info: Any, verify: Any) -> str:
    """The report's HTML from hologram.json and verify.json (None: not verified)."""
    settings = info["settings"]
    tool = info["tool"]
    setup_rows = [
        ("method", settings["method"]),
        ("stipples", f"{info['stats']['stipples']:,}"),
        ("model size, centre depth", f"{settings['size']} mm, z = {settings['center_z']} mm"),
        ("light", f"elevation {settings['light_elevation']}°, "
                  + ("sun" if settings["light_distance"] is None
                     else f"point at {settings['light_distance']} mm")),
        ("viewer", f"{settings['view_distance']} mm away, ±{settings['view_range']}°, "
                   f"eye height {settings['eye_height']} mm, IPD {settings['ipd']} mm"),
        ("tool", f"{tool['description']}, depth {tool['depth_mm']} mm, "
                 f"groove {tool['groove_width_mm']:.3f} mm wide"),
        ("software", f"specholo {info['specholo_version']}"),
    ]
    accuracy = "<p>Not verified yet: run <code>specholo verify</code>.</p>"
    if verify is not None:
        s = verify["summary"]
        light = verify.get("light")
        streaks = isinstance(light, dict)
        head = ("<tr><th>azimuth</th><th>median mm</th><th>p95 mm</th><th>p95 depth mm</th>"
                "<th>max mm</th><th>visibility</th><th>false glints</th>"
                + ("<th>end spills per eye</th><th>streak mm</th>" if streaks else "")
                + "</tr>")
        body = "".join(
            f"<tr><td>{r['azimuth']:+.1f}°</td><td>{r['median_error']:.3f}</td>"
            f"<td>{r['p95_error']:.3f}</td><td>{r['p95_depth_error']:.3f}</td>"
            f"<td>{r['max_error']:.3f}</td><td>{r['visibility']:.3f}</td>"
            f"<td>{r['false_glints']:.3f}</td>"
            + (f"<td>{r['end_spills']:.0f}</td><td>{r['streak_length']:.3f}</td>"
               if streaks else "") + "</tr>" for r in verify["azimuths"])
        worst = s["worst_p95_error"]
        under = ("each glint a point (a point light on a perfect mirror)" if not streaks else
                 f"each glint the streak a light {float(light['light_size']):.3g}° across "
                 f"makes on a surface of roughness {float(light['roughness']):g} (Beckmann "
                 f"alpha), with at most {float(s['max_end_spills']):.0f} false glints per eye "
                 "from stripe ends")
        accuracy = (
            f"<p>Worst 95th-percentile error {worst:.3f} mm "
            f"({'within' if worst <= 0.5 else 'beyond'} the ~0.5 mm a viewer's stereo acuity "
            f"resolves at 600 mm), lowest visibility {s['min_visibility']:.3f}, "
            f"most false glints {s['max_false_glints']:.3f}; verified from "
            f"<code>{html.escape(verify['source'])}</code>, {html.escape(under)}.</p>"
            f"<table class=num>{head}{body}</table>")
    pictures = "".join(
        f"<figure>{_img(folder / name)}<figcaption>{html.escape(text)}</figcaption></figure>"
        for name, text in PICTURES if (folder / name).is_file())
    page = _head(folder) + f"""<h2>Design</h2><table>{_rows(setup_rows)}</table>
<h2>Fabrication</h2><table>{_rows(fabrication_figures(info))}</table>
<h2>Accuracy, by head azimuth</h2>{accuracy}
<h2>What to do next</h2>{_next_steps(folder, info, verify)}
<h2>Pictures</h2>{pictures}
</body></html>
"""
    return page


def _label(key: str) -> str:
    """A verify.json key as a column's or a row's label: 'worst_p95_mm' ->
    'worst p95 mm'."""
    return key.replace("_", " ")


def _head(folder: Path) -> str:
    """The page's head and title, the same for every kind's report."""
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>specholo report: {html.escape(folder.name)}</title>
<style>
body {{ font: 15px/1.45 system-ui, sans-serif; max-width: 980px; margin: 2em auto;
       padding: 0 1em; color: #222; }}
h1 {{ font-size: 1.5em; }} h2 {{ font-size: 1.15em; margin-top: 1.6em; }}
table {{ border-collapse: collapse; margin: .5em 0; }}
th, td {{ padding: .2em .7em; border-bottom: 1px solid #ddd; text-align: left; }}
table.num td {{ text-align: right; font-variant-numeric: tabular-nums; }}
figure {{ margin: 1em 0; }} img {{ max-width: 100%; }}
figcaption {{ color: #666; font-size: .9em; }}
</style></head><body>
<h1>Specular hologram: {html.escape(folder.name)}</h1>
"""


def _table_cell(key: str, value: Any) -> str:
    """A figure of a verify.json row as the report prints it: angles signed in
    degrees, measures to a micrometre, counts whole, nothing measured as '-'."""
    if value is None:
        return "–"
    if isinstance(value, bool) or not isinstance(value, int | float):
        return html.escape(str(value))
    if key in ("azimuth", "elevation", "position") or key.endswith("_deg"):
        return f"{float(value):+.1f}°"
    if isinstance(value, int):
        return f"{value:,}"
    return f"{float(value):.3f}"


def _kind_accuracy(verify: Any) -> str:
    """Every figure a verify.json of any kind holds: its shared figures, its
    kind's summary and a row per verified position."""
    if not isinstance(verify, dict) or not isinstance(verify.get("summary"), dict):
        raise TypeError("verify.json holds no summary")
    summary = verify["summary"]
    key = verify.get("rows")
    rows = verify.get(key) if isinstance(key, str) else None
    if not isinstance(rows, list):
        raise TypeError("verify.json names no rows")
    figures = verify.get("figures")
    head = [("positions verified", f"{len(rows):,} {html.escape(_label(str(key)))}, every "
             f"{float(verify.get('step_deg', 0.0)):g}°")]
    head += [(_label(k), _table_cell(k, v)) for k, v in summary.items()]
    columns: list[str] = []
    for row in rows:
        for k in row:
            if k not in columns:
                columns.append(k)
    thead = "".join(f"<th>{html.escape(_label(k))}</th>" for k in columns)
    body = "".join("<tr>" + "".join(f"<td>{_table_cell(k, row.get(k))}</td>" for k in columns)
                   + "</tr>" for row in rows)
    lead = ""
    if isinstance(figures, dict):  # the figures every kind shares (not in older files)
        lead = (f"<p>Worst 95th-percentile error {_table_cell('worst', figures['worst_p95_mm'])} "
                f"mm, lowest visibility {_table_cell('lowest', figures['lowest_visibility'])} over "
                f"{_table_cell('positions', figures['positions'])} positions.</p>")
    rows_html = "".join(f"<tr><th>{k}</th><td>{v}</td></tr>" for k, v in head)
    return (f"{lead}<table>{rows_html}</table>"
            f"<table class=num><tr>{thead}</tr>{body}</table>")


def _kind_page(folder: Path, title: str, facts: list[tuple[str, str]], verify: Any) -> str:
    """The report of a design of any kind but the flat plate: its facts, its
    verification's figures and its pictures."""
    accuracy = ("<p>Not verified yet: run <code>specholo verify</code>.</p>"
                if verify is None else _kind_accuracy(verify))
    steps = []
    if verify is None:
        steps.append("Check it by simulating both eyes: <code>specholo verify "
                     f"{html.escape(str(folder))}</code>.")
    steps.append("Look at it before cutting: <code>specholo render</code>, "
                 "<code>stereo</code>, <code>animate</code> and <code>view</code> draw it "
                 "from the same glints as its verification.")
    for name, what in (("hologram.gcode", "the program that cuts it, read back by the "
                                          "safety check before it was kept (its header "
                                          "says how to set it up)"),
                       ("relief.gcode", "the second pass, with the V-bit its header names, "
                                        "that cuts the unused walls away"),
                       ("hologram.svg", "the grooves at 1:1 for a laser or plotter"),
                       ("hologram.stl", "the plate as a mesh")):
        if (folder / name).is_file():
            steps.append(f"<code>{name}</code>: {what}.")
    pictures = "".join(
        f"<figure>{_img(folder / name)}<figcaption>{html.escape(text)}</figcaption></figure>"
        for name, text in KIND_PICTURES if (folder / name).is_file())
    return _head(folder) + f"""<p>{html.escape(title[0].upper() + title[1:])}.</p>
<h2>Design</h2><table>{_rows(facts)}</table>
<h2>Accuracy</h2>{accuracy}
<h2>What to do next</h2><ol>{"".join(f"<li>{s}</li>" for s in steps)}</ol>
<h2>Pictures</h2>{pictures}
</body></html>
"""

"""A test coupon's sheet (``sheet.pdf``): the card at 1:1 and, for every glint,
from where it must show and where on the card.

The first page (A4 landscape) draws the card at true size, as seen from in
front: its outline and plate marks, the grooves, each rung's number and
setting, the label dots, and each stipple's glint track (where its glint
runs across the card as the eye moves through its window) with its letter;
beside it, how to light and look at the card, how to judge a rung, and how to
carry the chosen setting into the long job. The second page (A4 portrait)
lists, rung by rung, each stipple's window: from which azimuths its glint
must show (and where the eye stands for them), where on the card it runs, and
beyond which azimuths it must be dark.

It reads only what ``coupon.json`` holds and the card's grooves, so a folder's
sheet is drawn again the same from its files.
"""

from __future__ import annotations

import math
import os
import textwrap
from collections.abc import Iterator
from typing import Any

import numpy as np
from matplotlib import rc_context
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from specholo.fabrication.drawings.paper import write_pdf
from specholo.fabrication.plate import Plate
from specholo.toolpaths.grooves import Grooves

#: Paper (width, height), mm: the plan's page is landscape, the table's portrait.
LANDSCAPE = (297.0, 210.0)
PORTRAIT = (210.0, 297.0)
#: Page margin, mm.
MARGIN = 15.0
#: Length of the scale bar under the card, mm.
SCALE_BAR = 50.0
#: Colours of a rung's stipples a..e (a colour-blind safe set).
COLOURS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00")
_FONT = "DejaVu Sans"


def _figure(size: tuple[float, float]) -> Figure:
    """A page of the paper's size (mm), 72 dpi (display units are PDF points)."""
    return Figure(figsize=(size[0] / 25.4, size[1] / 25.4), dpi=72)


def _polylines(grooves: Grooves) -> list[np.ndarray]:
    """Each path as a polyline, its arcs drawn as chords every 5 degrees or less."""
    out = []
    v, b, o = grooves.vertices, grooves.bulges, grooves.offsets
    for j in range(grooves.n_paths):
        pts = [v[o[j]]]
        for k in range(o[j], o[j + 1] - 1):
            p, q, bulge = v[k], v[k + 1], float(b[k])
            sweep = 4.0 * math.atan(bulge)  # signed, counter-clockwise positive
            chord = q - p
            length = float(np.hypot(*chord))
            steps = int(abs(sweep) / math.radians(5.0))
            if steps >= 1 and length > 0:
                # the centre lies left of the chord for a counter-clockwise arc
                left = np.array([-chord[1], chord[0]]) / length
                centre = 0.5 * (p + q) + left * 0.25 * length * (1.0 - bulge * bulge) / bulge
                radius = float(np.hypot(*(p - centre)))
                a0 = math.atan2(p[1] - centre[1], p[0] - centre[0])
                for t in np.linspace(0.0, 1.0, steps + 2)[1:-1]:
                    a = a0 + t * sweep
                    pts.append(centre + radius * np.array([math.cos(a), math.sin(a)]))
            pts.append(q)
        out.append(np.asarray(pts))
    return out


def _light_words(viewing: dict[str, Any]) -> str:
    light = viewing["light"]
    elevation = float(light["elevation_deg"])
    where = (f"straight above the card's centre line, {elevation:g} deg out from its face "
             "(90 would be straight in front)")
    distance = light.get("distance_mm")
    what = ("one small bright light far away (the sun, or an LED a few metres off)"
            if distance is None else f"one small bright light {float(distance):g} mm from the "
                                     "card's centre")
    return f"Light: {what}, {where}, in a dark room."


def _texts(info: dict[str, Any]) -> list[tuple[str, str]]:
    """The plan page's text blocks: (heading, body)."""
    viewing = info["viewing"]
    settings = info["settings"]
    rungs = info["rungs"]
    name = "preload" if settings["holder"] == "spring" else "depth"
    distance = float(viewing["eye_distance_mm"])
    stipples = int(settings["stipples"])
    last = "abcde"[stipples - 1]
    far = rungs[0]["stipples"][0]
    ladder = ", ".join(f"{v:g}" for v in settings["ladder_mm"])
    tool = info["tool"]
    height = float(viewing["eye_height_mm"])
    level = ("level with the card's centre" if height == 0 else
             f"{abs(height):g} mm {'above' if height > 0 else 'below'} the card's centre")
    look = (f"{_light_words(viewing)} Eye: one eye, the other closed, {level} and "
            f"{distance:.0f} mm from the card's vertical centre line. An azimuth is the eye's "
            "angle about that line, to the right of straight in front (negative: to the "
            f"left): at {far['shows_deg'][0]:g} deg the eye stands {abs(far['eye_from_mm'][0]):.0f}"
            f" mm to the {'left' if far['eye_from_mm'][0] < 0 else 'right'} and "
            f"{far['eye_from_mm'][1]:.0f} mm out. Move the eye along that arc from left to "
            f"right: in every rung the glints a to {last} light up one after another, each only "
            "from its own window (page 2), running across the card as the eye moves (the "
            "coloured lines here) and stepping back a hair where one stroke hands over to the "
            "next.")
    judge = (f"A rung passes when every glint a to {last} shows from the whole of its window: "
             "one bright, sharp point (not a smear, not a sparkle of several) where the sheet "
             "says, within about a millimetre, and is dark from half a degree beyond it. The "
             f"windows at the ends (a and {last}) need the steepest groove walls: a rung cut "
             f"too shallow (too little {name}) loses them first, dim or gone. One cut too deep "
             "(too much) makes wide, rough grooves whose glints smear or break up. The rung "
             "numbers are engraved below the rungs as dots (rung 3: three dots), which glint "
             "from everywhere.")
    if settings["holder"] == "spring":
        carry = (f"Ladder of preloads {ladder} mm, the spring holder touched off on the card "
                 "as the program's header says. Take the middle one of the rungs that pass "
                 "(their setting is printed above each rung): design the long job with the "
                 f"same options and its --preload (page 2 gives the option). The grooves are "
                 f"expected to be {tool['depth_mm']:g} mm deep there. If no rung or every rung "
                 "passes, cut another coupon with a ladder moved that way (--preloads).")
    else:
        carry = (f"Ladder of depths {ladder} mm, a rigid holder: each rung's depth is below "
                 "Z0, so probe and level the card first (specholo probe and specholo level on "
                 "this folder) or the plate's own height error adds to every rung. Take the "
                 "middle one of the rungs that pass: design the long job with --holder rigid "
                 "and its --depth (page 2 gives the option), and probe and level that plate "
                 "too. If no rung or every rung passes, cut another coupon with a ladder "
                 "moved that way (--depths).")
    return [("How to look", look), ("How to judge a rung", judge), ("Then", carry)]


#: The enlarged plan's scale (the card twice its size, its tracks and letters legible).
ENLARGED = 2.0


def _card(fig: Figure, size: tuple[float, float], info: dict[str, Any], grooves: Grooves,
          at: tuple[float, float], scale: float) -> None:
    """The card drawn at ``scale`` (1: true size), its lower left ``at`` (mm on
    the page): outline and plate marks, grooves, label dots, each stipple's
    track in its colour; enlarged, the letters and each rung's number and
    setting too."""
    box = np.asarray(info["card"]["plate_mm"], dtype=float)
    width, height = box[1] - box[0]
    ax = fig.add_axes((at[0] / size[0], at[1] / size[1], scale * width / size[0],
                       scale * height / size[1]))
    ax.set_xlim(box[0, 0], box[1, 0])
    ax.set_ylim(box[0, 1], box[1, 1])
    ax.set_axis_off()
    plate = Plate.from_corners(box)
    outline = np.vstack([plate.corners(), plate.corners()[:1]])
    ax.plot(outline[:, 0], outline[:, 1], color="black", lw=0.6, clip_on=False)
    arm, radius = plate.mark_arm, plate.mark_radius
    t = np.linspace(0, 2 * np.pi, 49)
    for cx, cy in plate.marks():
        ax.plot([cx - arm, cx + arm], [cy, cy], color="#5DADE2", lw=0.3)
        ax.plot([cx, cx], [cy - arm, cy + arm], color="#5DADE2", lw=0.3)
        ax.plot(cx + radius * np.cos(t), cy + radius * np.sin(t), color="#5DADE2", lw=0.3)
    lines = [p for p in _polylines(grooves) if len(p) > 1]
    ax.add_collection(LineCollection(lines, colors="#444444", linewidths=0.3 * scale))
    dots = grooves.vertices[grooves.offsets[:-1][grooves.is_dot]]
    ax.scatter(dots[:, 0], dots[:, 1], s=0.6 * scale * scale, color="black", lw=0)
    name = "preload" if info["settings"]["holder"] == "spring" else "depth"
    for rung in info["rungs"]:
        x = float(rung["x_mm"])
        label = f"{rung['rung']}" if scale == 1 else f"{rung['rung']}\n{rung[name + '_mm']:g}"
        ax.text(x, box[1, 1] + 1.0 / scale, label, ha="center", va="bottom",
                fontsize=6 if scale == 1 else 7, clip_on=False)
        for k, st in enumerate(rung["stipples"]):
            track = np.asarray(st["track"], dtype=float)
            colour = COLOURS[k % len(COLOURS)]
            ax.plot(track[:, 1], track[:, 2], color=colour, lw=0.5 * scale, alpha=0.8)
            if scale > 1:
                ax.text(track[:, 1].min() - 0.3, float(np.median(track[:, 2])), st["letter"],
                        ha="right", va="center", fontsize=6, color=colour)


def _plan_page(info: dict[str, Any], grooves: Grooves) -> Figure:
    size = LANDSCAPE
    fig = _figure(size)
    settings = info["settings"]
    box = np.asarray(info["card"]["plate_mm"], dtype=float)
    width, height = box[1] - box[0]
    name = "preload" if settings["holder"] == "spring" else "depth"
    left = ENLARGED * max(width, SCALE_BAR)  # the left column's width, mm
    title = (f"specholo test coupon: {len(info['rungs'])} rungs of {name} "
             f"{', '.join(f'{v:g}' for v in settings['ladder_mm'])} mm, "
             f"{settings['holder']} holder, {info['tool']['description']}")
    fig.text(MARGIN / size[0], 1 - MARGIN / size[1], "\n".join(textwrap.wrap(title, 110)),
             fontsize=10, va="top", weight="bold")
    y = size[1] - MARGIN - 14
    fig.text(MARGIN / size[0], y / size[1], "The card at 1:1, seen from in front "
             f"({width:g} x {height:g} mm; check the {SCALE_BAR:g} mm bar with a ruler):",
             fontsize=7.5, va="top")
    at = (MARGIN, y - 8 - height)
    _card(fig, size, info, grooves, at, 1.0)
    bar = fig.add_axes((at[0] / size[0], (at[1] - 7) / size[1], SCALE_BAR / size[0],
                        3 / size[1]))
    bar.set_xlim(0, SCALE_BAR)
    bar.set_ylim(0, 3)
    bar.set_axis_off()
    bar.plot([0, SCALE_BAR], [1, 1], color="black", lw=0.8)
    for x in (0, SCALE_BAR):
        bar.plot([x, x], [0, 2], color="black", lw=0.8)
    bar.text(0.5 * SCALE_BAR, 1.6, f"{SCALE_BAR:g} mm", ha="center", va="bottom", fontsize=6)
    machining = info["machining"]
    machine = machining.get("machine")
    on = f" on the {machine['name']}" if isinstance(machine, dict) else ""
    minutes = 60.0 * float(machining["estimated_hours"])
    beside = (f"Cut by hologram.gcode in about {max(1, round(minutes))} min{on} (the "
              "estimate); hologram.svg is the same card. Positions are mm from the card's "
              "centre, the origin mark: x to the right, y up.")
    x_note = MARGIN + max(width, SCALE_BAR) + 6
    fig.text(x_note / size[0], (at[1] + height) / size[1],
             "\n".join(textwrap.wrap(beside, int((left - x_note + MARGIN) / 1.5))),
             fontsize=7, va="top", linespacing=1.35)
    y = at[1] - 14
    caption = (f"Enlarged {ENLARGED:g}:1: each rung's number and {name} (mm) above it, its "
               f"glints a to {'abcde'[int(settings['stipples']) - 1]} from the top, each along "
               "its coloured line as the eye moves from left to right.")
    fig.text(MARGIN / size[0], y / size[1], "\n".join(textwrap.wrap(caption, int(left / 1.5))),
             fontsize=7, va="top", linespacing=1.35)
    _card(fig, size, info, grooves, (MARGIN, y - 16 - ENLARGED * height), ENLARGED)
    # the text in the right column
    x_text = MARGIN + left + 10
    y = size[1] - MARGIN - 14
    chars = int((size[0] - MARGIN - x_text) / 1.55)
    for heading, body in _texts(info):
        fig.text(x_text / size[0], y / size[1], heading, fontsize=9, weight="bold", va="top")
        y -= 5
        wrapped = textwrap.wrap(body, chars)
        fig.text(x_text / size[0], y / size[1], "\n".join(wrapped), fontsize=7.5, va="top",
                 linespacing=1.35)
        y -= 3.6 * len(wrapped) + 5
    return fig


def _rows(info: dict[str, Any]) -> Iterator[tuple[str, bool]]:
    """The table page's lines: (text, whether it heads a rung)."""
    settings = info["settings"]
    name = "preload" if settings["holder"] == "spring" else "depth"
    distance = float(info["viewing"]["eye_distance_mm"])
    for rung in info["rungs"]:
        dots = f"{rung['rung']} dot" + ("s" if rung["rung"] > 1 else "")
        yield (f"Rung {rung['rung']} ({dots}): {name} {rung[name + '_mm']:g} mm, "
               f"cuts at Z{rung['cut_z_mm']:g}; carried into the long job as "
               f"specholo design ... {rung['design_option']}", True)
        for s in rung["stipples"]:
            a, b = s["shows_deg"]
            track = np.asarray(s["track"], dtype=float)
            first = track[track[:, 0] == track[:, 0].min()][0]
            last = track[track[:, 0] == track[:, 0].max()][-1]
            mid = s["glint_at_middle_mm"]
            ex0, ez0 = s["eye_from_mm"]
            ex1, ez1 = s["eye_to_mm"]
            lo, hi = s["dark_beyond_deg"]
            yield (f"  {s['letter']}: from azimuth {a:+.2f} to {b:+.2f} deg at {distance:.0f} mm "
                   f"(eye {ex0:+.0f} to {ex1:+.0f} mm across, {ez0:.0f} to {ez1:.0f} mm out) the "
                   f"glint is at x {first[1]:+.2f} y {first[2]:+.2f}, through x {mid[0]:+.2f} "
                   f"y {mid[1]:+.2f}, to x {last[1]:+.2f} y {last[2]:+.2f}; dark below "
                   f"{lo:+.1f} and above {hi:+.1f} deg", False)


def _table_pages(info: dict[str, Any]) -> Iterator[Figure]:
    size = PORTRAIT
    rows = list(_rows(info))
    band = info["tool"].get("band_mm")
    intro = ("Every glint, rung by rung. Positions are mm from the card's centre (x right, y "
             "up), where the glint is when the eye is at the window's first azimuth, its "
             "middle and its last; between them it moves along the coloured line of page 1, "
             "within the stripes' band "
             + (f"({float(band):g} mm) " if band is not None else "")
             + "of the sightline vertically. coupon.json holds every step of the way "
               f"({info['track_step_deg']:g} deg apart).")
    per_page = 64
    chars = int((size[0] - 2 * MARGIN) / 1.45)
    lines: list[tuple[str, bool]] = []
    for text, head in rows:
        wrapped = textwrap.wrap(text, chars, subsequent_indent="      ")
        lines += [(w, head) for w in wrapped]
    for page in range(max(1, math.ceil(len(lines) / per_page))):
        fig = _figure(size)
        y = size[1] - MARGIN
        if page == 0:
            fig.text(MARGIN / size[0], y / size[1], "Where each glint must show", fontsize=11,
                     weight="bold", va="top")
            y -= 7
            wrapped = textwrap.wrap(intro, chars)
            fig.text(MARGIN / size[0], y / size[1], "\n".join(wrapped), fontsize=7.5, va="top",
                     linespacing=1.35)
            y -= 3.6 * len(wrapped) + 4
        for text, head in lines[page * per_page:(page + 1) * per_page]:
            if head:
                y -= 1.5
            fig.text(MARGIN / size[0], y / size[1], text, fontsize=7,
                     weight="bold" if head else "normal", va="top", family="DejaVu Sans Mono"
                     if not head else _FONT)
            y -= 3.5
        yield fig


def write_sheet(path: str | os.PathLike[str], info: dict[str, Any], grooves: Grooves) -> None:
    """Write a coupon's sheet as a PDF, atomically (its pages at the paper's
    size, for 1:1 printing; no date, so the same coupon gives the same file).

    Args:
        path: the ``.pdf`` file.
        info: what the coupon's ``coupon.json`` holds.
        grooves: the card's grooves.
    """
    def figures() -> Iterator[Figure]:
        with rc_context({"font.family": _FONT}):
            yield _plan_page(info, grooves)
            yield from _table_pages(info)

    write_pdf(path, "specholo test coupon", figures())


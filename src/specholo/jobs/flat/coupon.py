"""A test coupon (``specholo coupon``): a small card cut before the long job, to
find the depth (a rigid holder) or preload (a spring holder) at which the
grooves glint where they should.

The card holds a ladder of *rungs* side by side, each cut at one setting of the
ladder. Every rung draws the same simple target, needing no model: a column of
3 to 5 points a few millimetres behind the card, one above the other, each
designed with the striped method of ``specholo design``
(:func:`~specholo.jobs.flat.design.design_runs`) for its own *window* of eye
azimuths, the windows spread over the design's viewing range. Seen with one
eye moving along the viewing arc, each rung's glints light up one after
another, each only from its window, and the windows
at the ends of the range need the steepest groove walls: a rung cut too
shallow loses them first. Below each rung its number is engraved as a row of
dots (rung 3: three dots), which glint from everywhere, so a card parted from
its sheet still says which rung is which.

Where the glints show is found on the designed grooves by the glint finder
:func:`specholo.verify` uses (:func:`~specholo.simulation.glints.find_glints`),
every :data:`TRACK_STEP` degrees over each window: its *track*, written into
``coupon.json`` and, in words, onto the sheet (``sheet.pdf``). The glint's
place for an azimuth between two rows of the track is found on the stroke that
shows it, linearly between (or just beyond) that stroke's rows
(:func:`sheet_positions`): the glint follows the sightline across the card and
steps back a band's height where one stroke hands over to the next.

The card is cut by one program (the flat design's writer and dialects, each
rung at its own Z, read back by the safety check before it is kept), and its
machining time, estimated on the chosen machine, must be at most
:data:`MAX_MINUTES`.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from specholo import __version__
from specholo.errors import SpecholoError
from specholo.fabrication.plate import Plate
from specholo.jobs.flat.settings import DesignConfig
from specholo.setup import PRELOAD_RANGE, Machining
from specholo.toolpaths.grooves import Grooves

#: Longest machining time of a coupon, minutes: a coupon is cut first, before
#: the long job, in the same evening.
MAX_MINUTES = 15.0
#: Largest card, mm (width, height): a rung column of 10 mm for 5 rungs, a 5 mm
#: border for the plate marks all round.
CARD = (60.0, 40.0)
#: Blank border of the card, mm (the plate marks reach 4 mm in).
BORDER = 5.0
#: Widest rung column, mm (fewer rungs make a narrower card).
PITCH = 10.0
#: Rungs and stipples a rung: (fewest, most, default).
RUNGS = (2, 9, 5)
STIPPLES = (3, 5, 5)
#: Each stipple's window of eye azimuths, degrees (default), and the least gap
#: between two windows: the glint must be dark in it for the sheet's "nowhere
#: else" to be seen.
WINDOW = 10.0
MIN_GAP = 2.0
#: How far the target points lie behind the card, mm: (least, most, default).
#: At 10 mm a glint crosses its rung by about 3 mm over a 10 degree window at
#: the ends of a +-45 degree range, which fits a 10 mm column.
BEHIND = (1.0, 40.0, 10.0)
#: Steps of the ladder when none is given, mm: a rigid holder's depth by two
#: fifths of the depth allowance (five rungs span 0.008 mm about the depth the
#: design chooses, the lowest still above the shallowest its windows need: a
#: plate a few micrometres off its Z shifts which rung passes), a spring
#: holder's preload by 0.1 mm (five rungs span 0.1-0.5 mm about the default
#: 0.3, the 0.25-0.5 mm that drag bits' makers give and a little less).
LADDER_STEP = {"rigid": 0.002, "spring": 0.1}
#: Step between the rows of a glint's track, degrees.
TRACK_STEP = 0.1
#: Beyond its window by this much, degrees, a glint must be dark (the groove
#: ends where the window does; its end shows a few hundredths of a degree on).
DARK_MARGIN = 0.5
#: How near its sheet's place a glint must be found, mm.
ON_THE_SHEET = 0.05
#: Distance between the dots of a rung's number, mm (resolved apart at 600 mm).
LABEL_PITCH = 0.5
#: Where the label dots sit below the lowest stipple, mm.
LABEL_DROP = 5.0
#: The heights of a rung's stipples by their number, from the top, mm above the
#: card's centre: 2 mm or more clear of the origin, where the plate is touched
#: off or probed (the labels go below the bottom one).
ROWS = {3: (13.0, 3.0, -7.0), 4: (13.0, 6.0, -3.0, -9.0), 5: (13.0, 8.0, 3.0, -2.0, -7.0)}
#: Letters naming a rung's stipples from the top.
LETTERS = "abcde"
#: The options of the coupon itself (the rest are ``specholo design``'s).
OWN_OPTIONS = ("rungs", "depths", "preloads", "step", "stipples", "window", "behind")


@dataclass(frozen=True)
class CouponConfig:
    """What a coupon is cut with and what it tries.

    Attributes:
        design: the long job's settings (light, views, tool, holder, feeds,
            machine, program); its depth is the ladder's middle (rigid) or the
            depth the grooves are expected to have (spring).
        ladder: each rung's setting, mm: depths (rigid) or preloads (spring).
        stipples: stipples a rung.
        window: each stipple's window of eye azimuths, degrees.
        behind: how far the target points lie behind the card, mm.
    """

    design: DesignConfig
    ladder: tuple[float, ...]
    stipples: int = STIPPLES[2]
    window: float = WINDOW
    behind: float = BEHIND[2]

    @property
    def holder(self) -> str:
        """``rigid`` or ``spring``."""
        return str(self.design.holder)

    @property
    def rungs(self) -> int:
        return len(self.ladder)

    @property
    def setting_name(self) -> str:
        """What the ladder varies, in a word."""
        return "depth" if self.holder == "rigid" else "preload"

    def rung_config(self, r: int) -> DesignConfig:
        """The design settings rung ``r`` is cut with (``specholo design`` takes
        the same with the rung's ``--depth`` or ``--preload``)."""
        if self.holder == "rigid":
            return dataclasses.replace(self.design, depth=self.ladder[r])
        return dataclasses.replace(self.design, preload=self.ladder[r])

    def option(self, r: int) -> str:
        """The ``specholo design`` option that carries rung ``r``'s setting."""
        v = f"{self.ladder[r]:g}"
        return f"--holder rigid --depth {v}" if self.holder == "rigid" else f"--preload {v}"

    def card(self) -> tuple[float, float]:
        """The card's width and height, mm."""
        return min(CARD[0], PITCH * self.rungs + 2.0 * BORDER), CARD[1]

    def saved(self) -> dict[str, Any]:
        """The settings as ``coupon.json`` records them (:meth:`from_saved` reads them)."""
        return {"design": asdict(self.design), "holder": self.holder,
                "ladder_mm": list(self.ladder), "stipples": self.stipples,
                "window_deg": self.window, "behind_mm": self.behind}

    @classmethod
    def from_saved(cls, saved: Any) -> CouponConfig:
        """The settings ``coupon.json`` recorded, checked as any coupon's are."""
        from specholo.readback import number, table, whole

        s = table(saved, "settings")
        ladder = s["ladder_mm"]
        if not isinstance(ladder, list):
            raise SpecholoError("settings.ladder_mm must be a list of numbers")
        config = cls(DesignConfig.from_saved(dict(table(s["design"], "settings.design"))),
                     tuple(number(v, "ladder_mm") for v in ladder),
                     whole(s["stipples"], "stipples"), number(s["window_deg"], "window_deg"),
                     number(s["behind_mm"], "behind_mm"))
        config.check()
        return config

    @classmethod
    def from_options(cls, values: Mapping[str, Any]) -> CouponConfig:
        """The coupon from the command's options (``specholo design``'s names for
        the long job's settings, and :data:`OWN_OPTIONS`), its ladder filled in
        around the depth or preload given (or the design's own) and checked."""
        given = {k.replace("-", "_"): v for k, v in values.items() if v is not None}
        own = {k: given.pop(k) for k in OWN_OPTIONS if k in given}
        design = DesignConfig.from_dict(given)
        if design.method != "striped":
            raise SpecholoError("a coupon's stipples are striped, as specholo design's: leave "
                                "out --method")
        _check_machine(design)
        rungs = _whole(own.get("rungs", RUNGS[2]), "rungs", RUNGS)
        stipples = _whole(own.get("stipples", STIPPLES[2]), "stipples", STIPPLES)
        window = _finite(own.get("window", WINDOW), "window")
        behind = _finite(own.get("behind", BEHIND[2]), "behind")
        rigid = design.holder == "rigid"
        wrong, right = ("preloads", "depths") if rigid else ("depths", "preloads")
        if wrong in own:
            raise SpecholoError(f"a {design.holder} holder's ladder is of {right}: use "
                                f"--{right}, or --holder {'spring' if rigid else 'rigid'}")
        given_ladder = own.get(right)
        if given_ladder is not None and ("step" in own or "rungs" in own):
            raise SpecholoError(f"--{right} lists every rung: leave out --rungs and --step")
        ladder = None if given_ladder is None else _numbers(given_ladder, right)
        # the card as it will be (its rungs place the points, which set the
        # tilts), to find the depth the design would choose for its views: a
        # rigid ladder's middle, the depth a spring holder's grooves are expected to have
        count = rungs if ladder is None else len(ladder)
        probe = cls(design, tuple(float(k + 1) for k in range(count)), stipples, window, behind)
        probe.check_geometry()
        if design.depth is None:
            design = dataclasses.replace(design, depth=_auto_depth(probe))
        if ladder is None:
            step = _finite(own.get("step", LADDER_STEP[design.holder or "rigid"]), "step")
            if not step > 0:
                raise SpecholoError(f"step must be a positive number of mm, got {step:g}")
            ladder = _ladder(design, rungs, step, _least_depth(probe) if rigid else 0.0)
        config = cls(design, tuple(ladder), stipples, window, behind)
        config.check()
        return config

    def check_geometry(self) -> None:
        """Refuse a card the rungs, windows or target do not fit."""
        lo, hi, _ = RUNGS
        if not lo <= self.rungs <= hi:
            raise SpecholoError(f"a coupon has {lo} to {hi} rungs, got {self.rungs}")
        lo, hi, _ = STIPPLES
        if not lo <= self.stipples <= hi:
            raise SpecholoError(f"a rung has {lo} to {hi} stipples, got {self.stipples}")
        near, far, _ = BEHIND
        if not near <= self.behind <= far:
            raise SpecholoError(f"behind must be in [{near:g}, {far:g}] mm, got "
                                f"{self.behind:g}")
        half = self.design.view_range
        most = (2.0 * half - MIN_GAP * (self.stipples - 1)) / self.stipples
        if not 1.0 <= self.window <= most:
            raise SpecholoError(
                f"window {self.window:g} deg does not fit: {self.stipples} windows of 1 to "
                f"{max(most, 1.0):.1f} deg fit in the view range +-{half:g} deg, "
                f"{MIN_GAP:g} deg apart")

    def check(self) -> None:
        """Refuse a coupon that cannot be cut as asked: its geometry, and a
        ladder whose rungs repeat, a tool cannot cut, or (rigid) whose walls
        cannot serve every window."""
        self.check_geometry()
        _check_machine(self.design)
        if len(set(self.ladder)) != len(self.ladder):
            raise SpecholoError(f"the ladder's {self.setting_name}s must differ, got "
                                f"{', '.join(f'{v:g}' for v in self.ladder)}")
        thick = self.design.stock_thickness
        for v in self.ladder:
            if v >= thick:
                raise SpecholoError(f"{self.setting_name} {v:g} mm cuts at a Z below the "
                                    f"plate's {thick:g} mm thickness")
        if self.holder == "spring":
            lo, hi = PRELOAD_RANGE
            for v in self.ladder:
                if not lo <= v <= hi:
                    raise SpecholoError(f"preload {v:g} mm is out of range: it must be in "
                                        f"[{lo:g}, {hi:g}] mm of spring compression")
            return
        least = _least_depth(self)
        for v in self.ladder:
            self.design.cutter().check_depth(v)
            if v < least - 1e-9:
                raise SpecholoError(f"depth {v:g} mm is too shallow for the coupon's windows: "
                                    f"their steepest glint needs a {least:g} mm groove "
                                    f"({self.design.cutter().describe()})")


def _check_machine(design: DesignConfig) -> None:
    """Refuse a tool or machine with no Z to ladder."""
    if design.tool == "laser" or design.holder is None:
        raise SpecholoError("a coupon ladders a holder's depth or preload: a laser has none "
                            "(its depth is set by power and feed)")
    profile = design.profile
    if profile is not None and not profile.has_z:
        raise SpecholoError(f"a coupon ladders a Z, and the {profile.name} ({profile.title}) "
                            "has none: use grbl-router or linuxcnc-mill")


def _whole(value: Any, name: str, bounds: tuple[int, int, int]) -> int:
    lo, hi, _ = bounds
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise SpecholoError(f"{name} must be a whole number in [{lo}, {hi}], got {value!r}")
    return value


def _finite(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(float(value)):
        raise SpecholoError(f"{name} must be a finite number, got {value!r}")
    return float(value)


def _numbers(values: Any, name: str) -> list[float]:
    """A ladder given as a list, or as text "0.1,0.2,0.3"."""
    if isinstance(values, str):
        try:
            values = [float(v) for v in values.replace(" ", "").split(",") if v]
        except ValueError as exc:
            raise SpecholoError(f"--{name} must be numbers of mm separated by commas, got "
                                f"{values!r}") from exc
    if not isinstance(values, list | tuple) or not values:
        raise SpecholoError(f"--{name} must list the rungs' {name}, mm")
    out = [_finite(v, name) for v in values]
    if not all(v > 0 for v in out):
        raise SpecholoError(f"--{name} must be positive numbers of mm")
    return out


def _ladder(design: DesignConfig, rungs: int, step: float, least: float) -> list[float]:
    """``rungs`` settings ``step`` apart about the design's own: a rigid holder's
    depth (raised to start no shallower than ``least``), a spring holder's
    preload (lowered or raised to lie within its range)."""
    if design.holder == "rigid":
        middle, lo, hi = design.depth_mm, least, math.inf
    else:
        middle, (lo, hi) = float(design.preload or 0.0), PRELOAD_RANGE
        hi = min(hi, design.stock_thickness)
    first = middle - 0.5 * (rungs - 1) * step
    first = min(max(first, lo), hi - (rungs - 1) * step)
    # to a tenth of a micrometre: the written Z's own grid is 0.01 um
    return [round(first + k * step, 4) for k in range(rungs)]


# ---------------------------------------------------------------- the card


@dataclass(frozen=True)
class Layout:
    """Where a coupon's rungs and stipples lie on its card (plate mm).

    Attributes:
        corners: (2, 2) the card's corners.
        rung_x: (R,) each rung's centre line.
        rows_y: (S,) where each stipple's glint crosses its rung, from the top.
        windows: (S, 2) each stipple's window of eye azimuths, degrees.
        label_y: the height of the rungs' label dots.
        points: (R * S, 3) the target points, rung by rung (stipple id
            r * S + i is rung r's stipple i).
        labels: (L, 2) the label dots, rung by rung (ids R * S on).
        label_rung: (L,) the rung of each label dot.
    """

    corners: np.ndarray
    rung_x: np.ndarray
    rows_y: np.ndarray
    windows: np.ndarray
    label_y: float
    points: np.ndarray
    labels: np.ndarray
    label_rung: np.ndarray

    @property
    def targets(self) -> int:
        return len(self.points)

    def rung_of(self, ids: np.ndarray) -> np.ndarray:
        """The rung of each stipple or label id."""
        ids = np.asarray(ids, dtype=np.int64)
        per = len(self.rows_y)
        label = np.clip(ids - self.targets, 0, max(len(self.label_rung) - 1, 0))
        return np.where(ids < self.targets, ids // per,
                        self.label_rung[label] if len(self.label_rung) else 0)


def layout(config: CouponConfig) -> Layout:
    """The card: rungs side by side, each stipple's point placed so that its
    glint crosses the rung's centre line at its row's height when the eye is
    in the middle of its window (eyes on the viewer's circle, as designed)."""
    width, height = config.card()
    rungs, n = config.rungs, config.stipples
    pitch = (width - 2.0 * BORDER) / rungs
    rung_x = -0.5 * width + BORDER + pitch * (np.arange(rungs) + 0.5)
    rows_y = np.array(ROWS[n])
    half = config.design.view_range
    w = config.window
    centres = np.linspace(-half + 0.5 * w, half - 0.5 * w, n)
    windows = np.stack([centres - 0.5 * w, centres + 0.5 * w], axis=1)
    viewer = config.design.setup().viewer
    eye = viewer.eye(np.radians(centres))  # (S, 3)
    d = config.behind
    # the sightline from the eye e through p = (px, py, -d) meets the card at
    # p + t (e - p) with t = d / (d + e_z): solved for p given where it meets it
    t = d / (d + eye[:, 2])
    points = np.empty((rungs * n, 3))
    for r, x in enumerate(rung_x):
        rows = slice(r * n, (r + 1) * n)
        points[rows, 0] = (x - t * eye[:, 0]) / (1.0 - t)
        points[rows, 1] = (rows_y - t * eye[:, 1]) / (1.0 - t)
        points[rows, 2] = -d
    label_y = float(rows_y[-1] - LABEL_DROP)
    labels, label_rung = [], []
    for r, x in enumerate(rung_x):
        k = r + 1
        labels += [[x + (j - 0.5 * (k - 1)) * LABEL_PITCH, label_y] for j in range(k)]
        label_rung += [r] * k
    corners = np.array([[-0.5 * width, -0.5 * height], [0.5 * width, 0.5 * height]])
    return Layout(corners, rung_x, rows_y, windows, label_y, points,
                  np.asarray(labels, dtype=float).reshape(-1, 2),
                  np.asarray(label_rung, dtype=np.int64))


def _runs(config: CouponConfig, lay: Layout, rung: int | None = None) -> Any:
    """The view intervals of the coupon's stipples (all rungs, or one)."""
    from specholo.toolpaths.common import make_runs

    n = config.stipples
    rungs = range(config.rungs) if rung is None else [rung]
    ids = np.array([r * n + i for r in rungs for i in range(n)], dtype=np.int64)
    start = np.radians(np.tile(lay.windows[:, 0], len(rungs)))
    end = np.radians(np.tile(lay.windows[:, 1], len(rungs)))
    return make_runs(lay.points, ids, start, end)


def _auto_depth(config: CouponConfig) -> float:
    """The depth ``specholo design`` would choose for the coupon's windows."""
    from specholo.jobs.flat.design import auto_depth

    lay = layout(config)
    design = dataclasses.replace(config.design, depth=None)
    return auto_depth(design.cutter(), design, lay.points, _runs(config, lay))


def _least_depth(config: CouponConfig) -> float:
    """The shallowest depth (mm, to the micrometre above) whose walls serve every
    window of the coupon with the design's tilt margin: a rigid rung any
    shallower would lose its steepest glints by design, not by its cut."""
    from specholo.jobs.flat.settings import TILT_MARGIN
    from specholo.optics.cutters import depth_for, needed_tilts, steepest_wall

    lay = layout(config)
    runs = _runs(config, lay)
    setup = config.design.setup()
    tilts, _ = needed_tilts(lay.points, runs.stipple, runs.start, runs.end, setup.light,
                            setup.viewer)
    cutter = config.design.cutter()
    steepest = steepest_wall(cutter)
    need = float(tilts.max()) + TILT_MARGIN
    depth = depth_for(cutter, need if steepest is None else min(need, steepest))
    if depth is None:
        raise SpecholoError(f"the {cutter.describe()} has no depth whose walls serve the "
                            f"coupon's windows (up to {math.degrees(need):.1f} deg)")
    return math.ceil(depth * 1000.0 - 1e-9) / 1000.0


# ---------------------------------------------------------------- the design


@dataclass(frozen=True)
class Rung:
    """One rung of a coupon.

    Attributes:
        index: its place on the card, from the left (0 first; the card numbers
            it index + 1).
        setting: its depth (rigid) or preload (spring), mm.
        config: the design settings it is cut with.
        cut_depth: the depth below the touch-off its cuts run at, mm (Z = -it).
        machining: its program's feeds and heights (a spring holder's lift).
        paths: (first, end) of its paths in the card's cutting order.
    """

    index: int
    setting: float
    config: DesignConfig
    cut_depth: float
    machining: Machining
    paths: tuple[int, int]


@dataclass
class Coupon:
    """A designed coupon, not yet written.

    Attributes:
        config: its settings.
        layout: where its rungs and stipples lie.
        grooves: every rung's grooves and label dots, in cutting order, rung
            after rung from the left.
        rungs: the rungs.
        tracks: stipple id -> its track: rows (k, 4) of eye azimuth (degrees),
            glint x and y (mm) and the path (stroke) that shows it.
        machining: the machining estimate, as a design's hologram.json holds it
            (hours by part, the machine).
        timings: seconds per stage.
    """

    config: CouponConfig
    layout: Layout
    grooves: Grooves
    rungs: list[Rung]
    tracks: dict[int, np.ndarray]
    machining: dict[str, Any]
    timings: dict[str, float]

    @property
    def plate(self) -> Plate:
        return Plate.from_corners(self.layout.corners, self.config.design.stock_thickness)

    def cut_depths(self) -> np.ndarray:
        """(n,) the depth each path of :attr:`grooves` is cut at, mm."""
        out = np.empty(self.grooves.n_paths)
        for rung in self.rungs:
            out[slice(*rung.paths)] = rung.cut_depth
        return out


def _rungs(config: CouponConfig) -> list[tuple[DesignConfig, float, Machining]]:
    """Each rung's settings, the depth its cuts run at and its machining."""
    out = []
    for r in range(config.rungs):
        rc = config.rung_config(r)
        holder = rc.holder_setup()
        assert holder is not None
        depth, machining = holder.program(rc.depth_mm, rc.setup().machining)
        out.append((rc, depth, machining))
    return out


def design_coupon(config: CouponConfig) -> Coupon:
    """Design every rung's grooves at its setting, put them in cutting order,
    find where each glint shows (its track) and time the card on the machine.

    Raises:
        SpecholoError: a stipple the striped method cannot design, rungs that
            would overlap, or a card taking longer than :data:`MAX_MINUTES`.
    """
    from specholo.fabrication.programs.order import order_paths
    from specholo.jobs.flat.design import design_runs

    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    lay = layout(config)
    n = config.stipples
    parts, rungs = [], []
    start = np.zeros(2)
    first = 0
    for r, (rc, depth, machining) in enumerate(_rungs(config)):
        grooves, dropped = design_runs(_runs(config, lay, r), rc)
        if len(dropped):
            raise SpecholoError(f"stipple {LETTERS[int(dropped[0]) % n]} of rung {r + 1} could "
                                "not be designed (the light in the eyes' plane): change "
                                "--light-elevation or --eye-height")
        _check_column(grooves, lay, r, rc)
        dots = np.flatnonzero(lay.label_rung == r)
        grooves = Grooves.concatenate([grooves, Grooves(
            lay.labels[dots], np.zeros(len(dots)), np.arange(len(dots) + 1, dtype=np.int64),
            lay.targets + dots)])
        # each rung cut whole, from where the last one ended: the tour of
        # order_paths starts at the origin, so the rung is moved to put it there
        shifted = Grooves(grooves.vertices - start, grooves.bulges, grooves.offsets,
                          grooves.stipple)
        ordered, _ = order_paths(shifted)
        grooves = Grooves(ordered.vertices + start, ordered.bulges, ordered.offsets,
                          ordered.stipple)
        start = grooves.vertices[-1]
        parts.append(grooves)
        rungs.append(Rung(r, config.ladder[r], rc, depth, machining,
                          (first, first + grooves.n_paths)))
        first += grooves.n_paths
    card = Grooves.concatenate(parts)
    timings["toolpaths"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    tracks: dict[int, np.ndarray] = {}
    for rung in rungs:
        tracks.update(_tracks(card, rung, lay, n))
    timings["tracks"] = time.perf_counter() - t0
    coupon = Coupon(config, lay, card, rungs, tracks, {}, timings)
    coupon.machining = machining_estimate(coupon)
    minutes = coupon.machining["estimated_hours"] * 60.0
    if minutes > MAX_MINUTES:
        raise SpecholoError(
            f"the coupon would take about {minutes:.0f} min to cut{_on(coupon.machining)}, more "
            f"than {MAX_MINUTES:g}: use fewer --rungs or --stipples, a narrower --window, a "
            "smaller --behind or faster --feed and --plunge")
    return coupon


def _on(machining: Mapping[str, Any]) -> str:
    machine = machining.get("machine")
    return f" on the {machine['name']}" if isinstance(machine, dict) else ""


def _check_column(grooves: Grooves, lay: Layout, r: int, config: DesignConfig) -> None:
    """Refuse a rung whose grooves leave its column (they would cross the next
    rung's) or the card's blank border."""
    (x0, y0), (x1, y1) = grooves.extent()
    half = 0.5 * config.cutter().section(config.depth_mm).width
    pitch = float(lay.rung_x[1] - lay.rung_x[0]) if len(lay.rung_x) > 1 else PITCH
    lo, hi = lay.rung_x[r] - 0.5 * pitch, lay.rung_x[r] + 0.5 * pitch
    (cx0, cy0), (cx1, cy1) = lay.corners + np.array([[BORDER, BORDER], [-BORDER, -BORDER]])
    if x0 - half < max(lo, cx0) or x1 + half > min(hi, cx1) or y0 - half < cy0 \
            or y1 + half > cy1:
        raise SpecholoError(f"rung {r + 1}'s grooves reach X{x0:.1f}..{x1:.1f}, past its "
                            f"{pitch:.1f} mm column: use fewer --rungs, a narrower --window "
                            "or a smaller --behind")


def rung_tool(rung: Rung) -> Any:
    """The round model of rung ``rung``'s groove (its depth's, or the depth a
    spring holder's grooves are expected to have)."""
    return rung.config.setup().tool


def _tracks(card: Grooves, rung: Rung, lay: Layout, n: int) -> dict[int, np.ndarray]:
    """Where each of the rung's stipples glints, every :data:`TRACK_STEP`
    degrees over its window (the window's ends included): rows of azimuth,
    x, y and the stroke (path of ``card``) that shows it."""
    from specholo.simulation.glints import Engraved, find_glints

    a, b = rung.paths
    setup = rung.config.setup()
    eng = Engraved.from_grooves(card.take(np.arange(a, b)), setup.tool)
    out: dict[int, np.ndarray] = {}
    for i, (lo, hi) in enumerate(lay.windows):
        sid = rung.index * n + i
        rows = []
        for az in track_azimuths(lo, hi):
            eye = setup.viewer.eye(np.radians([az]))[0]
            found = find_glints(eng, eye, setup.light)
            mine = found.stipple == sid
            rows += [[az, p[0], p[1], a + int(path)]
                     for p, path in zip(found.point[mine], found.path[mine], strict=True)]
        out[sid] = np.round(np.asarray(rows, dtype=float).reshape(-1, 4), 5)
    return out


def track_azimuths(lo: float, hi: float) -> np.ndarray:
    """The azimuths of a window's track, degrees: every :data:`TRACK_STEP`
    inside it, its ends left out (there the glint is at its groove's very end,
    which the program's rounding may take off)."""
    k = int(round((hi - lo) / TRACK_STEP))
    return np.round(lo + TRACK_STEP * np.arange(1, k), 6)


def shows(track: np.ndarray) -> tuple[float, float] | None:
    """The azimuths (degrees) from which a track's glint shows without a break:
    its first and last rows with a glint, where every row between has one but
    where one stroke hands over to the next (:func:`near_handover`); None
    where it shows from none or breaks off."""
    if not len(track):
        return None
    az = np.unique(track[:, 0])
    steps = np.round(np.diff(az) / TRACK_STEP).astype(np.int64)
    for k in np.flatnonzero(steps > 1):
        if steps[k] > 2 or not near_handover(track, 0.5 * (az[k] + az[k + 1])):
            return None
    return float(az[0]), float(az[-1])


def near_handover(track: np.ndarray, azimuth: float) -> bool:
    """Whether one stroke of a track hands over to the next within two steps of
    an azimuth (degrees). The two meet end to end as designed; as written to
    the program (coordinates to 10 nm, arc ends turned by up to 2e-4 rad), the
    glint near a stroke's end moves a few micrometres along it, so an eye
    within a few hundredths of a degree of the hand-over may find its glint on
    neither (at 600 mm a pupil is 0.3 degrees wide)."""
    near = track[np.abs(track[:, 0] - azimuth) <= 2.0 * TRACK_STEP + 1e-9]
    return len(np.unique(near[:, 3])) > 1


def sheet_positions(track: np.ndarray, azimuth: float) -> np.ndarray:
    """Where the sheet says a glint is seen from an eye azimuth (degrees): on
    each stroke of the track whose rows reach to within a step of it, linearly
    between its two rows about it (or beyond its last two). Between the last
    row of one stroke and the first of the next the hand-over may come
    anywhere: both places are given.

    Returns:
        (k, 2) plate positions, mm (none where the track has no stroke there).
    """
    out = []
    for stroke in np.unique(track[:, 3]):
        rows = track[track[:, 3] == stroke]
        rows = rows[np.argsort(rows[:, 0], kind="stable")]
        reach = TRACK_STEP + 1e-9
        if not rows[0, 0] - reach <= azimuth <= rows[-1, 0] + reach:
            continue
        if len(rows) == 1:
            out.append(rows[0, 1:3])
            continue
        i = int(np.clip(np.searchsorted(rows[:, 0], azimuth) - 1, 0, len(rows) - 2))
        t = (azimuth - rows[i, 0]) / (rows[i + 1, 0] - rows[i, 0])
        out.append(rows[i, 1:3] + t * (rows[i + 1, 1:3] - rows[i, 1:3]))
    return np.asarray(out, dtype=float).reshape(-1, 2)


def machining_estimate(coupon: Coupon) -> dict[str, Any]:
    """The card's machining time as the program runs, on the design's machine.

    :func:`~specholo.fabrication.programs.timing.estimate_time` takes one depth a
    program, and every part of its estimate adds up path by path (each path's
    move onto it from the last one's end, its plunge and retract, its cut), so
    a rung's share is the estimate of the paths up to its last less that of
    the paths before its first, both at its own Z: the card's estimate is
    exact, the move from one rung onto the next included.
    """
    from specholo.fabrication.programs.program import GcodeOptions
    from specholo.fabrication.programs.timing import estimate_time

    design = coupon.config.design
    profile = design.profile
    spindle = (design.spindle or 0.0) > 0
    dwell = GcodeOptions().dwell if spindle else 0.0
    keys = ("total_s", "cutting_s", "rapid_s", "plunge_s", "dwell_s", "hop_s", "hops", "lift_s",
            "delay_s")
    total = dict.fromkeys(keys, 0.0)
    for rung in coupon.rungs:
        a, b = rung.paths

        def upto(k: int, rung: Rung = rung) -> Any:
            return estimate_time(coupon.grooves.take(np.arange(k)), rung.cut_depth,
                                 rung.machining, dwell=dwell, machine=profile)

        after = upto(b)
        before = upto(a) if a else None
        for key in keys:
            total[key] += getattr(after, key) - (getattr(before, key) if before else 0.0)
    hours = {k.replace("_s", "_hours"): v / 3600.0 for k, v in total.items() if k != "hops"}
    out: dict[str, Any] = {
        "dialect": design.dialect, "units": design.units, "holder": design.holder,
        "estimated_hours": hours.pop("total_hours"), **hours, "hops": int(total["hops"]),
        "stipples_per_second": coupon.config.rungs * coupon.config.stipples / total["total_s"]
        if total["total_s"] > 0 else 0.0,
        "feed_mm_min": design.feed, "plunge_mm_min": design.plunge}
    if profile is not None:
        out["machine"] = {"name": profile.name, "title": profile.title, "kind": profile.kind,
                          "source": profile.source}
    return out


# ---------------------------------------------------------------- the program


def coupon_limits(coupon: Coupon) -> Any:
    """What the card's program may do (:class:`~specholo.fabrication.check.Limits`),
    from its settings as :func:`specholo.jobs.flat.folder.design_limits` has a design's:
    cut inside the card less half the widest groove, every cut in X/Y at one of
    the rungs' depths (or preloads), rapids at the safe height, hops no longer
    nor lower than set (a spring holder's: no X/Y move below its lift but its
    cuts), the feeds and spindle as set."""
    from specholo.fabrication.check import Limits, Stock, tool_kind

    design = coupon.config.design
    widths = [r.config.cutter().section(r.config.depth_mm).width for r in coupon.rungs]
    half = 0.5 * max(widths)
    (x0, y0), (x1, y1) = coupon.layout.corners
    stock = Stock(x0 + half, y0 + half, x1 - half, y1 - half, design.stock_thickness)
    m = coupon.rungs[0].machining
    spindle = float(design.spindle or 0.0)
    depths = [r.cut_depth for r in coupon.rungs]
    spring = coupon.config.holder == "spring"
    return Limits(stock, max(depths), m.safe_z, (min(m.feed, m.plunge), max(m.feed, m.plunge)),
                  (spindle, spindle), tool_kind(design.tool, spindle), hop_max=m.hop_max,
                  hop=m.hop, groove_depth=depths[0], depths=tuple(depths[1:]),
                  holder="spring" if spring else "rigid", lift=m.hop if spring else None)


def program_header(coupon: Coupon) -> dict[str, str]:
    """The card's program header lines (after the writer's own): what it is,
    each rung's X range and Z, how to hold and zero the tip, and the limits
    ``specholo check`` reads back."""
    config = coupon.config
    design = config.design
    lay = coupon.layout
    m = coupon.rungs[0].machining
    name = config.setting_name
    head = {"design": "test coupon", "cutter": design.cutter().describe(),
            "coupon": f"{config.rungs} rungs of {config.stipples} stipples, each rung at its "
                      f"own {name}; sheet.pdf says from where each glint shows"}
    pitch = float(lay.rung_x[1] - lay.rung_x[0])
    # coordinates in the program's units, as the writer's own lines give them;
    # the settings in mm, as the options take them
    per, decimals = (1.0, 5) if design.units == "mm" else (1.0 / 25.4, 6)

    def at(mm: float) -> str:  # to the program's grid, no trailing zeros
        return f"{mm * per:.{decimals}f}".rstrip("0").rstrip(".") or "0"

    for rung in coupon.rungs:
        x = lay.rung_x[rung.index]
        head[f"rung {rung.index + 1}"] = (
            f"X{at(x - 0.5 * pitch)}..{at(x + 0.5 * pitch)}: {name} {rung.setting:g} mm, cuts "
            f"at Z{at(-rung.cut_depth)}, {rung.index + 1} label dot"
            f"{'s' if rung.index else ''} below")
    if config.holder == "spring":
        head["holder"] = (f"spring-loaded; Z0 with the tip touching the plate; each rung cuts "
                          f"at its preload below it, lifts to Z{at(m.hop)} or Z{at(m.safe_z)} "
                          "between strokes")
        head["touch-off"] = (f"over X0 Y0, a paper shim on the plate, jog the tip down in "
                             f"{at(0.01)} {design.units} steps until the shim is pinched; G10 L20 "
                             "P1 Z<the shim's thickness>, remove the shim")
        head["expected depth"] = (f"{design.depth_mm:g} mm at the right preload; the rung "
                                  "whose glints all show crisply names it")
    else:
        head["holder"] = ("rigid; each rung cuts at its depth below Z0: the plate's Z must be "
                          "known over the card to a fraction of the ladder's step "
                          "(specholo probe, then specholo level)")
    head.update(coupon_limits(coupon).header())
    return head


def write_coupon(coupon: Coupon, out: str | os.PathLike[str],
                 inputs: Iterable[str | os.PathLike[str] | None] = (),
                 command: list[str] | None = None) -> dict[str, Any]:
    """Write the coupon's folder whole: ``hologram.gcode`` (checked before it is
    kept), ``hologram.svg``, ``coupon.json``, ``sheet.pdf``, ``grooves.npz`` and
    ``run.json``.

    Returns:
        What ``coupon.json`` holds.
    """
    import json

    from specholo.fabrication.atomic import atomic_open
    from specholo.fabrication.drawings.sheet import write_sheet
    from specholo.fabrication.drawings.svg import write_svg
    from specholo.fabrication.programs.gcode import write_gcode
    from specholo.fabrication.programs.program import GcodeOptions
    from specholo.staging import run_record, stage_design

    config = coupon.config
    design = config.design
    plate = coupon.plate
    info = coupon_json(coupon)
    spring = config.holder == "spring"
    middle = coupon.rungs[len(coupon.rungs) // 2]
    timings: dict[str, float] = {}
    with stage_design(out, inputs, kind="coupon", command=command) as stage:
        t0 = time.perf_counter()
        write_gcode(stage.path / "hologram.gcode", coupon.grooves, rung_tool(middle),
                    coupon.rungs[0].machining, header=program_header(coupon),
                    options=GcodeOptions(dialect=design.dialect,  # type: ignore[arg-type]
                                         units=design.units),  # type: ignore[arg-type]
                    depth=design.depth_mm, plate=plate,
                    width=design.cutter().section(design.depth_mm).width,
                    drawings=("SVG",), cut_depths=coupon.cut_depths())
        report = stage.check("hologram.gcode", coupon_limits(coupon))
        info["machining"]["safety_check"] = {"moves": report.moves, "violations": 0}
        timings["gcode"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        # a rigid card's rungs each in a layer of their own depth; a spring
        # holder's grooves all have the depth they are expected to have
        depths = None if spring else np.concatenate(
            [np.full(r.paths[1] - r.paths[0], rung_tool(r).depth) for r in coupon.rungs])
        write_svg(stage.path / "hologram.svg", coupon.grooves, rung_tool(middle), plate=plate,
                  depths=depths, cut=(design.depth_mm, design.cutter().section(
                      design.depth_mm).width) if spring else None)
        stage.save_grooves(coupon.grooves)
        stage.save_record("coupon", info, "coupon.json", sort_keys=False)
        write_sheet(stage.path / "sheet.pdf", info, coupon.grooves)
        timings["files"] = time.perf_counter() - t0
        with atomic_open(stage.path / "run.json") as fh:
            json.dump(run_record("coupon", command, {"design": coupon.timings,
                                                     "writing": timings},
                                 config.saved()), fh, indent=1)
    return info


def eye_offset(azimuth: float, distance: float) -> tuple[float, float]:
    """Where an eye at an azimuth (degrees) on the viewer's circle stands, mm:
    to the right of the card's centre line and out from its face."""
    a = math.radians(azimuth)
    return distance * math.sin(a), distance * math.cos(a)


def coupon_json(coupon: Coupon) -> dict[str, Any]:
    """What ``coupon.json`` holds: the settings, the card, how to look at it,
    each rung's setting and, per stipple, its point, window, the azimuths from
    which it shows and is dark, and its track (the sheet's positions)."""
    config = coupon.config
    design = config.design
    setup = design.setup()
    lay = coupon.layout
    n = config.stipples
    distance = setup.viewer.eye_radius
    rungs = []
    for rung in coupon.rungs:
        stipples = []
        for i in range(n):
            sid = rung.index * n + i
            track = coupon.tracks[sid]
            seen = shows(track)
            if seen is None:
                raise SpecholoError(f"rung {rung.index + 1}'s glint {LETTERS[i]} does not show "
                                    "over its whole window on the designed grooves: a deeper "
                                    f"{config.setting_name} or another --window")
            lo, hi = (float(v) for v in lay.windows[i])
            middle = sheet_positions(track, 0.5 * (lo + hi))
            stipples.append({
                "id": sid, "letter": LETTERS[i],
                "point_mm": [round(float(v), 5) for v in lay.points[sid]],
                "window_deg": [lo, hi], "shows_deg": list(seen),
                "dark_beyond_deg": [lo - DARK_MARGIN, hi + DARK_MARGIN],
                "eye_from_mm": [round(v, 1) for v in eye_offset(seen[0], distance)],
                "eye_to_mm": [round(v, 1) for v in eye_offset(seen[1], distance)],
                "glint_at_middle_mm": [round(float(v), 3) for v in middle[0]]
                if len(middle) else None,
                "track": track.tolist()})
        dots = np.flatnonzero(lay.label_rung == rung.index)
        rungs.append({
            "rung": rung.index + 1, config.setting_name + "_mm": rung.setting,
            "holder": config.holder, "cut_z_mm": -rung.cut_depth,
            "depth_mm": rung.setting if config.holder == "rigid" else design.depth_mm,
            "x_mm": round(float(lay.rung_x[rung.index]), 4),
            "paths": list(rung.paths), "design_option": config.option(rung.index),
            "label_dots_mm": lay.labels[dots].round(4).tolist(), "stipples": stipples})
    light = setup.light
    return {
        "specholo_version": __version__, "kind": "coupon",
        "settings": config.saved(),
        "frame": "plate mm: x right, y up, z toward the viewer, card at z = 0, origin at its "
                 "centre",
        "card": {"plate_mm": lay.corners.tolist(), "thickness_mm": design.stock_thickness},
        "viewing": {
            "eye_distance_mm": distance, "eye_height_mm": design.eye_height,
            "view_range_deg": design.view_range,
            "light": {"elevation_deg": design.light_elevation,
                      "distance_mm": light.distance},
            "azimuth": "one eye's azimuth, degrees, on a circle of eye_distance_mm about the "
                       "card's centre at eye_height_mm: 0 straight in front, positive to the "
                       "right (seen from in front)"},
        "tool": {"kind": design.tool, "description": design.cutter().describe(),
                 "depth_mm": design.depth_mm, "band_mm": design.band},
        "track_step_deg": TRACK_STEP, "on_the_sheet_mm": ON_THE_SHEET,
        "position_rule": (
            "a track's rows are azimuth (deg), glint x, y (mm) and the stroke showing it; "
            "from an azimuth between two rows the glint is on each stroke whose rows reach to "
            "within a step of it, linearly between its two rows about it (or beyond its "
            "last two); it shows from shows_deg[0] to shows_deg[1] and from nowhere outside "
            "dark_beyond_deg"),
        "rungs": rungs,
        "machining": coupon.machining,
    }


# ---------------------------------------------------------------- reading back


@dataclass
class LoadedCoupon:
    """A coupon read back from its folder.

    Attributes:
        config: its settings.
        layout: its card.
        info: its ``coupon.json``.
        grooves: its grooves (from ``grooves.npz``, or its program).
        rungs: each rung's design settings, by index.
        tracks: stipple id -> its track, as the sheet gives it.
        shows: stipple id -> (first, last) azimuth it shows from, degrees.
        dark: stipple id -> (low, high): it is dark outside, degrees.
    """

    config: CouponConfig
    layout: Layout
    info: dict[str, Any]
    grooves: Grooves
    rungs: list[DesignConfig]
    tracks: dict[int, np.ndarray]
    shows: dict[int, tuple[float, float]]
    dark: dict[int, tuple[float, float]]

    @property
    def points(self) -> np.ndarray:
        """The targets and the label dots (on the card), as stipples."""
        lab = self.layout.labels
        return np.concatenate([self.layout.points, np.column_stack([lab, np.zeros(len(lab))])])


def is_coupon_folder(folder: str | os.PathLike[str]) -> bool:
    """Whether ``folder`` holds a coupon."""
    return (Path(folder) / "coupon.json").is_file()


def load_coupon(folder: str | os.PathLike[str], from_gcode: bool = False) -> LoadedCoupon:
    """A coupon folder read back and checked.

    Args:
        folder: the folder :func:`write_coupon` wrote.
        from_gcode: read the grooves from ``hologram.gcode`` (the program that
            is cut) instead of ``grooves.npz``.

    Raises:
        SpecholoError: a file unreadable or unlike what the coupon writes.
    """
    from specholo.readback import number, read_json, settings_from, table

    folder = Path(folder)
    path = folder / "coupon.json"
    info = table(read_json(path), str(path))
    with settings_from(path):
        config = CouponConfig.from_saved(info["settings"])
        lay = layout(config)
        n = config.stipples
        tracks: dict[int, np.ndarray] = {}
        seen: dict[int, tuple[float, float]] = {}
        dark: dict[int, tuple[float, float]] = {}
        rungs = table(info, "coupon.json")["rungs"]
        if not isinstance(rungs, list) or len(rungs) != config.rungs:
            raise SpecholoError(f"rungs must list {config.rungs} rungs")
        for r, rung in enumerate(rungs):
            stipples = table(rung, "rung")["stipples"]
            if not isinstance(stipples, list) or len(stipples) != n:
                raise SpecholoError(f"each rung must list {n} stipples")
            for i, s in enumerate(stipples):
                s = table(s, "stipple")
                sid = r * n + i
                rows = np.asarray(s["track"], dtype=float)
                if rows.ndim != 2 or rows.shape[1] != 4 or not np.isfinite(rows).all():
                    raise SpecholoError("a track must be rows of 4 finite numbers")
                tracks[sid] = rows
                lo, hi = (number(v, "shows_deg") for v in s["shows_deg"])
                dlo, dhi = (number(v, "dark_beyond_deg") for v in s["dark_beyond_deg"])
                seen[sid], dark[sid] = (lo, hi), (dlo, dhi)
    total = lay.targets + len(lay.labels)
    if from_gcode:
        from specholo.fabrication.programs.gcode_reader import read_gcode

        grooves = read_gcode(folder / "hologram.gcode")
        grooves.validate(total, str(folder / "hologram.gcode"))
    else:
        grooves = Grooves.load(folder / "grooves.npz", total)
    return LoadedCoupon(config, lay, info, grooves,
                        [config.rung_config(r) for r in range(config.rungs)], tracks, seen, dark)


# ---------------------------------------------------------------- verifying


@dataclass(frozen=True)
class StippleCheck:
    """What simulated eyes found of one stipple against its sheet.

    Attributes:
        rung: the rung's index; stipple: the stipple's id.
        inside: eyes inside the azimuths it shows from; found: those that found
            it within :data:`ON_THE_SHEET` of the sheet's place.
        handover: eyes that found no glint within a step of a hand-over
            between two strokes (:func:`near_handover`), which the sheet allows.
        worst_mm: the largest distance of a glint found from the sheet's place.
        outside: eyes beyond its dark azimuths; stray: those that saw it.
    """

    rung: int
    stipple: int
    inside: int
    found: int
    handover: int
    worst_mm: float
    outside: int
    stray: int

    @property
    def ok(self) -> bool:
        return self.found + self.handover == self.inside and self.stray == 0


def verify_coupon(c: LoadedCoupon, step_deg: float = 1.0) -> list[StippleCheck]:
    """Simulate one eye at the azimuths each stipple's sheet names: between every
    two rows of its track (halfway, where the sheet interpolates) its glint must
    be found within :data:`ON_THE_SHEET` of the sheet's place, and from every
    ``step_deg`` beyond its dark azimuths (over the viewing range and 5 degrees
    past it) not at all."""
    from specholo.simulation.glints import Engraved, find_glints

    n = c.config.stipples
    half = c.config.design.view_range + 5.0
    ids = np.asarray(c.grooves.stipple)
    rung_of_path = c.layout.rung_of(ids)
    out = []
    for r, rc in enumerate(c.rungs):
        setup = rc.setup()
        eng = Engraved.from_grooves(c.grooves.take(np.flatnonzero(rung_of_path == r)),
                                    setup.tool)
        cache: dict[float, Any] = {}

        def look(az: float, setup: Any = setup, eng: Any = eng, cache: Any = cache) -> Any:
            key = round(az, 6)
            if key not in cache:
                eye = setup.viewer.eye(np.radians([az]))[0]
                cache[key] = find_glints(eng, eye, setup.light)
            return cache[key]

        for i in range(n):
            sid = r * n + i
            track = c.tracks[sid]
            lo, hi = c.shows[sid]
            rows = np.unique(track[(track[:, 0] >= lo) & (track[:, 0] <= hi), 0])
            inside = np.concatenate([rows, 0.5 * (rows[1:] + rows[:-1])])
            found, handover, worst = 0, 0, 0.0
            for az in inside:
                g = look(float(az))
                mine = g.point[g.stipple == sid][:, :2]
                want = sheet_positions(track, float(az))
                if not len(mine) and near_handover(track, float(az)):
                    handover += 1
                    continue
                if not len(mine) or not len(want):
                    worst = math.inf
                    continue
                gap = float(np.linalg.norm(mine[:, None] - want[None], axis=2).min())
                worst = max(worst, gap)
                found += gap <= ON_THE_SHEET
            dlo, dhi = c.dark[sid]
            scan = np.arange(-half, half + 1e-9, step_deg)
            outside = scan[(scan < dlo) | (scan > dhi)]
            stray = sum(int(np.any(look(float(az)).stipple == sid)) for az in outside)
            out.append(StippleCheck(r, sid, len(inside), found, handover, worst, len(outside),
                                    stray))
    return out

"""How long a machine takes to cut the grooves (an estimate for planning).

The model follows the programs :func:`~specholo.fabrication.programs.gcode.write_gcode`
writes: the tool starts above the origin at the safe height; for each path it
rapids to the start, plunges at the plunge rate, cuts along the arcs at the
feed and retracts at the rapid rate (a laser has no plunge or retract, and
fires for ``dot_time`` on a dot). Where the writer hops between paths
(:meth:`~specholo.setup.Machining.hops`, decided on the same lengths), the
retract and the plunge run between the groove and the hop height, and the move
over is a feed move at the cutting feed.

Every move accelerates and brakes at ``accel`` (trapezoidal velocity). Rapids,
plunges, retracts and hops start and end at rest (GRBL's planner would carry a
little speed through their right-angle corners: its junction deviation allows
~2.5 mm/s there at the defaults, so short hops take a few ms less). Within a groove the machine does
not stop between arcs; as in GRBL's planner, its speed is limited

- at each junction by the junction deviation ``delta``: turning by phi allows
  v^2 = accel * delta * cos(phi / 2) / (1 - cos(phi / 2)) (no limit when the
  tangent is continuous, as on the designed grooves);
- on an arc of radius r by the centripetal acceleration: v^2 <= accel * r;
- by the need to stop at the groove's end (a backward pass) and the speed it
  can reach from the previous junction (a forward pass).

Real controllers differ per axis and in their arc handling, so expect a few
per cent either way on a well-tuned machine.

On a machine profile (``machine``, :mod:`specholo.fabrication.programs.machines`) the
same moves are timed on that machine's figures: X/Y moves and arcs (cuts, hops,
rapids) accelerate at its X/Y acceleration and Z moves (plunges, retracts, the
lifts to the hop height) at its Z acceleration; rapids run at its maximum
rates, a plunge at most at its Z rate; corners follow its junction deviation.
A pen plotter has no Z: it travels pen up between strokes at its X/Y rate and
lifts and lowers its pen once a stroke (``lift_s``), never hopping. A CO2 laser
moves like a gantry without Z. A galvo's mirrors are modelled without inertia:
a jump takes its length over the jump speed plus the jump delay, a stroke its
length over the mark speed plus the laser-on and laser-off delays and a polygon
delay at each corner, a turn of more than :data:`CORNER` (``delay_s`` holds the
delays).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo._compiling import kernel
from specholo._threads import chunked
from specholo.errors import SpecholoError
from specholo.fabrication.programs.machines import MachineProfile
from specholo.fabrication.programs.order import HOPS, hop_lengths
from specholo.setup import Machining
from specholo.toolpaths.grooves import Grooves


@dataclass(frozen=True)
class TimeEstimate:
    """Machining time of a program, seconds.

    Attributes:
        total_s: everything below added up.
        cutting_s: feed moves along the grooves.
        rapid_s: rapids between grooves and retracts.
        plunge_s: plunges to the groove depth.
        dwell_s: the wait after starting the spindle, and laser dots.
        stipples: distinct stipple ids cut.
        stipples_per_s: stipples per second of machining (0 if nothing is cut).
        hop_s: hops between grooves (feed moves just above the surface).
        hops: moves between grooves made as hops.
        lift_s: a pen plotter lifting and lowering its pen, once a stroke.
        delay_s: a galvo's laser-on, laser-off, polygon and jump delays.
    """

    total_s: float
    cutting_s: float
    rapid_s: float
    plunge_s: float
    dwell_s: float
    stipples: int
    stipples_per_s: float
    hop_s: float = 0.0
    hops: int = 0
    lift_s: float = 0.0
    delay_s: float = 0.0


def trapezoid_time(length: np.ndarray, cap: np.ndarray | float, accel: float,
                   entry: np.ndarray | float = 0.0, leave: np.ndarray | float = 0.0) -> np.ndarray:
    """Time of moves under a trapezoidal velocity profile.

    Args:
        length: (k,) move lengths, mm.
        cap: top speed, mm/s (scalar or (k,)).
        accel: acceleration and braking, mm/s^2.
        entry: speed at the start, mm/s (scalar or (k,)); must be reachable,
            i.e. entry^2 <= leave^2 + 2 accel length and the other way round.
        leave: speed at the end, mm/s (scalar or (k,)).

    Returns:
        (k,) seconds: accelerate from ``entry``, cruise at the top speed if the
        move is long enough, brake to ``leave``.
    """
    length = np.asarray(length, dtype=float)
    u2 = np.square(entry)
    w2 = np.square(leave)
    # the highest speed reachable with room to brake, limited by the cap
    peak = np.minimum(cap, np.sqrt(np.maximum(accel * length + 0.5 * (u2 + w2), 0.0)))
    peak = np.maximum(peak, np.maximum(entry, leave))
    ramp = (2.0 * np.square(peak) - u2 - w2) / (2.0 * accel)
    with np.errstate(divide="ignore", invalid="ignore"):
        cruise = np.where(peak > 0, np.maximum(length - ramp, 0.0) / peak, 0.0)
    return (2.0 * peak - entry - leave) / accel + cruise


@kernel(helper=True)
def _trapezoid(length: float, cap: float, accel: float, entry: float, leave: float) -> float:
    """:func:`trapezoid_time` of one move."""
    u2, w2 = entry * entry, leave * leave
    peak = min(cap, math.sqrt(max(accel * length + 0.5 * (u2 + w2), 0.0)))
    peak = max(peak, max(entry, leave))
    ramp = (2.0 * peak * peak - u2 - w2) / (2.0 * accel)
    cruise = max(length - ramp, 0.0) / peak if peak > 0 else 0.0
    return (2.0 * peak - entry - leave) / accel + cruise


@kernel()
def _plan(length: np.ndarray, cap: np.ndarray, junction: np.ndarray, k: int, accel: float,
          entry: np.ndarray, leave: np.ndarray) -> None:
    """Entry and exit speeds of one path's k segments, starting and ending at rest.

    Args:
        length: (>= k,) segment lengths, mm.
        cap: (>= k,) top speed on each segment, mm/s.
        junction: (>= k,) speed limit at the junction *before* each segment,
            mm/s (ignored for the first).
        k: the path's segments.
        accel: mm/s^2.
        entry, leave: (>= k,) written.
    """
    # backward: the fastest entry from which the machine can still stop in time
    nxt = 0.0
    for i in range(k - 1, -1, -1):
        leave[i] = nxt
        v = min(math.sqrt(nxt * nxt + 2.0 * accel * length[i]), cap[i])
        v = min(v, junction[i], cap[i - 1]) if i > 0 else 0.0
        entry[i] = v
        nxt = v
    # forward: what it can reach from the previous junction
    cur = 0.0
    for i in range(k):
        entry[i] = cur
        cur = min(leave[i], math.sqrt(cur * cur + 2.0 * accel * length[i]))
        leave[i] = cur


#: Smallest turn at a junction that a galvo takes as a corner (waiting its
#: polygon delay there), radians. The designed grooves are tangent-continuous
#: (their biarcs turn by rounding errors at their joints), and a galvo traces
#: an arc as one smooth stroke; a turn of a degree is a visible kink.
CORNER = math.radians(1.0)


def _cutting_time(vertices: np.ndarray, bulges: np.ndarray, offsets: np.ndarray, feed: float,
                  accel: float, delta: float) -> tuple[float, int]:
    """Seconds of feed moves along every path: each path's arcs planned through
    their junctions (:func:`_plan`), one compiled pass with no per-arc arrays
    (at 10^6 stipples those took more memory than the machine has); and the
    junctions that turn by more than :data:`CORNER`.

    Args:
        vertices (m, 2), bulges (m,), offsets (n + 1,): the grooves.
        feed: mm/s; accel: mm/s^2; delta: junction deviation, mm.
    """
    n = offsets.size - 1
    longest = max(1, int(np.diff(offsets).max())) if n > 0 else 1
    # Blocks fixed by the paths alone, summed in order below: the same grooves
    # give the same last bits however many threads ran the blocks.
    blocks = min(n, 256)
    total = np.zeros(max(blocks, 1))
    corners = np.zeros(max(blocks, 1), dtype=np.int64)
    chunked(_cutting_blocks, 0, blocks, vertices, bulges, offsets, feed, accel, delta,
            math.cos(0.5 * CORNER), longest, total, corners)
    seconds = 0.0
    for blk in range(total.size):
        seconds += float(total[blk])
    return seconds, int(corners.sum())


@kernel(nogil=True)
def _cutting_blocks(lo: int, hi: int, vertices: np.ndarray, bulges: np.ndarray,
                    offsets: np.ndarray, feed: float, accel: float, delta: float,
                    cos_corner: float, longest: int, total: np.ndarray,
                    corners: np.ndarray) -> None:
    """:func:`_cutting_time` of blocks lo .. hi - 1 (of total.size) of the paths,
    each into its total, and its junctions whose half-turn's cosine is below
    ``cos_corner`` into its corners."""
    n, blocks = offsets.size - 1, total.size
    for blk in range(lo, hi):
        length, cap, junction = np.empty(longest), np.empty(longest), np.empty(longest)
        entry, leave = np.empty(longest), np.empty(longest)
        part = 0.0
        turns = 0
        for p in range(blk * n // blocks, (blk + 1) * n // blocks):
            a = offsets[p]
            k = offsets[p + 1] - a - 1
            out_dir = 0.0
            for i in range(k):
                b = bulges[a + i]
                dx = vertices[a + i + 1, 0] - vertices[a + i, 0]
                dy = vertices[a + i + 1, 1] - vertices[a + i, 1]
                chord = math.sqrt(dx * dx + dy * dy)
                sweep = 4.0 * math.atan(b)
                half = 0.5 * abs(sweep)
                length[i] = chord * half / math.sin(half) if abs(b) > 1e-12 else chord
                # centripetal acceleration: v^2 <= accel r
                cap[i] = feed if b == 0.0 else min(
                    feed, math.sqrt(accel * chord * (1.0 + b * b) / (4.0 * abs(b))))
                angle = math.atan2(dy, dx)
                if i > 0:  # the turn from the last arc's end tangent to this one's start
                    x = angle - 0.5 * sweep - out_dir
                    c = math.cos(0.5 * math.atan2(math.sin(x), math.cos(x)))
                    junction[i] = math.sqrt(accel * delta * c / (1.0 - c)) if c < 1.0 \
                        else math.inf
                    if c < cos_corner:
                        turns += 1
                out_dir = angle + 0.5 * sweep
            _plan(length, cap, junction, k, accel, entry, leave)
            for i in range(k):
                part += _trapezoid(length[i], cap[i], accel, entry[i], leave[i])
        total[blk] = part
        corners[blk] = turns


def _distinct(ids: np.ndarray) -> int:
    """How many different values ids (k,) holds: counted in a table where the
    ids are small non-negative integers (as stipple ids are), not sorted."""
    if ids.size and ids.dtype.kind in "iu" and 0 <= ids.min() and ids.max() < 4 * ids.size:
        return int(np.count_nonzero(np.bincount(ids)))
    return len(np.unique(ids))


def estimate_time(grooves: Grooves, depth: float, machining: Machining,
                  accel: float = 250.0, rapid: float = 3000.0, junction_deviation: float = 0.01,
                  dwell: float = 0.0, laser: bool = False, dot_time: float = 0.1,
                  machine: MachineProfile | None = None) -> TimeEstimate:
    """Estimate how long cutting the grooves takes, in the order given.

    Args:
        grooves: n paths, cut in order, each from its first vertex.
        depth: groove depth, mm.
        machining: feed and plunge rates (mm/min), safe height and hops (mm).
        accel: acceleration of every axis, mm/s^2.
        rapid: rapid (G0) rate, mm/min.
        junction_deviation: GRBL's ``$11``, mm: sets the speed through corners.
        dwell: seconds waited once after starting the spindle.
        laser: a laser: no plunges or retracts; dots fire for ``dot_time``.
        dot_time: seconds the laser fires on a dot.
        machine: the machine to time the program on (see the module's notes):
            its figures replace ``accel``, ``rapid`` and ``junction_deviation``,
            the feeds are capped at its rates, and a laser profile is a laser.
            None times it as above, every axis alike.

    Returns:
        Total seconds, split by kind of move, and stipples per second.

    Raises:
        SpecholoError: if a rate, the acceleration or a time is not positive
            (times may be 0), or the grooves hold an empty path.
    """
    for name, value, zero_ok in (("acceleration", accel, False), ("rapid rate", rapid, False),
                                 ("junction deviation", junction_deviation, True),
                                 ("dwell", dwell, True), ("dot time", dot_time, True),
                                 ("depth", depth, True)):
        v = float(value)
        if not math.isfinite(v) or v < 0 or (v == 0 and not zero_ok):
            raise SpecholoError(f"{name} must be a finite number "
                                f"{'>= 0' if zero_ok else '> 0'}, got {v:g}")
    if grooves.has_empty_path():
        raise SpecholoError("grooves contain an empty path")
    move = _Motion.of(machine, machining, accel, rapid, junction_deviation, laser)
    n = grooves.n_paths
    stipples = _distinct(np.asarray(grooves.stipple))
    offsets = np.asarray(grooves.offsets, dtype=np.int64)
    verts = np.ascontiguousarray(grooves.vertices, dtype=float).reshape(-1, 2)
    bulges = np.ascontiguousarray(grooves.bulges, dtype=float)
    dots = int(np.sum(grooves.is_dot))

    def hops(lo: int, hi: int) -> np.ndarray:
        """Air travel onto paths lo .. hi - 1, from their ends and the one before."""
        a = max(lo - 1, 0)
        starts, ends = verts[offsets[a:hi]], verts[offsets[a + 1:hi + 1] - 1]
        return hop_lengths(starts, ends, lo - a, hi - a)

    if move.galvo is not None:
        return _galvo_time(grooves, move, move.galvo, hops, verts, bulges, offsets, dwell,
                           dot_time, dots, stipples)
    # A block of paths at a time: the temporaries stay small at any size.
    rapid_s = hop_s = 0.0
    hopped = 0
    for lo in range(0, n, HOPS):
        air = hops(lo, min(lo + HOPS, n))
        # without a Z (a laser, a plotter's pen) nothing hops: every move over is a rapid
        hop = np.zeros(len(air), dtype=bool) if not move.z else machining.hops(air)
        if lo == 0:
            hop[0] = False  # the job starts at the safe height
        rapid_s += float(trapezoid_time(air[~hop], move.rapid, move.xy_accel).sum())
        hop_s += float(trapezoid_time(air[hop], move.feed, move.xy_accel).sum())
        hopped += int(hop.sum())
    plunge_s = lift_s = 0.0
    dwell_s = dwell if n else 0.0
    if move.laser:
        dwell_s += dot_time * dots
    elif move.z:
        # every path plunges once and retracts once; a hop shortens the retract
        # before it and the plunge after it to the hop height
        z = np.array([machining.safe_z + depth, machining.hop + depth])
        count = np.array([n - hopped, hopped])
        plunge_s = float(count @ trapezoid_time(z, move.plunge, move.z_accel))
        rapid_s += float(count @ trapezoid_time(z, move.z_rapid, move.z_accel))
    else:  # a plotter lowers its pen onto every stroke (a dot too) and lifts it after
        lift_s = n * move.pen_lift

    cutting_s = _cutting_time(verts, bulges, offsets, move.feed, move.xy_accel, move.delta)[0]

    total = cutting_s + rapid_s + plunge_s + dwell_s + hop_s + lift_s
    return TimeEstimate(total, cutting_s, rapid_s, plunge_s, dwell_s, stipples,
                        stipples / total if total > 0 else 0.0, hop_s, hopped, lift_s)


@dataclass(frozen=True)
class _Motion:
    """How a program's moves are timed, in mm/s and mm/s^2 (see :func:`estimate_time`).

    Attributes:
        feed: cutting feed (a laser's mark speed), capped at the X/Y rate.
        plunge: plunge feed, capped at the Z rate.
        rapid: X/Y rapids (a plotter's pen-up travel, a laser's travel).
        z_rapid: Z retracts.
        xy_accel, z_accel: accelerations.
        delta: junction deviation, mm.
        z: whether the tool plunges and retracts (and hops).
        laser: whether dots fire a beam.
        pen_lift: seconds a plotter takes to lower and lift its pen, per stroke.
        galvo: the galvo profile, whose strokes are timed without inertia, or None.
    """

    feed: float
    plunge: float
    rapid: float
    z_rapid: float
    xy_accel: float
    z_accel: float
    delta: float
    z: bool
    laser: bool
    pen_lift: float = 0.0
    galvo: MachineProfile | None = None

    @classmethod
    def of(cls, machine: MachineProfile | None, machining: Machining, accel: float,
           rapid: float, delta: float, laser: bool) -> _Motion:
        """Today's model (every axis at ``accel``, rapids at ``rapid`` mm/min)
        without a machine, else the machine's figures."""
        if machine is None:
            return cls(machining.feed / 60.0, machining.plunge / 60.0, rapid / 60.0,
                       rapid / 60.0, accel, accel, delta, not laser, laser)
        # a controller runs no move faster than its axes' maximum rate
        feed = min(machining.feed, machine.xy_rate) / 60.0
        xy_accel = machine.xy_accel if machine.xy_accel is not None else math.inf
        if machine.has_z:
            assert machine.z_rate is not None and machine.z_accel is not None
            return cls(feed, min(machining.plunge, machine.z_rate) / 60.0, machine.xy_rate / 60.0,
                       machine.z_rate / 60.0, xy_accel, machine.z_accel,
                       machine.junction_deviation, True, False)
        return cls(feed, 0.0, machine.xy_rate / 60.0, 0.0, xy_accel, math.inf,
                   machine.junction_deviation, False, machine.laser,
                   machine.pen_raise + machine.pen_lower,
                   machine if machine.kind == "galvo" else None)


def _galvo_time(grooves: Grooves, move: _Motion, galvo: MachineProfile,
                hops: Callable[[int, int], np.ndarray],
                verts: np.ndarray, bulges: np.ndarray, offsets: np.ndarray, dwell: float,
                dot_time: float, dots: int, stipples: int) -> TimeEstimate:
    """:func:`estimate_time` on a galvo: mirrors without inertia, so every jump
    takes its length over the jump speed and its jump delay, every stroke its
    length over the mark speed, the laser-on and laser-off delays and a polygon
    delay at each corner; a dot fires for ``dot_time``."""
    n = grooves.n_paths
    air = 0.0
    for lo in range(0, n, HOPS):
        air += float(hops(lo, min(lo + HOPS, n)).sum())
    rapid_s = air / move.rapid
    cutting_s = grooves.total_length() / move.feed
    corners = _cutting_time(verts, bulges, offsets, move.feed, 1.0, 0.0)[1]
    delay_s = (n * (galvo.jump_delay + galvo.laser_on_delay + galvo.laser_off_delay)
               + corners * galvo.polygon_delay)
    dwell_s = (dwell + dot_time * dots) if n else 0.0
    total = cutting_s + rapid_s + dwell_s + delay_s
    return TimeEstimate(total, cutting_s, rapid_s, 0.0, dwell_s, stipples,
                        stipples / total if total > 0 else 0.0, delay_s=delay_s)


def plain_duration(seconds: float) -> str:
    """A duration as a maker reads it: "40 min", "3 h 20 min", "2 days 5 h"."""
    if not math.isfinite(seconds) or seconds < 0:
        return "unknown"
    minutes = round(seconds / 60.0)
    if minutes < 1:
        return "under a minute"
    if minutes < 60:
        return f"{minutes} min"
    hours, minutes = divmod(minutes, 60)
    if hours < 48:
        return f"{hours} h {minutes} min" if minutes else f"{hours} h"
    days, hours = divmod(hours, 24)
    return f"{days} days {hours} h" if hours else f"{days} days"


def describe_machining(machining: dict[str, Any], feed: float) -> str:
    """One line in plain words from a design's ``machining`` figures (hours, as in
    hologram.json): the machine it is timed on (if one was chosen), the whole
    job, what takes the time, and the feed assumed."""
    total = 3600.0 * machining["estimated_hours"]
    machine = machining.get("machine")
    gantry = not isinstance(machine, dict) or machine.get("kind") in ("router", "mill")
    parts = [(what, 3600.0 * machining.get(key, 0.0)) for what, key in (
        ("cutting", "cutting_hours"), ("moving between grooves just above the plate", "hop_hours"),
        ("plunging", "plunge_hours"),
        ("rapids and retracts" if gantry else "travel between strokes", "rapid_hours"),
        ("lifting and lowering the pen", "lift_hours"),
        ("laser and mirror delays", "delay_hours"))]
    split = ", ".join(f"{what} {plain_duration(s)}" for what, s in parts if s >= 30.0)
    on = (f" on {machine['name']} ({machine['title']})" if isinstance(machine, dict) else "")
    return (f"machining{on}: about {plain_duration(total)} at {feed:g} mm/min"
            + (f" ({split})" if split else ""))

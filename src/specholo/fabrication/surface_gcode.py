"""G-code for grooves on curved hosts: 3-axis with a vertical tool, and 4-axis
with a rotary A axis for a cylinder; and an independent check of both.

3-axis: a ball is round, so a vertical ball-end tool whose centre sits at
C = c + (R - d) N cuts the same groove as one held along the local normal N,
as long as its shank clears the surface; that holds while the surface tilts
less than asin(1 - d / R) from vertical. Samples beyond that reach are left out
(and counted). The program moves the tool tip, R below the centre.

4-axis (cylinder only): the cylinder's axis lies along the machine's X, the A
axis turns it (degrees), and the tool stays over the axis, so it always cuts
along the local normal. Z is zero at the top of the cylinder's surface: the tip
goes to Z = -d.

All numbers are written with '.' as the decimal point whatever the locale.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.hosts.surfaces import Cylinder, Host
from specholo.setup import Machining, Tool
from specholo.toolpaths.conforming import ConformingGrooves


def reach_tilt(tool: Tool) -> float:
    """Steepest surface tilt (radians) a vertical tool reaches without its shank
    touching the surface beside the groove."""
    return math.asin(max(0.0, 1.0 - tool.depth / tool.radius))


@dataclass(frozen=True)
class SurfaceProgram:
    """A written program and its figures.

    Attributes:
        text: the G-code.
        paths: number of grooves cut.
        dropped_samples: samples beyond the 3-axis reach, left out.
        cut_length: length of cutting moves, mm (3-axis, tool tip) or of the
            grooves (4-axis).
    """

    text: str
    paths: int
    dropped_samples: int
    cut_length: float


def _f(v: float) -> str:
    s = f"{v:.4f}"
    return "0.0000" if s == "-0.0000" else s


def _header(machining: Machining, axes: int) -> list[str]:
    lines = [f"(specholo: grooves on a curved host, {axes}-axis)", "G21 G90 G17 G94"]
    if machining.spindle > 0:
        lines.append(f"M3 S{machining.spindle:.0f}")
    return lines


def write_surface_gcode(grooves: ConformingGrooves, host: Host, tool: Tool,
                        machining: Machining, axes: int = 3) -> SurfaceProgram:
    """Write the grooves as G-code.

    Args:
        grooves: the grooves (centreline samples with host normals).
        host: their host.
        tool: the ball model (radius, depth).
        machining: feeds, safe height, spindle.
        axes: 3, or 4 for a cylinder on a rotary axis.

    Returns:
        The program.

    Raises:
        SpecholoError: 4 axes for a host that is not a cylinder.
    """
    if axes not in (3, 4):
        raise SpecholoError(f"axes must be 3 or 4, got {axes}")
    if axes == 4 and not isinstance(host, Cylinder):
        raise SpecholoError("4-axis output is for a cylinder host (a rotary A axis)")
    lines = _header(machining, axes)
    paths = 0
    dropped = 0
    length = 0.0
    if axes == 3:
        top = float(np.nanmax(grooves.point[:, 2])) if len(grooves.point) else 0.0
        safe = top + machining.safe_z
        lines.append(f"G0 Z{_f(safe)}")
        limit = math.cos(reach_tilt(tool))
        for path in np.split(np.arange(len(grooves.point)),
                             np.flatnonzero(np.diff(grooves.stripe)) + 1):
            if path.size < 2:
                continue
            ok = grooves.normal[path, 2] >= limit
            dropped += int((~ok).sum())
            # Cut the runs of reachable samples, each a groove of its own.
            runs = np.split(path, np.flatnonzero(np.diff(ok.astype(int))) + 1)
            for run in runs:
                if run.size < 2 or grooves.normal[run[0], 2] < limit:
                    continue
                tip = (grooves.point[run] + (tool.radius - tool.depth) * grooves.normal[run]
                       - np.array([0.0, 0.0, tool.radius]))
                lines.append(f"(stipple {int(grooves.stipple[run[0]])})")
                lines.append(f"G0 X{_f(tip[0, 0])} Y{_f(tip[0, 1])}")
                lines.append(f"G1 Z{_f(tip[0, 2])} F{machining.plunge:.1f}")
                lines.append(f"F{machining.feed:.1f}")
                lines.extend(f"G1 X{_f(x)} Y{_f(y)} Z{_f(z)}" for x, y, z in tip[1:])
                lines.append(f"G0 Z{_f(safe)}")
                length += float(np.linalg.norm(np.diff(tip, axis=0), axis=1).sum())
                paths += 1
    else:
        assert isinstance(host, Cylinder)
        lines.append(f"G0 Z{_f(machining.safe_z)}")
        for path in np.split(np.arange(len(grooves.point)),
                             np.flatnonzero(np.diff(grooves.stripe)) + 1):
            if path.size < 2:
                continue
            p = grooves.point[path]
            a = np.degrees(np.unwrap(host.angle(p)))
            lines.append(f"(stipple {int(grooves.stipple[path[0]])})")
            lines.append(f"G0 X{_f(p[0, 1])} Y0.0000 A{_f(a[0])}")
            lines.append(f"G1 Z{_f(-tool.depth)} F{machining.plunge:.1f}")
            lines.append(f"F{machining.feed:.1f}")
            lines.extend(f"G1 X{_f(x)} A{_f(aa)}" for x, aa in zip(p[1:, 1], a[1:], strict=True))
            lines.append(f"G0 Z{_f(machining.safe_z)}")
            length += float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
            paths += 1
    if machining.spindle > 0:
        lines.append("M5")
    lines.append("M2")
    return SurfaceProgram("\n".join(lines) + "\n", paths, dropped, length)


_WORD = re.compile(r"([A-Z])([-+]?\d*\.?\d+)")


def check_surface_gcode(text: str, host: Host, tool: Tool, machining: Machining,
                        axes: int = 3, tolerance: float = 2e-3) -> dict[str, Any]:
    """Read a program back and check it cuts no deeper than the groove and
    moves fast only at the safe height.

    This reader shares no code with the writer: a modal interpreter of G0/G1
    with X, Y, Z, A and F words. For 3 axes, every cutting position's ball
    centre (R above the tip) must stay at least R - d from the host surface
    (measured along the host normal of the nearest surface point) and on the
    host's outer side; for 4 axes the tip's Z must stay at or above -d. Rapids
    must be at or above the safe height (Z only moves at a rapid otherwise).

    Returns:
        Figures: cutting moves, rapids, deepest cut.

    Raises:
        SpecholoError: the first violation, with its line number.
    """
    pos = {"X": 0.0, "Y": 0.0, "Z": math.inf, "A": 0.0}
    mode = 0
    cuts: list[tuple[int, float, float, float, float]] = []
    rapids = 0
    safe = None
    for number, raw in enumerate(text.splitlines(), 1):
        line = re.sub(r"\(.*?\)", "", raw).strip().upper()
        if not line:
            continue
        words = dict((k, float(v)) for k, v in _WORD.findall(line.replace(" ", "")))
        if "G" in words:
            g = int(words["G"])
            if g in (0, 1):
                mode = g
        for gm in re.findall(r"G(\d+)", line):
            if int(gm) in (0, 1):
                mode = int(gm)
        moved = any(k in words for k in ("X", "Y", "Z", "A"))
        old_z = pos["Z"]
        for axis in ("X", "Y", "Z", "A"):
            if axis in words:
                pos[axis] = words[axis]
        if not moved:
            continue
        if mode == 0:
            rapids += 1
            if safe is None and "Z" in words and not any(k in words for k in ("X", "Y", "A")):
                safe = pos["Z"]
            if any(k in words for k in ("X", "Y", "A")) and (safe is None or old_z < safe - 1e-9):
                raise SpecholoError(f"line {number}: rapid move below the safe height")
        else:
            cuts.append((number, pos["X"], pos["Y"], pos["Z"], pos["A"]))
    if safe is None:
        raise SpecholoError("no safe height set before the first rapid")
    deepest = 0.0
    if cuts:
        arr = np.array(cuts)
        if axes == 3:
            centre = arr[:, 1:4] + np.array([0.0, 0.0, tool.radius])
            near = host.project(centre)
            n = host.normal(near)
            dist = np.sum((centre - near) * n, axis=1)
            bad = dist < tool.radius - tool.depth - tolerance
            deepest = float(tool.radius - dist.min())
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise SpecholoError(
                    f"line {int(arr[i, 0])}: cuts {tool.radius - dist[i]:.4f} mm into the "
                    f"surface, deeper than the groove's {tool.depth:g} mm")
        else:
            deepest = float(-arr[:, 3].min())
            if deepest > tool.depth + tolerance:
                i = int(np.argmin(arr[:, 3]))
                raise SpecholoError(f"line {int(arr[i, 0])}: cuts {deepest:.4f} mm deep, "
                                    f"deeper than the groove's {tool.depth:g} mm")
    return {"cutting_moves": len(cuts), "rapids": rapids, "deepest_cut_mm": deepest,
            "safe_z": safe}

"""Grooves: the engraved geometry, as chains of circular arcs on the plate.

A groove is a path of vertices on the plate (z = 0) joined by circular arcs,
each given by its *bulge* b = tan(sweep / 4) (the DXF convention): b = 0 is a
straight segment, b > 0 turns counter-clockwise seen from the viewer (+z).
Arcs keep the groove's tangent continuous, which is what places the glints;
G-code (G2/G3), SVG and DXF all carry them exactly. A path of one vertex is a
dot: a plunge that leaves a spherical dimple.
"""

from __future__ import annotations

import contextlib
import math
import os
import zipfile
from dataclasses import dataclass, field
from typing import BinaryIO

import numba as nb
import numpy as np

from specholo._compiling import kernel
from specholo._pages import small_pages
from specholo._threads import chunked
from specholo.errors import SpecholoError

#: Largest coordinate of a groove vertex, mm, as :func:`read_gcode` accepts:
#: a plate is at most metres across, and every sum and square stays finite.
MAX_COORDINATE = 1e9
#: Largest bulge magnitude: tan(sweep / 4) of an arc of one full turn, the
#: largest sweep, is 1.6e16 in doubles.
MAX_BULGE = 1e17


def _arc_geometry(start: np.ndarray, end: np.ndarray,
                  bulge: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Centres (k, 2), radii, start angles and sweeps (k,) of arcs given by bulge."""
    k = bulge.size
    centre = np.empty((k, 2))
    radius = np.empty(k)
    start_angle = np.empty(k)
    sweep = np.empty(k)
    chunked(_arc_geometry_of, 0, k, start, end, bulge, centre, radius, start_angle, sweep,
            grain=4096)
    return centre, radius, start_angle, sweep


@kernel(nogil=True)
def _arc_geometry_of(lo: int, hi: int, start: np.ndarray, end: np.ndarray, bulge: np.ndarray,
                     centre: np.ndarray, radius: np.ndarray, start_angle: np.ndarray,
                     sweep: np.ndarray) -> None:
    """:func:`_arc_geometry` of arcs lo .. hi - 1."""
    for i in range(lo, hi):
        b = bulge[i]
        sweep[i] = 4.0 * math.atan(b)
        if b == 0.0:
            centre[i, 0] = centre[i, 1] = math.nan
            radius[i] = math.inf
            start_angle[i] = math.nan
            continue
        cx, cy = end[i, 0] - start[i, 0], end[i, 1] - start[i, 1]
        offset = (1.0 - b * b) / (4.0 * b)
        # The centre lies off the chord's middle, to its left for b > 0.
        centre[i, 0] = 0.5 * (start[i, 0] + end[i, 0]) - cy * offset
        centre[i, 1] = 0.5 * (start[i, 1] + end[i, 1]) + cx * offset
        radius[i] = math.sqrt(cx * cx + cy * cy) * (1.0 + b * b) / (4.0 * abs(b))
        start_angle[i] = math.atan2(start[i, 1] - centre[i, 1], start[i, 0] - centre[i, 0])


@kernel()
def path_length(vertices: np.ndarray, bulges: np.ndarray, a: int, b: int) -> float:
    """Length of the arcs of vertices a .. b - 1, mm."""
    part = 0.0
    for i in range(a, b - 1):
        dx, dy = vertices[i + 1, 0] - vertices[i, 0], vertices[i + 1, 1] - vertices[i, 1]
        chord = math.sqrt(dx * dx + dy * dy)  # math.hypot is ~7x slower here
        part += chord * _arc_over_chord(abs(bulges[i]))
    return part


@kernel(helper=True)
def _arc_over_chord(t: float) -> float:
    """An arc's length over its chord for |bulge| t: sweep / (2 sin(sweep / 2)) with
    sweep = 4 atan(t), which is atan(t) (1 + t^2) / t."""
    t2 = t * t
    if t < 1e-2:
        # atan(t) / t by its series, exact in double here (the next term is t^8 / 9):
        # the arcs of a design are mostly this flat, and atan is the costly part.
        return (1.0 + t2) * (1.0 - t2 * (1.0 / 3.0 - t2 * (0.2 - t2 / 7.0)))
    return math.atan(t) * (1.0 + t2) / t


@kernel()
def grow_box(vertices: np.ndarray, bulges: np.ndarray, a: int, b: int, lo_x: float,
             lo_y: float, hi_x: float, hi_y: float) -> tuple[float, float, float, float]:
    """The box (lo_x, lo_y, hi_x, hi_y) grown by the arcs of the path of vertices
    a .. b - 1 where they bulge past their ends (the box holds the vertices
    already): a circle's extreme point in each axis direction counts where the
    arc passes it."""
    for i in range(a, b - 1):
        bulge = bulges[i]
        if bulge == 0.0:
            continue
        x, y = vertices[i, 0], vertices[i, 1]
        cx, cy = vertices[i + 1, 0] - x, vertices[i + 1, 1] - y
        if abs(bulge) <= 1.0:
            # A minor arc stays within its sagitta (|bulge| chord / 2, bounded
            # here by the legs) of its chord: one inside the box so far,
            # with room to spare for rounding, cannot grow it.
            pad = 0.5 * abs(bulge) * (abs(cx) + abs(cy)) * (1.0 + 1e-6) + 1e-12
            x2, y2 = x + cx, y + cy
            if min(x, x2) - pad > lo_x and max(x, x2) + pad < hi_x \
                    and min(y, y2) - pad > lo_y and max(y, y2) + pad < hi_y:
                continue
        offset = (1.0 - bulge * bulge) / (4.0 * bulge)
        ox = x + 0.5 * cx - cy * offset
        oy = y + 0.5 * cy + cx * offset
        radius = math.sqrt(cx * cx + cy * cy) * (1.0 + bulge * bulge) / (4.0 * abs(bulge))
        # A point of the circle is on the arc iff it lies on the bulge's side
        # of the chord (minor and major arcs alike): no angles needed.
        if (cx * (oy - y) - cy * (ox + radius - x)) * bulge < 0.0:
            hi_x = max(hi_x, ox + radius)
        if (cx * (oy - y) - cy * (ox - radius - x)) * bulge < 0.0:
            lo_x = min(lo_x, ox - radius)
        if (cx * (oy + radius - y) - cy * (ox - x)) * bulge < 0.0:
            hi_y = max(hi_y, oy + radius)
        if (cx * (oy - radius - y) - cy * (ox - x)) * bulge < 0.0:
            lo_y = min(lo_y, oy - radius)
    return lo_x, lo_y, hi_x, hi_y


@kernel()
def measure_paths(vertices: np.ndarray, bulges: np.ndarray, offsets: np.ndarray, base: int,
                  first: int, stop: int, end: int) -> tuple[float, float, float, float, float]:
    """Box (lo_x, lo_y, hi_x, hi_y) and total length (mm) of paths first .. stop - 1,
    as :meth:`Grooves.measure` finds them: path q is vertices offsets[q] - base up
    to the next path's start, the last up to ``end``.

    Compiled on its own, without the caller's fast-math flags, so the figures are
    the same to the bit however it is called.
    """
    lo_x = lo_y = math.inf
    hi_x = hi_y = -math.inf
    total = 0.0
    # The vertices' box first: few arcs bulge past it, and the others need no
    # look at their circles (:func:`grow_box`).
    for i in range(offsets[first] - base if first < stop else end, end):
        lo_x, hi_x = min(lo_x, vertices[i, 0]), max(hi_x, vertices[i, 0])
        lo_y, hi_y = min(lo_y, vertices[i, 1]), max(hi_y, vertices[i, 1])
    for q in range(first, stop):
        a = offsets[q] - base
        b = offsets[q + 1] - base if q + 1 < stop else end
        total += path_length(vertices, bulges, a, b)
        lo_x, lo_y, hi_x, hi_y = grow_box(vertices, bulges, a, b, lo_x, lo_y, hi_x, hi_y)
    return lo_x, lo_y, hi_x, hi_y, total


@kernel(nogil=True)
def _extent(first: int, stop: int, vertices: np.ndarray, bulges: np.ndarray,
            offsets: np.ndarray, box: np.ndarray, lengths: np.ndarray) -> None:
    """Corners of the centrelines of chunks first .. stop - 1 of the paths (of
    box.shape[0]), arcs counted where they bulge past their ends: lo x, lo y,
    hi x, hi y to ``box`` (chunks, 4).

    One pass over the vertices (:func:`grow_box`), chunks run on threads
    (:meth:`Grooves.measure`). Each path's length goes to ``lengths``
    (n_paths,) on the way, unless it is empty.
    """
    n_paths = offsets.size - 1
    chunks = box.shape[0]
    measure = lengths.size > 0
    for c in range(first, stop):
        lo_x = lo_y = math.inf
        hi_x = hi_y = -math.inf
        for j in range(c * n_paths // chunks, (c + 1) * n_paths // chunks):
            a, b = offsets[j], offsets[j + 1]
            if measure:
                lengths[j] = path_length(vertices, bulges, a, b)
            for i in range(a, b):
                lo_x, hi_x = min(lo_x, vertices[i, 0]), max(hi_x, vertices[i, 0])
                lo_y, hi_y = min(lo_y, vertices[i, 1]), max(hi_y, vertices[i, 1])
            lo_x, lo_y, hi_x, hi_y = grow_box(vertices, bulges, a, b, lo_x, lo_y, hi_x, hi_y)
        box[c, 0], box[c, 1], box[c, 2], box[c, 3] = lo_x, lo_y, hi_x, hi_y


@dataclass(frozen=True)
class Segments:
    """The arcs of a set of grooves as flat arrays (one row per arc).

    Attributes:
        start: (k, 2) start points, mm.
        end: (k, 2) end points, mm.
        bulge: (k,) bulges.
        path: (k,) index of the path each arc belongs to.
    """

    start: np.ndarray
    end: np.ndarray
    bulge: np.ndarray
    path: np.ndarray

    def __len__(self) -> int:
        return len(self.bulge)

    def geometry(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Centres, radii, start angles and signed sweeps of the arcs.

        Straight segments (bulge 0) get an infinite radius and NaN centre.

        Returns:
            centre (k, 2), radius (k,), start angle (k,), sweep (k,) in radians.
        """
        f = np.ascontiguousarray
        return _arc_geometry(f(self.start, dtype=float), f(self.end, dtype=float),
                             f(self.bulge, dtype=float))

    def lengths(self) -> np.ndarray:
        """Arc lengths (k,) in mm."""
        d = self.end - self.start
        chord = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])  # norm along rows, faster
        b = np.abs(self.bulge)
        sweep = 4.0 * np.arctan(b)
        with np.errstate(divide="ignore", invalid="ignore"):
            arc = np.where(b > 1e-12, chord * sweep / (2.0 * np.sin(0.5 * sweep)), chord)
        return arc


@dataclass(frozen=True)
class Grooves:
    """Grooves of a hologram, as a structure of arrays.

    Attributes:
        vertices: (m, 2) vertex positions on the plate in mm.
        bulges: (m,) bulge of the arc from each vertex to the next in its path;
            the last vertex of a path has bulge 0 and no arc.
        offsets: (n_paths + 1,) start of each path in ``vertices``; path j is
            ``vertices[offsets[j]:offsets[j + 1]]``.
        stipple: (n_paths,) id of the stipple each path draws.
        known: the :meth:`extent` (2, 2) and total length (mm), where whoever
            made the arrays found them on the way (None: measured when asked).
    """

    vertices: np.ndarray
    bulges: np.ndarray
    offsets: np.ndarray
    stipple: np.ndarray
    known: tuple[np.ndarray, float] | None = field(default=None, compare=False, repr=False)

    @classmethod
    def empty(cls) -> Grooves:
        """Grooves with no paths."""
        return cls(np.zeros((0, 2)), np.zeros(0), np.zeros(1, dtype=np.int64),
                   np.zeros(0, dtype=np.int64))

    @classmethod
    def concatenate(cls, parts: list[Grooves]) -> Grooves:
        """Join several groove sets into one, keeping path order."""
        parts = [p for p in parts if p.n_paths]
        if not parts:
            return cls.empty()
        if len(parts) == 1:
            return parts[0]
        starts = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
        offsets = np.concatenate(
            [[0]] + [p.offsets[1:] + s for p, s in zip(parts, starts, strict=True)]
        )
        return cls(
            np.concatenate([p.vertices for p in parts]),
            np.concatenate([p.bulges for p in parts]),
            offsets.astype(np.int64),
            np.concatenate([p.stipple for p in parts]).astype(np.int64),
        )

    @property
    def n_paths(self) -> int:
        return len(self.stipple)

    @property
    def path_sizes(self) -> np.ndarray:
        """Number of vertices of each path, shape (n_paths,)."""
        return np.diff(self.offsets)

    def has_empty_path(self) -> bool:
        """Whether some path has no vertex (read from the offsets, no per-path sizes)."""
        o = self.offsets
        return bool(np.any(o[1:] <= o[:-1]))

    @property
    def is_dot(self) -> np.ndarray:
        """(n_paths,) True for single-vertex paths (dimples)."""
        return self.path_sizes == 1

    def arcs(self) -> tuple[np.ndarray, np.ndarray]:
        """The first vertex (k,) and path (k,) of every arc (every vertex but a
        path's last starts one)."""
        last = np.zeros(len(self.vertices), dtype=bool)
        last[self.offsets[1:] - 1] = True
        first = np.flatnonzero(~last)
        return first, np.repeat(np.arange(self.n_paths), self.path_sizes)[first]

    def segments(self) -> Segments:
        """All arcs of all paths as flat arrays."""
        first, path = self.arcs()
        return Segments(self.vertices[first], self.vertices[first + 1], self.bulges[first],
                        path)

    def dots(self) -> tuple[np.ndarray, np.ndarray]:
        """Dimples: positions (k, 2) and path indices (k,)."""
        idx = np.flatnonzero(self.is_dot)
        return self.vertices[self.offsets[idx]], idx

    def total_length(self) -> float:
        """Total groove length in mm (dots count as 0)."""
        return self.extent_and_length()[1]

    def bounds(self) -> np.ndarray:
        """(2, 2) lower-left and upper-right corners of all vertices (mm)."""
        if len(self.vertices) == 0:
            return np.zeros((2, 2))
        # Column by column: numpy reduces an (m, 2) array along its rows ~25x slower.
        x, y = self.vertices[:, 0], self.vertices[:, 1]
        return np.array([[x.min(), y.min()], [x.max(), y.max()]], dtype=float)

    def extent(self) -> np.ndarray:
        """(2, 2) corners of the centrelines, arcs included where they bulge past
        their end points (the tool follows the arc, not its chord); zeros if empty."""
        return self.known[0].copy() if self.known is not None else self.measure(False)[0]

    def extent_and_length(self) -> tuple[np.ndarray, float]:
        """:meth:`extent` (2, 2) and the total length in mm, from one pass over the
        arcs (none if known)."""
        if self.known is not None:
            return self.known[0].copy(), self.known[1]
        extent, lengths = self.measure()
        return extent, float(lengths.sum())

    def measure(self, lengths: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`extent` and, in the same pass over the arcs, each path's length.

        Returns:
            extent (2, 2) and lengths (n_paths,) in mm (empty if not asked for).
        """
        out = np.zeros(self.n_paths if lengths else 0)
        if len(self.vertices) == 0:
            return np.zeros((2, 2)), out
        f = np.ascontiguousarray
        chunks = max(1, min(4 * nb.get_num_threads(), self.n_paths))
        box = np.empty((chunks, 4))
        chunked(_extent, 0, chunks, f(self.vertices, dtype=float), f(self.bulges, dtype=float),
                f(self.offsets, dtype=np.int64), box, out)
        extent = np.array([[box[:, 0].min(), box[:, 1].min()],
                           [box[:, 2].max(), box[:, 3].max()]])
        return extent, out

    def take(self, paths: np.ndarray) -> Grooves:
        """The given paths (k,), in that order, as grooves of their own."""
        paths = np.asarray(paths, dtype=np.int64)
        offsets = np.asarray(self.offsets, dtype=np.int64)
        starts = offsets[paths]
        sizes = offsets[paths + 1] - starts
        first = np.cumsum(sizes) - sizes  # where each path begins in the output
        idx = np.repeat(starts - first, sizes) + np.arange(int(sizes.sum()), dtype=np.int64)
        return Grooves(self.vertices[idx], self.bulges[idx],
                       np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                       self.stipple[paths])

    def save(self, path: str | os.PathLike[str] | BinaryIO) -> None:
        """Write to an ``.npz`` file, or an open binary file (the caller makes the
        write atomic).

        The vertices and bulges are stored as they are: doubles that deflate by
        only 5% and 17%, at 40 MB/s (4.5 of the 19 s a design of 2 x 10^4
        stipples took, minutes at 10^6). The offsets and stipple ids deflate to
        a fifth, at the fastest level, which does as well here as the default.
        """
        with contextlib.ExitStack() as files:
            fh = path if hasattr(path, "write") else files.enter_context(open(path, "wb"))
            zf = files.enter_context(zipfile.ZipFile(fh, "w", zipfile.ZIP_DEFLATED,
                                                     compresslevel=1))
            for name, arr, deflate in (("vertices", self.vertices, False),
                                       ("bulges", self.bulges, False),
                                       ("offsets", self.offsets, True),
                                       ("stipple", self.stipple, True)):
                # A ZipInfo of its own keeps the 1980 timestamp: the same bytes every run.
                member = f"{name}.npy" if deflate else zipfile.ZipInfo(f"{name}.npy")
                with zf.open(member, "w", force_zip64=True) as out:
                    np.lib.format.write_array(out, np.asanyarray(arr), allow_pickle=False)

    @classmethod
    def load(cls, path: str | os.PathLike[str], stipples: int | None = None) -> Grooves:
        """Read grooves written by :meth:`save` (or ``np.savez``), checked as
        :meth:`validate` checks them.

        Args:
            path: the ``.npz`` file.
            stipples: the number of stipples the ids must lie below, if known.

        Raises:
            SpecholoError: an unreadable file, or arrays the grooves cannot be.
        """
        from specholo.readback import ArraySpec, load_arrays

        a = load_arrays(path, {"vertices": ArraySpec((None, 2)), "bulges": ArraySpec((None,)),
                               "offsets": ArraySpec((None,), np.int64),
                               "stipple": ArraySpec((None,), np.int64)})
        grooves = cls(a["vertices"], a["bulges"], a["offsets"], a["stipple"])
        grooves.validate(stipples, os.fspath(path))
        return grooves

    def validate(self, stipples: int | None = None, where: str = "grooves") -> None:
        """Refuse arrays that are not grooves, before any compiled kernel indexes them.

        The kernels trust the offsets to bound every path within the vertices
        and the ids to index the stipples; NaN or huge coordinates and bulges
        would reach integer conversions (pixels, grid cells) whose result is
        undefined. One pass over each array, a chunk at a time.

        Args:
            stipples: the number of stipples the ids must lie below, if known.
            where: what to name in a refusal (the file).

        Raises:
            SpecholoError: naming ``where`` and the first thing wrong.
        """
        from specholo.readback import bounded, check_offsets, within

        v, b, o, s = self.vertices, self.bulges, self.offsets, self.stipple
        if not all(isinstance(x, np.ndarray) for x in (v, b, o, s)):
            raise SpecholoError(f"{where}: grooves must be numpy arrays")
        if v.ndim != 2 or v.shape[1] != 2 or v.dtype.kind != "f":
            raise SpecholoError(f"{where}: vertices must be (m, 2) floats, got {v.dtype} "
                                f"{v.shape}")
        m = len(v)
        if b.shape != (m,) or b.dtype.kind != "f":
            raise SpecholoError(f"{where}: bulges must be one float per vertex ({m}), got "
                                f"{b.dtype} {b.shape}")
        if o.ndim != 1 or len(o) == 0 or o.dtype.kind not in "iu":
            raise SpecholoError(f"{where}: offsets must be integers, one more than the paths")
        if s.shape != (len(o) - 1,) or s.dtype.kind not in "iu":
            raise SpecholoError(f"{where}: stipple ids must be one integer per path "
                                f"({len(o) - 1}), got {s.dtype} {s.shape}")
        if not bounded(v, MAX_COORDINATE):
            raise SpecholoError(f"{where}: vertices must be finite and within "
                                f"{MAX_COORDINATE:g} mm of the plate centre")
        if not bounded(b, MAX_BULGE):
            raise SpecholoError(f"{where}: bulges must be finite numbers within {MAX_BULGE:g}")
        check_offsets(o, m, where)
        top = np.iinfo(np.int64).max if stipples is None else stipples - 1
        if len(s) and not within(s, 0, top):
            below = "" if stipples is None else f" and below the {stipples} stipples"
            raise SpecholoError(f"{where}: stipple ids must be 0 or more{below}, got "
                                f"{int(s.min())} to {int(s.max())}")


class GroovesBuilder:
    """Grooves assembled part by part without holding the parts and the whole at once.

    Storage is reserved up front where the caller knows a bound (:meth:`reserve`):
    untouched pages of a reservation take no memory, so a generous bound costs
    nothing, and parts are written straight into it (:meth:`extend`). Past the
    reservation the arrays grow in place (``ndarray.resize``). :meth:`build`
    hands back the used rows, trimming the rest without a copy.
    """

    def __init__(self) -> None:
        self._vertices = np.zeros((0, 2))
        self._bulges = np.zeros(0)
        self._offsets = np.zeros(1, dtype=np.int64)
        self._stipple = np.zeros(0, dtype=np.int64)
        self._n_vertices = 0
        self._n_paths = 0
        # Box (lo_x, lo_y, hi_x, hi_y) and length of the parts, while every part's are known.
        self._box: list[float] | None = [math.inf, math.inf, -math.inf, -math.inf]
        self._length = 0.0
        self._noted = True

    def reserve(self, vertices: int, paths: int) -> None:
        """Room for at least this many vertices and paths in all (before any part)."""
        if self._n_vertices or self._n_paths:
            raise ValueError("reserve before adding any part")
        try:
            with small_pages():  # written once, at several times the speed
                self._vertices = np.empty((max(vertices, 0), 2))
                self._bulges = np.empty(max(vertices, 0))
                self._offsets = np.empty(max(paths, 0) + 1, dtype=np.int64)
                self._stipple = np.empty(max(paths, 0), dtype=np.int64)
        except MemoryError:  # the system refuses the address space: grow as needed
            self.__init__()  # type: ignore[misc]
        self._offsets[0] = 0

    @staticmethod
    def _room(a: np.ndarray, need: int) -> np.ndarray:
        if need > len(a):
            a.resize((need,) + a.shape[1:], refcheck=False)
        return a

    def extend(self, vertices: int,
               paths: int) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Rows for a part of this many vertices and paths, to be filled by the caller.

        Returns:
            The part's first vertex index, and views into the builder's
            storage: vertices (vertices, 2), bulges (vertices,), path start
            offsets (paths,) (indices into the whole, so that first vertex
            plus the part's own) and stipples (paths,).
        """
        if not self._noted:
            self._box = None  # the previous part was never noted
        self._noted = False
        v0, p0 = self._n_vertices, self._n_paths
        v1, p1 = v0 + vertices, p0 + paths
        self._vertices = self._room(self._vertices, v1)
        self._bulges = self._room(self._bulges, v1)
        self._offsets = self._room(self._offsets, p1 + 1)
        self._stipple = self._room(self._stipple, p1)
        self._n_vertices, self._n_paths = v1, p1
        return (v0, self._vertices[v0:v1], self._bulges[v0:v1], self._offsets[p0:p1],
                self._stipple[p0:p1])

    def note(self, box: np.ndarray, length: float) -> None:
        """Record the extent of the part last extended, as lo_x, lo_y, hi_x, hi_y
        (4,), and its total length (mm), so that :meth:`build` need not measure."""
        if self._box is not None and not self._noted:
            lo_x, lo_y, hi_x, hi_y = (float(v) for v in box)
            b = self._box
            self._box = [min(b[0], lo_x), min(b[1], lo_y), max(b[2], hi_x), max(b[3], hi_y)]
            self._length += float(length)
        self._noted = True

    def add(self, part: Grooves) -> None:
        """Append a part's paths after those already added."""
        if not part.n_paths:
            return
        base, v, b, o, s = self.extend(len(part.vertices), part.n_paths)
        v[:], b[:], s[:] = part.vertices, part.bulges, part.stipple
        o[:] = part.offsets[:-1] + base
        extent, length = part.extent_and_length()
        self.note(extent.ravel(), length)

    def build(self) -> Grooves:
        """The grooves added so far (the builder must not be used afterwards)."""
        nv, npath = self._n_vertices, self._n_paths
        self._offsets = self._room(self._offsets, npath + 1)
        self._offsets[npath] = nv
        arrays = []
        for a, n in ((self._vertices, nv), (self._bulges, nv), (self._offsets, npath + 1),
                     (self._stipple, npath)):
            if len(a) > n:
                a.resize((n,) + a.shape[1:], refcheck=False)  # shrinks in place
            arrays.append(a)
        known = None
        if self._box is not None and self._noted and npath:
            known = (np.array(self._box).reshape(2, 2), self._length)
        out = Grooves(arrays[0], arrays[1], arrays[2], arrays[3], known=known)
        self.__init__()  # type: ignore[misc]
        return out


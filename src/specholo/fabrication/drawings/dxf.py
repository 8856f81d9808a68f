"""DXF drawing of the grooves, in mm, for CAD/CAM programs and laser software.

Each groove is an LWPOLYLINE whose vertices carry their bulges, so arcs stay
exact arcs (the DXF bulge is the same tan(sweep / 4) the grooves use, and DXF,
like the plate, has y up: nothing is flipped). Coordinates are written with 9
decimals (1e-9 mm) and bulges with 12 (the sweep within 4e-12 rad), trailing
zeros left out; the dots' radii and the extents keep Python's shortest
round-trip text.
Arcs the other exporters draw straight (:func:`~specholo.fabrication.exporting.is_straight`)
get bulge 0 here too: a near-zero bulge means a near-infinite radius, which
some CAD programs mishandle.

A dot (single plunge) is a CIRCLE as wide as its dimple, centred on the plunge.
POINT entities would be the literal choice, but laser software and many
viewers do not show or select them; a circle is visible, drawn at the true
dimple size, and CAM drilling operations take circle centres as drill points.

Layers are those of :func:`~specholo.fabrication.drawings.svg.plan_layers`: grooves and
dots of each depth class, named like ``GROOVES_D0.080_R0.250`` (depth and ball
radius in mm), each in its own colour. The drawing is in the plate frame (x
right, y up, origin at the plate centre), $INSUNITS = 4 (mm), $MEASUREMENT = 1.

The layer ``PLATE`` holds the plate (:mod:`~specholo.fabrication.plate`): its
outline as a closed LWPOLYLINE and each registration mark as two LINEs (a
crosshair) and a CIRCLE, in the colour of the SVG's plate layer. The extents
and the initial view take in the whole plate.

The same grooves give the same file byte for byte: the drawing's dates and
GUIDs, which ezdxf would otherwise take from the clock and a random source,
are its fixed values (1 January 2000 and the constant GUID), and its classes
are listed in name order, not in the order of a set of strings.

The ENTITIES section is written here, not by ezdxf, a chunk of paths at a time
and formatted by a compiled loop (:class:`~specholo.fabrication.exporting.TextRows`):
adding 10^5 entities one by one through ezdxf takes minutes and holds the whole
drawing in memory, and even Python's float text costs microseconds a number.
ezdxf writes the rest of the drawing (header, tables, objects) with an empty
modelspace and the entities go in its place, laid out as ezdxf lays them out,
with the handles ezdxf would have given them: each layer's entities take the
handles after the layer's own, and $HANDSEED lies past them all. The plate's
few entities are ezdxf's own, added after the grooves' handles are taken, so
they and their handles are the same on every run too; the grooves are written
before them.
"""

from __future__ import annotations

import contextlib
import io
import os
from collections.abc import Iterator
from typing import Any

import ezdxf
import numpy as np
from ezdxf import units

from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open
from specholo.fabrication.drawings.svg import (
    PLATE_COLOUR,
    PLATE_LAYER_NAME,
    Layer,
    drawing_bounds,
    plan_layers,
    take_paths,
)
from specholo.fabrication.exporting import (
    TextRows,
    check_grooves,
    drawn_extent,
    format_number,
    in_order,
    is_straight,
    path_chunks,
)
from specholo.fabrication.plate import Plate
from specholo.setup import Tool
from specholo.toolpaths.grooves import Grooves

#: DXF version written: R2010 has LWPOLYLINE, $INSUNITS and UTF-8 text, and
#: every current CAD/CAM or laser program reads it.
DXF_VERSION = "R2010"

_CHUNK_ROWS = 1 << 16
#: Decimals of the written coordinates (mm; 1e-9 mm keeps every vertex within
#: check_grooves' 1e9 mm in an int64) and bulges.
_DECIMALS = 9
_SCALE = 10**_DECIMALS
_BULGE_DECIMALS = 12
_BULGE_SCALE = 10**_BULGE_DECIMALS
# Larger bulges (sweeps within 4e-6 rad of a full turn) are written with one
# decimal: the sweep moves by 4 db / (1 + b^2), so that is still finer.
_BIG_BULGE = 1e6
_MAX_BULGE = 1e17
# where ezdxf writes the modelspace (the plate's entities only)
_ENTITIES = "  0\nSECTION\n  2\nENTITIES\n"


@contextlib.contextmanager
def _reproducible() -> Iterator[None]:
    """ezdxf's fixed dates, GUIDs and marker strings while a drawing is made or written."""
    before = ezdxf.options.write_fixed_meta_data_for_testing
    ezdxf.options.write_fixed_meta_data_for_testing = True
    try:
        yield
    finally:
        ezdxf.options.write_fixed_meta_data_for_testing = before


def _written_bulges(g: Grooves) -> np.ndarray:
    """(m,) bulge written at each vertex: 0 after a path's last vertex and for
    arcs drawn straight."""
    m = len(g.vertices)
    last = np.zeros(m, dtype=bool)
    last[g.offsets[1:] - 1] = True
    bulge = np.zeros(m)
    segs = g.segments()
    bulge[~last] = np.where(is_straight(segs), 0.0, segs.bulge)
    return bulge


def _polylines(g: Grooves, first_handle: int, layer: str, owner: str) -> bytes:
    """The DXF text of the paths of ``g`` as LWPOLYLINEs (a vertex's bulge only
    when it is not 0), with handles from ``first_handle``."""
    verts = g.vertices.reshape(-1, 2)
    m = len(verts)
    first = np.zeros(m, dtype=bool)
    first[g.offsets[:-1]] = True
    handle = np.cumsum(first) - 1 + first_handle
    count = np.repeat(g.path_sizes, g.path_sizes)
    bulge = _written_bulges(g)
    q = np.rint(verts * _SCALE).astype(np.int64)
    big = np.abs(bulge) >= _BIG_BULGE
    qb = np.rint(np.where(big, 0.0, bulge) * _BULGE_SCALE).astype(np.int64)
    qbig = np.rint(np.clip(np.where(big, bulge, 0.0), -_MAX_BULGE, _MAX_BULGE)
                   * 10).astype(np.int64)
    bent = (qb != 0) | big
    t = TextRows(m)
    t.text("  0\nLWPOLYLINE\n  5\n", first)
    t.hex(handle, first)
    t.text(f"\n330\n{owner}\n100\nAcDbEntity\n  8\n{layer}\n100\nAcDbPolyline\n 90\n", first)
    t.number(count, 0, first)
    t.text("\n 70\n0\n", first)
    t.text(" 10\n")
    t.number(q[:, 0], _DECIMALS, trim=True)
    t.text("\n 20\n")
    t.number(q[:, 1], _DECIMALS, trim=True)
    t.text("\n")
    t.text(" 42\n", bent)
    t.number(qb, _BULGE_DECIMALS, bent & ~big, trim=True)
    t.number(qbig, 1, big, trim=True)
    t.text("\n", bent)
    return t.tobytes()


def _circles(g: Grooves, first_handle: int, layer: str, owner: str, radius: float) -> bytes:
    """The DXF text of the dots of ``g`` as CIRCLEs of ``radius``, handles from
    ``first_handle``."""
    centres = g.vertices.reshape(-1, 2)[g.offsets[:-1]]
    q = np.rint(centres * _SCALE).astype(np.int64)
    t = TextRows(len(centres))
    t.text("  0\nCIRCLE\n  5\n")
    t.hex(np.arange(first_handle, first_handle + len(centres)))
    t.text(f"\n330\n{owner}\n100\nAcDbEntity\n  8\n{layer}\n100\nAcDbCircle\n 10\n")
    t.number(q[:, 0], _DECIMALS, trim=True)
    t.text("\n 20\n")
    t.number(q[:, 1], _DECIMALS, trim=True)
    t.text(f"\n 30\n0.0\n 40\n{float(radius)!r}\n")
    return t.tobytes()


def _add_plate(msp: Any, plate: Plate) -> None:
    """The plate's outline and registration marks on layer ``PLATE`` of the modelspace."""
    attribs = {"layer": PLATE_LAYER_NAME}
    msp.add_lwpolyline([(float(x), float(y)) for x, y in plate.corners()], close=True,
                       dxfattribs=attribs)
    arm, r = plate.mark_arm, plate.mark_radius
    for x, y in plate.marks():
        x, y = float(x), float(y)
        msp.add_line((x - arm, y), (x + arm, y), dxfattribs=attribs)
        msp.add_line((x, y - arm), (x, y + arm), dxfattribs=attribs)
        msp.add_circle((x, y), r, dxfattribs=attribs)


def write_dxf(path: str | os.PathLike[str], grooves: Grooves, tool: Tool,
              depths: np.ndarray | None = None, plate: Plate | None = None,
              cut: tuple[float, float] | None = None) -> list[Layer]:
    """Write the grooves as a DXF drawing in mm, atomically, a chunk of paths at a time.

    Args:
        path: destination ``.dxf`` file.
        grooves: m vertices in n paths; paths of one vertex are dots.
        tool: ball-end tool; with its depth (or ``depths``) it sets the layer
            names and the dots' diameter.
        depths: optional (n,) depth of each path, mm; each depth class gets its
            own groove and dot layers.
        plate: the plate, drawn on layer ``PLATE`` with its registration marks;
            default the plate fitted to the grooves
            (:func:`~specholo.fabrication.plate.fit_plate`).
        cut: (depth, width) mm of the grooves as cut, where the tool is not the
            ball ``tool`` models (see :func:`~specholo.fabrication.drawings.svg.plan_layers`).

    Returns:
        The groove and dot layers written (non-empty ones only), by number.

    Raises:
        SpecholoError: if the grooves hold an empty path or non-finite numbers,
            or ``depths`` is malformed.
    """
    check_grooves(grooves)
    layers = plan_layers(grooves, tool, depths, cut)

    with _reproducible():
        doc = ezdxf.new(DXF_VERSION, units=units.MM)
    doc.header["$MEASUREMENT"] = 1  # metric
    msp = doc.modelspace()
    owner = msp.block_record.dxf.handle
    r = format_number(tool.radius, 3)
    handles = doc.entitydb.handles
    first_handles = []
    for layer in layers:
        entry = doc.layers.add(layer.name, color=layer.aci)
        kind = "dots (plunges)" if layer.dots else "grooves"
        entry.description = (f"specholo {kind}: depth {format_number(layer.depth, 4)} mm, "
                             f"ball radius {r} mm, width {format_number(layer.width, 4)} mm")
        # the layer's entities take the next handles, as when ezdxf adds them
        first = int(str(handles), 16)
        first_handles.append(first)
        handles.reset(f"{first + len(layer.paths):X}")
    widest = max([layer.width for layer in layers] or [tool.width])
    if plate is None:
        plate = Plate.fitted(drawn_extent(grooves), widest)
    entry = doc.layers.add(PLATE_LAYER_NAME, color=PLATE_COLOUR[0])
    entry.description = (f"specholo plate {format_number(plate.width, 4)} x "
                         f"{format_number(plate.height, 4)} mm and registration marks: "
                         "crosshair and circle inside each corner and at the origin")
    _add_plate(msp, plate)

    # extents and the initial view, so viewers open on the drawing and the plate
    box = drawing_bounds(grooves, 0.5 * widest)
    lo, hi = plate.box if box is None else (np.minimum(box[0], plate.box[0]),
                                            np.maximum(box[1], plate.box[1]))
    # ezdxf copies these into $EXTMIN/$EXTMAX
    msp.dxf.extmin = (float(lo[0]), float(lo[1]), 0.0)
    msp.dxf.extmax = (float(hi[0]), float(hi[1]), 0.0)
    size = float(max(hi[0] - lo[0], hi[1] - lo[1], 1.0))
    doc.set_modelspace_vport(1.1 * size, center=(float(0.5 * (lo[0] + hi[0])),
                                                 float(0.5 * (lo[1] + hi[1]))))

    text = io.StringIO()
    # The CLASSES section lists the entity types in use in the order of a set,
    # which changes with the string hash seed: list them sorted instead.
    in_use = doc.entitydb.dxf_types_in_use
    doc.entitydb.dxf_types_in_use = lambda: sorted(in_use())  # type: ignore[method-assign,assignment,return-value]
    with _reproducible():
        doc.write(text)
    drawing = text.getvalue()
    at = drawing.find(_ENTITIES)
    if at < 0 or drawing.find(_ENTITIES, at + 1) >= 0:
        raise SpecholoError(f"ezdxf {ezdxf.__version__} wrote no single ENTITIES section")
    at += len(_ENTITIES)  # the grooves go before the plate's entities
    with atomic_open(path, "wb") as fh:
        fh.write(doc.encode(drawing[:at]))
        for layer, first in zip(layers, first_handles, strict=True):
            def entities(a: int, b: int, layer: Layer = layer, first: int = first) -> bytes:
                g = take_paths(grooves, layer.paths[a:b])
                if layer.dots:
                    return _circles(g, first + a, layer.name, owner, 0.5 * layer.width)
                return _polylines(g, first + a, layer.name, owner)

            for chunk in in_order(entities, path_chunks(grooves, _CHUNK_ROWS, layer.paths)):
                fh.write(chunk)
        fh.write(doc.encode(drawing[at:]))
    return layers

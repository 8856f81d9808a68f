"""DXF drawing of the grooves, in mm, for CAD/CAM programs and laser software.

Each groove is an LWPOLYLINE whose vertices carry their bulges, so arcs stay
exact arcs (the DXF bulge is the same tan(sweep / 4) the grooves use, and DXF,
like the plate, has y up: nothing is flipped). Coordinates and bulges are
written with Python's shortest round-trip text, so they read back bit for bit.
Arcs the other exporters draw straight (:func:`~specholo.fabrication.gcode.is_straight`)
get bulge 0 here too: a near-zero bulge means a near-infinite radius, which
some CAD programs mishandle.

A dot (single plunge) is a CIRCLE as wide as its dimple, centred on the plunge.
POINT entities would be the literal choice, but laser software and many
viewers do not show or select them; a circle is visible, drawn at the true
dimple size, and CAM drilling operations take circle centres as drill points.

Layers are those of :func:`~specholo.fabrication.svg.plan_layers`: grooves and
dots of each depth class, named like ``GROOVES_D0.080_R0.250`` (depth and ball
radius in mm), each in its own colour. The drawing is in the plate frame (x
right, y up, origin at the plate centre), $INSUNITS = 4 (mm), $MEASUREMENT = 1.

The same grooves give the same file byte for byte: the drawing's dates and
GUIDs, which ezdxf would otherwise take from the clock and a random source,
are its fixed values (1 January 2000 and the constant GUID), and its classes
are listed in name order, not in the order of a set of strings.
"""

from __future__ import annotations

import contextlib
import io
import os
from collections.abc import Iterator

import ezdxf
import numpy as np
from ezdxf import units

from specholo.fabrication.atomic import atomic_open
from specholo.fabrication.gcode import check_grooves, format_number, is_straight
from specholo.fabrication.svg import Layer, arc_bounds, plan_layers
from specholo.setup import Tool
from specholo.toolpaths.grooves import Grooves

#: DXF version written: R2010 has LWPOLYLINE, $INSUNITS and UTF-8 text, and
#: every current CAD/CAM or laser program reads it.
DXF_VERSION = "R2010"


@contextlib.contextmanager
def _reproducible() -> Iterator[None]:
    """ezdxf's fixed dates, GUIDs and marker strings while a drawing is made or written."""
    before = ezdxf.options.write_fixed_meta_data_for_testing
    ezdxf.options.write_fixed_meta_data_for_testing = True
    try:
        yield
    finally:
        ezdxf.options.write_fixed_meta_data_for_testing = before


def write_dxf(path: str | os.PathLike[str], grooves: Grooves, tool: Tool,
              depths: np.ndarray | None = None) -> list[Layer]:
    """Write the grooves as a DXF drawing in mm, atomically.

    Args:
        path: destination ``.dxf`` file.
        grooves: m vertices in n paths; paths of one vertex are dots.
        tool: ball-end tool; with its depth (or ``depths``) it sets the layer
            names and the dots' diameter.
        depths: optional (n,) depth of each path, mm; each depth class gets its
            own groove and dot layers.

    Returns:
        The layers written (non-empty ones only), by number.

    Raises:
        SpecholoError: if the grooves hold an empty path or non-finite numbers,
            or ``depths`` is malformed.
    """
    check_grooves(grooves)
    layers = plan_layers(grooves, tool, depths)
    verts = np.asarray(grooves.vertices, dtype=float).reshape(-1, 2)
    offsets = np.asarray(grooves.offsets, dtype=np.int64)
    m = len(verts)

    segs = grooves.segments()
    last = np.zeros(m, dtype=bool)
    last[offsets[1:] - 1] = True
    bulge = np.zeros(m)
    bulge[~last] = np.where(is_straight(segs), 0.0, segs.bulge)
    # one [x, y, bulge] row per vertex, as Python floats for ezdxf
    xyb = np.column_stack([verts, bulge]).tolist()

    with _reproducible():
        doc = ezdxf.new(DXF_VERSION, units=units.MM)
    doc.header["$MEASUREMENT"] = 1  # metric
    msp = doc.modelspace()
    r = format_number(tool.radius, 3)
    for layer in layers:
        entry = doc.layers.add(layer.name, color=layer.aci)
        kind = "dots (plunges)" if layer.dots else "grooves"
        entry.description = (f"specholo {kind}: depth {format_number(layer.depth, 4)} mm, "
                             f"ball radius {r} mm, width {format_number(layer.width, 4)} mm")
        attribs = {"layer": layer.name}
        starts = offsets[layer.paths]
        if layer.dots:
            radius = 0.5 * layer.width
            for i in starts.tolist():
                msp.add_circle(xyb[i][:2], radius, dxfattribs=attribs)
        else:
            for i, j in zip(starts.tolist(), offsets[layer.paths + 1].tolist(), strict=True):
                msp.add_lwpolyline(xyb[i:j], format="xyb", dxfattribs=attribs)

    # extents and the initial view, so viewers open on the drawing
    dots, _ = grooves.dots()
    half = 0.5 * max([layer.width for layer in layers] or [tool.width])
    parts = [dots - half, dots + half] + ([arc_bounds(segs)] if len(segs) else [])
    extent = np.concatenate(parts) if m else np.zeros((1, 2))
    lo, hi = extent.min(axis=0), extent.max(axis=0)
    if m:  # ezdxf copies these into $EXTMIN/$EXTMAX; an empty drawing keeps its "no extents"
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
    with atomic_open(path, "wb") as fh:
        fh.write(doc.encode(text.getvalue()))
    return layers

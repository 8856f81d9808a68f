"""Drawings of the grooves: SVG (:mod:`.svg`) and DXF (:mod:`.dxf`) for plotters,
lasers and CAD, and PDF patterns to print (:mod:`.pattern`, :mod:`.stroke_pattern`
for scratching by hand, :mod:`.sheet` for a test coupon's sheet)."""

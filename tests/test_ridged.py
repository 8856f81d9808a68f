"""Ridged full-parallax plates: glints on the sightlines, shared plate, outputs."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

from specholo.errors import SpecholoError
from specholo.fabrication.check import Stock, check_gcode
from specholo.fabrication.heightmap import (
    HeightMap,
    read_image,
    tool_tip,
    write_images,
    write_raster_gcode,
    write_stl,
)
from specholo.optics.surfaces import Kind
from specholo.setup import Light, Machining, Setup, Viewer
from specholo.simulation.heightfield import (
    SlopeIndex,
    crossing_labels,
    find_field_glints,
    head_eyes,
    verify_field,
)
from specholo.toolpaths.ridged import RidgedPlate, RidgeOptions, design_ridged

SETUP = Setup(light=Light(math.radians(45.0)), viewer=Viewer(600.0, 0.0, math.radians(20.0)))
POINTS = np.array([[-4.0, 2.0, -20.0], [5.0, -3.0, -35.0], [0.0, 6.0, -12.0],
                   [3.0, 3.0, 15.0], [-6.0, -5.0, -50.0], [1.0, -1.0, -0.2]])


@pytest.fixture(scope="module")
def plate() -> RidgedPlate:
    return design_ridged(POINTS, None, None, SETUP,
                         RidgeOptions(delta=0.1, elevation_range=math.radians(10.0)))


def test_heights_stay_in_the_shell_and_every_stipple_keeps_a_region(plate):
    z = plate.heights.z
    assert z.max() <= 0.0 and z.min() >= -2.0 * plate.delta - 1e-6
    assert plate.dropped.size == 0 and np.all(plate.kept > 0) and np.all(plate.kept <= 1)
    assert plate.kind[5] == Kind.DOT and plate.optics.sigma[3] == 1.0


def _sightline_distance(glint: np.ndarray, eye: np.ndarray, p: np.ndarray) -> float:
    d = p - eye
    return float(np.linalg.norm(np.cross(glint - eye, d)) / np.linalg.norm(d))


def test_glints_land_on_the_sightline_for_eyes_the_region_serves(plate):
    """Random eyes over azimuth and elevation: where the region holds the sightline
    crossing (a few cells in), the glint lies on the sightline through p."""
    hm = plate.heights
    index = SlopeIndex.build(hm)
    rng = np.random.default_rng(3)
    ids = np.arange(len(POINTS))
    served = lit = 0
    worst = 0.0
    az_seen, el_seen = [], []
    for _ in range(120):
        az = rng.uniform(-0.35, 0.35)
        el = rng.uniform(-0.17, 0.17)
        eye = 600.0 * np.array([math.cos(el) * math.sin(az), math.sin(el),
                                math.cos(el) * math.cos(az)])
        inside = crossing_labels(hm, eye, POINTS, -plate.delta) == ids
        for dx, dy in ((0.1, 0), (-0.1, 0), (0, 0.1), (0, -0.1)):
            shifted = POINTS + np.array([dx, dy, 0.0]) * (1 - POINTS[:, 2:] / eye[2])
            inside &= crossing_labels(hm, eye, shifted, -plate.delta) == ids
        inside[5] = False  # the dot shows its cap, near p but not on the sightline
        glints = find_field_glints(index, eye, SETUP.light)
        for j in np.flatnonzero(inside):
            served += 1
            k = np.flatnonzero(glints.glints.stipple == j)
            if k.size:
                lit += 1
                az_seen.append(az)
                el_seen.append(el)
                worst = max(worst, max(_sightline_distance(glints.glints.point[i], eye, POINTS[j])
                                       for i in k))
    assert served > 50
    assert lit >= 0.5 * served  # the rest fall in riser shadows
    assert worst < 0.04
    # Both horizontal and vertical motion were exercised.
    assert np.ptp(az_seen) > 0.4 and np.ptp(el_seen) > 0.2


def test_patches_do_not_overlap(plate):
    """One stipple per cell, and every facet cell lies on a level set of its own
    stipple's optic (the rest are risers, shell floor or a dot)."""
    hm = plate.heights
    labels = hm.labels
    assert labels is not None and labels.shape == hm.z.shape
    ratio = round(plate.block / hm.resolution)
    np.testing.assert_array_equal(labels, np.repeat(np.repeat(plate.block_labels, ratio, 0),
                                                    ratio, 1))
    yy, xx = np.meshgrid(hm.y, hm.x, indexing="ij")
    for j in range(5):
        cells = np.flatnonzero((labels == j).ravel())[::7]
        s = np.stack([xx.ravel()[cells], yy.ravel()[cells], hm.z.ravel()[cells]], axis=1)
        k = (plate.optics.phi(s, np.full(len(cells), j)) - plate.level0[j]) / plate.step[j]
        on_facet = np.abs(k - np.rint(k)) < 1e-3
        assert on_facet.mean() > 0.85
        # ...and not on another stipple's foliation.
        other = (j + 1) % 5
        k2 = (plate.optics.phi(s, np.full(len(cells), other)) - plate.level0[other]) \
            / plate.step[other]
        assert (np.abs(k2 - np.rint(k2)) < 1e-3).mean() < 0.2
    # Kept shares recount from the block raster.
    area = np.bincount(plate.block_labels[plate.block_labels >= 0], minlength=len(POINTS))
    np.testing.assert_allclose(plate.area, area * plate.block**2)


def test_verify_reports_azimuth_and_elevation(plate):
    reports = verify_field(plate.heights, POINTS, SETUP, azimuths=np.radians([-10.0, 10.0]),
                           elevations=np.radians([-5.0, 5.0]), shell=plate.delta)
    angles = np.array([(r.azimuth, r.elevation) for r in reports])
    np.testing.assert_allclose(angles, [(-10, -5), (-10, 5), (10, -5), (10, 5)])
    errors = [r.max_error for r in reports if not math.isnan(r.max_error)]
    assert errors and max(errors) < 0.3
    left, right = head_eyes(SETUP.viewer, 0.0, math.radians(10.0))
    assert left[1] == right[1] == pytest.approx(600.0 * math.sin(math.radians(10.0)))
    assert np.linalg.norm(right - left) == pytest.approx(SETUP.viewer.ipd)


def test_images_round_trip_to_the_quantisation_step(tmp_path: Path):
    rng = np.random.default_rng(0)
    z = -rng.uniform(0.0, 0.2, (37, 53)).astype(np.float32)
    z[0, 0] = 0.0
    hm = HeightMap(z, np.array([-2.5, 1.25]), 0.05)
    scale = write_images(tmp_path / "plate", hm)
    step = scale["z_step_mm"]
    for name in ("plate.png", "plate.tif"):
        back = read_image(tmp_path / name)
        np.testing.assert_allclose(back.origin, hm.origin)
        assert back.resolution == pytest.approx(hm.resolution)
        assert np.max(np.abs(back.z.astype(float) - z)) <= 0.5 * step + 1e-7
    sidecar = json.loads((tmp_path / "plate.json").read_text())
    assert sidecar["mm_per_px"] == 0.05 and sidecar["images"] == ["plate.png", "plate.tif"]
    assert sidecar["z_min_mm"] == pytest.approx(float(z.min()))


def test_stl_is_watertight(tmp_path: Path, plate):
    hm = plate.heights
    crop = HeightMap(hm.z[:200, :300], hm.origin, hm.resolution)
    mesh = write_stl(tmp_path / "plate.stl", crop, thickness=2.0)
    back = trimesh.load(tmp_path / "plate.stl", force="mesh")
    assert mesh.is_watertight and back.is_watertight and back.volume > 0
    assert back.bounds[0][2] == pytest.approx(-2.0)


def test_raster_gcode_stays_in_the_plate_and_above_the_deepest_cut(tmp_path: Path, plate):
    hm = plate.heights
    j0, i0 = np.argwhere(hm.z < -0.05)[0]
    crop = HeightMap(np.pad(hm.z[j0:j0 + 60, i0:i0 + 90], 8), hm.origin, hm.resolution)
    machining = Machining(feed=200.0, plunge=50.0, safe_z=1.0, spindle=20000.0)
    path = tmp_path / "plate.gcode"
    stats = write_raster_gcode(path, crop, radius=0.1, machining=machining, stepover=0.04)
    lo, hi = crop.bounds
    report = check_gcode(path, Stock(lo[0], lo[1], hi[0], hi[1], 3.0),
                         max_depth=-float(crop.z.min()), safe_z=1.0, feed_range=(50.0, 200.0),
                         spindle_range=(20000.0, 20000.0))
    assert report.ok, report.summary()
    zs = [float(v) for v in re.findall(r"Z(-?\d+\.\d+)", path.read_text())]
    assert min(zs) >= float(crop.z.min()) - 1e-5
    assert stats.deepest_tip_mm == pytest.approx(min(zs), abs=1e-5)
    # The tip never sits below the surface under the ball.
    tip = tool_tip(crop, 0.1)
    assert np.all(tip >= crop.z - 1e-7)


def test_bad_options():
    with pytest.raises(SpecholoError, match="whole number"):
        RidgeOptions(resolution=0.03, block=0.2)
    with pytest.raises(SpecholoError, match="labels"):
        find_field_glints(HeightMap(np.zeros((4, 4), np.float32), np.zeros(2), 0.1),
                          np.array([0.0, 0.0, 600.0]), SETUP.light)

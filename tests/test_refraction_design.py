"""Refraction holograms: a clear plate lit from behind, its front face ridged.

Forward ray traces through the designed height field (the light refracted at
the planar back face, then at the engraved facet) reach the eye on the
sightline through the point; the command line designs, verifies (by tracing
the light through the plate) and renders such a plate; bad input is refused
in one line with no output."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from specholo.errors import SpecholoError
from specholo.jobs.ridged.design import load_ridged_design
from specholo.jobs.ridged.settings import RidgedConfig
from specholo.optics.refraction import back_entry
from specholo.optics.surfaces import Kind, Source, refract
from specholo.setup import BackLight, Light, Setup, Viewer
from specholo.simulation.heightfield import (
    SlopeIndex,
    crossing_labels,
    find_field_glints,
    verify_field,
)
from specholo.simulation.transmission import in_plate_directions
from specholo.toolpaths.ridged import RidgedPlate, RidgeOptions, design_ridged
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
POINTS = np.array([[-4.0, 2.0, -20.0], [5.0, -3.0, -35.0], [0.0, 6.0, -12.0],
                   [3.0, 3.0, 15.0], [-6.0, -5.0, -50.0], [1.0, -1.0, -0.2]])
#: A point light 400 mm from the plate centre, 15 degrees above the axis behind it.
LAMP = BackLight(math.radians(-75.0), 400.0, 3.0, 1.49)
VIEWER = Viewer(600.0, 0.0, math.radians(20.0))
# A few bunny stipples on a small, coarse plate: designs and verifies in seconds.
SMALL = ["--method", "ridged", "--optic", "refract", "--light-distance", "600",
         "--stipples", "40", "--view-range", "8", "--elevation-range", "4",
         "--raster", "0.05", "--formats", "png", "--size", "60", "--center-z", "-40"]


def run(argv: list[Any], capsys) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    a, b = _unit(a), _unit(b)
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b)))


@pytest.fixture(scope="module", params=["point", "sun"])
def lit_plate(request) -> tuple[RidgedPlate, BackLight]:
    light = LAMP if request.param == "point" else BackLight(math.radians(-75.0), None)
    plate = design_ridged(POINTS, None, None, Setup(light=light, viewer=VIEWER),
                          RidgeOptions(delta=0.1, elevation_range=math.radians(10.0)),
                          refraction="exact")
    return plate, light


def _eyes(count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    az = rng.uniform(-0.35, 0.35, count)
    el = rng.uniform(-0.17, 0.17, count)
    return 600.0 * np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], 1)


def _served(plate: RidgedPlate, eye: np.ndarray) -> np.ndarray:
    """Stipples (not dots) whose region holds the eye's sightline crossing, a few
    cells in."""
    hm = plate.heights
    ids = np.arange(len(POINTS))
    inside = crossing_labels(hm, eye, POINTS, -plate.delta) == ids
    for dx, dy in ((0.15, 0), (-0.15, 0), (0, 0.15), (0, -0.15)):
        shifted = POINTS + np.array([dx, dy, 0.0]) * (1 - POINTS[:, 2:] / eye[2])
        inside &= crossing_labels(hm, eye, shifted, -plate.delta) == ids
    inside &= plate.kind != Kind.DOT
    return np.flatnonzero(inside)


def _surface_on_sightline(plate: RidgedPlate, eye: np.ndarray,
                          p: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Where the sightline from the eye through p meets the designed height field,
    and the field's normal there (a quadratic fitted to the 5 x 5 cells about it,
    all on one facet); None beside a riser."""
    hm = plate.heights
    d = p - eye

    def gap(t: float) -> float:
        q = eye + t * d
        i, j = (q[:2] - hm.origin) / hm.resolution
        i0, j0 = int(np.floor(i)), int(np.floor(j))
        a, b = i - i0, j - j0
        z = hm.z[j0:j0 + 2, i0:i0 + 2].astype(float)
        h = ((1 - a) * (1 - b) * z[0, 0] + a * (1 - b) * z[0, 1]
             + (1 - a) * b * z[1, 0] + a * b * z[1, 1])
        return q[2] - h

    lo, hi = (eye[2] - 0.0) / (eye[2] - p[2]) * 0.999, (eye[2] + 0.3) / (eye[2] - p[2])
    if gap(lo) * gap(hi) > 0:
        return None
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(mid) * gap(lo) > 0 else (lo, mid)
    s = eye + 0.5 * (lo + hi) * d
    i, j = np.rint((s[:2] - hm.origin) / hm.resolution).astype(int)
    jj, ii = np.mgrid[j - 2:j + 3, i - 2:i + 3]
    x = hm.origin[0] + ii * hm.resolution - s[0]
    y = hm.origin[1] + jj * hm.resolution - s[1]
    z = hm.z[jj, ii].astype(float)
    a = np.stack([np.ones(x.size), x.ravel(), y.ravel(), x.ravel() ** 2, (x * y).ravel(),
                  y.ravel() ** 2], axis=1)
    coef, *_ = np.linalg.lstsq(a, z.ravel(), rcond=None)
    if np.max(np.abs(a @ coef - z.ravel())) > 2e-7:  # a riser or a region edge
        return None
    return s, np.array([-coef[1], -coef[2], 1.0])


def test_forward_trace_reaches_the_eye_on_the_sightline(lit_plate):
    """Trace the light forward: from the lamp (or the sun) to the back face, refracted
    there into the plate, up to where the eye's sightline through p meets the
    milled front face, refracted there by the field's own normal into air. The
    exit ray heads for the eye, for eyes over azimuth and elevation."""
    plate, light = lit_plate
    source = Source.from_light(light)
    traced = 0
    worst_exit = worst_path = 0.0
    azimuths, elevations = [], []
    for eye in _eyes(80, 5):
        for j in _served(plate, eye):
            hit = _surface_on_sightline(plate, eye, POINTS[j])
            if hit is None:
                continue
            s, normal = hit
            # The ray from the light that enters the back face at b ...
            _, b, _ = back_entry(source, s[None], light.plate)
            b = b[0]
            incoming = (_unit(b - source.position) if source.position is not None
                        else -source.direction)
            inside = refract(incoming[None], np.array([[0.0, 0.0, 1.0]]), 1.0, light.index)[0]
            # ... crosses the plate to s (it passes within a nanometre of it) ...
            t = (s[2] - b[2]) / inside[2]
            worst_path = max(worst_path, float(np.linalg.norm(b + t * inside - s)))
            # ... and leaves through the facet toward the eye.
            out = refract(inside[None], normal[None], light.index, 1.0)[0]
            assert np.all(np.isfinite(out))
            worst_exit = max(worst_exit, _angle(out, eye - s))
            traced += 1
            azimuths.append(math.atan2(eye[0], eye[2]))
            elevations.append(math.asin(eye[1] / 600.0))
    assert traced > 40
    assert worst_path < 1e-6
    # 2e-5 rad: 0.01 mm at the eye, 600 mm away.
    assert worst_exit < 2e-5
    assert np.ptp(azimuths) > 0.4 and np.ptp(elevations) > 0.2


def test_simulated_glints_lie_on_the_sightlines(lit_plate):
    """The physical glint finder (light traced through the plate) puts the glints of
    served stipples on their sightlines."""
    plate, light = lit_plate
    index = SlopeIndex.build(plate.heights)
    served = lit = 0
    worst = 0.0
    for eye in _eyes(40, 7):
        found = find_field_glints(index, eye, light)
        for j in _served(plate, eye):
            served += 1
            k = np.flatnonzero(found.glints.stipple == j)
            if k.size:
                lit += 1
                d = POINTS[j] - eye
                for g in found.glints.point[k]:
                    worst = max(worst, float(np.linalg.norm(np.cross(g - eye, d))
                                             / np.linalg.norm(d)))
    assert served > 60
    assert lit >= 0.6 * served
    assert worst < 0.03


def test_facets_are_level_sets_and_the_light_tracer_agrees_with_fermat():
    plate = design_ridged(POINTS, None, None, Setup(light=LAMP, viewer=VIEWER),
                          RidgeOptions(delta=0.1, elevation_range=math.radians(10.0)),
                          refraction="exact")
    hm = plate.heights
    assert hm.z.max() <= 0.0 and hm.z.min() >= -0.2 - 1e-6 and plate.dropped.size == 0
    assert plate.model == "exact" and plate.kind[0] == Kind.TWO_SURFACE
    yy, xx = np.meshgrid(hm.y, hm.x, indexing="ij")
    for j in range(5):
        cells = np.flatnonzero((hm.labels == j).ravel())[::11]
        s = np.stack([xx.ravel()[cells], yy.ravel()[cells], hm.z.ravel()[cells]], axis=1)
        k = (plate.optics.phi(s, np.full(len(cells), j)) - plate.level0[j]) / plate.step[j]
        assert (np.abs(k - np.rint(k)) < 1e-3).mean() > 0.85
    # The simulator's in-plate rays (bisection on the angle of incidence, Snell in
    # vector form) are the Fermat solve's.
    rng = np.random.default_rng(1)
    s = np.stack([rng.uniform(-40, 40, 200), rng.uniform(-40, 40, 200),
                  rng.uniform(-0.2, 0.0, 200)], axis=1)
    for light in (LAMP, BackLight(math.radians(-60.0), None, 6.0, 1.7)):
        _, _, d = back_entry(Source.from_light(light), s, light.plate)
        assert np.max(np.linalg.norm(in_plate_directions(light, s) - d, axis=1)) < 1e-9


def test_the_simulator_tells_the_models_apart():
    """Physics is the judge: the single-interface oval (the back face ignored) misses
    its points by millimetres; the exact optic and, for a light on the axis, the
    paper's approximation do not."""
    lamp = BackLight(math.radians(-90.0), 400.0, 3.0, 1.49)
    setup = Setup(light=lamp, viewer=VIEWER)
    worst = {}
    for model in ("exact", "approx", "single"):
        plate = design_ridged(POINTS[:5], None, None, setup,
                              RidgeOptions(delta=0.1, resolution=0.04, block=0.2,
                                           elevation_range=math.radians(8.0)),
                              refraction=model)
        reports = verify_field(plate.heights, POINTS[:5], setup, None,
                               np.radians([-15.0, 0.0, 15.0]), np.radians([-5.0, 5.0]),
                               shell=0.1)
        worst[model] = np.nanmax([r.p95_error for r in reports])
    assert worst["exact"] < 0.3 and worst["approx"] < 0.3
    assert worst["single"] > 3 * worst["exact"]


def _one_line_error(argv: list[Any], capsys) -> str:
    code, _, err = run(argv, capsys)
    assert code != 0, argv
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.fixture(scope="module")
def designed(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("refract") / "holo"
    assert main(["design", str(BUNNY), "--out", str(out), *SMALL]) == 0
    return out


def test_cli_designs_and_verifies_a_refraction_plate(designed: Path, capsys):
    info = json.loads((designed / "hologram.json").read_text())
    assert info["design"] == "ridged" and info["settings"]["optic"] == "refract"
    assert info["settings"]["light_elevation"] == -90.0  # straight behind by default
    r = info["refraction"]
    assert r["model"] == "exact" and r["index"] == 1.49 and r["back_face_z_mm"] == -3.0
    assert r["light"]["kind"] == "point"
    np.testing.assert_allclose(r["light"]["position_mm"], [0.0, 0.0, -600.0], atol=1e-9)
    assert info["ridged"]["kept_stipples"] >= 10
    assert isinstance(load_ridged_design(designed).config.setup().light, BackLight)
    code, out, err = run(["verify", designed], capsys)
    assert code == 0, err
    assert "refraction" in out and "p95 error" in out
    result = json.loads((designed / "verify.json").read_text())
    assert result["optic"] == "refract" and result["refraction"] == "exact"
    views = result["views"]
    assert len(views) == 15  # 5 azimuths x 3 elevations
    glinting = [v for v in views if not math.isnan(v["p95_error"])]
    # Every head sees stipples in stereo, within 0.3 mm of where they belong.
    assert len(glinting) == len(views)
    assert max(v["p95_error"] for v in glinting) < 0.3
    assert result["summary"]["mean_visibility"] > 0.3
    assert result["summary"]["max_false_glints"] < 0.02


def test_render_of_a_refraction_plate_shows_its_glints(designed: Path, tmp_path: Path,
                                                        capsys):
    from PIL import Image
    from scipy.spatial import cKDTree
    from test_render import spots

    from specholo.preview.render import field_glint_pixels, field_plate, plate_camera

    out = tmp_path / "still.png"
    code, _, err = run(["render", designed, "--azimuth", 4, "--elevation", 2, "--width", 800,
                        "--height", 600, "--out", out], capsys)
    assert code == 0, err
    loaded = load_ridged_design(designed)
    setup = loaded.config.setup()
    camera = plate_camera(setup, field_plate(loaded.heights), math.radians(4.0),
                          math.radians(2.0), width=800, height=600)
    glints = field_glint_pixels(loaded.heights, setup, camera)
    assert len(glints.pixel) >= 3
    found, _ = spots(np.asarray(Image.open(out).convert("RGB")))
    d, _ = cKDTree(glints.pixel).query(found)
    assert len(found) == len(glints.pixel) and d.max() < 2.0


def test_bad_refraction_input_is_one_line_and_writes_nothing(tmp_path: Path, capsys):
    refract = ["--method", "ridged", "--optic", "refract"]
    bad = [
        ([*refract, "--index", "1"], "index"),
        ([*refract, "--index", "0.8"], "index"),
        ([*refract, "--index", "5"], "index"),
        ([*refract, "--index", "nan"], "index"),
        ([*refract, "--light-elevation", "45"], "lit from behind"),
        ([*refract, "--light-elevation", "0"], "lit from behind"),
        ([*refract, "--light-elevation", "-180"], "(-180, 0)"),
        ([*refract, "--light-distance", "2"], "back face"),
        ([*refract, "--light-elevation", "-10", "--light-distance", "10"], "back face"),
        (["--optic", "refract"], "--method ridged"),
        (["--method", "ridged", "--index", "1.6"], "--optic refract"),
        (["--method", "ridged", "--refraction", "single"], "--optic refract"),
        ([*refract, "--refraction", "paraxial"], "refraction"),
        (["--method", "ridged", "--optic", "transmit"], "optic"),
        (["--method", "ridged", "--light-elevation", "-90"], "light elevation"),
    ]
    for extra, message in bad:
        out = tmp_path / "out"
        err = _one_line_error(["design", BUNNY, "--out", out, *extra], capsys)
        assert message in err, (extra, err)
        assert not out.exists(), extra
        assert list(tmp_path.iterdir()) == [], extra


def test_library_refuses_a_light_on_the_wrong_side():
    with pytest.raises(SpecholoError, match="lit from behind"):
        BackLight(math.radians(30.0))
    with pytest.raises(SpecholoError, match="back face"):
        BackLight(math.radians(-90.0), 2.0, 3.0)
    with pytest.raises(SpecholoError, match="index"):
        BackLight(math.radians(-90.0), None, 3.0, 1.0)
    with pytest.raises(SpecholoError, match="BackLight"):
        design_ridged(POINTS, None, None, Setup(light=Light(math.radians(45.0)),
                                                viewer=VIEWER), refraction="exact")
    with pytest.raises(SpecholoError, match="lit from behind"):
        RidgedConfig(optic="refract")

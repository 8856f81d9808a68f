"""Single-point optics as level sets: normality, forward ray traces, refraction."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from specholo.errors import SpecholoError
from specholo.optics.normality import reflect
from specholo.optics.refraction import (
    ClearPlate,
    TwoSurfaceOptics,
    approximation_error,
    back_entry,
    back_light,
    fitted_centre,
    paraxial_centre,
)
from specholo.optics.surfaces import Kind, PointOptics, Source, refract
from specholo.setup import Light

coord = st.floats(-60.0, 60.0, allow_nan=False)
depth = st.floats(1.0, 120.0, allow_nan=False)
eye_dist = st.floats(80.0, 3000.0, allow_nan=False)
small = st.floats(-3.0, 3.0, allow_nan=False)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    a, b = _unit(a), _unit(b)
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b)))


@st.composite
def front_light(draw: st.DrawFn) -> Source:
    """A point light or a sun in front of the plate (z > 0)."""
    if draw(st.booleans()):
        pos = np.array([draw(coord) * 10, draw(coord) * 10, draw(st.floats(20.0, 3000.0))])
        return Source(position=pos)
    el = draw(st.floats(0.1, math.pi - 0.1))
    az = draw(st.floats(-math.pi, math.pi))
    return Source(direction=np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az),
                                      math.sin(el)]))


@st.composite
def point_and_eye(draw: st.DrawFn, pz_sign: int | None = None) -> tuple[np.ndarray, np.ndarray,
                                                                        np.ndarray]:
    """A virtual point p (in front of or behind the plate), a surface point a near
    the plate, and an eye on a sightline through p that passes near a."""
    sign = draw(st.sampled_from([-1.0, 1.0])) if pz_sign is None else float(pz_sign)
    p = np.array([draw(coord), draw(coord), sign * draw(depth)])
    a = np.array([draw(coord), draw(coord), draw(st.floats(-0.5, 0.5))])
    aim = a + np.array([draw(small), draw(small), 0.0])
    # Behind: the eye beyond the plate on the line from p through aim; in front:
    # the eye beyond p on the line from aim through p (p between eye and surface).
    direction = _unit(aim - p) if sign < 0 else _unit(p - aim)
    assume(direction[2] > 0.2)
    eye = p + draw(eye_dist) * direction
    return p, a, eye


@settings(max_examples=200, deadline=None)
@given(light=front_light(), geo=point_and_eye())
def test_mirror_level_sets_satisfy_normality_and_reflect_to_the_eye(light, geo):
    p, a, eye = geo
    optics = PointOptics.mirror(p[None], light)
    level = optics.phi(a[None])
    s = optics.sightline_point(eye[None], level)[0]
    assume(np.all(np.isfinite(s)))
    # s is on the level set and on the sightline through p.
    assert abs(optics.phi(s[None])[0] - level[0]) < 1e-9 * (1 + abs(level[0]))
    assert np.linalg.norm(np.cross(s - eye, p - eye)) / np.linalg.norm(p - eye) < 1e-8
    grad = optics.gradient(s[None])[0]
    h = optics.normality(s[None], eye[None])[0]
    # grad phi is minus the normality vector, not merely parallel to it.
    np.testing.assert_allclose(-grad, h, atol=1e-9)
    incoming = -light.towards(s[None])[0]
    out = reflect(incoming[None], grad[None])[0]
    assert _angle(out, eye - s) < 1e-8


# Most random ray pairs cannot be joined by any refraction (both must be on the
# transmitted side), so many draws are rejected by design.
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(geo=point_and_eye(), eta1=st.floats(1.0, 2.0), eta2=st.floats(1.0, 2.0),
       light_z=st.floats(-3000.0, -5.0), lx=coord, ly=coord, sun=st.booleans())
def test_cartesian_ovals_refract_to_the_eye(geo, eta1, eta2, light_z, lx, ly, sun):
    assume(abs(eta1 - eta2) > 0.02)
    p, a, eye = geo
    source = (Source(direction=np.array([lx, ly, light_z])) if sun
              else Source(position=np.array([lx * 10, ly * 10, light_z])))
    optics = PointOptics.lens(p[None], source, eta1, eta2)
    assert optics.kinds()[0] == Kind.CARTESIAN_OVAL
    level = optics.phi(a[None])
    s = optics.sightline_point(eye[None], level)[0]
    assume(np.all(np.isfinite(s)))
    d_in = -source.towards(s[None])[0]
    d_out = _unit(eye - s)
    # Only ray pairs a refraction can join: both on the transmitted side.
    assume(np.dot(d_in, d_out) > min(eta1, eta2) / max(eta1, eta2) + 1e-3)
    grad = optics.gradient(s[None])[0]
    np.testing.assert_allclose(-grad, optics.normality(s[None], eye[None])[0], atol=1e-9)
    out = refract(d_in[None], grad[None], eta1, eta2)[0]
    assert _angle(out, d_out) < 1e-7


@settings(max_examples=100, deadline=None)
@given(geo=point_and_eye(pz_sign=-1), thickness=st.floats(1.0, 12.0),
       distance=st.floats(50.0, 2000.0), elevation=st.floats(-0.6, 0.6),
       index=st.floats(1.3, 1.8))
def test_planar_back_front_surface_is_exact(geo, thickness, distance, elevation, index):
    p, a, eye = geo
    plate = ClearPlate(thickness, index)
    source = back_light(distance, elevation, plate)
    a = a.copy()
    a[2] = min(a[2], 0.0)
    optics = TwoSurfaceOptics.for_points(p[None], source, plate)
    level = optics.phi(a[None], np.array([0]))
    s = optics.sightline_point(eye[None], level, np.array([0]))[0]
    assume(np.all(np.isfinite(s)) and s[2] > plate.back_z + 0.1)
    length, b, d = back_entry(source, s[None], plate)
    b, d = b[0], d[0]
    # Fermat: the entry point is where Snell's law holds at the back face ...
    into = refract(_unit(b - source.position)[None], np.array([[0.0, 0.0, 1.0]]), 1.0, index)[0]
    assert _angle(into, d) < 1e-8
    # ... and a stationary (minimal) optical path.
    for shift in ([0.01, 0.0, 0.0], [0.0, 0.01, 0.0]):
        b2 = b + np.array(shift)
        assert (np.linalg.norm(b2 - source.position) + index * np.linalg.norm(s - b2)
                >= length[0] - 1e-9)
    out = refract(d[None], optics.gradient(s[None], np.array([0])), index, 1.0)[0]
    d_out = _unit(eye - s)
    assume(np.dot(d, d_out) > 1.0 / index + 1e-3)
    assert _angle(out, d_out) < 1e-7


def test_kinds():
    sun = Light(math.radians(45.0))
    lamp = Light(math.radians(45.0), 500.0)
    pts = np.array([[0.0, 0.0, -30.0], [0.0, 0.0, 20.0], [1.0, 2.0, 0.0],
                    [*lamp.position]])
    assert PointOptics.mirror(pts, lamp).kinds().tolist() == [
        Kind.HYPERBOLOID, Kind.ELLIPSOID, Kind.DOT, Kind.SPHERE]
    assert PointOptics.mirror(pts[:3], sun).kinds().tolist() == [
        Kind.PARABOLOID, Kind.PARABOLOID, Kind.DOT]
    # The sphere about the light: phi = 2 |s - i|, normals point at the light.
    optics = PointOptics.mirror(pts[3:], lamp)
    s = np.array([[3.0, -4.0, 0.0]])
    np.testing.assert_allclose(_unit(-optics.gradient(s[None])[0]), _unit(lamp.position - s))


def test_level_set_heights_are_on_the_level_set():
    optics = PointOptics.mirror(np.array([[0.0, 0.0, -30.0], [5.0, 5.0, 10.0]]),
                                Light(math.radians(40.0), 800.0))
    xy = np.array([[[0.0, 1.0], [2.0, -1.0]], [[5.0, 6.0], [4.0, 3.0]]])
    level = optics.phi(np.array([[[0.0, 0.0, -0.05]], [[5.0, 5.0, -0.05]]]))
    z = optics.height(xy, level)
    s = np.concatenate([xy, z[..., None]], axis=-1)
    np.testing.assert_allclose(optics.phi(s), np.broadcast_to(level, z.shape), atol=1e-10)


def test_bad_input():
    with pytest.raises(SpecholoError, match="exactly one"):
        Source()
    with pytest.raises(SpecholoError, match="sigma"):
        PointOptics(np.zeros((2, 3)), np.array([1.0, 0.5]), Source(position=np.ones(3)))
    with pytest.raises(SpecholoError, match="behind the back face"):
        TwoSurfaceOptics.for_points(np.zeros((1, 3)), Source(position=np.array([0, 0, 5.0])),
                                    ClearPlate())


def _pairs(az_deg: list[float], el_deg: list[float]) -> tuple[np.ndarray, np.ndarray]:
    az, el = np.meshgrid(np.radians(az_deg), np.radians(el_deg))
    az, el = az.ravel(), el.ravel()
    head = 600.0 * np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], 1)
    tangent = np.stack([np.cos(az), np.zeros_like(az), -np.sin(az)], axis=1)
    return head - 32.0 * tangent, head + 32.0 * tangent


def test_approximation_is_tight_for_a_distant_light_on_the_axis():
    plate = ClearPlate(3.0)
    left, right = _pairs([-20.0, 0.0, 20.0], [-10.0, 0.0, 10.0])
    far = approximation_error(np.array([5.0, 5.0, -30.0]), back_light(2000.0, 0.0, plate),
                              plate, left, right, "paraxial")
    near = approximation_error(np.array([5.0, 5.0, -30.0]), back_light(200.0, 0.0, plate),
                               plate, left, right, "paraxial")
    assert far.p95_error < 0.01 and far.max_angle < 1e-4
    assert near.max_angle > far.max_angle
    # A sun behind the plate: the rays in the plate stay parallel, the oval is exact.
    sun = Source(direction=np.array([0.0, 0.3, -1.0]))
    exact = approximation_error(np.array([5.0, 5.0, -30.0]), sun, plate, left, right)
    assert exact.max_angle < 1e-9 and exact.p95_error < 1e-6


def test_fitted_centre_beats_the_paraxial_one_off_axis():
    plate = ClearPlate(6.0)
    source = back_light(500.0, math.radians(30.0), plate)
    left, right = _pairs([-20.0, 0.0, 20.0], [-10.0, 0.0, 10.0])
    p = np.array([10.0, 5.0, -40.0])
    par = approximation_error(p, source, plate, left, right, "paraxial")
    fit = approximation_error(p, source, plate, left, right, "fitted")
    assert fit.max_angle < par.max_angle
    # Paraxially the light appears n times as far behind the back face.
    c = paraxial_centre(source, plate)
    assert c[2] == pytest.approx(plate.back_z - plate.index * (plate.back_z - source.position[2]))
    region = np.array([[x, y, 0.0] for x in (-0.5, 0.5) for y in (-0.5, 0.5)])
    near_axis = fitted_centre(back_light(500.0, 0.0, plate), plate, region)
    assert near_axis[2] == pytest.approx(paraxial_centre(back_light(500.0, 0.0, plate),
                                                         plate)[2], rel=1e-4)

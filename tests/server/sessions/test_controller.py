"""The Controller's gesture math (pure functions, no GL, no server)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from renderer.geometry.scene import Camera, SceneError
from server.sessions import controller


def project(cam: Camera, point, width: float, height: float) -> tuple[float, float]:
    """Pixel (x, y) (row 0 on top, pixel centres at +0.5) where ``point`` is drawn (SHADING.md)."""
    right, up, forward = cam.basis()
    d = np.subtract(point, cam.position)
    z = d @ forward
    s = math.tan(math.radians(cam.fov_y) / 2)
    u, v = (d @ right) / z, (d @ up) / z
    x = (u / (s * width / height) + 1) / 2 * width - 0.5
    y = (1 - v / s) / 2 * height - 0.5
    return x, y


CAMERAS = [
    Camera(),
    Camera(position=(30.0, 20.0, 50.0), target=(1.0, -2.0, 3.0), up=(0.0, 1.0, 0.0), fov_y=45.0),
    Camera(position=(0.0, 100.0, 0.1), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, -1.0), fov_y=90.0),
]


@pytest.mark.parametrize("cam", CAMERAS)
@pytest.mark.parametrize("dx,dy", [(10.0, 0.0), (0.0, -25.0), (-33.5, 12.25)])
def test_pan_moves_what_is_at_the_target_with_the_finger(cam, dx, dy):
    w, h = 320, 544
    # a point at the target's distance, off-centre
    right, up, _ = cam.basis()
    point = np.array(cam.target) + 3.0 * right - 2.0 * up
    x0, y0 = project(cam, point, w, h)
    moved = controller.pan(cam, dx, dy, h)
    x1, y1 = project(moved, point, w, h)
    assert x1 == pytest.approx(x0 + dx, abs=1e-6)
    assert y1 == pytest.approx(y0 + dy, abs=1e-6)


def test_pan_moves_camera_and_target_together_in_the_camera_plane():
    cam = CAMERAS[1]
    moved = controller.pan(cam, 40.0, -17.0, 544)
    before = np.subtract(cam.target, cam.position)
    after = np.subtract(moved.target, moved.position)
    assert np.allclose(before, after)  # same view direction and distance
    _, _, forward = cam.basis()
    assert abs(np.subtract(moved.position, cam.position) @ forward) < 1e-9  # no motion along the view axis
    assert moved.up == cam.up and moved.fov_y == cam.fov_y


def test_pan_scale_is_world_units_per_pixel_at_the_target():
    cam = Camera()  # distance 100, fov 60°
    k = controller.world_per_pixel(cam, 1000)
    assert k == pytest.approx(2 * 100 * math.tan(math.radians(30)) / 1000)
    moved = controller.pan(cam, -1000.0, 0.0, 1000)  # finger left by a full view height
    assert moved.position[0] == pytest.approx(1000 * k)


def test_pinch_spread_moves_forward_and_pinch_moves_back():
    cam = Camera()
    fwd = controller.pinch(cam, 2.0)
    assert fwd.position == pytest.approx((0.0, 0.0, 50.0)) and fwd.target == cam.target
    back = controller.pinch(cam, 0.5)
    assert back.position == pytest.approx((0.0, 0.0, 200.0))
    assert controller.pinch(cam, 1.0).position == pytest.approx(cam.position)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(min_value=1e-3, max_value=1e3), min_size=1, max_size=40))
def test_pinch_never_reaches_or_passes_the_target(scales):
    cam = CAMERAS[1]
    axis = np.subtract(cam.target, cam.position)
    for s in scales:
        try:
            cam = controller.pinch(cam, s, min_distance=1e-3)
        except SceneError:  # only allowed when moving back beyond the coordinate range
            assert s < 1
            continue
        offset = np.subtract(cam.target, cam.position)
        assert np.linalg.norm(offset) >= 1e-3 * (1 - 1e-9)
        assert offset @ axis > 0  # still in front: never went through


def test_pinch_stops_at_the_minimum_distance():
    cam = Camera(position=(0.0, 0.0, 1.0))
    close = controller.pinch(cam, 1e3, min_distance=0.01)
    assert close.position[2] == pytest.approx(0.01)
    closer = controller.pinch(close, 10.0, min_distance=0.01)
    assert closer.position[2] == pytest.approx(0.01)


def test_reset_returns_home_camera():
    assert controller.reset(CAMERAS[2]) is CAMERAS[2]


def test_pan_out_of_range_raises_scene_error():
    cam = Camera(position=(9.9e6, 0.0, 100.0), target=(9.9e6, 0.0, 0.0))
    with pytest.raises(SceneError):
        controller.pan(cam, -1e6, 0.0, 10)


# ---- orbit ------------------------------------------------------------------------------
def _offset(cam: Camera) -> np.ndarray:
    return np.subtract(cam.position, cam.target)


@pytest.mark.parametrize("cam", CAMERAS)
@pytest.mark.parametrize("yaw,pitch", [(30.0, 0.0), (0.0, -20.0), (-75.5, 12.25), (360.0, 0.0)])
def test_orbit_keeps_the_target_and_the_distance(cam, yaw, pitch):
    moved = controller.orbit(cam, yaw, pitch)
    assert moved.target == cam.target
    assert np.linalg.norm(_offset(moved)) == pytest.approx(np.linalg.norm(_offset(cam)), rel=1e-12)
    assert moved.up == cam.up and moved.fov_y == cam.fov_y


def test_orbit_yaw_turns_about_up_towards_the_cameras_right():
    cam = Camera()  # at +z, looking at the origin, up +y
    moved = controller.orbit(cam, 90.0, 0.0)
    assert moved.position == pytest.approx((100.0, 0.0, 0.0), abs=1e-9)  # to its right (+x)
    back = controller.orbit(cam, -90.0, 0.0)
    assert back.position == pytest.approx((-100.0, 0.0, 0.0), abs=1e-9)
    # Any yaw keeps the height along up (a turntable: the horizon stays level).
    tilted = CAMERAS[1]
    up = np.array(tilted.up) / np.linalg.norm(tilted.up)
    for yaw in (10.0, 123.0, -200.0):
        assert _offset(controller.orbit(tilted, yaw, 0.0)) @ up == pytest.approx(_offset(tilted) @ up, abs=1e-9)


def test_orbit_pitch_turns_about_right_and_moves_the_camera_down():
    cam = Camera()
    moved = controller.orbit(cam, 0.0, 30.0)
    d = 100.0
    assert moved.position == pytest.approx((0.0, -d * math.sin(math.radians(30)), d * math.cos(math.radians(30))))
    right, _, _ = cam.basis()
    assert _offset(moved) @ right == pytest.approx(0.0, abs=1e-9)  # the rotation axis is right
    assert np.allclose(moved.basis()[0], right)  # … and right stays


def test_orbit_composes_and_undoes():
    cam = CAMERAS[1]
    once = controller.orbit(cam, 50.0, 20.0)
    twice = controller.orbit(controller.orbit(cam, 30.0, 5.0), 20.0, 15.0)
    assert twice.position == pytest.approx(once.position, abs=1e-9)
    split = controller.orbit(controller.orbit(cam, 50.0, 0.0), 0.0, 20.0)  # yaw and pitch commute
    assert split.position == pytest.approx(once.position, abs=1e-9)
    back = controller.orbit(once, -50.0, -20.0)
    assert back.position == pytest.approx(cam.position, abs=1e-9)


@pytest.mark.parametrize("pitch", [89.5, 120.0, 360.0, -89.5, -179.0, -360.0])
def test_orbit_pitch_stops_short_of_the_poles(pitch):
    cam = Camera()  # polar angle 90°
    moved = controller.orbit(cam, 0.0, pitch)
    theta = controller.polar_angle(moved)
    assert controller.MIN_POLAR_DEG - 1e-9 <= theta <= 180.0 - controller.MIN_POLAR_DEG + 1e-9
    assert theta == pytest.approx(min(180 - controller.MIN_POLAR_DEG, max(controller.MIN_POLAR_DEG, 90 + pitch)))
    # Never flipped: the view's right vector points the same way as before.
    assert moved.basis()[0] @ cam.basis()[0] > 0.99


def test_orbit_from_near_a_pole_may_come_back_but_not_go_further():
    cam = Camera(position=(0.0, 100.0, 1.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))  # from above: ≈ 0.57°
    theta = controller.polar_angle(cam)
    assert theta < controller.MIN_POLAR_DEG
    assert controller.polar_angle(controller.orbit(cam, 0.0, -10.0)) == pytest.approx(theta)
    assert controller.polar_angle(controller.orbit(cam, 0.0, 10.0)) == pytest.approx(theta + 10.0)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-360, 360), st.floats(-360, 360)), min_size=1, max_size=30))
def test_orbit_never_flips_the_view(steps):
    cam = CAMERAS[1]
    d0 = np.linalg.norm(_offset(cam))
    for yaw, pitch in steps:
        cam = controller.orbit(cam, yaw, pitch)
        theta = controller.polar_angle(cam)
        assert controller.MIN_POLAR_DEG - 1e-6 <= theta <= 180 - controller.MIN_POLAR_DEG + 1e-6
        assert np.linalg.norm(_offset(cam)) == pytest.approx(d0, rel=1e-9)


def test_orbit_refuses_non_finite_angles():
    with pytest.raises(ValueError):
        controller.orbit(Camera(), math.nan, 0.0)
    with pytest.raises(ValueError):
        controller.orbit(Camera(), 0.0, math.inf)

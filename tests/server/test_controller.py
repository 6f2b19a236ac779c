"""The Controller's gesture math (pure functions, no GL, no server)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from renderer.scene import Camera, SceneError
from server import controller


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

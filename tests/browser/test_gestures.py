"""Gestures in a real Chromium: touch through the DevTools protocol, mouse, wheel, keys.

Each test checks the session's camera through the API moved the mapped way
("the scene follows the finger": dragging right moves the camera along −right;
spreading moves it towards the target, pinching away), that a new frame was
displayed (a preview while moving, the full frame after), and that the console
stayed clean.
"""

from __future__ import annotations

import math

import numpy as np
from browser_support import Touch, basis, distance, moved


def world_per_css_px(client, cam) -> float:
    """World units per CSS pixel at the target's distance, for the frame as displayed."""
    shown = client.page.evaluate("""() => { const r = window.pocketray.state.render;
        const s = document.getElementById('stage'); const a = r.width / r.height;
        return s.clientWidth / s.clientHeight > a ? s.clientHeight : s.clientWidth / a; }""")
    return 2 * distance(cam) * math.tan(math.radians(cam["fov_y"]) / 2) / shown


def assert_new_frames(client, before: int, preview=True) -> None:
    """A new frame was shown; while moving at the preview level, at the end the full frame."""
    client.wait_idle(min_frames=before + 1)
    log = client.hook("log")[before:]
    assert log, "no new frame was displayed"
    if preview:
        assert any(
            f["level"] == "preview" and (f["width"], f["height"]) == (160, 272) and f["contentType"] == "image/jpeg"
            for f in log
        ), log
    last = log[-1]
    assert (last["level"], last["width"], last["height"], last["contentType"]) == ("full", 320, 544, "image/png"), last


def test_one_finger_drag_pans_the_scene_with_the_finger(open_client):
    c = open_client("mobile")
    touch = Touch(c.page)
    cam0, n0 = c.camera(), c.frame_count
    touch.gesture([(150, 300)], [(230, 300)])  # 80 CSS px to the right
    assert_new_frames(c, n0)
    cam1 = c.camera()
    right, up, forward = basis(cam0)
    d = moved(cam0, cam1)
    # The camera went left (−right) by 80 px at the target's distance: the scene followed the finger.
    expected = 80 * world_per_css_px(c, cam0)
    assert np.dot(d, right) < 0
    assert abs(-np.dot(d, right) - expected) < 0.05 * expected, (d, expected)
    assert abs(np.dot(d, up)) < 1e-6 * expected and abs(np.dot(d, forward)) < 1e-6 * expected
    assert np.allclose(moved({"position": cam0["target"]}, {"position": cam1["target"]}), d)

    n1 = c.frame_count
    touch.gesture([(200, 250)], [(200, 330)])  # 80 px down: the camera goes up
    assert_new_frames(c, n1)
    d2 = moved(cam1, c.camera())
    assert np.dot(d2, basis(cam1)[1]) > 0.9 * expected
    assert c.errors() == []
    assert c.hook("errors") == []


def test_two_finger_spread_moves_forward_and_pinch_moves_back(open_client, artifacts):
    c = open_client("mobile")
    touch = Touch(c.page)
    cam0, n0 = c.camera(), c.frame_count
    touch.gesture([(140, 320), (220, 320)], [(60, 320), (300, 320)])  # spread 80 → 240 px: ×3
    assert_new_frames(c, n0)
    cam1 = c.camera()
    assert distance(cam1) < distance(cam0)
    assert math.isclose(distance(cam1), distance(cam0) / 3, rel_tol=0.02), (distance(cam0), distance(cam1))
    assert np.allclose(cam1["target"], cam0["target"])  # along the view axis only
    assert np.allclose(np.cross(moved(cam0, cam1), basis(cam0)[2]), 0, atol=1e-6)

    n1 = c.frame_count
    touch.gesture([(60, 320), (300, 320)], [(120, 320), (240, 320)])  # pinch 240 → 120 px: ×½
    assert_new_frames(c, n1)
    cam2 = c.camera()
    assert distance(cam2) > distance(cam1)
    assert math.isclose(distance(cam2), 2 * distance(cam1), rel_tol=0.02)

    c.page.screenshot(path=str(artifacts / "client.png"))
    assert c.errors() == []
    assert c.hook("errors") == []


def test_double_tap_resets_the_camera(open_client):
    c = open_client("mobile")
    home = c.camera()  # the scene's camera framed for this screen's aspect (renderer/scenes/scenarios.py fit_camera)
    touch = Touch(c.page)
    n0 = c.frame_count
    touch.gesture([(150, 300)], [(220, 260)])
    c.wait_idle(min_frames=n0 + 1)
    assert not np.allclose(c.camera()["position"], home["position"])
    n1 = c.frame_count
    touch.tap(180, 320)
    touch.tap(182, 321)
    c.wait_idle(min_frames=n1 + 1)
    cam = c.camera()
    assert np.allclose(cam["position"], home["position"]) and np.allclose(cam["target"], home["target"])
    assert c.errors() == []


def test_mouse_drag_wheel_and_keys_on_the_desktop(open_client):
    c = open_client("desktop")
    m = c.page.mouse
    cam0, n0 = c.camera(), c.frame_count
    m.move(400, 300)
    m.down()
    m.move(480, 300, steps=8)  # drag right
    m.up()
    assert_new_frames(c, n0)
    cam1 = c.camera()
    d = moved(cam0, cam1)
    expected = 80 * world_per_css_px(c, cam0)
    assert np.dot(d, basis(cam0)[0]) < 0
    assert abs(-np.dot(d, basis(cam0)[0]) - expected) < 0.05 * expected

    n1 = c.frame_count
    m.wheel(0, -100)  # wheel up / away: forward
    assert_new_frames(c, n1, preview=False)
    cam2 = c.camera()
    assert distance(cam2) < distance(cam1)
    n2 = c.frame_count
    m.wheel(0, 100)  # wheel down: back
    assert_new_frames(c, n2, preview=False)
    assert math.isclose(distance(c.camera()), distance(cam1), rel_tol=1e-6)

    # Keyboard: arrows move the camera the arrow's way, + and − dolly.
    c.page.focus("#view")
    cam3, n3 = c.camera(), c.frame_count
    c.page.keyboard.press("ArrowRight")
    c.wait_idle(min_frames=n3 + 1)
    cam4 = c.camera()
    assert np.dot(moved(cam3, cam4), basis(cam3)[0]) > 0
    n4 = c.frame_count
    c.page.keyboard.press("+")
    c.wait_idle(min_frames=n4 + 1)
    cam5 = c.camera()
    assert distance(cam5) < distance(cam4)
    n5 = c.frame_count
    c.page.keyboard.press("-")
    c.wait_idle(min_frames=n5 + 1)
    assert distance(c.camera()) > distance(cam5)
    assert c.errors() == []
    assert c.hook("errors") == []


def test_gestures_during_a_request_are_merged_and_latest_wins(open_client):
    """Many moves while one request is in flight: few requests, the sum of the moves."""
    c = open_client("mobile")
    touch = Touch(c.page)
    cam0, r0 = c.camera(), c.hook("requests")
    touch.gesture([(100, 300)], [(260, 300)], steps=40)
    c.wait_idle(min_frames=1)
    cam1 = c.camera()
    requests = c.hook("requests") - r0
    assert requests < 40, requests  # merged, not one request per move
    expected = 160 * world_per_css_px(c, cam0)  # nothing lost in the merge
    assert abs(-np.dot(moved(cam0, cam1), basis(cam0)[0]) - expected) < 0.05 * expected
    versions = [f["version"] for f in c.hook("log")]
    assert versions == sorted(versions)  # never an older frame after a newer one
    assert c.errors() == []

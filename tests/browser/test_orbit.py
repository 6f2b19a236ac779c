"""Orbit in a real Chromium: a two-finger twist, a one-finger drag in orbit mode,
the desktop's right-drag, shift-drag and shift + arrows all turn the session's camera about
its target (the service's Controller does it: the camera read back from the API)."""

from __future__ import annotations

import math

import numpy as np
from browser_support import Touch, distance

ORBIT_DEGREES_PER_VIEW = 180  # client_web/js/ui/controls.js: a drag the frame's height turns 180°


def angles(cam: dict) -> tuple[float, float]:
    """(azimuth about up, polar angle from up) of the camera about its target, degrees; azimuth 0 at
    +z, growing towards +x (yaw > 0 moves the home camera to its right)."""
    o = np.subtract(cam["position"], cam["target"])
    up = np.asarray(cam["up"], float) / np.linalg.norm(cam["up"])
    polar = math.degrees(math.acos(float(o @ up) / float(np.linalg.norm(o))))
    flat = o - (o @ up) * up
    return math.degrees(math.atan2(flat[0], flat[2])), polar


def shown_height(c) -> float:
    return c.page.evaluate("""() => { const r = window.pocketray.state.render;
        const s = document.getElementById('stage'); const a = r.width / r.height;
        return s.clientWidth / s.clientHeight > a ? s.clientHeight : s.clientWidth / a; }""")


def assert_orbited(cam0: dict, cam1: dict, yaw: float, pitch: float, tol: float = 0.5) -> None:
    assert np.allclose(cam1["target"], cam0["target"], atol=1e-9), (cam0, cam1)  # the target stays
    # … and the distance (a twist's pointers move one at a time: pinch ratios that cancel, to rounding)
    assert math.isclose(distance(cam1), distance(cam0), rel_tol=1e-6)
    (a0, p0), (a1, p1) = angles(cam0), angles(cam1)
    assert abs((a1 - a0 + 180) % 360 - 180 - yaw) < tol, (a1 - a0, yaw)
    assert abs((p1 - p0) - pitch) < tol, (p1 - p0, pitch)


def test_a_two_finger_twist_orbits_the_camera_about_its_target(open_client):
    c = open_client("mobile")
    touch = Touch(c.page)
    cam0, n0 = c.camera(), c.frame_count
    cx, cy, r = 180, 320, 70
    turn = [
        [
            (cx - r * math.cos(math.radians(a)), cy - r * math.sin(math.radians(a))),
            (cx + r * math.cos(math.radians(a)), cy + r * math.sin(math.radians(a))),
        ]
        for a in range(0, 31, 3)
    ]
    touch.path(turn)  # 30° clockwise on screen, fingers 140 px apart
    c.wait_idle(min_frames=n0 + 1)
    assert_orbited(cam0, c.camera(), yaw=30.0, pitch=0.0)  # the scene turned the fingers' way
    assert c.errors() == [] and c.hook("errors") == []


def test_orbit_mode_turns_the_camera_with_one_finger(open_client):
    c = open_client("mobile")
    p, touch = c.page, Touch(c.page)
    b = p.locator("#orbit-toggle").bounding_box()
    touch.tap(b["x"] + b["width"] / 2, b["y"] + b["height"] / 2)
    assert p.get_attribute("#orbit-toggle", "aria-pressed") == "true"
    k = ORBIT_DEGREES_PER_VIEW / shown_height(c)
    cam0, n0 = c.camera(), c.frame_count
    touch.gesture([(120, 300)], [(200, 300)])  # right by 80 px: the scene turns right
    c.wait_idle(min_frames=n0 + 1)
    cam1 = c.camera()
    assert_orbited(cam0, cam1, yaw=-80 * k, pitch=0.0)
    n1 = c.frame_count
    touch.gesture([(180, 250)], [(180, 310)])  # down by 60 px: the camera rises
    c.wait_idle(min_frames=n1 + 1)
    cam2 = c.camera()
    assert_orbited(cam1, cam2, yaw=0.0, pitch=-60 * k)
    assert cam2["position"][1] > cam1["position"][1]
    touch.tap(b["x"] + b["width"] / 2, b["y"] + b["height"] / 2)  # back to moving the camera
    assert p.get_attribute("#orbit-toggle", "aria-pressed") == "false"
    n2 = c.frame_count
    touch.gesture([(120, 300)], [(200, 300)])
    c.wait_idle(min_frames=n2 + 1)
    assert not np.allclose(c.camera()["target"], cam2["target"])  # a pan moves the target with it
    p.reload()
    c.wait_idle(min_frames=1)
    assert p.get_attribute("#orbit-toggle", "aria-pressed") == "false"  # the choice is remembered
    assert c.errors() == [] and c.hook("errors") == []


def test_right_drag_shift_drag_and_shift_arrows_orbit_on_the_desktop(open_client):
    c = open_client("desktop")
    m, kb = c.page.mouse, c.page.keyboard
    k = ORBIT_DEGREES_PER_VIEW / shown_height(c)
    cam0, n0 = c.camera(), c.frame_count
    m.move(400, 300)
    m.down(button="right")
    m.move(460, 300, steps=6)
    m.up(button="right")
    c.wait_idle(min_frames=n0 + 1)
    cam1 = c.camera()
    assert_orbited(cam0, cam1, yaw=-60 * k, pitch=0.0)
    n1 = c.frame_count
    kb.down("Shift")
    m.move(400, 300)
    m.down()
    m.move(400, 340, steps=6)
    m.up()
    kb.up("Shift")
    c.wait_idle(min_frames=n1 + 1)
    cam2 = c.camera()
    assert_orbited(cam1, cam2, yaw=0.0, pitch=-40 * k)
    c.page.focus("#view")
    n2 = c.frame_count
    kb.press("Shift+ArrowRight")
    c.wait_idle(min_frames=n2 + 1)
    assert_orbited(cam2, c.camera(), yaw=5.0, pitch=0.0)
    assert c.errors() == [] and c.hook("errors") == []

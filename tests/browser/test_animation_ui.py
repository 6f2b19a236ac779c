"""Playing an animated scene in the client: the museum from a link, play/pause,
frames posed at advancing times, the update scheme from the settings panel, and the
service's update time in the overlay."""

from __future__ import annotations

import time

MUSEUM_QUERY = "scenario=museum&n=32&motion=rigid&seed=0&width=96&height=128&preview_scale=0.5&max_recursion_depth=1"


def test_play_pause_poses_frames_at_advancing_times(open_client, server):
    c = open_client("mobile", MUSEUM_QUERY)
    p = c.page
    sid = c.hook("sessionId")
    info = server.session(sid)["scene_info"]
    assert info["animated"] and info["museum"]["kind"] == "rigid" and info["n_moving"] == 32
    assert p.is_visible("#play-button")
    assert p.get_attribute("#play-button", "aria-pressed") == "false"
    assert c.hook("lastFrame.time") == 0

    icon = lambda: p.evaluate("""() => ['.icon-play', '.icon-pause'].map((s) =>
        getComputedStyle(document.querySelector('#play-button ' + s)).display !== 'none')""")
    assert icon() == [True, False] and p.text_content("#play-button .label") == "Play"
    n0 = c.frame_count
    p.click("#play-button")
    assert p.get_attribute("#play-button", "aria-pressed") == "true"
    assert icon() == [False, True] and p.text_content("#play-button .label") == "Pause"  # ❚❚ while playing
    p.wait_for_function(f"() => window.pocketray.frameCount >= {n0 + 4}", timeout=60_000)
    t_a = c.hook("lastFrame.time")
    p.wait_for_function(f"() => window.pocketray.lastFrame.time > {t_a}", timeout=30_000)
    t_b = c.hook("lastFrame.time")
    assert t_b > t_a > 0, (t_a, t_b)
    assert c.hook("lastFrame.level") == "preview"  # playing: the preview level
    field = lambda name: p.text_content(f'#overlay [data-field="{name}"]')
    assert field("anim").endswith("▶")
    assert field("build") not in ("", "–")  # Server-Timing "update"
    assert isinstance(c.hook("lastFrame.timing.update"), (int, float))

    p.click("#play-button")  # pause
    assert p.get_attribute("#play-button", "aria-pressed") == "false"
    assert icon() == [True, False]
    c.wait_idle()
    t_paused = c.hook("lastFrame.time")
    assert c.hook("lastFrame.level") == "full"  # the full frame after the last one
    c.wait_rest()  # the paused view at rest is refined (a colour view's stream: frames of the same time) …
    n_paused = c.frame_count
    time.sleep(1.0)
    assert c.frame_count == n_paused  # … and then, paused: no more frames
    assert c.hook("lastFrame.time") == t_paused and t_paused >= t_b
    assert c.errors() == []


def test_update_scheme_from_the_settings_panel(open_client, server):
    c = open_client("desktop", MUSEUM_QUERY)
    p = c.page
    sid = c.hook("sessionId")
    p.click("#settings-toggle")
    assert p.is_visible("#f-motion")  # museum: its motion is offered
    n0 = c.frame_count
    p.select_option("#f-method", "bvh")
    c.wait_idle(min_frames=n0 + 1)
    n1 = c.frame_count
    p.select_option("#f-update", "refit")
    c.wait_idle(min_frames=n1 + 1)
    s = server.session(sid)["settings"]
    assert (s["method"], s["update"]) == ("bvh", "refit")
    # A thesis scenario hides the motion control and the play button.
    n2 = c.frame_count
    p.select_option("#f-scenario", "2")
    c.wait_idle(min_frames=n2 + 1)
    assert not p.is_visible("#f-motion")
    assert not p.is_visible("#play-button")
    assert server.session(c.hook("sessionId"))["scene_info"]["scenario"] == 2
    assert c.errors() == []


def test_the_museum_keeps_its_own_n(open_client, server):
    """Scenario 2 with 4,096 spheres, then the museum: its own n (moving spheres), not 4,096 of them;
    back to scenario 2: the 4,096 again."""
    c = open_client("desktop", "scenario=2&n=4096&seed=1&radius=1&width=96&height=128&max_recursion_depth=1")
    p = c.page
    p.click("#settings-toggle")
    assert p.input_value("#f-n") == "4096"
    n0 = c.frame_count
    p.select_option("#f-scenario", "museum")
    c.wait_idle(min_frames=n0 + 1)
    info = server.session(c.hook("sessionId"))["scene_info"]
    assert info["museum"]["n"] == 64 and info["n_moving"] <= 64 and p.input_value("#f-n") == "64"
    assert p.text_content('label[for="f-n"]') == "Moving spheres (n)"
    n1 = c.frame_count
    p.select_option("#f-scenario", "2")
    c.wait_idle(min_frames=n1 + 1)
    info = server.session(c.hook("sessionId"))["scene_info"]
    assert (info["scenario"], info["n"]) == (2, 4096) and p.input_value("#f-n") == "4096"
    assert c.errors() == []

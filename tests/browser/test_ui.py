"""The rest of the View: overlay, settings panel, accessibility basics, errors and recovery."""

from __future__ import annotations

import json
import time
import urllib.request

import numpy as np
from browser_support import FAILED_LOAD, http_json


def retry_now(c) -> None:
    """The banner's "Retry now" (by script: the banner may already be gone when the retry won)."""
    c.page.evaluate("() => document.querySelector('#banner [data-retry]').click()")


def test_overlay_shows_timing_and_tree_and_can_be_hidden(open_client):
    c = open_client("mobile")
    field = lambda name: c.page.text_content(f'#overlay [data-field="{name}"]')
    assert c.page.is_visible("#overlay")
    for name in ("trace", "encode", "build", "upload"):
        assert field(name) not in ("", "–"), name
    assert field("time").endswith("ms")
    assert field("method") == "bih"
    assert field("n") == "64"
    assert field("depth") not in ("", "–")
    inner, leaves = (int(x) for x in field("nodes").split("+"))
    assert leaves >= 1 and inner >= 0
    assert field("res").startswith("320×544")

    c.page.click("#overlay-toggle")
    assert not c.page.is_visible("#overlay")
    assert c.page.get_attribute("#overlay-toggle", "aria-pressed") == "false"
    c.page.reload()
    c.wait_idle(min_frames=1)
    assert not c.page.is_visible("#overlay")  # the choice is remembered
    c.page.click("#overlay-toggle")
    assert c.page.is_visible("#overlay")
    assert c.errors() == []


def test_settings_panel_applies_through_the_api(open_client, server, artifacts):
    c = open_client("desktop")
    p = c.page
    p.click("#settings-toggle")
    assert p.is_visible("#settings")
    p.screenshot(path=str(artifacts / "client-settings.png"))
    # Every control is labelled; every button has a name.
    unlabelled = p.evaluate("""() => [...document.querySelectorAll('#settings input, #settings select')]
        .filter(e => !e.hidden && e.labels.length === 0).map(e => e.name)""")
    assert unlabelled == []
    nameless = p.evaluate("""() => [...document.querySelectorAll('button')]
        .filter(b => !(b.getAttribute('aria-label') || b.textContent.trim())).map(b => b.id)""")
    assert nameless == []
    methods = p.evaluate("() => [...document.querySelectorAll('#f-method option')].map(o => o.value)")
    assert {"bih", "bruteforce"} <= set(methods)

    sid, n0 = c.hook("sessionId"), c.frame_count
    p.select_option("#f-mode", "depth")
    c.wait_idle(min_frames=n0 + 1)
    assert server.session(sid)["settings"]["mode"] == "depth"

    n1 = c.frame_count
    p.fill("#f-max_recursion_depth", "1")
    p.press("#f-max_recursion_depth", "Enter")
    p.locator("#f-max_recursion_depth").blur()
    c.wait_idle(min_frames=n1 + 1)
    assert server.session(sid)["settings"]["max_recursion_depth"] == 1

    n2 = c.frame_count
    p.select_option("#f-method", "bruteforce")
    c.wait_idle(min_frames=n2 + 1)
    assert server.session(sid)["settings"]["method"] == "bruteforce"
    assert c.hook("lastFrame.method") == "bruteforce"

    # Resolution: a preset is PATCHed as width/height.
    n3 = c.frame_count
    p.select_option("#f-resolution", "640x1088")
    c.wait_idle(min_frames=n3 + 1)
    s = server.session(sid)["settings"]
    assert (s["width"], s["height"]) == (640, 1088)
    assert (c.hook("lastFrame.width"), c.hook("lastFrame.height")) == (640, 1088)

    # Scene parameters make a new session with that scene.
    n4 = c.frame_count
    p.fill("#f-n", "27")
    p.locator("#f-n").blur()
    c.wait_idle(min_frames=n4 + 1)
    new_sid = c.hook("sessionId")
    assert new_sid != sid
    assert server.session(new_sid)["scene_info"]["n"] == 27

    # A refused value is shown, and the panel comes back to what the session has.
    p.fill("#f-n", "-5")
    p.locator("#f-n").blur()
    assert c.hook("sessionId") == new_sid
    p.keyboard.press("Escape")
    assert not p.is_visible("#settings")
    assert c.errors() == []


def test_a_declared_setting_is_shown_by_the_settings_sheet(open_client):
    """The sheet is made from GET /api/info's declarations: a setting declared there (added to the answer on its
    way here; tests/server/test_setting_declaration.py adds one to the table itself and sees the API take it)
    gets a labelled field within its bounds and with its default, shown for the modes that read it; a value
    outside its bounds is refused by the sheet, and another is PATCHed as that setting."""
    from renderer.config.settings import SettingSpec

    extra = SettingSpec(
        "gain",
        "number",
        1.0,
        "brightness factor of the image (a test's setting)",
        "Gain",
        unit="×",
        bounds=(0.0, 4.0),
        modes=("color",),
        sheet=True,
        client=True,
    ).metadata()

    def info(route):
        answer = route.fetch()
        body = answer.json()
        body["settings"].append(extra)
        route.fulfill(response=answer, json=body)

    c = open_client("desktop", query=None)
    p = c.page
    p.route("**/api/info", info)
    sent: list[dict] = []
    p.on(
        "request",
        lambda r: (
            sent.append(json.loads(r.post_data or "{}"))
            if r.method == "PATCH" and r.url.endswith("/settings")
            else None
        ),
    )
    c.open()
    p.click("#settings-toggle")
    assert p.is_visible("#f-gain")
    assert p.text_content('label[for="f-gain"]') == "Gain (×)"
    assert (p.get_attribute("#f-gain", "min"), p.get_attribute("#f-gain", "max")) == ("0", "4")
    assert p.input_value("#f-gain") == "1"
    assert (
        p.evaluate("() => document.querySelector('#f-gain').closest('fieldset').querySelector('legend').textContent")
        == "Rendering"
    )

    p.fill("#f-gain", "5")
    p.locator("#f-gain").blur()
    assert p.get_attribute("#f-gain", "aria-invalid") == "true"
    assert p.text_content('.field[data-setting="gain"] .field-error') == "Gain: a number 0 … 4"
    assert not any("gain" in body for body in sent)

    p.fill("#f-gain", "2.5")
    p.locator("#f-gain").blur()
    deadline = time.monotonic() + 10
    while not any("gain" in body for body in sent) and time.monotonic() < deadline:
        p.wait_for_timeout(50)
    assert [body for body in sent if "gain" in body] == [{"gain": 2.5}]
    # (this service has no such setting: its 422 is shown next to the field)
    p.wait_for_selector('.field[data-setting="gain"] .field-error')

    p.fill("#f-gain", "1")  # back to a value the sheet takes, then a mode that does not read it
    p.select_option("#f-mode", "depth")
    p.wait_for_function("() => document.querySelector('.field[data-setting=\"gain\"]').hidden")
    assert not p.is_visible("#f-gain")


def test_reload_resumes_the_session_and_an_expired_one_is_replaced(open_client):
    c = open_client("mobile")
    sid = c.hook("sessionId")
    before = c.camera()
    moved = http_json("POST", f"{c.server.base}/api/sessions/{sid}/gesture", {"type": "pinch", "scale": 2})["camera"]
    assert np.abs(np.subtract(moved["position"], before["position"])).max() > 1.0
    c.page.reload()
    c.wait_idle(min_frames=1)
    assert c.hook("sessionId") == sid  # localStorage kept it
    np.testing.assert_allclose(c.camera()["position"], moved["position"], atol=1e-6)  # and the scene's camera

    c.page.evaluate("""() => localStorage.setItem('pocketray.session',
        JSON.stringify({id: 'no-such-session', scene: {scenario: 1, n: 64, seed: 1, radius: 1}}))""")
    c.page.reload()
    c.wait_idle(min_frames=1)
    new_sid = c.hook("sessionId")
    assert new_sid not in (sid, "no-such-session")
    assert any("expired" in n["text"] for n in c.hook("notices"))
    assert c.page.is_visible("#notice")
    assert c.errors(allow=(FAILED_LOAD,)) == []  # the 404 of the old id is logged by Chromium


def test_a_session_that_expires_while_in_use_is_replaced(open_client, server):
    c = open_client("mobile")
    sid = c.hook("sessionId")
    req = urllib.request.Request(f"{server.base}/api/sessions/{sid}", method="DELETE")
    urllib.request.urlopen(req, timeout=10).close()
    n0 = c.frame_count
    c.page.focus("#view")
    c.page.keyboard.press("ArrowLeft")  # 404: the session is gone
    c.page.wait_for_function("sid => window.pocketray.sessionId !== sid", arg=sid, timeout=10_000)
    c.wait_idle(min_frames=n0 + 1)
    new_sid = c.hook("sessionId")
    info = server.session(new_sid)["scene_info"]
    assert (info["scenario"], info["n"], info["seed"]) == (1, 64, 1)  # the same scene
    assert c.page.evaluate("() => JSON.parse(localStorage.getItem('pocketray.session')).id") == new_sid
    assert any("expired" in n["text"] for n in c.hook("notices"))
    assert c.hook("errors") == []
    assert c.errors(allow=(FAILED_LOAD,)) == []


def test_unreachable_service_shows_a_banner_and_recovers(open_client):
    c = open_client("mobile")
    n0 = c.frame_count
    c.page.route("**/api/**", lambda route: route.abort("connectionrefused"))
    c.page.focus("#view")
    c.page.keyboard.press("ArrowLeft")
    c.page.wait_for_selector("#banner", state="visible", timeout=10_000)
    assert "Cannot reach" in c.page.text_content("#banner")
    assert c.hook("status") == "offline"
    c.page.keyboard.press("ArrowLeft")  # queued meanwhile
    time.sleep(0.8)  # let it retry at least once more
    c.page.unroute("**/api/**")
    retry_now(c)
    c.wait_idle(min_frames=n0 + 1)
    assert not c.page.is_visible("#banner")
    assert c.hook("status") == "ready"
    assert c.hook("errors") == []
    assert c.errors(allow=(FAILED_LOAD,)) == []


def test_busy_service_is_waited_for_as_retry_after_says(open_client):
    c = open_client("mobile")
    n0 = c.frame_count
    answered = []

    def busy_once(route):
        if not answered:
            answered.append(time.monotonic())
            route.fulfill(status=503, headers={"Retry-After": "1"}, body="busy")
        else:
            answered.append(time.monotonic())
            route.continue_()

    c.page.route("**/api/sessions/*/gesture*", busy_once)
    c.page.focus("#view")
    c.page.keyboard.press("ArrowUp")
    c.page.wait_for_selector("#banner.busy", state="visible", timeout=10_000)
    c.wait_idle(min_frames=n0 + 1)
    assert len(answered) >= 2 and answered[1] - answered[0] >= 0.9
    assert not c.page.is_visible("#banner")
    assert c.hook("errors") == []
    assert c.errors(allow=(FAILED_LOAD,)) == []


def test_a_server_restart_resumes_the_same_scene(open_client, server):
    c = open_client("mobile")
    sid = c.hook("sessionId")
    c.page.focus("#view")
    n0 = c.frame_count
    c.page.keyboard.press("+")
    c.wait_idle(min_frames=n0 + 1)
    cam = c.camera()
    server.stop()
    try:
        n1 = c.frame_count
        c.page.keyboard.press("ArrowLeft")
        c.page.wait_for_selector("#banner", state="visible", timeout=10_000)
    finally:
        server.start()
    retry_now(c)
    c.wait_idle(min_frames=n1 + 1)
    assert c.hook("sessionId") == sid
    after = c.camera()
    assert after["position"] != cam["position"]  # the key press applied after the restart
    assert abs(after["position"][2] - cam["position"][2]) < 1e-6
    assert c.errors(allow=(FAILED_LOAD,)) == []

"""Errors where the eye is: notices above the open sheet, the form's limits from
/api/info (the resolution allowed at the current samples per pixel), refusals next to their
field in the panel's words, invalid values put back when the sheet closes, and a scene too
heavy to render explained by the service instead of retried without end."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request

from browser_support import FAILED_LOAD, FAST_QUERY, Touch, http_json

API_WORDS = ("samples_per_pixel", "max_recursion_depth", "max_prims", "POCKETRAY_")


def invalid(page, name: str) -> str | None:
    """The message marked next to field `name` (None when it is not marked)."""
    if page.get_attribute(f"#f-{name}", "aria-invalid") != "true":
        return None
    described = page.get_attribute(f"#f-{name}", "aria-describedby")
    assert described and page.is_visible(f"#{described}"), name
    return page.text_content(f"#{described}")


def test_a_notice_is_drawn_above_the_open_sheet(open_client):
    c = open_client("portrait", FAST_QUERY + "&webgl2=0")
    p, touch = c.page, Touch(c.page)
    b = p.locator("#settings-toggle").bounding_box()
    touch.tap(b["x"] + b["width"] / 2, b["y"] + b["height"] / 2)
    assert p.is_visible("#settings")
    p.select_option("#f-renderer", "device")  # cannot: a notice says so, the sheet still open
    p.wait_for_selector("#notice > p", state="visible")
    note, sheet = p.locator("#notice > p").last.bounding_box(), p.locator("#settings").bounding_box()
    assert note["y"] + note["height"] <= sheet["y"], (note, sheet)  # above the sheet's top edge …
    on_top = p.evaluate(
        """([x, y]) => !!document.elementFromPoint(x, y).closest('#notice')""",
        [note["x"] + note["width"] / 2, note["y"] + note["height"] / 2],
    )
    assert on_top  # … and nothing drawn over it
    z = p.evaluate("""() => [getComputedStyle(document.querySelector('#messages')).zIndex,
                             getComputedStyle(document.querySelector('#settings')).zIndex].map(Number)""")
    assert z[0] > z[1], z
    p.select_option("#f-renderer", "server")
    p.select_option("#f-renderer", "device")  # the same refusal again: the line stays, no second copy
    texts = p.eval_on_selector_all("#notice > p", "ps => ps.map((x) => x.textContent)")
    assert len(texts) == len(set(texts)), texts
    # the gesture hint, not yet dismissed, is not drawn over the open sheet
    assert p.evaluate("() => !document.querySelector('#hint').hidden") and not p.is_visible("#hint")
    assert c.errors() == []


def test_the_form_allows_the_resolution_the_service_allows_at_these_samples(open_client, server):
    c = open_client("wide")
    p = c.page
    sid = c.hook("sessionId")
    assert c.hook("info.limits.max_image_side") == 4096
    p.click("#settings-toggle")
    assert p.is_visible("#f-samples_per_pixel")  # the setting the service's messages name is shown
    n0 = c.frame_count
    p.select_option("#f-samples_per_pixel", "4")
    c.wait_idle(min_frames=n0 + 1)
    assert server.session(sid)["settings"]["samples_per_pixel"] == 4
    assert c.hook("lastFrame.samples") == 4 and p.text_content('#overlay [data-field="samples"]').startswith("4 spp")
    p.select_option("#f-resolution", "custom")
    assert p.get_attribute("#f-width", "max") == "2048"  # 4096 / √4
    requests = []
    p.on("request", lambda r: requests.append(r.url) if r.method == "PATCH" else None)
    p.fill("#f-width", "4096")
    p.locator("#f-width").blur()
    text = invalid(p, "width")
    assert text and "Width" in text and "2,048" in text and "4 samples per pixel" in text, text
    assert not any(w in text for w in API_WORDS), text
    assert requests == [] and server.session(sid)["settings"]["width"] == 320  # nothing was sent
    p.click("#settings [data-close]")
    p.click("#settings-toggle")
    assert p.input_value("#f-width") == "320" and invalid(p, "width") is None
    assert c.errors() == []


def test_invalid_values_are_marked_and_put_back_when_the_sheet_closes(open_client, server):
    c = open_client("wide")
    p = c.page
    sid = c.hook("sessionId")
    before = server.session(sid)
    p.click("#settings-toggle")
    for name, value, words in (
        ("n", "0", ("Spheres (n)", "1 …")),
        ("max_recursion_depth", "99", ("Recursion depth", "1 … 8")),
        ("radius", "-1", ("Radius", "more than 0 … 20")),
    ):
        p.fill(f"#f-{name}", value)
        p.locator(f"#f-{name}").blur()
        text = invalid(p, name)
        assert text and all(w in text for w in words), (name, text)
        assert p.input_value(f"#f-{name}") == value  # still what was typed, while the sheet is open
    assert c.hook("sessionId") == sid and server.session(sid) == before  # nothing applied
    p.keyboard.press("Escape")
    assert not p.is_visible("#settings")
    p.click("#settings-toggle")
    assert [p.input_value(f"#f-{k}") for k in ("n", "max_recursion_depth", "radius")] == ["64", "2", "1"]
    assert [invalid(p, k) for k in ("n", "max_recursion_depth", "radius")] == [None, None, None]
    assert p.locator("#settings .field-error").count() == 0
    assert c.errors() == []


def test_a_refusal_by_the_service_is_shown_at_its_field_in_the_panels_words(open_client, server):
    c = open_client("wide")
    p = c.page
    other = http_json("POST", f"{server.base}/api/sessions", {"scenario": 1, "n": 8})["id"]
    req = urllib.request.Request(
        f"{server.base}/api/sessions/{other}/settings",
        method="PATCH",
        data=json.dumps({"width": 4096, "samples_per_pixel": 16}).encode(),
        headers={"Content-Type": "application/json"},
    )
    try:
        urllib.request.urlopen(req, timeout=30)
        raise AssertionError("the service accepted 4096 px at 16 samples per pixel")
    except urllib.error.HTTPError as e:
        assert e.code == 422
        refusal = e.read()
    assert b"samples_per_pixel" in refusal
    # The service's own answer, as if to this client's next change.
    p.route(
        "**/api/sessions/*/settings",
        lambda route: route.fulfill(status=422, body=refusal, content_type="application/json"),
    )
    p.click("#settings-toggle")
    p.select_option("#f-samples_per_pixel", "9")
    p.wait_for_function("() => window.pocketray.errors.length > 0")
    text = invalid(p, "samples_per_pixel")
    assert text and text.startswith("Quality (samples per pixel): "), text
    assert not any(w in text for w in API_WORDS), text
    assert c.hook("errors")[-1]["inline"] is True and c.hook("errors")[-1]["field"] == "samples_per_pixel"
    c.wait_idle()
    p.keyboard.press("Escape")
    p.click("#settings-toggle")
    assert p.input_value("#f-samples_per_pixel") == "1" and invalid(p, "samples_per_pixel") is None
    assert c.errors(allow=(FAILED_LOAD,)) == []


def test_a_scene_too_heavy_to_render_gets_the_services_explanation(open_client, server):
    """n = 2,097,152 at 16 samples per pixel: the service refuses the new session with its 422 — the frame's estimated
    cost is over POCKETRAY_MAX_FRAME_COST, its spheres crowding every ray (renderer/frame/cost.py).
    The client asks once, says why next to n, and keeps the scene on screen — and its
    session — with the overlay describing it."""
    c = open_client("wide")
    p = c.page
    sid = c.hook("sessionId")
    refused = []

    def sessions(route):
        if route.request.method == "POST":
            refused.append(route.request.url)
        route.continue_()

    p.route("**/api/sessions", sessions)
    p.click("#settings-toggle")
    # 16 samples per pixel: at the client's frame a 2^21-sphere scene is then over the cap whatever
    # the fitted constants (at 1 sample it is admitted, and its build and frame take seconds)
    p.select_option("#f-samples_per_pixel", "16")
    c.wait_idle()
    p.fill("#f-n", "2097152")
    p.locator("#f-n").blur()
    p.wait_for_function("() => window.pocketray.errors.length > 0", timeout=60_000)
    c.wait_idle()
    time.sleep(1.0)  # a retry would have gone by now
    assert len(refused) == 1, refused  # one frame asked for, no retries
    text = invalid(p, "n")
    assert text and "2,097,152 primitives" in text and "lower n" in text, text
    assert not any(w in text for w in API_WORDS), text
    assert c.hook("sessionId") == sid  # back to the scene on screen
    assert p.evaluate("() => JSON.parse(localStorage.getItem('pocketray.session')).id") == sid
    assert p.text_content('#overlay [data-field="n"]') == "64"
    p.keyboard.press("Escape")
    p.click("#settings-toggle")
    assert p.input_value("#f-n") == "64"
    n0 = c.frame_count  # and the scene on screen still answers
    p.keyboard.press("Escape")
    p.focus("#view")
    p.keyboard.press("ArrowLeft")
    c.wait_idle(min_frames=n0 + 1)
    assert c.errors(allow=(FAILED_LOAD,)) == []

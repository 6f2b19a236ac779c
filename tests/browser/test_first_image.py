"""The first image after load and the page's link (client_web/js/frames.js, settings.js): a new page
shows a small preview first and then its full frame; every render setting the service declares, and
the demo scenes, can be set by the link's query, and a value the service would not take is ignored
with a notice."""

from __future__ import annotations

import json
from urllib.parse import parse_qs, urlparse

from browser_support import FAILED_LOAD, Touch

# No preview_scale: the client's own choice (auto: the first preview at ¼ of the frame's sides).
PAGE = "scenario=1&n=64&seed=1&radius=1&width=320&height=544&max_recursion_depth=2&refine_samples=16"


def requests_of(c, part: str) -> list:
    got: list = []
    c.page.on("request", lambda r: part in r.url and got.append(r))
    return got


def test_the_first_image_after_load_is_a_small_preview_then_the_full_frame(open_client):
    c = open_client(query=None)
    frames = requests_of(c, "/api/sessions/")
    c.open(PAGE)
    c.wait_idle(min_frames=2)
    log = c.hook("log")
    # (the resting view's refinement parts may follow it: the log's first full frame is the one)
    first, full = log[0], next(e for e in log if e["level"] == "full")
    assert first["level"] == "preview", log
    assert first["width"] * first["height"] < 320 * 544 / 4, log  # ¼ of the sides at most: a 16th of the pixels
    assert (full["level"], full["part"], full["width"], full["height"]) == ("full", "final", 320, 544), log
    # The preview was asked first, at the service's interactive profile (one sample per pixel).
    urls = [r.url for r in frames if "/frame?" in r.url]
    assert "samples_per_pixel=1" in urls[0] and f"width={first['width']}" in urls[0], urls
    assert "width=320" in urls[1], urls
    assert c.errors(allow=(FAILED_LOAD,)) == []


def test_a_fixed_preview_scale_of_one_asks_for_no_quick_preview(open_client):
    c = open_client(query=PAGE + "&preview_scale=1&preview_format=png")
    # (the resting view's refinement parts, full frames too, may follow)
    assert {e["level"] for e in c.hook("log")} == {"full"}


def test_link_settings_reach_the_session(open_client, server):
    c = open_client(query=None)
    posts = requests_of(c, "/api/sessions")
    c.open(
        "scenario=mesh:cornell&integrator=path&tone_map=aces&exposure=0.5&min_weight=0.1&specialize=false"
        "&width=96&height=128&max_recursion_depth=3"
    )
    # The scene goes with the session's creation (asked for while GET /api/info is on its way), the
    # link's render settings in the PATCH that follows once the service has declared them.
    body = json.loads(next(r for r in posts if r.method == "POST").post_data)
    assert body["mesh_scene"] == {"kind": "cornell"}, body
    patch = json.loads(next(r for r in posts if r.method == "PATCH").post_data)
    want = {"integrator": "path", "tone_map": "aces", "exposure": 0.5, "min_weight": 0.1, "specialize": False}
    # The Cornell box opens path-traced (its recommended settings): the link's integrator needs no PATCH.
    assert set(want) - set(patch) <= {"integrator"}, patch
    assert {k: patch[k] for k in want if k in patch} == {k: v for k, v in want.items() if k in patch}, patch
    s = server.session(c.hook("sessionId"))
    assert {k: s["settings"][k] for k in want} == want, s["settings"]
    assert s["scene_info"]["mesh_scene"]["kind"] == "cornell"
    assert c.hook("ignoredParams") == []


def test_invalid_link_values_are_ignored_with_a_notice(open_client, server):
    c = open_client(query=PAGE + "&samples_per_pixel=0&tone_map=sepia&bogus=1&exposure=1")
    ignored = sorted(x["name"] for x in c.hook("ignoredParams"))
    assert ignored == ["bogus", "samples_per_pixel", "tone_map"]
    notices = " ".join(n["text"] for n in c.hook("notices"))
    for part in ("samples_per_pixel=0", "tone_map=sepia", "bogus=1", "1 … 4096", "clamp, reinhard, aces"):
        assert part in notices, notices
    s = server.session(c.hook("sessionId"))["settings"]
    assert (s["exposure"], s["tone_map"], s["samples_per_pixel"]) == (1.0, "clamp", 1), s  # the valid one taken
    assert c.hook("lastFrame.level") == "full"


def test_previews_while_moving_are_at_the_measured_scale(open_client):
    c = open_client(query=None)
    sent = requests_of(c, "/gesture?")
    c.open(PAGE)
    Touch(c.page).gesture([(150, 300)], [(230, 300)], steps=12)
    c.wait_idle(min_frames=3)
    sizes = [(int(q["width"][0]), int(q["height"][0])) for q in (parse_qs(urlparse(r.url).query) for r in sent)]
    assert sizes, "no gesture asked for a frame"
    # Each on the sizer's ladder (2^(−k/4) of the frame's sides, ⅛ … 1), none larger than the frame.
    ladder = {(max(8, round(320 * 2 ** (-k / 4))), max(8, round(544 * 2 ** (-k / 4)))) for k in range(13)}
    assert set(sizes) <= ladder, sizes
    # The first at the sizer's start, ¼ (the load's quick preview is not a gesture's: not counted).
    assert sizes[0] == (80, 136), sizes
    scale = c.hook("previewScale")
    assert 0.125 <= scale <= 1 and (round(320 * scale), round(544 * scale)) in ladder, scale


def test_the_sheet_offers_auto_and_a_fixed_scale_turns_it_off(open_client):
    c = open_client(query=PAGE)
    p = c.page
    p.click("#settings-toggle")
    assert p.input_value("#f-previewScale") == "auto"
    p.select_option("#f-previewScale", "0.5")
    assert (c.hook("state.client.previewAuto"), c.hook("previewScale")) == (False, 0.5)
    p.select_option("#f-previewScale", "auto")
    assert (c.hook("state.client.previewAuto"), c.hook("previewScale")) == (True, 0.25)

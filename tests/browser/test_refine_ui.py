"""Refinement while still in the client (docs/API.md, "Refinement"): after a gesture ends, the path
integrator's view is refined by the service's stream — its frames shown as they arrive, with their
sample counts rising and the counter saying them — and the next gesture stops the stream."""

from __future__ import annotations

import re

from browser_support import Touch

# The Cornell box path-traced, small; a target the stream does not reach while the test looks.
QUERY = (
    "scenario=mesh:cornell&width=64&height=64&preview_scale=0.5&integrator=path&samples_per_pixel=1"
    "&max_recursion_depth=3&refine_samples=65536&refine_time_ms=600000"
)


def parts(c) -> list[dict]:
    return c.hook("refinement.parts")


def wait_parts(c, n: int, timeout: float = 60_000) -> None:
    c.page.wait_for_function("n => window.pocketray.refinement.parts.length >= n", arg=n, timeout=timeout)


def drag(c, touch: Touch) -> None:
    box = c.page.locator("#view").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    touch.gesture([(x, y)], [(x + 40, y)])


def test_a_resting_view_is_refined_until_the_next_gesture(open_client):
    c = open_client(query=QUERY)
    c.wait_idle(min_frames=1, timeout=60_000)
    touch = Touch(c.page)
    drag(c, touch)
    stopped = c.hook("refinement.stopped")
    c.page.evaluate("() => { window.pocketray.refinement.parts.length = 0; }")
    wait_parts(c, 2)
    got = parts(c)
    samples = [p["samples"] for p in got]
    assert all(a < b for a, b in zip(samples, samples[1:], strict=False)), got
    assert all(p["target"] == 65536 and not p["done"] for p in got), got
    assert c.hook("refining") is True
    badge = c.page.locator("#refine")
    assert badge.is_visible()
    assert re.fullmatch(r"\d+ / 65536 samples", badge.locator("[data-field=samples]").inner_text())
    assert c.hook("lastFrame.level") == "full"

    # The next gesture stops the stream (the counter goes); the view it leaves refines anew, from the start.
    before = len(parts(c))
    drag(c, touch)
    c.page.wait_for_function("n => window.pocketray.refinement.stopped > n", arg=stopped)
    wait_parts(c, before + 1)
    after = parts(c)[before:]
    assert after[0]["samples"] <= samples[0], (samples, after)
    assert c.errors() == []


def test_the_sheet_offers_the_denoiser_and_the_targets_with_the_path_integrator(open_client):
    c = open_client(query=QUERY.replace("refine_samples=65536", "refine_samples=128"))
    c.wait_idle(min_frames=1, timeout=60_000)
    c.page.click("#settings-toggle")
    fields = ("#f-denoise", "#f-refine_samples", "#f-refine_time_ms", "#f-refine_noise")
    assert all(c.page.locator(f).is_visible() for f in fields)
    assert c.page.locator("#f-refine_samples").input_value() == "128"
    c.page.select_option("#f-integrator", "whitted")
    c.page.wait_for_function("() => window.pocketray.state.render.integrator === 'whitted'")
    assert not c.page.locator("#f-denoise").is_visible(), "Whitted frames are not denoised"
    assert all(c.page.locator(f).is_visible() for f in fields[1:]), "… but refined, by jittered slices"

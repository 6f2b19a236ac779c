"""The settings sheet with the path integrator: the samples select offers counts of paths (those the
service's work cap admits at the frame's size, counted as renderer/frame/cost.py counts them), the depth goes
to 16, a count picked reaches the session, and going back to Whitted carries its own values."""

from __future__ import annotations

QUERY = (
    "scenario=mesh:cornell&width=32&height=32&preview_scale=0.5&integrator=path&samples_per_pixel=4"
    "&max_recursion_depth=3&refine_samples=4"
)


def options(c, field: str) -> list[tuple[str, bool]]:
    return [
        tuple(x) for x in c.page.eval_on_selector_all(f"{field} option", "os => os.map((o) => [o.value, o.disabled])")
    ]


def test_the_sheet_picks_64_paths_and_depth_12_and_the_session_gets_them(open_client):
    c = open_client(query=QUERY)
    c.wait_idle(min_frames=1, timeout=60_000)
    sid = c.hook("sessionId")
    c.page.click("#settings-toggle")
    assert options(c, "#f-samples_per_pixel") == [(str(s), False) for s in (1, 4, 16, 64, 256, 1024)]
    assert c.page.locator("#f-max_recursion_depth").get_attribute("max") == "16"
    c.page.select_option("#f-samples_per_pixel", "64")
    c.page.wait_for_function("() => window.pocketray.state.render.samples_per_pixel === 64")
    c.page.fill("#f-max_recursion_depth", "12")
    c.page.locator("#f-max_recursion_depth").dispatch_event("change")
    c.page.wait_for_function("() => window.pocketray.state.render.max_recursion_depth === 12")
    got = c.server.session(sid)["settings"]
    assert (got["integrator"], got["samples_per_pixel"], got["max_recursion_depth"]) == ("path", 64, 12)
    # Whitted cannot take 64 samples or depth 12: the same change brings the nearest it can.
    c.page.select_option("#f-integrator", "whitted")
    c.page.wait_for_function("() => window.pocketray.state.render.integrator === 'whitted'")
    assert [v for v, _ in options(c, "#f-samples_per_pixel")] == ["1", "4", "9", "16"]
    got = c.server.session(sid)["settings"]
    assert (got["integrator"], got["samples_per_pixel"], got["max_recursion_depth"]) == ("whitted", 16, 8)
    assert c.page.locator("#f-max_recursion_depth").get_attribute("max") == "8"
    assert not c.errors(), c.errors()

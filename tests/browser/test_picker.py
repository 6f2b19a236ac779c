"""The scene picker is the service's (GET /api/info's ``scenes``: its entries and their recommended
settings), the client's own list only when the service gives none; a picked scene brings its settings
(the path integrator's resting image denoised), and a new session says the frame's aspect to a
service that frames its demo scenes for one. The service's list is fed here by rewriting
``/api/info`` in the page (the service of this checkout may not list its scenes yet)."""

from __future__ import annotations

import json

from browser_support import FAILED_LOAD, Client

# No depth in the link: the scene's recommended depth applies (a link's own would win).
QUERY = "scenario=1&n=64&seed=1&radius=1&width=48&height=80&preview_scale=0.5"
SCENES = [
    {"value": "1", "label": "Grid of spheres", "settings": {}},
    {"value": "mesh:cornell", "label": "Cornell box", "settings": {"integrator": "path", "max_recursion_depth": 3}},
]


def with_scenes(route) -> None:
    res = route.fetch()
    info = res.json()
    info["scenes"] = SCENES
    route.fulfill(response=res, body=json.dumps(info), headers={**res.headers, "content-type": "application/json"})


def test_the_picker_is_the_services_list_and_a_pick_brings_its_settings(browser, server):
    from browser_support import MOBILE

    ctx = browser.new_context(**MOBILE)
    try:
        page = ctx.new_page()
        page.route("**/api/info", with_scenes)
        posted: list[dict] = []
        page.on(
            "request",
            lambda r: r.method == "POST" and r.url.endswith("/api/sessions") and posted.append(json.loads(r.post_data)),
        )
        c = Client(server, ctx, page)
        c.open(QUERY)
        options = page.eval_on_selector_all("#f-scenario option", "os => os.map((o) => [o.value, o.textContent])")
        assert options == [["1", "Grid of spheres"], ["mesh:cornell", "Cornell box"]]
        # the new page's session was asked with the frame's aspect (a service that refuses it is asked again)
        assert posted and abs(posted[0]["aspect"] - 48 / 80) < 1e-3, posted
        page.click("#settings-toggle")
        page.select_option("#f-scenario", "mesh:cornell")
        page.wait_for_function("() => window.pocketray.state.scene.scenario === 'mesh:cornell'", timeout=60_000)
        render = c.hook("state.render")
        assert (render["integrator"], render["max_recursion_depth"], render["denoise"]) == ("path", 3, "oidn")
        assert posted[-1]["mesh_scene"] == {"kind": "cornell"} and posted[-1]["settings"]["integrator"] == "path"
        assert c.errors(allow=(FAILED_LOAD,)) == []
    finally:
        ctx.close()


def test_without_the_services_list_the_picker_is_the_clients_own(open_client):
    c = open_client()
    options = c.page.eval_on_selector_all("#f-scenario option", "os => os.map((o) => o.value)")
    assert {"1", "museum", "mesh:cornell", "mesh:table"} <= set(options)

"""The settings sheet's *Table and lamp* (POST /api/sessions {mesh_scene: {kind: "table"}}): a
scene of analytic shapes only. Choosing it makes a session of the recipe whose frame is on
screen, and the canvas's label counts its shapes (no triangle)."""

from __future__ import annotations

from renderer.scenes.scenarios import mesh_scene


def test_the_table_of_analytic_shapes_is_in_the_scene_picker(open_client, server):
    c = open_client("desktop")
    p = c.page
    first = c.hook("sessionId")
    c.page.click("#settings-toggle")
    assert p.is_visible("#settings")
    options = p.eval_on_selector_all("#f-scenario option", "os => os.map((o) => [o.value, o.textContent])")
    assert any(v == "mesh:table" and t.startswith("Table and lamp") for v, t in options), options
    n0 = c.frame_count
    pixels = p.evaluate("() => document.querySelector('#view').toDataURL()")
    p.select_option("#f-scenario", "mesh:table")
    p.wait_for_function("id => window.pocketray.sessionId !== id", arg=first)
    c.wait_idle(min_frames=n0 + 1)
    info = server.session(c.hook("sessionId"))["scene_info"]
    want = mesh_scene("table")
    assert info["mesh_scene"]["kind"] == "table" and info["n_shapes"] == want.n_shapes > 0
    assert info.get("n_triangles", 0) == 0
    assert c.hook("lastFrameVersion") == server.session(c.hook("sessionId"))["version"]
    assert p.evaluate("() => document.querySelector('#view').toDataURL()") != pixels  # the table on screen
    label = p.get_attribute("#view", "aria-label")
    assert "table" in label and f"{want.n_shapes} analytic shapes" in label, label
    assert p.eval_on_selector("#overlay [data-meshes]", "e => e.hidden") is True  # no triangles to count
    assert c.hook("errors") == [] and c.errors() == []

"""Meshes in the client: the settings sheet's mesh scenes (POST /api/sessions
{mesh_scene}) and its model file picker (POST /api/sessions/{id}/meshes, the file's bytes as
the body). A mesh scene's frame says its triangles (overlay, canvas label); an uploaded OBJ
changes the frame and the session's scene_info; a corrupt, misnamed or too big file is
refused next to the picker in the panel's words, and the scene on screen stays."""

from __future__ import annotations

from pathlib import Path

from renderer.geometry.meshes import icosphere
from renderer.io.mesh_io import export_mesh, load_mesh
from renderer.scenes.scenarios import mesh_scene

PICKER = "#f-model"
CORPUS = Path("/usr/share/assimp/models")  # Debian's assimp-testmodels (scripts/bootstrap.sh)
API_WORDS = ("POCKETRAY_", "query.", "body:")


def invalid(page, name: str) -> str | None:
    """The message marked next to field `name` (None when it is not marked), as test_ui_errors reads it."""
    if page.get_attribute(f"#f-{name}", "aria-invalid") != "true":
        return None
    described = page.get_attribute(f"#f-{name}", "aria-describedby")
    assert described and page.is_visible(f"#{described}"), name
    return page.text_content(f"#{described}")


def canvas_pixels(page) -> str:
    return page.evaluate("() => document.querySelector('#view').toDataURL()")


def open_sheet(c):
    c.page.click("#settings-toggle")
    assert c.page.is_visible("#settings")


def test_choosing_a_mesh_scene_shows_its_triangles(open_client, server):
    c = open_client("desktop")
    p = c.page
    first = c.hook("sessionId")
    open_sheet(c)
    assert p.is_visible(PICKER) and p.get_attribute(PICKER, "accept").startswith(".obj,.ply,.stl,.glb,.gltf,.zip")
    assert p.get_attribute(PICKER, "multiple") is not None  # a model file picked with its side files
    assert p.get_attribute(PICKER, "aria-label") and p.text_content("label[for='f-model']").startswith("Add a model")
    labels = p.eval_on_selector_all("#f-scenario option", "os => os.map((o) => o.value)")
    assert {"mesh:teapot", "mesh:mixed", "mesh:room"} <= set(labels)
    n0 = c.frame_count
    p.select_option("#f-scenario", "mesh:teapot")
    p.wait_for_function("id => window.pocketray.sessionId !== id", arg=first)
    c.wait_idle(min_frames=n0 + 1)
    sid = c.hook("sessionId")
    info = server.session(sid)["scene_info"]
    want = mesh_scene("teapot")
    assert info["mesh_scene"]["kind"] == "teapot" and info["n_triangles"] == want.n_triangles > 0
    # The overlay and the canvas's label describe the frame on screen: its triangles.
    assert p.text_content('#overlay [data-field="triangles"]') == str(want.n_triangles)
    assert p.eval_on_selector("#overlay [data-meshes]", "e => e.hidden") is False
    assert c.hook("lastFrame.triangles") == want.n_triangles
    label = p.get_attribute("#view", "aria-label")
    assert "teapot" in label and f"{want.n_triangles} triangles" in label
    # n, seed and radius make no mesh scene: hidden; the picker stays.
    for name in ("n", "seed", "radius"):
        assert not p.is_visible(f"#f-{name}"), name
    assert p.is_visible(PICKER)
    # Another: the mixed scene (spheres and triangles), then back to spheres with the old n.
    n1 = c.frame_count
    p.select_option("#f-scenario", "mesh:mixed")
    p.wait_for_function("id => window.pocketray.sessionId !== id", arg=sid)
    c.wait_idle(min_frames=n1 + 1)
    mixed = server.session(c.hook("sessionId"))["scene_info"]
    assert mixed["n_spheres"] == 27 and mixed["n_triangles"] == mesh_scene("mixed").n_triangles
    assert p.text_content('#overlay [data-field="triangles"]') == str(mixed["n_triangles"])
    n2 = c.frame_count
    sid2 = c.hook("sessionId")
    p.select_option("#f-scenario", "1")
    p.wait_for_function("id => window.pocketray.sessionId !== id", arg=sid2)
    c.wait_idle(min_frames=n2 + 1)
    back = server.session(c.hook("sessionId"))["scene_info"]
    assert back["scenario"] == 1 and back["n"] == 64 and back.get("n_triangles", 0) == 0
    assert p.eval_on_selector("#overlay [data-meshes]", "e => e.hidden") is True
    assert c.hook("errors") == [] and c.errors() == []


def test_an_uploaded_obj_joins_the_scene_and_changes_the_frame(open_client, server):
    c = open_client("mobile")
    p = c.page
    sid = c.hook("sessionId")
    before = server.session(sid)
    assert before["scene_info"].get("n_triangles", 0) == 0
    pixels = canvas_pixels(p)
    ball = export_mesh(icosphere(2), "obj")
    n_tri = load_mesh(ball, "obj").n_triangles
    open_sheet(c)
    n0 = c.frame_count
    p.set_input_files(PICKER, files=[{"name": "ball.obj", "mimeType": "text/plain", "buffer": ball}])
    p.wait_for_function("v => window.pocketray.lastFrameVersion > v", arg=before["version"])
    c.wait_idle(min_frames=n0 + 1)
    assert c.hook("sessionId") == sid  # the same session, its scene grown
    after = server.session(sid)
    assert after["scene_info"]["n_triangles"] == n_tri and after["scene_info"]["n_meshes"] == 1
    assert after["version"] > before["version"] and c.hook("lastFrameVersion") == after["version"]
    assert after["scene_info"]["n_spheres"] == before["scene_info"]["n_spheres"]
    assert canvas_pixels(p) != pixels  # the model is in the frame
    assert p.text_content('#overlay [data-field="triangles"]') == str(n_tri)
    assert f"{n_tri} triangles" in p.get_attribute("#view", "aria-label")
    assert invalid(p, "model") is None
    # the service framed the camera again to show the model beside the scene
    assert server.session(sid)["camera"] != before["camera"]
    assert c.hook("errors") == [] and c.errors() == []


def test_a_gltf_picked_with_its_bin_and_image_is_sent_as_one_zip(open_client, server):
    """Several files picked at once: the client zips them (stored), the service opens the zip and
    finds the .gltf's buffer beside it; a second model among them is refused before sending."""
    c = open_client("mobile")
    p = c.page
    sid = c.hook("sessionId")
    before = server.session(sid)
    folder = CORPUS / "glTF2" / "BoxTextured-glTF"
    picked = [
        {"name": n, "mimeType": "application/octet-stream", "buffer": (folder / n).read_bytes()}
        for n in ("BoxTextured.gltf", "BoxTextured0.bin", "CesiumLogoFlat.png")
    ]
    open_sheet(c)
    n0 = c.frame_count
    p.set_input_files(PICKER, files=picked)
    p.wait_for_function("v => window.pocketray.lastFrameVersion > v", arg=before["version"])
    c.wait_idle(min_frames=n0 + 1)
    after = server.session(sid)
    assert after["scene_info"]["n_triangles"] == 12 and after["scene_info"]["n_meshes"] == 1
    assert invalid(p, "model") is None
    two = [*picked, {"name": "ball.obj", "mimeType": "text/plain", "buffer": export_mesh(icosphere(1), "obj")}]
    p.set_input_files(PICKER, files=two)
    p.wait_for_function("() => document.querySelector('#f-model-error')?.textContent.includes('pick one model')")
    assert server.session(sid)["version"] == after["version"]
    assert c.hook("errors") == [] and c.errors() == []


def test_a_corrupt_misnamed_or_too_big_file_is_refused_next_to_the_picker(open_client, server):
    c = open_client("mobile")
    c.wait_rest()  # the first view's refinement done: nothing changes the canvas but the upload
    p = c.page
    sid = c.hook("sessionId")
    before = server.session(sid)
    pixels, frames = canvas_pixels(p), c.frame_count
    open_sheet(c)
    # Corrupt: the service's 422, in the panel's words, next to the picker.
    p.set_input_files(
        PICKER,
        files=[
            {"name": "broken.ply", "mimeType": "application/octet-stream", "buffer": b"this is not a ply file\n" * 4}
        ],
    )
    p.wait_for_function("() => window.pocketray.errors.length > 0")
    text = invalid(p, "model")
    assert text and text.startswith("Model: ") and "PLY" in text, text
    assert not any(w in text for w in API_WORDS), text
    err = c.hook("errors")[-1]
    assert err["status"] == 422 and err["inline"] is True and err["field"] == "model"
    c.wait_idle()
    assert server.session(sid)["version"] == before["version"]  # nothing changed
    assert server.session(sid)["scene_info"] == before["scene_info"]
    assert c.hook("sessionId") == sid and c.frame_count == frames and canvas_pixels(p) == pixels
    # Misnamed: refused here, nothing sent.
    p.set_input_files(PICKER, files=[{"name": "notes.txt", "mimeType": "text/plain", "buffer": b"v 0 0 0\n"}])
    p.wait_for_function("() => document.querySelector('#f-model-error')?.textContent.includes('notes.txt')")
    assert ".obj" in invalid(p, "model")
    # Too big for the service's body limit (GET /api/info): refused before the upload.
    p.evaluate("() => { window.pocketray.info.limits.max_body_bytes = 1000; }")
    ball = export_mesh(icosphere(2), "obj")
    assert len(ball) > 1000
    p.set_input_files(PICKER, files=[{"name": "ball.obj", "mimeType": "text/plain", "buffer": ball}])
    p.wait_for_function("() => document.querySelector('#f-model-error')?.textContent.includes('too big')")
    assert "1 kB" in invalid(p, "model")
    assert server.session(sid)["version"] == before["version"] and canvas_pixels(p) == pixels
    # Closing the sheet puts the picker back unmarked.
    p.click("#settings [data-close]")
    assert p.get_attribute(PICKER, "aria-invalid") is None
    assert c.errors(allow=("Failed to load resource",)) == []


def test_upload_refusals_in_the_panel_words(open_client):
    c = open_client("mobile")
    got = c.page.evaluate("""async () => {
      const m = await import('/js/ui/messages.js');
      const big = m.explainUpload({status: 413, detail: 'body: request body of 70000000 bytes exceeds the limit of '
                                    + '67108864 bytes (POCKETRAY_MAX_BODY_BYTES)'});
      const bad = m.explainUpload({status: 422, detail: [{loc: ['body'], msg: 'body: the model has 2,000,000 '
                                    + 'triangles; at most 1,048,576 allowed (POCKETRAY_MAX_TRIANGLES = 1048576, 0 in '
                                    + 'the scene)'}]});
      return {big, bad, name: m.modelFileProblem('a.dae', 10, 'dae', ['obj', 'stl'], 100),
              empty: m.modelFileProblem('a.obj', 0, 'obj', ['obj'], 100),
              ok: m.modelFileProblem('a.obj', 10, 'obj', ['obj'], 100)};
    }""")
    assert got["big"] == {
        "field": "model",
        "status": 413,
        "text": "Model: the file is too big (70.0 MB; the service takes at most 67.1 MB)",
    }
    assert got["bad"]["field"] == "model" and got["bad"]["text"].startswith("Model: the model has 2,000,000 triangles")
    assert "POCKETRAY" not in got["bad"]["text"]
    assert got["name"] == "Model: a.dae is not a model file the service reads (.obj, .stl)"
    assert got["empty"] == "Model: a.obj is empty" and got["ok"] is None


def test_in_device_mode_an_uploaded_model_is_traced_by_the_device(browser, server):
    """The device fetches the grown scene's data after an upload (its triangles in the frame)."""
    from browser_support import CHROMIUM, CHROMIUM_ARGS, MOBILE, Client

    gl = browser.browser_type.launch(
        executable_path=CHROMIUM,
        headless=True,
        args=[*CHROMIUM_ARGS, "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
    )
    try:
        ctx = gl.new_context(**MOBILE)
        c = Client(server, ctx, ctx.new_page())
        c.open(
            "scenario=1&n=27&seed=1&radius=1&width=96&height=160&max_recursion_depth=2&preview_scale=1"
            "&refine_ms=0&renderer=device&mode=color"
        )
        p = c.page
        assert c.hook("lastFrame.renderer") == "device"
        sid, pixels = c.hook("sessionId"), canvas_pixels(p)
        version = server.session(sid)["version"]
        open_sheet(c)
        ball = export_mesh(icosphere(2), "obj")
        p.set_input_files(PICKER, files=[{"name": "ball.obj", "mimeType": "text/plain", "buffer": ball}])
        p.wait_for_function("v => window.pocketray.lastFrameVersion > v", arg=version)
        c.wait_idle()
        assert c.hook("lastFrame.renderer") == "device" and c.hook("sessionId") == sid
        assert server.session(sid)["scene_info"]["n_triangles"] == load_mesh(ball, "obj").n_triangles
        assert canvas_pixels(p) != pixels
        assert c.hook("lastFrame.triangles") == load_mesh(ball, "obj").n_triangles
        assert c.hook("errors") == [] and c.errors() == []
    finally:
        gl.close()


def test_a_link_to_a_mesh_scene_opens_it_and_a_reload_keeps_it(open_client, server):
    c = open_client("mobile", "scenario=mesh:room&width=160&height=272&max_recursion_depth=2&preview_scale=1")
    p = c.page
    sid = c.hook("sessionId")
    info = server.session(sid)["scene_info"]
    assert info["mesh_scene"]["kind"] == "room" and info["n_triangles"] == mesh_scene("room").n_triangles
    assert p.eval_on_selector("#f-scenario", "e => e.value") == "mesh:room"
    p.reload()
    c.wait_idle(min_frames=1)
    assert c.hook("sessionId") == sid  # the same scene asked for: the stored session
    assert c.hook("errors") == [] and c.errors() == []

"""Device mode path-traces: with ``integrator=path`` the browser's WebGL2 runs the server's path
integrator (the same GLSL ES 3.00 variant, data and uniforms from ``device-data``), in passes of
``path.samples_per_pass`` samples summed in a float target, and shows the mean tone-mapped as the
server's png.

The same sampler gives the same paths on both sides (a pixel's sample i depends on the pixel and
i alone), so the frames differ only by the two GL implementations' float arithmetic (Mesa's
llvmpipe; Chromium's ANGLE on SwiftShader here): the device's frame is the server's at the same
sample count, PSNR ≥ 40 dB, for the Cornell box with bih and bvh (and the other one-pass tree
methods). The display's tone map (GLSL, client_web/js/device/device_gl.js) is checked against
renderer/image/tonemap.py on the device's own radiance. Nothing here skips.
"""

from __future__ import annotations

import base64
import io
import urllib.request

import numpy as np
import pytest
from browser_support import MOBILE, Client, canvas_rgb, http_json
from PIL import Image

from renderer.image.tonemap import display_u8
from renderer.limits import DEVICE_PATH_SAMPLES_PER_PASS
from tests.helpers import psnr

pytestmark = pytest.mark.long  # a browser tracing paths on the device

W = 64
SPP = 64
DEPTH = 6
TONE = dict(tone_map="aces", exposure=0.5)
# (denoise off: the demo recommends OIDN, and the device would then filter its image by its guides)
CORNELL = {"mesh_scene": {"kind": "cornell", "detail": 1}, "settings": {"denoise": "off"}}


@pytest.fixture(scope="module")
def cornell(server) -> str:
    return http_json("POST", f"{server.base}/api/sessions", CORNELL)["id"]


def server_frame(server, sid: str, **q) -> bytes:
    query = "&".join(f"{k}={v}" for k, v in q.items())
    with urllib.request.urlopen(f"{server.base}/api/sessions/{sid}/frame?{query}", timeout=120) as r:
        return r.read()


def device_path_render(c: Client, **params) -> dict:
    r = c.page.evaluate("(p) => window.pocketray.device.renderOnce(p)", params)
    h, w = r["height"], r["width"]
    r["color"] = np.frombuffer(base64.b64decode(r["color"]), np.uint8).reshape(h, w, 3)
    assert r["radiance"] is not None, "a path-traced frame reads back its radiance"
    r["radiance"] = np.frombuffer(base64.b64decode(r["radiance"]), np.float32).reshape(h, w, 3)
    return r


# Every one-pass method: BIH and BVH on the Cornell box at 64 × 64 and 64 samples, the other trees
# at 32 × 32; brute force (every ray tests every triangle) on its coarsest tessellation at 16
# samples, so that SwiftShader takes seconds.
CASES = {
    "bih": (1, W, SPP),
    "bvh": (1, W, SPP),
    "kdtree": (1, 32, SPP),
    "twolevel": (1, 32, SPP),
    "bruteforce": (0, 32, 16),
}


@pytest.mark.parametrize("method", list(CASES))
def test_device_path_frame_equals_the_servers(device_page, server, method):
    detail, side, spp = CASES[method]
    body = {"mesh_scene": {"kind": "cornell", "detail": detail}, "settings": {"denoise": "off"}}
    cornell = http_json("POST", f"{server.base}/api/sessions", body)["id"]
    common = dict(
        width=side, height=side, method=method, integrator="path", max_recursion_depth=DEPTH, samples_per_pixel=spp
    )
    dev = device_path_render(device_page, session=cornell, mode="color", **common, **TONE)
    assert dev["infoLog"] == {"vertex": "", "fragment": "", "program": ""}, dev["infoLog"]
    assert "PATH" in dev["shader"]["features"] and dev["shader"]["max_recursion_depth"] == DEPTH
    assert dev["path"] == {"samples": spp, "perPass": DEVICE_PATH_SAMPLES_PER_PASS, "guides": False}
    assert dev["bands"] >= spp // DEVICE_PATH_SAMPLES_PER_PASS  # one pass per 4 samples, each in bands

    radiance = np.load(io.BytesIO(server_frame(server, cornell, format="npy", mode="color", **common)))
    assert radiance.dtype == np.float32 and radiance.shape == (side, side, 3)
    assert radiance.mean() > 0.05  # the box is lit
    # Linear radiance, compared where the display sees it (clamp, no exposure: 0 … 1 → 0 … 255).
    linear = psnr(display_u8(dev["radiance"], "clamp", 0.0), display_u8(radiance, "clamp", 0.0))
    rel = float(np.sqrt(np.mean((dev["radiance"] - radiance) ** 2)) / np.sqrt(np.mean(radiance**2)))
    print(f"{method}: linear radiance PSNR {linear:.2f} dB, relative RMS {rel:.2e}")
    assert linear >= 40.0 and rel < 0.01, (linear, rel)

    png = server_frame(server, cornell, format="png", mode="color", **common, **TONE)
    shown = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
    print(f"{method}: tone-mapped canvas against the server's png: {psnr(dev['color'], shown):.2f} dB")
    assert psnr(dev["color"], shown) >= 40.0, psnr(dev["color"], shown)
    # The canvas is renderer/image/tonemap.py's display of the device's own radiance (GLSL float32 vs
    # NumPy float64: a byte apart at most, at a rounding boundary).
    mine = display_u8(dev["radiance"], TONE["tone_map"], TONE["exposure"])
    diff = np.abs(dev["color"].astype(int) - mine.astype(int))
    assert diff.max() <= 1 and (diff == 0).mean() >= 0.99, (diff.max(), (diff == 0).mean())
    assert device_page.errors() == []


@pytest.mark.parametrize("tone_map", ["clamp", "reinhard", "aces"])
def test_the_display_tone_maps_as_the_server(device_page, server, cornell, tone_map):
    """Each operator at a bright and a dark exposure: the canvas is display_u8 of the radiance."""
    common = dict(width=24, height=24, method="bih", integrator="path", max_recursion_depth=3, samples_per_pixel=4)
    for exposure in (2.0, -1.5):
        dev = device_path_render(
            device_page, session=cornell, mode="color", tone_map=tone_map, exposure=exposure, **common
        )
        mine = display_u8(dev["radiance"], tone_map, exposure)
        diff = np.abs(dev["color"].astype(int) - mine.astype(int))
        assert diff.max() <= 1 and (diff == 0).mean() >= 0.98, (tone_map, exposure, diff.max(), (diff == 0).mean())
        assert len(np.unique(dev["color"])) > 8  # not one flat colour


def test_device_mode_in_the_client_path_traces(gl_browser, server):
    """The live view with integrator=path (a link's settings): device frames of the Cornell box at
    the session's sample count, the picture the server shows for the same view; a ray engine is
    refused (the service's 422 names the integrator) and the client says so."""
    ctx = gl_browser.new_context(**MOBILE)
    try:
        c = Client(server, ctx, ctx.new_page())
        c.open(
            "scenario=mesh:cornell&width=48&height=48&integrator=path&samples_per_pixel=16&tone_map=reinhard"
            # no denoiser (a new path session's own is on), no refinement past 16 samples: the server's frame
            "&max_recursion_depth=4&preview_scale=1&refine_ms=0&renderer=device&mode=color&denoise=off&refine_samples=16"
        )
        last = c.hook("lastFrame")
        assert last["renderer"] == "device", last
        assert c.hook("state.render.integrator") == "path" and c.hook("state.render.tone_map") == "reinhard"
        assert c.hook("device.path") == {"samples_per_pass": DEVICE_PATH_SAMPLES_PER_PASS, "guides": False}
        assert last["samples"] == 16
        shown_device = canvas_rgb(c)
        c.page.click("#settings-toggle")
        assert c.page.locator("#f-integrator").input_value() == "path"
        assert c.page.locator("#f-tone_map").input_value() == "reinhard"
        tone_field = c.page.locator('.field[data-setting="tone_map"]')
        assert not tone_field.is_hidden()  # shown with the path integrator (ui/limits.js: only there)

        n1 = c.frame_count  # the same view from the server: the same tone-mapped picture
        c.page.select_option("#f-renderer", "server")
        c.wait_idle(min_frames=n1 + 1)
        c.wait_rest()  # the server's view at rest: one sample, then refined to the 16 of the link
        assert c.hook("lastFrame.renderer") == "server" and c.hook("lastFrame.samples") == 16
        shown_server = canvas_rgb(c)
        assert shown_device.shape == shown_server.shape
        assert psnr(shown_device, shown_server) >= 40.0, psnr(shown_device, shown_server)
        assert c.errors() == [] and c.hook("errors") == []

        # Whitted's image is not tone-mapped: the sheet hides tone map and exposure then.
        n2 = c.frame_count
        c.page.select_option("#f-integrator", "whitted")
        c.wait_idle(min_frames=n2 + 1)
        assert c.hook("state.render.integrator") == "whitted" and tone_field.is_hidden()
        c.page.select_option("#f-integrator", "path")
        c.wait_idle(min_frames=n2 + 2)

        # A ray engine cannot trace paths: the service's 422 names the integrator, in a notice (its
        # field is hidden with a ray engine, which does not read it).
        c.page.select_option("#f-method", "rayengine")
        c.page.wait_for_selector("#notice:not(:empty)")
        said = c.page.locator("#notice").inner_text()
        assert "integrator 'path' is not available with method 'rayengine'" in said, said
    finally:
        ctx.close()

"""Device mode accumulates and denoises as the server does.

- The à-trous filter's GLSL (client_web/js/device/device_gl.js) is renderer/image/atrous.py's NumPy
  port, run on the very inputs the device read back (its mean radiance and guides).
- On a noisy 16-sample Cornell box the device's filtered frame is closer to Mitsuba 3's (the
  independent oracle) than its unfiltered one.
- While the view rests the live client adds one pass per frame to the same sum, past the
  session's samples_per_pixel up to its refinement target (refine_samples, as the server's
  stream): after k steps its mean is the server's frame of all k passes' samples (PSNR ≥ 40 dB,
  as tests/browser/test_device_path.py), and a gesture starts a new sum.
Nothing here skips; the images are 32 × 32 (SwiftShader is slow).
"""

from __future__ import annotations

import base64
import io
import math
import urllib.request

import numpy as np
import pytest
from browser_support import MOBILE, Client, Touch, http_json

from renderer.image.atrous import atrous
from renderer.image.tonemap import display_u8
from renderer.limits import DEVICE_PATH_SAMPLES_PER_PASS
from renderer.oracle import mitsuba_scene
from renderer.scenes.scenarios import mesh_scene
from tests.helpers import psnr

SIDE = 32
DEPTH = 8
CORNELL = {"mesh_scene": {"kind": "cornell", "detail": 0, "smooth": False}}
MITSUBA_SPP = 256  # its own noise bounds both PSNRs: the bar is a gain, not a level


@pytest.fixture(scope="module")
def filtered(device_page, server) -> dict:
    """A 16-sample Cornell box traced by the device with denoise=atrous, its arrays read back."""
    sid = http_json("POST", f"{server.base}/api/sessions", CORNELL)["id"]
    params = dict(
        session=sid, width=SIDE, height=SIDE, method="bih", mode="color", integrator="path",
        max_recursion_depth=DEPTH, samples_per_pixel=16, denoise="atrous",
    )  # fmt: skip
    r = device_page.page.evaluate("(p) => window.pocketray.device.renderOnce(p)", params)
    assert r["infoLog"] == {"vertex": "", "fragment": "", "program": ""}, r["infoLog"]
    assert "GUIDES" in r["shader"]["features"] and r["path"]["guides"] is True
    for k in ("radiance", "albedo", "normal", "denoised"):
        assert r[k] is not None, f"{k} read back: {r['display']} {r['path']}"
        r[k] = np.frombuffer(base64.b64decode(r[k]), np.float32).reshape(SIDE, SIDE, 3)
    return r


def test_the_glsl_filter_is_the_numpy_port(filtered):
    mine = atrous(filtered["radiance"], filtered["albedo"], filtered["normal"], 16)
    got = filtered["denoised"]
    # float32 on both sides, exp() and the sums' order differ: relative 1e-4 of the image's scale.
    scale = float(np.abs(mine).max())
    err = float(np.abs(got - mine).max())
    print(f"à-trous GLSL vs NumPy: max |Δ| {err:.2e} (image max {scale:.2f})")
    assert err <= 1e-4 * scale, (err, scale)
    assert float(np.abs(got - filtered["radiance"]).mean()) > 1e-3, "the filter changed the image"
    inside = np.linalg.norm(filtered["normal"], axis=-1) > 0.5  # the guides are means of unit normals
    assert inside.mean() > 0.9 and (filtered["albedo"] >= 0).all() and (filtered["albedo"] <= 1 + 1e-5).all()


def test_the_filter_brings_a_noisy_cornell_box_closer_to_mitsuba(filtered):
    reference = mitsuba_scene.render(mesh_scene("cornell", 0, smooth=False), SIDE, SIDE, MITSUBA_SPP, DEPTH)

    def db(a: np.ndarray) -> float:
        mse = float(np.mean((np.clip(a, 0, 1).astype(np.float64) - np.clip(reference, 0, 1)) ** 2))
        return -10.0 * math.log10(mse)

    noisy, denoised = db(filtered["radiance"]), db(filtered["denoised"])
    print(f"16 samples against Mitsuba {MITSUBA_SPP}: noisy {noisy:.2f} dB, à-trous {denoised:.2f} dB")
    assert denoised >= noisy + 1.0, (noisy, denoised)


def server_npy(server, sid: str, **q) -> np.ndarray:
    query = "&".join(f"{k}={v}" for k, v in q.items())
    with urllib.request.urlopen(f"{server.base}/api/sessions/{sid}/frame?{query}", timeout=120) as r:
        return np.load(io.BytesIO(r.read()))


def live_radiance(c: Client) -> np.ndarray:
    rb = c.hook("device.readback()")
    return np.frombuffer(base64.b64decode(rb["radiance"]), np.float32).reshape(rb["height"], rb["width"], 3)


def test_the_resting_view_accumulates_passes_into_the_servers_frame(gl_browser, server):
    spp = 4 * DEVICE_PATH_SAMPLES_PER_PASS  # four rests of one pass each
    # A square screen: the Cornell box is framed for the screen's aspect (renderer/scenes/scenarios.py
    # fit_camera), so the square frames compared here show it as large as a portrait screen's width does.
    ctx = gl_browser.new_context(**{**MOBILE, "viewport": {"width": 360, "height": 360}})
    try:
        c = Client(server, ctx, ctx.new_page())
        c.open(
            # samples_per_pixel is one pass: the resting view goes past it to the refinement target
            f"scenario=mesh:cornell&width={SIDE}&height={SIDE}&integrator=path"
            f"&samples_per_pixel={DEVICE_PATH_SAMPLES_PER_PASS}&refine_samples={spp}"
            "&max_recursion_depth=4&preview_scale=1&refine_ms=0&renderer=device&mode=color&denoise=off"
        )
        sid = c.hook("sessionId")
        steps = [DEVICE_PATH_SAMPLES_PER_PASS * (i + 1) for i in range(4)]
        c.page.wait_for_function("() => window.pocketray.idle && window.pocketray.device.accumulation?.samples === 16")
        acc = c.hook("device.accumulation")
        assert acc == {"samples": spp, "target": spp, "shown": steps}, acc  # each mean shown as it grew
        assert c.hook("lastFrame.samples") == spp and c.hook("lastFrame.renderer") == "device"
        common = dict(format="npy", mode="color", integrator="path", samples_per_pixel=spp, max_recursion_depth=4)

        def agrees() -> float:
            """PSNR of the device's mean against the server's frame, over the pixels where no path
            took another branch: SwiftShader's and llvmpipe's float32 differ in the last bits, and a
            path that meets an edge then may bounce elsewhere — at most 2 of the 1,024 pixels (their
            radiance 0.05 apart or more), every other one the same samples."""
            radiance = server_npy(server, sid, width=SIDE, height=SIDE, **common)
            live = live_radiance(c)
            diverged = np.abs(live - radiance).max(axis=2) >= 0.05
            assert diverged.sum() <= 2, int(diverged.sum())
            keep = ~diverged
            return psnr(display_u8(live, "clamp", 0.0)[keep], display_u8(radiance, "clamp", 0.0)[keep])

        first = agrees()
        assert first >= 40.0, first

        # A gesture: the sum starts again from the new view's first pass, and grows to the same target.
        n0 = c.frame_count
        box = c.page.locator("#view").bounding_box()
        x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        Touch(c.page).gesture([(x, y)], [(x + 30, y + 5)], steps=4)
        c.wait_idle(min_frames=n0 + 1, timeout=60_000)
        c.page.wait_for_function("() => window.pocketray.idle && window.pocketray.device.accumulation?.samples === 16")
        assert c.hook("device.accumulation")["shown"] == steps
        second = agrees()  # the server's Model followed the gesture: the same view, the same samples
        print(f"accumulated {spp} samples in {len(steps)} rests: {first:.2f} dB, after a gesture {second:.2f} dB")
        assert second >= 40.0, second
        assert c.errors() == [] and c.hook("errors") == []
    finally:
        ctx.close()


def test_the_resting_view_shows_each_mean_filtered_with_a_denoiser(gl_browser, server):
    """A link's denoise=atrous: the data's variant writes the guides and every mean shown is the
    filter's output, tone-mapped (the canvas is display_u8 of the filtered mean)."""
    side, spp = 24, 2 * DEVICE_PATH_SAMPLES_PER_PASS
    ctx = gl_browser.new_context(**MOBILE)
    try:
        c = Client(server, ctx, ctx.new_page())
        c.open(
            f"scenario=mesh:cornell&width={side}&height={side}&integrator=path&samples_per_pixel={spp}&refine_samples={spp}"
            "&max_recursion_depth=4&preview_scale=1&refine_ms=0&renderer=device&mode=color&denoise=atrous"
        )
        c.page.wait_for_function(
            f"() => window.pocketray.idle && window.pocketray.device.accumulation?.samples === {spp}"
        )
        assert c.hook("device.path")["guides"] is True  # the session's denoise: the data's variant has GUIDES
        assert c.hook("device.accumulation")["shown"] == [DEVICE_PATH_SAMPLES_PER_PASS, spp]
        rb = c.hook("device.readback()")
        arrays = {
            k: np.frombuffer(base64.b64decode(rb[k]), np.float32).reshape(side, side, 3)
            for k in ("radiance", "albedo", "normal", "denoised")
        }
        mine = atrous(arrays["radiance"], arrays["albedo"], arrays["normal"], spp)
        assert np.abs(arrays["denoised"] - mine).max() <= 1e-4 * float(np.abs(mine).max())
        shown = np.frombuffer(base64.b64decode(rb["color"]), np.uint8).reshape(side, side, 3)
        diff = np.abs(shown.astype(int) - display_u8(arrays["denoised"], "clamp", 0.0).astype(int))
        assert diff.max() <= 1 and (diff == 0).mean() >= 0.98, (diff.max(), (diff == 0).mean())
        assert c.errors() == [] and c.hook("errors") == []
    finally:
        ctx.close()

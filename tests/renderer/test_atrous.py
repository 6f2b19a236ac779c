"""The edge-avoiding à-trous filter (renderer/atrous.py), the server's ``denoise=atrous`` and the
reference of the device's GLSL copy (tests/browser/test_device_denoise.py holds them equal): it
keeps a flat image, smooths noise where the guides agree, keeps an edge where they differ, and the
server's frame with ``denoise=atrous`` is the filter of its own mean and guides."""

from __future__ import annotations

import numpy as np

from renderer.atrous import atrous, parameters
from renderer.denoise import denoise_result
from renderer.scenarios import mesh_scene
from renderer.settings import DENOISERS, RenderSettings

H, W = 24, 20


def flat_guides() -> tuple[np.ndarray, np.ndarray]:
    albedo = np.full((H, W, 3), 0.5, np.float32)
    normal = np.zeros((H, W, 3), np.float32)
    normal[..., 2] = 1.0
    return albedo, normal


def test_a_flat_image_stays_flat():
    albedo, normal = flat_guides()
    image = np.full((H, W, 3), 2.5, np.float32)
    out = atrous(image, albedo, normal)
    assert out.dtype == np.float32 and out.shape == image.shape
    np.testing.assert_allclose(out, image, rtol=1e-6)


def test_noise_is_smoothed_where_the_guides_agree():
    albedo, normal = flat_guides()
    rng = np.random.default_rng(1)
    image = (0.5 + 0.05 * rng.standard_normal((H, W, 3))).astype(np.float32)
    out = atrous(image, albedo, normal)
    assert out.std() < 0.3 * image.std(), (out.std(), image.std())
    assert abs(float(out.mean()) - float(image.mean())) < 0.01


def test_an_edge_of_the_normal_guide_stays_sharp():
    albedo, normal = flat_guides()
    image = np.full((H, W, 3), 0.4, np.float32)  # a step the colour's weight alone hardly stops
    image[:, W // 2 :] = 0.6
    turned = normal.copy()
    turned[:, W // 2 :] = (1.0, 0.0, 0.0)  # another face of the scene
    kept = atrous(image, albedo, turned)
    blurred = atrous(image, albedo, normal)  # the same step with nothing telling the faces apart
    step = slice(W // 2 - 1, W // 2 + 1)
    assert np.abs(kept[:, step] - image[:, step]).max() < 1e-3
    assert np.abs(blurred[:, step] - image[:, step]).max() > 0.02


def test_the_setting_and_the_parameters():
    assert "atrous" in DENOISERS
    p = parameters()
    assert p["iterations"] == 5 and len(p["kernel"]) == 5 and abs(sum(p["kernel"]) - 1.0) < 1e-12


def test_the_servers_atrous_frame_is_the_filter_of_its_mean_and_guides(gl_renderer):
    scene = mesh_scene("cornell", 0, smooth=False)
    settings = RenderSettings(
        width=16, height=16, integrator="path", samples_per_pixel=4, max_recursion_depth=4, format="npy"
    )
    traced = gl_renderer.render(scene, settings.with_(denoise="atrous"))
    assert traced.guides is not None, "denoise=atrous traces the guides' variant"
    out = denoise_result(traced, scene, "atrous")
    assert out.stats["denoise"] == "atrous" and out.samples == traced.samples
    np.testing.assert_array_equal(out.image, np.maximum(atrous(traced.image, *traced.guides), 0.0))
    assert not np.array_equal(out.image, traced.image)

"""The edge-avoiding à-trous filter (renderer/image/atrous.py), the server's ``denoise=atrous`` and the
reference of the device's GLSL copy (tests/browser/test_device_denoise.py holds them equal): it
keeps a flat image, smooths noise where the guides agree, keeps an edge where they differ, and the
server's frame with ``denoise=atrous`` is the filter of its own mean and guides."""

from __future__ import annotations

import numpy as np

from renderer.config.settings import DENOISERS, RenderSettings
from renderer.image.atrous import atrous, parameters
from renderer.image.denoise import denoise_result
from renderer.scenes.scenarios import mesh_scene

H, W = 24, 20


def flat_guides() -> tuple[np.ndarray, np.ndarray]:
    albedo = np.full((H, W, 3), 0.5, np.float32)
    normal = np.zeros((H, W, 3), np.float32)
    normal[..., 2] = 1.0
    return albedo, normal


def test_a_flat_image_stays_flat():
    albedo, normal = flat_guides()
    image = np.full((H, W, 3), 2.5, np.float32)
    out = atrous(image, albedo, normal, 16)
    assert out.dtype == np.float32 and out.shape == image.shape
    np.testing.assert_allclose(out, image, rtol=1e-6)


def test_noise_is_smoothed_where_the_guides_agree():
    albedo, normal = flat_guides()
    rng = np.random.default_rng(1)
    image = (0.5 + 0.05 * rng.standard_normal((H, W, 3))).astype(np.float32)
    out = atrous(image, albedo, normal, 16)
    assert out.std() < 0.3 * image.std(), (out.std(), image.std())
    assert abs(float(out.mean()) - float(image.mean())) < 0.01


def test_an_edge_of_the_normal_guide_stays_sharp():
    albedo, normal = flat_guides()
    rng = np.random.default_rng(4)
    clean = np.full((H, W, 3), 0.45, np.float32)  # a step smaller than the noise: the luminance alone
    clean[:, W // 2 :] = 0.55  # cannot tell it from the noise
    image = (clean + 0.08 * rng.standard_normal((H, W, 3))).astype(np.float32)
    turned = normal.copy()
    turned[:, W // 2 :] = (1.0, 0.0, 0.0)  # another face of the scene
    kept = atrous(image, albedo, turned, 1)
    blurred = atrous(image, albedo, normal, 1)  # the same step with nothing telling the faces apart
    step = slice(W // 2 - 1, W // 2 + 1)

    def jump(out: np.ndarray) -> float:
        return float(out[:, step][:, 1].mean() - out[:, step][:, 0].mean())

    assert abs(jump(kept) - 0.1) < 0.03, jump(kept)  # the faces' step across the edge's two columns
    assert jump(blurred) < 0.06, jump(blurred)


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
    np.testing.assert_array_equal(out.image, np.maximum(atrous(traced.image, *traced.guides, traced.samples), 0.0))
    assert not np.array_equal(out.image, traced.image)


def pattern_under_flat_guides() -> np.ndarray:
    """A mirror's reflected detail as the filter sees it: 4-pixel checks of 0.2 and 0.8 that neither
    guide shows (a mirror's first hit is one albedo and one smooth normal)."""
    yy, xx = np.mgrid[:H, :W]
    checks = ((yy // 4 + xx // 4) % 2).astype(np.float32)
    return np.repeat((0.2 + 0.6 * checks)[..., None], 3, axis=2)


def test_detail_that_the_guides_do_not_show_is_kept_at_one_sample():
    albedo, normal = flat_guides()
    clean = pattern_under_flat_guides()
    rng = np.random.default_rng(2)
    noisy = (clean * (1.0 + 0.1 * rng.standard_normal((H, W, 1)))).astype(np.float32)
    out = atrous(noisy, albedo, normal, 1)  # one sample: the noisiest mean, the filter at its widest
    err_out = float(np.abs(out - clean).mean())
    err_in = float(np.abs(noisy - clean).mean())
    # The checks stay: the filter's error is below the noise's, where smoothing them away costs 0.3.
    assert err_out < err_in, (err_out, err_in)


def test_a_firefly_is_not_spread_into_a_blotch():
    albedo, normal = flat_guides()
    rng = np.random.default_rng(3)
    image = (0.5 + 0.02 * rng.standard_normal((H, W, 3))).astype(np.float32)
    image[H // 2, W // 2] = 50.0  # one path that met a light by chance
    out = atrous(image, albedo, normal, 16)
    assert np.abs(out - 0.5).max() < 0.1, float(np.abs(out - 0.5).max())


def test_a_converged_image_is_left_alone():
    albedo, normal = flat_guides()
    yy, xx = np.mgrid[:H, :W]
    image = np.repeat((0.2 + 0.6 * xx / W + 0.3 * (yy > H // 2))[..., None], 3, axis=2).astype(np.float32)
    out = atrous(image, albedo, normal, 1024)
    assert np.abs(out - image).max() < 0.02 * float(image.max()), float(np.abs(out - image).max())


def test_the_corners_are_smoothed_as_the_rest():
    """A corner pixel's quadrant toward the outside holds no pixel: it measures no noise (0)."""
    albedo, normal = flat_guides()
    rng = np.random.default_rng(5)
    image = (0.5 + 0.05 * rng.standard_normal((H, W, 3))).astype(np.float32)
    out = atrous(image, albedo, normal, 16)
    corners = out[[0, 0, -1, -1], [0, -1, 0, -1]]
    assert np.abs(corners - 0.5).max() < 0.3 * np.abs(image - 0.5).max(), corners

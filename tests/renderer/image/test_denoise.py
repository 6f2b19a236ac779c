"""The denoiser (renderer/image/denoise.py): Intel Open Image Denoise guided by the first hit's albedo
and normal. Against Mitsuba 3 (the independent oracle of tests/renderer/gl/test_mitsuba.py), a
denoised 16-sample Cornell box is ≥ 3 dB closer than the noisy one; ``off`` changes nothing; the
albedo guide is each material's as the path integrator's lobes see it."""

from __future__ import annotations

import math

import numpy as np

from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Scene
from renderer.image.denoise import denoise_result, first_hit_albedo, material_albedos
from renderer.oracle import mitsuba_scene
from renderer.scenes.scenarios import mesh_scene

SIDE = 48
DEPTH = 8
# Mitsuba at 256 samples (3 s at 48²): its own noise bounds both PSNRs (measured: noisy 24.8 dB,
# denoised 28.7 dB), so 3 dB is the bar.
REFERENCE_SPP = 256


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR in dB of linear radiance clipped to [0, 1] (as tests/renderer/gl/test_mitsuba.py)."""
    mse = float(np.mean((np.clip(a, 0, 1).astype(np.float64) - np.clip(b, 0, 1)) ** 2))
    return math.inf if mse == 0 else -10.0 * math.log10(mse)


def test_a_denoised_cornell_box_is_closer_to_mitsuba(gl_renderer):
    scene = mesh_scene("cornell", 0, smooth=False)
    reference = mitsuba_scene.render(scene, SIDE, SIDE, REFERENCE_SPP, DEPTH)
    settings = RenderSettings(
        width=SIDE, height=SIDE, integrator="path", samples_per_pixel=16, max_recursion_depth=DEPTH, format="npy"
    )
    noisy = gl_renderer.render(scene, settings.with_(denoise="oidn"))  # traced with the guides
    assert np.array_equal(noisy.image, gl_renderer.render(scene, settings).image), "the radiance is as without"
    assert noisy.guides is not None and gl_renderer.render(scene, settings).guides is None
    albedo, normal = noisy.guides
    inside = noisy.primid >= 0
    length = np.linalg.norm(normal[inside], axis=-1)  # a mean of unit normals: 1 inside a face, less on edges
    assert (length <= 1.0 + 1e-5).all() and (np.abs(length - 1.0) < 1e-3).mean() > 0.8
    np.testing.assert_allclose(
        albedo.mean(axis=(0, 1)), first_hit_albedo(scene, noisy.primid).mean(axis=(0, 1)), atol=0.02
    )
    denoised = denoise_result(noisy, scene, "oidn")
    gain = psnr(denoised.image, reference) - psnr(noisy.image, reference)
    assert gain >= 3.0, gain
    assert denoised.image.dtype == np.float32 and denoised.image.shape == noisy.image.shape
    assert (denoised.image >= 0).all() and denoised.stats["denoise"] == "oidn"
    assert np.array_equal(denoised.primid, noisy.primid) and denoised.samples == noisy.samples == 16
    assert denoise_result(noisy, scene, "off") is noisy, "off: the very result"


def test_the_albedo_guide_is_what_the_lobes_reflect():
    scene = Scene.from_json(
        {
            "camera": {"position": [0, 0, 5], "target": [0, 0, 0], "fov_y": 40},
            "materials": [
                {"color": [0.5, 0.2, 0.1], "diffuse": 1.0, "reflective": 0.0},
                {"color": [0.2, 0.2, 0.2], "diffuse": 0.0, "reflective": 1.0},  # a mirror: white
                {"color": [1.0, 0.0, 0.0], "diffuse": 1.0, "reflective": 1.0},  # weights over 1: halved
            ],
            "spheres": [{"center": [0, 0, 0], "radius": 1, "material": 1}],
            "planes": [{"point": [0, -1, 0], "normal": [0, 1, 0], "material": 2}],
            "environment": {"color": [2.0, 0.5, 0.0]},
        }
    )
    np.testing.assert_allclose(material_albedos(scene), [[0.5, 0.2, 0.1], [1, 1, 1], [1.0, 0.5, 0.5]], atol=1e-6)
    primid = np.array([[0, 1, -1]], np.int32)
    np.testing.assert_allclose(first_hit_albedo(scene, primid)[0], [[1, 1, 1], [1.0, 0.5, 0.5], [1.0, 0.5, 0.0]])

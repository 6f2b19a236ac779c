"""Knobs that trade speed for accuracy or specialise the shader.

Specialisation must be exact (primid identical, colour PSNR ≥ 50 dB against
the generic variant); supersampling must equal the reference traced at the
higher resolution and box-filtered; the weight cut-off at ε = 0 changes nothing.
What the knobs' CPU halves decide is tested beside them: the scene features in
``tests/renderer/frame/test_features.py``, ``auto`` in ``test_methods.py``, validation in
``test_settings.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Material, Scene
from renderer.oracle.reference import render_reference
from renderer.scenes.scenarios import scenario
from tests.helpers import psnr

W, H = 96, 160


def diffuse_only(n: int) -> Scene:
    s = scenario(3, n)
    matte = Material(
        color=(0.2, 0.6, 0.9), ambient=0.2, diffuse=0.7, specular=0.1, shininess=20, reflective=0.0, transmissive=0.0
    )
    return Scene(
        s.camera,
        s.lights,
        (matte,),
        s.sphere_centers,
        s.sphere_radii,
        np.zeros(s.n_spheres, np.int32),
        tuple(p.__class__(p.point, p.normal, 0) for p in s.planes),
    )


SCENES = {
    "diffuse-only": lambda: diffuse_only(64),
    "16 spheres": lambda: scenario(2, 16),
    "scenario 3": lambda: scenario(3, 256),
}


@pytest.mark.parametrize("name", list(SCENES))
def test_specialised_variant_is_exact(gl_renderer, name):
    scene = SCENES[name]()
    s = RenderSettings(width=W, height=H, max_recursion_depth=5)
    special = gl_renderer.render(scene, s)
    generic = gl_renderer.render(scene, s.with_(specialize=False))
    assert (special.primid == generic.primid).all()
    assert psnr(special.image_u8(), generic.image_u8()) >= 50.0
    if name == "diffuse-only":
        assert special.stats["recursion_depth"] == 1
        assert set(special.stats["features_removed"]) == {"NO_REFLECTION", "NO_TRANSMISSION"}
    assert generic.stats["features_removed"] == [] and generic.stats["recursion_depth"] == 5


def test_supersampling_matches_reference_box_filter(gl_renderer):
    scene = scenario(2, 64)
    s = RenderSettings(width=48, height=80, max_recursion_depth=3, samples_per_pixel=4)
    gpu = gl_renderer.render(scene, s)
    big = render_reference(scene, s.with_(width=96, height=160, samples_per_pixel=1))
    expect = np.clip(big.image, 0, 1).reshape(80, 2, 48, 2, 3).mean(axis=(1, 3))
    expect_u8 = np.floor(expect * 255 + 0.5).astype(np.uint8)
    assert gpu.image.shape == (80, 48, 3)
    assert psnr(gpu.image_u8(), expect_u8) >= 40.0
    # The ids are those of the rays through the pixel centres (docs/FORMATS.md), not of a sub-pixel.
    centre = render_reference(scene, s.with_(samples_per_pixel=1, mode="primid"))
    assert (gpu.primid == centre.primid).mean() >= 0.999
    assert (gpu.primid != big.primid[1::2, 1::2]).any(), "a sub-pixel's id is not the centre's everywhere"
    # The reference supersamples the same way.
    ref = render_reference(scene, s)
    assert ref.image.shape == (80, 48, 3) and (ref.image_u8() == expect_u8).all()
    assert (ref.primid == centre.primid).all()


@pytest.mark.parametrize("mode", ["depth", "primid", "normal"])
def test_data_modes_trace_the_pixel_centres_whatever_the_samples(gl_renderer, mode):
    """depth, primid and normal are one ray through each pixel centre at any samples_per_pixel."""
    scene = scenario(3, 64)
    s = RenderSettings(width=48, height=80, mode=mode, samples_per_pixel=4)
    one = gl_renderer.render(scene, s.with_(samples_per_pixel=1))
    four = gl_renderer.render(scene, s)
    for field in ("image", "depth", "primid", "normal"):
        np.testing.assert_array_equal(getattr(four, field), getattr(one, field))
    ref = render_reference(scene, s)
    assert (ref.primid == four.primid).mean() >= 0.999


def test_weight_cutoff(gl_renderer):
    scene = scenario(3, 64)
    s = RenderSettings(width=W, height=H, max_recursion_depth=5)
    base = gl_renderer.render(scene, s).image_u8()
    assert (gl_renderer.render(scene, s.with_(min_weight=0.0)).image_u8() == base).all()
    # kr, kt < 1: ε = 1 cuts every secondary ray, which is the depth-1 image.
    cut = gl_renderer.render(scene, s.with_(min_weight=1.0)).image_u8()
    primary = gl_renderer.render(scene, s.with_(max_recursion_depth=1)).image_u8()
    assert psnr(cut, primary) >= 60.0 and psnr(cut, base) < 60.0


def test_png_frames_at_one_sample_read_one_rgba8_target(gl_renderer):
    """A png or jpeg frame at 1 sample per pixel renders into one RGBA8 target, the
    shader rounding as image_u8 does: the same bytes as the float frame's image_u8. Its float
    arrays are traced again only when read (the service never reads them); a supersampled
    frame keeps its float sub-pixels."""
    scene = scenario(3, 256)
    s = RenderSettings(width=48, height=80, max_recursion_depth=3)
    png = gl_renderer.render(scene, s)
    npy = gl_renderer.render(scene, s.with_(format="npy"))
    assert png.stats["target"] == "rgba8" and npy.stats["target"] == "float"
    np.testing.assert_array_equal(png.image_u8(), npy.image_u8())
    assert png._full is None, "image_u8 did not trace again"
    for field in ("image", "depth", "primid", "normal"):
        np.testing.assert_array_equal(getattr(png, field), getattr(npy, field))
    assert gl_renderer.render(scene, s.with_(format="jpeg", samples_per_pixel=4)).stats["target"] == "float"
    from renderer.gl import GLRenderer

    assert GLRenderer(gl_renderer.ctx, image_targets=False).render(scene, s).stats["target"] == "float"


@pytest.mark.parametrize("mode", ["depth", "primid", "normal", "color", "recursion"])
def test_frames_draw_the_background_variant_where_rays_meet_no_sphere(gl_renderer, mode):
    """Outside the spheres' projected box (and, in colour and recursion, where the ray meets
    no plane either) a frame is drawn by the variant without traversal: the same pixels, bit
    for bit, in bands too; a camera inside the box draws every pixel with the tracer."""
    from renderer.gl import GLRenderer

    full = GLRenderer(gl_renderer.ctx, background=False)
    scene = scenario(3, 256)
    s = RenderSettings(width=64, height=96, mode=mode, format="npy", max_recursion_depth=4)
    culled = gl_renderer.render(scene, s)
    assert 0 < culled.stats["background_pixels"] < 64 * 96
    banded = gl_renderer.begin(scene, s, band_rows=7).run()
    # bands resized from their measured time (a budget no band meets: one row each after the first)
    fed_frame = gl_renderer.begin(scene, s, band_rows=7, slice_ms=1e-6)
    fed = fed_frame.run()
    assert fed_frame.band_rows == 1 and fed_frame.slices >= 96 - 7 + 1
    want = full.render(scene, s)
    for res in (culled, banded, fed):
        for field in ("image", "depth", "primid", "normal"):
            np.testing.assert_array_equal(getattr(res, field), getattr(want, field), err_msg=field)
    from renderer.geometry.scene import Camera

    inside = scene.with_camera(Camera(position=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0)))
    assert "background_pixels" not in gl_renderer.render(inside, s).stats


def whitted_slices(gl_renderer, scene: Scene, s: RenderSettings, n: int, per_frame: int = 1):
    """A Whitted accumulation of ``n`` slices, ``per_frame`` a frame, each frame going on from the
    sum and count the last one left; its last result."""
    held: tuple = (None, 0)
    for _ in range(0, n, per_frame):
        r = gl_renderer.begin(scene, s, accumulated=held, slices=per_frame).run()
        assert r.sample_sum is not None and r.sample_sum.dtype == np.float32
        held = (r.sample_sum, r.samples)
    return r


@pytest.mark.parametrize("spp", [1, 4])
def test_whitted_slices_add_up_to_one_frame_of_their_jittered_samples(gl_renderer, spp):
    """Frames of one jittered slice each, going on from the accumulation, equal one frame of all the
    slices (up to float rounding); the first slice alone is the plain frame, bit for bit."""
    scene = scenario(2, 16)
    s = RenderSettings(width=24, height=20, max_recursion_depth=3, samples_per_pixel=spp, format="npy")
    plain = gl_renderer.render(scene, s)
    first = gl_renderer.begin(scene, s, accumulated=(None, 0)).run()
    assert np.array_equal(first.image, plain.image) and first.samples == spp
    assert np.array_equal(first.primid, plain.primid) and np.array_equal(first.depth, plain.depth)
    np.testing.assert_allclose(first.sample_sum / spp, plain.image, rtol=1e-6, atol=1e-7)
    apart = whitted_slices(gl_renderer, scene, s, 4)
    together = gl_renderer.begin(scene, s, accumulated=(None, 0), slices=4).run()
    assert apart.samples == together.samples == 4 * spp == together.stats["samples"]
    np.testing.assert_allclose(apart.image, together.image, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(apart.sample_sum, together.sample_sum, rtol=1e-6, atol=1e-5)
    assert np.array_equal(apart.primid, plain.primid), "the ids stay the pixel centres'"
    assert np.abs(apart.image - plain.image).max() > 1e-3, "the later slices traced other points"
    # a png frame at one sample (an 8-bit target otherwise) accumulates in floats too
    png = gl_renderer.begin(scene, s.with_(format="png"), accumulated=(None, 0), slices=4).run()
    np.testing.assert_allclose(png.image, together.image, rtol=1e-6, atol=1e-6)


def test_whitted_accumulation_converges_to_the_pixel_integral(gl_renderer):
    """Near the spheres' silhouettes a pixel's mean over its area differs from any fixed grid's;
    the jittered slices' mean approaches the float64 reference's 32 × 32 sub-pixel mean as they
    grow (the R2 points fill the cells evenly), well past the 16-sample grid's error."""
    scene = scenario(2, 16)
    s = RenderSettings(width=20, height=16, max_recursion_depth=2, samples_per_pixel=4, format="npy")
    ref = render_reference(scene, s, supersample=32).image.astype(np.float64)
    centre = render_reference(scene, s, supersample=1).image
    edge = np.abs(ref - centre).max(axis=2) > 0.01  # the pixels the sub-pixel grid matters to
    assert edge.sum() >= 8

    def error(img: np.ndarray) -> float:
        return float(np.abs(img.astype(np.float64) - ref)[edge].mean())

    grid16 = error(gl_renderer.render(scene, s.with_(samples_per_pixel=16)).image)
    errs = {n: error(gl_renderer.begin(scene, s, accumulated=(None, 0), slices=n).run().image) for n in (1, 4, 64)}
    assert errs[1] > errs[4] > errs[64], errs
    assert errs[64] < 0.5 * grid16, (errs, grid16)


@pytest.mark.parametrize("k", [2, 3, 4])
@pytest.mark.parametrize("size", [(37, 23), (160, 96)])
def test_the_box_filter_adds_sub_pixels_as_the_interleaved_grid_did(k, size):
    """The box filter reads each sub-pixel pass's image where it was read back: bit for bit the mean
    (and the float64 sum) of the kH × kW grid they interleave into, whose reduction order it follows."""
    from renderer.gl.frame import box_filter

    h, w = size
    rng = np.random.default_rng(k)
    # Magnitudes spread over many binades, so that any other order of the additions rounds differently.
    subs = {
        (sx, sy): (rng.random((h, w, 4)) * 10.0 ** rng.integers(-6, 4, (h, w, 4))).astype(np.float32)
        for sy in range(k)
        for sx in range(k)
    }
    grid = np.empty((h * k, w * k, 4), np.float32)
    for (sx, sy), img in subs.items():
        grid[sy::k, sx::k] = img
    cells = grid[::-1][..., :3].reshape(h, k, w, k, 3)
    mean = box_filter(subs, k)
    assert mean.dtype == np.float32 and mean.shape == (h, w, 3)
    np.testing.assert_array_equal(mean, cells.mean(axis=(1, 3)))
    np.testing.assert_array_equal(box_filter(subs, k, np.float64), cells.sum(axis=(1, 3), dtype=np.float64))
    other = [subs[(sx, sy)][::-1, :, :3] for sy in range(k) for sx in range(k)]  # another order: not the same
    assert not np.array_equal(sum(other[1:], other[0]) / np.float32(k * k), mean)

"""The path integrator (docs/SHADING.md, "Path integrator"): white furnaces for every one-pass
method, energy never created, batches equal one batch, deterministic frames, no NaN or infinity
on the stability catalogue's hard cases, emission and environment seen by both integrators, and
the refusals (ray engines, Whitted's bounds)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import binary_dilation, binary_erosion

from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Scene, SceneError
from renderer.image.tonemap import display_u8
from renderer.oracle.reference import render_reference
from tests.renderer.gl.support import path
from tests.stability.cases import CASES

ONE_PASS = [n for n, m in METHODS.items() if "path" in m.capabilities.integrators]
RAY_ENGINES = [n for n, m in METHODS.items() if m.capabilities.multi_pass]

DIFFUSE = {"color": [0.5, 0.6, 0.7], "diffuse": 1.0, "reflective": 0.0, "ambient": 0.0}
MIRROR = {"color": [1, 1, 1], "diffuse": 0.0, "reflective": 1.0}
GLASS = {"color": [1, 1, 1], "diffuse": 0.0, "reflective": 0.0, "transmissive": 1.0, "ior": 1.5}


def furnace(material: dict, environment=(1.0, 1.0, 1.0), **extra) -> Scene:
    """One unit sphere of ``material`` inside a constant environment, filling most of the view."""
    return Scene.from_json(
        {
            "camera": {"position": [0, 0, 4], "target": [0, 0, 0], "fov_y": 34},
            "lights": [],
            "materials": [material],
            "spheres": [{"center": [0, 0, 0], "radius": 1.0}],
            "environment": {"color": list(environment)},
            **extra,
        }
    )


def inside(result) -> np.ndarray:
    """The pixels whose every sample meets the sphere (away from its silhouette)."""
    return binary_erosion(result.primid >= 0, iterations=2)


@pytest.mark.parametrize("method", ONE_PASS)
def test_white_furnace(gl_renderer, method):
    """A diffuse sphere of albedo ρ inside radiance 1 converges to ρ; a mirror and clear glass to 1
    (within 1 % at 32 samples; the diffuse and mirror estimates have no variance at all here)."""
    for material, want in ((DIFFUSE, DIFFUSE["color"]), (MIRROR, [1, 1, 1]), (GLASS, [1, 1, 1])):
        r = gl_renderer.render(furnace(material), path(method=method))
        px = inside(r)
        assert px.sum() > 200
        got = r.image[px].mean(axis=0)
        np.testing.assert_allclose(got, want, rtol=0.01, err_msg=f"{method}: {material}")
        assert np.isfinite(r.image).all()
        outside = ~binary_dilation(r.primid >= 0, iterations=2)
        assert np.allclose(r.image[outside], 1.0), "a missed ray sees the environment"


def test_lobe_weights_over_one_are_normalised(gl_renderer):
    """Weights summing above 1 are scaled to sum 1 (energy never created): diffuse 1 + mirror 1 of
    albedo 0.5 gives 0.5·0.5 + 0.5·1 = 0.75 in the furnace, not 1.5."""
    r = gl_renderer.render(furnace({**DIFFUSE, "color": [0.5, 0.5, 0.5], "reflective": 1.0}), path(spp=256))
    np.testing.assert_allclose(r.image[inside(r)].mean(), 0.75, rtol=0.01)
    r = gl_renderer.render(
        furnace({**GLASS, "diffuse": 1.0, "reflective": 1.0, "color": [0.2, 0.2, 0.2]}), path(spp=64)
    )
    assert r.image[inside(r)].mean() <= 1.0 + 0.01


def test_rough_mirror_loses_no_more_than_it_should(gl_renderer):
    """GGX (single scattering, F = 1, separable Smith masking) in the furnace: below 1, close to it
    for small α; at α = 0.8 about half is lost (its directional albedo is 0.43 at normal incidence,
    0.51 at cos 0.5, by an independent integration over the hemisphere)."""
    r = gl_renderer.render(furnace({**MIRROR, "roughness": 0.1}), path(spp=64))
    v = r.image[inside(r)].mean()
    assert 0.97 < v <= 1.001
    r = gl_renderer.render(furnace({**MIRROR, "roughness": 0.8}), path(spp=64))
    v = r.image[inside(r)].mean()
    assert 0.4 < v < 0.6


def test_batches_equal_one_batch_and_frames_repeat(gl_renderer):
    """Sample i of a pixel is the same path in whichever pass traces it: 20 samples as 20, as
    7 + 7 + 6 and as 1 × 20 give one image up to float rounding; the same frame twice is equal."""
    scene = furnace(
        {**DIFFUSE, "reflective": 0.3, "transmissive": 0.2, "roughness": 0.3},
        (0.8, 0.9, 1.0),
        planes=[{"point": [0, -1, 0], "normal": [0, 1, 0], "material": 0}],
        lights=[{"position": [2, 3, 3], "color": [1, 1, 1]}],
    )
    s = path(spp=20)
    images = [gl_renderer.begin(scene, s, samples_per_pass=k).run().image for k in (20, 7, 1)]
    for img in images[1:]:
        np.testing.assert_allclose(img, images[0], rtol=1e-5, atol=1e-6)
    assert np.array_equal(
        gl_renderer.render(scene, s).image, gl_renderer.begin(scene, s, samples_per_pass=16).run().image
    )
    assert np.array_equal(gl_renderer.render(scene, s).image, gl_renderer.render(scene, s).image)
    assert gl_renderer.render(scene, s).image.std() > 0


@pytest.mark.parametrize(
    "name",
    [
        "camera_inside_sphere",
        "tir_inside_glass",
        "nested_spheres",
        "offset_1e6",
        "radius_1e-3_at_1e6",
        "light_on_surface",
        "fov_179",
        "glass_mirror_room_depth8",
        "camera_on_plane",
    ],
)
def test_no_nan_or_infinity_reaches_a_pixel(gl_renderer, name):
    case = next(c for c in CASES if c.name == name)
    scene = case.build()
    data = scene.to_json()
    data["environment"] = {"color": [0.5, 0.5, 0.5]}
    lit = Scene.from_json(data) if not scene.meshes else scene
    for sc in (scene, lit):
        r = gl_renderer.render(
            sc, path(width=32, height=32, spp=8, max_prims=case.max_prims, max_tree_depth=case.max_tree_depth)
        )
        assert np.isfinite(r.image).all() and (r.image >= 0).all(), name


def test_point_lights_keep_the_thesis_exposure(gl_renderer):
    """A Lambertian floor under a point light at the camera's target distance has the radiance
    Whitted's diffuse term gives it (the light's radiant intensity is π·d²·color)."""
    d = 10.0
    scene = Scene.from_json(
        {
            "camera": {"position": [0, d, 0.001], "target": [0, 0, 0], "fov_y": 10},
            "lights": [{"position": [0, d, 0], "color": [1, 1, 1]}],
            "materials": [{"color": [0.5, 0.5, 0.5], "diffuse": 0.8, "reflective": 0, "ambient": 0, "specular": 0}],
            "planes": [{"point": [0, 0, 0], "normal": [0, 1, 0]}],
        }
    )
    whitted = gl_renderer.render(scene, RenderSettings(width=16, height=16, format="npy", max_recursion_depth=1))
    traced = gl_renderer.render(scene, path(width=16, height=16, spp=4, depth=2))
    centre = (slice(6, 10), slice(6, 10))
    np.testing.assert_allclose(traced.image[centre], whitted.image[centre], rtol=0.01)


def test_emission_and_environment_in_both_integrators(gl_renderer):
    """An emitting sphere is seen directly (its front side) and the environment on a miss, by the
    Whitted tracer as by the reference, and by the path integrator."""
    glow = {
        "color": [0.2, 0.2, 0.2],
        "ambient": 0.0,
        "diffuse": 0.0,
        "specular": 0.0,
        "reflective": 0.0,
        "emission": [2.0, 0.5, 0.25],
    }
    scene = furnace(glow, (0.1, 0.2, 0.3))
    s = RenderSettings(width=24, height=24, format="npy")
    gpu, ref = gl_renderer.render(scene, s), render_reference(scene, s)
    np.testing.assert_allclose(np.clip(gpu.image, 0, 1), ref.image, atol=1e-5)  # (the reference's is clamped)
    hit = gpu.primid >= 0
    assert np.allclose(gpu.image[hit], [2.0, 0.5, 0.25], atol=1e-6)
    assert np.allclose(gpu.image[~hit], [0.1, 0.2, 0.3], atol=1e-6)
    r = gl_renderer.render(scene, path(width=24, height=24, spp=4))
    assert np.allclose(r.image[inside(r)], [2.0, 0.5, 0.25], rtol=1e-5)


def test_a_mesh_emits_on_the_side_its_winding_faces(gl_renderer):
    """A triangle's emission is seen from its front (counter-clockwise) side only."""
    quad = {
        "vertices": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
        "triangles": [[0, 1, 2], [0, 2, 3]],
        "material": 0,
    }
    mat = {"color": [0, 0, 0], "diffuse": 0.0, "reflective": 0.0, "ambient": 0.0, "emission": [1.0, 1.0, 1.0]}
    for z, lit in ((4, True), (-4, False)):
        scene = Scene.from_json(
            {
                "camera": {"position": [0, 0, z], "target": [0, 0, 0], "fov_y": 20},
                "lights": [],
                "materials": [mat],
                "meshes": [quad],
            }
        )
        r = gl_renderer.render(scene, path(width=16, height=16, spp=2))
        assert (r.primid >= 0).all()
        assert np.allclose(r.image, 1.0 if lit else 0.0), z


def test_png_is_tone_mapped_and_npy_is_radiance(gl_renderer):
    scene = furnace(DIFFUSE, (3.0, 3.0, 3.0))
    r = gl_renderer.render(scene, path(spp=4, tone_map="reinhard", exposure=1.0))
    assert r.array().dtype == np.float32 and r.array().shape == (32, 32, 3)
    np.testing.assert_allclose(r.array()[~binary_dilation(r.primid >= 0, iterations=2)], 3.0)
    u8 = r.image_u8()
    assert u8.dtype == np.uint8 and (u8 == display_u8(r.image, "reinhard", 1.0)).all()
    assert tuple(display_u8(np.array([[[0.0, 0.5, 6.0]]]), "reinhard", 1.0)[0, 0]) == (0, 188, 246)
    png = gl_renderer.render(scene, path(spp=4, tone_map="reinhard", exposure=1.0).with_(format="png"))
    assert (png.image_u8() == u8).all()


def test_refusals():
    for method in RAY_ENGINES:
        with pytest.raises(SceneError) as e:
            RenderSettings(method=method, integrator="path")
        assert e.value.field == "integrator"
        assert all(m in e.value.message for m in ("bih", "bruteforce", "bvh", "kdtree", "twolevel", "auto"))
    RenderSettings(method="auto", integrator="path", samples_per_pixel=4096, max_recursion_depth=16)
    for kw in ({"samples_per_pixel": 5}, {"max_recursion_depth": 9}):
        with pytest.raises(SceneError) as e:
            RenderSettings(**kw)  # Whitted's own bounds
        assert e.value.field == next(iter(kw))
    for kw in ({"samples_per_pixel": 4097}, {"max_recursion_depth": 17}):
        with pytest.raises(SceneError):
            RenderSettings(integrator="path", **kw)
    with pytest.raises(SceneError) as e:
        Scene.from_json({"materials": [{"emission": [1, -1, 0]}]})
    assert e.value.field == "materials[0].emission[1]"
    with pytest.raises(SceneError) as e:
        Scene.from_json({"materials": [{"roughness": 2}]})
    assert e.value.field == "materials[0].roughness"
    with pytest.raises(SceneError) as e:
        Scene.from_json({"materials": [{}], "environment": {"colour": [1, 1, 1]}})
    assert e.value.field == "environment.colour"
    assert Scene.from_json({"materials": [{}], "lights": []}).lights == ()


def test_sampling_emitting_spheres_changes_the_noise_not_the_mean(gl_renderer, monkeypatch):
    """Next-event estimation to an emitting sphere, weighted by MIS against BSDF sampling, has the
    mean of BSDF sampling alone (which the frame falls back to with no sphere sampled), and less noise."""
    from renderer.gpu import gpu_layout

    scene = Scene.from_json(
        {
            "camera": {"position": [0, 3, 6], "target": [0, 0, 0], "fov_y": 40},
            "lights": [],
            "materials": [
                {"color": [0.8, 0.8, 0.8], "diffuse": 1.0, "reflective": 0, "ambient": 0},
                {"color": [0, 0, 0], "diffuse": 0, "reflective": 0, "emission": [10, 10, 10]},
            ],
            "planes": [{"point": [0, 0, 0], "normal": [0, 1, 0], "material": 0}],
            "spheres": [
                {"center": [0, 1.5, 0], "radius": 0.3, "material": 1},
                {"center": [1, 0.5, 0], "radius": 0.5, "material": 0},
            ],
        }
    )
    s = path(width=24, height=24, spp=2048, depth=8)
    sampled = gl_renderer.render(scene, s).image
    original = gpu_layout.emitter_uniforms
    monkeypatch.setattr(
        gpu_layout,
        "emitter_uniforms",
        lambda sc: {**original(sc), gpu_layout.NUM_EMITTERS.name: 0, gpu_layout.EMITTER_LAST.name: -1},
    )
    alone = gl_renderer.render(scene, s).image
    floor = np.s_[15:]
    np.testing.assert_allclose(sampled[floor].mean(), alone[floor].mean(), rtol=0.02)
    np.testing.assert_allclose(sampled.mean(), alone.mean(), rtol=0.01)
    assert sampled[floor].std() < alone[floor].std()


def test_the_cornell_box(gl_renderer):
    """The demo scene: lit by its ceiling panel alone, both integrators draw it, the path
    integrator's frame is finite and brighter where the panel shines (floor) than at the back's top."""
    from renderer.scenes.scenarios import mesh_scene

    scene = mesh_scene("cornell", 0)
    assert scene.lights == () and any(m.emits for m in scene.materials)
    r = gl_renderer.render(scene, path(width=32, height=32, spp=16, depth=8))
    assert np.isfinite(r.image).all() and r.image.mean() > 0.05
    assert r.image[26:30, 8:24].mean() > r.image[4:8, 2:6].mean()
    w = gl_renderer.render(scene, RenderSettings(width=32, height=32, format="npy"))
    assert (w.primid >= 0).all(), "the walls close the view"


def test_a_progressive_frame_previews_its_first_pass(gl_renderer):
    """A frame of several passes offers the mean of its first pass as its preview (the service
    shows it while the rest is traced): the image of a frame of that many samples."""
    scene = furnace(
        {**DIFFUSE, "reflective": 0.4, "roughness": 0.2},
        (0.5, 0.7, 1.0),
        lights=[{"position": [2, 3, 3], "color": [1, 1, 1]}],
    )
    frame = gl_renderer.begin(scene, path(spp=20), samples_per_pass=8)
    while frame.preview is None:
        assert not frame.step()
    first = gl_renderer.render(scene, path(spp=8)).image
    np.testing.assert_allclose(frame.preview.image, first, rtol=1e-5, atol=1e-6)
    assert frame.preview.stats["preview"] and frame.run().stats["tracer_passes"] == 3


def test_sampling_emitting_triangles_changes_the_noise_not_the_mean(gl_renderer, monkeypatch):
    """Next-event estimation to emitting triangles (the Cornell box's ceiling quad), MIS-weighted
    against BSDF sampling: the mean of BSDF sampling alone (against Mitsuba: 39 dB where BSDF sampling
    alone reaches 30 at 1,024 samples)."""
    from renderer.gpu import gpu_layout
    from renderer.scenes.scenarios import mesh_scene

    scene = mesh_scene("cornell", 0, smooth=False)
    s = path(width=24, height=24, spp=512, depth=6)
    sampled = gl_renderer.render(scene, s).image
    original = gpu_layout.emitter_uniforms
    monkeypatch.setattr(gpu_layout, "emitter_uniforms", lambda sc: {**original(sc), gpu_layout.NUM_EMIT_TRIS.name: 0})
    alone = gl_renderer.render(scene, s).image
    np.testing.assert_allclose(sampled.mean(), alone.mean(), rtol=0.02)
    floor = np.s_[18:, 4:20]
    np.testing.assert_allclose(sampled[floor].mean(), alone[floor].mean(), rtol=0.04)
    assert np.abs(sampled - alone).mean() < 0.1  # (the noise: tests/renderer/gl/test_mitsuba.py, Cornell box)


# One emitting shape of each kind over a diffuse floor (the emitter's radiance 4, the floor's albedo
# 0.7; an occluder between them for the shadow rays): next-event estimation samples its surfaces.
EMITTING_SHAPES = {
    "cylinders": {"base": [-0.5, 1.2, -4], "axis": [1, 0.2, 0], "radius": 0.3, "height": 1.0, "caps": True},
    "cones": {"base": [0, 1.0, -4], "axis": [0, 1, 0], "base_radius": 0.4, "top_radius": 0.1, "height": 0.5},
    "disks": {"center": [0, 1.4, -4], "normal": [0, -1, 0], "radius": 0.5, "inner_radius": 0.2},
    "tori": {"center": [0, 1.2, -4], "axis": [0.3, 1, 0], "major_radius": 0.4, "minor_radius": 0.1},
}


@pytest.mark.parametrize("kind", list(EMITTING_SHAPES))
def test_sampling_emitting_shapes_changes_the_noise_not_the_mean(gl_renderer, monkeypatch, kind):
    """Next-event estimation to an emitting analytic shape (a point uniform on its side, caps, disk or
    torus), MIS-weighted against BSDF sampling: the floor's mean as BSDF sampling alone finds it, with
    less noise (the pixels' spread about a 4,096-sample image of BSDF sampling alone)."""
    from renderer.gpu import gpu_layout

    scene = Scene.from_json(
        {
            "camera": {"position": [0, 2.5, 0], "target": [0, 0, -4], "fov_y": 50},
            "lights": [],
            "materials": [
                {"color": [0.7] * 3, "diffuse": 1.0, "reflective": 0, "ambient": 0},
                {"color": [0, 0, 0], "diffuse": 0.0, "reflective": 0, "ambient": 0, "emission": [4, 4, 4]},
            ],
            "planes": [{"point": [0, 0, 0], "normal": [0, 1, 0], "material": 0}],
            "spheres": [{"center": [0.6, 0.3, -4.2], "radius": 0.3, "material": 0}],
            kind: [{**EMITTING_SHAPES[kind], "material": 1}],
        }
    )
    assert gpu_layout.emitter_uniforms(scene)[gpu_layout.NUM_EMIT_PATCHES.name] > 0
    s = path(width=32, height=32, spp=256, depth=3)
    sampled = gl_renderer.render(scene, s)
    original = gpu_layout.emitter_uniforms
    monkeypatch.setattr(
        gpu_layout, "emitter_uniforms", lambda sc: {**original(sc), gpu_layout.NUM_EMIT_PATCHES.name: 0}
    )
    alone = gl_renderer.render(scene, s).image
    truth = gl_renderer.render(scene, s.with_(samples_per_pixel=4096)).image
    floor = (sampled.primid == 1)[..., None].repeat(3, axis=2)  # the plane: ids after the one sphere
    assert floor.mean() > 0.3
    np.testing.assert_allclose(sampled.image[floor].mean(), truth[floor].mean(), rtol=0.03)
    np.testing.assert_allclose(alone[floor].mean(), truth[floor].mean(), rtol=0.03)
    err_nee = np.abs(sampled.image - truth)[floor].mean()
    err_alone = np.abs(alone - truth)[floor].mean()
    assert err_nee < 0.7 * err_alone, (err_nee, err_alone)


@pytest.mark.parametrize("ior", [1.5, 3.0])
def test_a_rough_dielectric_creates_no_energy(gl_renderer, ior):
    """Rough glass (GGX, single scattering) in the white furnace: never above 1 beyond the noise, at
    α → 0 the smooth glass's 1, below it the rougher the more (the masked light is lost: measured
    0.98, 0.77, 0.33 at α = 0.05, 0.3, 1 and ior 1.5, as Mitsuba's roughdielectric within 0.2 %,
    tests/renderer/gl/test_mitsuba.py)."""
    means = []
    for alpha in (1e-4, 0.05, 0.3, 1.0):
        r = gl_renderer.render(furnace({**GLASS, "ior": ior, "roughness": alpha}), path(spp=128))
        assert np.isfinite(r.image).all() and (r.image >= 0).all()
        v = float(r.image[inside(r)].mean())
        assert v <= 1.005 and float(r.image.mean()) <= 1.005, (alpha, v)
        means.append(v)
    assert means[0] > 0.995, means  # α = 1e-4 is all but smooth glass
    assert means[0] > means[1] > means[2] > means[3] > 0.05, means


@pytest.mark.parametrize("alpha", [1e-4, 1.0])
def test_a_rough_dielectric_at_grazing_angles(gl_renderer, alpha):
    """A camera 1e-3 above a rough glass plane looks along it (its lower half meets the plane, the
    rows next to the horizon at grazing angles), a rough glass sphere's silhouette too, in the white
    furnace: no NaN or infinity, nothing above 1 beyond the noise. At α = 1e-4 and depth 3 (one bounce,
    no Russian roulette: each sample is G1 ≤ 1 of the one direction the plane sends it, reflected or
    refracted, into the environment) every pixel whose rays meet the plane at cos θ > 0.01 is 1 within
    0.1 %: a sample lost to a float accident (counted as 0) would take 1/64 from its pixel."""
    glass = {**GLASS, "roughness": alpha}
    h = 1e-3
    data = {
        "camera": {"position": [0, h, 0], "target": [0, h, -10], "fov_y": 30},
        "lights": [],
        "materials": [glass],
        "planes": [{"point": [0, 0, 0], "normal": [0, 1, 0]}],
        "environment": {"color": [1, 1, 1]},
    }
    with_sphere = Scene.from_json({**data, "spheres": [{"center": [0.5, 0.3, -6], "radius": 0.6}]})
    r = gl_renderer.render(with_sphere, path(spp=64))
    assert np.isfinite(r.image).all() and (r.image >= 0).all()
    assert (r.primid >= 0).mean() > 0.4
    assert r.image.mean() <= 1.005
    r = gl_renderer.render(Scene.from_json(data), path(spp=64, depth=3))
    assert np.isfinite(r.image).all() and (r.image >= 0).all() and r.image.max() <= 1.0 + 1e-6
    if alpha < 0.01:
        steep = (r.primid == 0) & (h / np.where(r.primid == 0, r.depth, np.inf) > 0.01)
        steep[1:] &= steep[:-1].copy()  # the pixel above too: none of the pixel's samples is more grazing
        assert steep.sum() > 300
        np.testing.assert_allclose(r.image[steep], 1.0, atol=1e-3)


def test_a_diffuse_plane_under_an_emitting_plane_has_the_closed_form(gl_renderer):
    """Emitting planes are met by BSDF sampling alone (docs/SHADING.md): under an infinite emitter of
    radiance Le, every cosine-distributed direction from a parallel floor meets it, so the floor of
    albedo ρ has radiance ρ·Le (E = π·Le); with the emitter's underside diffuse of albedo c as well,
    the light between them sums to ρ·Le / (1 − ρc): the mean within 1 % (Russian roulette's noise, at 1,024
    samples: a pixel's standard deviation 0.04, so the mean's 0.15 %; measured +0.12 %)."""
    le, rho, c = 2.0, 0.6, 0.5
    cases = ((0.0, 2, 1, rho * le), (0.0, 8, 4, rho * le), (c, 16, 1024, rho * le / (1 - rho * c)))
    for ceiling_albedo, depth, spp, want in cases:
        scene = Scene.from_json(
            {
                "camera": {"position": [0, 0.5, 0], "target": [0.3, 0, 0.2], "fov_y": 40},
                "lights": [],
                "materials": [
                    {"color": [rho] * 3, "diffuse": 1.0, "reflective": 0, "ambient": 0},
                    {
                        "color": [ceiling_albedo] * 3,
                        "diffuse": 1.0 if ceiling_albedo else 0.0,
                        "reflective": 0,
                        "emission": [le] * 3,
                    },
                ],
                "planes": [
                    {"point": [0, 0, 0], "normal": [0, 1, 0], "material": 0},
                    {"point": [0, 1, 0], "normal": [0, -1, 0], "material": 1},
                ],
            }
        )
        r = gl_renderer.render(scene, path(width=16, height=16, spp=spp, depth=depth))
        assert (r.primid == 0).all()  # (ids: planes after the spheres; the floor is plane 0)
        np.testing.assert_allclose(r.image.mean(), want, rtol=0.01, err_msg=f"c={ceiling_albedo} depth={depth}")
        if not ceiling_albedo:  # one bounce that always meets the emitter: no variance at all
            np.testing.assert_allclose(r.image, want, rtol=1e-5)


def test_frames_that_go_on_from_held_samples_equal_one_frame(gl_renderer):
    """An accumulation: frames of 16, 16 and 8 samples, each going on from the sum and count the
    last one left, give the image of one 40-sample frame (up to float rounding) and say so."""
    from renderer.scenes.scenarios import mesh_scene

    scene = mesh_scene("cornell", 0)
    held = (None, 0)  # an accumulation that holds nothing yet
    for spp in (16, 16, 8):
        r = gl_renderer.begin(scene, path(width=24, height=24, spp=spp, depth=6), accumulated=held).run()
        assert r.sample_sum is not None and r.sample_sum.dtype == np.float32
        held = (r.sample_sum, r.samples)
    one = gl_renderer.render(scene, path(width=24, height=24, spp=40, depth=6))
    assert r.samples == one.samples == 40 and r.stats["samples"] == 40
    np.testing.assert_allclose(r.image, one.image, rtol=1e-5, atol=1e-6)
    assert one.sample_sum is None, "a frame that holds nothing hands no sum back"
    first = gl_renderer.begin(scene, path(width=24, height=24, spp=16, depth=6)).run().image
    assert np.abs(r.image - first).max() > 1e-3, "the later frames added samples of their own"

"""The glTF metallic-roughness material (renderer/materials/pbr.py; docs/SHADING.md, "PBR") rendered:
the white furnace over metallic × roughness against the same BRDF integrated in NumPy
(renderer/materials/pbr_brdf.py), Whitted's PBR rule against the float64 reference tracer for every one-pass
method, alpha mask and blend, double-sidedness, volume attenuation, and Mitsuba 3 where its models
are ours (a white rough conductor, a rough dielectric of transmission 1, an ior-1 dielectric as
Lambert)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import binary_erosion

from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Scene
from renderer.materials import pbr_brdf
from renderer.oracle import mitsuba_scene
from renderer.oracle.path_scenes import PBR_MATERIALS, path_scene, pbr_scene
from renderer.oracle.reference import render_reference
from tests.helpers import psnr
from tests.renderer.gl.support import path

pytestmark = pytest.mark.gl

ONE_PASS = [n for n, m in METHODS.items() if m.capabilities.shader]
METALLIC = (0.0, 0.5, 1.0)
ROUGHNESS = (0.0, 0.25, 0.5, 0.75, 1.0)
CAMERA = {"position": [0, 0, 4], "target": [0, 0, 0], "fov_y": 34}


def pbr(**kw) -> dict:
    return {"kind": "pbr", **kw}


def furnace(material: dict, environment=(1.0, 1.0, 1.0)) -> Scene:
    """One unit sphere of ``material`` inside a constant environment, filling most of the view."""
    return Scene.from_json(
        {
            "camera": CAMERA,
            "lights": [],
            "materials": [material],
            "spheres": [{"center": [0, 0, 0], "radius": 1.0}],
            "environment": {"color": list(environment)},
        }
    )


def expected_image(result, metallic: float, roughness: float) -> np.ndarray:
    """The furnace's radiance per pixel: a convex sphere under radiance 1 reflects its directional
    albedo at each pixel's view (no second bounce meets the sphere)."""
    h, w = result.primid.shape
    ys, xs = np.mgrid[:h, :w]
    t = math.tan(math.radians(CAMERA["fov_y"]) / 2)
    u = (2 * (xs + 0.5) / w - 1) * t * w / h
    v = (1 - 2 * (ys + 0.5) / h) * t
    d = np.stack([u, v, -np.ones_like(u)], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return pbr_brdf.furnace_radiance(-np.sum(d * result.normal, axis=-1), metallic, roughness)


def test_white_furnace_matches_the_brdf_integrated_in_numpy(gl_renderer):
    """A white PBR sphere under radiance 1: never brighter than 1 (+ noise), and its mean over the
    sphere equals NumPy's integral of the same BRDF over the pixels' views within 1.5 % — the single-
    scattering GGX's loss at high roughness included (docs/SHADING.md's table)."""
    for metallic in METALLIC:
        for roughness in ROUGHNESS:
            scene = furnace(pbr(base_color=[1, 1, 1], metallic=metallic, roughness=roughness))
            r = gl_renderer.render(scene, path(width=32, height=32, spp=128))
            inside = binary_erosion(r.primid >= 0, iterations=2)
            got = float(r.image[inside].mean())
            want = float(expected_image(r, metallic, roughness)[inside].mean())
            assert np.isfinite(r.image).all()
            assert got <= 1.01, (metallic, roughness, got)
            assert abs(got - want) <= 0.015 * want + 0.003, (metallic, roughness, got, want)


def test_the_furnace_loses_energy_at_high_roughness(gl_renderer):
    """The single-scattering GGX's loss: a white metal of roughness 1 keeps well under 60 % of the
    light (NumPy: 1 − ln 2 at normal incidence), one of roughness 0 all of it."""
    smooth = gl_renderer.render(furnace(pbr(metallic=1.0, roughness=0.0)), path(width=16, height=16, spp=16))
    rough = gl_renderer.render(furnace(pbr(metallic=1.0, roughness=1.0)), path(width=16, height=16, spp=64))
    np.testing.assert_allclose(smooth.image[smooth.primid >= 0].mean(), 1.0, atol=0.003)
    assert rough.image[rough.primid >= 0].mean() < 0.6
    assert abs(pbr_brdf.directional_albedo((1, 1, 1), 1.0, 1.0, 1.0)[0] - (1 - math.log(2))) < 0.01


WHITTED_MATERIALS = [
    {"color": [0.7, 0.7, 0.7], "diffuse": 0.8, "reflective": 0.0, "ambient": 0.2},
    pbr(base_color=[0.9, 0.5, 0.2], metallic=1.0, roughness=0.2),
    pbr(base_color=[0.2, 0.5, 0.9], metallic=0.0, roughness=0.5),
    pbr(
        base_color=[0.95, 0.95, 0.9],
        metallic=0.0,
        roughness=0.0,
        transmission=1.0,
        ior=1.5,
        attenuation_color=[0.8, 0.9, 0.6],
        attenuation_distance=1.5,
    ),
    pbr(base_color=[0.6, 0.8, 0.4], metallic=0.3, roughness=0.7, double_sided=True),
]


def whitted_scene() -> Scene:
    """Spheres of each kind on a Phong floor, a PBR mesh (a tetrahedron), two lights."""
    return Scene.from_json(
        {
            "camera": {"position": [0, 2.5, 7], "target": [0, 0.8, 0], "fov_y": 40},
            "lights": [
                {"position": [3, 5, 4], "color": [0.8, 0.8, 0.8]},
                {"position": [-4, 3, 2], "color": [0.3, 0.3, 0.4]},
            ],
            "materials": WHITTED_MATERIALS,
            "planes": [{"point": [0, 0, 0], "normal": [0, 1, 0], "material": 0}],
            "spheres": [
                {"center": [-1.6, 0.8, 0], "radius": 0.8, "material": 1},
                {"center": [0.2, 0.7, 0.6], "radius": 0.7, "material": 2},
                {"center": [1.7, 0.9, -0.3], "radius": 0.9, "material": 3},
            ],
            "meshes": [
                {
                    "vertices": [[-0.9, 0.01, 1.9], [0.3, 0.01, 2.2], [-0.3, 1.2, 1.6], [-0.4, 0.01, 1.0]],
                    "triangles": [[0, 1, 2], [0, 2, 3], [1, 3, 2], [0, 3, 1]],
                    "material": 4,
                }
            ],
            "environment": {"color": [0.15, 0.2, 0.3]},
        }
    )


@pytest.mark.parametrize("method", ONE_PASS)
def test_whitted_pbr_matches_the_reference(gl_renderer, method):
    """Whitted's PBR rule (ambient × occlusion × base colour, each light's BRDF · cos, the reflected
    ray by the specular Fresnel × (1 − roughness)², the refracted ray, Beer–Lambert inside) on the GPU
    equals the float64 reference: ≥ 40 dB, as the Phong scenes' comparisons."""
    scene = whitted_scene()
    s = RenderSettings(width=64, height=48, max_recursion_depth=5, method=method, format="npy")
    gpu, ref = gl_renderer.render(scene, s), render_reference(scene, s)
    assert (gpu.primid == ref.primid).mean() > 0.995
    p = psnr(gpu.image_u8(), ref.image_u8())
    assert p >= 40.0, f"{method}: colour PSNR {p:.1f} dB < 40"
    # … and the PBR materials do show: the metal sphere's pixels are not its ambient term alone
    metal = ref.primid == 0
    assert np.ptp(ref.image[metal][:, 0]) > 0.2


def cover(front: dict, behind: dict | None = None, environment=(1.0, 1.0, 1.0)) -> Scene:
    """A sphere of ``front`` before the camera, and (``behind``) a larger one behind it."""
    spheres = [{"center": [0, 0, 0], "radius": 1.0, "material": 0}]
    if behind is not None:
        spheres.append({"center": [0, 0, -6], "radius": 4.0, "material": 1})
    return Scene.from_json(
        {
            "camera": CAMERA,
            "lights": [],
            "materials": [front] + ([behind] if behind else []),
            "spheres": spheres,
            "environment": {"color": list(environment)},
        }
    )


BLACK = {"base_color": [0, 0, 0], "metallic": 0.0, "roughness": 1.0, "ior": 1.0}


def test_alpha_blend_is_stochastic_coverage_and_back_faces_follow_double_sided(gl_renderer):
    """A black sphere of alpha 0.25 (blend) under radiance 1: a path passes its front with probability
    0.75; a single-sided back face is culled (the exit passes), a double-sided one is met again.
    So 0.75 and 0.75² — opaque it would be 0, and culling nothing gives 0.5625 for both."""
    s = path(width=16, height=16, spp=256)
    for double_sided, want in ((False, 0.75), (True, 0.5625)):
        r = gl_renderer.render(furnace(pbr(**BLACK, alpha=0.25, alpha_mode="blend", double_sided=double_sided)), s)
        inside = binary_erosion(r.primid >= 0, iterations=1)
        np.testing.assert_allclose(r.image[inside].mean(), want, atol=0.02, err_msg=f"double_sided={double_sided}")


def test_alpha_mask_cuts_at_the_cutoff_in_both_integrators(gl_renderer):
    """A mask of alpha 0.4: with cutoff 0.5 the sphere is not there (the frame equals the frame without
    it), with cutoff 0.3 it is (its black covers the view)."""
    behind = {"color": [0.2, 0.6, 0.3], "diffuse": 1.0, "reflective": 0.0, "ambient": 0.5}
    empty = Scene.from_json(
        {**cover(pbr(**BLACK), behind).to_json(), "spheres": [{"center": [0, 0, -6], "radius": 4.0, "material": 1}]}
    )
    for settings in (RenderSettings(width=16, height=16, format="npy"), path(width=16, height=16, spp=16)):
        cut = gl_renderer.render(cover(pbr(**BLACK, alpha=0.4, alpha_mode="mask", alpha_cutoff=0.5), behind), settings)
        kept = gl_renderer.render(cover(pbr(**BLACK, alpha=0.4, alpha_mode="mask", alpha_cutoff=0.3), behind), settings)
        none = gl_renderer.render(empty, settings)
        centre = (slice(6, 10), slice(6, 10))
        np.testing.assert_allclose(cut.image[centre], none.image[centre], atol=1e-4)
        assert kept.image[centre].max() < 0.05 < none.image[centre].min()


def test_a_single_sided_plane_is_invisible_from_behind_in_whitted(gl_renderer):
    """A PBR plane facing away from the camera: culled when single-sided (the environment shows),
    shaded when double-sided; a Phong plane is shaded from both sides, as before."""

    def scene(double_sided: bool) -> Scene:
        return Scene.from_json(
            {
                "camera": {"position": [0, -2, 4], "target": [0, 0, 0], "fov_y": 40},
                "lights": [{"position": [0, -3, 3], "color": [1, 1, 1]}],
                "materials": [pbr(base_color=[0.8, 0.2, 0.2], metallic=0.0, roughness=0.6, double_sided=double_sided)],
                "planes": [{"point": [0, 0, 0], "normal": [0, 1, 0], "material": 0}],
                "environment": {"color": [0.1, 0.3, 0.9]},
            }
        )

    s = RenderSettings(width=16, height=16, format="npy")
    single, double = gl_renderer.render(scene(False), s), gl_renderer.render(scene(True), s)
    np.testing.assert_allclose(single.image[12:], np.broadcast_to([0.1, 0.3, 0.9], (4, 16, 3)), atol=1e-5)
    assert double.image[12:, :, 0].min() > 0.3
    ref = render_reference(scene(False), s)
    np.testing.assert_allclose(single.image, ref.image, atol=2e-3)


def test_volume_attenuation_follows_beer_lambert(gl_renderer):
    """Clear glass of ior 1 (nothing reflects, nothing bends) with attenuation colour c after distance
    d: a ray through the sphere's centre keeps c^(2/d) of the environment, in both integrators."""
    glass = pbr(
        base_color=[1, 1, 1],
        metallic=0.0,
        roughness=0.0,
        transmission=1.0,
        ior=1.0,
        attenuation_color=[0.5, 0.8, 1.0],
        attenuation_distance=1.0,
    )
    want = np.array([0.5, 0.8, 1.0]) ** 2.0
    for settings in (RenderSettings(width=15, height=15, format="npy"), path(width=15, height=15, spp=16)):
        r = gl_renderer.render(furnace(glass), settings)
        np.testing.assert_allclose(r.image[7, 7], want, rtol=0.02, err_msg=settings.integrator)


# ---- Mitsuba 3 as the oracle where the models coincide (tests/renderer/gl/test_mitsuba.py's budgets)


def clipped_psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((np.clip(a, 0, 1).astype(np.float64) - np.clip(b, 0, 1)) ** 2))
    return math.inf if mse == 0 else -10.0 * math.log10(mse)


@pytest.mark.parametrize("name", list(PBR_MATERIALS))
def test_agrees_with_mitsuba_where_the_models_coincide(gl_renderer, name):
    """32 × 32, depth 8, ours at 1,024 samples against Mitsuba's at 4,096 (test_mitsuba.py's budget):
    ≥ 38 dB and the means within 1 %. (The rough conductor: Mitsuba's Smith masking is the separable
    form, ours the specification's height-correlated one, a little brighter at grazing angles.)"""
    scene = pbr_scene(name)
    reference = mitsuba_scene.render(scene, 32, 32, 4096, 8)
    ours = gl_renderer.render(scene, path(width=32, height=32, spp=1024, depth=8)).image
    p = clipped_psnr(ours, reference)
    assert p >= 38.0, (name, p)
    np.testing.assert_allclose(ours.mean(), reference.mean(), rtol=0.01, err_msg=name)


def test_mitsuba_export_refuses_what_it_has_no_model_for():
    doc = pbr_scene("pbr_diffuse").to_json()
    doc["materials"][2] = pbr(metallic=0.5, roughness=0.5)
    scene = Scene.from_json(doc)
    with pytest.raises(mitsuba_scene.NoMitsubaMaterial, match="metallic 0.5"):
        mitsuba_scene.scene_dict(scene, 8, 8, 1, 4)


def test_a_pbr_emitter_lights_a_pbr_lambert_floor_as_the_phong_ones_do(gl_renderer):
    """The path scenes' area light (renderer/oracle/path_scenes.py) with its materials as PBR ones — the lamp
    emissive × strength = the Phong emission, the grey floor and sphere ior-1 dielectrics (F0 = 0:
    Lambert) — renders the Phong scene's image: the emitter is seen and sampled by next-event
    estimation alike (means within 1 %, 35 dB at 256 samples)."""
    phong = path_scene("area_light")
    doc = phong.to_json()
    doc["materials"] = [
        pbr(base_color=[0.7, 0.7, 0.7], metallic=0.0, roughness=1.0, ior=1.0),
        pbr(base_color=[0, 0, 0], metallic=0.0, ior=1.0, emissive=[1.0, 0.875, 0.75], emissive_strength=8.0),
    ]
    s = path(width=32, height=32, spp=256, depth=8)
    a, b = gl_renderer.render(phong, s).image, gl_renderer.render(Scene.from_json(doc), s).image
    np.testing.assert_allclose(b.mean(), a.mean(), rtol=0.01)
    assert clipped_psnr(a, b) >= 35.0

"""The PBR data format on the host side: a scene with a glTF metallic-roughness material packs every
material record with its kind (stride MATERIAL_STRIDE, the kind's id first), always in u_materials,
and its variants carry PBR (FEATURE_PBR 1) with the PBR accessors; a scene of Phong materials alone
packs and compiles as before. Features, the cost model's branching and the denoiser's albedo read
both kinds; the NumPy BRDF's furnace albedos are what the specification's formulas give."""

from __future__ import annotations

import math

import numpy as np
import pytest

from renderer.config.methods import check_primitives
from renderer.frame.features import scene_features
from renderer.frame.shader_source import tracer_source
from renderer.geometry.scene import Material, Scene, SceneError
from renderer.gpu import gpu_layout
from renderer.image.denoise import material_albedos
from renderer.materials import pack_records, pbr_brdf, record_texels
from renderer.materials.pbr import PbrMaterial

BASE = {
    "camera": {"position": [0, 0, 5], "target": [0, 0, 0]},
    "lights": [{"position": [1, 3, 2], "color": [1, 1, 1]}],
    "spheres": [{"center": [0, 0, 0], "radius": 1, "material": 0}, {"center": [2, 0, 0], "radius": 1, "material": 1}],
}
PHONG = {"color": [0.2, 0.4, 0.6], "reflective": 0.0}
GLASS = {"kind": "pbr", "base_color": [0.9, 0.8, 0.7], "metallic": 0.0, "roughness": 0.3, "transmission": 1.0}


def scene(*materials: dict) -> Scene:
    return Scene.from_json({**BASE, "materials": list(materials)})


def test_a_pbr_scene_packs_every_record_with_its_kind():
    s = scene(PHONG, GLASS)
    stride = gpu_layout.MATERIAL_STRIDE
    assert stride == 1 + max(record_texels(Material), record_texels(PbrMaterial)) == 20
    recs = gpu_layout.pack_materials(s.materials).reshape(2, stride, 4)
    assert recs[0, 0, 0] == gpu_layout.KIND_IDS["phong"] == 0 and recs[1, 0, 0] == gpu_layout.KIND_IDS["pbr"] == 1
    np.testing.assert_array_equal(recs[0, 1:4].reshape(-1, 4), pack_records([s.materials[0]], Material))
    np.testing.assert_array_equal(recs[1, 1:].reshape(-1, 4), pack_records([s.materials[1]], PbrMaterial))
    assert gpu_layout.material_texture(s)  # the PBR record is too large for the uniform array


def test_a_phong_scene_packs_and_compiles_as_before():
    s = scene(PHONG, {"color": [1, 1, 1], "reflective": 0.5})
    np.testing.assert_array_equal(gpu_layout.pack_materials(s.materials), pack_records(s.materials, Material))
    f = scene_features(s)
    assert not f.pbr and "PBR" not in f.defines() and not gpu_layout.material_texture(s)
    text = tracer_source("bvh", "color", 3, f.defines())
    assert "#define FEATURE_PBR 0" in text and "#define pbr_metallic(m)" not in text
    assert "#define MATERIAL_STRIDE" not in text


def test_features_read_both_kinds():
    f = scene_features(scene(PHONG, GLASS))
    assert f.pbr and {"PBR", "MATERIAL_TEXTURE"} <= set(f.defines())
    assert f.reflection and f.transmission and f.split  # roughness < 1 reflects; transmission refracts
    text = tracer_source("bvh", "color", 3, f.defines())
    assert "#define FEATURE_PBR 1" in text and "#define pbr_transmission(m)" in text
    rough_metal = {"kind": "pbr", "metallic": 1.0, "roughness": 1.0}
    g = scene_features(scene(PHONG, rough_metal))
    assert not g.reflection and not g.transmission  # roughness 1: Whitted traces no mirror ray


def test_the_denoisers_guide_is_the_base_colour():
    np.testing.assert_allclose(material_albedos(scene(PHONG, GLASS))[1], [0.9, 0.8, 0.7], rtol=1e-6)


def test_the_ray_engines_refuse_a_pbr_scene():
    with pytest.raises(SceneError, match="pbr"):
        check_primitives("rayengine", scene(PHONG, GLASS))
    check_primitives("bvh", scene(PHONG, GLASS))


def test_the_numpy_brdf_keeps_what_the_formulas_say():
    """A white metal of roughness 1 at normal incidence keeps 1 − ln 2 (D = 1/π, V = 1/(2(1 + n·i)));
    a white smooth metal keeps 1; a white dielectric of ior 1 is Lambert (albedo 1 at every view); no
    material gains energy at any view."""
    assert abs(pbr_brdf.directional_albedo((1, 1, 1), 1.0, 1.0, 1.0)[0] - (1 - math.log(2))) < 0.005
    assert abs(pbr_brdf.directional_albedo((1, 1, 1), 1.0, 0.0, 0.5)[0] - 1.0) < 0.01
    for c in (1.0, 0.3, 0.05):
        lam = pbr_brdf.directional_albedo((1, 1, 1), 0.0, 1.0, c, ior=1.0)
        np.testing.assert_allclose(lam, 1.0, atol=0.01)
    for metallic in (0.0, 0.5, 1.0):
        for roughness in (0.0, 0.5, 1.0):
            for c in (1.0, 0.4, 0.05):
                assert pbr_brdf.directional_albedo((1, 1, 1), metallic, roughness, c)[0] <= 1.01

"""Scene features (renderer.frame.features): what the specialised shader may leave out follows
the materials the scene's primitives use and whether it has lights. That the specialised
variant renders exactly like the generic one is tested in ``tests/renderer/gl/test_frame.py``."""

from __future__ import annotations

import numpy as np

from renderer.frame.features import scene_features
from renderer.geometry.scene import Material, Scene
from renderer.scenes.scenarios import TABLE_4_1, scenario


def test_scene_features_follow_used_materials():
    s = scenario(1, 3)  # spheres 0..2 are red (i % 4 != 3): no transmissive sphere
    f = scene_features(s)
    assert f.reflection and not f.transmission and f.lights
    assert scene_features(scenario(1, 4)).transmission
    no_light = Scene(s.camera, (), TABLE_4_1, s.sphere_centers, s.sphere_radii, s.sphere_materials, s.planes)
    assert "NO_LIGHTS" in scene_features(no_light).defines()


def test_counts_data_formats_and_the_task_stack():
    """The defines: compiled-in counts, NO_SPLIT where reflection and transmission
    never meet in one used material, the data formats in every variant (the generic one
    too), all in FEATURE_DEFINES order; the stats' removals are the NO_* ones."""
    from renderer.frame.features import FEATURE_DEFINES, GENERIC

    s = scenario(3, 64)  # red reflects, transparent transmits: never both
    f = scene_features(s)
    assert f.defines() == ("NO_SPLIT", "PLANES_1", "LIGHTS_1", "EQUAL_RADII")
    assert f.removed() == ["NO_SPLIT"]
    assert f.generic().defines() == ("EQUAL_RADII",) and GENERIC.defines() == ()
    assert list(f.defines()) == [d for d in FEATURE_DEFINES if d in f.defines()]
    both = Material(reflective=0.2, transmissive=0.5)
    radii = s.sphere_radii * np.linspace(0.5, 1.5, s.n_spheres)
    many = tuple(both if i == 0 else TABLE_4_1[i % 2] for i in range(17))
    g = scene_features(Scene(s.camera, (), many, s.sphere_centers, radii, s.sphere_materials % 17, ()))
    assert g.defines() == ("NO_LIGHTS", "PLANES_0", "MATERIAL_TEXTURE")  # no lights: no LIGHTS_k
    assert scene_features(
        Scene(s.camera, s.lights, (both,), s.sphere_centers, s.sphere_radii, s.sphere_materials * 0, s.planes)
    ).split

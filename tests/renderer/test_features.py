"""Scene features (renderer.features): what the specialised shader may leave out follows
the materials the scene's primitives use and whether it has lights. That the specialised
variant renders exactly like the generic one is tested in ``tests/renderer/gl/test_render_knobs.py``."""

from __future__ import annotations

from renderer.features import scene_features
from renderer.scenarios import TABLE_4_1, scenario
from renderer.scene import Scene


def test_scene_features_follow_used_materials():
    s = scenario(1, 3)  # spheres 0..2 are red (i % 4 != 3): no transmissive sphere
    f = scene_features(s)
    assert f.reflection and not f.transmission and f.lights
    assert scene_features(scenario(1, 4)).transmission
    no_light = Scene(s.camera, (), TABLE_4_1, s.sphere_centers, s.sphere_radii, s.sphere_materials, s.planes)
    assert "NO_LIGHTS" in scene_features(no_light).defines()

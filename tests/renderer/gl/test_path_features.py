"""The path integrator's variant holds only what the scene needs (renderer/frame/features.py,
PATH_REMOVALS): the GGX lobes where nothing is rough, next-event estimation of emitting spheres or
triangles or analytic shapes where none emits. Each removal is exact: the specialised variant renders the generic
one's image (the same samples, the same paths)."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.frame.features import PATH_REMOVALS, frame_features
from renderer.oracle.path_scenes import path_scene
from tests.renderer.gl.support import path

# scene → the path removals its variant carries
EXPECTED = {
    "cornell": {"NO_ROUGHNESS", "NO_SPHERE_LIGHTS", "NO_SHAPE_LIGHTS"},  # smooth mirror and glass, an emitting quad
    "rough_conductor": {"NO_TRIANGLE_LIGHTS", "NO_SHAPE_LIGHTS"},  # GGX, an emitting sphere, no mesh
    "glass_caustic": {"NO_ROUGHNESS", "NO_TRIANGLE_LIGHTS", "NO_SHAPE_LIGHTS"},
    "mesh_point_light": set(),  # nothing emits (a point light): the shader infers the light kinds
    "area_light": {"NO_TRIANGLE_LIGHTS", "NO_SHAPE_LIGHTS"},  # nothing reflects or transmits: NO_ROUGHNESS inferred
}


@pytest.mark.parametrize("name", list(EXPECTED))
def test_path_removals_follow_the_scene(name):
    scene = path_scene(name)
    features, _ = frame_features(scene, path())
    assert set(features.defines()) & set(PATH_REMOVALS) == EXPECTED[name]
    assert set(features.removed()) >= EXPECTED[name]
    generic, _ = frame_features(scene, path(specialize=False))
    assert not set(generic.defines()) & set(PATH_REMOVALS)
    whitted, _ = frame_features(scene, path(spp=1, depth=8).with_(integrator="whitted"))
    assert not set(whitted.defines()) & set(PATH_REMOVALS), "Whitted variants' text is unchanged"


@pytest.mark.parametrize("name", ["cornell", "rough_conductor", "area_light"])
def test_specialised_path_variant_is_exact(gl_renderer, name):
    """Specialised and generic variants trace the same paths: equal images up to float rounding
    of the code around them (a removed lobe or light that a scene used would change them by far
    more: its light, or a path's every later bounce)."""
    scene = path_scene(name)
    s = path(width=24, height=40, spp=8, depth=8)
    special = gl_renderer.render(scene, s)
    generic = gl_renderer.render(scene, s.with_(specialize=False))
    assert set(special.stats["features_removed"]) >= EXPECTED[name]
    assert special.image.mean() > 0.01
    np.testing.assert_allclose(special.image, generic.image, rtol=1e-4, atol=1e-5)

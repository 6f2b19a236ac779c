"""Preparing a frame (renderer.prepare): the method resolved and its data built, or the frame refused."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.methods import METHODS
from renderer.scene import SceneError
from renderer.settings import RenderSettings


def test_prepare_frame_refuses_the_ray_engines_on_a_scene_with_meshes_and_resolves_auto_with_triangles(
    mixed_trees_scene,
):
    from renderer.prepare import prepare_frame

    for name in ("rayengine", "hre"):
        assert "triangles" not in METHODS[name].capabilities.primitives
        with pytest.raises(SceneError) as e:
            prepare_frame(mixed_trees_scene, RenderSettings(width=8, height=8, method=name))
        assert e.value.field == "method" and "spheres and planes only" in e.value.message
    few_spheres = mixed_trees_scene.with_geometry(np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32))
    frame = prepare_frame(few_spheres, RenderSettings(width=8, height=8, method="auto"))
    assert frame.method == "bih"  # thousands of triangles: past the brute-force crossover
    assert frame.cost.ms > 0 and frame.stats["triangles"] == mixed_trees_scene.n_triangles

"""What every method's ``prepare`` hands the GPU (renderer.accel.base): its packed data."""

from __future__ import annotations

import pytest

from renderer.config.methods import METHODS
from renderer.scenes.scenarios import scenario

TREE_METHODS = ("bih", "bvh", "kdtree", "twolevel", "bruteforce")


@pytest.mark.parametrize("name", TREE_METHODS)
def test_a_sphere_scene_still_packs_its_gpu_data(name):
    s = scenario(2, 200, seed=3)
    prep = METHODS[name].prepare(s, 4, 64)
    assert isinstance(prep.packed.textures, dict)
    assert "triangles" not in prep.stats
    assert not {"u_triangles", "u_tri_normals", "u_tri_base"} & (set(prep.packed.textures) | set(prep.packed.uniforms))

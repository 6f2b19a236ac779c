"""What every method's ``prepare`` hands the GPU (renderer.accel.base): its packed data, or a
refusal naming the methods that trace meshes."""

from __future__ import annotations

import pytest

from renderer.accel.base import NotOnGPU
from renderer.methods import METHODS
from renderer.scenarios import scenario
from renderer.scene import SceneError

TREE_METHODS = ("bih", "bvh", "kdtree", "twolevel", "bruteforce")


def test_a_method_whose_layout_packs_spheres_only_would_refuse_meshes(mixed_trees_scene):
    """NotOnGPU (no method needs it since every layout holds triangles): reading it raises
    SceneError("meshes") naming the method and the methods that trace meshes."""
    from renderer.accel.base import MESH_METHODS, gpu_data

    packed = gpu_data(mixed_trees_scene, lambda: None, meshes_on_gpu=False, method="newtree")
    assert isinstance(packed, NotOnGPU)
    with pytest.raises(SceneError) as e:
        _ = packed.textures
    assert e.value.field == "meshes" and "'newtree'" in e.value.message
    assert (
        ", ".join(MESH_METHODS) in e.value.message and f"{mixed_trees_scene.n_triangles:,} triangles" in e.value.message
    )
    assert gpu_data(scenario(2, 8), lambda: "packed", meshes_on_gpu=False) == "packed"  # spheres only: packed


@pytest.mark.parametrize("name", TREE_METHODS)
def test_a_sphere_scene_still_packs_its_gpu_data(name):
    s = scenario(2, 200, seed=3)
    prep = METHODS[name].prepare(s, 4, 64)
    assert not isinstance(prep.packed, NotOnGPU) and isinstance(prep.packed.textures, dict)
    assert "triangles" not in prep.stats
    assert not {"u_triangles", "u_tri_normals", "u_tri_base"} & (set(prep.packed.textures) | set(prep.packed.uniforms))

"""Method ``twolevel`` (renderer.accel.twolevel), without a GPU: the static spheres go to the
kd-tree, the moving ones to the BVH, the packed sphere records hold scene ids, and the
static kd-tree is built once per static set. That every frame renders the brute-force
ids is tested on the GPU in ``tests/renderer/gl/test_renderer.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderer.accel.cpu_trace import trace_tree
from renderer.accel.twolevel import TwoLevelMethod
from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Scene
from renderer.gpu import gpu_layout
from renderer.oracle.reference import primary_rays
from renderer.scenes.animation import (
    AnimatedScene,
    RigidGroup,
    museum,
    pose,
)
from renderer.scenes.tree_update import TreeUpdate
from tests.renderer.scenes.test_animation import two_mesh_scene


@pytest.mark.parametrize("kind", ["rigid", "deformable", "incoherent"])
def test_static_spheres_in_the_kd_tree_moving_ones_in_the_bvh(kind):
    frame = pose(museum(48, kind, seed=1), 0.7)
    scene, moving = frame.scene, frame.moving
    prep = TwoLevelMethod().prepare(scene, 4, 64, update=TreeUpdate(scheme="refit", key="t", moving=moving))
    static_ids, moving_ids = set(np.flatnonzero(~moving).tolist()), set(np.flatnonzero(moving).tolist())
    assert static_ids and moving_ids
    assert prep.stats["static"] == len(static_ids) and prep.stats["moving"] == len(moving_ids)
    u = prep.packed.uniforms
    assert (u["u_kd_count"], u["u_bvh_count"]) == (len(static_ids), len(moving_ids))
    equal = gpu_layout.equal_radii(scene)
    # the BVH holds each moving sphere exactly once, as its scene id, with its centre
    bvh = gpu_layout.unpack_sphere_records(prep.packed.textures["u_bvh_spheres"].data, equal)
    ids = bvh["id"][: len(moving_ids)]
    assert sorted(ids.tolist()) == sorted(moving_ids)
    np.testing.assert_array_equal(bvh["centre"][: len(ids)], scene.sphere_centers[ids].astype(np.float32))
    assert bvh["last"][len(ids) - 1] and not bvh["last"][len(ids) :].any()
    # the kd-tree may list a sphere in several leaves, but only static ones, and all of them
    kd = set(gpu_layout.unpack_sphere_records(prep.packed.textures["u_kd_spheres"].data, equal)["id"].tolist())
    assert static_ids <= kd and kd <= static_ids | {0}, "kd records are static scene ids (0 pads the last row)"
    assert prep.stats["bytes"] == prep.stats["kd"]["bytes"] + prep.stats["bvh"]["bytes"]


def test_the_static_tree_is_built_once_per_static_set():
    anim = museum(32, "rigid", seed=2)
    method = TwoLevelMethod()
    cached = []
    for t in (0.0, 0.5, 1.0):
        f = pose(anim, t)
        prep = method.prepare(f.scene, 4, 64, update=TreeUpdate(scheme="refit", key="anim", moving=f.moving))
        cached.append(prep.stats["kd_cached"])
    assert cached == [False, True, True], "the static spheres did not move: one kd-tree build"
    # another animation (key) or a static sphere that moved: a build of its own
    again = method.prepare(f.scene, 4, 64, update=TreeUpdate(scheme="refit", key="other", moving=f.moving))
    assert again.stats["kd_cached"] is False
    c = f.scene.sphere_centers.copy()
    c[np.flatnonzero(~f.moving)[0]] += 0.5
    moved = Scene(
        f.scene.camera,
        f.scene.lights,
        f.scene.materials,
        c,
        f.scene.sphere_radii,
        f.scene.sphere_materials,
        f.scene.planes,
    )
    prep = method.prepare(moved, 4, 64, update=TreeUpdate(scheme="refit", key="anim", moving=f.moving))
    assert prep.stats["kd_cached"] is False


def test_a_plain_scene_is_all_static_and_a_bad_mask_is_refused():
    scene = pose(museum(16, "rigid"), 0.0).scene
    prep = TwoLevelMethod().prepare(scene, 4, 64)
    assert (prep.stats["static"], prep.stats["moving"]) == (scene.n_spheres, 0)
    with pytest.raises(ValueError, match="moving mask"):
        TwoLevelMethod().prepare(scene, 4, 64, update=TreeUpdate(moving=np.zeros(scene.n_spheres + 1, bool)))


def test_a_mask_of_the_wrong_length_is_refused_by_twolevel(mixed_trees_scene):
    with pytest.raises(ValueError, match="triangles"):
        METHODS["twolevel"].prepare(
            mixed_trees_scene, 4, 64, update=TreeUpdate(moving=np.zeros(mixed_trees_scene.n_spheres, bool))
        )


def test_twolevel_puts_a_moving_mesh_in_its_bvh_and_follows_it_between_frames():
    from renderer.frame.prepare import prepare_frame

    s = two_mesh_scene()
    anim = AnimatedScene(s, (RigidGroup(0, 0, mesh=2, angular_velocity=0.5),))
    n_moving = s.meshes[2].n_triangles
    for t in (0.0, 0.4, 0.8):
        rs = RenderSettings(width=8, height=8, method="twolevel", update="refit", time=t)
        frame = prepare_frame(anim, rs, key="mesh-anim")
        assert frame.stats["moving"] == n_moving and frame.stats["static"] == s.n_spheres + s.n_triangles - n_moving
        o, d = primary_rays(frame.scene.camera, 24, 24)
        _, ids = trace_tree(frame.prepared.tree, frame.scene, o, d)
        _, bf = trace_tree(None, frame.scene, o, d)
        np.testing.assert_array_equal(ids, bf)
    assert frame.stats["kd_cached"] is True and frame.stats["scheme"] == "refit"

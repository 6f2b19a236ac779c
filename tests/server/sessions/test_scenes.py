"""A session's scene source with meshes (server.sessions.scenes): stored, loaded bit for bit, and
streamed as exactly the scene JSON — without a server (no GL)."""

from __future__ import annotations

import json

import numpy as np

from renderer.animation import AnimatedScene, Deformable, RigidGroup, museum, pose
from renderer.meshes import teapot
from renderer.scenarios import mesh_scene
from renderer.scene import Camera
from server.sessions.scenes import SceneCache, load_source, scene_info, scene_json_chunks, scene_source


def scene_with_meshes():
    s = mesh_scene("mixed", detail=1)
    return s.with_geometry(
        s.sphere_centers, s.sphere_radii, s.sphere_materials, (*s.meshes, teapot(2, size=2.0, smooth=False))
    )


def test_the_npz_source_keeps_meshes_bit_for_bit_with_their_motions():
    anim = AnimatedScene(scene_with_meshes(), (RigidGroup(0, 0, mesh=1), Deformable(0, 9)))
    cam = Camera((1.0, 2.0, 50.0))
    back = load_source(scene_source(anim), cam)
    assert isinstance(back, AnimatedScene) and back.camera == cam
    for a, b in zip(anim.scene.meshes, back.scene.meshes, strict=True):
        np.testing.assert_array_equal(a.vertices, b.vertices)
        np.testing.assert_array_equal(a.triangles, b.triangles)
        assert a.material == b.material and (a.normals is None) == (b.normals is None)
        if a.normals is not None:
            np.testing.assert_array_equal(a.normals, b.normals)
    assert [m.mesh for m in back.motions] == [1, None]
    assert scene_info(back) == scene_info(anim)
    assert scene_info(back)["n_moving_meshes"] == 1 and scene_info(back)["n_triangles"] == anim.scene.n_triangles


def test_the_streamed_json_is_exactly_the_scene_json():
    scene = scene_with_meshes()
    text = b"".join(scene_json_chunks(scene, spheres_per_chunk=7)).decode()
    assert text == json.dumps(scene.to_json(), separators=(",", ":"))
    anim = AnimatedScene(scene, (RigidGroup(0, 0, mesh=0),))
    got = json.loads(b"".join(scene_json_chunks(anim, spheres_per_chunk=3)))
    assert got == json.loads(json.dumps(anim.to_json()))
    no_spheres = scene.with_geometry(np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32))
    assert b"".join(scene_json_chunks(no_spheres)).decode() == json.dumps(no_spheres.to_json(), separators=(",", ":"))


def test_the_cache_weighs_triangles():
    cache = SceneCache(max_spheres=10_000)
    scene = scene_with_meshes()  # ~1,000 triangles: weighs ~4,000
    for i in range(4):
        cache.put((f"s{i}", "r"), scene)
    assert cache.get(("s0", "r")) is None and cache.get(("s3", "r")) is scene


def test_sources_keep_the_motions():
    """What the store keeps (and a restarted process reads) is the same animation."""
    anim = museum(20, "mixed", seed=4)
    again = load_source(scene_source(anim), anim.camera)
    assert again.motions == anim.motions
    np.testing.assert_array_equal(again.scene.sphere_centers, anim.scene.sphere_centers)
    t = 0.8
    np.testing.assert_array_equal(pose(again, t).scene.sphere_centers, pose(anim, t).scene.sphere_centers)

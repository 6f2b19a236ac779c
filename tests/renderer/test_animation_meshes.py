"""Motions of meshes (renderer.animation): a rigid motion moves a mesh as one body, the
deformable wave deforms its vertices, and the posed frame says which triangles move."""

from __future__ import annotations

import json

import numpy as np
import pytest

from renderer.animation import (
    AnimatedScene,
    Deformable,
    Incoherent,
    RigidGroup,
    animated_scene_from_json,
    motion_to_json,
    pose,
)
from renderer.meshes import icosphere, teapot
from renderer.scenarios import mesh_scene
from renderer.scene import SceneError


def two_mesh_scene():
    s = mesh_scene("mixed", detail=1)
    return s.with_geometry(s.sphere_centers, s.sphere_radii, s.sphere_materials, (*s.meshes, teapot(3, size=2.0)))


def test_a_rigid_motion_moves_a_mesh_as_one_body_and_turns_its_normals():
    s = two_mesh_scene()
    anim = AnimatedScene(
        s,
        (
            RigidGroup(
                0,
                0,
                pivot=(1.0, 2.0, 3.0),
                axis=(0.0, 1.0, 1.0),
                angular_velocity=0.7,
                amplitude=(0.0, 2.0, 0.0),
                period=3.0,
                mesh=0,
            ),
        ),
    )
    frame = pose(anim, 1.3)
    before, after = s.meshes[0], frame.scene.meshes[0]
    d0 = np.linalg.norm(before.vertices[:, None] - before.vertices[None], axis=2)
    d1 = np.linalg.norm(after.vertices[:, None] - after.vertices[None], axis=2)
    np.testing.assert_allclose(d1, d0, atol=1e-12)  # distances kept: rigid
    assert np.abs(after.vertices - before.vertices).max() > 1.0
    # normals turn with the body: still the icosphere's radial directions
    centre = after.vertices.mean(axis=0)
    radial = (after.vertices - centre) / np.linalg.norm(after.vertices - centre, axis=1, keepdims=True)
    np.testing.assert_allclose(after.normals, radial, atol=1e-9)
    np.testing.assert_array_equal(after.triangles, before.triangles)
    # the other meshes and every sphere stay; the triangles of mesh 0 are the moving ones
    np.testing.assert_array_equal(frame.scene.meshes[1].vertices, s.meshes[1].vertices)
    np.testing.assert_array_equal(frame.scene.sphere_centers, s.sphere_centers)
    assert len(frame.moving) == s.n_spheres + s.n_triangles
    r = s.mesh_triangle_range(0)
    expect = np.zeros(len(frame.moving), bool)
    expect[s.n_spheres + r.start : s.n_spheres + r.stop] = True
    np.testing.assert_array_equal(frame.moving, expect)


def test_the_deformable_wave_deforms_a_mesh_and_recomputes_its_smooth_normals():
    s = two_mesh_scene()
    anim = AnimatedScene(
        s, (Deformable(0, 0, amplitude=0.5, wavelength=4.0, speed=2.0, mesh=2), RigidGroup(0, 5, angular_velocity=1.0))
    )
    frame = pose(anim, 0.8)
    before, after = s.meshes[2], frame.scene.meshes[2]
    moved = np.linalg.norm(after.vertices - before.vertices, axis=1)
    assert moved.max() <= 0.5 * np.sqrt(3) + 1e-12 and moved.max() > 0.1
    d0 = np.linalg.norm(before.vertices[:5, None] - before.vertices[None, 5:10], axis=2)
    d1 = np.linalg.norm(after.vertices[:5, None] - after.vertices[None, 5:10], axis=2)
    assert np.abs(d1 - d0).max() > 1e-3  # not rigid
    np.testing.assert_allclose(np.linalg.norm(after.normals, axis=1), 1.0, atol=1e-12)
    assert frame.moving[:5].all() and not frame.moving[5 : s.n_spheres].any()


@pytest.mark.parametrize(
    "motions,field",
    [
        ([{"kind": "rigid", "mesh": 5}], "motions[0].mesh"),
        ([{"kind": "rigid", "mesh": 0}, {"kind": "deformable", "mesh": 0}], "motions[1].mesh"),
        ([{"kind": "incoherent", "mesh": 0}], "motions[0].mesh"),
        ([{"kind": "rigid", "mesh": 0, "first": 0}], "motions[0].first"),
        ([{"kind": "rigid"}], "motions[0].first"),
        ([{"kind": "deformable", "mesh": 1, "amplitude": 2e7}], "motions[0]"),
    ],
)
def test_bad_mesh_motions_name_the_field(motions, field):
    d = {**two_mesh_scene().to_json(), "motions": motions}
    with pytest.raises(SceneError) as e:
        animated_scene_from_json(d)
    assert e.value.field.startswith(field), str(e.value)


def test_mesh_motions_round_trip_as_json_without_first_and_count():
    s = two_mesh_scene()
    anim = AnimatedScene(s, (RigidGroup(0, 0, mesh=1, angular_velocity=0.25), Deformable(2, 3)))
    out = json.loads(json.dumps(anim.to_json()))
    assert out["motions"][0] == {
        "kind": "rigid",
        "mesh": 1,
        "pivot": [0.0, 0.0, 0.0],
        "axis": [0.0, 1.0, 0.0],
        "angular_velocity": 0.25,
        "amplitude": [0.0, 0.0, 0.0],
        "period": 4.0,
    }
    assert "mesh" not in out["motions"][1] and out["motions"][1]["first"] == 2
    again = animated_scene_from_json(out)
    np.testing.assert_array_equal(pose(again, 2.0).scene.triangle_corners, pose(anim, 2.0).scene.triangle_corners)
    assert again.moving_meshes.tolist() == [False, True, False]
    assert motion_to_json(again.motions[0]) == out["motions"][0]
    # a plain sphere motion's JSON is as it was
    assert set(motion_to_json(Incoherent(0, 1))) == {
        "kind",
        "first",
        "count",
        "box_min",
        "box_max",
        "speed",
        "lifetime",
        "absent",
        "seed",
    }


def test_a_scene_without_meshes_refuses_a_mesh_motion():
    from renderer.scenarios import scenario

    with pytest.raises(SceneError) as e:
        AnimatedScene(scenario(1, 8), (RigidGroup(0, 0, mesh=0),))
    assert e.value.field == "motions[0].mesh"
    assert icosphere(0).n_triangles == 20


def test_twolevel_puts_a_moving_mesh_in_its_bvh_and_follows_it_between_frames():
    from renderer.accel.cpu_trace import trace_tree
    from renderer.prepare import prepare_frame
    from renderer.reference import primary_rays
    from renderer.settings import RenderSettings

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

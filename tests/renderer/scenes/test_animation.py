"""Animated scenes (renderer.scenes.animation): motion models and validation.

- bad input names its field (bad motions, overlapping ranges, negative time) and nothing
  is applied (the animation settings' own checks are in ``test_settings.py``);
- the three kinds of motion behave as stated (rigid bodies keep their distances,
  deformation is bounded and continuous, incoherent spheres stay in their box and
  disappear and reappear).

Exactness frame after frame on the GPU is in ``tests/renderer/gl/test_renderer.py``.

Motions of meshes (renderer.scenes.animation): a rigid motion moves a mesh as one body, the
deformable wave deforms its vertices, and the posed frame says which triangles move.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from renderer.geometry.meshes import icosphere, teapot
from renderer.geometry.scene import SceneError
from renderer.scenes.animation import (
    AnimatedScene,
    Deformable,
    Incoherent,
    RigidGroup,
    animated_scene_from_json,
    motion_to_json,
    museum,
    pose,
)
from renderer.scenes.scenarios import mesh_scene, scenario


def base_json(n: int = 16) -> dict:
    return scenario(1, n).to_json()


@pytest.mark.parametrize(
    "motion,field",
    [
        ({"kind": "wobble", "first": 0, "count": 4}, "motions[0].kind"),
        ({"kind": "rigid", "first": 0, "count": 4, "spin": 1}, "motions[0].spin"),
        ({"kind": "rigid", "count": 4}, "motions[0].first"),
        ({"kind": "rigid", "first": 0, "count": 40}, "motions[0].count"),
        ({"kind": "rigid", "first": 0, "count": 4, "amplitude": [1, float("inf"), 0]}, "motions[0].amplitude[1]"),
        ({"kind": "rigid", "first": 0, "count": 4, "axis": [0, 0, 0]}, "motions[0].axis"),
        ({"kind": "rigid", "first": 0, "count": 4, "pivot": [9e6, 0, 0], "amplitude": [5e6, 0, 0]}, "motions[0]"),
        ({"kind": "deformable", "first": 0, "count": 4, "amplitude": 2e7}, "motions[0].amplitude"),
        ({"kind": "deformable", "first": 0, "count": 4, "wavelength": 0}, "motions[0].wavelength"),
        (
            {"kind": "incoherent", "first": 0, "count": 4, "box_min": [0, 0, 0], "box_max": [1, -1, 1]},
            "motions[0].box_max[1]",
        ),
        ({"kind": "incoherent", "first": 0, "count": 4, "absent": 1.0}, "motions[0].absent"),
        ({"kind": "incoherent", "first": 0, "count": 4, "lifetime": -2}, "motions[0].lifetime"),
    ],
)
def test_bad_motions_name_the_field(motion, field):
    d = base_json()
    d["motions"] = [motion]
    with pytest.raises(SceneError) as e:
        animated_scene_from_json(d)
    assert e.value.field == field, e.value


def test_overlapping_ranges_and_bad_time_are_rejected():
    d = base_json()
    d["motions"] = [{"kind": "rigid", "first": 0, "count": 8}, {"kind": "deformable", "first": 6, "count": 4}]
    with pytest.raises(SceneError) as e:
        animated_scene_from_json(d)
    assert e.value.field == "motions[1].first"
    anim = museum(16, "rigid")
    with pytest.raises(SceneError) as e:
        pose(anim, -0.5)
    assert e.value.field == "time"


def test_json_round_trip_and_static_spheres():
    anim = museum(32, "mixed")
    again = animated_scene_from_json(anim.to_json())
    assert again.motions == anim.motions
    np.testing.assert_array_equal(again.moving, anim.moving)
    assert not anim.moving[:576].any() and anim.moving[576:].all()


def test_rigid_groups_move_as_one_body():
    anim = museum(64, "rigid")
    a, b = pose(anim, 0.0), pose(anim, 1.7)
    np.testing.assert_allclose(a.scene.sphere_centers, anim.scene.sphere_centers)
    for m in anim.motions:
        sl = slice(m.first, m.first + m.count)
        ca, cb = a.scene.sphere_centers[sl], b.scene.sphere_centers[sl]
        da = np.linalg.norm(ca[:, None] - ca[None], axis=2)
        db = np.linalg.norm(cb[:, None] - cb[None], axis=2)
        np.testing.assert_allclose(da, db, atol=1e-9)
        assert np.abs(cb - ca).max() > 0.1
    np.testing.assert_array_equal(a.scene.sphere_centers[:576], b.scene.sphere_centers[:576])


def test_deformation_is_bounded_and_continuous():
    anim = museum(64, "deformable")
    rest = anim.scene.sphere_centers
    m = anim.motions[0]
    for t in (0.0, 0.3, 2.0):
        c = pose(anim, t).scene.sphere_centers
        assert np.abs(c - rest).max() <= m.amplitude + 1e-12
        c2 = pose(anim, t + 1e-3).scene.sphere_centers
        assert np.abs(c2 - c).max() < 0.1


def test_incoherent_spheres_stay_in_their_box_and_come_and_go():
    anim = museum(200, "incoherent")
    m = anim.motions[0]
    counts = set()
    for t in np.linspace(0.0, 6.0, 13):
        f = pose(anim, float(t))
        counts.add(f.scene.n_spheres)
        moving = f.scene.sphere_centers[f.moving]
        inside = (moving >= np.asarray(m.box_min) - 1e-9) & (moving <= np.asarray(m.box_max) + 1e-9)
        assert inside.all() or t == 0.0
        assert (f.ids[~f.moving] < 576).all() and f.moving.sum() == (f.ids >= 576).sum()
        again = pose(anim, float(t))
        np.testing.assert_array_equal(again.scene.sphere_centers, f.scene.sphere_centers)
    assert len(counts) > 1, "spheres appear and disappear"
    fixed = museum(50, "incoherent", absent=0.0)
    assert {pose(fixed, t).scene.n_spheres for t in (0.0, 1.0, 3.3)} == {fixed.scene.n_spheres}


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
    # a plain sphere motion's JSON names no mesh
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
    from renderer.scenes.scenarios import scenario

    with pytest.raises(SceneError) as e:
        AnimatedScene(scenario(1, 8), (RigidGroup(0, 0, mesh=0),))
    assert e.value.field == "motions[0].mesh"
    assert icosphere(0).n_triangles == 20


def test_a_posed_scene_and_a_scene_under_the_sky_keep_their_textures_and_vertex_attributes():
    """A textured PBR mesh that moves, or a textured scene put under the sky, still reads its texture
    (a scene without its textures is refused: the material names a texture it no longer has)."""
    import dataclasses

    from renderer.materials.pbr import PbrMaterial
    from renderer.materials.texture import Texture
    from renderer.scenes.scenarios import with_sky

    s = two_mesh_scene()
    uvs = np.zeros((len(s.meshes[1].vertices), 2))
    moving = dataclasses.replace(s.meshes[1], material=len(s.materials), uvs=uvs)
    s = dataclasses.replace(
        s,
        materials=(*s.materials, PbrMaterial(base_color_texture=0)),
        meshes=(s.meshes[0], moving, *s.meshes[2:]),
        textures=(Texture(np.full((2, 2, 4), 200, np.uint8)),),
    )
    posed = pose(AnimatedScene(s, (RigidGroup(0, 0, mesh=1, angular_velocity=0.25),)), 1.0).scene
    assert posed.textures == s.textures and posed.meshes[1].uvs is not None
    assert with_sky(s).textures == s.textures

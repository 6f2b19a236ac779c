"""Animated scenes (issue #9, renderer.animation): motion models and validation.

- bad input names its field (bad motions, overlapping ranges, negative time) and nothing
  is applied (the animation settings' own checks are in ``test_settings.py``);
- the three kinds of motion behave as stated (rigid bodies keep their distances,
  deformation is bounded and continuous, incoherent spheres stay in their box and
  disappear and reappear).

Exactness frame after frame on the GPU is in ``tests/renderer/gl/test_renderer.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderer.animation import animated_scene_from_json, museum, pose
from renderer.scenarios import scenario
from renderer.scene import SceneError


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

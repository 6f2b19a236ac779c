"""Boxes of primitives and the trees' index space (renderer.accel.primitives)."""

from __future__ import annotations

import numpy as np

from renderer.accel.primitives import scene_aabbs, scene_to_tree_ids, tree_to_scene_ids, triangle_aabbs


def test_triangle_boxes_hold_the_triangle_in_both_precisions():
    rng = np.random.default_rng(0)
    c = rng.uniform(-1, 1, (500, 3, 3)) * 10.0 ** rng.integers(-3, 7, (500, 1, 1)) + rng.choice([0.0, 1e6], (500, 1, 1))
    lo, hi = triangle_aabbs(c)
    assert lo.dtype == hi.dtype == np.float32
    for corners in (c, c.astype(np.float32).astype(np.float64)):
        assert (lo[:, None, :] <= corners).all() and (corners <= hi[:, None, :]).all()
    assert (lo < c.min(axis=1)).all() and (hi > c.max(axis=1)).all()  # strictly: rounded outwards


def test_the_tree_index_space_is_spheres_then_triangles_and_maps_to_scene_ids(mixed_trees_scene):
    lo, hi = scene_aabbs(mixed_trees_scene)
    assert len(lo) == mixed_trees_scene.n_spheres + mixed_trees_scene.n_triangles
    tree_ids = np.array(
        [-1, 0, mixed_trees_scene.n_spheres - 1, mixed_trees_scene.n_spheres, mixed_trees_scene.n_spheres + 5]
    )
    ids = tree_to_scene_ids(tree_ids, mixed_trees_scene.n_spheres, len(mixed_trees_scene.planes))
    np.testing.assert_array_equal(
        ids,
        [
            -1,
            0,
            mixed_trees_scene.n_spheres - 1,
            mixed_trees_scene.triangle_id_base,
            mixed_trees_scene.triangle_id_base + 5,
        ],
    )
    np.testing.assert_array_equal(
        scene_to_tree_ids(ids, mixed_trees_scene.n_spheres, len(mixed_trees_scene.planes)), tree_ids
    )
    assert (
        scene_to_tree_ids(np.array([mixed_trees_scene.n_spheres]), mixed_trees_scene.n_spheres, 1)[0] == -1
    )  # a plane

"""Method ``bruteforce`` (renderer.accel.bruteforce): no structure, the sphere records in id order."""

from __future__ import annotations

import numpy as np

from renderer.accel.bruteforce import SPHERES, BruteForce
from renderer.gpu import gpu_layout
from renderer.scenes.scenarios import mesh_scene, scenario


def test_prepare_packs_the_sphere_records_in_id_order_and_builds_nothing():
    s = scenario(3, 100, seed=2)
    prep = BruteForce().prepare(s, 4, 64)
    assert prep.tree is None and prep.build_ms == 0.0
    assert prep.stats == {"method": "bruteforce", "primitives": 100}
    records = gpu_layout.sphere_records(s, np.arange(s.n_spheres))
    packed = prep.packed.textures[SPHERES.name].data.reshape(-1, records.shape[1])  # wrapped in rows
    np.testing.assert_array_equal(packed[: len(records)], records)
    assert not packed[len(records) :].any()
    assert set(prep.packed.textures) | set(prep.packed.uniforms) == {SPHERES.name}


def test_a_mesh_scene_adds_the_triangle_records():
    s = mesh_scene("mixed", 1)
    prep = BruteForce().prepare(s, 4, 64)
    assert prep.stats["primitives"] == s.n_spheres + s.n_triangles and prep.stats["triangles"] == s.n_triangles
    assert {b.name for b in gpu_layout.TRIANGLE_BINDINGS} <= set(prep.packed.textures) | set(prep.packed.uniforms)

"""The BVH's GPU data (renderer.accel.bvh_layout): what ``pack_bvh`` hands the shader. That the
inner records say what the build's nodes say, over random scenes, is checked with the build's
invariants in ``test_bvh.py`` (``check_bvh``)."""

from __future__ import annotations

import numpy as np

from renderer.accel import bvh_layout as L
from renderer.accel.bih import sphere_aabbs
from renderer.accel.bvh import build_bvh
from renderer.gpu import gpu_layout
from renderer.scenes.scenarios import scenario


def elements(tex: gpu_layout.PackedTexture, count: int) -> np.ndarray:
    return tex.data.reshape(-1, tex.data.shape[-1])[:count]


def test_pack_bvh_holds_the_inner_records_the_leaf_order_spheres_and_the_root():
    s = scenario(2, 200, seed=4)
    bvh = build_bvh(*sphere_aabbs(s.sphere_centers, s.sphere_radii), 4, 64)
    packed = L.pack_bvh(bvh, s)
    assert set(packed.textures) | set(packed.uniforms) == {b.name for b in L.BINDINGS if b.needs is None}
    records, root = L.gpu_records(bvh)
    inner = int((bvh.left >= 0).sum())
    assert records.shape == (L.RECORDS_PER_NODE * inner, 4) and records.nbytes == inner * L.RECORD_BYTES
    np.testing.assert_array_equal(elements(packed.textures[L.NODES.name], len(records)), records)
    order, last = L.leaf_order(bvh)
    assert sorted(order) == list(range(s.n_spheres)) and last.sum() == int((bvh.left < 0).sum())
    want = gpu_layout.sphere_records(s, order, last)
    np.testing.assert_array_equal(elements(packed.textures[L.SPHERES.name], len(want)), want)
    assert packed.uniforms[L.ROOT.name] == root == 0  # the root is the first inner record
    np.testing.assert_allclose(packed.uniforms[L.ROOT_MIN.name], bvh.bmin[0])
    np.testing.assert_allclose(packed.uniforms[L.ROOT_MAX.name], bvh.bmax[0])


def test_ids_map_the_built_primitives_to_the_scenes_spheres():
    s = scenario(2, 40, seed=5)
    ids = np.arange(0, 40, 2)  # a BVH over every other sphere, as twolevel builds its moving set
    bvh = build_bvh(*sphere_aabbs(s.sphere_centers[ids], s.sphere_radii[ids]), 2, 64)
    order, last = L.leaf_order(bvh)
    want = gpu_layout.sphere_records(s, ids[order], last)
    got = L.pack_bvh(bvh, s, ids=ids).textures[L.SPHERES.name]
    np.testing.assert_array_equal(elements(got, len(want)), want)


def test_the_glsl_defines_are_the_layouts_constants():
    lines = set(L.glsl_defines().splitlines())
    assert f"#define BVH_REF_LEAF {L.REF_LEAF}u" in lines and f"#define BVH_STACK_SIZE {L.STACK_SIZE}" in lines
    assert L.REF_INDEX == L.REF_LEAF - 1 and L.REF_LEAF == 1 << 31

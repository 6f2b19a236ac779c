"""The kd-tree's GPU data (renderer.accel.kdtree_layout): what ``pack_kdtree`` hands the shader.
That the inner records say what the build's nodes say, over random scenes, is checked with the
build's invariants in ``test_kdtree.py`` (``check_kdtree``)."""

from __future__ import annotations

import numpy as np

from renderer.accel import kdtree_layout as L
from renderer.accel.bih import sphere_aabbs
from renderer.accel.kdtree import build_kdtree
from renderer.gpu import gpu_layout
from renderer.scenes.scenarios import scenario


def elements(tex: gpu_layout.PackedTexture, count: int) -> np.ndarray:
    return tex.data.reshape(-1, tex.data.shape[-1])[:count]


def test_pack_kdtree_holds_the_inner_records_every_leafs_spheres_and_the_root():
    s = scenario(2, 200, seed=4)
    kd = build_kdtree(*sphere_aabbs(s.sphere_centers, s.sphere_radii))
    packed = L.pack_kdtree(kd, s)
    assert set(packed.textures) | set(packed.uniforms) == {b.name for b in L.BINDINGS if b.needs is None}
    prims, first, last = L.leaf_runs(kd)
    leaves = kd.axis < 0
    assert len(prims) == int(kd.count[leaves].sum()) and set(prims) == set(range(s.n_spheres))
    assert last.sum() == int((kd.count[leaves] > 0).sum())  # one run per leaf that holds spheres
    records, root = L.gpu_records(kd, first)
    assert records.shape == (int((~leaves).sum()), 4) and records.nbytes == len(records) * L.RECORD_BYTES
    np.testing.assert_array_equal(elements(packed.textures[L.NODES.name], len(records)), records)
    want = gpu_layout.sphere_records(s, prims, last)
    np.testing.assert_array_equal(elements(packed.textures[L.SPHERES.name], len(want)), want)
    assert packed.uniforms[L.ROOT.name] == root == 0
    np.testing.assert_allclose(packed.uniforms[L.BOX_MIN.name], kd.global_box[0])
    np.testing.assert_allclose(packed.uniforms[L.BOX_MAX.name], kd.global_box[1])


def test_the_refs_leave_room_for_the_axis_and_the_glsl_defines_are_the_layouts_constants():
    assert L.REF_LEAF | L.REF_EMPTY | L.REF_INDEX <= L.LOW_MASK  # a ref fits below the axis bits
    assert L.REF_LEAF & L.REF_EMPTY == 0 and L.REF_INDEX == L.REF_EMPTY - 1
    lines = set(L.glsl_defines().splitlines())
    assert f"#define KD_REF_LEAF {L.REF_LEAF}u" in lines and f"#define KD_REF_EMPTY {L.REF_EMPTY}u" in lines

"""The BIH's GPU records (renderer.accel.bih_layout) against the built tree."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from renderer.accel.bih import build_bih, sphere_aabbs
from tests.helpers import HYP
from tests.renderer.accel.support import decode, scenes


@settings(max_examples=60, **HYP)
@given(scene=scenes(), max_prims=st.integers(1, 16), max_tree_depth=st.integers(1, 64), empty_cuts=st.booleans())
def test_gpu_records_are_the_built_tree(scene, max_prims, max_tree_depth, empty_cuts):
    """The GPU layout (bih_layout.gpu_records, leaf_order) says what the thesis's nodes say:
    every inner node has a record with its axis and clips; its child refs name the child's
    record, or the first sphere record of a leaf, whose run ends (flag) after its count; a
    cut's empty child (a leaf of no primitives) is named by its sibling's ref."""
    from renderer.accel import bih_layout as L

    c, r = scene
    bih = build_bih(*sphere_aabbs(c, r), max_prims, max_tree_depth, empty_cuts=empty_cuts)
    leaf, axis, left, cl, cr, off, cnt = decode(bih)
    records, root = L.gpu_records(bih)
    order, last = L.leaf_order(bih)
    inner = np.flatnonzero(~leaf)
    assert len(records) == len(inner) and records.shape[1] == 4
    np.testing.assert_array_equal(order, bih.indices)
    rec_of = {int(node): k for k, node in enumerate(inner)}

    def ref_of(node: int, sibling: int | None = None) -> int:
        if leaf[node] and cnt[node] == 0 and sibling is not None:
            return ref_of(sibling)
        return (L.REF_LEAF | int(off[node])) if leaf[node] else rec_of[int(node)]

    assert root == ref_of(0)
    for k, node in enumerate(inner):
        x, y, z, w = (int(v) for v in records[k])
        assert x >> L.AXIS_SHIFT == axis[node]
        assert (x & L.CHILD_MASK, w) == (ref_of(left[node], left[node] + 1), ref_of(left[node] + 1, left[node]))
        assert np.uint32(y).view(np.float32) == cl[node] and np.uint32(z).view(np.float32) == cr[node]
    for node in np.flatnonzero(leaf):
        if cnt[node]:
            run = last[off[node] : off[node] + cnt[node]]
            assert run[-1] and not run[:-1].any(), "a leaf's run ends at its last record"
    assert last.sum() == (cnt[leaf] > 0).sum()

"""Method ``kdtree`` (renderer.accel.kdtree): tree invariants, cost scaling, compaction.

Property tests (hypothesis) over random and degenerate scenes: every primitive that
straddles a plane is in both children, every primitive whose box meets a leaf's voxel is
in that leaf (so every primitive is reachable), the GPU words (renderer.accel.kdtree_layout)
say the same. The GPU renders of the method are in ``tests/renderer/gl/test_renderer.py``.
"""

from __future__ import annotations

import time

import numpy as np
from hypothesis import given, settings, strategies as st

from renderer.accel import kdtree_layout
from renderer.accel.bih import sphere_aabbs
from renderer.accel.kdtree import build_kdtree
from renderer.scenes.scenarios import scenario
from tests.helpers import HYP
from tests.renderer.accel.support import sphere_sets


def kd_node_sets(kd) -> list[set]:
    """The primitives below every node (union of its leaves' lists)."""
    m = kd.n_nodes
    sets: list[set] = [set() for _ in range(m)]
    order = np.argsort(-kd.depth, kind="stable")
    for i in order:
        if kd.axis[i] < 0:
            sets[i] = set(kd.leaf_prims(i).tolist())
        else:
            sets[i] = sets[kd.left[i]] | sets[kd.left[i] + 1]
    return sets


def check_kdtree(kd, lo: np.ndarray, hi: np.ndarray, max_tree_depth: int) -> None:
    n = len(lo)
    m = kd.n_nodes
    assert kd.depth.max(initial=1) <= min(max_tree_depth, kd.max_depth) <= kdtree_layout.STACK_SIZE
    inner = np.flatnonzero(kd.axis >= 0)
    li = kd.left[inner]
    seen = np.zeros(m, np.int64)
    seen[0] = 1
    seen[li] += 1
    seen[li + 1] += 1
    assert (seen == 1).all()
    ax = kd.axis[inner]
    rows = np.arange(len(inner))
    # children voxels: the parent's split at the plane, which lies strictly inside it
    assert (kd.vmin[inner, :][rows, ax] < kd.split[inner]).all() and (kd.split[inner] < kd.vmax[inner][rows, ax]).all()
    exp_lmax = kd.vmax[inner].copy()
    exp_lmax[rows, ax] = kd.split[inner]
    exp_rmin = kd.vmin[inner].copy()
    exp_rmin[rows, ax] = kd.split[inner]
    np.testing.assert_array_equal(kd.vmin[li], kd.vmin[inner])
    np.testing.assert_array_equal(kd.vmax[li], exp_lmax)
    np.testing.assert_array_equal(kd.vmin[li + 1], exp_rmin)
    np.testing.assert_array_equal(kd.vmax[li + 1], kd.vmax[inner])
    leaves = np.flatnonzero(kd.axis < 0)
    for leaf in leaves:
        p = kd.leaf_prims(leaf)
        assert (np.diff(p) > 0).all(), "leaf lists are sorted, without repeats"
        assert kd.offset[leaf] + kd.count[leaf] <= len(kd.indices)
    sets = kd_node_sets(kd)
    if n:
        assert sets[0] == set(range(n)), "every primitive reachable"
        # completeness: a primitive whose box meets a leaf's open voxel is in that leaf
        for leaf in leaves:
            meets = np.flatnonzero(((lo < kd.vmax[leaf]) & (hi > kd.vmin[leaf])).all(axis=1))
            assert set(meets.tolist()) <= sets[leaf], f"leaf {leaf} misses primitives of its voxel"
        # a straddler is in both children
        for i in inner:
            a, p = kd.axis[i], kd.split[i]
            straddle = {j for j in sets[i] if lo[j, a] < p < hi[j, a]}
            assert straddle <= sets[kd.left[i]] and straddle <= sets[kd.left[i] + 1]
    # the GPU records: each leaf a run of its own primitives, empty ones flagged
    prims, first, last = kdtree_layout.leaf_runs(kd)
    records, root = kdtree_layout.gpu_records(kd, first)
    rec_of = {int(k): i for i, k in enumerate(inner)}

    def ref_of(node: int) -> int:
        if kd.axis[node] >= 0:
            return rec_of[int(node)]
        return kdtree_layout.REF_LEAF | (int(first[node]) if kd.count[node] else kdtree_layout.REF_EMPTY)

    assert root == ref_of(0) and records.shape == (len(inner), 4)
    for i, node in enumerate(inner):
        x, y, z, w = (int(v) for v in records[i])
        assert x >> kdtree_layout.AXIS_SHIFT == kd.axis[node] and w == 0
        assert (x & kdtree_layout.LOW_MASK, z) == (ref_of(kd.left[node]), ref_of(kd.left[node] + 1))
        assert np.uint32(y).view(np.float32) == kd.split[node]
    for node in leaves:
        run = prims[first[node] : first[node] + kd.count[node]]
        np.testing.assert_array_equal(run, kd.leaf_prims(node))
        if kd.count[node]:
            assert (
                last[first[node] + kd.count[node] - 1]
                and not last[first[node] : first[node] + kd.count[node] - 1].any()
            )
    assert len(prims) == kd.count[leaves].sum()


@settings(max_examples=40, **HYP)
@given(sphere_sets(max_n=90), st.integers(1, 64), st.sampled_from([1.0, 0.9, 0.5, 0.1]), st.sampled_from([0, 4, 1000]))
def test_kdtree_invariants(spheres, max_tree_depth, cost_scale, window):
    c, r = spheres
    lo, hi = sphere_aabbs(c, r)
    kd = build_kdtree(lo, hi, max_tree_depth=max_tree_depth, cost_scale=cost_scale, compaction_window=window)
    check_kdtree(kd, lo, hi, max_tree_depth)
    assert kd.stats.references >= len(lo)
    assert kd.stats.indices <= kd.stats.references


def test_kdtree_cost_scaling_makes_smaller_trees_and_compaction_shares_lists():
    s = scenario(3, 1024)
    lo, hi = sphere_aabbs(s.sphere_centers, s.sphere_radii)
    plain = build_kdtree(lo, hi, cost_scale=1.0)
    scaled = build_kdtree(lo, hi, cost_scale=0.5)
    assert scaled.stats.nodes < plain.stats.nodes and scaled.stats.bytes < plain.stats.bytes
    assert scaled.stats.sah_cost >= plain.stats.sah_cost * 0.999
    loose = build_kdtree(lo, hi, cost_scale=1.0, compaction_window=0)
    assert plain.stats.indices <= loose.stats.indices == loose.stats.references


def test_kdtree_terminates_on_degenerate_input():
    same = np.zeros((2000, 3))
    t0 = time.process_time()  # CPU seconds: the machine's load does not stretch them
    kd = build_kdtree(*sphere_aabbs(same, np.linspace(0.5, 4, 2000)), cost_scale=1.0)
    assert time.process_time() - t0 < 10.0
    assert kd.stats.references <= 64 * 2000 + 1024

"""Method ``bvh`` (renderer.accel.bvh): tree invariants after builds and updates.

Property tests (hypothesis) over random and degenerate scenes: every BVH node box holds
its children and its primitives, each primitive is in exactly one leaf, depth within the
limit, the GPU words (renderer.accel.bvh_layout) say the same — after the build and after
any number of refits and selective rebuilds under random motion, incoherent included.
The GPU renders of the method are in ``tests/renderer/gl/test_renderer.py``.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from renderer.accel import bvh_layout
from renderer.accel.bih import sphere_aabbs
from renderer.accel.bvh import BVHUpdater, build_bvh, near_masks, refit, selective_rebuild, split_costs
from renderer.scenes.scenarios import scenario
from tests.helpers import HYP
from tests.renderer.accel.support import sphere_sets


def motion(c: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
    if kind == "rigid":
        return c + rng.uniform(-5, 5, 3)
    if kind == "deformable":
        return c + rng.normal(0, 0.3, c.shape)
    return rng.uniform(-30, 30, c.shape)  # incoherent: every sphere teleports


# ---------------------------------------------------------------- BVH invariants


def check_bvh(b, lo: np.ndarray, hi: np.ndarray, max_tree_depth: int) -> None:
    n = len(lo)
    assert b.n_primitives == n
    assert sorted(b.indices.tolist()) == list(range(n)), "every primitive exactly once"
    assert b.depth.max(initial=1) <= max_tree_depth <= bvh_layout.STACK_SIZE
    if n == 0:
        assert b.n_nodes == 1 and b.left[0] == -1 and b.count[0] == 0
        return
    assert b.first[0] == 0 and b.count[0] == n
    inner = np.flatnonzero(b.left >= 0)
    li = b.left[inner]
    assert (li > inner).all() and (li + 1 < b.n_nodes).all()
    for c in (li, li + 1):
        assert (b.bmin[inner] <= b.bmin[c]).all() and (b.bmax[inner] >= b.bmax[c]).all(), "box holds its children"
        assert (b.depth[c] == b.depth[inner] + 1).all()
    assert (b.count[li] >= 1).all() and (b.count[li + 1] >= 1).all()
    assert (b.first[li] == b.first[inner]).all()
    assert (b.first[li + 1] == b.first[li] + b.count[li]).all()
    assert (b.count[li] + b.count[li + 1] == b.count[inner]).all()
    # every node reached exactly once from the root
    seen = np.zeros(b.n_nodes, np.int64)
    seen[0] = 1
    seen[li] += 1
    seen[li + 1] += 1
    assert (seen == 1).all(), "every node has exactly one parent"
    leaves = np.flatnonzero(b.left < 0)
    assert b.count[leaves].sum() == n
    slot_leaf = np.repeat(leaves, b.count[leaves])
    pos = np.concatenate([np.arange(f, f + c) for f, c in zip(b.first[leaves], b.count[leaves], strict=True)])
    p = b.indices[pos]
    assert (lo[p] >= b.bmin[slot_leaf]).all() and (hi[p] <= b.bmax[slot_leaf]).all(), "leaf box holds its spheres"
    assert (b.near_mask[leaves] == 0).all()
    np.testing.assert_array_equal(b.near_mask, near_masks(b.bmin, b.bmax, b.left))
    # the GPU records: an inner node's record holds both children's boxes and refs
    records, root = bvh_layout.gpu_records(b)
    inner = np.flatnonzero(b.left >= 0)
    rec_of = {int(k): i for i, k in enumerate(inner)}

    def ref_of(node: int) -> int:
        return (bvh_layout.REF_LEAF | int(b.first[node])) if b.left[node] < 0 else rec_of[int(node)]

    assert root == ref_of(0) and records.shape == (4 * len(inner), 4)
    rec = records.reshape(-1, 4, 4)
    f = lambda a: a.copy().view(np.float32)
    for i, node in enumerate(inner):
        lc, rc = b.left[node], b.left[node] + 1
        np.testing.assert_array_equal(f(rec[i, 0, :3]), b.bmin[lc])
        np.testing.assert_array_equal(f(rec[i, 1, :3]), b.bmax[lc])
        np.testing.assert_array_equal(f(rec[i, 2, :3]), b.bmin[rc])
        np.testing.assert_array_equal(f(rec[i, 3, :3]), b.bmax[rc])
        assert (rec[i, 0, 3], rec[i, 1, 3], rec[i, 2, 3]) == (ref_of(lc), ref_of(rc), b.near_mask[node])
    order, last = bvh_layout.leaf_order(b)
    np.testing.assert_array_equal(order, b.indices)
    assert last.sum() == len(leaves) if n else not last.any()
    assert all(last[b.first[k] + b.count[k] - 1] for k in leaves if b.count[k])


@settings(max_examples=40, **HYP)
@given(sphere_sets(), st.integers(1, 8), st.integers(1, 64))
def test_bvh_build_invariants(spheres, max_prims, max_tree_depth):
    c, r = spheres
    lo, hi = sphere_aabbs(c, r)
    b = build_bvh(lo, hi, max_prims, max_tree_depth)
    check_bvh(b, lo, hi, max_tree_depth)
    leaves = b.left < 0
    forced = b.depth[leaves] >= max_tree_depth
    assert (b.count[leaves][~forced] <= max_prims).all(), "leaves beyond max_prims only at the depth limit"
    assert b.stats.nodes == b.n_nodes and b.stats.leaves == int(leaves.sum())


@settings(max_examples=30, **HYP)
@given(
    sphere_sets(max_n=100),
    st.integers(1, 8),
    st.integers(2, 64),
    st.lists(st.sampled_from(["rigid", "deformable", "incoherent"]), min_size=1, max_size=4),
    st.sampled_from(["refit", "selective"]),
    st.integers(0, 2**31),
)
def test_bvh_invariants_after_updates(spheres, max_prims, max_tree_depth, motions, scheme, seed):
    c, r = spheres
    rng = np.random.default_rng(seed)
    up = BVHUpdater(max_prims, max_tree_depth, threshold=rng.choice([0.0, 0.3, 1.0]))
    b = up.update(c, r, scheme)
    for kind in motions:
        c = motion(c, kind, rng)
        b = up.update(c, r, scheme)
        lo, hi = sphere_aabbs(c, r)
        check_bvh(b, lo, hi, max_tree_depth)
        if scheme == "selective" and b.n_primitives:
            inner = b.left >= 0
            # after a selective rebuild no node exceeds its recorded cost by more than the threshold
            # unless it was kept (not topmost) — the recorded costs are finite
            assert np.isfinite(b.split_cost[inner]).all()


def test_refit_keeps_structure_and_selective_rebuilds_degraded_subtrees():
    s = scenario(2, 2048, seed=4)
    lo, hi = sphere_aabbs(s.sphere_centers, s.sphere_radii)
    rng = np.random.default_rng(1)
    b = build_bvh(lo, hi, 4)
    left0 = b.left.copy()
    c2 = rng.uniform(-20, 20, s.sphere_centers.shape)  # incoherent
    lo2, hi2 = sphere_aabbs(c2, s.sphere_radii)
    r = refit(b, lo2, hi2)
    np.testing.assert_array_equal(r.left, left0)
    check_bvh(r, lo2, hi2, 64)
    refit_cost = r.stats.sah_cost
    b = build_bvh(lo, hi, 4)
    sel = selective_rebuild(b, lo2, hi2, 0.3)
    check_bvh(sel, lo2, hi2, 64)
    assert sel.stats.rebuilt_subtrees >= 1
    assert sel.stats.sah_cost < 0.8 * refit_cost, "rebuilding the degraded subtrees restores quality"
    fresh = build_bvh(lo2, hi2, 4).stats.sah_cost
    assert sel.stats.sah_cost <= 1.5 * fresh
    # a small coherent motion rebuilds little or nothing
    b = build_bvh(lo, hi, 4)
    lo3, hi3 = sphere_aabbs(s.sphere_centers + 0.01, s.sphere_radii)
    sel = selective_rebuild(b, lo3, hi3, 0.3)
    assert sel.stats.rebuilt_primitives <= 0.05 * 2048
    costs = split_costs(sel)
    assert np.isfinite(costs[sel.left >= 0]).all()


def test_updater_rebuilds_on_topology_change_and_rejects_unknown_scheme():
    up = BVHUpdater(4)
    c = np.random.default_rng(0).uniform(-5, 5, (50, 3))
    up.update(c, np.ones(50), "refit")
    b = up.update(c[:40], np.ones(40), "refit")  # spheres disappeared
    assert b.n_primitives == 40 and "topology" in b.stats.scheme
    check_bvh(b, *sphere_aabbs(c[:40], np.ones(40)), 64)
    with pytest.raises(ValueError, match="scheme"):
        up.update(c, np.ones(50), "sometimes")


def test_bvh_build_is_fast_and_terminates_on_degenerate_input():
    s = scenario(3, 4096)
    t0 = time.process_time()  # CPU seconds: the machine's load does not stretch them
    b = build_bvh(*sphere_aabbs(s.sphere_centers, s.sphere_radii), 4)
    assert time.process_time() - t0 < 5.0
    assert b.stats.depth_max <= 64
    same = np.zeros((3000, 3))
    b = build_bvh(*sphere_aabbs(same, np.ones(3000)), 1)
    assert b.stats.median_splits > 0 and b.stats.depth_max <= 13
    b = build_bvh(*sphere_aabbs(same, np.ones(3000)), 1, max_tree_depth=3)
    assert b.stats.depth_max == 3 and b.stats.depth_limited_leaves == 4


def test_bvh_boxes_are_tight_where_the_bins_give_them():
    """Child boxes come from the bins' prefix and suffix boxes (not from their primitives):
    each must be exactly the union of its primitives' boxes, at any magnitude — boxes near
    ±1e38 (whose centroid sums and spreads overflow float32), mixed sizes, coincident ones."""
    rng = np.random.default_rng(20)
    cases = {
        "mixed": (rng.uniform(-50, 50, (3000, 3)), rng.uniform(0.01, 3, (3000, 1))),
        "huge": (rng.uniform(-3e38, 3e38, (500, 3)), rng.uniform(1e30, 1e36, (500, 1))),
        "clusters": (np.repeat(rng.uniform(-1, 1, (40, 3)), 25, axis=0), np.full((1000, 1), 0.5)),
    }
    for name, (c, r) in cases.items():
        lo = np.clip(c - r, -3.3e38, 3.3e38).astype(np.float32)
        hi = np.clip(c + r, -3.3e38, 3.3e38).astype(np.float32)
        b = build_bvh(lo, hi, 2)
        check_bvh(b, lo, hi, 64)
        for node in range(b.n_nodes):
            p = b.indices[b.first[node] : b.first[node] + b.count[node]]
            np.testing.assert_array_equal(b.bmin[node], lo[p].min(axis=0), err_msg=f"{name} node {node}")
            np.testing.assert_array_equal(b.bmax[node], hi[p].max(axis=0), err_msg=f"{name} node {node}")
        assert b.stats.leaves > len(lo) // 4, f"{name}: the bins found splits"

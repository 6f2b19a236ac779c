"""BIH build (renderer.accel.bih); its CPU traversal is tested in ``test_bih_traverse.py``.

- Table 4.2, scenario 1, bit-exact;
- structural invariants of the build over random and degenerate scenes;
- termination on degenerate input;
- the empty scene; bad build settings.

Pruning by the node intervals is exact only when every sphere lies inside its
float32 AABB; ``sphere_aabbs`` bounds both the float32 sphere (what the GPU
sees) and the float64 one (what the reference sees), checked by
``test_float64_sphere_inside_its_aabb``.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from renderer.accel import bih_layout as L
from renderer.accel.bih import build_bih, build_for_spheres, sphere_aabbs
from renderer.accel.bih_traverse import brute_force, traverse
from renderer.scenarios import scenario
from tests.helpers import HYP
from tests.renderer.accel.support import decode, scenes

# ---------------------------------------------------------------------------
# helpers

def walk(bih):
    """DFS from the root: per node the number of times it is reached, its depth
    (root = 1) and the tightest ancestor clip bounds: ``upper[node, axis]`` =
    min clip_left over ancestors where it lies left, ``lower`` = max clip_right
    over ancestors where it lies right."""
    leaf, axis, left, cl, cr, _, _ = decode(bih)
    m = len(bih.nodes)
    seen = np.zeros(m, dtype=np.int64)
    depth = np.zeros(m, dtype=np.int64)
    upper = np.full((m, 3), np.inf, dtype=np.float32)
    lower = np.full((m, 3), -np.inf, dtype=np.float32)
    stack = [0]
    depth[0] = 1
    while stack:
        k = stack.pop()
        seen[k] += 1
        if seen[k] > 1 or leaf[k]:
            continue
        lc = int(left[k])
        assert 1 <= lc and lc + 1 < m, f"node {k}: children {lc}, {lc + 1} out of range ({m} nodes)"
        a = int(axis[k])
        assert a in (0, 1, 2)
        for ch in (lc, lc + 1):
            depth[ch] = depth[k] + 1
            upper[ch] = upper[k]
            lower[ch] = lower[k]
        upper[lc, a] = min(upper[lc, a], cl[k])
        lower[lc + 1, a] = max(lower[lc + 1, a], cr[k])
        stack.extend([lc + 1, lc])
    return seen, depth, upper, lower


def check_invariants(bih, centers, radii, max_prims, max_tree_depth):
    n = len(radii)
    leaf, axis, left, cl, cr, off, cnt = decode(bih)
    m = len(bih.nodes)
    st_ = bih.stats
    seen, depth, upper, lower = walk(bih)

    # every node reachable exactly once, depths as stored, depth <= max
    assert (seen == 1).all(), f"nodes reached {seen.min()}..{seen.max()} times"
    assert np.array_equal(depth, bih.node_depths)
    assert depth.max() <= max_tree_depth

    # leaves tile the index array; indices is a permutation
    assert sorted(bih.indices.tolist()) == list(range(n))
    lv = np.flatnonzero(leaf)
    order = np.argsort(off[lv], kind="stable")
    o_s, c_s = off[lv][order], cnt[lv][order]
    ends = o_s + c_s
    if len(lv):
        assert o_s[0] == 0 and ends[-1] == n
        assert np.array_equal(o_s[1:], ends[:-1])
    # inner nodes never have empty children except through the leaf count of 0 for n = 0
    if n > 0:
        assert (c_s > 0).all(), "empty leaf"

    # primitives inside every ancestor's clip interval
    lo, hi = sphere_aabbs(centers, radii)
    for k in lv:
        p = bih.indices[off[k]:off[k] + cnt[k]]
        assert (hi[p] <= upper[k]).all(), f"leaf {k}: AABB max beyond an ancestor's clip_left"
        assert (lo[p] >= lower[k]).all(), f"leaf {k}: AABB min below an ancestor's clip_right"

    # oversized leaves: at the depth limit, or forced (and then counted)
    big = leaf & (cnt > max_prims)
    assert int((big & (depth < max_tree_depth)).sum()) == st_.forced_leaves

    # statistics
    assert st_.primitives == n
    assert st_.leaves == int(leaf.sum()) and st_.inner_nodes == m - st_.leaves
    assert st_.leaves == st_.inner_nodes + 1
    assert st_.bytes == m * L.NODE_BYTES + 4 * n + 24
    assert st_.depth_max == int(depth[lv].max()) and st_.depth_min == int(depth[lv].min())
    assert st_.depth_avg == pytest.approx(depth[lv].mean())
    assert st_.prims_per_leaf_max == cnt[lv].max() and st_.prims_per_leaf_min == cnt[lv].min()
    assert st_.prims_per_leaf_avg * st_.leaves == pytest.approx(n)
    assert sum(st_.leaf_histogram) == pytest.approx(1.0)
    if n:
        assert np.array_equal(bih.global_aabb, np.stack([lo.min(axis=0), hi.max(axis=0)]))


# ---------------------------------------------------------------------------
# build

def test_table_4_2_scenario_1():
    sc = scenario(1, 4096)
    s1 = build_for_spheres(sc.sphere_centers, sc.sphere_radii, max_prims=1).stats
    assert (s1.inner_nodes, s1.leaves) == (4095, 4096)
    assert (s1.depth_min, s1.depth_avg, s1.depth_max) == (13, 13.0, 13)
    s8 = build_for_spheres(sc.sphere_centers, sc.sphere_radii, max_prims=8).stats
    assert (s8.inner_nodes, s8.leaves) == (511, 512)
    assert (s8.depth_min, s8.depth_avg, s8.depth_max) == (10, 10.0, 10)
    assert s8.prims_per_leaf_min == s8.prims_per_leaf_max == 8


@settings(max_examples=100, **HYP)
@given(scene=scenes(), max_prims=st.integers(1, 16), max_tree_depth=st.integers(1, 64))
def test_build_invariants(scene, max_prims, max_tree_depth):
    c, r = scene
    bih = build_for_spheres(c, r, max_prims=max_prims, max_tree_depth=max_tree_depth)
    check_invariants(bih, c, r, max_prims, max_tree_depth)


@pytest.mark.parametrize("max_prims", [1, 8])
def test_degenerate_terminates(max_prims):
    c = np.full((10_000, 3), 3.25)
    r = np.ones(10_000)
    t0 = time.perf_counter()
    bih = build_for_spheres(c, r, max_prims=max_prims)
    assert time.perf_counter() - t0 < 5.0
    assert bih.stats.forced_leaves >= 1
    check_invariants(bih, c, r, max_prims, 64)


def test_empty_scene():
    bih = build_for_spheres(np.zeros((0, 3)), np.zeros(0))
    check_invariants(bih, np.zeros((0, 3)), np.zeros(0), 8, 64)
    res = traverse(bih, np.zeros((0, 3)), np.zeros(0), np.zeros((2, 3)), np.array([[0, 0, 1.0], [1.0, 0, 0]]))
    assert np.isinf(res.t).all() and (res.prim == -1).all() and (res.nodes_visited == 0).all()


# ---------------------------------------------------------------------------
# regression: a float64 sphere whose centre is not float32-representable used
# to stick out of its box by up to one float32 step, and the float64 traversal
# then pruned a hit that brute force finds

def test_float64_sphere_inside_its_aabb():
    c = np.array([[2.0**20 + 0.0625 + 1e-9, 0.0, 0.0]])
    r = np.array([0.15])
    lo, _ = sphere_aabbs(c, r)
    bih = build_for_spheres(c, r, max_prims=1)
    o, d = np.array([[1048575.92, -5.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
    res = traverse(bih, c, r, o, d)
    bt, bp = brute_force(c, r, o, d)
    assert bp[0] == 0  # the ray passes 0.1425 from the centre of a sphere of radius 0.15
    assert float(lo[0, 0]) <= c[0, 0] - r[0] and res.prim[0] == bp[0]


def test_build_bih_rejects_bad_settings():
    lo, hi = sphere_aabbs(np.zeros((2, 3)), np.ones(2))
    with pytest.raises(ValueError):
        build_bih(lo, hi, max_prims=0)
    with pytest.raises(ValueError):
        build_bih(lo, hi, max_tree_depth=65)

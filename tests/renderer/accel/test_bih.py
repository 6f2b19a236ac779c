"""BIH build (renderer.accel.bih); its CPU traversal is tested in ``test_bih_traverse.py``.

- Table 4.2, scenario 1, bit-exact;
- structural invariants of the build over random and degenerate scenes, with and without
  the empty-space cuts (step 0; the trees over triangles), and that the cuts leave no leaf
  a cut worth making;
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
from hypothesis import given, settings, strategies as st

from renderer.accel import bih_layout as L
from renderer.accel.bih import EMPTY_CUT_AREA, build_bih, build_for_scene, build_for_spheres, sphere_aabbs
from renderer.accel.bih_traverse import brute_force, traverse
from renderer.geometry.meshes import icosphere, teapot
from renderer.oracle.reference import primary_rays
from renderer.scenes.scenarios import scenario
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


def check_invariants(bih, centers, radii, max_prims, max_tree_depth, boxes=None):
    """The build's invariants; ``boxes`` (lo, hi): the primitives' boxes when not spheres'."""
    n = len(radii) if boxes is None else len(boxes[0])
    leaf, axis, left, cl, cr, off, cnt = decode(bih)
    m = len(bih.nodes)
    st_ = bih.stats
    seen, depth, upper, lower = walk(bih)

    # every node reachable exactly once, depths as stored, depth <= max
    assert (seen == 1).all(), f"nodes reached {seen.min()}..{seen.max()} times"
    assert np.array_equal(depth, bih.node_depths)
    assert depth.max() <= max_tree_depth

    # a cut's empty child: a leaf of no primitives behind a clip plane at ±EMPTY_CLIP, its
    # sibling holding the node's primitives; no other empty leaf (but the root of n = 0)
    empty = leaf & (cnt == 0)
    if n > 0:
        assert not empty[0]
        for k in np.flatnonzero(~leaf):
            lc = int(left[k])
            if empty[lc]:
                assert not empty[lc + 1] and cl[k] == -np.float32(L.EMPTY_CLIP), f"node {k}: empty left child"
            if empty[lc + 1]:
                assert not empty[lc] and cr[k] == np.float32(L.EMPTY_CLIP), f"node {k}: empty right child"
        parent_of_empty = int(empty.sum())
        assert parent_of_empty == st_.cut_nodes

    # leaves tile the index array; indices is a permutation
    assert sorted(bih.indices.tolist()) == list(range(n))
    lv = np.flatnonzero(leaf & ~empty) if n > 0 else np.flatnonzero(leaf)
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
    lo, hi = sphere_aabbs(centers, radii) if boxes is None else boxes
    for k in lv:
        p = bih.indices[off[k] : off[k] + cnt[k]]
        assert (hi[p] <= upper[k]).all(), f"leaf {k}: AABB max beyond an ancestor's clip_left"
        assert (lo[p] >= lower[k]).all(), f"leaf {k}: AABB min below an ancestor's clip_right"

    # oversized leaves: at the depth limit, or forced (and then counted)
    big = leaf & (cnt > max_prims)
    assert int((big & (depth < max_tree_depth)).sum()) == st_.forced_leaves

    # statistics
    assert st_.primitives == n
    assert st_.leaves == len(lv) and st_.inner_nodes == m - st_.leaves - st_.cut_nodes
    assert st_.leaves == st_.inner_nodes - st_.cut_nodes + 1
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


@settings(max_examples=100, **HYP)
@given(scene=scenes(), max_prims=st.integers(1, 16), max_tree_depth=st.integers(1, 64))
def test_build_invariants_with_empty_cuts(scene, max_prims, max_tree_depth):
    c, r = scene
    bih = build_bih(*sphere_aabbs(c, r), max_prims=max_prims, max_tree_depth=max_tree_depth, empty_cuts=True)
    check_invariants(bih, c, r, max_prims, max_tree_depth)
    assert np.array_equal(np.sort(bih.indices), np.arange(len(r)))


def test_sphere_trees_have_no_cuts():
    """build_for_scene cuts empty space only with triangles: a sphere scene keeps the thesis's tree."""
    sc = scenario(2, 1024)
    bih = build_for_scene(sc)
    thesis = build_for_spheres(sc.sphere_centers, sc.sphere_radii)
    assert bih.stats.cut_nodes == 0
    assert np.array_equal(bih.nodes, thesis.nodes) and np.array_equal(bih.indices, thesis.indices)


def _regions(bih):
    """Every node's region: the global box clipped by its ancestors' planes (float32)."""
    _, _, upper, lower = walk(bih)
    g = bih.global_aabb
    return np.maximum(lower, g[0]), np.minimum(upper, g[1])


@pytest.mark.parametrize("max_prims", [1, 8])
def test_empty_cuts_over_triangles(max_prims):
    """A tessellated surface (a teapot and a tilted icosphere): the tree over the triangles'
    boxes holds its invariants, no leaf above the depth limit is left a cut worth making
    (step 0's rule, evaluated on its region and its primitives' tight box), and the cuts
    take most of the triangle tests off primary rays, traced exactly."""
    pot = teapot(8, smooth=False)
    ico = icosphere(3, radius=1.5, center=(4.0, 1.0, 0.5))
    corners = np.concatenate([pot.vertices[pot.triangles], ico.vertices[ico.triangles]])
    from renderer.accel.primitives import triangle_aabbs

    lo, hi = triangle_aabbs(corners)
    bih = build_bih(lo, hi, max_prims=max_prims, empty_cuts=True)
    check_invariants(bih, None, None, max_prims, 64, boxes=(lo, hi))
    assert bih.stats.cut_nodes > 0

    leaf, _, _, _, _, off, cnt = decode(bih)
    rmin, rmax = _regions(bih)
    for k in np.flatnonzero(leaf & (cnt > 0) & (bih.node_depths < 64)):
        p = bih.indices[off[k] : off[k] + cnt[k]]
        tmin, tmax = lo[p].min(axis=0), hi[p].max(axis=0)
        assert (rmin[k] <= tmin).all() and (tmax <= rmax[k]).all()
        ext = (rmax[k] - rmin[k]).astype(np.float64)
        gap = np.maximum((tmin - rmin[k]).astype(np.float64), (rmax[k] - tmax).astype(np.float64))
        gain = gap * (ext.sum() - ext)
        half_area = ext[0] * ext[1] + ext[1] * ext[2] + ext[2] * ext[0]
        assert gain.max() <= EMPTY_CUT_AREA * half_area, f"leaf {k}: a cut of {gain.max() / half_area:.2f} left"

    # primary rays at a teapot-like view: exact, and far fewer tests than without cuts
    from renderer.geometry.scene import Camera

    cam = Camera((2.0, 4.0, 9.0), (1.5, 0.8, 0.0), (0.0, 1.0, 0.0), 40.0)
    o, d = primary_rays(cam, 48, 40)
    none = (np.zeros((0, 3)), np.zeros(0))
    res = traverse(bih, *none, o, d, triangles=corners)
    bt, bp = brute_force(*none, o, d, triangles=corners)
    assert np.array_equal(res.prim, bp) and np.array_equal(res.t.view(np.int64), bt.view(np.int64))
    assert (bp >= 0).mean() > 0.2
    thesis = traverse(build_bih(lo, hi, max_prims=max_prims), *none, o, d, triangles=corners)
    assert np.array_equal(thesis.prim, bp)
    assert res.tests.mean() < 0.5 * thesis.tests.mean()


@pytest.mark.parametrize("max_prims", [1, 8])
def test_degenerate_terminates(max_prims):
    c = np.full((10_000, 3), 3.25)
    r = np.ones(10_000)
    t0 = time.process_time()  # CPU seconds: the machine's load does not stretch them
    bih = build_for_spheres(c, r, max_prims=max_prims)
    assert time.process_time() - t0 < 5.0
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

"""Methods ``bvh`` and ``kdtree`` (issue #9): tree invariants and exactness on the GPU.

- property tests (hypothesis) of both builds over random and degenerate scenes:
  every BVH node box holds its children and its primitives, each primitive is in
  exactly one leaf, depth within the limit — after the build and after any number
  of refits and selective rebuilds under random motion, incoherent included; every
  kd-tree primitive that straddles a plane is in both children, every primitive
  whose box meets a leaf's voxel is in that leaf (so every primitive is reachable);
- the layout constants of the shaders equal the Python layout modules;
- the GLSL tracer with ``bvh`` and ``kdtree`` against brute force (primid ≥ 99.99 %)
  and the float64 reference (primid ≥ 99.9 %, colour PSNR ≥ 40 dB), scenarios 1–3,
  n = 64 and 1024, recursion depth 1 and 5, 96 × 160;
- a BVH refitted after an incoherent motion (every sphere teleported) renders the
  same ids as brute force: slow perhaps, never wrong.
"""

from __future__ import annotations

import re
import time

import numpy as np
import pytest

from renderer.shader_source import tracer_source as shader_source
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from renderer.accel import bvh_layout, kdtree_layout
from renderer.accel.bih import sphere_aabbs
from renderer.accel.bvh import (BVHUpdater, build_bvh, near_masks, refit, selective_rebuild,
                          split_costs)
from renderer.accel.kdtree import build_kdtree
from renderer.methods import METHODS
from renderer.reference import render_reference
from renderer.scenarios import scenario
from renderer.scene import Scene
from renderer.settings import RenderSettings
from tests.helpers import ROOT

HYP = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
W, H = 96, 160


# ------------------------------------------------------------------------- scenes

@st.composite
def sphere_sets(draw, max_n: int = 120):
    """Random, clustered and degenerate sphere sets (centres, radii)."""
    n = draw(st.integers(0, max_n))
    kind = draw(st.sampled_from(["uniform", "clustered", "one_centre", "duplicates", "line", "scales"]))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
    if kind == "uniform":
        c = rng.uniform(-20, 20, (n, 3))
        r = rng.uniform(0.05, 3.0, n)
    elif kind == "clustered":
        c = rng.normal(0, 1, (n, 3)) * rng.choice([0.01, 1.0, 10.0], (n, 1)) + rng.choice([-15.0, 15.0], (n, 3))
        r = rng.uniform(0.01, 1.0, n)
    elif kind == "one_centre":
        c = np.broadcast_to(rng.uniform(-5, 5, 3), (n, 3)).copy()
        r = rng.uniform(0.5, 4.0, n)
    elif kind == "duplicates":
        base = rng.uniform(-10, 10, ((n + 1) // 2, 3))
        c = np.concatenate([base, base])[:n]
        r = np.full(n, 1.0)
    elif kind == "line":
        c = np.zeros((n, 3))
        c[:, 0] = np.linspace(-10, 10, n)
        r = np.full(n, 0.5)
    else:
        c = rng.uniform(-1, 1, (n, 3)) * 10.0 ** rng.integers(-3, 4, (n, 1))
        r = 10.0 ** rng.uniform(-3, 2, n)
    return c, r


def motion(c: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
    if kind == "rigid":
        return c + rng.uniform(-5, 5, 3)
    if kind == "deformable":
        return c + rng.normal(0, 0.3, c.shape)
    return rng.uniform(-30, 30, c.shape)          # incoherent: every sphere teleports


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
    pos = np.concatenate([np.arange(f, f + c) for f, c in zip(b.first[leaves], b.count[leaves])])
    p = b.indices[pos]
    assert (lo[p] >= b.bmin[slot_leaf]).all() and (hi[p] <= b.bmax[slot_leaf]).all(), "leaf box holds its spheres"
    assert (b.near_mask[leaves] == 0).all()
    np.testing.assert_array_equal(b.near_mask, near_masks(b.bmin, b.bmax, b.left))
    # the GPU words say the same
    u = bvh_layout.unpack_nodes(b.texels())
    np.testing.assert_array_equal(u["left"], b.left)
    np.testing.assert_array_equal(u["bmin"], b.bmin)
    np.testing.assert_array_equal(u["bmax"], b.bmax)
    np.testing.assert_array_equal(u["count"][leaves], b.count[leaves])
    np.testing.assert_array_equal(u["first"][leaves], b.first[leaves])
    np.testing.assert_array_equal(u["near_mask"], b.near_mask)


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
@given(sphere_sets(max_n=100), st.integers(1, 8), st.integers(2, 64),
       st.lists(st.sampled_from(["rigid", "deformable", "incoherent"]), min_size=1, max_size=4),
       st.sampled_from(["refit", "selective"]), st.integers(0, 2 ** 31))
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
    c2 = rng.uniform(-20, 20, s.sphere_centers.shape)      # incoherent
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
    b = up.update(c[:40], np.ones(40), "refit")            # spheres disappeared
    assert b.n_primitives == 40 and "topology" in b.stats.scheme
    check_bvh(b, *sphere_aabbs(c[:40], np.ones(40)), 64)
    with pytest.raises(ValueError, match="scheme"):
        up.update(c, np.ones(50), "sometimes")


def test_bvh_build_is_fast_and_terminates_on_degenerate_input():
    s = scenario(3, 4096)
    t0 = time.perf_counter()
    b = build_bvh(*sphere_aabbs(s.sphere_centers, s.sphere_radii), 4)
    assert time.perf_counter() - t0 < 5.0
    assert b.stats.depth_max <= 64
    same = np.zeros((3000, 3))
    b = build_bvh(*sphere_aabbs(same, np.ones(3000)), 1)
    assert b.stats.median_splits > 0 and b.stats.depth_max <= 13
    b = build_bvh(*sphere_aabbs(same, np.ones(3000)), 1, max_tree_depth=3)
    assert b.stats.depth_max == 3 and b.stats.depth_limited_leaves == 4


# ------------------------------------------------------------- kd-tree invariants

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
    for l in leaves:
        p = kd.leaf_prims(l)
        assert (np.diff(p) > 0).all(), "leaf lists are sorted, without repeats"
        assert kd.offset[l] + kd.count[l] <= len(kd.indices)
    sets = kd_node_sets(kd)
    if n:
        assert sets[0] == set(range(n)), "every primitive reachable"
        # completeness: a primitive whose box meets a leaf's open voxel is in that leaf
        for l in leaves:
            meets = np.flatnonzero(((lo < kd.vmax[l]) & (hi > kd.vmin[l])).all(axis=1))
            assert set(meets.tolist()) <= sets[l], f"leaf {l} misses primitives of its voxel"
        # a straddler is in both children
        for i in inner:
            a, p = kd.axis[i], kd.split[i]
            straddle = {j for j in sets[i] if lo[j, a] < p < hi[j, a]}
            assert straddle <= sets[kd.left[i]] and straddle <= sets[kd.left[i] + 1]
    u = kdtree_layout.unpack_nodes(kd.words())
    np.testing.assert_array_equal(u["axis"], kd.axis)
    np.testing.assert_array_equal(u["left"][inner], kd.left[inner])
    np.testing.assert_array_equal(u["split"][inner], kd.split[inner])
    np.testing.assert_array_equal(u["count"][leaves], kd.count[leaves])
    np.testing.assert_array_equal(u["offset"][leaves], kd.offset[leaves])


@settings(max_examples=40, **HYP)
@given(sphere_sets(max_n=90), st.integers(1, 64), st.sampled_from([1.0, 0.9, 0.5, 0.1]),
       st.sampled_from([0, 4, 1000]))
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
    t0 = time.perf_counter()
    kd = build_kdtree(*sphere_aabbs(same, np.linspace(0.5, 4, 2000)), cost_scale=1.0)
    assert time.perf_counter() - t0 < 10.0
    assert kd.stats.references <= 64 * 2000 + 1024


# ------------------------------------------------------------------ shader layout

@pytest.mark.parametrize("name,module", [("bvh", bvh_layout), ("kdtree", kdtree_layout)])
def test_shader_gets_layout_constants_from_python(name, module):
    """The one definition of each layout reaches the shader through the host header."""
    src = shader_source(name, "color", 1)
    for line in module.glsl_defines().splitlines():
        assert line in src
    method_src = (ROOT / "shaders" / f"method_{name}.glsl").read_text()
    for line in module.glsl_defines().splitlines():  # no second copy of the constants in the method file
        assert line.split()[1] not in re.findall(r"#define (\w+)", method_src)


def test_methods_registered():
    assert {"bvh", "kdtree"} <= set(METHODS)
    RenderSettings(method="bvh")
    RenderSettings(method="kdtree")


# --------------------------------------------------------------------------- GPU

def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


_REF: dict = {}


def reference(sc: int, n: int, depth: int):
    if (sc, n, depth) not in _REF:
        _REF[(sc, n, depth)] = render_reference(
            scenario(sc, n), RenderSettings(width=W, height=H, max_recursion_depth=depth, method="bruteforce"))
    return _REF[(sc, n, depth)]


@pytest.mark.parametrize("depth", [1, 5])
@pytest.mark.parametrize("sc,n", [(sc, n) for sc in (1, 2, 3) for n in (64, 1024)])
def test_gpu_bvh_kdtree_exact(gl_renderer, sc, n, depth):
    scene = scenario(sc, n)
    ref = reference(sc, n, depth)
    base = RenderSettings(width=W, height=H, max_recursion_depth=depth, max_prims=4)
    bf = gl_renderer.render(scene, base.with_(method="bruteforce"))
    for method in ("bvh", "kdtree"):
        g = gl_renderer.render(scene, base.with_(method=method))
        assert np.isfinite(g.image).all()
        agree_bf = (g.primid == bf.primid).mean()
        assert agree_bf >= 0.9999, f"{method}: ids agree with brute force on {agree_bf:.6f}"
        agree_ref = (g.primid == ref.primid).mean()
        assert agree_ref >= 0.999, f"{method}: ids agree with the reference on {agree_ref:.5f}"
        p = psnr(g.image_u8(), ref.image_u8())
        assert p >= 40.0, f"{method}: colour PSNR {p:.1f} dB < 40"
        assert g.stats["method"] == method


def test_gpu_refit_after_incoherent_motion_is_exact(gl_renderer):
    """Refit keeps a tree valid whatever the motion: ids equal brute force frame after frame."""
    rng = np.random.default_rng(5)
    s0 = scenario(2, 512, seed=2)
    base = RenderSettings(width=W, height=H, max_recursion_depth=3, max_prims=4)
    for scheme in ("refit", "selective"):
        c = s0.sphere_centers
        for frame in range(3):
            scene = Scene(s0.camera, s0.lights, s0.materials, c, s0.sphere_radii, s0.sphere_materials, s0.planes)
            g = gl_renderer.render(scene, base.with_(method="bvh", update=scheme), key=("teleport", scheme))
            bf = gl_renderer.render(scene, base.with_(method="bruteforce"))
            agree = (g.primid == bf.primid).mean()
            assert agree >= 0.9999, f"{scheme}, frame {frame}: {agree:.6f}"
            if frame:
                assert g.stats["scheme"] == scheme
            c = rng.uniform(-20, 20, c.shape)      # every sphere teleports

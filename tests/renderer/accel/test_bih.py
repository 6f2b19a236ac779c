"""BIH build (renderer.accel.bih) and CPU traversal (renderer.accel.bih_traverse).

- Table 4.2, scenario 1, bit-exact;
- structural invariants of the build over random and degenerate scenes;
- termination on degenerate input;
- traversal == brute force (same (t, prim), t bitwise) over random scenes and
  adversarial rays, plus the heat-mode counters.

Pruning by the node intervals is exact only when every sphere lies inside its
float32 AABB; ``sphere_aabbs`` bounds both the float32 sphere (what the GPU
sees) and the float64 one (what the reference sees), checked by
``test_float64_sphere_inside_its_aabb``.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from renderer.accel import bih_layout as L
from renderer.accel.bih import build_bih, build_for_spheres, sphere_aabbs
from renderer.accel.bih_traverse import brute_force, traverse
from renderer.scenarios import scenario

HYP = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# ---------------------------------------------------------------------------
# helpers

def decode(bih):
    w0 = bih.nodes[:, 0]
    leaf = L.is_leaf(w0)
    axis = L.axis_of(w0)
    left = L.left_child(w0)
    cl, cr = L.clips(bih.nodes)
    off = bih.nodes[:, 1].astype(np.int64)
    cnt = bih.nodes[:, 2].astype(np.int64)
    return leaf, axis, left, cl, cr, off, cnt


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
# scalar oracle: SHADING.md's pseudo-code transcribed one ray at a time

def _sphere_scalar(o, d, c, r, far_only):
    px, py, pz = o[0] - c[0], o[1] - c[1], o[2] - c[2]
    b = px * d[0] + py * d[1] + pz * d[2]
    fx, fy, fz = px - b * d[0], py - b * d[1], pz - b * d[2]
    h2 = r * r - (fx * fx + fy * fy + fz * fz)
    if h2 < 0.0:
        return math.inf
    h = math.sqrt(h2)
    if not far_only and -b - h > 0.0:
        return -b - h
    return -b + h if -b + h > 0.0 else math.inf


def traverse_scalar(bih, c, r, o, d, ignore=-1, far_only=-1):
    """(t, prim, nodes_visited, gaps, tests) of one ray, literally as SHADING.md says."""
    o = [float(x) for x in o]
    d = [float(x) for x in d]
    best_t, best_p = math.inf, -1
    visited = gaps = tests = 0
    if len(r) == 0:
        return best_t, best_p, visited, gaps, tests
    leaf, axis, left, cl, cr, off, cnt = decode(bih)
    lo, hi = bih.global_aabb.astype(np.float64)
    t0, t1 = 0.0, math.inf
    for k in range(3):
        if d[k] == 0.0:
            if o[k] < lo[k] or o[k] > hi[k]:
                return best_t, best_p, visited, gaps, tests
        else:
            ta, tb = (float(lo[k]) - o[k]) / d[k], (float(hi[k]) - o[k]) / d[k]
            if d[k] < 0.0:
                ta, tb = tb, ta
            t0, t1 = max(t0, ta), min(t1, tb)
    if not t0 <= t1:
        return best_t, best_p, visited, gaps, tests
    stack = [(0, t0, t1)]
    while stack:
        node, a, b = stack.pop()
        if a > best_t:
            continue
        while True:
            visited += 1
            if leaf[node]:
                tests += int(cnt[node])
                for i in range(int(off[node]), int(off[node] + cnt[node])):
                    p = int(bih.indices[i])
                    if p == ignore:
                        continue
                    t = _sphere_scalar(o, d, c[p], float(r[p]), p == far_only)
                    if t < best_t or (t == best_t and t < math.inf and p < best_p):
                        best_t, best_p = t, p
                break
            ax, lc = int(axis[node]), int(left[node])
            cL, cR = float(cl[node]), float(cr[node])
            if d[ax] == 0.0:
                near = (lc, a, b) if o[ax] <= cL else None
                far = (lc + 1, a, b) if o[ax] >= cR else None
            else:
                tL, tR = (cL - o[ax]) / d[ax], (cR - o[ax]) / d[ax]
                if d[ax] > 0.0:
                    near, far = (lc, a, min(b, tL)), (lc + 1, max(a, tR), b)
                else:
                    near, far = (lc + 1, a, min(b, tR)), (lc, max(a, tL), b)
                near = near if near[1] <= near[2] else None
                far = far if far[1] <= far[2] else None
            if near is None and far is None:
                gaps += 1
                break
            if near is not None and near[1] > best_t:
                near = None
            if far is not None and far[1] > best_t:
                far = None
            if near is not None and far is not None:
                stack.append(far)
                node, a, b = near
            elif near is not None or far is not None:
                node, a, b = near or far
            else:
                break
    return best_t, best_p, visited, gaps, tests


# ---------------------------------------------------------------------------
# scenes

SCALES = [1e-3, 1.0, 20.0, 1e6]
SPECIALS = [0.0, 1.0, -1.0, 0.5, -0.5, 2.0, 1e-3, -1e-3]


@st.composite
def scenes(draw, max_n=300, f32=False):
    n = draw(st.integers(0, max_n))
    kind = draw(st.sampled_from(["uniform", "same", "dups", "line", "grid", "specials", "cluster"]))
    scale = draw(st.sampled_from(SCALES))
    shift = draw(st.sampled_from([0.0, 0.0, 1e6, -20.0]))
    rkind = draw(st.sampled_from(["const", "uniform", "loguniform"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if kind == "uniform":
        c = rng.uniform(-scale, scale, (n, 3))
    elif kind == "same":
        c = np.broadcast_to(rng.uniform(-scale, scale, 3), (n, 3)).copy()
    elif kind == "dups":
        pts = rng.uniform(-scale, scale, (draw(st.integers(1, 5)), 3))
        c = pts[rng.integers(0, len(pts), n)]
    elif kind == "line":
        p0 = rng.uniform(-scale, scale, 3)
        dirn = draw(st.sampled_from([np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([1.0, 1.0, 1.0]),
                                     rng.normal(size=3)]))
        c = p0 + rng.uniform(-scale, scale, (n, 1)) * dirn
    elif kind == "grid":
        c = rng.integers(-4, 5, (n, 3)) * (scale / 4)
    elif kind == "specials":
        c = rng.choice(np.array(SPECIALS) * scale, (n, 3))
    else:  # a dense cluster far from the origin
        c = rng.normal(size=(n, 3)) * scale * 1e-3
    c = c + shift
    if rkind == "const":
        r = np.full(n, draw(st.sampled_from([1e-3, 1.0, scale, 0.1 * scale])))
    elif rkind == "uniform":
        r = rng.uniform(1e-3, max(2e-3, 0.2 * scale), n)
    else:
        r = 10.0 ** rng.uniform(-3, np.log10(max(1.0, scale)), n)
    if f32:
        c = c.astype(np.float32).astype(np.float64)
        r = r.astype(np.float32).astype(np.float64)
    return c, r


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
# traversal

def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _signed_zero_axis_dirs(rng, k):
    """k axis-aligned unit directions with explicit +0.0 / -0.0 components."""
    d = np.where(rng.random((k, 3)) < 0.5, 0.0, -0.0)
    ax = rng.integers(0, 3, k)
    d[np.arange(k), ax] = rng.choice([1.0, -1.0], k)
    return d


def make_rays(bih, c, r, rng, per_kind):
    """Adversarial rays: list of (origins, dirs, ignore, far_only)."""
    n = len(r)
    k = per_kind
    box = bih.global_aabb.astype(np.float64)
    if n == 0:
        box = np.array([[-1.0] * 3, [1.0] * 3])
    lo, hi = box
    ext = float(np.max(hi - lo)) + 1.0
    inside = lambda m: lo + rng.random((m, 3)) * (hi - lo)  # noqa: E731
    none = lambda m: np.full(m, -1, dtype=np.int64)  # noqa: E731
    out = []
    # 1. from outside, aimed at sphere centres / points of the box
    tgt = c[rng.integers(0, n, k)] if n else inside(k)
    tgt = np.where(rng.random((k, 1)) < 0.5, tgt, inside(k))
    dirs = _unit(rng.normal(size=(k, 3)))
    out.append((tgt - 3.0 * ext * dirs, dirs, none(k), none(k)))
    # 2. from inside the global box, random directions
    out.append((inside(k), _unit(rng.normal(size=(k, 3))), none(k), none(k)))
    # 3. axis-aligned with signed zeros, through sphere centres or random points
    o = inside(k)
    if n:
        o = np.where(rng.random((k, 1)) < 0.6, c[rng.integers(0, n, k)], o)
    d = _signed_zero_axis_dirs(rng, k)
    back = rng.random(k) < 0.5  # start outside the box, behind along d
    o = np.where(back[:, None], o - 2.0 * ext * d, o)
    out.append((o, d, none(k), none(k)))
    # 4. one zero component (±0), the others random
    d = rng.normal(size=(k, 3))
    z = rng.integers(0, 3, k)
    d[np.arange(k), z] = np.where(rng.random(k) < 0.5, 0.0, -0.0)
    out.append((inside(k), _unit(d), none(k), none(k)))
    # 5. origins exactly on clip planes, parallel to them or not
    leaf, axis, left, cl, cr, _, _ = decode(bih)
    inner = np.flatnonzero(~leaf)
    if len(inner):
        nd = inner[rng.integers(0, len(inner), k)]
        ax = axis[nd]
        o = inside(k)
        if n:
            o = np.where(rng.random((k, 1)) < 0.5, c[rng.integers(0, n, k)], o)
        o[np.arange(k), ax] = np.where(rng.random(k) < 0.5, cl[nd], cr[nd]).astype(np.float64)
        d = _unit(rng.normal(size=(k, 3)))
        par = rng.random(k) < 0.5
        d[par, ax[par]] = np.where(rng.random(par.sum()) < 0.5, 0.0, -0.0)
        d = _unit(d)
        ax2 = rng.random(k) < 0.3
        d[ax2] = _signed_zero_axis_dirs(rng, int(ax2.sum()))
        d[ax2 & par, :] = 0.0
        d[ax2 & par, (ax[ax2 & par] + 1) % 3] = 1.0
        out.append((o, d, none(k), none(k)))
    # 6. secondary rays leaving a sphere's surface (SHADING.md's exclusion rules)
    if n:
        s = rng.integers(0, n, k)
        nrm = _unit(rng.normal(size=(k, 3)))
        o = c[s] + r[s, None] * nrm
        d = _unit(rng.normal(size=(k, 3)))
        leaving = np.sum(d * nrm, axis=1) >= 0.0
        out.append((o, d, np.where(leaving, s, -1), np.where(leaving, -1, s)))
    return out


def check_traversal(scene, max_prims, max_tree_depth, seed, per_kind=10, oracle=True):
    c, r = scene
    bih = build_for_spheres(c, r, max_prims=max_prims, max_tree_depth=max_tree_depth)
    rng = np.random.default_rng(seed)
    parts = make_rays(bih, c, r, rng, per_kind)
    o = np.concatenate([p[0] for p in parts])
    d = np.concatenate([p[1] for p in parts])
    ign = np.concatenate([p[2] for p in parts])
    far = np.concatenate([p[3] for p in parts])
    res = traverse(bih, c, r, o, d, ignore=ign, far_only=far)
    bt, bp = brute_force(c, r, o, d, ignore=ign, far_only=far)
    bad = (res.prim != bp) | (res.t.view(np.int64) != bt.view(np.int64))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise AssertionError(
            f"{int(bad.sum())} of {len(o)} rays differ; first: o={o[i].tolist()} d={d[i].tolist()} "
            f"ignore={ign[i]} far_only={far[i]}: traverse ({res.t[i]!r}, {res.prim[i]}) "
            f"brute ({bt[i]!r}, {bp[i]})")
    assert res.t.dtype == np.float64 and res.prim.dtype == np.int64
    if oracle:
        for i in range(len(o)):
            want = traverse_scalar(bih, c, r, o[i], d[i], int(ign[i]), int(far[i]))
            got = (res.t[i], res.prim[i], res.nodes_visited[i], res.gaps[i], res.tests[i])
            assert got == want, f"ray {i} o={o[i].tolist()} d={d[i].tolist()}: {got} != oracle {want}"
    # counters: nothing visited without the global box, a visit per test batch
    box_hit = res.nodes_visited > 0
    assert (res.tests[~box_hit] == 0).all() and (res.gaps[~box_hit] == 0).all()
    assert (res.prim[~box_hit] == -1).all()
    assert (res.tests <= len(r) * np.maximum(res.nodes_visited, 1)).all()
    assert (res.gaps <= res.nodes_visited).all()


@settings(max_examples=100, **HYP)
@given(scene=scenes(f32=True), max_prims=st.integers(1, 16), max_tree_depth=st.integers(1, 64),
       seed=st.integers(0, 2**32 - 1))
def test_traverse_matches_brute_force(scene, max_prims, max_tree_depth, seed):
    check_traversal(scene, max_prims, max_tree_depth, seed)


@pytest.mark.slow
@settings(max_examples=5000, **HYP)
@given(scene=scenes(f32=True), max_prims=st.integers(1, 16), max_tree_depth=st.integers(1, 64),
       seed=st.integers(0, 2**32 - 1))
def test_traverse_matches_brute_force_slow(scene, max_prims, max_tree_depth, seed):
    check_traversal(scene, max_prims, max_tree_depth, seed)


def _camera_rays(sc, w, h):
    right, up, fwd = sc.camera.basis()
    s = np.tan(np.radians(sc.camera.fov_y) / 2)
    x, y = np.meshgrid(np.arange(w), np.arange(h))
    u = ((2 * (x + 0.5) / w - 1) * s * w / h).reshape(-1, 1)
    v = ((1 - 2 * (y + 0.5) / h) * s).reshape(-1, 1)
    d = _unit(fwd + u * right + v * up)
    return np.broadcast_to(np.asarray(sc.camera.position, dtype=np.float64), d.shape), d


@pytest.mark.parametrize("number", [1, 2, 3])
@pytest.mark.parametrize("max_prims", [1, 8])
def test_scenarios_match_brute_force(number, max_prims):
    sc = scenario(number, 512)
    c, r = sc.sphere_centers, sc.sphere_radii
    bih = build_for_spheres(c, r, max_prims=max_prims)
    o, d = _camera_rays(sc, 48, 64)
    # aim a second batch at the cube so that most rays enter the hierarchy
    rng = np.random.default_rng(number)
    o2 = np.broadcast_to(o[0], (2000, 3))
    d2 = _unit(rng.uniform(-20, 20, (2000, 3)) - o2)
    o, d = np.concatenate([o, o2]), np.concatenate([d, d2])
    res = traverse(bih, c, r, o, d)
    bt, bp = brute_force(c, r, o, d)
    assert np.array_equal(res.prim, bp)
    assert np.array_equal(res.t.view(np.int64), bt.view(np.int64))
    assert (bp >= 0).sum() > 100
    assert (res.tests[bp >= 0] >= 1).all()
    for i in rng.choice(len(o), 150, replace=False):
        want = traverse_scalar(bih, c, r, o[i], d[i])
        assert (res.t[i], res.prim[i], res.nodes_visited[i], res.gaps[i], res.tests[i]) == want


def test_counters_scenario_1():
    sc = scenario(1, 64)  # 4×4×4 grid, centres at ±5, ±15, radius 1
    c, r = sc.sphere_centers, sc.sphere_radii
    bih = build_for_spheres(c, r, max_prims=1)
    o = np.array([[0.0, 0.0, 100.0],     # down the z axis, between the spheres
                  [0.0, 50.0, 100.0],    # misses the global box
                  [5.0, 5.0, 100.0],     # straight onto sphere (5, 5, 15)
                  [10.0, 10.0, 100.0]])  # between columns of spheres, off-axis
    d = np.array([[0.0, -0.0, -1.0], [0.0, 0.0, -1.0], [0.0, 0.0, -1.0], [-0.0, 0.0, -1.0]])
    res = traverse(bih, c, r, o, d)
    assert res.nodes_visited[1] == 0 and res.tests[1] == 0 and res.prim[1] == -1
    assert res.prim[0] == -1 and res.gaps[0] > 0 and res.tests[0] == 0
    hit = int(np.flatnonzero((c == [5.0, 5.0, 15.0]).all(axis=1))[0])
    assert res.prim[2] == hit and res.t[2] == 84.0
    assert res.prim[3] == -1 and res.gaps[3] > 0
    bt, bp = brute_force(c, r, o, d)
    assert np.array_equal(res.prim, bp) and np.array_equal(res.t, bt)


def test_counters_prune():
    """A ray along a row of spheres stops after the first hit: far subtrees are dropped."""
    c = np.stack([np.arange(16) * 4.0, np.zeros(16), np.zeros(16)], axis=1)
    r = np.ones(16)
    bih = build_for_spheres(c, r, max_prims=1)
    res = traverse(bih, c, r, np.array([[-10.0, 0, 0], [100.0, 0, 0]]), np.array([[1.0, 0, 0], [-1.0, 0, 0]]))
    assert res.prim.tolist() == [0, 15]
    assert res.t.tolist() == [9.0, 39.0]
    assert (res.tests < 16).all() and (res.nodes_visited < 2 * 16 - 1).all()


def test_ties_go_to_lower_id():
    # duplicates share a leaf; equal spheres in separate leaves via max_prims 1 and a forced depth
    c = np.array([[0.0, 0, 0], [5.0, 0, 0], [0.0, 0, 0], [5.0, 0, 0]])
    r = np.ones(4)
    for mp, depth in [(1, 64), (1, 2), (4, 64)]:
        bih = build_for_spheres(c, r, max_prims=mp, max_tree_depth=depth)
        o = np.array([[0.0, 0, 10.0], [5.0, 0, -10.0], [-10.0, 0, 0]])
        d = np.array([[0.0, 0, -1.0], [0.0, 0, 1.0], [1.0, 0, 0]])
        res = traverse(bih, c, r, o, d)
        assert res.prim.tolist() == [0, 1, 0] and res.t.tolist() == [9.0, 9.0, 9.0]


def test_secondary_rules():
    c = np.array([[0.0, 0, 0], [0.0, 0, -5.0]])
    r = np.array([1.0, 1.0])
    bih = build_for_spheres(c, r, max_prims=1)
    o = np.array([[0.0, 0, 1.0], [0.0, 0, 1.0], [0.0, 0, 1.0]])
    d = np.array([[0.0, 0, -1.0], [0.0, 0, -1.0], [0.0, 0, 1.0]])
    # entering sphere 0 at its top: far root t = 2; ignoring it: sphere 1 at t = 5; leaving: nothing
    res = traverse(bih, c, r, o, d, ignore=np.array([-1, 0, 0]), far_only=np.array([0, -1, -1]))
    assert res.prim.tolist() == [0, 1, -1] and res.t.tolist() == [2.0, 5.0, np.inf]
    # no rule: a ray starting on the surface has t_near = 0, which is not > 0: the far side
    res = traverse(bih, c, r, o, d)
    assert res.prim.tolist() == [0, 0, -1] and res.t.tolist() == [2.0, 2.0, np.inf]
    assert brute_force(c, r, o, d)[1].tolist() == [0, 0, -1]
    assert brute_force(c, r, o, d, ignore=np.array([-1, 0, 0]), far_only=np.array([0, -1, -1]))[1].tolist() == [0, 1, -1]


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

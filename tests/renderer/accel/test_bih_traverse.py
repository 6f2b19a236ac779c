"""CPU traversal of the BIH (renderer.accel.bih_traverse) against brute force and a scalar oracle.

- traversal == brute force (same (t, prim), t bitwise) over random scenes and
  adversarial rays (±0 direction components, origins on clip planes, secondary rays
  leaving a sphere), and == SHADING.md's pseudo-code transcribed one ray at a time,
  counters included (the heat mode's nodes visited, empty gaps, sphere tests);
- the thesis's scenarios, pruning, ties to the lower id, the secondary-ray rules;
- the same over trees with the build's empty-space cuts (step 0 of renderer.accel.bih, made
  for triangles, here over the spheres' boxes): the oracle reads the thesis's nodes, where
  a cut's empty child is a leaf of no primitives, the traversal the GPU records, where it
  names its sibling, so equal counters also say that no ray ever takes a cut's empty side.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from renderer.accel.bih import build_bih, build_for_spheres, sphere_aabbs
from renderer.accel.bih_traverse import brute_force, traverse
from renderer.accel.primitives import tree_to_scene_ids
from renderer.config.methods import METHODS
from renderer.oracle.reference import trace_rays
from renderer.scenes.scenarios import scenario
from tests.helpers import HYP
from tests.renderer.accel.support import decode, scenes

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
    inside = lambda m: lo + rng.random((m, 3)) * (hi - lo)
    none = lambda m: np.full(m, -1, dtype=np.int64)
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


def check_traversal(scene, max_prims, max_tree_depth, seed, per_kind=10, oracle=True, empty_cuts=False):
    c, r = scene
    bih = build_bih(*sphere_aabbs(c, r), max_prims=max_prims, max_tree_depth=max_tree_depth, empty_cuts=empty_cuts)
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
            f"brute ({bt[i]!r}, {bp[i]})"
        )
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
@given(
    scene=scenes(f32=True),
    max_prims=st.integers(1, 16),
    max_tree_depth=st.integers(1, 64),
    seed=st.integers(0, 2**32 - 1),
)
def test_traverse_matches_brute_force(scene, max_prims, max_tree_depth, seed):
    check_traversal(scene, max_prims, max_tree_depth, seed)


@pytest.mark.slow
@settings(max_examples=5000, **HYP)
@given(
    scene=scenes(f32=True),
    max_prims=st.integers(1, 16),
    max_tree_depth=st.integers(1, 64),
    seed=st.integers(0, 2**32 - 1),
)
def test_traverse_matches_brute_force_slow(scene, max_prims, max_tree_depth, seed):
    check_traversal(scene, max_prims, max_tree_depth, seed)


@settings(max_examples=100, **HYP)
@given(
    scene=scenes(f32=True),
    max_prims=st.integers(1, 16),
    max_tree_depth=st.integers(1, 64),
    seed=st.integers(0, 2**32 - 1),
)
def test_traverse_with_empty_cuts_matches_brute_force(scene, max_prims, max_tree_depth, seed):
    check_traversal(scene, max_prims, max_tree_depth, seed, empty_cuts=True)


@pytest.mark.slow
@settings(max_examples=2000, **HYP)
@given(
    scene=scenes(f32=True),
    max_prims=st.integers(1, 16),
    max_tree_depth=st.integers(1, 64),
    seed=st.integers(0, 2**32 - 1),
)
def test_traverse_with_empty_cuts_matches_brute_force_slow(scene, max_prims, max_tree_depth, seed):
    check_traversal(scene, max_prims, max_tree_depth, seed, empty_cuts=True)


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
    o = np.array(
        [
            [0.0, 0.0, 100.0],  # down the z axis, between the spheres
            [0.0, 50.0, 100.0],  # misses the global box
            [5.0, 5.0, 100.0],  # straight onto sphere (5, 5, 15)
            [10.0, 10.0, 100.0],
        ]
    )  # between columns of spheres, off-axis
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
    assert brute_force(c, r, o, d, ignore=np.array([-1, 0, 0]), far_only=np.array([0, -1, -1]))[1].tolist() == [
        0,
        1,
        -1,
    ]


def test_a_ray_leaving_a_triangle_ignores_it_in_the_traversal_and_in_the_reference(mixed_trees_scene):
    c = mixed_trees_scene.triangle_corners
    rng = np.random.default_rng(2)
    j = rng.choice(np.flatnonzero(~mixed_trees_scene.triangle_degenerate), 500, replace=False)
    w = rng.dirichlet((1, 1, 1), len(j))
    p = np.einsum("ik,ikj->ij", w, c[j])
    n = np.cross(c[j, 1] - c[j, 0], c[j, 2] - c[j, 0])
    d = n / np.linalg.norm(n, axis=1, keepdims=True)  # straight off the surface, outwards
    ignore = mixed_trees_scene.n_spheres + j
    res = traverse(
        METHODS["bih"].prepare(mixed_trees_scene, 4, 64).tree,
        mixed_trees_scene.sphere_centers,
        mixed_trees_scene.sphere_radii,
        p,
        d,
        ignore=ignore,
        triangles=c,
    )
    assert not (res.prim == ignore).any()
    t_ref, id_ref = trace_rays(mixed_trees_scene, p, d, src=mixed_trees_scene.triangle_id_base + j)
    not_plane = id_ref != mixed_trees_scene.n_spheres  # the plane (id n) is outside the BIH
    assert not_plane.sum() > 100
    np.testing.assert_array_equal(
        tree_to_scene_ids(res.prim, mixed_trees_scene.n_spheres, len(mixed_trees_scene.planes))[not_plane],
        id_ref[not_plane],
    )

"""CPU BIH traversal in float64, vectorised over rays (docs/SHADING.md).

This is the reference for what the shader's ``intersect_spheres`` (``shaders/method_bih.glsl``) does, including
the heat-mode counters, on the same GPU layout (:mod:`bih_layout`): inner records whose
child refs name an inner record or a leaf's first sphere record, and the spheres in leaf
order, each leaf a run of records ended by the one flagged last. All rays run in
lockstep: every *step* each live ray either pops an entry off its own explicit stack or
visits one node (an inner record or a leaf), so the Python loop runs over steps (about
the number of nodes the busiest ray visits), never over rays.

What it implements, exactly as SHADING.md's "BIH traversal" pseudo-code:

- slab test against the global AABB, intersected with ``[0, inf)``; an axis
  with ``d = ±0`` misses when ``o`` is outside the slab and constrains nothing
  otherwise (no ``(bound - o) / 0``);
- at an inner node with ``d[axis] > 0`` the left child is near, valid on
  ``[a, min(b, tL)]``, the right one far, valid on ``[max(a, tR), b]``; with
  ``d[axis] < 0`` the roles swap; with ``d[axis] = ±0`` the left child is valid
  on ``[a, b]`` when ``o[axis] <= clip_left`` and the right one when
  ``o[axis] >= clip_right`` (left is then taken as "near", as in the shader);
  ``tL``/``tR`` are computed in float64 from the node's float32 clip values;
- an interval ``[lo, hi]`` is valid when ``lo <= hi``; neither child valid is
  one pass through the empty gap (``gaps += 1``); a valid child whose ``lo``
  exceeds the best hit so far is dropped; with both left, the far one is
  pushed with its own interval; a popped entry whose ``a`` exceeds the best
  hit is skipped (not counted as visited);
- a leaf tests the spheres of its run of records, up to the one flagged last
  (``tests += count``, ignored spheres included, as in the shader);
- nearest hit with ``t > 0``; exactly equal ``t`` goes to the lower id.

Sphere intersection (shared with :func:`brute_force`, so both give bitwise
the same ``t``): ``b = dot(o - c, d)``, ``h² = r² - |(o - c) - b d|²``, roots
``-b ∓ h``, first root ``> 0``. Secondary-ray rules: ``ignore[i]`` is a sphere
ray ``i`` does not see at all, ``far_only[i]`` one for which only the far root
``-b + h`` counts (``-1`` = none).

Triangles (``triangles``: float64 corners (T, 3, 3), tree primitives ``n …`` after the
``n`` spheres, :mod:`renderer.accel.primitives`): the watertight test of Woop, Benthin &
Wald (:func:`triangle_t`, docs/SHADING.md "Triangles"), both sides hit, a zero-area
triangle never; ``ignore`` may name a triangle (the one a secondary ray leaves). A leaf's
triangle tests count in ``tests`` like its sphere tests. Returned ids are tree indices
(a triangle's scene id is ``i + n_planes``). On the GPU a triangle's leaf-order record is a
slot at the same position a sphere's record would have (``gpu_layout.leaf_records``: the
key flagged ``TRI_SLOT`` with the triangle's index, the corners in ``u_triangles``), so the
runs decoded here from :func:`bih_layout.leaf_order` are the shader's record for record.

Exactness against brute force: the intervals only prune, and pruning is safe
when every float64 primitive lies inside its float32 AABB (see
``tests/renderer/accel/test_bih.py`` and the note there on ``sphere_aabbs``; ``triangle_aabbs``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ..geometry.shapes import Shapes, pair_t
from . import bih_layout as L
from .bih import BIH

__all__ = ["TraversalResult", "traverse", "brute_force", "sphere_t", "triangle_t"]

# Pairs (ray, sphere) evaluated at once by brute_force.
_BRUTE_CHUNK = 1 << 21


@dataclass
class TraversalResult:
    t: np.ndarray  # float64 (R,), inf on a miss
    prim: np.ndarray  # int64 (R,), sphere id or -1
    nodes_visited: np.ndarray  # int64 (R,)
    gaps: np.ndarray  # int64 (R,)
    tests: np.ndarray  # int64 (R,)


def sphere_t(
    o: Sequence[np.ndarray],
    d: Sequence[np.ndarray],
    c: Sequence[np.ndarray],
    r: np.ndarray,
    ids: np.ndarray,
    ignore: np.ndarray,
    far_only: np.ndarray,
) -> np.ndarray:
    """t of the first accepted hit of ray ``(o, d)`` with sphere ``(c, r)``, inf if none.

    ``o, d, c`` are tuples/lists of three broadcastable float64 arrays (x, y, z
    components), ``r`` and ``ids`` broadcast with them, ``ignore``/``far_only``
    are the per-ray ids. The arithmetic is written out component by component
    so that any broadcast shape gives bitwise the same result.
    """
    px, py, pz = o[0] - c[0], o[1] - c[1], o[2] - c[2]
    b = px * d[0] + py * d[1] + pz * d[2]
    fx, fy, fz = px - b * d[0], py - b * d[1], pz - b * d[2]
    h2 = r * r - (fx * fx + fy * fy + fz * fz)
    hit = h2 >= 0.0
    h = np.sqrt(np.where(hit, h2, 0.0))
    t_near = -b - h
    t_far = -b + h
    far_t = np.where(t_far > 0.0, t_far, np.inf)
    t = np.where(t_near > 0.0, t_near, far_t)
    t = np.where(ids == far_only, far_t, t)
    return np.where(hit & (ids != ignore), t, np.inf)


def _pick(k: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Component ``k`` (0, 1, 2: x, y, z) of each element."""
    return np.where(k == 0, x, np.where(k == 1, y, z))


def _edge(qx: np.ndarray, py: np.ndarray, qy: np.ndarray, px: np.ndarray) -> np.ndarray:
    """``qx·py − qy·px``; an element that rounds to exactly 0 is recomputed exactly (rational
    arithmetic: in float64 the paper's double-precision fallback has no wider type to go to).
    Per edge, so that ``E(Q, P) = −E(P, Q)`` holds bit for bit between neighbours."""
    qx, py, qy, px = np.broadcast_arrays(qx, py, qy, px)
    e = qx * py - qy * px
    for k in zip(*np.nonzero(e == 0.0), strict=True):
        exact = Fraction(float(qx[k])) * Fraction(float(py[k])) - Fraction(float(qy[k])) * Fraction(float(px[k]))
        f = float(exact)
        e[k] = f if (f != 0.0 or exact == 0) else (5e-324 if exact > 0 else -5e-324)
    return e


def triangle_t(o, d, v0, v1, v2, ids: np.ndarray, ignore: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """t of the watertight hit (Woop, Benthin & Wald 2013) of ray ``(o, d)`` with triangle
    ``(v0, v1, v2)``; inf when none, when ``t ≤ 0``, when ``ids == ignore`` or the triangle
    is not ``valid`` (zero area). Component tuples that broadcast, as :func:`sphere_t`.

    The shear: ``kz`` the axis of the largest |d| (the first on ties), ``kx, ky`` the
    next ones, swapped when ``d[kz] < 0``; corners relative to ``o`` sheared to
    ``(A[kx] − A[kz] d[kx]/d[kz], A[ky] − A[kz] d[ky]/d[kz])``; the edge functions
    ``U = E(B, C)``, ``V = E(C, A)``, ``W = E(A, B)`` (:func:`_edge`) of one sign (zeros
    allowed: a ray through an edge or vertex hits), ``det = U + V + W ≠ 0``, and
    ``t = (U A[kz] + V B[kz] + W C[kz]) / (d[kz] det)`` with the ``1/d[kz]`` applied to each
    z first, as the paper does."""
    dx, dy, dz = d
    ax, ay, az = np.abs(dx), np.abs(dy), np.abs(dz)
    kz = np.where((ax >= ay) & (ax >= az), 0, np.where(ay >= az, 1, 2))
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    dkz = _pick(kz, dx, dy, dz)
    neg = dkz < 0.0
    kx, ky = np.where(neg, ky, kx), np.where(neg, kx, ky)
    with np.errstate(divide="ignore", invalid="ignore"):
        sx = _pick(kx, dx, dy, dz) / dkz
        sy = _pick(ky, dx, dy, dz) / dkz
        sz = 1.0 / dkz

    def shear(v):
        px, py, pz = v[0] - o[0], v[1] - o[1], v[2] - o[2]
        zc = _pick(kz, px, py, pz)
        return _pick(kx, px, py, pz) - sx * zc, _pick(ky, px, py, pz) - sy * zc, sz * zc

    a_x, a_y, a_z = shear(v0)
    b_x, b_y, b_z = shear(v1)
    c_x, c_y, c_z = shear(v2)
    u = _edge(c_x, b_y, c_y, b_x)
    v = _edge(a_x, c_y, a_y, c_x)
    w = _edge(b_x, a_y, b_y, a_x)
    mixed = ((u < 0) | (v < 0) | (w < 0)) & ((u > 0) | (v > 0) | (w > 0))
    det = u + v + w
    big_t = u * a_z + v * b_z + w * c_z
    ok = ~mixed & (det != 0.0) & valid & (ids != ignore)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(ok, big_t / np.where(ok, det, 1.0), np.inf)
    return np.where(t > 0.0, t, np.inf)


def _corners(triangles) -> tuple[np.ndarray, np.ndarray]:
    """float64 (T, 3, 3) corners and their validity (not of exactly zero area)."""
    if triangles is None:
        return np.zeros((0, 3, 3)), np.zeros(0, bool)
    c = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    cross = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    return c, (cross != 0.0).any(axis=1)


def _prepare(centers, radii, origins, dirs, ignore, far_only):
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
    if len(c) != len(r):
        raise ValueError(f"{len(c)} centres but {len(r)} radii")
    if len(o) != len(d):
        raise ValueError(f"{len(o)} origins but {len(d)} directions")
    n_rays = len(o)

    def ids(x, name):
        if x is None:
            return np.full(n_rays, -1, dtype=np.int64)
        x = np.asarray(x, dtype=np.int64).reshape(-1)
        if len(x) != n_rays:
            raise ValueError(f"{name}: expected {n_rays} ids, got {len(x)}")
        return x

    return c, r, o, d, ids(ignore, "ignore"), ids(far_only, "far_only")


def _shape_t(shapes: Shapes | None, n_before: int, o, d, ray: np.ndarray, pid: np.ndarray, ign) -> np.ndarray:
    """t of rays ``ray`` with tree primitives ``pid`` that are analytic shapes (tree index
    ``n_before + k``: shape ``k``), a ray leaving one (``ign``) dropping its root at the origin."""
    assert shapes is not None  # (a tree primitive past the triangles is a shape)
    k = pid - n_before
    return pair_t(shapes, k, o[ray], d[ray], np.where(ign[ray] == pid, k, -1))


def brute_force(
    centers, radii, origins, dirs, ignore=None, far_only=None, triangles=None, shapes: Shapes | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit of every ray over all spheres (and ``triangles``, then analytic ``shapes``,
    tree ids after them): ``(t, prim)``.

    ``t`` float64 (inf on a miss), ``prim`` int64 (-1 on a miss); exactly
    equal ``t`` goes to the lower id.
    """
    c, r, o, d, ign, far = _prepare(centers, radii, origins, dirs, ignore, far_only)
    n_rays, n = len(o), len(c)
    t_best = np.full(n_rays, np.inf)
    prim = np.full(n_rays, -1, dtype=np.int64)
    tri, valid = _corners(triangles)
    if shapes is not None and len(shapes) and n_rays:
        # The shapes' ids come last: a triangle's or a sphere's equal t wins below.
        first = n + len(tri)
        ray = np.repeat(np.arange(n_rays, dtype=np.int64), len(shapes))
        pid = first + np.tile(np.arange(len(shapes), dtype=np.int64), n_rays)
        t = _shape_t(shapes, first, o, d, ray, pid, ign).reshape(n_rays, len(shapes))
        k = np.argmin(t, axis=1)
        tk = t[np.arange(n_rays), k]
        t_best = tk
        prim = np.where(np.isfinite(tk), first + k, -1)
    if len(tri) and n_rays:
        ids = (n + np.arange(len(tri), dtype=np.int64))[None, :]
        v0, v1, v2 = (tuple(tri[None, :, k, a] for a in range(3)) for k in range(3))
        step = max(1, _BRUTE_CHUNK // len(tri))
        for s in range(0, n_rays, step):
            e = min(n_rays, s + step)
            oo = (o[s:e, 0:1], o[s:e, 1:2], o[s:e, 2:3])
            dd = (d[s:e, 0:1], d[s:e, 1:2], d[s:e, 2:3])
            t = triangle_t(oo, dd, v0, v1, v2, ids, ign[s:e, None], valid[None, :])
            k = np.argmin(t, axis=1)
            tk = t[np.arange(e - s), k]
            better = np.isfinite(tk) & (tk <= t_best[s:e])  # a triangle's id is below every shape's
            t_best[s:e] = np.where(better, tk, t_best[s:e])
            prim[s:e] = np.where(better, n + k, prim[s:e])
    if n == 0 or n_rays == 0:
        return t_best, prim
    ids = np.arange(n, dtype=np.int64)[None, :]
    cc = (c[None, :, 0], c[None, :, 1], c[None, :, 2])
    rr = r[None, :]
    step = max(1, _BRUTE_CHUNK // n)
    for s in range(0, n_rays, step):
        e = min(n_rays, s + step)
        oo = (o[s:e, 0:1], o[s:e, 1:2], o[s:e, 2:3])
        dd = (d[s:e, 0:1], d[s:e, 1:2], d[s:e, 2:3])
        t = sphere_t(oo, dd, cc, rr, ids, ign[s:e, None], far[s:e, None])
        k = np.argmin(t, axis=1)  # first minimum: the lower id on ties
        tk = t[np.arange(e - s), k]
        better = np.isfinite(tk) & (tk <= t_best[s:e])  # a sphere's id is below every triangle's
        t_best[s:e] = np.where(better, tk, t_best[s:e])
        prim[s:e] = np.where(better, k, prim[s:e])
    return t_best, prim


def _clip_global(box: np.ndarray, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slab test against the global AABB intersected with [0, inf): (hit, t0, t1)."""
    lo = box[0].astype(np.float64)
    hi = box[1].astype(np.float64)
    n_rays = len(o)
    t0 = np.zeros(n_rays)
    t1 = np.full(n_rays, np.inf)
    ok = np.ones(n_rays, dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for a in range(3):
            oa, da = o[:, a], d[:, a]
            zero = da == 0.0  # +0 and -0
            ok &= ~(zero & ((oa < lo[a]) | (oa > hi[a])))
            ta = (lo[a] - oa) / da
            tb = (hi[a] - oa) / da
            near = np.where(da > 0.0, ta, tb)
            far = np.where(da > 0.0, tb, ta)
            t0 = np.where(zero, t0, np.maximum(t0, near))
            t1 = np.where(zero, t1, np.minimum(t1, far))
    ok &= t0 <= t1
    return ok, t0, t1


def traverse(
    bih: BIH,
    centers: np.ndarray,
    radii: np.ndarray,
    origins: np.ndarray,
    dirs: np.ndarray,
    ignore: np.ndarray | None = None,
    far_only: np.ndarray | None = None,
    triangles: np.ndarray | None = None,
    shapes: Shapes | None = None,
) -> TraversalResult:
    """Nearest hit of every ray through ``bih`` (built over these spheres and triangles).

    Returns the same ``(t, prim)`` as :func:`brute_force` plus the heat-mode
    counters of SHADING.md. ``centers``/``radii`` are the float64 spheres the
    hierarchy was built for (primitive ``i`` of the build is sphere ``i``), ``triangles``
    its float64 triangle corners (primitive ``n + j`` is triangle ``j``).
    """
    c, r, o, d, ign, far = _prepare(centers, radii, origins, dirs, ignore, far_only)
    tri, valid = _corners(triangles)
    n_s = len(c)
    n_rays = len(o)
    best_t = np.full(n_rays, np.inf)
    best_p = np.full(n_rays, -1, dtype=np.int64)
    visited = np.zeros(n_rays, dtype=np.int64)
    gaps = np.zeros(n_rays, dtype=np.int64)
    tests = np.zeros(n_rays, dtype=np.int64)
    result = TraversalResult(best_t, best_p, visited, gaps, tests)
    n_t = n_s + len(tri)  # (the first shape's tree index)
    n = n_t + (len(shapes) if shapes is not None else 0)
    if n == 0 or n_rays == 0:
        return result
    if len(bih.indices) != n:
        raise ValueError(
            f"BIH built over {len(bih.indices)} primitives, got {n_s} spheres, {len(tri)} triangles "
            f"and {n - n_t} shapes"
        )

    # The GPU layout, decoded: inner records, and the spheres in leaf order with the end
    # of each record's run.
    records, root = L.gpu_records(bih)
    order, last = L.leaf_order(bih)
    ends = np.flatnonzero(last)
    run_end = ends[np.searchsorted(ends, np.arange(n))]
    fields = L.NODE.unpack(records)
    axis_of = fields["axis"].astype(np.int64)
    left_of = fields["left"].astype(np.int64)
    right_of = fields["right"].astype(np.int64)
    clip_l = fields["clip_left"].astype(np.float64)
    clip_r = fields["clip_right"].astype(np.float64)
    cx, cy, cz = c[:, 0], c[:, 1], c[:, 2]
    tv = [[tri[:, k, a] for a in range(3)] for k in range(3)]

    hit_box, t0, t1 = _clip_global(bih.global_aabb, o, d)

    # Per-ray explicit stacks; the current node lives outside the stack. A ray
    # pushes at most one far child per level of its current path, so the
    # tree's actual depth (<= max_tree_depth) + 1 entries always suffice.
    cap = int(min(bih.max_tree_depth, int(bih.node_depths.max(initial=1)))) + 1
    st_node = np.zeros((n_rays, cap), dtype=np.int64)
    st_a = np.zeros((n_rays, cap))
    st_b = np.zeros((n_rays, cap))
    sp = np.zeros(n_rays, dtype=np.int64)
    cur = np.zeros(n_rays, dtype=np.int64)
    cur_a = np.zeros(n_rays)
    cur_b = np.zeros(n_rays)
    has_cur = np.zeros(n_rays, dtype=bool)

    # stack = [(root, t0, t1)] for the rays that hit the global box.
    live = np.flatnonzero(hit_box)
    st_node[live, 0] = root
    st_a[live, 0] = t0[live]
    st_b[live, 0] = t1[live]
    sp[live] = 1

    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        while len(live):
            # Pop until every live ray has a node or an empty stack; a popped
            # entry that starts beyond the best hit is skipped.
            need = live[~has_cur[live] & (sp[live] > 0)]
            while len(need):
                sp[need] -= 1
                s = sp[need]
                a = st_a[need, s]
                ok = a <= best_t[need]
                got = need[ok]
                cur[got] = st_node[got, s[ok]]
                cur_a[got] = a[ok]
                cur_b[got] = st_b[got, s[ok]]
                has_cur[got] = True
                need = need[~ok]
                need = need[sp[need] > 0]
            live = live[has_cur[live]]
            if not len(live):
                break

            visited[live] += 1
            ref = cur[live]
            is_leaf = (ref & L.REF_LEAF) != 0
            idx = ref & L.REF_INDEX

            # Leaves: test the run of sphere records, keep the nearest (lower id on ties).
            lr = live[is_leaf]
            if len(lr):
                start = idx[is_leaf]
                cnt = run_end[start] - start + 1
                tests[lr] += cnt
                has_cur[lr] = False
                total = int(cnt.sum())
                if total:
                    ray = np.repeat(lr, cnt)
                    starts = np.cumsum(cnt) - cnt
                    pos = np.repeat(start - starts, cnt) + np.arange(total, dtype=np.int64)
                    pid = order[pos]
                    t = np.full(total, np.inf)
                    sp_ = np.flatnonzero(pid < n_s)
                    if len(sp_):
                        ry, ps = ray[sp_], pid[sp_]
                        t[sp_] = sphere_t(
                            (o[ry, 0], o[ry, 1], o[ry, 2]),
                            (d[ry, 0], d[ry, 1], d[ry, 2]),
                            (cx[ps], cy[ps], cz[ps]),
                            r[ps],
                            ps,
                            ign[ry],
                            far[ry],
                        )
                    kp_ = np.flatnonzero(pid >= n_t)
                    if len(kp_):
                        t[kp_] = _shape_t(shapes, n_t, o, d, ray[kp_], pid[kp_], ign)
                    tp_ = np.flatnonzero((pid >= n_s) & (pid < n_t))
                    if len(tp_):
                        ry, ps = ray[tp_], pid[tp_]
                        j = ps - n_s
                        v0, v1, v2 = (tuple(tv[k][a][j] for a in range(3)) for k in range(3))
                        t[tp_] = triangle_t(
                            (o[ry, 0], o[ry, 1], o[ry, 2]),
                            (d[ry, 0], d[ry, 1], d[ry, 2]),
                            v0,
                            v1,
                            v2,
                            ps,
                            ign[ry],
                            valid[j],
                        )
                    order_t = np.lexsort((pid, t, ray))
                    ray_s = ray[order_t]
                    first = np.ones(total, dtype=bool)
                    first[1:] = ray_s[1:] != ray_s[:-1]
                    sel = order_t[first]
                    rr, tt, pp = ray[sel], t[sel], pid[sel]
                    bt, bp = best_t[rr], best_p[rr]
                    better = np.isfinite(tt) & ((tt < bt) | ((tt == bt) & (pp < bp)))
                    best_t[rr[better]] = tt[better]
                    best_p[rr[better]] = pp[better]

            # Inner nodes: per-child intervals.
            ir = live[~is_leaf]
            if len(ir):
                nd = idx[~is_leaf]
                ax = axis_of[nd]
                oa = o[ir, ax]
                da = d[ir, ax]
                a = cur_a[ir]
                b = cur_b[ir]
                cl = clip_l[nd]
                cr = clip_r[nd]
                lc = left_of[nd]
                rc = right_of[nd]
                t_l = (cl - oa) / da
                t_r = (cr - oa) / da
                pos_d = da > 0.0
                zero = da == 0.0
                near_node = np.where(pos_d | zero, lc, rc)
                far_node = np.where(pos_d | zero, rc, lc)
                near_hi = np.minimum(b, np.where(pos_d, t_l, t_r))
                far_lo = np.maximum(a, np.where(pos_d, t_r, t_l))
                near_ok = np.where(zero, oa <= cl, a <= near_hi)
                far_ok = np.where(zero, oa >= cr, far_lo <= b)
                near_hi = np.where(zero, b, near_hi)
                far_lo = np.where(zero, a, far_lo)

                gap = ~near_ok & ~far_ok
                gaps[ir[gap]] += 1
                bt = best_t[ir]
                near_ok &= a <= bt
                far_ok &= far_lo <= bt

                both = near_ok & far_ok
                pr = ir[both]
                ps = sp[pr]
                if len(pr) and int(ps.max()) >= cap:
                    raise RuntimeError("BIH traversal stack overflow (tree deeper than max_tree_depth?)")
                st_node[pr, ps] = far_node[both]
                st_a[pr, ps] = far_lo[both]
                st_b[pr, ps] = b[both]
                sp[pr] += 1

                go_near = near_ok
                go_far = ~near_ok & far_ok
                gn, gf = ir[go_near], ir[go_far]
                cur[gn] = near_node[go_near]
                cur_b[gn] = near_hi[go_near]  # cur_a stays a
                cur[gf] = far_node[go_far]
                cur_a[gf] = far_lo[go_far]  # cur_b stays b
                has_cur[ir[~(go_near | go_far)]] = False

            live = live[has_cur[live] | (sp[live] > 0)]

    return result

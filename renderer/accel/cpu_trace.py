"""CPU traversals of the BVH and the kd-tree, and a primary-ray tracer over any method's tree.

The GPU traverses these trees in ``shaders/method_bvh.glsl`` / ``method_kdtree.glsl``; this
module is their float64 counterpart on the CPU, vectorised over rays in lockstep like
:mod:`renderer.accel.bih_traverse` (each step, every live ray pops an entry or visits one
node), so that the trees built over spheres, triangles *and analytic shapes* can be checked
against brute force. Primitive tests are those of ``bih_traverse``
(:func:`~renderer.accel.bih_traverse.sphere_t`, :func:`~renderer.accel.bih_traverse.triangle_t`)
and :func:`renderer.geometry.shapes.pair_t`, nearest ``t > 0``, exactly equal ``t`` to the lower id.

- BVH: a stack of nodes; a node is entered when the ray's slab interval through its box
  meets ``[0, best t]`` (closed: a hit exactly at the best t may still be a lower id).
- kd-tree: a stack of (node, t interval) as the BIH's, from the global box; at an inner
  node the near child gets ``[a, min(b, t_split)]`` and the far one ``[max(a, t_split), b]``
  (a ray in the split plane, ``d[axis] = 0``, takes the side of its origin, both when on
  the plane); an entry starting beyond the best hit is dropped. A primitive is in every
  leaf its box overlaps, so pruning by entry distance never loses a hit.

:func:`trace_tree` turns a method's :class:`~renderer.accel.base.PreparedMethod` into
scene primitive ids of primary rays, planes included (tested on their own, as the shader
does).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.shapes import Shapes, pair_t
from .bih import BIH
from .bih_traverse import _corners, sphere_t, traverse, triangle_t
from .bvh import BVH
from .kdtree import KdTree
from .primitives import tree_to_scene_ids

__all__ = ["TreePrimitives", "traverse_bvh", "traverse_kdtree", "trace_tree"]


@dataclass(frozen=True)
class TreePrimitives:
    """A scene's tree primitives in float64: spheres ``0 … n−1``, then triangles, then analytic shapes."""

    centers: np.ndarray  # (n, 3)
    radii: np.ndarray  # (n,)
    corners: np.ndarray  # (T, 3, 3)
    valid: np.ndarray  # (T,) not of zero area
    shapes: Shapes = field(default_factory=Shapes.empty)

    @staticmethod
    def of(scene) -> TreePrimitives:
        corners, valid = _corners(scene.triangle_corners)
        return TreePrimitives(
            np.asarray(scene.sphere_centers, np.float64).reshape(-1, 3),
            np.asarray(scene.sphere_radii, np.float64).reshape(-1),
            corners,
            valid,
            scene.shapes,
        )

    @property
    def n_spheres(self) -> int:
        return len(self.radii)

    def __len__(self) -> int:
        return len(self.radii) + len(self.corners) + len(self.shapes)

    def hits(self, o: np.ndarray, d: np.ndarray, ray: np.ndarray, pid: np.ndarray) -> np.ndarray:
        """t of ray ``ray[k]`` with tree primitive ``pid[k]`` (inf: no hit with t > 0)."""
        t = np.full(len(ray), np.inf)
        none = np.full(len(ray), -1, np.int64)
        sph = np.flatnonzero(pid < self.n_spheres)
        if len(sph):
            r, p = ray[sph], pid[sph]
            c = self.centers[p]
            t[sph] = sphere_t(
                (o[r, 0], o[r, 1], o[r, 2]),
                (d[r, 0], d[r, 1], d[r, 2]),
                (c[:, 0], c[:, 1], c[:, 2]),
                self.radii[p],
                p,
                none[sph],
                none[sph],
            )
        first_shape = self.n_spheres + len(self.corners)
        shp = np.flatnonzero(pid >= first_shape)
        if len(shp):
            t[shp] = pair_t(self.shapes, pid[shp] - first_shape, o[ray[shp]], d[ray[shp]])
        tri = np.flatnonzero((pid >= self.n_spheres) & (pid < first_shape))
        if len(tri):
            r, p = ray[tri], pid[tri]
            j = p - self.n_spheres
            v0, v1, v2 = (tuple(self.corners[j, k, a] for a in range(3)) for k in range(3))
            t[tri] = triangle_t(
                (o[r, 0], o[r, 1], o[r, 2]), (d[r, 0], d[r, 1], d[r, 2]), v0, v1, v2, p, none[tri], self.valid[j]
            )
        return t


def _nearest(best_t: np.ndarray, best_p: np.ndarray, ray: np.ndarray, t: np.ndarray, pid: np.ndarray) -> None:
    """Fold the candidate hits (ray, t, pid) into the per-ray best (lower id on equal t)."""
    ok = np.isfinite(t)
    ray, t, pid = ray[ok], t[ok], pid[ok]
    if not len(ray):
        return
    order = np.lexsort((pid, t, ray))
    ray, t, pid = ray[order], t[order], pid[order]
    first = np.concatenate([[True], ray[1:] != ray[:-1]])
    ray, t, pid = ray[first], t[first], pid[first]
    bt, bp = best_t[ray], best_p[ray]
    better = (t < bt) | ((t == bt) & (pid < bp))
    best_t[ray[better]] = t[better]
    best_p[ray[better]] = pid[better]


def _leaf_hits(prims: TreePrimitives, o, d, rays, first, count, indices, ids, best_t, best_p) -> None:
    total = int(count.sum())
    if not total:
        return
    ray = np.repeat(rays, count)
    starts = np.cumsum(count) - count
    pos = np.repeat(first - starts, count) + np.arange(total, dtype=np.int64)
    pid = ids[indices[pos]]
    _nearest(best_t, best_p, ray, prims.hits(o, d, ray, pid), pid)


def _slab(lo: np.ndarray, hi: np.ndarray, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ray/box intervals row-wise: (meets, t_near, t_far); an axis with d = ±0 constrains
    nothing when o is inside its slab and misses otherwise (no (bound − o) / 0)."""
    lo = lo.astype(np.float64)
    hi = hi.astype(np.float64)
    t0 = np.full(len(o), -np.inf)
    t1 = np.full(len(o), np.inf)
    ok = np.ones(len(o), dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for a in range(3):
            oa, da = o[:, a], d[:, a]
            zero = da == 0.0
            ok &= ~(zero & ((oa < lo[:, a]) | (oa > hi[:, a])))
            ta, tb = (lo[:, a] - oa) / da, (hi[:, a] - oa) / da
            t0 = np.where(zero, t0, np.maximum(t0, np.minimum(ta, tb)))
            t1 = np.where(zero, t1, np.minimum(t1, np.maximum(ta, tb)))
    return ok & (t0 <= t1), t0, t1


def traverse_bvh(
    bvh: BVH, prims: TreePrimitives, origins: np.ndarray, dirs: np.ndarray, ids: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit (t, tree primitive id; inf / −1 on a miss) of every ray through ``bvh``.

    ``ids`` maps the BVH's primitives to tree primitives (a two-level method's subset);
    None: the identity (the BVH was built over all of ``prims``)."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(dirs, np.float64).reshape(-1, 3)
    n_rays = len(o)
    best_t = np.full(n_rays, np.inf)
    best_p = np.full(n_rays, -1, np.int64)
    if bvh.n_primitives == 0 or n_rays == 0:
        return best_t, best_p
    ids = np.arange(bvh.n_primitives, dtype=np.int64) if ids is None else np.asarray(ids, np.int64)
    cap = int(bvh.depth.max(initial=1)) + 2
    stack = np.zeros((n_rays, cap), np.int64)
    sp = np.zeros(n_rays, np.int64)
    cur = np.zeros(n_rays, np.int64)
    live = np.arange(n_rays)
    has = np.ones(n_rays, dtype=bool)
    while len(live):
        need = live[~has[live] & (sp[live] > 0)]
        sp[need] -= 1
        cur[need] = stack[need, sp[need]]
        has[need] = True
        live = live[has[live]]
        if not len(live):
            break
        node = cur[live]
        meets, t0, t1 = _slab(bvh.bmin[node], bvh.bmax[node], o[live], d[live])
        meets &= (t1 >= 0.0) & (t0 <= best_t[live])
        has[live[~meets]] = False
        rays, node = live[meets], node[meets]
        leaf = bvh.left[node] < 0
        lr, ln = rays[leaf], node[leaf]
        has[lr] = False
        _leaf_hits(prims, o, d, lr, bvh.first[ln], bvh.count[ln], bvh.indices, ids, best_t, best_p)
        ir, inn = rays[~leaf], node[~leaf]
        if len(ir) and int(sp[ir].max()) >= cap:
            raise RuntimeError("BVH traversal stack overflow")
        stack[ir, sp[ir]] = bvh.left[inn] + 1
        sp[ir] += 1
        cur[ir] = bvh.left[inn]
        live = live[has[live] | (sp[live] > 0)]
    return best_t, best_p


def traverse_kdtree(
    kd: KdTree, prims: TreePrimitives, origins: np.ndarray, dirs: np.ndarray, ids: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit (t, tree primitive id; inf / −1 on a miss) of every ray through ``kd``;
    ``ids`` as :func:`traverse_bvh`."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(dirs, np.float64).reshape(-1, 3)
    n_rays = len(o)
    best_t = np.full(n_rays, np.inf)
    best_p = np.full(n_rays, -1, np.int64)
    n_prims = int(kd.stats.primitives) if kd.stats is not None else int(kd.indices.max(initial=-1)) + 1
    if n_prims == 0 or n_rays == 0:
        return best_t, best_p
    ids = np.arange(n_prims, dtype=np.int64) if ids is None else np.asarray(ids, np.int64)
    meets, t0, t1 = _slab(np.repeat(kd.global_box[:1], n_rays, 0), np.repeat(kd.global_box[1:], n_rays, 0), o, d)
    t0 = np.maximum(t0, 0.0)
    meets &= t0 <= t1
    cap = int(kd.depth.max(initial=1)) + 2
    st_node = np.zeros((n_rays, cap), np.int64)
    st_a = np.zeros((n_rays, cap))
    st_b = np.zeros((n_rays, cap))
    sp = np.zeros(n_rays, np.int64)
    live = np.flatnonzero(meets)
    st_a[live, 0], st_b[live, 0] = t0[live], t1[live]
    sp[live] = 1
    split = kd.split.astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        while len(live):
            sp[live] -= 1
            s = sp[live]
            node, a, b = st_node[live, s], st_a[live, s], st_b[live, s]
            keep = a <= best_t[live]
            rays, node, a, b = live[keep], node[keep], a[keep], b[keep]
            leaf = kd.axis[node] < 0
            lr, ln = rays[leaf], node[leaf]
            _leaf_hits(prims, o, d, lr, kd.offset[ln], kd.count[ln], kd.indices, ids, best_t, best_p)
            ir, inn, a, b = rays[~leaf], node[~leaf], a[~leaf], b[~leaf]
            ax = kd.axis[inn]
            oa, da, sv = o[ir, ax], d[ir, ax], split[inn]
            ts = (sv - oa) / da
            pos, zero = da > 0.0, da == 0.0
            lc = kd.left[inn]
            near = np.where(pos | zero, lc, lc + 1)
            far = np.where(pos | zero, lc + 1, lc)
            near_hi = np.where(zero, b, np.minimum(b, ts))
            far_lo = np.where(zero, a, np.maximum(a, ts))
            near_ok = np.where(zero, oa <= sv, a <= near_hi)
            far_ok = np.where(zero, oa >= sv, far_lo <= b)
            bt = best_t[ir]
            near_ok &= a <= bt
            far_ok &= far_lo <= bt
            # push far first, then near on top (visited next)
            for ok, child, lo_, hi_ in ((far_ok, far, far_lo, b), (near_ok, near, a, near_hi)):
                r = ir[ok]
                if len(r) and int(sp[r].max()) >= cap:
                    raise RuntimeError("kd-tree traversal stack overflow")
                st_node[r, sp[r]] = child[ok]
                st_a[r, sp[r]] = lo_[ok]
                st_b[r, sp[r]] = hi_[ok]
                sp[r] += 1
            live = live[sp[live] > 0]
    return best_t, best_p


def _planes(scene, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t_best = np.full(len(o), np.inf)
    p_best = np.full(len(o), -1, np.int64)
    for j, pl in enumerate(scene.planes):
        n = np.asarray(pl.normal)
        den = d @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((np.asarray(pl.point) - o) @ n) / den
        ok = (den != 0.0) & (t > 0.0) & (t < t_best)
        t_best[ok], p_best[ok] = t[ok], scene.n_spheres + j
    return t_best, p_best


def trace_tree(tree, scene, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit (t, scene primitive id) of primary rays through a prepared method's
    ``tree`` (a BIH, BVH, kd-tree, a two-level ``(kd, static_ids, bvh, moving_ids)``, or None
    for brute force), the scene's planes tested on their own."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(dirs, np.float64).reshape(-1, 3)
    prims = TreePrimitives.of(scene)
    if tree is None:
        from .bih_traverse import brute_force

        t, p = brute_force(prims.centers, prims.radii, o, d, triangles=prims.corners, shapes=prims.shapes)
    elif isinstance(tree, BIH):
        res = traverse(tree, prims.centers, prims.radii, o, d, triangles=prims.corners, shapes=prims.shapes)
        t, p = res.t, res.prim
    elif isinstance(tree, BVH):
        t, p = traverse_bvh(tree, prims, o, d)
    elif isinstance(tree, KdTree):
        t, p = traverse_kdtree(tree, prims, o, d)
    else:
        kd, static_ids, bvh, moving_ids = tree
        t, p = traverse_kdtree(kd, prims, o, d, static_ids)
        t2, p2 = traverse_bvh(bvh, prims, o, d, moving_ids)
        take = (t2 < t) | ((t2 == t) & (p2 >= 0) & ((p < 0) | (p2 < p)))
        t, p = np.where(take, t2, t), np.where(take, p2, p)
    ids = tree_to_scene_ids(p, scene.n_spheres, len(scene.planes))
    tp, pp = _planes(scene, o, d)
    # a plane's id lies between the spheres' and the triangles' (and shapes')
    take = (tp < t) | ((tp == t) & np.isfinite(tp) & ((ids < 0) | (pp < ids)))
    return np.where(take, tp, t), np.where(take, pp, ids)

"""Bounding volume hierarchy over sphere boxes: binned SAH build, refit, selective rebuild.

Build (Wald 2007's binned SAH, Reiter §2.4.4): top-down, every node of one
round at once with NumPy, as ``renderer/bih.py`` does. Each open node

1. becomes a leaf when it holds one primitive or reaches ``max_tree_depth``
   (depth counts the root as 1, as Table 4.2 does);
2. otherwise bins its primitives' box centroids into ``BINS`` equal bins of the
   node's centroid bounds on each axis and evaluates the SAH of the ``BINS − 1``
   splits between bins on every axis, with tight child boxes:
   ``cost = C_TRAV + C_ISECT · (A_L · n_L + A_R · n_R) / A``;
3. splits at the cheapest one when the node holds more than ``max_prims``
   primitives or when the split is cheaper than the leaf (``C_ISECT · n``);
   when all centroids coincide (no bin split exists) and the node holds more
   than ``max_prims``, it splits at the object median (``median_splits``).

No re-sorting per node: the primitives are sorted by centroid once per axis,
and each round partitions the three orders stably, so every node's primitives
stay sorted on every axis and a bin is a contiguous run (O(n log n) in all).
Each primitive is in exactly one leaf; leaves are ranges of ``indices``.
Siblings are allocated in pairs (right = left + 1), round by round.

Updates (Reiter §3.2.2, §4.4.1), per frame, given the spheres' new positions
(same count, same ids):

- ``refit``: recompute the leaf boxes from their primitives and every inner box
  bottom-up (level by level), and re-evaluate the near masks. The structure is
  kept, so the tree stays exact (every box holds its subtree) whatever the
  motion; only its quality can degrade.
- ``selective``: refit, then re-evaluate each inner node's split cost
  ``(A_L n_L + A_R n_R) / A`` (listing 4.15) against the cost recorded when it
  was split; every topmost node whose cost grew beyond ``1 + threshold``
  (+30 % by default) is rebuilt from its primitive range, the rest of the tree is
  kept, and the node array is compacted (breadth-first).
- ``rebuild``: a new build.

Near mask (Reiter's ordered traversal, listing 4.13): for each of the 8 ray
direction octants, the child with the larger visible surface area inside the
corridor of rays that can hit both children is visited first. (The listing
writes ``lvalid ? 0 : area``; the text means the area when the clipped box is
valid, which is what is computed here.)
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ..limits import DEFAULT_TEXTURE_WIDTH
from ..tree_update import DEFAULT_THRESHOLD, REBUILD, UPDATE_SCHEMES, TreeUpdate
from . import bvh_layout as L
from .base import BIG_LEAF, Capabilities, PreparedMethod, gpu_data, mesh_stats
from .primitives import scene_aabbs, sphere_aabbs

BINS = 16
C_TRAV = 1.0
C_ISECT = 1.0


@dataclass
class BVHStats:
    """Statistics of a BVH after its latest build or update.

    ``sah_cost``: the tree's SAH cost ``(C_TRAV Σ_inner A + C_ISECT Σ_leaf A·n) / A_root``.
    ``bytes``: memory of the build's layout, nodes (32 B each) + index array (4 B per
    primitive), as before issue 18 (the GPU now reads 64 B per inner node and a sphere
    record per primitive: ``bvh_layout``).
    ``update_ms``: time of the latest update (= ``build_ms`` after a build).
    ``rebuilt_subtrees`` / ``rebuilt_primitives``: what the latest selective
    rebuild rebuilt (0 after refit, all after a rebuild).
    """
    primitives: int
    nodes: int
    inner_nodes: int
    leaves: int
    depth_max: int
    depth_avg: float
    prims_per_leaf_avg: float
    prims_per_leaf_max: int
    sah_cost: float
    sah_nodes: float
    sah_tests: float
    sah_big_tests: float
    median_splits: int
    depth_limited_leaves: int
    scheme: str
    rebuilt_subtrees: int
    rebuilt_primitives: int
    build_ms: float
    update_ms: float
    bytes: int

    def to_json(self) -> dict:
        return asdict(self)


@dataclass
class BVH:
    """A BVH as struct-of-arrays (root at 0; children of inner ``i`` at ``left[i]``, ``left[i] + 1``).

    bmin, bmax: float32 (N, 3) node boxes. left: int64 (N,), −1 for leaves.
    first, count: the node's range ``indices[first : first + count]`` (every node,
    inner ones too: a subtree's primitives are contiguous). depth: root = 1.
    split_cost: ``(A_L n_L + A_R n_R) / A`` recorded when the node was split (NaN
    in leaves). near_mask: uint8, listing 4.13's mask (0 in leaves).
    indices: int64 (n,) primitive ids in leaf order. prim_lo/prim_hi: the float32
    primitive boxes the tree was last fitted to.
    """
    bmin: np.ndarray
    bmax: np.ndarray
    left: np.ndarray
    first: np.ndarray
    count: np.ndarray
    depth: np.ndarray
    split_cost: np.ndarray
    near_mask: np.ndarray
    indices: np.ndarray
    prim_lo: np.ndarray
    prim_hi: np.ndarray
    max_prims: int
    max_tree_depth: int
    stats: BVHStats = field(repr=False, default=None)  # type: ignore[assignment]

    @property
    def n_nodes(self) -> int:
        return len(self.left)

    @property
    def n_primitives(self) -> int:
        return len(self.indices)

    def texels(self) -> np.ndarray:
        """The node array in the GPU layout of :mod:`bvh_layout`."""
        return L.pack_nodes(self.bmin, self.bmax, self.left, self.first, self.count, self.near_mask)


# ----------------------------------------------------------------------------- helpers

def _half_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Half the surface area of boxes (…, 3), float64 (empty boxes give garbage: mask them)."""
    d = hi.astype(np.float64) - lo.astype(np.float64)
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]


def _expand(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Ranges [lo, hi) → (segment of each element, its position, segment starts, total)."""
    count = hi - lo
    k = len(lo)
    starts = np.zeros(k, dtype=np.int64)
    if k > 1:
        np.cumsum(count[:-1], out=starts[1:])
    total = int(count.sum())
    seg = np.repeat(np.arange(k, dtype=np.int64), count)
    pos = np.arange(total, dtype=np.int64) + np.repeat(lo - starts, count)
    return seg, pos, starts, total


class _Nodes:
    """Growable node arrays used while building."""

    def __init__(self, capacity: int):
        capacity = max(capacity, 1)
        self.bmin = np.zeros((capacity, 3), np.float32)
        self.bmax = np.zeros((capacity, 3), np.float32)
        self.left = np.full(capacity, -1, np.int64)
        self.first = np.zeros(capacity, np.int64)
        self.count = np.zeros(capacity, np.int64)
        self.depth = np.ones(capacity, np.int64)
        self.next = 0

    @staticmethod
    def of(bvh: BVH, extra: int) -> "_Nodes":
        nodes = _Nodes(bvh.n_nodes + extra)
        m = bvh.n_nodes
        nodes.bmin[:m], nodes.bmax[:m] = bvh.bmin, bvh.bmax
        nodes.left[:m], nodes.first[:m], nodes.count[:m], nodes.depth[:m] = bvh.left, bvh.first, bvh.count, bvh.depth
        nodes.next = m
        return nodes


def _grow(nodes: _Nodes, ords: np.ndarray, loT: np.ndarray, hiT: np.ndarray, cenT: np.ndarray,
          slot: np.ndarray, lo: np.ndarray, hi: np.ndarray, depth: np.ndarray,
          max_prims: int, max_depth: int) -> dict:
    """Build subtrees top-down from open nodes ``slot`` over position ranges [lo, hi).

    ``loT``/``hiT`` are the primitive boxes (float32, (3, n)), ``cenT`` their centres
    (float64, (3, n)). ``ords[a]`` maps positions to primitive ids, sorted by centroid
    on axis ``a`` within each open range; it is partitioned in place, so ``ords[0]``
    ends as the leaf-ordered index array over these ranges. Returns counters.
    """
    side = np.zeros(loT.shape[1], dtype=bool)
    median = depth_limited = 0
    while len(slot):
        count = hi - lo
        seg, pos, starts, total = _expand(lo, hi)
        p0 = ords[0][pos]
        for k in range(3):
            nodes.bmin[slot, k] = np.minimum.reduceat(loT[k][p0], starts)
            nodes.bmax[slot, k] = np.maximum.reduceat(hiT[k][p0], starts)
        nodes.first[slot] = lo
        nodes.count[slot] = count
        nodes.depth[slot] = depth
        nodes.left[slot] = -1
        depth_limited += int(((depth >= max_depth) & (count > 1)).sum())
        open_ = (count > 1) & (depth < max_depth)
        cand = np.flatnonzero(open_)
        if not len(cand):
            break
        clo, chi, cnt = lo[cand], hi[cand], count[cand]
        kc = len(cand)
        if kc == len(slot):
            cseg, cpos, cst, ctot = seg, pos, starts, total
        else:
            cseg, cpos, cst, ctot = _expand(clo, chi)
        cend = cst + cnt
        best = np.full(kc, np.inf)
        best_axis = np.zeros(kc, np.int64)
        best_cell = np.zeros(kc, np.int64)
        # Cells: BINS bins of the centroid bounds for nodes of more than BINS
        # primitives; one cell per primitive (a full sweep in centroid order,
        # as Reiter does for small nodes) otherwise.
        big = cnt > BINS
        ncells = np.where(big, BINS, cnt)
        cell_base = np.zeros(kc, np.int64)
        if kc > 1:
            np.cumsum(ncells[:-1], out=cell_base[1:])
        total_cells = int(ncells.sum())
        cell_seg = np.repeat(np.arange(kc, dtype=np.int64), ncells)
        local = np.arange(ctot, dtype=np.int64) - cst[cseg]
        big_e = big[cseg]
        nmin = nodes.bmin[slot[cand]].T.astype(np.float64)                   # (3, kc)
        ext_n = nodes.bmax[slot[cand]].T.astype(np.float64) - nmin
        inv_ext = 1.0 / np.where(ext_n > 0, ext_n, 1.0)
        ext_c = ext_n[:, cell_seg]                                         # (3, cells)
        # Segmented scans: values normalised to [0, 1] within their node and
        # offset by 2 per node, so one running max never crosses a node boundary.
        off = 2.0 * cell_seg
        off_r = 2.0 * (kc - 1 - cell_seg[::-1])
        same = np.zeros(total_cells, dtype=bool)
        same[:-1] = cell_seg[1:] == cell_seg[:-1]
        gl = np.empty(total_cells)
        gh = np.empty(total_cells)
        dl = np.empty((3, total_cells))
        dr = np.empty((3, total_cells))
        cells = []
        with np.errstate(invalid="ignore", over="ignore"):
            for a in range(3):
                pa = ords[a][cpos]
                c = cenT[a][pa]
                cmin, cmax = c[cst], c[cend - 1]
                ext = cmax - cmin
                scale = np.where(ext > 0, BINS / np.where(ext > 0, ext, 1.0), 0.0)
                b = np.floor((c - cmin[cseg]) * scale[cseg]).astype(np.int64)
                np.clip(b, 0, BINS - 1, out=b)
                cell = cell_base[cseg] + np.where(big_e, b, local)
                cells.append(cell)
                rs = np.flatnonzero(np.concatenate([[True], cell[1:] != cell[:-1]]))
                singletons = len(rs) == ctot
                rc, rseg = cell[rs], cseg[rs]
                gn = np.zeros(total_cells, np.int64)
                gn[rc] = np.diff(np.concatenate([rs, [ctot]]))
                for k in range(3):
                    vlo, vhi = loT[k][pa], hiT[k][pa]
                    if not singletons:
                        vlo, vhi = np.minimum.reduceat(vlo, rs), np.maximum.reduceat(vhi, rs)
                    gl.fill(1.0)
                    gh.fill(0.0)
                    gl[rc] = (vlo - nmin[k][rseg]) * inv_ext[k][rseg]
                    gh[rc] = (vhi - nmin[k][rseg]) * inv_ext[k][rseg]
                    pl = off - np.maximum.accumulate(off - gl)
                    ph = np.maximum.accumulate(gh + off) - off
                    dl[k] = (ph - pl) * ext_c[k]
                    sl = off_r - np.maximum.accumulate(off_r - gl[::-1])
                    sh = np.maximum.accumulate(gh[::-1] + off_r) - off_r
                    dr[k] = ((sh - sl) * ext_c[k][::-1])[::-1]
                a_l = dl[0] * dl[1] + dl[1] * dl[2] + dl[2] * dl[0]
                a_r = np.zeros(total_cells)
                a_r[:-1] = (dr[0] * dr[1] + dr[1] * dr[2] + dr[2] * dr[0])[1:]
                cn = np.cumsum(gn)
                n_l = cn - (cn[cell_base] - gn[cell_base])[cell_seg]
                n_r = cnt[cell_seg] - n_l
                # ties (e.g. coincident boxes) go to the most balanced split
                balance = 1.0 + 1e-9 * np.abs(n_l - n_r) / cnt[cell_seg]
                cost = np.where(same & (n_l > 0) & (n_r > 0), (a_l * n_l + a_r * n_r) * balance, np.inf)
                cmin_node = np.minimum.reduceat(cost, cell_base)
                better = cmin_node < best
                if better.any():
                    hit = np.flatnonzero((cost == cmin_node[cell_seg]) & better[cell_seg])
                    hs = cell_seg[hit]
                    first_hit = np.concatenate([[True], hs[1:] != hs[:-1]])
                    nodes_b, cells_b = hs[first_hit], hit[first_hit]
                    best[nodes_b] = cmin_node[nodes_b]
                    best_axis[nodes_b] = a
                    best_cell[nodes_b] = cells_b
        d = ext_n
        area = d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
        has = np.isfinite(best)
        with np.errstate(invalid="ignore", divide="ignore"):
            sah_split = C_TRAV + C_ISECT * best / np.where(area > 0, area, 1.0)
        do_sah = has & ((cnt > max_prims) | (sah_split < C_ISECT * cnt))
        do_median = ~has & (cnt > max_prims)
        split = do_sah | do_median
        median += int(do_median.sum())
        if not split.any():
            break
        # side of every primitive of a splitting node (True = left)
        for a in range(3):
            m = (do_sah & (best_axis == a))[cseg]
            if m.any():
                side[ords[a][cpos[m]]] = cells[a][m] <= best_cell[cseg[m]]
        m = do_median[cseg]
        if m.any():
            side[ords[0][cpos[m]]] = local[m] < (cnt[cseg[m]] // 2)
        # stable partition of the three orders (left part first)
        ms = split[cseg]
        n_left = None
        for a in range(3):
            pa = ords[a][cpos]
            li = (side[pa] & ms).astype(np.int64)
            excl = np.cumsum(li) - li
            rank = excl - excl[cst][cseg]
            if n_left is None:
                n_left = np.add.reduceat(li, cst)
            dest = np.where(li == 1, clo[cseg] + rank, clo[cseg] + n_left[cseg] + (local - rank))
            ords[a][dest[ms]] = pa[ms]
        sp = np.flatnonzero(split)
        msp = len(sp)
        child = nodes.next + 2 * np.arange(msp, dtype=np.int64)
        nodes.next += 2 * msp
        nodes.left[slot[cand[sp]]] = child
        mid = clo[sp] + n_left[sp]
        slot = np.concatenate([child, child + 1])
        lo = np.concatenate([clo[sp], mid])
        hi = np.concatenate([mid, chi[sp]])
        depth = np.concatenate([depth[cand[sp]] + 1, depth[cand[sp]] + 1])
    return {"median_splits": median, "depth_limited_leaves": depth_limited}


def near_masks(bmin: np.ndarray, bmax: np.ndarray, left: np.ndarray) -> np.ndarray:
    """Listing 4.13 for every inner node: uint8 mask, bit s = 1 → right child first for octant s.

    In float32 (an ordering heuristic: exactness is not needed), one octant at a time.
    """
    out = np.zeros(len(left), dtype=np.uint8)
    inner = np.flatnonzero(left >= 0)
    if not len(inner):
        return out
    li = left[inner]
    lL, lU = bmin[li], bmax[li]
    rL, rU = bmin[li + 1], bmax[li + 1]
    mask = np.zeros(len(inner), dtype=np.uint8)
    zero = np.float32(0)
    with np.errstate(over="ignore", invalid="ignore"):
        for s in range(8):
            neg = np.array([(s >> a) & 1 for a in range(3)], dtype=bool)
            int_l = np.where(neg, np.maximum(lL, rL), np.minimum(lL, rL))
            int_u = np.where(neg, np.maximum(lU, rU), np.minimum(lU, rU))
            right_front = np.where(neg, lU < rU, lL > rL)
            left_l, left_u = np.maximum(lL, int_l), np.minimum(lU, int_u)
            right_l, right_u = np.maximum(rL, int_l), np.minimum(rU, int_u)
            lvalid = (left_l <= left_u).all(axis=1)
            rvalid = (right_l <= right_u).all(axis=1)
            d = left_u - left_l
            la = np.where(lvalid, d[:, 0] * d[:, 1] + d[:, 1] * d[:, 2] + d[:, 2] * d[:, 0], zero)
            d = right_u - right_l
            ra = np.where(rvalid, d[:, 0] * d[:, 1] + d[:, 1] * d[:, 2] + d[:, 2] * d[:, 0], zero)
            both = (lvalid & rvalid)[:, None]
            di = np.maximum(np.minimum(left_u, right_u) - np.maximum(left_l, right_l), zero)
            occl = np.stack([di[:, 1] * di[:, 2], di[:, 0] * di[:, 2], di[:, 0] * di[:, 1]], axis=1)
            la = la - np.where(both & right_front, occl, zero).sum(axis=1)
            ra = ra - np.where(both & ~right_front, occl, zero).sum(axis=1)
            mask |= ((la < ra).astype(np.uint8) << np.uint8(s))
    out[inner] = mask
    return out


def split_costs(bvh_or_arrays) -> np.ndarray:
    """``(A_L n_L + A_R n_R) / A`` of every inner node from the current boxes (NaN in leaves)."""
    b = bvh_or_arrays
    out = np.full(len(b.left), np.nan)
    inner = np.flatnonzero(b.left >= 0)
    if len(inner):
        li = b.left[inner]
        a = _half_area(b.bmin[inner], b.bmax[inner])
        num = _half_area(b.bmin[li], b.bmax[li]) * b.count[li] + _half_area(b.bmin[li + 1], b.bmax[li + 1]) * b.count[li + 1]
        with np.errstate(invalid="ignore", divide="ignore"):
            out[inner] = np.where(a > 0, num / np.where(a > 0, a, 1.0), np.inf)
    return out


def sah_cost(bvh: BVH) -> float:
    """The tree's SAH cost relative to its root box."""
    if bvh.n_primitives == 0:
        return 0.0
    a = _half_area(bvh.bmin, bvh.bmax)
    root = a[0]
    if not root > 0:
        return float(C_ISECT * bvh.n_primitives)
    inner = bvh.left >= 0
    return float((C_TRAV * a[inner].sum() + C_ISECT * (a[~inner] * bvh.count[~inner]).sum()) / root)


def expected_work(bvh: BVH) -> dict[str, float]:
    """The SAH's two terms apart (renderer/cost.py): node visits and primitive tests a ray
    through the root box can expect."""
    n = bvh.n_primitives
    if n == 0:
        return {"sah_nodes": 0.0, "sah_tests": 0.0, "sah_big_tests": 0.0}
    a = _half_area(bvh.bmin, bvh.bmax)
    root = a[0]
    if not root > 0:
        return {"sah_nodes": 0.0, "sah_tests": float(n), "sah_big_tests": float(n if n > BIG_LEAF else 0)}
    inner = bvh.left >= 0
    leaf_work = a[~inner] * bvh.count[~inner]
    return {"sah_nodes": float(a[inner].sum() / root), "sah_tests": float(leaf_work.sum() / root),
            "sah_big_tests": float(leaf_work[bvh.count[~inner] > BIG_LEAF].sum() / root)}


def _sorted_orders(cen: np.ndarray, pos_lo: np.ndarray, pos_hi: np.ndarray, prims: np.ndarray,
                   n: int) -> np.ndarray:
    """(3, n) orders: within each range [pos_lo, pos_hi), ``prims`` of that range sorted by centroid per axis."""
    ords = np.zeros((3, n), dtype=np.int64)
    seg, pos, _, _ = _expand(pos_lo, pos_hi)
    p = prims[pos]
    for a in range(3):
        o = np.lexsort((p, cen[p, a], seg))
        ords[a][pos] = p[o]
    return ords


def _finish(nodes: _Nodes, indices: np.ndarray, plo: np.ndarray, phi: np.ndarray, max_prims: int,
            max_tree_depth: int, split_cost: np.ndarray | None) -> BVH:
    m = nodes.next
    bvh = BVH(bmin=nodes.bmin[:m].copy(), bmax=nodes.bmax[:m].copy(), left=nodes.left[:m].copy(),
              first=nodes.first[:m].copy(), count=nodes.count[:m].copy(), depth=nodes.depth[:m].copy(),
              split_cost=np.full(m, np.nan) if split_cost is None else split_cost[:m].copy(),
              near_mask=np.zeros(m, np.uint8), indices=indices, prim_lo=plo, prim_hi=phi,
              max_prims=max_prims, max_tree_depth=max_tree_depth)
    bvh.near_mask = near_masks(bvh.bmin, bvh.bmax, bvh.left)
    return bvh


def _stats(bvh: BVH, scheme: str, counters: dict, rebuilt: tuple[int, int], build_ms: float,
           update_ms: float) -> BVHStats:
    leaf = bvh.left < 0
    counts = bvh.count[leaf]
    depths = bvh.depth[leaf]
    return BVHStats(
        primitives=bvh.n_primitives, nodes=bvh.n_nodes, inner_nodes=int((~leaf).sum()), leaves=int(leaf.sum()),
        depth_max=int(bvh.depth.max(initial=1)), depth_avg=float(depths.mean()) if len(depths) else 0.0,
        prims_per_leaf_avg=float(counts.mean()) if len(counts) else 0.0,
        prims_per_leaf_max=int(counts.max(initial=0)), sah_cost=sah_cost(bvh), **expected_work(bvh),
        median_splits=int(counters.get("median_splits", 0)),
        depth_limited_leaves=int(counters.get("depth_limited_leaves", 0)), scheme=scheme,
        rebuilt_subtrees=rebuilt[0], rebuilt_primitives=rebuilt[1], build_ms=build_ms, update_ms=update_ms,
        bytes=int(bvh.n_nodes * L.NODE_BYTES + bvh.n_primitives * 4))


# ------------------------------------------------------------------------------- build

def _check_params(max_prims: int, max_tree_depth: int) -> None:
    if max_prims < 1:
        raise ValueError("max_prims must be >= 1")
    if not 1 <= max_tree_depth <= L.STACK_SIZE:
        raise ValueError(f"max_tree_depth must be in 1 … {L.STACK_SIZE}")


def build_bvh(aabb_min: np.ndarray, aabb_max: np.ndarray, max_prims: int = 4,
              max_tree_depth: int = L.STACK_SIZE) -> BVH:
    """Binned-SAH BVH over float32 primitive boxes ``(n, 3)``; terminates for any finite input."""
    t0 = time.perf_counter()
    _check_params(max_prims, max_tree_depth)
    plo = np.ascontiguousarray(aabb_min, dtype=np.float32).reshape(-1, 3)
    phi = np.ascontiguousarray(aabb_max, dtype=np.float32).reshape(-1, 3)
    n = len(plo)
    if n >= (1 << 30):
        raise ValueError("too many primitives")
    cen = (plo.astype(np.float64) + phi.astype(np.float64)) * 0.5
    nodes = _Nodes(2 * n - 1)
    counters: dict = {}
    if n == 0:
        nodes.bmin[0], nodes.bmax[0] = np.inf, -np.inf
        nodes.next = 1
        indices = np.zeros(0, np.int64)
    else:
        prims = np.arange(n, dtype=np.int64)
        ords = _sorted_orders(cen, np.zeros(1, np.int64), np.full(1, n, np.int64), prims, n)
        nodes.next = 1
        counters = _grow(nodes, ords, np.ascontiguousarray(plo.T), np.ascontiguousarray(phi.T),
                         np.ascontiguousarray(cen.T), np.zeros(1, np.int64),
                         np.zeros(1, np.int64),
                         np.full(1, n, np.int64), np.ones(1, np.int64), max_prims, max_tree_depth)
        indices = ords[0]
    bvh = _finish(nodes, indices, plo, phi, max_prims, max_tree_depth, None)
    bvh.split_cost = split_costs(bvh)
    ms = (time.perf_counter() - t0) * 1e3
    bvh.stats = _stats(bvh, "rebuild", counters, (1 if n else 0, n), ms, ms)
    return bvh


def build_for_spheres(centers: np.ndarray, radii: np.ndarray, max_prims: int = 4,
                      max_tree_depth: int = L.STACK_SIZE) -> BVH:
    lo, hi = sphere_aabbs(centers, radii)
    return build_bvh(lo, hi, max_prims, max_tree_depth)


def build_for_scene(scene, max_prims: int = 4, max_tree_depth: int = L.STACK_SIZE) -> BVH:
    """A BVH over the scene's spheres then triangles (:mod:`renderer.accel.primitives`)."""
    lo, hi = scene_aabbs(scene)
    return build_bvh(lo, hi, max_prims, max_tree_depth)


# ------------------------------------------------------------------------------ update

def _levels(bvh: BVH) -> list[np.ndarray]:
    """Inner nodes grouped by depth, deepest first."""
    inner = np.flatnonzero(bvh.left >= 0)
    if not len(inner):
        return []
    d = bvh.depth[inner]
    order = np.argsort(-d, kind="stable")
    inner, d = inner[order], d[order]
    cut = np.flatnonzero(np.diff(d)) + 1
    return np.split(inner, cut)


def _refit_boxes(bvh: BVH, plo: np.ndarray, phi: np.ndarray) -> None:
    """Leaf boxes from their primitives, inner boxes bottom-up (in place)."""
    leaves = np.flatnonzero((bvh.left < 0) & (bvh.count > 0))
    if len(leaves):
        leaves = leaves[np.argsort(bvh.first[leaves], kind="stable")]
        idx = bvh.indices
        bvh.bmin[leaves] = np.minimum.reduceat(plo[idx], bvh.first[leaves], axis=0)
        bvh.bmax[leaves] = np.maximum.reduceat(phi[idx], bvh.first[leaves], axis=0)
    for lvl in _levels(bvh):
        li = bvh.left[lvl]
        bvh.bmin[lvl] = np.minimum(bvh.bmin[li], bvh.bmin[li + 1])
        bvh.bmax[lvl] = np.maximum(bvh.bmax[li], bvh.bmax[li + 1])
    bvh.prim_lo, bvh.prim_hi = plo, phi


def _relayout(bvh: BVH) -> BVH:
    """Breadth-first compaction: only nodes reachable from the root, pairs kept together."""
    order = [np.zeros(1, np.int64)]
    frontier = order[0]
    while len(frontier):
        inner = frontier[bvh.left[frontier] >= 0]
        kids = np.stack([bvh.left[inner], bvh.left[inner] + 1], axis=1).ravel()
        if len(kids):
            order.append(kids)
        frontier = kids
    o = np.concatenate(order)
    new_id = np.full(bvh.n_nodes, -1, np.int64)
    new_id[o] = np.arange(len(o))
    left = bvh.left[o]
    return BVH(bmin=bvh.bmin[o], bmax=bvh.bmax[o], left=np.where(left >= 0, new_id[np.maximum(left, 0)], -1),
               first=bvh.first[o], count=bvh.count[o], depth=bvh.depth[o], split_cost=bvh.split_cost[o],
               near_mask=bvh.near_mask[o], indices=bvh.indices, prim_lo=bvh.prim_lo, prim_hi=bvh.prim_hi,
               max_prims=bvh.max_prims, max_tree_depth=bvh.max_tree_depth, stats=bvh.stats)


def refit(bvh: BVH, aabb_min: np.ndarray, aabb_max: np.ndarray) -> BVH:
    """Refit ``bvh`` (in place, and returned) to new boxes of the same primitives."""
    t0 = time.perf_counter()
    plo = np.ascontiguousarray(aabb_min, dtype=np.float32).reshape(-1, 3)
    phi = np.ascontiguousarray(aabb_max, dtype=np.float32).reshape(-1, 3)
    if len(plo) != bvh.n_primitives:
        raise ValueError(f"refit: the BVH holds {bvh.n_primitives} primitives, got {len(plo)}")
    _refit_boxes(bvh, plo, phi)
    bvh.near_mask = near_masks(bvh.bmin, bvh.bmax, bvh.left)
    ms = (time.perf_counter() - t0) * 1e3
    old = bvh.stats
    bvh.stats = _stats(bvh, "refit", {}, (0, 0), old.build_ms if old else 0.0, ms)
    return bvh


def selective_rebuild(bvh: BVH, aabb_min: np.ndarray, aabb_max: np.ndarray,
                      threshold: float = DEFAULT_THRESHOLD) -> BVH:
    """Refit, then rebuild every topmost subtree whose split cost grew beyond ``1 + threshold``.

    Returns a new (compacted) BVH; ``bvh`` itself is refitted in place.
    """
    t0 = time.perf_counter()
    if not threshold >= 0:
        raise ValueError("threshold must be >= 0")
    plo = np.ascontiguousarray(aabb_min, dtype=np.float32).reshape(-1, 3)
    phi = np.ascontiguousarray(aabb_max, dtype=np.float32).reshape(-1, 3)
    n = len(plo)
    if n != bvh.n_primitives:
        raise ValueError(f"selective rebuild: the BVH holds {bvh.n_primitives} primitives, got {n}")
    _refit_boxes(bvh, plo, phi)
    now = split_costs(bvh)
    with np.errstate(invalid="ignore"):
        marked = (bvh.left >= 0) & (now > bvh.split_cost * (1.0 + threshold))
    # keep only the topmost marked nodes (top-down by depth)
    blocked = np.zeros(bvh.n_nodes, dtype=bool)
    for lvl in reversed(_levels(bvh)):
        f = blocked[lvl] | marked[lvl]
        li = bvh.left[lvl]
        blocked[li] = f
        blocked[li + 1] = f
    roots = np.flatnonzero(marked & ~blocked)
    counters: dict = {}
    if len(roots):
        cen = (plo.astype(np.float64) + phi.astype(np.float64)) * 0.5
        lo, hi = bvh.first[roots], bvh.first[roots] + bvh.count[roots]
        nodes = _Nodes.of(bvh, 2 * int(bvh.count[roots].sum()))
        split_cost = np.concatenate([bvh.split_cost, np.full(nodes.bmin.shape[0] - bvh.n_nodes, np.nan)])
        ords = _sorted_orders(cen, lo, hi, bvh.indices, n)
        counters = _grow(nodes, ords, np.ascontiguousarray(plo.T), np.ascontiguousarray(phi.T),
                         np.ascontiguousarray(cen.T), roots.astype(np.int64), lo, hi,
                         bvh.depth[roots].copy(),
                         bvh.max_prims, bvh.max_tree_depth)
        seg, pos, _, _ = _expand(lo, hi)
        indices = bvh.indices.copy()
        indices[pos] = ords[0][pos]
        grown = _finish(nodes, indices, plo, phi, bvh.max_prims, bvh.max_tree_depth, split_cost)
        grown.stats = bvh.stats
        # record the split costs of the new splits (the kept nodes keep their original ones)
        fresh = split_costs(grown)
        new_nodes = np.zeros(grown.n_nodes, dtype=bool)
        new_nodes[roots] = True
        new_nodes[bvh.n_nodes:] = True
        grown.split_cost = np.where(new_nodes, fresh, grown.split_cost)
        out = _relayout(grown)
    else:
        bvh.near_mask = near_masks(bvh.bmin, bvh.bmax, bvh.left)
        out = bvh
    ms = (time.perf_counter() - t0) * 1e3
    old = bvh.stats
    out.stats = _stats(out, "selective", counters, (len(roots), int(bvh.count[roots].sum()) if len(roots) else 0),
                       old.build_ms if old else 0.0, ms)
    return out


class BVHUpdater:
    """Keeps one animation's BVH between frames and applies the chosen update scheme.

    ``update(centers, radii, scheme)`` returns the frame's BVH over spheres,
    ``update_boxes(lo, hi, scheme)`` over any primitives' boxes (spheres and triangles).
    A change in the number of primitives (spheres appearing or disappearing) or in the
    build limits always rebuilds (Reiter §4.1: resizing needs a rebuild); so does the first
    frame.
    """

    def __init__(self, max_prims: int = 4, max_tree_depth: int = L.STACK_SIZE,
                 threshold: float = DEFAULT_THRESHOLD):
        _check_params(max_prims, max_tree_depth)
        self.max_prims = max_prims
        self.max_tree_depth = max_tree_depth
        self.threshold = threshold
        self.bvh: BVH | None = None

    def update(self, centers: np.ndarray, radii: np.ndarray, scheme: str = "rebuild") -> BVH:
        lo, hi = sphere_aabbs(centers, radii)
        return self.update_boxes(lo, hi, scheme)

    def update_boxes(self, lo: np.ndarray, hi: np.ndarray, scheme: str = "rebuild") -> BVH:
        if scheme not in UPDATE_SCHEMES:
            raise ValueError(f"unknown update scheme {scheme!r}; one of {', '.join(UPDATE_SCHEMES)}")
        old = self.bvh
        if scheme == "rebuild" or old is None or old.n_primitives != len(lo) or old.n_primitives == 0:
            self.bvh = build_bvh(lo, hi, self.max_prims, self.max_tree_depth)
            if scheme != "rebuild":
                self.bvh.stats.scheme = f"{scheme} (rebuilt: {'first frame' if old is None else 'topology'})"
        elif scheme == "refit":
            self.bvh = refit(old, lo, hi)
        else:
            self.bvh = selective_rebuild(old, lo, hi, self.threshold)
        return self.bvh


# ------------------------------------------------------------------------------ method

class BVHMethod:
    """Method ``bvh``: the BVH of this module, traced by ``shaders/method_bvh.glsl``.

    ``prepare`` rebuilds per request by default, like the thesis's BIH. With the
    :class:`~renderer.tree_update.TreeUpdate` scheme ``refit`` or ``selective`` the BVH
    of the previous frame with the same ``key`` (an animation or session; one shared
    slot when None) is updated instead, as long as the sphere count and build limits
    are unchanged. The last ``CACHE_SLOTS`` keys are kept.
    """
    name = "bvh"
    capabilities = Capabilities(shader="method_bvh.glsl", update_schemes=UPDATE_SCHEMES,
                                settings=("max_prims", "max_tree_depth", "update"), meshes_on_gpu=True)
    bindings = L.BINDINGS
    glsl_defines = staticmethod(L.glsl_defines)
    CACHE_SLOTS = 8

    def __init__(self) -> None:
        self._updaters: dict = {}

    def updater(self, key, max_prims: int, max_tree_depth: int, threshold: float = DEFAULT_THRESHOLD) -> BVHUpdater:
        k = (key, max_prims, max_tree_depth, threshold)
        up = self._updaters.pop(k, None) or BVHUpdater(max_prims, max_tree_depth, threshold)
        self._updaters[k] = up                       # most recent last
        while len(self._updaters) > self.CACHE_SLOTS:
            self._updaters.pop(next(iter(self._updaters)))
        return up

    def build(self, scene, max_prims: int, max_tree_depth: int, update: TreeUpdate = REBUILD) -> BVH:
        """The frame's BVH over the scene's spheres and triangles (built, or updated from the
        previous frame of ``update.key``)."""
        lo, hi = scene_aabbs(scene)
        return self.build_boxes(lo, hi, max_prims, max_tree_depth, update)

    def build_boxes(self, lo: np.ndarray, hi: np.ndarray, max_prims: int, max_tree_depth: int,
                    update: TreeUpdate = REBUILD) -> BVH:
        """The same over primitive boxes (float32 (n, 3)): the two-level method's moving part."""
        if update.scheme == "rebuild":
            return build_bvh(lo, hi, max_prims, max_tree_depth)
        return self.updater(update.key, max_prims, max_tree_depth, update.threshold).update_boxes(
            lo, hi, update.scheme)

    def prepare(self, scene, max_prims: int, max_tree_depth: int, max_width: int = DEFAULT_TEXTURE_WIDTH,
                update: TreeUpdate = REBUILD) -> PreparedMethod:
        t0 = time.perf_counter()
        bvh = self.build(scene, max_prims, max_tree_depth, update)
        ms = (time.perf_counter() - t0) * 1e3
        packed = gpu_data(scene, meshes_on_gpu=True, method=self.name,
                          pack=lambda: L.pack_bvh(bvh, scene, None, max_width))
        return PreparedMethod(packed, ms,
                              {"method": self.name, **bvh.stats.to_json(), **mesh_stats(scene)}, tree=bvh)

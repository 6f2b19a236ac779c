"""Bounding volume hierarchy over primitive boxes (spheres, triangles): binned SAH build,
refit, selective rebuild.

Build (Wald 2007's binned SAH, Reiter §2.4.4): top-down, every node of one
round at once with NumPy, as ``renderer/accel/bih.py`` does. Each open node

1. becomes a leaf when it holds one primitive or reaches ``max_tree_depth``
   (depth counts the root as 1, as Table 4.2 does);
2. otherwise bins its primitives' box centroids, as Wald does, into equal bins of
   the node's centroid bounds on the axis where those bounds are longest —
   ``BINS`` bins, or the next power of two above a smaller node's primitive count
   — and evaluates the SAH of every split between bins, with tight child boxes:
   ``cost = C_TRAV + C_ISECT · (A_L · n_L + A_R · n_R) / A``;
3. splits at the cheapest one when the node holds more than ``max_prims``
   primitives or when the split is cheaper than the leaf (``C_ISECT · n``);
   when all centroids coincide (no bin split exists) and the node holds more
   than ``max_prims``, it splits at the object median (``median_splits``).

No sorting: binning needs none, so a round reads each primitive's row (box and
centroid, kept in position order, :func:`_rows`) once, bins it, and moves it once
(a stable partition per node): O(n) per level. The child boxes come from the bins'
prefix and suffix boxes. One axis per node (Wald's choice) rather than three costs
a third of the sweeps for a tree ~1–3 % higher in SAH cost (1,003,520 triangles:
69.5 against 67.7 for three axes with full sweeps of small nodes; `docs/RESULTS.md`,
section meshes, has the build times).
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
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from ..limits import DEFAULT_TEXTURE_WIDTH
from ..scenes.tree_update import DEFAULT_THRESHOLD, REBUILD, UPDATE_SCHEMES, TreeUpdate
from . import bvh_layout as L
from .base import BIG_LEAF, Capabilities, PreparedMethod, mesh_stats
from .primitives import scene_aabbs, sphere_aabbs
from .ranges import expand

BINS = 16
C_TRAV = 1.0
C_ISECT = 1.0


@dataclass
class BVHStats:
    """Statistics of a BVH after its latest build or update.

    ``sah_cost``: the tree's SAH cost ``(C_TRAV Σ_inner A + C_ISECT Σ_leaf A·n) / A_root``.
    ``bytes``: memory of the build's layout, nodes (32 B each) + index array (4 B per
    primitive); the GPU reads other records (64 B per inner node and a sphere record per
    primitive: ``bvh_layout``).
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
    stats: BVHStats = field(repr=False, default=None)  # type: ignore[assignment]  # the build sets it

    @property
    def n_nodes(self) -> int:
        return len(self.left)

    @property
    def n_primitives(self) -> int:
        return len(self.indices)


# ----------------------------------------------------------------------------- helpers


def _half_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Half the surface area of boxes (…, 3), float64 (empty boxes give garbage: mask them)."""
    d = hi.astype(np.float64) - lo.astype(np.float64)
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]


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
    def of(bvh: BVH, extra: int) -> _Nodes:
        nodes = _Nodes(bvh.n_nodes + extra)
        m = bvh.n_nodes
        nodes.bmin[:m], nodes.bmax[:m] = bvh.bmin, bvh.bmax
        nodes.left[:m], nodes.first[:m], nodes.count[:m], nodes.depth[:m] = bvh.left, bvh.first, bvh.count, bvh.depth
        nodes.next = m
        return nodes


# The build's working rows: one float32 row per primitive, its box and centroid, kept in
# position order (every node's primitives contiguous), so a round reads them sequentially
# and moves them once, instead of gathering them at random through an index array.
LO, HI, CEN = slice(0, 3), slice(3, 6), slice(6, 9)
ROW = 9


def _rows(plo: np.ndarray, phi: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """(n, ROW) rows of primitives ``ids`` in that order."""
    rows = np.empty((len(ids), ROW), np.float32)
    rows[:, LO], rows[:, HI] = plo[ids], phi[ids]
    rows[:, CEN] = rows[:, LO] * np.float32(0.5) + rows[:, HI] * np.float32(0.5)  # no overflow near ±3e38
    return rows


def _set_boxes(nodes: _Nodes, rows: np.ndarray, slot: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """Boxes of nodes ``slot`` from their primitives at positions [lo, hi)."""
    if not len(slot):
        return
    _, pos, starts = expand(lo, hi - lo)
    r = rows[pos]
    nodes.bmin[slot] = np.minimum.reduceat(r[:, LO], starts, axis=0)
    nodes.bmax[slot] = np.maximum.reduceat(r[:, HI], starts, axis=0)


@dataclass
class _Split:
    """The cheapest SAH split of each node (between two of its bins)."""

    cost: np.ndarray  # (k,) (A_L n_L + A_R n_R), inf: none exists
    bin: np.ndarray  # (k,) last bin of the left child
    left_lo: np.ndarray  # (k, 3) float32 child boxes
    left_hi: np.ndarray
    right_lo: np.ndarray
    right_hi: np.ndarray


def _widths(count: np.ndarray) -> np.ndarray:
    """Bins per node: BINS, or for a node of fewer primitives the next power of two (more
    bins than primitives would only add empty cells to scan)."""
    return np.minimum(BINS, 1 << np.ceil(np.log2(count)).astype(np.int64))


def _bins(r: np.ndarray, seg: np.ndarray, starts: np.ndarray, width: int) -> np.ndarray:
    """Each primitive's bin on its node's longest centroid axis (Wald 2007: ``width`` equal
    bins of the centroid bounds; all in bin 0 where every centroid coincides)."""
    c = r[:, CEN]
    cmin = np.minimum.reduceat(c, starts, axis=0).astype(np.float64)
    spread = np.maximum.reduceat(c, starts, axis=0) - cmin  # float64: no overflow
    axis = np.argmax(spread, axis=1)
    k = np.arange(len(starts))
    ext, base = spread[k, axis], cmin[k, axis]
    scale = np.where(ext > 0, width / np.where(ext > 0, ext, 1.0), 0.0)
    a = axis[seg]
    ce = np.where(a == 0, c[:, 0], np.where(a == 1, c[:, 1], c[:, 2]))
    b = ((ce - base[seg]) * scale[seg]).astype(np.int64)  # ≥ 0: truncation is the floor
    np.clip(b, 0, width - 1, out=b)
    return b


def _cheapest_split(r: np.ndarray, seg: np.ndarray, b: np.ndarray, count: np.ndarray, width: int) -> _Split:
    """The cheapest of the ``width − 1`` splits between bins of every node.

    The bins form a dense (width, k) grid — bin-major, so each scan step covers every node at
    once: a cell holds the box and count of its primitives (empty cells +inf/−inf and 0),
    and the prefix and suffix boxes are float32 min/max scans (exact: min and max do not
    round). The areas are float32 too (they only rank splits; equal boxes still give equal
    costs, which the float64 balance term then orders).
    """
    k = len(count)
    cell = b * k + seg
    blo = np.full((3, width * k), np.inf, np.float32)
    bhi = np.full((3, width * k), -np.inf, np.float32)
    for a in range(3):
        np.minimum.at(blo[a], cell, r[:, a])
        np.maximum.at(bhi[a], cell, r[:, 3 + a])
    n = np.bincount(cell, minlength=width * k).reshape(width, k)
    blo3, bhi3 = blo.reshape(3, width, k), bhi.reshape(3, width, k)
    pl, ph = _scan(blo3, np.minimum), _scan(bhi3, np.maximum)
    sl, sh = _scan(blo3, np.minimum, reverse=True), _scan(bhi3, np.maximum, reverse=True)
    n_l = np.cumsum(n, axis=0)[:-1]
    n_r = count - n_l
    with np.errstate(invalid="ignore", over="ignore"):
        d = ph[:, :-1] - pl[:, :-1]
        a_l = d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
        d = sh[:, 1:] - sl[:, 1:]
        a_r = d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
        # ties (e.g. coincident boxes) go to the most balanced split, then the lowest bin
        balance = 1.0 + 1e-9 * np.abs(n_l - n_r) / count
        cost = np.where((n_l > 0) & (n_r > 0), (a_l * n_l + a_r * n_r) * balance, np.inf)
    j = np.argmin(cost, axis=0)
    at, nxt = j * k + np.arange(k), (j + 1) * k + np.arange(k)
    flat = lambda x: x.reshape(3, width * k)
    return _Split(cost.reshape(-1)[at], j, flat(pl)[:, at].T, flat(ph)[:, at].T, flat(sl)[:, nxt].T, flat(sh)[:, nxt].T)


def _scan(x: np.ndarray, op: np.ufunc, reverse: bool = False) -> np.ndarray:
    """Running ``op`` along axis 1 of (3, width, k): one whole-row step per bin (numpy's
    ``accumulate`` along a middle axis is several times slower for short rows)."""
    out = x.copy()
    steps = range(x.shape[1] - 2, -1, -1) if reverse else range(1, x.shape[1])
    d = 1 if reverse else -1
    for i in steps:
        op(out[:, i + d], out[:, i], out=out[:, i])
    return out


def _partition(
    rows: np.ndarray,
    ids: np.ndarray,
    r: np.ndarray,
    pos: np.ndarray,
    seg: np.ndarray,
    starts: np.ndarray,
    local: np.ndarray,
    lo: np.ndarray,
    left: np.ndarray,
) -> np.ndarray:
    """Partition the rows (and ids) of each range stably, ``left`` ones first; ``r`` are the
    rows at ``pos``, the ranges' elements in order (``local``: each one's place in its range).
    Returns each range's left count."""
    cs = np.cumsum(left, dtype=np.int64)
    n_left = np.add.reduceat(left.astype(np.int64), starts)
    before = cs[starts] - left[starts]  # left primitives of the earlier ranges
    # the k-th left primitive of a range goes to lo + k, the k-th right one to lo + n_left + k;
    # with cs the running left count, both are one add away
    dest = np.where(left, (lo - before - 1)[seg] + cs, (lo + n_left + before)[seg] + local - cs)
    moved = ids[pos]
    # rows moved as opaque 36-byte records: twice as fast as fancy assignment of float rows
    record = np.dtype((np.void, rows.itemsize * ROW))
    rows.view(record)[dest, 0] = np.ascontiguousarray(r).view(record)[:, 0]
    ids[dest] = moved
    return n_left


def _grow(
    nodes: _Nodes,
    rows: np.ndarray,
    ids: np.ndarray,
    slot: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    depth: np.ndarray,
    max_prims: int,
    max_depth: int,
) -> dict:
    """Build subtrees top-down from open nodes ``slot`` over position ranges [lo, hi).

    ``rows`` (:func:`_rows`) and ``ids`` (primitive ids) are in position order and are
    partitioned in place, so ``ids`` ends as the leaf-ordered index array over these
    ranges. Each round: (1) record the open nodes, (2) bin each one's primitives on its
    longest centroid axis and find the cheapest split, (3) split or make a leaf, (4) mark
    every primitive's side, (5) partition and open the children, whose boxes come from the
    bins. Returns counters.
    """
    median = depth_limited = 0
    _set_boxes(nodes, rows, slot, lo, hi)
    while len(slot):
        # (1) the open nodes
        count = hi - lo
        nodes.first[slot] = lo
        nodes.count[slot] = count
        nodes.depth[slot] = depth
        nodes.left[slot] = -1
        depth_limited += int(((depth >= max_depth) & (count > 1)).sum())
        cand = np.flatnonzero((count > 1) & (depth < max_depth))
        if not len(cand):
            break
        # candidates grouped by their bin count, so each group's primitives are one run
        width = _widths(count[cand])
        order = np.argsort(width, kind="stable")
        cand, width = cand[order], width[order]
        clo, cnt = lo[cand], count[cand]
        seg, pos, starts = expand(clo, cnt)
        r = rows.take(pos, axis=0)  # take: twice as fast as fancy indexing of rows
        # (2) the cheapest split of each node, group by group
        b = np.empty(len(pos), np.int64)
        parts = []
        edges = np.flatnonzero(np.concatenate([[True], width[1:] != width[:-1], [True]]))
        for g0, g1 in zip(edges[:-1], edges[1:], strict=True):
            e0, e1 = starts[g0], (starts[g1] if g1 < len(cand) else len(pos))
            gseg = seg[e0:e1] - g0
            b[e0:e1] = _bins(r[e0:e1], gseg, starts[g0:g1] - e0, int(width[g0]))
            parts.append(_cheapest_split(r[e0:e1], gseg, b[e0:e1], cnt[g0:g1], int(width[g0])))
        best = _Split(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(_Split)))
        # (3) split when it must (more than max_prims) or when the SAH says so
        ext = nodes.bmax[slot[cand]].astype(np.float64) - nodes.bmin[slot[cand]].astype(np.float64)
        area = ext[:, 0] * ext[:, 1] + ext[:, 1] * ext[:, 2] + ext[:, 2] * ext[:, 0]
        has = np.isfinite(best.cost)
        with np.errstate(invalid="ignore", divide="ignore"):
            sah_split = C_TRAV + C_ISECT * best.cost / np.where(area > 0, area, 1.0)
        do_sah = has & ((cnt > max_prims) | (sah_split < C_ISECT * cnt))
        do_median = ~has & (cnt > max_prims)  # every centroid coincides: the object median
        median += int(do_median.sum())
        split = np.flatnonzero(do_sah | do_median)
        if not len(split):
            break
        # (4) the side of every primitive (True = left; a node that stays a leaf keeps its order)
        local = pos - clo[seg]
        left = np.where(do_sah[seg], b <= best.bin[seg], ~do_median[seg] | (local < (cnt // 2)[seg]))
        # (5) the children: left then right, allocated in pairs
        n_left = _partition(rows, ids, r, pos, seg, starts, local, clo, left)[split]
        slo, scnt = clo[split], cnt[split]
        child = nodes.next + 2 * np.arange(len(split), dtype=np.int64)
        nodes.next += 2 * len(split)
        nodes.left[slot[cand[split]]] = child
        mid = slo + n_left
        nodes.bmin[child], nodes.bmax[child] = best.left_lo[split], best.left_hi[split]
        nodes.bmin[child + 1], nodes.bmax[child + 1] = best.right_lo[split], best.right_hi[split]
        med = np.flatnonzero(do_median[split])
        if len(med):  # median splits have no bin boxes
            _set_boxes(
                nodes,
                rows,
                np.concatenate([child[med], child[med] + 1]),
                np.concatenate([slo[med], mid[med]]),
                np.concatenate([mid[med], slo[med] + scnt[med]]),
            )
        slot = np.concatenate([child, child + 1])
        lo = np.concatenate([slo, mid])
        hi = np.concatenate([mid, slo + scnt])
        depth = np.concatenate([depth[cand[split]] + 1, depth[cand[split]] + 1])
    return {"median_splits": median, "depth_limited_leaves": depth_limited}


def near_masks(bmin: np.ndarray, bmax: np.ndarray, left: np.ndarray) -> np.ndarray:
    """Listing 4.13 for every inner node: uint8 mask, bit s = 1 → right child first for octant s.

    In float32 (an ordering heuristic: exactness is not needed). Each axis' terms depend
    only on the sign of the direction along it, so they are formed once per axis and sign
    and combined for the 8 octants.
    """
    out = np.zeros(len(left), dtype=np.uint8)
    inner = np.flatnonzero(left >= 0)
    if not len(inner):
        return out
    li = left[inner]
    lL, lU = bmin[li].T, bmax[li].T
    rL, rU = bmin[li + 1].T, bmax[li + 1].T
    zero = np.float32(0)
    terms = {}
    with np.errstate(over="ignore", invalid="ignore"):
        for a in range(3):
            for neg in (0, 1):
                # the corridor of rays that can hit both children, along axis a
                pick = np.maximum if neg else np.minimum
                int_l, int_u = pick(lL[a], rL[a]), pick(lU[a], rU[a])
                right_front = lU[a] < rU[a] if neg else lL[a] > rL[a]
                left_l, left_u = np.maximum(lL[a], int_l), np.minimum(lU[a], int_u)
                right_l, right_u = np.maximum(rL[a], int_l), np.minimum(rU[a], int_u)
                di = np.maximum(np.minimum(left_u, right_u) - np.maximum(left_l, right_l), zero)
                terms[a, neg] = (
                    left_l <= left_u,
                    right_l <= right_u,
                    left_u - left_l,
                    right_u - right_l,
                    di,
                    right_front,
                )
        mask = np.zeros(len(inner), dtype=np.uint8)
        for s in range(8):
            t = [terms[a, (s >> a) & 1] for a in range(3)]
            lvalid = t[0][0] & t[1][0] & t[2][0]
            rvalid = t[0][1] & t[1][1] & t[2][1]
            dl, dr, di = [x[2] for x in t], [x[3] for x in t], [x[4] for x in t]
            la = np.where(lvalid, dl[0] * dl[1] + dl[1] * dl[2] + dl[2] * dl[0], zero)
            ra = np.where(rvalid, dr[0] * dr[1] + dr[1] * dr[2] + dr[2] * dr[0], zero)
            both = lvalid & rvalid
            occl = (di[1] * di[2], di[0] * di[2], di[0] * di[1])
            front = [both & x[5] for x in t]
            la = la - (
                np.where(front[0], occl[0], zero)
                + np.where(front[1], occl[1], zero)
                + np.where(front[2], occl[2], zero)
            )
            ra = ra - (
                np.where(both & ~t[0][5], occl[0], zero)
                + np.where(both & ~t[1][5], occl[1], zero)
                + np.where(both & ~t[2][5], occl[2], zero)
            )
            mask |= (la < ra).astype(np.uint8) << np.uint8(s)
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
        num = (
            _half_area(b.bmin[li], b.bmax[li]) * b.count[li]
            + _half_area(b.bmin[li + 1], b.bmax[li + 1]) * b.count[li + 1]
        )
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
    """The SAH's two terms apart (renderer/frame/cost.py): node visits and primitive tests a ray
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
    return {
        "sah_nodes": float(a[inner].sum() / root),
        "sah_tests": float(leaf_work.sum() / root),
        "sah_big_tests": float(leaf_work[bvh.count[~inner] > BIG_LEAF].sum() / root),
    }


def _finish(
    nodes: _Nodes,
    indices: np.ndarray,
    plo: np.ndarray,
    phi: np.ndarray,
    max_prims: int,
    max_tree_depth: int,
    split_cost: np.ndarray | None,
) -> BVH:
    m = nodes.next
    bvh = BVH(
        bmin=nodes.bmin[:m].copy(),
        bmax=nodes.bmax[:m].copy(),
        left=nodes.left[:m].copy(),
        first=nodes.first[:m].copy(),
        count=nodes.count[:m].copy(),
        depth=nodes.depth[:m].copy(),
        split_cost=np.full(m, np.nan) if split_cost is None else split_cost[:m].copy(),
        near_mask=np.zeros(m, np.uint8),
        indices=indices,
        prim_lo=plo,
        prim_hi=phi,
        max_prims=max_prims,
        max_tree_depth=max_tree_depth,
    )
    bvh.near_mask = near_masks(bvh.bmin, bvh.bmax, bvh.left)
    return bvh


def _stats(
    bvh: BVH, scheme: str, counters: dict, rebuilt: tuple[int, int], build_ms: float, update_ms: float
) -> BVHStats:
    leaf = bvh.left < 0
    counts = bvh.count[leaf]
    depths = bvh.depth[leaf]
    return BVHStats(
        primitives=bvh.n_primitives,
        nodes=bvh.n_nodes,
        inner_nodes=int((~leaf).sum()),
        leaves=int(leaf.sum()),
        depth_max=int(bvh.depth.max(initial=1)),
        depth_avg=float(depths.mean()) if len(depths) else 0.0,
        prims_per_leaf_avg=float(counts.mean()) if len(counts) else 0.0,
        prims_per_leaf_max=int(counts.max(initial=0)),
        sah_cost=sah_cost(bvh),
        **expected_work(bvh),
        median_splits=int(counters.get("median_splits", 0)),
        depth_limited_leaves=int(counters.get("depth_limited_leaves", 0)),
        scheme=scheme,
        rebuilt_subtrees=rebuilt[0],
        rebuilt_primitives=rebuilt[1],
        build_ms=build_ms,
        update_ms=update_ms,
        bytes=int(bvh.n_nodes * L.NODE_BYTES + bvh.n_primitives * 4),
    )


# ------------------------------------------------------------------------------- build


def _check_params(max_prims: int, max_tree_depth: int) -> None:
    if max_prims < 1:
        raise ValueError("max_prims must be >= 1")
    if not 1 <= max_tree_depth <= L.STACK_SIZE:
        raise ValueError(f"max_tree_depth must be in 1 … {L.STACK_SIZE}")


def build_bvh(
    aabb_min: np.ndarray, aabb_max: np.ndarray, max_prims: int = 4, max_tree_depth: int = L.STACK_SIZE
) -> BVH:
    """Binned-SAH BVH over float32 primitive boxes ``(n, 3)``; terminates for any finite input."""
    t0 = time.perf_counter()
    _check_params(max_prims, max_tree_depth)
    plo = np.ascontiguousarray(aabb_min, dtype=np.float32).reshape(-1, 3)
    phi = np.ascontiguousarray(aabb_max, dtype=np.float32).reshape(-1, 3)
    n = len(plo)
    if n >= (1 << 30):
        raise ValueError("too many primitives")
    nodes = _Nodes(2 * n - 1)
    counters: dict = {}
    indices = np.arange(n, dtype=np.int64)
    nodes.next = 1
    if n == 0:
        nodes.bmin[0], nodes.bmax[0] = np.inf, -np.inf
    else:
        counters = _grow(
            nodes,
            _rows(plo, phi, indices),
            indices,
            np.zeros(1, np.int64),
            np.zeros(1, np.int64),
            np.full(1, n, np.int64),
            np.ones(1, np.int64),
            max_prims,
            max_tree_depth,
        )
    bvh = _finish(nodes, indices, plo, phi, max_prims, max_tree_depth, None)
    bvh.split_cost = split_costs(bvh)
    ms = (time.perf_counter() - t0) * 1e3
    bvh.stats = _stats(bvh, "rebuild", counters, (1 if n else 0, n), ms, ms)
    return bvh


def build_for_spheres(
    centers: np.ndarray, radii: np.ndarray, max_prims: int = 4, max_tree_depth: int = L.STACK_SIZE
) -> BVH:
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
    return BVH(
        bmin=bvh.bmin[o],
        bmax=bvh.bmax[o],
        left=np.where(left >= 0, new_id[np.maximum(left, 0)], -1),
        first=bvh.first[o],
        count=bvh.count[o],
        depth=bvh.depth[o],
        split_cost=bvh.split_cost[o],
        near_mask=bvh.near_mask[o],
        indices=bvh.indices,
        prim_lo=bvh.prim_lo,
        prim_hi=bvh.prim_hi,
        max_prims=bvh.max_prims,
        max_tree_depth=bvh.max_tree_depth,
        stats=bvh.stats,
    )


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


def selective_rebuild(
    bvh: BVH, aabb_min: np.ndarray, aabb_max: np.ndarray, threshold: float = DEFAULT_THRESHOLD
) -> BVH:
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
        lo, hi = bvh.first[roots], bvh.first[roots] + bvh.count[roots]
        nodes = _Nodes.of(bvh, 2 * int(bvh.count[roots].sum()))
        split_cost = np.concatenate([bvh.split_cost, np.full(nodes.bmin.shape[0] - bvh.n_nodes, np.nan)])
        indices = bvh.indices.copy()
        counters = _grow(
            nodes,
            _rows(plo, phi, indices),
            indices,
            roots.astype(np.int64),
            lo,
            hi,
            bvh.depth[roots].copy(),
            bvh.max_prims,
            bvh.max_tree_depth,
        )
        grown = _finish(nodes, indices, plo, phi, bvh.max_prims, bvh.max_tree_depth, split_cost)
        grown.stats = bvh.stats
        # record the split costs of the new splits (the kept nodes keep their original ones)
        fresh = split_costs(grown)
        new_nodes = np.zeros(grown.n_nodes, dtype=bool)
        new_nodes[roots] = True
        new_nodes[bvh.n_nodes :] = True
        grown.split_cost = np.where(new_nodes, fresh, grown.split_cost)
        out = _relayout(grown)
    else:
        bvh.near_mask = near_masks(bvh.bmin, bvh.bmax, bvh.left)
        out = bvh
    ms = (time.perf_counter() - t0) * 1e3
    old = bvh.stats
    out.stats = _stats(
        out,
        "selective",
        counters,
        (len(roots), int(bvh.count[roots].sum()) if len(roots) else 0),
        old.build_ms if old else 0.0,
        ms,
    )
    return out


class BVHUpdater:
    """Keeps one animation's BVH between frames and applies the chosen update scheme.

    ``update(centers, radii, scheme)`` returns the frame's BVH over spheres,
    ``update_boxes(lo, hi, scheme)`` over any primitives' boxes (spheres and triangles).
    A change in the number of primitives (spheres appearing or disappearing) or in the
    build limits always rebuilds (Reiter §4.1: resizing needs a rebuild); so does the first
    frame.
    """

    def __init__(self, max_prims: int = 4, max_tree_depth: int = L.STACK_SIZE, threshold: float = DEFAULT_THRESHOLD):
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
    :class:`~renderer.scenes.tree_update.TreeUpdate` scheme ``refit`` or ``selective`` the BVH
    of the previous frame with the same ``key`` (an animation or session; one shared
    slot when None) is updated instead, as long as the sphere count and build limits
    are unchanged. The last ``CACHE_SLOTS`` keys are kept.
    """

    name = "bvh"
    label = "BVH (binned SAH)"
    capabilities = Capabilities(
        shader="method_bvh.glsl",
        update_schemes=UPDATE_SCHEMES,
        settings=("max_prims", "max_tree_depth", "update", "integrator"),
        meshes_on_gpu=True,
    )
    bindings = L.BINDINGS
    glsl_defines = staticmethod(L.glsl_defines)
    CACHE_SLOTS = 8

    def __init__(self) -> None:
        self._updaters: dict = {}

    def updater(self, key, max_prims: int, max_tree_depth: int, threshold: float = DEFAULT_THRESHOLD) -> BVHUpdater:
        k = (key, max_prims, max_tree_depth, threshold)
        up = self._updaters.pop(k, None) or BVHUpdater(max_prims, max_tree_depth, threshold)
        self._updaters[k] = up  # most recent last
        while len(self._updaters) > self.CACHE_SLOTS:
            self._updaters.pop(next(iter(self._updaters)))
        return up

    def build(self, scene, max_prims: int, max_tree_depth: int, update: TreeUpdate = REBUILD) -> BVH:
        """The frame's BVH over the scene's spheres and triangles (built, or updated from the
        previous frame of ``update.key``)."""
        lo, hi = scene_aabbs(scene)
        return self.build_boxes(lo, hi, max_prims, max_tree_depth, update)

    def build_boxes(
        self, lo: np.ndarray, hi: np.ndarray, max_prims: int, max_tree_depth: int, update: TreeUpdate = REBUILD
    ) -> BVH:
        """The same over primitive boxes (float32 (n, 3)): the two-level method's moving part."""
        if update.scheme == "rebuild":
            return build_bvh(lo, hi, max_prims, max_tree_depth)
        return self.updater(update.key, max_prims, max_tree_depth, update.threshold).update_boxes(lo, hi, update.scheme)

    def prepare(
        self,
        scene,
        max_prims: int,
        max_tree_depth: int,
        max_width: int = DEFAULT_TEXTURE_WIDTH,
        update: TreeUpdate = REBUILD,
    ) -> PreparedMethod:
        t0 = time.perf_counter()
        bvh = self.build(scene, max_prims, max_tree_depth, update)
        ms = (time.perf_counter() - t0) * 1e3
        packed = L.pack_bvh(bvh, scene, None, max_width)
        return PreparedMethod(packed, ms, {"method": self.name, **bvh.stats.to_json(), **mesh_stats(scene)}, tree=bvh)

"""SAH kd-tree over sphere boxes (Wald & Havran 2006; Reiter §2.3.1, §4.3, §5.1.2).

Build in O(n log n): the 2n box bounds (start and end events) are sorted once
per axis; every round then handles all open nodes at once with NumPy:

1. **sweep** — per axis, the node's events are in position order, so the number
   of primitives left of a candidate plane ``p`` (those with ``min < p``) and
   right of it (``max > p``) are running counts; every distinct event position
   strictly inside the node's voxel is a candidate. The SAH cost is
   ``C_TRAV + C_ISECT · (A_L n_L + A_R n_R) / A`` with the voxel areas of both
   sides, times ``EMPTY_BONUS`` when one side is empty;
2. **termination** — a node becomes a leaf when the cheapest split is not
   cheaper than the leaf, ``C_ISECT · n · s(depth)``, or at the depth limit.
   ``s`` is Reiter's cost scaling: ``s(d) = cost_scale^((d − 1) / (D − 1))``,
   1 at the root, ``cost_scale`` at the maximal depth ``D`` (``cost_scale = 1``
   is the plain SAH criterion). ``D = min(max_tree_depth, 8 + 1.3 log2 n)``;
3. **split** — a primitive goes left when its (clipped) box starts below the
   plane and right when it ends above it: one that straddles the plane is in
   both children. The event lists are split stably, a straddler's events
   duplicated and its box clipped at the plane, which keeps both children's
   lists sorted: nothing is ever sorted again.

Finally the leaves' index lists are compacted (Reiter's algorithm 6): in
depth-first order, each leaf's sorted list reuses an identical run among the
last ``compaction_window`` entries of the global list when there is one, and
is appended otherwise.

All positions are float32, the GPU's precision; primitive boxes are
``bih.sphere_aabbs`` (rounded outwards), so a sphere is inside its box and a
point of a sphere on one side of a plane implies that its box reaches that side.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ..limits import DEFAULT_TEXTURE_WIDTH
from ..scenes.tree_update import REBUILD, TreeUpdate
from . import kdtree_layout as L
from .base import BIG_LEAF, Capabilities, PreparedMethod, mesh_stats
from .primitives import scene_aabbs, sphere_aabbs

C_TRAV = 1.0
C_ISECT = 1.0
EMPTY_BONUS = 0.8
DEFAULT_COST_SCALE = 0.9
COMPACTION_WINDOW = 1000
# Guard against reference blow-up on pathological input: beyond this many
# references per primitive no node is split any more (counted in the stats).
MAX_REFS_PER_PRIM = 64


def auto_max_depth(n: int) -> int:
    """Havran's depth limit ``8 + 1.3 log2 n`` (root = depth 1)."""
    return int(8 + 1.3 * math.log2(max(n, 1)))


@dataclass
class KdStats:
    """Statistics of a kd-tree build.

    ``references``: primitive references in all leaves (a straddler counts once
    per leaf); ``indices``: entries of the compacted index array; ``bytes``:
    nodes (8 B) + compacted index array (4 B each) + global box (24 B), Fig. 5.4's
    "size" (the build's layout; the GPU's, ``kdtree_layout``, holds a sphere record per
    reference); ``sah_cost``: ``(C_TRAV Σ_inner A + C_ISECT Σ_leaf A·n) / A_root``.
    """

    primitives: int
    nodes: int
    inner_nodes: int
    leaves: int
    empty_leaves: int
    depth_max: int
    depth_avg: float
    max_depth: int
    cost_scale: float
    references: int
    indices: int
    refs_per_prim: float
    prims_per_leaf_avg: float
    sah_cost: float
    sah_nodes: float
    sah_tests: float
    sah_big_tests: float
    rounds: int
    blowup_stops: int
    build_ms: float
    compaction_ms: float
    bytes: int

    def to_json(self) -> dict:
        return asdict(self)


@dataclass
class KdTree:
    """A kd-tree as struct-of-arrays; root at 0, children of inner ``i`` at ``left[i]``, ``left[i] + 1``.

    axis: −1 in leaves. split: float32 plane position (inner). count/offset: the
    leaf's range of ``indices`` (ranges of different leaves may overlap after
    compaction). depth: root = 1. vmin/vmax: float32 voxel of every node.
    """

    axis: np.ndarray
    left: np.ndarray
    split: np.ndarray
    count: np.ndarray
    offset: np.ndarray
    depth: np.ndarray
    vmin: np.ndarray
    vmax: np.ndarray
    indices: np.ndarray
    global_box: np.ndarray
    max_depth: int
    cost_scale: float
    stats: KdStats = field(repr=False, default=None)  # type: ignore[assignment]  # the build sets it

    @property
    def n_nodes(self) -> int:
        return len(self.axis)

    def leaf_prims(self, node: int) -> np.ndarray:
        return self.indices[self.offset[node] : self.offset[node] + self.count[node]]


def _first_in_group(keys: np.ndarray) -> np.ndarray:
    """For a sorted key array, the index of the first element with the same key."""
    return np.searchsorted(keys, keys, side="left")


def build_kdtree(
    aabb_min: np.ndarray,
    aabb_max: np.ndarray,
    max_tree_depth: int = L.STACK_SIZE,
    cost_scale: float = DEFAULT_COST_SCALE,
    compaction_window: int = COMPACTION_WINDOW,
    max_depth: int | None = None,
) -> KdTree:
    """SAH kd-tree over float32 primitive boxes ``(n, 3)``; terminates for any finite input.

    ``max_depth`` overrides the automatic depth limit (still capped by ``max_tree_depth``).
    ``compaction_window = 0`` stores every leaf's list separately (no reuse).
    """
    t_start = time.perf_counter()
    if not 1 <= max_tree_depth <= L.STACK_SIZE:
        raise ValueError(f"max_tree_depth must be in 1 … {L.STACK_SIZE}")
    if not 0 < cost_scale <= 1:
        raise ValueError("cost_scale must be in (0, 1]")
    plo = np.ascontiguousarray(aabb_min, dtype=np.float32).reshape(-1, 3)
    phi = np.ascontiguousarray(aabb_max, dtype=np.float32).reshape(-1, 3)
    n = len(plo)
    D = max(1, min(max_tree_depth, max_depth if max_depth is not None else auto_max_depth(n)))
    if n == 0:
        gbox = np.array([[np.inf] * 3, [-np.inf] * 3], dtype=np.float32)
    else:
        gbox = np.stack([plo.min(axis=0), phi.max(axis=0)])

    # node fields, collected per round and scattered at the end
    f_slot, f_axis, f_left, f_split, f_depth, f_vmin, f_vmax = [], [], [], [], [], [], []
    leaf_slot, leaf_prim = [], []
    next_slot = 1
    rounds = blowup = 0

    # open nodes
    slot = np.zeros(1, np.int64)
    depth = np.ones(1, np.int64)
    vmin = gbox[:1].astype(np.float32).copy()
    vmax = gbox[1:].astype(np.float32).copy()
    ref_node = np.zeros(n, np.int64)
    ref_prim = np.arange(n, dtype=np.int64)
    ev_ref, ev_pos, ev_st = [], [], []
    for a in range(3):
        pos = np.concatenate([plo[:, a], phi[:, a]])
        order = np.argsort(pos, kind="stable")
        ev_pos.append(pos[order])
        ev_ref.append(np.concatenate([ref_prim, ref_prim])[order])
        ev_st.append(order < n)
    if n == 0:
        f_slot.append(slot)
        f_axis.append(np.full(1, -1))
        f_left.append(np.full(1, -1))
        f_split.append(np.zeros(1, np.float32))
        f_depth.append(depth)
        f_vmin.append(vmin)
        f_vmax.append(vmax)
        slot = slot[:0]

    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        while len(slot):
            rounds += 1
            k = len(slot)
            N = np.bincount(ref_node, minlength=k).astype(np.int64)
            best = np.full(k, np.inf)
            best_axis = np.zeros(k, np.int64)
            best_pos = np.zeros(k, np.float32)
            may_split = depth < D
            if len(ref_node) > MAX_REFS_PER_PRIM * n + 1024:
                blowup += int(may_split.sum())
                may_split[:] = False
            if may_split.any():
                e_base = np.zeros(k, np.int64)
                if k > 1:
                    np.cumsum(2 * N[:-1], out=e_base[1:])
                v0 = vmin.astype(np.float64)
                v1 = vmax.astype(np.float64)
                vd = v1 - v0
                area = vd[:, 0] * vd[:, 1] + vd[:, 1] * vd[:, 2] + vd[:, 2] * vd[:, 0]
                for a in range(3):
                    er, ep, es = ev_ref[a], ev_pos[a], ev_st[a]
                    ne = ref_node[er]
                    m = len(ep)
                    st_i = es.astype(np.int64)
                    cs = np.cumsum(st_i) - st_i  # starts strictly before
                    s_before = cs - cs[e_base][ne]
                    en_i = 1 - st_i
                    ce = np.cumsum(en_i)  # ends up to and including
                    e_incl = ce - (ce - en_i)[e_base][ne]
                    gs = np.empty(m, dtype=bool)
                    gs[0] = True
                    gs[1:] = (ep[1:] != ep[:-1]) | (ne[1:] != ne[:-1])
                    gfirst = np.flatnonzero(gs)
                    glast = np.concatenate([gfirst[1:] - 1, [m - 1]])
                    p = ep[gfirst].astype(np.float64)
                    gn = ne[gfirst]
                    n_l = s_before[gfirst]
                    n_r = N[gn] - e_incl[glast]
                    lo_a, hi_a = v0[gn, a], v1[gn, a]
                    o1, o2 = (a + 1) % 3, (a + 2) % 3
                    s = vd[gn, o1] + vd[gn, o2]
                    q = vd[gn, o1] * vd[gn, o2]
                    a_l = (p - lo_a) * s + q
                    a_r = (hi_a - p) * s + q
                    cost = C_TRAV + C_ISECT * (a_l * n_l + a_r * n_r) / area[gn]
                    cost = np.where((n_l == 0) | (n_r == 0), cost * EMPTY_BONUS, cost)
                    cost = np.where((p > lo_a) & (p < hi_a) & may_split[gn], cost, np.inf)
                    gseg = np.flatnonzero(np.concatenate([[True], gn[1:] != gn[:-1]]))
                    cmin = np.minimum.reduceat(cost, gseg)
                    node_of = gn[gseg]
                    better_nodes = node_of[cmin < best[node_of]]
                    if len(better_nodes):
                        bmask = np.zeros(k, dtype=bool)
                        bmask[better_nodes] = True
                        full_min = np.full(k, np.inf)
                        full_min[node_of] = cmin
                        hit = np.flatnonzero((cost == full_min[gn]) & bmask[gn])
                        hs = gn[hit]
                        fh = np.concatenate([[True], hs[1:] != hs[:-1]])
                        nb, gb = hs[fh], hit[fh]
                        best[nb] = full_min[nb]
                        best_axis[nb] = a
                        best_pos[nb] = ep[gfirst[gb]]
            scale = cost_scale ** ((depth - 1) / max(D - 1, 1))
            split = np.isfinite(best) & (best < C_ISECT * N * scale) & may_split

            # record every open node; leaves get their references
            f_slot.append(slot)
            f_depth.append(depth)
            f_vmin.append(vmin.copy())
            f_vmax.append(vmax.copy())
            f_axis.append(np.where(split, best_axis, -1))
            f_split.append(np.where(split, best_pos, np.float32(0)).astype(np.float32))
            sp = np.flatnonzero(split)
            rank = np.full(k, -1, np.int64)
            rank[sp] = np.arange(len(sp))
            child = next_slot + 2 * np.arange(len(sp), dtype=np.int64)
            next_slot += 2 * len(sp)
            lefts = np.full(k, -1, np.int64)
            lefts[sp] = child
            f_left.append(lefts)
            lm = ~split[ref_node]
            if lm.any():
                leaf_slot.append(slot[ref_node[lm]])
                leaf_prim.append(ref_prim[lm])
            if not len(sp):
                break

            # classify the references of splitting nodes
            go_l = np.zeros(len(ref_node), dtype=bool)
            go_r = np.zeros(len(ref_node), dtype=bool)
            for a in range(3):
                er, ep, es = ev_ref[a], ev_pos[a], ev_st[a]
                ne = ref_node[er]
                m = split[ne] & (best_axis[ne] == a)
                pn = best_pos[ne]
                sm = m & es
                go_l[er[sm]] = ep[sm] < pn[sm]
                em = m & ~es
                go_r[er[em]] = ep[em] > pn[em]

            # children: interleaved (left, right) per splitting node; empty ones are leaves now
            c_cnt = np.stack(
                [np.bincount(ref_node[go_l], minlength=k)[sp], np.bincount(ref_node[go_r], minlength=k)[sp]], axis=1
            ).ravel()
            c_slot = np.stack([child, child + 1], axis=1).ravel()
            c_depth = np.repeat(depth[sp] + 1, 2)
            c_vmin = np.repeat(vmin[sp], 2, axis=0)
            c_vmax = np.repeat(vmax[sp], 2, axis=0)
            r2 = np.arange(len(sp))
            c_vmax[2 * r2, best_axis[sp]] = best_pos[sp]
            c_vmin[2 * r2 + 1, best_axis[sp]] = best_pos[sp]
            empty = c_cnt == 0
            if empty.any():
                e = np.flatnonzero(empty)
                f_slot.append(c_slot[e])
                f_depth.append(c_depth[e])
                f_vmin.append(c_vmin[e])
                f_vmax.append(c_vmax[e])
                f_axis.append(np.full(len(e), -1))
                f_left.append(np.full(len(e), -1))
                f_split.append(np.zeros(len(e), np.float32))
            keep = ~empty
            new_id = np.cumsum(keep) - 1
            k_new = int(keep.sum())

            # new references: the left stream and the right stream, each sorted by new node
            i_l = np.flatnonzero(go_l)
            i_r = np.flatnonzero(go_r)
            key_l = new_id[2 * rank[ref_node[i_l]]]
            key_r = new_id[2 * rank[ref_node[i_r]] + 1]
            n_new = np.bincount(np.concatenate([key_l, key_r]), minlength=k_new).astype(np.int64)
            r_base = np.zeros(k_new, np.int64)
            if k_new > 1:
                np.cumsum(n_new[:-1], out=r_base[1:])
            dest_l = r_base[key_l] + (np.arange(len(key_l)) - _first_in_group(key_l))
            dest_r = r_base[key_r] + (np.arange(len(key_r)) - _first_in_group(key_r))
            r_total = int(n_new.sum())
            new_ref_node = np.empty(r_total, np.int64)
            new_ref_prim = np.empty(r_total, np.int64)
            new_ref_node[dest_l], new_ref_node[dest_r] = key_l, key_r
            new_ref_prim[dest_l], new_ref_prim[dest_r] = ref_prim[i_l], ref_prim[i_r]
            map_l = np.full(len(ref_node), -1, np.int64)
            map_r = np.full(len(ref_node), -1, np.int64)
            map_l[i_l], map_r[i_r] = dest_l, dest_r

            # new events: split stably, straddlers duplicated and clipped at the plane
            e_base_new = 2 * r_base
            for a in range(3):
                er, ep, es = ev_ref[a], ev_pos[a], ev_st[a]
                ne = ref_node[er]
                out_ref = np.empty(2 * r_total, np.int64)
                out_pos = np.empty(2 * r_total, np.float32)
                out_st = np.empty(2 * r_total, dtype=bool)
                for go, mp, clip_end in ((go_l, map_l, True), (go_r, map_r, False)):
                    j = np.flatnonzero(go[er])
                    nr = mp[er[j]]
                    key = new_ref_node[nr]
                    pj = ep[j]
                    nj = ne[j]
                    on_axis = best_axis[nj] == a
                    if clip_end:
                        clip = on_axis & ~es[j] & (pj > best_pos[nj])
                    else:
                        clip = on_axis & es[j] & (pj < best_pos[nj])
                    pj = np.where(clip, best_pos[nj], pj)
                    dest = e_base_new[key] + (np.arange(len(key)) - _first_in_group(key))
                    out_ref[dest], out_pos[dest], out_st[dest] = nr, pj, es[j]
                ev_ref[a], ev_pos[a], ev_st[a] = out_ref, out_pos, out_st

            ref_node, ref_prim = new_ref_node, new_ref_prim
            slot, depth = c_slot[keep], c_depth[keep]
            vmin, vmax = c_vmin[keep], c_vmax[keep]

    # assemble the node arrays
    m = next_slot
    axis = np.full(m, -1, np.int64)
    left = np.full(m, -1, np.int64)
    split_pos = np.zeros(m, np.float32)
    ndepth = np.ones(m, np.int64)
    nvmin = np.zeros((m, 3), np.float32)
    nvmax = np.zeros((m, 3), np.float32)
    for s, ax, lf, spl, dp, v0_, v1_ in zip(f_slot, f_axis, f_left, f_split, f_depth, f_vmin, f_vmax, strict=True):
        axis[s], left[s], split_pos[s], ndepth[s], nvmin[s], nvmax[s] = ax, lf, spl, dp, v0_, v1_

    # depth-first (preorder) rank of every node
    inner = np.flatnonzero(axis >= 0)
    size = np.ones(m, np.int64)
    pre = np.zeros(m, np.int64)
    if len(inner):
        d_in = ndepth[inner]
        order = np.argsort(-d_in, kind="stable")
        inner_desc, d_desc = inner[order], d_in[order]
        levels = np.split(inner_desc, np.flatnonzero(np.diff(d_desc)) + 1)
        for lvl in levels:
            size[lvl] = 1 + size[left[lvl]] + size[left[lvl] + 1]
        for lvl in reversed(levels):
            pre[left[lvl]] = pre[lvl] + 1
            pre[left[lvl] + 1] = pre[lvl] + 1 + size[left[lvl]]

    # leaf lists in depth-first order, each sorted; then algorithm 6
    t_comp = time.perf_counter()
    count = np.zeros(m, np.int64)
    offset = np.zeros(m, np.int64)
    ls = np.concatenate(leaf_slot) if leaf_slot else np.zeros(0, np.int64)
    lp = np.concatenate(leaf_prim) if leaf_prim else np.zeros(0, np.int64)
    references = len(lp)
    if references:
        o = np.lexsort((lp, pre[ls]))
        ls, lp = ls[o], lp[o]
        starts = np.flatnonzero(np.concatenate([[True], ls[1:] != ls[:-1]]))
        leaves_dfs = ls[starts]
        counts = np.diff(np.concatenate([starts, [len(ls)]]))
        count[leaves_dfs] = counts
        if compaction_window > 0:
            buf = lp.astype("<i4").tobytes()
            glob = bytearray()
            win = 4 * int(compaction_window)
            offs = np.empty(len(starts), np.int64)
            for i, (s0, c) in enumerate(zip(starts.tolist(), counts.tolist(), strict=True)):
                key = buf[4 * s0 : 4 * (s0 + c)]
                at = glob.find(key, max(0, len(glob) - win))
                while at != -1 and at % 4:
                    at = glob.find(key, at + 1)
                if at == -1:
                    offs[i] = len(glob) // 4
                    glob += key
                else:
                    offs[i] = at // 4
            offset[leaves_dfs] = offs
            indices = np.frombuffer(bytes(glob), dtype="<i4").astype(np.int64)
        else:
            offset[leaves_dfs] = starts
            indices = lp.copy()
    else:
        indices = np.zeros(0, np.int64)
    compaction_ms = (time.perf_counter() - t_comp) * 1e3

    kd = KdTree(
        axis=axis,
        left=left,
        split=split_pos,
        count=count,
        offset=offset,
        depth=ndepth,
        vmin=nvmin,
        vmax=nvmax,
        indices=indices,
        global_box=gbox.astype(np.float32),
        max_depth=D,
        cost_scale=float(cost_scale),
    )
    leaf = axis < 0
    vd = nvmax.astype(np.float64) - nvmin.astype(np.float64)
    area = vd[:, 0] * vd[:, 1] + vd[:, 1] * vd[:, 2] + vd[:, 2] * vd[:, 0]
    sah = (
        float((C_TRAV * area[~leaf].sum() + C_ISECT * (area[leaf] * count[leaf]).sum()) / area[0])
        if n and area[0] > 0
        else float(C_ISECT * n)
    )
    # The SAH's terms apart, for the cost model (renderer/frame/cost.py).
    sah_nodes = float(area[~leaf].sum() / area[0]) if n and area[0] > 0 else 0.0
    sah_tests = float((area[leaf] * count[leaf]).sum() / area[0]) if n and area[0] > 0 else float(n)
    big = leaf & (count > BIG_LEAF)
    sah_big_tests = (
        float((area[big] * count[big]).sum() / area[0]) if n and area[0] > 0 else float(n if n > BIG_LEAF else 0)
    )
    nonempty = leaf & (count > 0)
    build_ms = (time.perf_counter() - t_start) * 1e3
    kd.stats = KdStats(
        primitives=n,
        nodes=m,
        inner_nodes=int((~leaf).sum()),
        leaves=int(leaf.sum()),
        empty_leaves=int((leaf & (count == 0)).sum()),
        depth_max=int(ndepth.max(initial=1)),
        depth_avg=float(ndepth[leaf].mean()) if leaf.any() else 1.0,
        max_depth=D,
        cost_scale=float(cost_scale),
        references=references,
        indices=len(indices),
        refs_per_prim=references / n if n else 0.0,
        prims_per_leaf_avg=float(count[nonempty].mean()) if nonempty.any() else 0.0,
        sah_cost=sah,
        sah_nodes=sah_nodes,
        sah_tests=sah_tests,
        sah_big_tests=sah_big_tests,
        rounds=rounds,
        blowup_stops=blowup,
        build_ms=build_ms,
        compaction_ms=compaction_ms,
        bytes=int(m * L.NODE_BYTES + len(indices) * 4 + 24),
    )
    return kd


def build_for_spheres(
    centers: np.ndarray,
    radii: np.ndarray,
    max_tree_depth: int = L.STACK_SIZE,
    cost_scale: float = DEFAULT_COST_SCALE,
    **kw,
) -> KdTree:
    lo, hi = sphere_aabbs(centers, radii)
    return build_kdtree(lo, hi, max_tree_depth=max_tree_depth, cost_scale=cost_scale, **kw)


def build_for_scene(scene, max_tree_depth: int = L.STACK_SIZE, cost_scale: float = DEFAULT_COST_SCALE, **kw) -> KdTree:
    """A kd-tree over the scene's spheres then triangles (:mod:`renderer.accel.primitives`)."""
    lo, hi = scene_aabbs(scene)
    return build_kdtree(lo, hi, max_tree_depth=max_tree_depth, cost_scale=cost_scale, **kw)


class KdTreeMethod:
    """Method ``kdtree``: the SAH kd-tree of this module (cost scaling on), rebuilt per request,
    traced by ``shaders/method_kdtree.glsl``. ``max_prims`` is not used: the SAH decides."""

    name = "kdtree"
    label = "kd-tree (SAH)"
    # (no max_prims: the SAH decides leaves)
    capabilities = Capabilities(
        shader="method_kdtree.glsl", settings=("max_tree_depth", "integrator"), meshes_on_gpu=True
    )
    bindings = L.BINDINGS
    glsl_defines = staticmethod(L.glsl_defines)
    cost_scale = DEFAULT_COST_SCALE

    def prepare(
        self,
        scene,
        max_prims: int,
        max_tree_depth: int,
        max_width: int = DEFAULT_TEXTURE_WIDTH,
        update: TreeUpdate = REBUILD,
    ) -> PreparedMethod:
        """Builds a fresh tree every frame: a kd-tree is not refitted (``update`` is ignored)."""
        t0 = time.perf_counter()
        kd = build_for_scene(scene, max_tree_depth, self.cost_scale)
        ms = (time.perf_counter() - t0) * 1e3
        packed = L.pack_kdtree(kd, scene, None, max_width)
        return PreparedMethod(packed, ms, {"method": self.name, **kd.stats.to_json(), **mesh_stats(scene)}, tree=kd)

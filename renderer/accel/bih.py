"""Bounding Interval Hierarchy build (thesis listings 3.3 and 3.4).

The build is the thesis's in-place quicksort over primitive indices, run for
all nodes of one round at once with NumPy instead of one node per recursive
call, so that a per-request rebuild is fast in Python. Each round takes every
open node and does what one pass of listing 3.4's body does for it:

1. leaf when ``count <= max_prims`` or ``depth == max_tree_depth``
   (depth counts the root as 1, as Table 4.2 does);
2. ``split`` = middle of the **node box's** widest axis; a primitive goes
   left when its AABB centre ``< split``; ``nodeL/nodeR`` = the primitives' own
   extent on that axis;
3. *optimized node*: if ``(nodeR - nodeL) * 1.3 <`` the box's extent on the
   axis, shrink the box to ``[nodeL, nodeR]`` and retry the node next round;
4. all primitives on one side: halve the box towards that side and retry
   (no empty child is made);
5. otherwise make an inner node: ``clip_left`` = max of the left AABB maxima,
   ``clip_right`` = min of the right AABB minima, the left child's box is the
   node box with ``max = clip_left``, the right's with ``min = clip_right``,
   and partition the index range in place (left part first).

Listing 3.4 loops forever when all centres coincide, since no split ever
separates them. A retry that cannot move the split any more (float precision
reached) or the ``MAX_RETRIES``-th retry of one node makes a leaf instead,
counted in ``BIHStats.forced_leaves``.

Everything is float32, the GPU's precision: primitive AABBs are rounded
outwards (``nextafter``) so a sphere as the GPU sees it is always inside its
box, and clip planes are exact float32 values the shader compares against.
The right child is stored right after the left one (listing 3.2).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from .. import limits
from ..limits import MAX_RETRIES, MAX_TREE_DEPTH
from ..scene import Scene
from ..tree_update import REBUILD, TreeUpdate
from . import bih_layout as L
from .base import BIG_LEAF, Capabilities, PreparedMethod, gpu_data, mesh_stats
from .primitives import scene_aabbs, sphere_aabbs

OPTIMIZED_NODE_FACTOR = np.float32(1.3)
# MAX_RETRIES (limits): retries (optimized-node shrinks and one-sided halvings) allowed
# per node before it becomes a leaf. float32 halving exhausts its precision long before.


@dataclass
class BIHStats:
    """Table 4.2's statistics plus what this implementation adds.

    Depths count the root as 1. ``leaf_histogram`` holds the fraction of
    leaves with 0, 1, 2, 3, 4 and more than 4 primitives. ``bytes`` is
    Fig. 4.5's memory: nodes (12 B each) + index array (4 B per primitive) +
    global AABB (24 B), the thesis's layout (the GPU's since issue 18, ``bih_layout``:
    16 B per inner node and a 16- or 32-byte sphere record per primitive).
    """
    primitives: int
    inner_nodes: int
    leaves: int
    prims_per_leaf_min: float
    prims_per_leaf_avg: float
    prims_per_leaf_max: float
    depth_min: int
    depth_avg: float
    depth_max: int
    leaf_histogram: list[float]
    optimized_nodes: int
    one_sided_retries: int
    forced_leaves: int
    rounds: int
    build_ms: float
    bytes: int
    sah_nodes: float = 0.0
    sah_tests: float = 0.0
    sah_big_tests: float = 0.0      # of sah_tests, those in leaves of more than BIG_LEAF spheres

    def to_json(self) -> dict:
        return asdict(self)


@dataclass
class BIH:
    """A built hierarchy.

    nodes: uint32 (count, 3) in the layout of :mod:`bih_layout`, root at 0.
    indices: int32 (n,), the sorted primitive-index array leaves point into.
    global_aabb: float32 (2, 3) min and max; for n = 0 min = +inf, max = -inf.
    node_depths: int32 depth of every node, inner and leaf; the root is depth 1.
    """
    nodes: np.ndarray
    indices: np.ndarray
    global_aabb: np.ndarray
    node_depths: np.ndarray
    max_prims: int
    max_tree_depth: int
    stats: BIHStats


def build_bih(aabb_min: np.ndarray, aabb_max: np.ndarray, max_prims: int = 8,
              max_tree_depth: int = MAX_TREE_DEPTH) -> BIH:
    """Build a BIH over primitives given by float32 AABBs ``(n, 3)``.

    Returns the node array, the sorted index array, the global AABB and the
    statistics. Terminates for any finite input, degenerate ones included.
    """
    t0 = time.perf_counter()
    if max_prims < 1:
        raise ValueError("max_prims must be >= 1")
    if not 1 <= max_tree_depth <= MAX_TREE_DEPTH:
        raise ValueError(f"max_tree_depth must be in 1 … {MAX_TREE_DEPTH}")
    pmin = np.ascontiguousarray(aabb_min, dtype=np.float32).reshape(-1, 3)
    pmax = np.ascontiguousarray(aabb_max, dtype=np.float32).reshape(-1, 3)
    n = len(pmin)
    if n >= L.MAX_NODES // 2:
        raise ValueError(f"too many primitives for the 30-bit child index: {n}")
    centre = (pmin + pmax) * np.float32(0.5)
    # Flat views: element (prim, axis) lives at prim*3 + axis.
    fmin, fmax, fcen = pmin.ravel(), pmax.ravel(), centre.ravel()

    nodes = L.empty_nodes(max(2 * n - 1, 1))
    node_depth = np.zeros(len(nodes), dtype=np.int32)
    indices = np.arange(n, dtype=np.int32)
    if n == 0:
        gbox = np.array([[np.inf] * 3, [-np.inf] * 3], dtype=np.float32)
    else:
        gbox = np.stack([pmin.min(axis=0), pmax.max(axis=0)])

    # Open nodes: slot in the node array, index range [lo, hi), box, depth, retries.
    slot = np.zeros(1, dtype=np.int64)
    lo = np.zeros(1, dtype=np.int64)
    hi = np.full(1, n, dtype=np.int64)
    bmin = gbox[:1].copy() if n else np.zeros((1, 3), np.float32)
    bmax = gbox[1:].copy() if n else np.zeros((1, 3), np.float32)
    depth = np.ones(1, dtype=np.int64)
    retries = np.zeros(1, dtype=np.int64)
    next_slot = 1
    optimized = one_sided = forced = rounds = 0
    leaf_slots: list[np.ndarray] = []

    # Surface areas for the cost model (renderer/cost.py): Σ over inner nodes of their box's
    # area, Σ over leaves of area × primitives; relative to the root's, the expected node
    # visits and primitive tests of a ray through the root box (the SAH's terms).
    area_inner = 0.0
    area_leaf_prims = 0.0
    area_big_prims = 0.0

    def make_leaves(mask: np.ndarray) -> None:
        nonlocal area_leaf_prims, area_big_prims
        cnt = hi[mask] - lo[mask]
        a = _half_area(bmin[mask], bmax[mask]) * cnt
        area_leaf_prims += float(a.sum())
        area_big_prims += float(a[cnt > BIG_LEAF].sum())
        s = slot[mask]
        nodes[s, 0] = np.uint32(L.LEAF_TAG)
        nodes[s, 1] = lo[mask].astype(np.uint32)
        nodes[s, 2] = (hi[mask] - lo[mask]).astype(np.uint32)
        node_depth[s] = depth[mask]
        leaf_slots.append(s)

    while len(slot):
        rounds += 1
        count = hi - lo
        leaf = (count <= max_prims) | (depth >= max_tree_depth)
        if leaf.any():
            make_leaves(leaf)
            keep = ~leaf
            slot, lo, hi, bmin, bmax, depth, retries, count = (
                slot[keep], lo[keep], hi[keep], bmin[keep], bmax[keep], depth[keep], retries[keep], count[keep])
            if not len(slot):
                break
        k = len(slot)
        ext = bmax - bmin
        axis = np.argmax(ext, axis=1)
        rows = np.arange(k)
        a_min, a_max = bmin[rows, axis], bmax[rows, axis]
        split = (a_min + a_max) * np.float32(0.5)

        # Gather the open nodes' elements: positions lo..hi-1 of each, concatenated.
        starts = np.zeros(k, dtype=np.int64)
        np.cumsum(count[:-1], out=starts[1:])
        total = int(starts[-1] + count[-1])
        seg = np.repeat(np.arange(k), count)
        pos = np.arange(total, dtype=np.int64) + np.repeat(lo - starts, count)
        prim = indices[pos].astype(np.int64)
        flat = prim * 3 + axis[seg]
        left = fcen[flat] < split[seg]
        emin, emax = fmin[flat], fmax[flat]

        node_l = np.minimum.reduceat(emin, starts)
        node_r = np.maximum.reduceat(emax, starts)
        n_left = np.add.reduceat(left.astype(np.int64), starts)

        # Listing 3.4 lines 27-38: optimized node, then the one-sided retries.
        shrink = (node_r - node_l) * OPTIMIZED_NODE_FACTOR < (a_max - a_min)
        all_left = ~shrink & (n_left == count)
        all_right = ~shrink & (n_left == 0)
        do_split = ~(shrink | all_left | all_right)
        retry = ~do_split
        optimized += int(shrink.sum())
        one_sided += int(all_left.sum() + all_right.sum())

        new_min = np.where(shrink, node_l, np.where(all_right, split, a_min))
        new_max = np.where(shrink, node_r, np.where(all_left, split, a_max))
        # A retry that no longer changes the box (float precision reached), or
        # one too many, ends the node as a leaf: listing 3.4 would loop forever.
        stuck = retry & (((new_min == a_min) & (new_max == a_max)) | (retries + 1 > MAX_RETRIES))
        bmin[rows, axis] = new_min
        bmax[rows, axis] = new_max

        if stuck.any():
            forced += int(stuck.sum())
            make_leaves(stuck)

        # Inner nodes: clip planes and the in-place partition (left part first).
        sp = np.flatnonzero(do_split)
        m = len(sp)
        if m:
            area_inner += float(_half_area(bmin[sp], bmax[sp]).sum())
            neg = np.float32(-np.inf)
            pos_inf = np.float32(np.inf)
            clip_l = np.maximum.reduceat(np.where(left, emax, neg), starts)[sp]
            clip_r = np.minimum.reduceat(np.where(left, pos_inf, emin), starts)[sp]
            in_split = do_split[seg]
            li = left.astype(np.int64)
            excl = np.cumsum(li) - li                      # lefts before each element
            left_rank = excl - excl[starts][seg]           # ... within its segment
            local = np.arange(total, dtype=np.int64) - starts[seg]
            dest = np.where(left, lo[seg] + left_rank, lo[seg] + n_left[seg] + (local - left_rank))
            dest = dest[in_split]
            indices[dest] = prim[in_split]

            child = next_slot + 2 * np.arange(m, dtype=np.int64)
            next_slot += 2 * m
            s = slot[sp]
            ax = axis[sp]
            nodes[s, 0] = (ax.astype(np.uint32) << np.uint32(L.AXIS_SHIFT)) | child.astype(np.uint32)
            nodes[s, 1] = clip_l.astype(np.float32).view(np.uint32)
            nodes[s, 2] = clip_r.astype(np.float32).view(np.uint32)
            node_depth[s] = depth[sp]

            lbmin, lbmax = bmin[sp].copy(), bmax[sp].copy()
            rbmin, rbmax = bmin[sp].copy(), bmax[sp].copy()
            r = np.arange(m)
            lbmax[r, ax] = clip_l
            rbmin[r, ax] = clip_r
            mid = lo[sp] + n_left[sp]
            cont = retry & ~stuck
            slot = np.concatenate([slot[cont], child, child + 1])
            lo = np.concatenate([lo[cont], lo[sp], mid])
            hi = np.concatenate([hi[cont], mid, hi[sp]])
            bmin = np.concatenate([bmin[cont], lbmin, rbmin])
            bmax = np.concatenate([bmax[cont], lbmax, rbmax])
            depth = np.concatenate([depth[cont], depth[sp] + 1, depth[sp] + 1])
            retries = np.concatenate([retries[cont] + 1, np.zeros(2 * m, np.int64)])
        else:
            cont = retry & ~stuck
            slot, lo, hi, bmin, bmax, depth = slot[cont], lo[cont], hi[cont], bmin[cont], bmax[cont], depth[cont]
            retries = retries[cont] + 1

    nodes = nodes[:next_slot]
    node_depth = node_depth[:next_slot]
    leaves = np.concatenate(leaf_slots) if leaf_slots else np.zeros(0, np.int64)
    counts = nodes[leaves, 2].astype(np.int64)
    depths = node_depth[leaves]
    hist = [float(np.mean(counts == i)) for i in range(5)] + [float(np.mean(counts > 4))]
    build_ms = (time.perf_counter() - t0) * 1e3
    stats = BIHStats(
        primitives=n, inner_nodes=int(next_slot - len(leaves)), leaves=int(len(leaves)),
        prims_per_leaf_min=float(counts.min()), prims_per_leaf_avg=float(counts.mean()),
        prims_per_leaf_max=float(counts.max()),
        depth_min=int(depths.min()), depth_avg=float(depths.mean()), depth_max=int(depths.max()),
        leaf_histogram=hist, optimized_nodes=optimized, one_sided_retries=one_sided, forced_leaves=forced,
        rounds=rounds, build_ms=build_ms, bytes=int(next_slot * L.NODE_BYTES + n * 4 + 24),
        **_expected_work(area_inner, area_leaf_prims, area_big_prims, gbox, n))
    return BIH(nodes=nodes, indices=indices, global_aabb=gbox.astype(np.float32), node_depths=node_depth,
               max_prims=max_prims, max_tree_depth=max_tree_depth, stats=stats)


def _half_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    d = np.maximum(hi.astype(np.float64) - lo.astype(np.float64), 0.0)
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]


def _expected_work(area_inner: float, area_leaf_prims: float, area_big_prims: float, gbox: np.ndarray,
                   n: int) -> dict[str, float]:
    """``sah_nodes``, ``sah_tests``: node visits and primitive tests a ray through the root box
    can expect (areas relative to the root's); ``sah_big_tests`` the part of the tests in
    leaves of more than BIG_LEAF primitives. A root of no area (all primitives at one point)
    is one leaf of n tests."""
    root = float(_half_area(gbox[0], gbox[1])) if n else 0.0
    if not root > 0:
        return {"sah_nodes": 0.0, "sah_tests": float(n), "sah_big_tests": float(n if n > BIG_LEAF else 0)}
    return {"sah_nodes": area_inner / root, "sah_tests": area_leaf_prims / root, "sah_big_tests": area_big_prims / root}


def build_for_spheres(centers: np.ndarray, radii: np.ndarray, max_prims: int = 8,
                      max_tree_depth: int = MAX_TREE_DEPTH) -> BIH:
    """Listing 3.3: sphere AABBs, the global AABB, then the subdivision."""
    lo, hi = sphere_aabbs(centers, radii)
    return build_bih(lo, hi, max_prims=max_prims, max_tree_depth=max_tree_depth)


def build_for_scene(scene: Scene, max_prims: int = 8, max_tree_depth: int = MAX_TREE_DEPTH) -> BIH:
    """A BIH over the scene's spheres and triangles (tree primitive ``i``: sphere ``i``, then
    triangle ``i − n_spheres``; :mod:`renderer.accel.primitives`). Spheres only: the same
    tree as :func:`build_for_spheres`."""
    lo, hi = scene_aabbs(scene)
    return build_bih(lo, hi, max_prims=max_prims, max_tree_depth=max_tree_depth)


class BoundingIntervalHierarchy:
    """Method ``bih``: the thesis's BIH (listings 3.3–3.5), rebuilt per request and traced
    by ``shaders/method_bih.glsl``."""
    name = "bih"
    capabilities = Capabilities(shader="method_bih.glsl", settings=("max_prims", "max_tree_depth"),
                                meshes_on_gpu=True)
    bindings = L.BINDINGS
    glsl_defines = staticmethod(L.glsl_defines)

    def prepare(self, scene: Scene, max_prims: int, max_tree_depth: int,
                max_width: int = limits.DEFAULT_TEXTURE_WIDTH, update: TreeUpdate = REBUILD) -> PreparedMethod:
        t0 = time.perf_counter()
        bih = build_for_scene(scene, max_prims, max_tree_depth)
        build_ms = (time.perf_counter() - t0) * 1e3
        return PreparedMethod(gpu_data(scene, lambda: L.pack_bih(bih, scene, max_width), True), build_ms,
                              {"method": self.name, **bih.stats.to_json(), **mesh_stats(scene)}, tree=bih)

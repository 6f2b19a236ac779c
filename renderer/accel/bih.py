"""Bounding Interval Hierarchy build (thesis listings 3.3 and 3.4).

The build is the thesis's in-place quicksort over primitive indices, run for
all nodes of one round at once with NumPy instead of one node per recursive
call, so that a per-request rebuild is fast in Python. Each round takes every
open node and does what one pass of listing 3.4's body does for it:

0. *(trees over triangles or analytic shapes only, ``empty_cuts``; beyond the thesis)* cut off empty space:
   while the node's **region** — the part of space the traversal's intervals bound there,
   the global box clipped by every ancestor's planes — has, on some axis, an empty slab
   above or below its primitives' tight box whose removal takes more than
   ``EMPTY_CUT_AREA`` (10 %) of the region's surface area, the node becomes a *cut*: an
   inner node on that axis whose one child holds all its primitives, bounded by the
   primitives' extent on that side (``clip_left`` = their maximum for a cut above,
   ``clip_right`` = their minimum for a cut below), and whose other child is an empty leaf
   behind a clip plane at ``±bih_layout.EMPTY_CLIP`` that no ray reaches; the primitives'
   child goes on in the same round (at most six cuts, one level each, and never past
   ``max_tree_depth``). The largest slab is cut first;
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

Why the cuts: a BIH node bounds its children on one axis only, and the thesis's optimized
node (step 3) shrinks the box the *build* splits, not what the traversal sees. For spheres
spread through a volume that costs little (and the trees of sphere scenes stay the thesis's,
bit for bit, as Table 4.2 and the frame catalogue of tests/golden check). A tessellated surface is another
matter. On the experiments' teapot (``bench/experiments/meshes.py``, 102,720 triangles)
the thesis's build left the median leaf a region 8.9× its triangles' extent in y (a tenth
of the leaves over 179×) and 21× their surface area, so a ray passing near the surface
crossed many leaves and tested their triangles: 52 tests and 34 node visits per primary ray
(160 × 272 rays of its view, 79 % missing the teapot; the worst, a miss, tested 866
triangles in 154 leaves) against the BVH's 0.7 and 6. With the cuts: 2.7 tests and 12 visits.

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
from dataclasses import asdict, dataclass, fields

import numpy as np

from .. import limits
from ..geometry.scene import Scene
from ..limits import MAX_RETRIES, MAX_TREE_DEPTH
from ..scenes.tree_update import REBUILD, TreeUpdate
from . import bih_layout as L
from .base import BIG_LEAF, Capabilities, PreparedMethod, mesh_stats
from .primitives import scene_aabbs, sphere_aabbs
from .ranges import positions, segments

OPTIMIZED_NODE_FACTOR = np.float32(1.3)
# Step 0: the least share of a region's surface area (the probability that a ray through the
# region meets the slab) a cut must take off. Measured on the teapot and an icosphere grid,
# 0.05 … 0.3 trace within a few per cent of each other; smaller values deepen the tree.
EMPTY_CUT_AREA = 0.1
# MAX_RETRIES (limits): retries (optimized-node shrinks and one-sided halvings) allowed
# per node before it becomes a leaf. float32 halving exhausts its precision long before.


@dataclass
class BIHStats:
    """Table 4.2's statistics plus what this implementation adds.

    ``inner_nodes`` counts the cuts too, ``leaves`` only the leaves that hold primitives
    (not a cut's empty child), so ``leaves = inner_nodes − cut_nodes + 1``, as the thesis's
    own table has inner nodes beyond ``leaves − 1``. Depths count the root as 1. ``leaf_histogram``
    holds the fraction of leaves with 0, 1, 2, 3, 4 and more than 4 primitives. ``bytes`` is
    Fig. 4.5's memory: nodes (12 B each) + index array (4 B per primitive) +
    global AABB (24 B), the thesis's layout (the GPU reads ``bih_layout``'s records:
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
    sah_big_tests: float = 0.0  # of sah_tests, those in leaves of more than BIG_LEAF spheres
    cut_nodes: int = 0  # step 0's cuts: inner nodes whose other child is an empty leaf

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


def build_bih(
    aabb_min: np.ndarray,
    aabb_max: np.ndarray,
    max_prims: int = 8,
    max_tree_depth: int = MAX_TREE_DEPTH,
    empty_cuts: bool = False,
) -> BIH:
    """Build a BIH over primitives given by float32 AABBs ``(n, 3)``.

    Returns the node array, the sorted index array, the global AABB and the
    statistics. Terminates for any finite input, degenerate ones included.
    ``empty_cuts``: cut empty space off every node first (the module's docstring, step 0).
    """
    t0 = time.perf_counter()
    if max_prims < 1:
        raise ValueError("max_prims must be >= 1")
    if not 1 <= max_tree_depth <= MAX_TREE_DEPTH:
        raise ValueError(f"max_tree_depth must be in 1 … {MAX_TREE_DEPTH}")
    pmin = np.ascontiguousarray(aabb_min, dtype=np.float32).reshape(-1, 3)
    pmax = np.ascontiguousarray(aabb_max, dtype=np.float32).reshape(-1, 3)
    n = len(pmin)
    # At most 2n − 1 nodes, and with cuts at most six cuts (two nodes each) above each of them.
    if (13 if empty_cuts else 1) * 2 * n >= L.MAX_NODES:
        raise ValueError(f"too many primitives for the 30-bit child index: {n}")
    centre = (pmin + pmax) * np.float32(0.5)
    # Flat views: element (prim, axis) lives at prim*3 + axis.
    fmin, fmax, fcen = pmin.ravel(), pmax.ravel(), centre.ravel()
    # With cuts, each primitive's row (min, −max): one minimum over a node's rows is its tight box.
    rows6 = np.concatenate([pmin, -pmax], axis=1) if empty_cuts else None

    store = _NodeStore(max(2 * n - 1, 1))
    indices = np.arange(n, dtype=np.int32)
    if n == 0:
        gbox = np.array([[np.inf] * 3, [-np.inf] * 3], dtype=np.float32)
    else:
        gbox = np.stack([pmin.min(axis=0), pmax.max(axis=0)])
    box0 = (gbox[:1].copy(), gbox[1:].copy()) if n else (np.zeros((1, 3), np.float32),) * 2
    op = _Open(
        slot=np.zeros(1, np.int64),
        lo=np.zeros(1, np.int64),
        hi=np.full(1, n, np.int64),
        bmin=box0[0].copy(),
        bmax=box0[1].copy(),
        rmin=box0[0].copy(),
        rmax=box0[1].copy(),
        depth=np.ones(1, np.int64),
        retries=np.zeros(1, np.int64),
    )
    optimized = one_sided = forced = rounds = cuts = 0
    leaf_slots: list[np.ndarray] = []

    # Surface areas for the cost model (renderer/frame/cost.py): Σ over inner nodes of their box's
    # area, Σ over leaves of area × primitives; relative to the root's, the expected node
    # visits and primitive tests of a ray through the root box (the SAH's terms).
    area = {"inner": 0.0, "leaf_prims": 0.0, "big_prims": 0.0}

    def make_leaves(mask: np.ndarray) -> None:
        cnt = op.hi[mask] - op.lo[mask]
        # A ray tests a leaf's primitives wherever it passes its clip planes: the region they bound
        # (rmin/rmax), not the box the one-sided retries shrank (primitives at one point shrink that
        # to nothing, while every ray through the root still tests them all).
        a = _half_area(op.rmin[mask], op.rmax[mask]) * cnt
        area["leaf_prims"] += float(a.sum())
        area["big_prims"] += float(a[cnt > BIG_LEAF].sum())
        s = op.slot[mask]
        store.leaves(s, op.lo[mask], cnt, op.depth[mask])
        leaf_slots.append(s)

    while len(op.slot):
        rounds += 1
        count = op.hi - op.lo
        if empty_cuts and n:
            starts, seg = segments(count)
            prim = indices[positions(op.lo, starts, seg)]
            assert rows6 is not None  # made when empty_cuts
            rows = np.take(rows6, prim, axis=0)
            tight = np.minimum.reduceat(rows, starts, axis=0)
            cuts += _cut_empty_space(op, tight[:, :3], -tight[:, 3:], store, max_tree_depth, area)
        leaf = (count <= max_prims) | (op.depth >= max_tree_depth)
        if leaf.all():
            make_leaves(leaf)
            break
        # The split axis: the box's widest; the elements' AABB on it and its centre (the
        # same float32 values from the rows as from the flat arrays).
        axis = np.argmax(op.bmax - op.bmin, axis=1)
        if empty_cuts:
            r = rows.ravel()
            flat = np.arange(len(prim), dtype=np.int64) * 6 + axis[seg]
            emin, emax = r[flat], -r[flat + 3]
        if leaf.any():
            make_leaves(leaf)
            keep = ~leaf
            op, count, axis = op.select(keep), count[keep], axis[keep]
            if empty_cuts:
                el = keep[seg]
                prim, emin, emax = prim[el], emin[el], emax[el]
                starts, seg = segments(count)
        if empty_cuts:
            cen = (emin + emax) * np.float32(0.5)
        else:
            starts, seg = segments(count)
            prim = indices[positions(op.lo, starts, seg)]
            flat = prim.astype(np.int64) * 3 + axis[seg]
            emin, emax, cen = fmin[flat], fmax[flat], fcen[flat]
        k = len(op.slot)
        at = np.arange(k)
        a_min, a_max = op.bmin[at, axis], op.bmax[at, axis]
        split = (a_min + a_max) * np.float32(0.5)
        left = cen < split[seg]

        node_l = np.minimum.reduceat(emin, starts)
        node_r = np.maximum.reduceat(emax, starts)
        n_left = np.add.reduceat(left, starts, dtype=np.int64)

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
        stuck = retry & (((new_min == a_min) & (new_max == a_max)) | (op.retries + 1 > MAX_RETRIES))
        op.bmin[at, axis] = new_min
        op.bmax[at, axis] = new_max

        if stuck.any():
            forced += int(stuck.sum())
            make_leaves(stuck)

        cont = op.select(retry & ~stuck)
        cont.retries += 1
        nxt = [cont]
        sp = np.flatnonzero(do_split)
        if len(sp):
            # Inner nodes: clip planes and the in-place partition (left part first).
            area["inner"] += float(_half_area(op.bmin[sp], op.bmax[sp]).sum())
            clip_l = np.maximum.reduceat(np.where(left, emax, np.float32(-np.inf)), starts)[sp]
            clip_r = np.minimum.reduceat(np.where(left, np.float32(np.inf), emin), starts)[sp]
            # Element i of a node whose elements start at s: ``lo + (lefts before i in the
            # node)`` when it goes left, else ``lo + n_left + (rights before it in the node)``.
            before = np.cumsum(left, dtype=np.int64) - left  # lefts before i, all nodes
            base_l = op.lo - before[starts]
            base_r = op.lo + n_left - starts + before[starts]
            dest = np.where(
                left,
                before + np.repeat(base_l, count),
                np.arange(len(left), dtype=np.int64) - before + np.repeat(base_r, count),
            )
            if len(sp) == k:
                indices[dest] = prim
            else:
                moved = np.repeat(do_split, count)
                indices[dest[moved]] = prim[moved]

            node = op.select(sp)
            ax = axis[sp]
            child = store.inner(node.slot, ax, clip_l, clip_r, node.depth)
            mid = node.lo + n_left[sp]
            lc, rc = node.select(slice(None)), node.select(slice(None))
            at = np.arange(len(sp))
            lc.slot, lc.hi = child, mid
            rc.slot, rc.lo = child + 1, mid
            lc.bmax[at, ax] = lc.rmax[at, ax] = clip_l
            rc.bmin[at, ax] = rc.rmin[at, ax] = clip_r
            for c in (lc, rc):
                c.depth = c.depth + 1
                c.retries = np.zeros(len(sp), np.int64)
            nxt += [lc, rc]
        op = _Open.concat(nxt)

    nodes, node_depth = store.done()
    leaves = np.concatenate(leaf_slots) if leaf_slots else np.zeros(0, np.int64)
    counts = nodes[leaves, 2].astype(np.int64)
    depths = node_depth[leaves]
    hist = [float(np.mean(counts == i)) for i in range(5)] + [float(np.mean(counts > 4))]
    build_ms = (time.perf_counter() - t0) * 1e3
    stats = BIHStats(
        primitives=n,
        inner_nodes=int(len(nodes) - len(leaves) - cuts),
        leaves=int(len(leaves)),
        prims_per_leaf_min=float(counts.min()),
        prims_per_leaf_avg=float(counts.mean()),
        prims_per_leaf_max=float(counts.max()),
        depth_min=int(depths.min()),
        depth_avg=float(depths.mean()),
        depth_max=int(depths.max()),
        leaf_histogram=hist,
        optimized_nodes=optimized,
        one_sided_retries=one_sided,
        forced_leaves=forced,
        rounds=rounds,
        build_ms=build_ms,
        bytes=int(len(nodes) * L.NODE_BYTES + n * 4 + 24),
        cut_nodes=cuts,
        **_expected_work(area["inner"], area["leaf_prims"], area["big_prims"], gbox, n),
    )
    return BIH(
        nodes=nodes,
        indices=indices,
        global_aabb=gbox.astype(np.float32),
        node_depths=node_depth,
        max_prims=max_prims,
        max_tree_depth=max_tree_depth,
        stats=stats,
    )


def _cut_empty_space(
    op: _Open, tmin: np.ndarray, tmax: np.ndarray, store: _NodeStore, max_tree_depth: int, area: dict
) -> int:
    """Step 0 of the module's docstring on the open nodes ``op`` (their primitives' tight
    boxes ``tmin``/``tmax``): while the best cut of a node — the side of its region, on any
    axis, whose empty slab takes the most surface area off it — takes more than
    ``EMPTY_CUT_AREA`` of the region's area and the node is above ``max_tree_depth``, make
    the node a cut and go on with its primitives' child. Returns the number of cuts."""
    made = 0
    act = np.flatnonzero(op.depth < max_tree_depth)
    while len(act):
        rmin, rmax = op.rmin[act], op.rmax[act]
        ext = (rmax - rmin).astype(np.float64)
        gap_lo = (tmin[act] - rmin).astype(np.float64)
        gap_hi = (rmax - tmax[act]).astype(np.float64)
        # The half-area ext_x·ext_y + ext_y·ext_z + ext_z·ext_x loses gap × (the other two extents).
        gain = np.maximum(gap_lo, gap_hi) * (ext.sum(axis=1, keepdims=True) - ext)
        ax = np.argmax(gain, axis=1)
        r = np.arange(len(act))
        half_area = ext[:, 0] * ext[:, 1] + ext[:, 1] * ext[:, 2] + ext[:, 2] * ext[:, 0]
        ok = gain[r, ax] > EMPTY_CUT_AREA * half_area
        act, ax, r = act[ok], ax[ok], r[ok]
        if not len(act):
            break
        made += len(act)
        top = gap_hi[r, ax] >= gap_lo[r, ax]
        value = np.where(top, tmax[act, ax], tmin[act, ax])
        area["inner"] += float(_half_area(op.bmin[act], op.bmax[act]).sum())
        op.slot[act] = store.cut(op.slot[act], ax, top, value, op.lo[act], op.depth[act])
        op.depth[act] += 1
        t, b = act[top], act[~top]
        op.rmax[t, ax[top]] = value[top]
        op.rmin[b, ax[~top]] = value[~top]
        op.bmax[t, ax[top]] = np.minimum(op.bmax[t, ax[top]], value[top])
        op.bmin[b, ax[~top]] = np.maximum(op.bmin[b, ax[~top]], value[~top])
        act = act[op.depth[act] < max_tree_depth]
    return made


@dataclass
class _Open:
    """The open nodes of a round: slot in the node array, index range ``[lo, hi)``, box
    (float32 (k, 3) ``bmin``/``bmax``: where listing 3.4's rules put the split), region
    (``rmin``/``rmax``: what the traversal's intervals bound there, the box before the
    thesis's silent shrinks and halvings), depth (root = 1), retries."""

    slot: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    bmin: np.ndarray
    bmax: np.ndarray
    rmin: np.ndarray
    rmax: np.ndarray
    depth: np.ndarray
    retries: np.ndarray

    def select(self, which) -> _Open:
        """The nodes ``which`` (a mask, indices or a slice), as copies."""
        return _Open(*(np.array(getattr(self, f.name)[which]) for f in fields(self)))

    @staticmethod
    def concat(parts: list[_Open]) -> _Open:
        return _Open(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(_Open)))


class _NodeStore:
    """The build's node array as it grows (thesis layout, :mod:`bih_layout`) and each
    node's depth; siblings are allocated in pairs, the right one after the left (listing 3.2)."""

    def __init__(self, capacity: int):
        self.nodes = L.empty_nodes(capacity)
        self.depth = np.zeros(capacity, dtype=np.int32)
        self.used = 1  # the root

    def _pairs(self, m: int) -> np.ndarray:
        need = self.used + 2 * m
        if need > len(self.nodes):
            grow = max(need, len(self.nodes) * 5 // 4) - len(self.nodes)
            self.nodes = np.concatenate([self.nodes, L.empty_nodes(grow)])
            self.depth = np.concatenate([self.depth, np.zeros(grow, np.int32)])
        child = self.used + 2 * np.arange(m, dtype=np.int64)
        self.used = need
        return child

    def inner(self, s, axis, clip_l, clip_r, depth) -> np.ndarray:
        """Inner nodes at slots ``s``; returns their left children's slots."""
        child = self._pairs(len(s))
        self.nodes[s, 0] = (axis.astype(np.uint32) << np.uint32(L.AXIS_SHIFT)) | child.astype(np.uint32)
        self.nodes[s, 1] = np.asarray(clip_l, np.float32).view(np.uint32)
        self.nodes[s, 2] = np.asarray(clip_r, np.float32).view(np.uint32)
        self.depth[s] = depth
        return child

    def leaves(self, s, offset, count, depth) -> None:
        self.nodes[s, 0] = np.uint32(L.LEAF_TAG)
        self.nodes[s, 1] = offset.astype(np.uint32)
        self.nodes[s, 2] = count.astype(np.uint32)
        self.depth[s] = depth

    def cut(self, s, axis, top, value, offset, depth) -> np.ndarray:
        """Cuts at slots ``s``: ``top`` cuts off the space above ``value`` on ``axis`` (the
        primitives left, clip_left = value; the right child empty, clip_right = +EMPTY_CLIP),
        else the space below it (the left child empty, clip_left = −EMPTY_CLIP; the primitives
        right, clip_right = value). The empty child is a leaf of no primitives at ``offset``.
        Returns the slots of the primitives' children."""
        far = np.float32(L.EMPTY_CLIP)
        child = self.inner(s, axis, np.where(top, value, -far), np.where(top, far, value), depth)
        self.leaves(child + top, offset, np.zeros(len(s), np.int64), depth + 1)
        return child + ~top

    def done(self) -> tuple[np.ndarray, np.ndarray]:
        return self.nodes[: self.used], self.depth[: self.used]


def _half_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    d = np.maximum(hi.astype(np.float64) - lo.astype(np.float64), 0.0)
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]


def _expected_work(
    area_inner: float, area_leaf_prims: float, area_big_prims: float, gbox: np.ndarray, n: int
) -> dict[str, float]:
    """``sah_nodes``, ``sah_tests``: node visits and primitive tests a ray through the root box
    can expect (areas relative to the root's); ``sah_big_tests`` the part of the tests in
    leaves of more than BIG_LEAF primitives. A root of no area (all primitives at one point)
    is one leaf of n tests."""
    root = float(_half_area(gbox[0], gbox[1])) if n else 0.0
    if not root > 0:
        return {"sah_nodes": 0.0, "sah_tests": float(n), "sah_big_tests": float(n if n > BIG_LEAF else 0)}
    return {"sah_nodes": area_inner / root, "sah_tests": area_leaf_prims / root, "sah_big_tests": area_big_prims / root}


def build_for_spheres(
    centers: np.ndarray, radii: np.ndarray, max_prims: int = 8, max_tree_depth: int = MAX_TREE_DEPTH
) -> BIH:
    """Listing 3.3: sphere AABBs, the global AABB, then the subdivision."""
    lo, hi = sphere_aabbs(centers, radii)
    return build_bih(lo, hi, max_prims=max_prims, max_tree_depth=max_tree_depth)


def build_for_scene(scene: Scene, max_prims: int = 8, max_tree_depth: int = MAX_TREE_DEPTH) -> BIH:
    """A BIH over the scene's spheres, triangles and analytic shapes (tree primitive ``i``:
    sphere ``i``, then the triangles, then the shapes; :mod:`renderer.accel.primitives`), with
    step 0's empty-space cuts when there are triangles or shapes. Spheres only: the same tree
    as :func:`build_for_spheres`."""
    lo, hi = scene_aabbs(scene)
    return build_bih(
        lo, hi, max_prims=max_prims, max_tree_depth=max_tree_depth, empty_cuts=scene.n_triangles + scene.n_shapes > 0
    )


class BoundingIntervalHierarchy:
    """Method ``bih``: the thesis's BIH (listings 3.3–3.5), rebuilt per request and traced
    by ``shaders/method_bih.glsl``."""

    name = "bih"
    label = "BIH (thesis)"
    capabilities = Capabilities(
        shader="method_bih.glsl", settings=("max_prims", "max_tree_depth", "integrator"), meshes_on_gpu=True
    )
    bindings = L.BINDINGS
    glsl_defines = staticmethod(L.glsl_defines)

    def prepare(
        self,
        scene: Scene,
        max_prims: int,
        max_tree_depth: int,
        max_width: int = limits.DEFAULT_TEXTURE_WIDTH,
        update: TreeUpdate = REBUILD,
    ) -> PreparedMethod:
        t0 = time.perf_counter()
        bih = build_for_scene(scene, max_prims, max_tree_depth)
        build_ms = (time.perf_counter() - t0) * 1e3
        return PreparedMethod(
            L.pack_bih(bih, scene, max_width),
            build_ms,
            {"method": self.name, **bih.stats.to_json(), **mesh_stats(scene)},
            tree=bih,
        )

"""The BVH's layouts, defined once for packer, shader and tests: the build's and the GPU's.

**Build** (:class:`renderer.accel.bvh.BVH`): struct of arrays — per node its box
(``bmin``/``bmax``), ``left`` (the right child is at ``left + 1``: siblings are stored in
pairs; −1 in leaves), the range ``first``/``count`` of the index array and Reiter's near
mask (listing 4.13: bit ``s`` says which child to visit first for a ray of direction
octant ``s``, octant bit ``a`` set when ``d[a] < 0``; 0 = left, 1 = right). Its memory
(``BVHStats.bytes``) counts ``NODE_BYTES`` = 32 per node: two boxes' corners and two words.

**Conversion** (:func:`gpu_records`): an inner node's record holds both children's boxes,
which is what the traversal tests there; a leaf has no record (its parent's ref says
where its spheres are), and the spheres are sphere records in leaf order
(:func:`renderer.gpu_layout.sphere_records`, the last of each leaf flagged), so no index
array is read. Inner records keep the build's order, renumbered without the leaves.
With triangles a tree primitive that is a triangle has a slot of a sphere record's size
there instead (:func:`renderer.gpu_layout.leaf_records`, its corners in ``u_triangles``), so
positions, refs and the ``last`` flags are as for spheres.

**GPU** (``u_bvh_nodes``, a record array: RGBA32UI texture or uniform block), inner node
``i`` at records ``4i … 4i + 3``::

    4i      x, y, z  left child's box minimum    w  the left child's ref
    4i + 1  x, y, z  left child's box maximum    w  the right child's ref
    4i + 2  x, y, z  right child's box minimum   w  the near mask (bits 7..0)
    4i + 3  x, y, z  right child's box maximum   w  0
                                                                   total: 64 bytes
    ref bit 31 (REF_LEAF) set: a leaf; bits 30..0 its first sphere record
        bit 31 clear:          an inner node; bits 30..0 its record

The root's box and ref are uniforms (``u_bvh_root_min/max``, ``u_bvh_root``). Boxes are
float32 and hold every primitive of the subtree (sphere boxes are rounded outwards, see
``bih.sphere_aabbs``); the shader reinterprets them with ``uintBitsToFloat``.

**Traversal** (``shaders/method_bvh.glsl``): Reiter's ordered stack traversal as before —
both children's boxes tested, the near mask's child first, the other pushed with its entry
distance — in a descent loop that ends at a leaf child, a leaf loop over its sphere
records and a pop loop. The build never makes a tree deeper than ``max_tree_depth``
(≤ ``STACK_SIZE``), so the stack, one entry per level, cannot overflow.
:func:`glsl_defines` emits the constants.
"""

from __future__ import annotations

import numpy as np

from .. import gpu_layout
from ..gpu_layout import DEFAULT_TEXTURE_WIDTH, Binding, PackedScene, wrap_rows
from ..limits import MAX_TREE_DEPTH

NEAR_MASK_BITS = 0xFF
NODE_BYTES = 32
# One stack entry per tree level.
STACK_SIZE = MAX_TREE_DEPTH
# Relative slack of the box tests (shader and CPU checks): an entry distance is
# compared as t0 <= t_best * T_SLACK, an exit as t1 * T_SLACK >= t0. It only
# makes the culling conservative against float32 rounding (it never prunes).
T_SLACK = 1.00001
# In the slab test 1/d is taken as ±1/DIR_EPS for a direction component smaller
# than DIR_EPS in magnitude: it stays finite, so (bound − o) · (1/d) is never
# 0 · inf = NaN (a ray parallel to a slab outside it gets a huge, finite entry
# distance: conservative).
DIR_EPS = 1e-30

REF_LEAF = 1 << 31
REF_INDEX = REF_LEAF - 1
REF_NONE = 0xFFFFFFFF
RECORDS_PER_NODE = 4
RECORD_BYTES = 64

NODES = Binding("u_bvh_nodes", doc="4 records per inner node (bvh_layout)", records=True)
SPHERES = Binding("u_bvh_spheres", doc="spheres in leaf order (gpu_layout.sphere_records)", records=True)
ROOT = Binding("u_bvh_root", "highp uint", "the root's ref")
ROOT_MIN = Binding("u_bvh_root_min", "highp vec3", "the root's box")
ROOT_MAX = Binding("u_bvh_root_max", "highp vec3")
# The triangles' records (gpu_layout; only variants with the TRIANGLES data format read them).
# … and the analytic shapes' (the SHAPES data format).
TRIANGLE_BINDINGS = (
    gpu_layout.TRIANGLES,
    gpu_layout.TRI_NORMALS,
    gpu_layout.TRI_BASE,
    *gpu_layout.TREE_SHAPE_BINDINGS,
)
BINDINGS = (NODES, SPHERES, ROOT, ROOT_MIN, ROOT_MAX, *TRIANGLE_BINDINGS)


def gpu_records(bvh) -> tuple[np.ndarray, int]:
    """The build's nodes as GPU inner records: uint32 (4 · inner nodes, 4), and the root's ref."""
    inner = np.flatnonzero(bvh.left >= 0)
    index = np.zeros(bvh.n_nodes, dtype=np.int64)
    index[inner] = np.arange(len(inner))
    leaf = bvh.left < 0
    if (bvh.count[leaf] == 0).any() and bvh.n_primitives:
        raise ValueError("a BVH leaf without primitives has no sphere record to point at")
    ref = np.where(leaf, REF_LEAF | bvh.first, index).astype(np.uint32)
    lc = bvh.left[inner]
    rc = lc + 1
    out = np.zeros((len(inner), 4, 4), dtype=np.uint32)
    f = lambda a: np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)
    out[:, 0, :3], out[:, 0, 3] = f(bvh.bmin[lc]), ref[lc]
    out[:, 1, :3], out[:, 1, 3] = f(bvh.bmax[lc]), ref[rc]
    out[:, 2, :3], out[:, 2, 3] = f(bvh.bmin[rc]), bvh.near_mask[inner].astype(np.uint32) & np.uint32(NEAR_MASK_BITS)
    out[:, 3, :3] = f(bvh.bmax[rc])
    return out.reshape(-1, 4), int(ref[0])


def leaf_order(bvh) -> tuple[np.ndarray, np.ndarray]:
    """Positions in ``bvh.indices`` in leaf order (the index array's own order) and the
    ``last`` flags of their records."""
    leaves = np.flatnonzero(bvh.left < 0)
    return bvh.indices.astype(np.int64), gpu_layout.leaf_ends(bvh.first[leaves], bvh.count[leaves], bvh.n_primitives)


def glsl_defines() -> str:
    """The layout as GLSL ES 3.00 ``#define`` lines (shared with the shader)."""
    return (
        f"#define BVH_REF_LEAF {REF_LEAF}u\n"
        f"#define BVH_REF_INDEX {REF_INDEX}u\n"
        f"#define BVH_REF_NONE {REF_NONE}u\n"
        f"#define BVH_STACK_SIZE {STACK_SIZE}\n"
        f"#define BVH_T_SLACK {T_SLACK!r}\n"
        f"#define BVH_DIR_EPS {DIR_EPS!r}\n"
    )


def pack_bvh(bvh, scene, ids: np.ndarray | None = None, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedScene:
    """The BVH for the GPU: inner records, the sphere records in leaf order, the root's ref
    and box. ``ids``: the scene id of each primitive the BVH was built over (None: the
    primitives are the scene's tree primitives: spheres, then triangles). With triangles the
    leaf-order records hold triangle slots (:func:`renderer.gpu_layout.leaf_records`) and the
    triangles' records come along."""
    records, root = gpu_records(bvh)
    order, last = leaf_order(bvh)
    if ids is not None:
        order = np.asarray(ids, dtype=np.int64)[order]
    packed = PackedScene(
        textures={
            NODES.name: wrap_rows(records, max_width),
            SPHERES.name: wrap_rows(gpu_layout.leaf_records(scene, order, last), max_width),
        },
        uniforms=dict(
            zip(
                (ROOT.name, ROOT_MIN.name, ROOT_MAX.name),
                (root, *gpu_layout.box_uniform(bvh.bmin[0], bvh.bmax[0])),
                strict=True,
            )
        ),
    )
    return gpu_layout.merged(
        packed,
        gpu_layout.pack_triangles(scene, max_width, count=False),
        gpu_layout.pack_shapes(scene, max_width, count=False),
    )

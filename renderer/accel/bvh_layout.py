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
(:func:`renderer.gpu.gpu_layout.sphere_records`, the last of each leaf flagged), so no index
array is read. Inner records keep the build's order, renumbered without the leaves.
With triangles a tree primitive that is a triangle has a slot of a sphere record's size
there instead (:func:`renderer.gpu.gpu_layout.leaf_records`, its corners in ``u_triangles``), so
positions, refs and the ``last`` flags are as for spheres.

**GPU** (``u_bvh_nodes``, a record array: RGBA32UI texture or uniform block): inner node
``i`` is record ``i`` of :data:`NODE`, 4 texels holding both children's boxes and refs and the
near mask; that declaration makes the packer (:func:`gpu_records`), the shader's accessors
(``bvh_node_left_min(i)`` …, in the header) and the table in docs/FORMATS.md ("GPU records").
A ref with bit 31 (``REF_LEAF``) set is a leaf, bits 30..0 its first sphere record; clear, an
inner node, bits 30..0 its record.

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

from ..gpu import gpu_layout
from ..gpu.gpu_layout import DEFAULT_TEXTURE_WIDTH, Binding, PackedScene
from ..gpu.record_layout import Field, RecordLayout
from ..limits import MAX_TREE_DEPTH
from .tree_pack import pack_tree

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

NODES = Binding("u_bvh_nodes", doc="4 records per inner node (bvh_layout)", records=True)
NODE = RecordLayout(
    "bvh_node",
    NODES,
    texels=4,
    fields=(
        Field("left_min", 0, "xyz", "float", "the left child's box minimum"),
        Field("left_ref", 0, "w", "uint", "the left child's ref"),
        Field("left_max", 1, "xyz", "float", "the left child's box maximum"),
        Field("right_ref", 1, "w", "uint", "the right child's ref"),
        Field("right_min", 2, "xyz", "float", "the right child's box minimum"),
        Field(
            "near_mask",
            2,
            "w",
            "uint",
            "bit s: visit the right child first for a ray of direction octant s (bit a of s: d[a] < 0)",
            bits=(7, 0),
        ),
        Field("right_max", 3, "xyz", "float", "the right child's box maximum"),
    ),
    doc="a BVH's inner node: both children's boxes and refs (`renderer/accel/bvh_layout.py`)",
    notes=(
        "a ref with bit 31 (`REF_LEAF`) set: a leaf, bits 30..0 its first record in `u_bvh_spheres`; "
        "clear: an inner node, bits 30..0 its record",
        "the root's ref and box are the uniforms `u_bvh_root`, `u_bvh_root_min`, `u_bvh_root_max`",
    ),
)
RECORDS_PER_NODE = NODE.texels
RECORD_BYTES = NODE.bytes
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
    records = NODE.pack(
        len(inner),
        left_min=bvh.bmin[lc],
        left_ref=ref[lc],
        left_max=bvh.bmax[lc],
        right_ref=ref[rc],
        right_min=bvh.bmin[rc],
        near_mask=bvh.near_mask[inner],
        right_max=bvh.bmax[rc],
    )
    return records, int(ref[0])


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
    ) + NODE.glsl_accessors()


def pack_bvh(bvh, scene, ids: np.ndarray | None = None, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedScene:
    """The BVH for the GPU: inner records, the sphere records in leaf order, the root's ref
    and box. ``ids``: the scene id of each primitive the BVH was built over (None: the
    primitives are the scene's tree primitives: spheres, then triangles). With triangles the
    leaf-order records hold triangle slots (:func:`renderer.gpu.gpu_layout.leaf_records`) and the
    triangles' records come along."""
    records, root = gpu_records(bvh)
    order, last = leaf_order(bvh)
    uniforms = dict(
        zip((ROOT, ROOT_MIN, ROOT_MAX), (root, *gpu_layout.box_uniform(bvh.bmin[0], bvh.bmax[0])), strict=True)
    )
    return pack_tree(scene, (NODES, records), (SPHERES, order, last), uniforms, ids, max_width)

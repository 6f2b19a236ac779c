"""The BIH's two layouts, defined once: the build's node (thesis listing 3.2) and the GPU's.

**Build** (:mod:`renderer.accel.bih`, ``BIH.nodes``): the thesis's node, 12 bytes, three
little-endian 32-bit words::

    word 0  axis_leftChild   bits 31..30: 00 = x, 01 = y, 10 = z split axis,
                                          11 = leaf
                             bits 29..0:  inner node: index of the left child;
                                          the right child is at left + 1
    word 1  clipL_primOffset inner: float32 clip_left  (max of the left
                                    children's AABB maxima on the axis)
                             leaf:  uint32 offset into the sorted index array
    word 2  clipR_primCount  inner: float32 clip_right (min of the right
                                    children's AABB minima on the axis)
                             leaf:  uint32 number of primitives
                                                                   total: 12 bytes

Words 1 and 2 are a union, as in the thesis's C struct. The statistics (Table 4.2,
Fig. 4.5's memory) and the build's tests read this form.

A *cut* (the build's step 0, trees over triangles) is an ordinary inner node one of whose
children is a leaf of no primitives: its clip plane on that side is ``±EMPTY_CLIP`` (the
largest float32: ``clip_right = +EMPTY_CLIP`` behind an empty right child, ``clip_left =
−EMPTY_CLIP`` before an empty left one), the other plane bounds the primitives' child.

**Conversion** (:func:`gpu_records`, per frame after the build): the GPU gets no record for
a leaf — its parent says where the leaf's spheres are — and the spheres themselves in leaf
order (the sorted index array's order), as :func:`renderer.gpu.gpu_layout.sphere_records`, so a
leaf is a run of sphere records ended by the one flagged ``SPHERE_LAST`` and needs no index
array. A cut's empty child has no records: its ref is its sibling's (below). With triangles
a tree primitive that is a triangle has a *slot* of the same size there instead
(:func:`renderer.gpu.gpu_layout.leaf_records`: its key flagged ``TRI_SLOT`` with the triangle's
index; the corners in ``u_triangles``), so positions, refs and the ``last`` flags are the
same as for spheres. Inner nodes keep the build's order, renumbered without the leaves.

**GPU** (``u_bih_nodes``, a record array: RGBA32UI texture or uniform block): inner node
``i`` is record ``i`` of :data:`NODE`, one texel: the split axis, both clip planes, both
children's refs; that declaration makes the packer (:func:`gpu_records`), the shader's
accessors (``bih_node_clip_left(i)`` …, in the header), the CPU mirror's decoding
(:mod:`renderer.accel.bih_traverse`) and the table in docs/FORMATS.md ("GPU records"). A ref
with bit 29 (``REF_LEAF``) set is a leaf, bits 28..0 its first sphere record; clear, an inner
node, bits 28..0 its record. A cut's empty child has the ref of its sibling (the primitives'
child).

No ray takes a cut's empty side: with a direction of length ≤ 1 and the scene inside
``±MAX_COORDINATE``, ``(±EMPTY_CLIP − o) / d`` puts that child's interval beyond ``BIG`` (the
shader's largest t, ≥ every interval end) or below 0. Were it taken, the sibling's ref would
only make the ray walk the primitives' child once more: extra work, no hit lost or made.
So the shader and its CPU mirror trace cuts with listing 3.5's decisions, unchanged.

``u_bih_root`` is the root's ref (a leaf when the whole scene is one), ``u_box_min/max``
the global box. An RGBA32UI fetch costs llvmpipe 0.96 ns against 1.36 for the RGB32UI the
12-byte node needed, and one record answers for both children.

**Traversal** (``shaders/method_bih.glsl``, mirrored on the CPU by
:mod:`renderer.accel.bih_traverse`): a descent loop through inner records that ends at a
leaf child, a leaf loop over its sphere records, a pop loop; the decisions are listing
3.5's as corrected in docs/THESIS.md, unchanged. :func:`glsl_defines` emits the constants.
"""

from __future__ import annotations

import numpy as np

from ..gpu import gpu_layout
from ..gpu.gpu_layout import DEFAULT_TEXTURE_WIDTH, Binding, PackedScene
from ..gpu.record_layout import Field, RecordLayout
from ..limits import MAX_TREE_DEPTH
from .tree_pack import pack_tree

AXIS_SHIFT = 30
LEAF_TAG = 3 << AXIS_SHIFT  # both high bits set
CHILD_MASK = (1 << AXIS_SHIFT) - 1  # low 30 bits
NODE_BYTES = 12
NODE_WORDS = 3

# Largest node count the 30-bit child index can address.
MAX_NODES = 1 << AXIS_SHIFT
# One traversal-stack entry per tree level: a tree is never deeper than MAX_TREE_DEPTH.
STACK_SIZE = MAX_TREE_DEPTH

# The GPU record's child refs.
REF_LEAF = 1 << 29
REF_INDEX = REF_LEAF - 1
REF_NONE = 0xFFFFFFFF  # "no node" in the shader's loops (has REF_LEAF set)
# A cut's empty side (renderer.accel.bih, step 0): its clip plane at ±EMPTY_CLIP (the module's
# docstring: no ray takes it), and its ref in the GPU record is its sibling's.
EMPTY_CLIP = float(np.finfo(np.float32).max)

NODES = Binding("u_bih_nodes", doc="BIH inner nodes (bih_layout)", records=True)
NODE = RecordLayout(
    "bih_node",
    NODES,
    texels=1,
    fields=(
        Field("axis", 0, "x", "uint", "the split axis (0, 1, 2)", bits=(31, AXIS_SHIFT)),
        Field("left", 0, "x", "uint", "the left child's ref", bits=(AXIS_SHIFT - 1, 0)),
        Field("clip_left", 0, "y", "float", "the left children's largest coordinate on the axis"),
        Field("clip_right", 0, "z", "float", "the right children's smallest coordinate on the axis"),
        Field("right", 0, "w", "uint", "the right child's ref"),
    ),
    doc="a BIH's inner node: its axis, both clip planes and both children's refs (`renderer/accel/bih_layout.py`)",
    notes=(
        "a ref with bit 29 (`REF_LEAF`) set: a leaf, bits 28..0 its first record in `u_bih_spheres`; "
        "clear: an inner node, bits 28..0 its record; a cut's empty child has its sibling's ref",
        "the root's ref and the global box are the uniforms `u_bih_root`, `u_box_min`, `u_box_max`",
    ),
)
RECORD_BYTES = NODE.bytes
SPHERES = Binding("u_bih_spheres", doc="spheres in leaf order (gpu_layout.sphere_records)", records=True)
ROOT = Binding("u_bih_root", "highp uint", "the root's ref")
BOX_MIN = Binding("u_box_min", "highp vec3", "BIH global AABB")
BOX_MAX = Binding("u_box_max", "highp vec3")
# The triangles' records (gpu_layout, read only by variants with the TRIANGLES data format).
# (Not u_num_triangles: the tree's leaves say where the triangles are.)
# The analytic shapes' records likewise (the SHAPES data format).
BINDINGS = (
    NODES,
    SPHERES,
    ROOT,
    BOX_MIN,
    BOX_MAX,
    gpu_layout.TRIANGLES,
    gpu_layout.TRI_NORMALS,
    gpu_layout.TRI_BASE,
    *gpu_layout.TREE_SHAPE_BINDINGS,
)


def empty_nodes(count: int) -> np.ndarray:
    """An uninitialised node array: uint32 (count, 3)."""
    return np.empty((count, NODE_WORDS), dtype=np.uint32)


def is_leaf(word0: np.ndarray) -> np.ndarray:
    return (word0 & np.uint32(LEAF_TAG)) == np.uint32(LEAF_TAG)


def axis_of(word0: np.ndarray) -> np.ndarray:
    return (word0 >> np.uint32(AXIS_SHIFT)).astype(np.int64)


def left_child(word0: np.ndarray) -> np.ndarray:
    return (word0 & np.uint32(CHILD_MASK)).astype(np.int64)


def clips(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(clip_left, clip_right) as float32, meaningful for inner nodes."""
    f = nodes[:, 1:3].view(np.float32)
    return f[:, 0], f[:, 1]


def gpu_records(bih) -> tuple[np.ndarray, int]:
    """The build's nodes as GPU inner records: uint32 (inner nodes, 4), and the root's ref."""
    nodes = bih.nodes
    w0 = nodes[:, 0]
    leaf = is_leaf(w0)
    inner = np.flatnonzero(~leaf)
    index = np.zeros(len(nodes), dtype=np.int64)
    index[inner] = np.arange(len(inner))
    ref = np.where(leaf, REF_LEAF | nodes[:, 1].astype(np.int64), index).astype(np.uint32)
    left = left_child(w0[inner])
    # A cut's empty child (a leaf of no primitives) is named by its sibling's ref.
    empty = leaf & (nodes[:, 2] == 0)
    if len(nodes) > 1 and empty.any():
        el, er = empty[left], empty[left + 1]
        ref[left[el]] = ref[left[el] + 1]
        ref[left[er] + 1] = ref[left[er]]
    cl, cr = clips(nodes[inner])
    records = NODE.pack(
        len(inner), axis=axis_of(w0[inner]), left=ref[left], clip_left=cl, clip_right=cr, right=ref[left + 1]
    )
    return records, int(ref[0])


def leaf_order(bih) -> tuple[np.ndarray, np.ndarray]:
    """The spheres in leaf order and the ``last`` flags of their records."""
    w0 = bih.nodes[:, 0]
    leaves = np.flatnonzero(is_leaf(w0))
    last = gpu_layout.leaf_ends(bih.nodes[leaves, 1], bih.nodes[leaves, 2], len(bih.indices))
    return bih.indices.astype(np.int64), last


def glsl_defines() -> str:
    """The layout as GLSL ES 3.00 ``#define`` lines (shared with the shader)."""
    return (
        f"#define BIH_STACK_SIZE {STACK_SIZE}\n"
        f"#define BIH_REF_LEAF {REF_LEAF}u\n"
        f"#define BIH_REF_INDEX {REF_INDEX}u\n"
        f"#define BIH_REF_NONE {REF_NONE}u\n"
    ) + NODE.glsl_accessors()


def pack_bih(bih, scene, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedScene:
    """The BIH of ``scene``'s spheres and triangles for the GPU: inner records, the leaf-order
    records (a sphere's record or a triangle's slot per tree primitive,
    :func:`renderer.gpu.gpu_layout.leaf_records`: for spheres only, the sphere records), the
    root's ref and the global AABB, and the triangles' records when there are any."""
    records, root = gpu_records(bih)
    order, last = leaf_order(bih)
    uniforms = dict(zip((ROOT, BOX_MIN, BOX_MAX), (root, *gpu_layout.box_uniform(*bih.global_aabb)), strict=True))
    return pack_tree(scene, (NODES, records), (SPHERES, order, last), uniforms, None, max_width)

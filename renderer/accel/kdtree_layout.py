"""The kd-tree's layouts (Reiter's listing 4.5), defined once for packer, shader and tests.

**Build** (:class:`renderer.accel.kdtree.KdTree`): struct of arrays — per node its split
``axis`` (−1 in leaves), ``left`` (the right child is at ``left + 1``: siblings stored in
pairs, figure 4.3), the ``split`` plane's position, and a leaf's range ``offset``/``count``
of the compacted index array (leaves' ranges may overlap, algorithm 6). Its memory
(``KdStats.bytes``) counts ``NODE_BYTES`` = 8 per node, listing 4.5's node: a word for the
axis and the child or count, a word for the split or the offset.

The left child holds everything below the plane (``x[axis] < split``), the right child
everything above; a primitive whose box straddles the plane is in both.

**Conversion** (:func:`gpu_records`): a leaf has no record, its parent's ref says where its
spheres are, and every leaf's spheres are a run of sphere records
(:func:`renderer.gpu.gpu_layout.sphere_records`, the last flagged) in leaf order — a straddler
has a record in every leaf it is in, so no index array is read (the runs hold the
references, ``stats.references``, not the compacted index array). An empty leaf has no
records: its ref says so. Inner records keep the build's order, renumbered without leaves.
With triangles a tree primitive that is a triangle has a slot of a sphere record's size
there instead (:func:`renderer.gpu.gpu_layout.leaf_records`, its corners in ``u_triangles``), so
positions, refs and the ``last`` flags are as for spheres.

**GPU** (``u_kd_nodes``, a record array: RGBA32UI texture or uniform block): inner node
``i`` is record ``i`` of :data:`NODE`, one texel: the split axis and plane, both children's
refs; that declaration makes the packer (:func:`gpu_records`), the shader's accessors
(``kd_node_axis(i)`` …, in the header) and the table in docs/FORMATS.md ("GPU records"). A ref
with bit 29 (``REF_LEAF``) set is a leaf: bit 28 (``REF_EMPTY``) set, it has no primitives, else
bits 27..0 its first sphere record; bit 29 clear, an inner node, bits 27..0 its record.

``u_kd_root`` is the root's ref, ``u_kd_box_min/max`` the root's voxel.

**Traversal** (``shaders/method_kdtree.glsl``): front to back with early exit, as before,
in a descent loop that ends at a leaf child, a leaf block (its sphere records, the
early exit) and a pop loop.
"""

from __future__ import annotations

import numpy as np

from ..gpu import gpu_layout
from ..gpu.gpu_layout import DEFAULT_TEXTURE_WIDTH, Binding, PackedScene
from ..gpu.record_layout import Field, RecordLayout
from ..limits import MAX_TREE_DEPTH
from .tree_pack import pack_tree

AXIS_SHIFT = 30
LOW_MASK = (1 << AXIS_SHIFT) - 1
NODE_BYTES = 8
# One stack entry per level; the build never makes a deeper tree.
STACK_SIZE = MAX_TREE_DEPTH
# Relative slack (shader and checks): interval comparisons that decide which
# children to visit, pruning of popped entries and the early exit are made
# conservative against float32 rounding by this factor (they only add work).
T_SLACK = 1.00001

REF_LEAF = 1 << 29
REF_EMPTY = 1 << 28
REF_INDEX = REF_EMPTY - 1
REF_NONE = 0xFFFFFFFF

NODES = Binding("u_kd_nodes", doc="kd-tree inner nodes (kdtree_layout)", records=True)
NODE = RecordLayout(
    "kd_node",
    NODES,
    texels=1,
    fields=(
        Field("axis", 0, "x", "uint", "the split axis (0, 1, 2)", bits=(31, AXIS_SHIFT)),
        Field("left", 0, "x", "uint", "the left child's ref (below the plane)", bits=(AXIS_SHIFT - 1, 0)),
        Field("split", 0, "y", "float", "the split plane's position on the axis"),
        Field("right", 0, "z", "uint", "the right child's ref (above the plane)"),
    ),
    doc="a kd-tree's inner node: its plane and both children's refs (`renderer/accel/kdtree_layout.py`)",
    notes=(
        "a ref with bit 29 (`REF_LEAF`) set: a leaf — bit 28 (`REF_EMPTY`) set: it has no primitives, "
        "else bits 27..0 its first record in `u_kd_spheres`; bit 29 clear: an inner node, bits 27..0 its record",
        "the root's ref and voxel are the uniforms `u_kd_root`, `u_kd_box_min`, `u_kd_box_max`",
    ),
)
RECORD_BYTES = NODE.bytes
SPHERES = Binding("u_kd_spheres", doc="each leaf's spheres (gpu_layout.sphere_records)", records=True)
ROOT = Binding("u_kd_root", "highp uint", "the root's ref")
BOX_MIN = Binding("u_kd_box_min", "highp vec3", "the root's voxel")
BOX_MAX = Binding("u_kd_box_max", "highp vec3")
# The triangles' records (gpu_layout; only variants with the TRIANGLES data format read them).
# … and the analytic shapes' (the SHAPES data format).
TRIANGLE_BINDINGS = (
    gpu_layout.TRIANGLES,
    gpu_layout.TRI_NORMALS,
    gpu_layout.TRI_BASE,
    *gpu_layout.TREE_SHAPE_BINDINGS,
)
BINDINGS = (NODES, SPHERES, ROOT, BOX_MIN, BOX_MAX, *TRIANGLE_BINDINGS)


def leaf_runs(kd) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every leaf's primitives, leaf after leaf: (primitive positions in the concatenation,
    each leaf's first record, the ``last`` flags)."""
    leaves = np.flatnonzero(kd.axis < 0)
    counts = kd.count[leaves].astype(np.int64)
    starts = np.zeros(len(leaves), dtype=np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    total = int(counts.sum())
    pos = np.repeat(kd.offset[leaves].astype(np.int64) - starts, counts) + np.arange(total, dtype=np.int64)
    first = np.zeros(kd.n_nodes, dtype=np.int64)
    first[leaves] = starts
    return kd.indices[pos].astype(np.int64), first, gpu_layout.leaf_ends(starts, counts, total)


def gpu_records(kd, first: np.ndarray) -> tuple[np.ndarray, int]:
    """The build's nodes as GPU inner records: uint32 (inner nodes, 4), and the root's ref;
    ``first``: each leaf's first sphere record (:func:`leaf_runs`)."""
    leaf = kd.axis < 0
    inner = np.flatnonzero(~leaf)
    index = np.zeros(kd.n_nodes, dtype=np.int64)
    index[inner] = np.arange(len(inner))
    ref = np.where(leaf, np.where(kd.count > 0, REF_LEAF | first, REF_LEAF | REF_EMPTY), index).astype(np.uint32)
    lc = kd.left[inner]
    records = NODE.pack(len(inner), axis=kd.axis[inner], left=ref[lc], split=kd.split[inner], right=ref[lc + 1])
    return records, int(ref[0])


def glsl_defines() -> str:
    """The layout as GLSL ES 3.00 ``#define`` lines (shared with the shader)."""
    return (
        f"#define KD_REF_LEAF {REF_LEAF}u\n"
        f"#define KD_REF_EMPTY {REF_EMPTY}u\n"
        f"#define KD_REF_INDEX {REF_INDEX}u\n"
        f"#define KD_REF_NONE {REF_NONE}u\n"
        f"#define KD_STACK_SIZE {STACK_SIZE}\n"
        f"#define KD_T_SLACK {T_SLACK!r}\n"
    ) + NODE.glsl_accessors()


def pack_kdtree(kd, scene, ids: np.ndarray | None = None, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedScene:
    """The kd-tree for the GPU: inner records, every leaf's sphere records, the root's ref
    and voxel. ``ids``: the scene id of each primitive the tree was built over (None: the
    primitives are the scene's tree primitives: spheres, then triangles). With triangles the
    leaf records hold triangle slots (:func:`renderer.gpu.gpu_layout.leaf_records`) and the
    triangles' records come along."""
    prims, first, last = leaf_runs(kd)
    records, root = gpu_records(kd, first)
    uniforms = dict(zip((ROOT, BOX_MIN, BOX_MAX), (root, *gpu_layout.box_uniform(*kd.global_box)), strict=True))
    return pack_tree(scene, (NODES, records), (SPHERES, prims, last), uniforms, ids, max_width)

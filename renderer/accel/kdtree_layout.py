"""The kd-tree node layout (Reiter's listing 4.5), defined once for packer, shader and tests.

One node is 8 bytes, two little-endian 32-bit words (texture ``u_kd_nodes``,
RG32UI, node ``i`` at texel ``i``)::

    word 0  bits 31..30  00 / 01 / 10 = split axis x / y / z, 11 = leaf
            bits 29..0   inner: index of the left child; the right child is at
                                left + 1 (siblings stored in pairs, figure 4.3)
                         leaf:  number of primitives
    word 1               inner: float32 bits of the split plane's position
                         leaf:  offset into the compacted index array
                                ``u_kd_indices`` (leaves' ranges may overlap,
                                algorithm 6)

The left child holds everything below the plane (``x[axis] < split``), the
right child everything above; a primitive whose box straddles the plane is in
both. The root's voxel is the global box (uniforms ``u_kd_box_min/max``).
"""

from __future__ import annotations

import numpy as np

from ..gpu_layout import DEFAULT_TEXTURE_WIDTH, Binding, PackedScene, wrap_rows
from ..limits import MAX_TREE_DEPTH

AXIS_SHIFT = 30
LEAF_TAG = 3 << AXIS_SHIFT
LOW_MASK = (1 << AXIS_SHIFT) - 1
NODE_BYTES = 8
MAX_NODES = 1 << AXIS_SHIFT
# One stack entry per level; the build never makes a deeper tree.
STACK_SIZE = MAX_TREE_DEPTH
# Relative slack (shader and checks): interval comparisons that decide which
# children to visit, pruning of popped entries and the early exit are made
# conservative against float32 rounding by this factor (they only add work).
T_SLACK = 1.00001

NODES = Binding("u_kd_nodes", "highp usampler2D", "kd-tree nodes (kdtree_layout)")
INDICES = Binding("u_kd_indices", "highp usampler2D", "compacted primitive index array")
BOX_MIN = Binding("u_kd_box_min", "highp vec3", "the root's voxel")
BOX_MAX = Binding("u_kd_box_max", "highp vec3")
BINDINGS = (NODES, INDICES, BOX_MIN, BOX_MAX)


def pack_nodes(axis: np.ndarray, left: np.ndarray, split: np.ndarray, count: np.ndarray,
               offset: np.ndarray) -> np.ndarray:
    """Node arrays (axis −1 for leaves) → uint32 (nodes, 2)."""
    m = len(axis)
    out = np.empty((m, 2), dtype=np.uint32)
    leaf = axis < 0
    w0 = np.where(leaf, np.uint64(LEAF_TAG) | count.astype(np.uint64),
                  (np.maximum(axis, 0).astype(np.uint64) << np.uint64(AXIS_SHIFT)) | np.maximum(left, 0).astype(np.uint64))
    out[:, 0] = w0.astype(np.uint32)
    out[:, 1] = np.where(leaf, offset.astype(np.uint32), np.asarray(split, dtype=np.float32).view(np.uint32))
    return out


def unpack_nodes(words: np.ndarray) -> dict[str, np.ndarray]:
    """The inverse of :func:`pack_nodes` (tests and tools)."""
    w = np.asarray(words, dtype=np.uint32).reshape(-1, 2)
    tag = (w[:, 0] >> np.uint32(AXIS_SHIFT)).astype(np.int64)
    leaf = tag == 3
    low = (w[:, 0] & np.uint32(LOW_MASK)).astype(np.int64)
    return {"leaf": leaf, "axis": np.where(leaf, -1, tag), "left": np.where(leaf, -1, low),
            "count": np.where(leaf, low, 0), "offset": np.where(leaf, w[:, 1].astype(np.int64), 0),
            "split": w[:, 1].copy().view(np.float32)}


def glsl_defines() -> str:
    """The layout as GLSL ES 3.00 ``#define`` lines (shared with the shader)."""
    return (f"#define KD_AXIS_SHIFT {AXIS_SHIFT}u\n"
            f"#define KD_LEAF_TAG {LEAF_TAG}u\n"
            f"#define KD_LOW_MASK {LOW_MASK}u\n"
            f"#define KD_STACK_SIZE {STACK_SIZE}\n"
            f"#define KD_T_SLACK {T_SLACK!r}\n")


def pack_kdtree(kd, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedScene:
    """The kd-tree's nodes (RG32UI, see above), compacted index array and global box."""
    return PackedScene(
        textures={NODES.name: wrap_rows(kd.words(), max_width),
                  INDICES.name: wrap_rows(kd.indices.astype(np.uint32), max_width)},
        uniforms={BOX_MIN.name: tuple(float(x) for x in kd.global_box[0]),
                  BOX_MAX.name: tuple(float(x) for x in kd.global_box[1])})

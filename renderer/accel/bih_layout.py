"""The BIH node layout (thesis listing 3.2), defined once for packer and shader.

One node is 12 bytes, three little-endian 32-bit words::

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

Words 1 and 2 are a union, as in the thesis's C struct: a leaf stores integers
in the bits, an inner node stores float bits. On the GPU the node array is an
RGB32UI texture and the shader reinterprets words 1–2 with
``uintBitsToFloat`` in inner nodes. :func:`glsl_defines` emits the constants
below for the shader, so the two sides cannot drift apart.
"""

from __future__ import annotations

import numpy as np

from ..gpu_layout import DEFAULT_TEXTURE_WIDTH, Binding, PackedScene, wrap_rows
from ..limits import MAX_TREE_DEPTH

AXIS_SHIFT = 30
LEAF_TAG = 3 << AXIS_SHIFT          # both high bits set
CHILD_MASK = (1 << AXIS_SHIFT) - 1  # low 30 bits
NODE_BYTES = 12
NODE_WORDS = 3

# Largest node count the 30-bit child index can address.
MAX_NODES = 1 << AXIS_SHIFT
# One traversal-stack entry per tree level: a tree is never deeper than MAX_TREE_DEPTH.
STACK_SIZE = MAX_TREE_DEPTH

NODES = Binding("u_nodes", "highp usampler2D", "BIH nodes (bih_layout)")
INDICES = Binding("u_indices", "highp usampler2D", "BIH sorted primitive indices")
BOX_MIN = Binding("u_box_min", "highp vec3", "BIH global AABB")
BOX_MAX = Binding("u_box_max", "highp vec3")
BINDINGS = (NODES, INDICES, BOX_MIN, BOX_MAX)


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


def glsl_defines() -> str:
    """The layout as GLSL ES 3.00 ``#define`` lines (shared with the shader)."""
    return (f"#define BIH_STACK_SIZE {STACK_SIZE}\n"
            f"#define BIH_AXIS_SHIFT {AXIS_SHIFT}u\n"
            f"#define BIH_LEAF_TAG {LEAF_TAG}u\n"
            f"#define BIH_CHILD_MASK {CHILD_MASK}u\n")


def pack_bih(bih, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedScene:
    """The BIH's node array, index array and global AABB."""
    return PackedScene(
        textures={NODES.name: wrap_rows(bih.nodes, max_width),
                  INDICES.name: wrap_rows(bih.indices.astype(np.uint32), max_width)},
        uniforms={BOX_MIN.name: tuple(float(x) for x in bih.global_aabb[0]),
                  BOX_MAX.name: tuple(float(x) for x in bih.global_aabb[1])})

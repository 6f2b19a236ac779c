"""The BVH node layout, defined once for packer, shader and tests.

One node is 32 bytes: two RGBA32UI texels (texture ``u_bvh_nodes``), node ``i``
at texels ``2i`` and ``2i + 1``::

    texel 2i      x, y, z  float32 bits of the node box's minimum corner
                  w        inner: index of the left child; the right child is
                                  at left + 1 (siblings are stored in pairs)
                           leaf:  offset into the index array ``u_bvh_indices``
    texel 2i + 1  x, y, z  float32 bits of the node box's maximum corner
                  w        bit 31 (INNER_FLAG): set in inner nodes
                           inner: bits 7..0 = Reiter's near mask (listing 4.13):
                                  bit s says which child to visit first for a
                                  ray of direction octant s (octant bit a is
                                  set when d[a] < 0); 0 = left, 1 = right
                           leaf:  bits 30..0 = number of primitives

Boxes are float32 and hold every primitive of the subtree (sphere boxes are
rounded outwards, see ``bih.sphere_aabbs``); the shader reinterprets them
with ``uintBitsToFloat``. The texture is integer so no driver can touch the
bits of the words stored in ``w``.

The root is node 0. The build never makes a tree deeper than
``max_tree_depth`` (≤ ``STACK_SIZE``), so the shader's traversal stack, one
entry per level, cannot overflow. :func:`glsl_defines` emits the constants.
"""

from __future__ import annotations

import numpy as np

from ..gpu_layout import DEFAULT_TEXTURE_WIDTH, Binding, PackedScene, wrap_rows
from ..limits import MAX_TREE_DEPTH

INNER_FLAG = 1 << 31
COUNT_MASK = INNER_FLAG - 1
NEAR_MASK_BITS = 0xFF
TEXELS_PER_NODE = 2
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

NODES = Binding("u_bvh_nodes", "highp usampler2D", "2 texels per node (bvh_layout)")
INDICES = Binding("u_bvh_indices", "highp usampler2D", "primitive ids in leaf order")
BINDINGS = (NODES, INDICES)


def pack_nodes(bmin: np.ndarray, bmax: np.ndarray, left: np.ndarray, first: np.ndarray,
               count: np.ndarray, near_mask: np.ndarray) -> np.ndarray:
    """Node arrays → uint32 (2 · nodes, 4) texels in the layout above."""
    m = len(left)
    out = np.empty((m, 2, 4), dtype=np.uint32)
    out[:, 0, :3] = np.ascontiguousarray(bmin, dtype=np.float32).view(np.uint32)
    out[:, 1, :3] = np.ascontiguousarray(bmax, dtype=np.float32).view(np.uint32)
    inner = left >= 0
    out[:, 0, 3] = np.where(inner, left, first).astype(np.uint32)
    out[:, 1, 3] = np.where(inner, np.uint32(INNER_FLAG) | (near_mask.astype(np.uint32) & np.uint32(NEAR_MASK_BITS)),
                            count.astype(np.uint32) & np.uint32(COUNT_MASK))
    return out.reshape(2 * m, 4)


def unpack_nodes(texels: np.ndarray) -> dict[str, np.ndarray]:
    """The inverse of :func:`pack_nodes` (for tests and tools)."""
    t = np.asarray(texels, dtype=np.uint32).reshape(-1, 2, 4)
    w0 = t[:, 0, 3].astype(np.int64)
    w1 = t[:, 1, 3]
    inner = (w1 & np.uint32(INNER_FLAG)) != 0
    return {"bmin": t[:, 0, :3].copy().view(np.float32), "bmax": t[:, 1, :3].copy().view(np.float32),
            "inner": inner, "left": np.where(inner, w0, -1), "first": np.where(inner, 0, w0),
            "count": np.where(inner, 0, (w1 & np.uint32(COUNT_MASK)).astype(np.int64)),
            "near_mask": np.where(inner, (w1 & np.uint32(NEAR_MASK_BITS)).astype(np.int64), 0)}


def glsl_defines() -> str:
    """The layout as GLSL ES 3.00 ``#define`` lines (shared with the shader)."""
    return (f"#define BVH_INNER_FLAG {INNER_FLAG}u\n"
            f"#define BVH_COUNT_MASK {COUNT_MASK}u\n"
            f"#define BVH_STACK_SIZE {STACK_SIZE}\n"
            f"#define BVH_T_SLACK {T_SLACK!r}\n"
            f"#define BVH_DIR_EPS {DIR_EPS!r}\n")


def pack_bvh(bvh, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedScene:
    """The BVH's nodes (two RGBA32UI texels each, see above) and its index array."""
    return PackedScene(
        textures={NODES.name: wrap_rows(bvh.texels(), max_width),
                  INDICES.name: wrap_rows(bvh.indices.astype(np.uint32), max_width)})

"""The one packer of the hierarchies (BIH, BVH, kd-tree; the two-level method packs one of each).

Every tree hands the GPU the same four things: its inner records (packed by its
:class:`renderer.gpu.record_layout.RecordLayout` in ``<method>_layout.py``), the leaf-order
records — a sphere record or a triangle's or shape's slot per tree primitive, each leaf a run
ended by the one flagged last (:func:`renderer.gpu.gpu_layout.leaf_records`) — the root's ref and
box as uniforms, and the scene's triangle and shape records its leaves point into.
"""

from __future__ import annotations

import numpy as np

from ..gpu import gpu_layout
from ..gpu.gpu_layout import DEFAULT_TEXTURE_WIDTH, Binding, PackedScene, wrap_rows


def pack_tree(
    scene,
    nodes: tuple[Binding, np.ndarray],
    leaves: tuple[Binding, np.ndarray, np.ndarray],
    uniforms: dict[Binding, object],
    ids: np.ndarray | None = None,
    max_width: int = DEFAULT_TEXTURE_WIDTH,
) -> PackedScene:
    """A tree for the GPU. ``nodes``: the binding and the uint32 ``(n, 4)`` inner records;
    ``leaves``: the binding, the tree primitive of each leaf-order record and their ``last``
    flags; ``uniforms``: the root's ref and box. ``ids``: the scene's tree primitive id of each
    primitive the tree was built over (None: the scene's tree primitives themselves); the
    leaf-order records name scene primitives through it. ``max_width``: texels per row."""
    node_binding, records = nodes
    leaf_binding, order, last = leaves
    if ids is not None:
        order = np.asarray(ids, dtype=np.int64)[order]
    packed = PackedScene(
        textures={
            node_binding.name: wrap_rows(records, max_width),
            leaf_binding.name: wrap_rows(gpu_layout.leaf_records(scene, order, last), max_width),
        },
        uniforms={b.name: v for b, v in uniforms.items()},
    )
    return gpu_layout.merged(
        packed,
        gpu_layout.pack_triangles(scene, max_width, count=False),
        gpu_layout.pack_shapes(scene, max_width, count=False),
    )

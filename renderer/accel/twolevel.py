"""Method ``twolevel`` (Reiter §3.2.2, Figure 5.6): static primitives in a kd-tree, moving ones in a BVH."""

from __future__ import annotations

import time

import numpy as np

from ..geometry.scene import Scene
from ..gpu.gpu_layout import DEFAULT_TEXTURE_WIDTH, Binding, PackedScene
from ..scenes.tree_update import REBUILD, UPDATE_SCHEMES, TreeUpdate
from . import bvh_layout, kdtree_layout
from .base import Capabilities, PreparedMethod, mesh_stats
from .bvh import BVHMethod
from .bvh_layout import pack_bvh
from .kdtree import DEFAULT_COST_SCALE, build_kdtree
from .kdtree_layout import pack_kdtree
from .primitives import scene_aabbs

KD_COUNT = Binding("u_kd_count", "highp int", "spheres in the kd-tree (static)")
BVH_COUNT = Binding("u_bvh_count", "highp int", "spheres in the BVH (moving)")


class TwoLevelMethod:
    """Method ``twolevel`` (Reiter §3.2.2, Figure 5.6): the static spheres in an SAH kd-tree,
    built once per distinct static set and cached; the moving ones in a BVH updated per frame
    with the chosen scheme. Every ray traverses both and keeps the nearer hit
    (``shaders/method_twolevel.glsl``: kd-tree first, its hit then bounds the BVH).

    ``update.moving`` is a bool mask over the scene's tree primitives — spheres, then
    triangles (from :func:`renderer.scenes.animation.pose`; for a scene without triangles, one
    per sphere); without it everything counts as static (a plain scene has no motion).
    Tree primitive ids are those of :mod:`renderer.accel.primitives`; ``tree`` of the
    prepared method is ``(kd, static_ids, bvh, moving_ids)``, each structure built over its
    subset (its primitive ``i`` is tree primitive ``ids[i]``).
    """

    name = "twolevel"
    label = "Two levels (kd-tree + BVH)"
    capabilities = Capabilities(
        shader="method_twolevel.glsl",
        update_schemes=UPDATE_SCHEMES,
        settings=("max_prims", "max_tree_depth", "update", "integrator"),
        meshes_on_gpu=True,
    )
    # Both trees' bindings; the triangles' records, which both list, once.
    bindings = (
        *kdtree_layout.BINDINGS,
        *(b for b in bvh_layout.BINDINGS if b not in kdtree_layout.TRIANGLE_BINDINGS),
        KD_COUNT,
        BVH_COUNT,
    )

    @staticmethod
    def glsl_defines() -> str:
        return bvh_layout.glsl_defines() + kdtree_layout.glsl_defines()

    CACHE_SLOTS = 8

    def __init__(self) -> None:
        self._bvh = BVHMethod()
        self._kd: dict = {}

    def _static_tree(self, lo: np.ndarray, hi: np.ndarray, static_ids: np.ndarray, max_tree_depth: int, key):
        lo, hi = lo[static_ids], hi[static_ids]
        sig = (key, max_tree_depth, len(static_ids), hash(static_ids.tobytes()), hash(lo.tobytes()), hash(hi.tobytes()))
        hit = self._kd.pop(sig, None)
        if hit is None:
            hit = build_kdtree(lo, hi, max_tree_depth=max_tree_depth, cost_scale=DEFAULT_COST_SCALE)
            fresh = True
        else:
            fresh = False
        self._kd[sig] = hit
        while len(self._kd) > self.CACHE_SLOTS:
            self._kd.pop(next(iter(self._kd)))
        return hit, fresh

    def prepare(
        self,
        scene: Scene,
        max_prims: int,
        max_tree_depth: int,
        max_width: int = DEFAULT_TEXTURE_WIDTH,
        update: TreeUpdate = REBUILD,
    ) -> PreparedMethod:
        t0 = time.perf_counter()
        n = scene.n_spheres + scene.n_triangles
        mv = np.zeros(n, dtype=bool) if update.moving is None else np.asarray(update.moving, dtype=bool).reshape(-1)
        if len(mv) == n:  # a mask without the analytic shapes: they stay in the static tree
            mv = np.concatenate([mv, np.zeros(scene.n_shapes, dtype=bool)])
        n += scene.n_shapes
        if len(mv) != n:
            raise ValueError(
                f"moving mask has {len(mv)} entries for {scene.n_spheres} spheres and {scene.n_triangles} triangles"
            )
        static_ids = np.flatnonzero(~mv)
        moving_ids = np.flatnonzero(mv)
        lo, hi = scene_aabbs(scene)
        kd, fresh = self._static_tree(lo, hi, static_ids, max_tree_depth, update.key)
        t1 = time.perf_counter()
        bvh = self._bvh.build_boxes(lo[moving_ids], hi[moving_ids], max_prims, max_tree_depth, update)
        t2 = time.perf_counter()
        packed = pack_twolevel(kd, static_ids, bvh, moving_ids, scene, max_width)
        stats = {
            "method": self.name,
            "static": int(len(static_ids)),
            "moving": int(len(moving_ids)),
            "kd_build_ms": (t1 - t0) * 1e3 if fresh else 0.0,
            "kd_cached": not fresh,
            "bvh_update_ms": (t2 - t1) * 1e3,
            "scheme": bvh.stats.scheme,
            "kd": kd.stats.to_json(),
            "bvh": bvh.stats.to_json(),
            "bytes": kd.stats.bytes + bvh.stats.bytes,
            **mesh_stats(scene),
        }
        return PreparedMethod(packed, (t2 - t0) * 1e3, stats, tree=(kd, static_ids, bvh, moving_ids))


def pack_twolevel(
    kd, kd_ids: np.ndarray, bvh, bvh_ids: np.ndarray, scene: Scene, max_width: int = DEFAULT_TEXTURE_WIDTH
) -> PackedScene:
    """Two levels: the kd-tree over the spheres ``kd_ids`` and the BVH over ``bvh_ids``.

    Each structure was built over its subset (primitive ``i`` = tree primitive ``ids[i]``: a
    sphere, or a triangle after the spheres); their leaf records carry scene ids (a sphere's
    record) or triangle indices (a triangle's slot, gpu_layout.leaf_records), so the shader
    sees scene ids only. Both parts pack the same triangle records; they are one.
    """
    kd_part = pack_kdtree(kd, scene, kd_ids, max_width)
    bvh_part = pack_bvh(bvh, scene, bvh_ids, max_width)
    return PackedScene(
        textures={**kd_part.textures, **bvh_part.textures},
        uniforms={
            **kd_part.uniforms,
            **bvh_part.uniforms,
            KD_COUNT.name: int(len(kd_ids)),
            BVH_COUNT.name: int(len(bvh_ids)),
        },
    )

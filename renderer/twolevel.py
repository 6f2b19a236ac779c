"""Method ``twolevel`` (Reiter §3.2.2, Figure 5.6): static spheres in a kd-tree, moving ones in a BVH."""

from __future__ import annotations

import time

import numpy as np

from . import gpu_layout
from .bvh import BVHMethod
from .kdtree import DEFAULT_COST_SCALE, build_for_spheres
from .scene import Scene
from .tree_update import REBUILD, TreeUpdate


class TwoLevelMethod:
    """Method ``twolevel`` (Reiter §3.2.2, Figure 5.6): the static spheres in an SAH kd-tree,
    built once per distinct static set and cached; the moving ones in a BVH updated per frame
    with the chosen scheme. Every ray traverses both and keeps the nearer hit
    (``shaders/method_twolevel.glsl``: kd-tree first, its hit then bounds the BVH).

    ``update.moving`` is a bool mask over the scene's spheres (from :func:`renderer.animation.pose`); without
    it every sphere counts as static (a plain scene has no motion).
    """
    name = "twolevel"
    CACHE_SLOTS = 8

    def __init__(self) -> None:
        self._bvh = BVHMethod()
        self._kd: dict = {}

    def _static_tree(self, scene: Scene, static_ids: np.ndarray, max_tree_depth: int, key):
        c = scene.sphere_centers[static_ids]
        r = scene.sphere_radii[static_ids]
        sig = (key, max_tree_depth, len(static_ids), hash(static_ids.tobytes()), hash(c.tobytes()), hash(r.tobytes()))
        hit = self._kd.pop(sig, None)
        if hit is None:
            hit = build_for_spheres(c, r, max_tree_depth, DEFAULT_COST_SCALE)
            fresh = True
        else:
            fresh = False
        self._kd[sig] = hit
        while len(self._kd) > self.CACHE_SLOTS:
            self._kd.pop(next(iter(self._kd)))
        return hit, fresh

    def prepare(self, scene: Scene, max_prims: int, max_tree_depth: int, max_width: int = 4096,
                update: TreeUpdate = REBUILD):
        from .methods import PreparedMethod  # deferred: renderer.methods imports this module
        t0 = time.perf_counter()
        n = scene.n_spheres
        mv = np.zeros(n, dtype=bool) if update.moving is None else np.asarray(update.moving, dtype=bool).reshape(-1)
        if len(mv) != n:
            raise ValueError(f"moving mask has {len(mv)} entries for {n} spheres")
        static_ids = np.flatnonzero(~mv)
        moving_ids = np.flatnonzero(mv)
        kd, fresh = self._static_tree(scene, static_ids, max_tree_depth, update.key)
        t1 = time.perf_counter()
        sub = Scene(scene.camera, scene.lights, scene.materials, scene.sphere_centers[moving_ids],
                    scene.sphere_radii[moving_ids], scene.sphere_materials[moving_ids], scene.planes)
        bvh = self._bvh.build(sub, max_prims, max_tree_depth, update)
        t2 = time.perf_counter()
        packed = gpu_layout.pack_twolevel(kd, static_ids, bvh, moving_ids, max_width)
        stats = {"method": self.name, "static": int(len(static_ids)), "moving": int(len(moving_ids)),
                 "kd_build_ms": (t1 - t0) * 1e3 if fresh else 0.0, "kd_cached": not fresh,
                 "bvh_update_ms": (t2 - t1) * 1e3, "scheme": bvh.stats.scheme,
                 "kd": kd.stats.to_json(), "bvh": bvh.stats.to_json(),
                 "bytes": kd.stats.bytes + bvh.stats.bytes}
        return PreparedMethod(packed, (t2 - t0) * 1e3, stats)

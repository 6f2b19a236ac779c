"""Acceleration methods behind one interface.

A method turns a scene into what the GPU tracer needs for it: its textures
and uniforms (through the shared layout of :mod:`gpu_layout`) and statistics.
Its GLSL lives in ``shaders/method_<name>.glsl`` (``method_init()`` and
``intersect_spheres()``), spliced into ``raytrace.frag`` by the host; the
variant gets ``#define METHOD_<NAME>``. ``prepare`` runs on every request: the
thesis rebuilds its BIH for every frame, and so do we — except where a frame of an
animation asks a method that keeps its tree to update it instead
(:mod:`renderer.tree_update`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Protocol

from . import gpu_layout
from .bih import build_for_spheres
from .scene import Scene
from .tree_update import REBUILD, TreeUpdate


@dataclass
class PreparedMethod:
    """One request's acceleration data: GPU data, build time (ms), statistics."""
    packed: gpu_layout.PackedScene
    build_ms: float
    stats: dict[str, Any] = field(default_factory=dict)


class AccelerationMethod(Protocol):
    """A method of tracing the spheres.

    Single-pass methods implement ``prepare`` and a ``shaders/method_<name>.glsl``.
    A multi-pass method (one that draws primitives over ray textures, say)
    may instead define ``render_frame(renderer, scene, settings) -> RenderResult``;
    ``GLRenderer.render`` then hands it the whole frame.
    """
    name: str

    def prepare(self, scene: Scene, max_prims: int, max_tree_depth: int,
                max_width: int = gpu_layout.DEFAULT_TEXTURE_WIDTH,
                update: TreeUpdate = REBUILD) -> PreparedMethod:
        """The frame's acceleration data for the posed ``scene``; ``update`` says whether and
        how the previous frame's tree of the same animation may be updated instead."""


class BruteForce:
    """Every ray tests every sphere (the thesis's "BF" series)."""
    name = "bruteforce"

    def prepare(self, scene: Scene, max_prims: int, max_tree_depth: int,
                max_width: int = gpu_layout.DEFAULT_TEXTURE_WIDTH,
                update: TreeUpdate = REBUILD) -> PreparedMethod:
        return PreparedMethod(gpu_layout.PackedScene({}), 0.0,
                              {"method": self.name, "primitives": scene.n_spheres})


class BoundingIntervalHierarchy:
    """The thesis's BIH (listings 3.3–3.5), rebuilt per request."""
    name = "bih"

    def prepare(self, scene: Scene, max_prims: int, max_tree_depth: int,
                max_width: int = gpu_layout.DEFAULT_TEXTURE_WIDTH,
                update: TreeUpdate = REBUILD) -> PreparedMethod:
        t0 = time.perf_counter()
        bih = build_for_spheres(scene.sphere_centers, scene.sphere_radii, max_prims, max_tree_depth)
        build_ms = (time.perf_counter() - t0) * 1e3
        return PreparedMethod(gpu_layout.pack_bih(bih, max_width), build_ms,
                              {"method": self.name, **bih.stats.to_json()})


from .ray_engine import HierarchicalRayEngine, RayEngine  # noqa: E402  (multi-pass methods, issue #8)
from .bvh import BVHMethod  # noqa: E402  (issue #9)
from .kdtree import KdTreeMethod  # noqa: E402  (issue #9)
from .twolevel import TwoLevelMethod  # noqa: E402  (issue #9)
METHODS: dict[str, AccelerationMethod] = {m.name: m for m in (BoundingIntervalHierarchy(), BruteForce(), RayEngine(),
                                                               HierarchicalRayEngine(), BVHMethod(),
                                                               KdTreeMethod(), TwoLevelMethod())}

AUTO_METHOD = "auto"
# Below this many spheres brute force traces a frame faster than the BIH
# (bench/experiments: crossover per scenario; the smallest is taken).
AUTO_CROSSOVER_N = 16


def resolve_method(name: str, n_spheres: int) -> str:
    """The concrete method for a request: ``auto`` → brute force below the crossover."""
    if name != AUTO_METHOD:
        return name
    return BruteForce.name if n_spheres < AUTO_CROSSOVER_N else BoundingIntervalHierarchy.name

"""Everything a frame needs before the GPU: pose, build, cost — GL-free.

The service does this on the request's own thread, so the GL thread only traces, and so
a frame's cost is known before it is admitted (:mod:`renderer.cost`). A method that keeps
its tree between frames (``bvh``, ``twolevel``) is stateful, so builds are serialised by
a lock here.
"""

from __future__ import annotations

import threading
from collections.abc import Hashable
from dataclasses import dataclass

from .animation import AnimatedScene, pose
from .cost import DEFAULT_MODEL, CostModel, FrameCost, estimate
from .limits import DEFAULT_TEXTURE_WIDTH
from .methods import METHODS, PreparedMethod, check_primitives, resolve_method
from .scene import Scene
from .settings import RenderSettings
from .tree_update import TreeUpdate

_BUILD_LOCK = threading.Lock()


@dataclass
class PreparedFrame:
    """A posed scene, its method's data (None for the multi-pass methods) and its cost."""

    scene: Scene
    settings: RenderSettings
    method: str
    multi_pass: bool
    prepared: PreparedMethod | None
    cost: FrameCost
    pose_ms: float | None
    stats: dict


def prepare_frame(
    scene: Scene | AnimatedScene,
    settings: RenderSettings,
    *,
    key: Hashable | None = None,
    max_width: int = DEFAULT_TEXTURE_WIDTH,
    model: CostModel = DEFAULT_MODEL,
) -> PreparedFrame:
    """Pose ``scene`` at ``settings.time``, build (or update, per ``settings.update`` and the
    animation ``key``) the method's structure and estimate the frame's cost."""
    moving, pose_ms = None, None
    if isinstance(scene, AnimatedScene):
        posed = pose(scene, settings.time)
        scene, moving, pose_ms = posed.scene, posed.moving, posed.pose_ms
    n_tree = scene.n_spheres + scene.n_triangles + scene.n_shapes  # what a tree would hold (auto's crossover)
    name = resolve_method(settings.method, n_tree)
    method = METHODS[name]
    settings.check_method(n_tree)
    check_primitives(name, scene)
    update = TreeUpdate(settings.update, settings.update_threshold, key, moving)
    multi = method.capabilities.multi_pass
    with _BUILD_LOCK:
        prepared = method.prepare(scene, settings.max_prims, settings.max_tree_depth, max_width, update)
    stats = dict(prepared.stats)
    cost = estimate(name, stats, scene, settings, model, multi)
    return PreparedFrame(scene, settings, name, multi, None if multi else prepared, cost, pose_ms, stats)


def band_rows(cost: FrameCost, slice_ms: float, width: int, height: int) -> int:
    """Rows of a band that cost about ``slice_ms`` (at least one, at most the pass)."""
    per_row = cost.ms_per_pixel * width
    if per_row <= 0:
        return height
    return max(1, min(height, int(slice_ms / per_row)))


def batch_size(cost: FrameCost, slice_ms: float, n_primitives: int) -> int:
    """Primitives of a ray-engine batch that cost about ``slice_ms`` (at least one)."""
    per_prim = cost.ms / max(1, n_primitives)
    if per_prim <= 0:
        return max(1, n_primitives)
    return max(1, min(max(1, n_primitives), int(slice_ms / per_prim)))

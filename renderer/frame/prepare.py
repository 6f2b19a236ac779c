"""Everything a frame needs before the GPU: pose, plan (:mod:`renderer.frame.plan`), build, cost — GL-free.

The service does this on the request's own thread, so the GL thread only traces, and so
a frame's cost is known before it is admitted (:mod:`renderer.frame.cost`). A method that keeps
its tree between frames (``bvh``, ``twolevel``) is stateful, so builds are serialised by
a lock here.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections import OrderedDict
from collections.abc import Hashable
from dataclasses import dataclass, field

import numpy as np

from .. import limits
from ..config.methods import METHODS, PreparedMethod
from ..config.settings import RenderSettings
from ..geometry.scene import Camera, Scene
from ..limits import DEFAULT_TEXTURE_WIDTH
from ..modes import RAY_TREE_MODES
from ..oracle.reference import ray_tree_counts
from ..scenes.animation import AnimatedScene, pose
from ..scenes.tree_update import TreeUpdate
from . import first_hits
from .cost import DEFAULT_MODEL, CostModel, FrameCost, estimate
from .plan import FramePlan, plan_frame

_BUILD_LOCK = threading.Lock()


@dataclass
class PreparedFrame:
    """A frame's plan (its posed scene, settings, method and variant: :class:`renderer.frame.plan.FramePlan`),
    its method's data (None for the multi-pass methods) and its cost."""

    plan: FramePlan
    prepared: PreparedMethod | None
    cost: FrameCost
    pose_ms: float | None
    stats: dict
    model: CostModel = field(default=DEFAULT_MODEL, repr=False)
    level_rays: tuple[float, ...] | None = None  # the ray tree counted on a sample (sampled_level_rays)

    @property
    def scene(self) -> Scene:
        return self.plan.scene

    @property
    def settings(self) -> RenderSettings:
        return self.plan.settings

    @property
    def method(self) -> str:
        return self.plan.method

    @property
    def multi_pass(self) -> bool:
        return self.plan.multi_pass

    def estimate(self, settings: RenderSettings) -> FrameCost:
        """The cost of this frame's scene and build traced with ``settings`` instead (the same
        method, the same sampled ray tree — exact for any depth up to the frame's: what the 422 of a
        frame over the cap offers is costed as the frame was)."""
        return frame_cost(self.method, self.stats, self.scene, settings, self.model, self.multi_pass, self.level_rays)


def sampled_level_rays(scene: Scene, settings: RenderSettings) -> tuple[float, ...] | None:
    """Radiance rays per pixel at each level of the frame's ray tree, counted by the reference tracer
    on a grid of ``RAY_TREE_SAMPLE_SIDE`` pixels on its long side (the frame's aspect), ``min_weight``'s
    cut-off applied, up to ``max_recursion_depth`` levels; None where the model's ray tree of the
    materials stands instead: scenes of more than ``RAY_TREE_SAMPLE_MAX_PRIMITIVES`` primitives, modes
    without a ray tree and the path integrator. A scene's few glass or mirror surfaces branch only the
    rays that meet them (the demo room: 1.5 radiance rays a pixel, where every ray branching would be
    34; the default scene's spheres framed for a phone: 4.8, where the materials' tree says 21.9, an
    estimate 3.9 × the measured GL time against the sampled tree's 0.8 ×)."""
    path = settings.path_traced
    n = scene.n_tree_primitives
    if path or settings.mode not in RAY_TREE_MODES:
        return None
    if n > limits.RAY_TREE_SAMPLE_MAX_PRIMITIVES:
        return None
    side, w, h = limits.RAY_TREE_SAMPLE_SIDE, settings.width, settings.height
    sw, sh = (side, max(1, round(side * h / w))) if w >= h else (max(1, round(side * w / h)), side)
    # a view of this scene's geometry (shared by every camera's copy: Scene.with_camera) and of what the
    # count reads; the counts kept for it are reused for a camera near enough (RAY_TREE_REUSE_*)
    key = (
        id(scene.sphere_centers),
        id(scene.meshes),
        id(scene.shapes),
        sw,
        sh,
        settings.max_recursion_depth,
        settings.min_weight,
    )
    with _TREE_LOCK:
        held = _TREES.get(key)
    if held is not None and held[0]() is scene.sphere_centers and near_view(held[1], scene.camera):
        return held[2]
    counts = ray_tree_counts(scene, sw, sh, settings.max_recursion_depth, settings.min_weight)
    level_rays = tuple(c / (sw * sh) for c in counts)
    with _TREE_LOCK:
        _TREES[key] = (weakref.ref(scene.sphere_centers), scene.camera, level_rays)
        _TREES.move_to_end(key)
        while len(_TREES) > _TREES_KEPT:
            _TREES.popitem(last=False)
    return level_rays


def near_view(counted: Camera, camera: Camera) -> bool:
    """Whether ``camera`` sees nearly what ``counted`` saw: the same field of view, its forward
    direction within RAY_TREE_REUSE_DEG and its position within RAY_TREE_REUSE_MOVE of the distance
    to its target."""
    if counted.fov_y != camera.fov_y:
        return False
    a, b = np.subtract(counted.target, counted.position), np.subtract(camera.target, camera.position)
    la, lb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    cos = float(np.dot(a, b)) / (la * lb)
    moved = float(np.linalg.norm(np.subtract(counted.position, camera.position)))
    return cos >= math.cos(math.radians(limits.RAY_TREE_REUSE_DEG)) and moved <= limits.RAY_TREE_REUSE_MOVE * lb


# The last sampled ray trees (a view's preview, full frame and refinement ask for the same one, a drag's
# frames for nearly the same): by the scene's geometry (its sphere array held weakly: an id is reused
# once its array is gone) and what the count reads, with the camera they were counted for.
_TREES: OrderedDict[tuple, tuple[weakref.ref, Camera, tuple[float, ...]]] = OrderedDict()
_TREES_KEPT = 64
_TREE_LOCK = threading.Lock()


def frame_cost(
    method: str,
    stats: dict,
    scene: Scene,
    settings: RenderSettings,
    model: CostModel,
    multi_pass: bool,
    level_rays: tuple[float, ...] | None = None,
) -> FrameCost:
    """What the frame will really do, estimated: its traversal (:func:`renderer.frame.cost.estimate`; its
    ray tree ``level_rays`` where sampled), or, where its first hits are rasterised (``first_hits``:
    raster, tiles, or auto choosing one of them by these estimates — :func:`renderer.frame.first_hits.chosen`),
    its quads' overdraw (:func:`renderer.frame.first_hits.frame_cost`)."""
    traced = estimate(method, stats, scene, settings, model, multi_pass, level_rays)
    if multi_pass:
        return traced
    path = settings.path_traced  # as the variant decides
    how = first_hits.chosen(scene, settings, path, method, stats)
    return first_hits.frame_cost(how, scene, settings, traced, model) if how else traced


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
    at_rest = scene.n_tree_primitives  # auto's choice, the same for every pose
    if isinstance(scene, AnimatedScene):
        posed = pose(scene, settings.time)
        scene, moving, pose_ms = posed.scene, posed.moving, posed.pose_ms
    plan = plan_frame(scene, settings, tree_primitives=at_rest)
    update = TreeUpdate(settings.update, settings.update_threshold, key, moving)
    multi = plan.multi_pass
    with _BUILD_LOCK:
        prepared = METHODS[plan.method].prepare(scene, settings.max_prims, settings.max_tree_depth, max_width, update)
    stats = dict(prepared.stats)
    level_rays = sampled_level_rays(scene, settings)
    cost = frame_cost(plan.method, stats, scene, settings, model, multi, level_rays)
    return PreparedFrame(plan, None if multi else prepared, cost, pose_ms, stats, model, level_rays)


def band_rows(cost: FrameCost, slice_ms: float, width: int, height: int) -> int:
    """Rows of a band that cost about ``slice_ms`` where the scene is (at least one, at most the
    pass): the frame's cost is spent where the primitives' box covers the image, so a band sized
    by the whole image's average would cost 1 / coverage times the budget there."""
    per_row = cost.ms_per_pixel * width / max(limits.MIN_BAND_COVERAGE, min(1.0, cost.coverage))
    if per_row <= 0:
        return height
    return max(1, min(height, int(slice_ms / per_row)))


def batch_size(cost: FrameCost, slice_ms: float, n_primitives: int) -> int:
    """Primitives of a ray-engine batch that cost about ``slice_ms`` (at least one)."""
    per_prim = cost.ms / max(1, n_primitives)
    if per_prim <= 0:
        return max(1, n_primitives)
    return max(1, min(max(1, n_primitives), int(slice_ms / per_prim)))

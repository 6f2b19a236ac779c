"""What a frame will cost, estimated before it is traced: the service admits, slices and
schedules frames by it (docs/API.md, "Cost of a frame").

A frame is ``passes`` passes of ``pixels`` fragments each (:func:`renderer.gl.frame.plan_passes`;
the ray engines trace the whole grid per layer). Each fragment traces a ray tree: one
radiance ray per level, ``levels`` levels (the recursion depth the variant can reach, cut
by ε), branching in two where a material both reflects and transmits, and continuing to
the next level with probability ``level_decay``; each radiance ray in the colour mode also
casts one shadow ray per light. Each ray costs what its hierarchy says a ray through the
scene's box costs — the SAH's two terms, computed by the build (``sah_nodes`` node visits,
``sah_tests`` sphere tests: a single leaf of n spheres costs n tests, as brute force) — plus
one test per plane. The ray engines draw every primitive over every ray of a layer
(``ns_raster`` per primitive and pixel).

The constants are nanoseconds of this project's reference machine (2 cores, Mesa
llvmpipe), fitted by ``bench/cost.py`` to measured traces; the fit is in docs/RESULTS.md.
The estimate is for bounding and scheduling (admission, slice sizes, Retry-After), not a
prediction to the millisecond.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .features import GENERIC, scene_features
from .modes import AVERAGED_MODES, RAY_TREE_MODES
from .scene import Scene


@dataclass(frozen=True)
class CostModel:
    """Nanoseconds per unit of work on the reference machine."""
    ns_frame: float = 2.0e6        # per frame: uploads, draw set-up, read-back
    ns_pixel: float = 40.0         # per fragment and traced ray: generation, shading, write
    ns_node: float = 2.0           # per node visit
    ns_test: float = 2.5           # per sphere (or plane) test
    ns_raster: float = 1.0         # ray engines: per primitive drawn over one ray
    level_decay: float = 0.5       # share of rays whose path goes on to the next level


# Fitted by bench/cost.py (see docs/RESULTS.md, "Cost model"); rerun it on another machine.
DEFAULT_MODEL = CostModel()


@dataclass(frozen=True)
class FrameCost:
    """The estimate of one frame. ``ms`` is the whole frame; ``ms_per_pixel`` one fragment
    of one pass (what a band of rows costs per pixel)."""
    passes: int
    pixels: int                 # fragments per pass
    rays_per_pixel: float       # radiance and shadow rays of one fragment
    nodes_per_ray: float
    tests_per_ray: float
    ms: float
    ms_per_pixel: float
    degenerate: bool            # the hierarchy tests (nearly) every sphere on every ray

    def to_json(self) -> dict[str, Any]:
        return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in self.__dict__.items()}


def traversal_work(method: str, stats: dict[str, Any], n_spheres: int) -> tuple[float, float]:
    """(node visits, primitive tests) a ray can expect from the structure a build reported;
    ``n_spheres``: the primitives a brute-force ray tests (spheres and triangles)."""
    if method in ("bruteforce", "rayengine", "hre") or not stats:
        return 0.0, float(n_spheres)
    if method == "twolevel":
        parts = [stats.get("kd") or {}, stats.get("bvh") or {}]
        return (sum(float(p.get("sah_nodes", 0.0)) for p in parts),
                sum(float(p.get("sah_tests", 0.0)) for p in parts))
    return float(stats.get("sah_nodes", 0.0)), float(stats.get("sah_tests", n_spheres))


def ray_tree(scene: Scene, settings, model: CostModel = DEFAULT_MODEL) -> tuple[int, float]:
    """(levels, radiance rays per pixel) of the ray tree the settings trace in this scene."""
    if settings.mode not in RAY_TREE_MODES:
        return 1, 1.0
    features = scene_features(scene) if settings.specialize else GENERIC
    levels = features.recursion_depth(settings.max_recursion_depth)
    used = (set(np.unique(scene.sphere_materials).tolist()) | {p.material for p in scene.planes}
            | {m.material for m in scene.meshes})
    mats = [scene.materials[i] for i in used] or list(scene.materials)
    k_max = max((max(m.reflective, m.transmissive) for m in mats), default=0.0)
    if settings.min_weight > 0 and 0 < k_max < 1:   # ε stops a path once its weight k_max^(L−1) < ε
        levels = min(levels, 1 + int(math.floor(math.log(settings.min_weight) / math.log(k_max) + 1e-9)))
    if k_max == 0:
        levels = 1
    branching = 2.0 if any(m.reflective > 0 and m.transmissive > 0 for m in mats) else 1.0
    g = branching * model.level_decay
    rays = sum(g ** level for level in range(levels))
    return levels, rays


def estimate(method: str, stats: dict[str, Any], scene: Scene, settings, model: CostModel = DEFAULT_MODEL,
             multi_pass: bool = False) -> FrameCost:
    """The cost of tracing ``scene`` with ``settings`` by ``method`` whose build reported ``stats``."""
    k = settings.supersampling
    averaged = settings.mode in AVERAGED_MODES
    w, h = settings.width, settings.height
    levels, radiance = ray_tree(scene, settings, model)
    lights = len(scene.lights) if settings.mode == "color" else 0
    rays = radiance * (1 + lights)
    n = scene.n_spheres + scene.n_triangles     # what a tree holds (a triangle test costs as a sphere's)
    nodes, tests = traversal_work(method, stats, n)
    tests += len(scene.planes)
    degenerate = n >= 64 and tests >= 0.5 * n and method not in ("bruteforce", "rayengine", "hre")
    if multi_pass:
        # Every primitive is drawn over the whole padded grid, once per layer and per light.
        pixels = w * h * (k * k if averaged else 1)
        per_pixel = model.ns_pixel * rays + model.ns_raster * (n + len(scene.planes)) * rays
        passes = 1 + (1 if averaged and k > 1 else 0)
        total = model.ns_frame + pixels * per_pixel + (w * h * model.ns_raster * n if passes > 1 else 0.0)
        return FrameCost(passes, pixels, rays, 0.0, float(n), total / 1e6, per_pixel / 1e6, False)
    passes = 1 + (k * k if averaged and k > 1 else 0)
    pixels = w * h
    per_pixel = rays * (model.ns_pixel + model.ns_node * nodes + model.ns_test * tests)
    total = model.ns_frame + passes * pixels * per_pixel
    return FrameCost(passes, pixels, rays, nodes, tests, total / 1e6, per_pixel / 1e6, degenerate)


def largest_accepted(method: str, stats: dict[str, Any], scene: Scene, settings, limit_ms: float,
                     model: CostModel = DEFAULT_MODEL, multi_pass: bool = False) -> dict[str, Any]:
    """For each setting that makes a frame cheaper without a new build, the value closest to
    the requested one whose frame fits ``limit_ms``: the largest width, height, samples per
    pixel and recursion depth (None where even the smallest does not fit)."""
    def fits(**kw) -> bool:
        return estimate(method, stats, scene, replace(settings, **kw), model, multi_pass).ms <= limit_ms
    out: dict[str, Any] = {}
    for name in ("width", "height"):
        lo, hi = 0, getattr(settings, name)
        while lo < hi:                       # cost grows with the side: bisect the largest that fits
            mid = (lo + hi + 1) // 2
            if fits(**{name: mid}):
                lo = mid
            else:
                hi = mid - 1
        out[name] = lo or None
    out["samples_per_pixel"] = next((s for s in (16, 9, 4, 1) if s <= settings.samples_per_pixel
                                     and fits(samples_per_pixel=s)), None)
    out["max_recursion_depth"] = next((d for d in range(settings.max_recursion_depth, 0, -1)
                                       if fits(max_recursion_depth=d)), None)
    return out

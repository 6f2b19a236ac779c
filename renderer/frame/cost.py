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
one test per plane. A triangle's (or an analytic shape's) test is a leaf test as a sphere's (``n`` =
spheres + triangles + shapes) and costs ``ns_mesh_test`` more: Woop et al.'s test fetches three
records instead of one and does more arithmetic. A mesh scene's ray tree is counted on a sample of
its pixels (``level_rays``, :func:`renderer.frame.prepare.sampled_level_rays`) rather than taken from its
materials: its few glass or mirror surfaces branch only the rays that meet them. The ray engines draw
every primitive over every ray of a layer (``ns_raster`` per primitive and pixel).

The constants are nanoseconds of this project's reference machine (2 cores, Mesa
llvmpipe), fitted by the cost experiment to measured traces; the fit is in docs/RESULTS.md.
The estimate is for bounding and scheduling, not a prediction to the millisecond: slices,
Retry-After and the queue's work use ``ms`` (the median frame is estimated right); the cap
on a frame, POCKETRAY_MAX_FRAME_COST, uses ``bound_ms``, what 90 % of the fitted frames'
measured times stay below.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..geometry.scene import Scene
from ..geometry.shapes import bounds as shape_bounds
from ..integrators import Integrator
from ..materials.kinds import AnyMaterial
from ..materials.phong import Material
from ..modes import AVERAGED_MODES, RAY_TREE_MODES
from .features import GENERIC, scene_features


@dataclass(frozen=True)
class CostModel:
    """Nanoseconds per unit of work on the reference machine (the terms of :func:`terms`)."""

    ns_frame: float = 1.0e6  # per frame: uploads, draw set-up, read-back
    ns_pixel: float = 150.0  # per fragment and traced ray: generation, shading, writes
    ns_node: float = 2.0  # per node visit of a ray inside the scene's box
    ns_test: float = 4.0  # per sphere test in small leaves (the SAH's count; a ray stops early)
    ns_leaf_test: float = 20.0  # per sphere test in leaves of more than BIG_LEAF (every one is made)
    ns_bf_test: float = 10.0  # brute force: per sphere test (every ray tests every sphere)
    ns_pass: float = 50.0  # ray engines: per full-screen pass and pixel
    ns_raster: float = 3.0  # ray engines: per primitive drawn over one ray
    ns_mesh_test: float = 0.0  # per triangle or analytic-shape test of a ray inside the scene's box
    level_decay: float = 0.7  # share of rays whose path goes on to the next level
    upper: float = 2.5  # measured / estimated that 90 % of the fitted frames stay below

    TERMS = ("frame", "pixel", "node", "test", "leaf_test", "bf_test", "pass", "raster", "mesh_test")

    def vector(self) -> np.ndarray:
        return np.array(
            [
                self.ns_frame,
                self.ns_pixel,
                self.ns_node,
                self.ns_test,
                self.ns_leaf_test,
                self.ns_bf_test,
                self.ns_pass,
                self.ns_raster,
                self.ns_mesh_test,
            ]
        )


# Fitted by bench/experiments/cost.py to 368 frames of every method on this project's
# reference machine (2 cores, llvmpipe; docs/RESULTS.md, "Cost model"), scaled so that the
# median frame is estimated right; rerun it on another machine.
# Refitted for the shader shaped for llvmpipe (its frames are 0.3-0.6x the ones of the first fit, which
# refused the phone client's default still frame), with dense scenes up to 2^21 spheres.
DEFAULT_MODEL = CostModel(
    ns_frame=7.27e6,
    ns_pixel=76.0,
    ns_node=3.30,
    ns_test=0.0,
    ns_leaf_test=1.43,
    ns_bf_test=1.91,
    ns_pass=52.6,
    ns_raster=2.45,
    # Calibrated on the demo meshes (room, mixed) against sphere frames measured beside them
    # (bench/experiments/cost.py, mesh_frames): a ray through 2,700 triangles of the room costs
    # 5-9 times one through spheres, where every (small-leaf) sphere test is free in the fit above.
    ns_mesh_test=25.0,
    level_decay=0.7,
    upper=2.13,
)


# Rasterised first hits (renderer/frame/first_hits.py): a primary-ray frame's trace is a fixed part, one
# full-screen pass when the scene has planes, and its spheres' quads' fragments. Nanoseconds in this
# model's units, fitted (least squares, no negative term) by bench/experiments/first_hits.py to 36 frames
# (scenarios 1-3, n = 64 … 65,536, with and without the plane, 640 × 1088) traced every way in one run
# (docs/RESULTS.md, "First hits without a traversal per pixel"); with the traversal's estimate, the
# cheapest of the three was the fastest measured, or within 10 % of it, in 32 of them.
RASTER_NS_FRAME = 3.85e6
RASTER_NS_FRAGMENT = 35.7
RASTER_NS_PLANE_PIXEL = 39.0


def first_hits_ms(fragments: float, pixels: float, planes: bool) -> float:
    """The trace stage of a frame whose first hits are rasterised, in ms: ``fragments`` its quads
    shade over all its passes, ``pixels`` its passes' pixels, ``planes`` whether it has planes."""
    return (
        RASTER_NS_FRAME + RASTER_NS_FRAGMENT * fragments + (RASTER_NS_PLANE_PIXEL * pixels if planes else 0.0)
    ) / 1e6


# … and per tile (first_hits=tiles): a fixed part, the (tile, sphere) pairs the host sorts into lists, the
# pixels of tiles with a list (their term fitted to 0: the lists' early exit keeps them cheap, the fixed
# part holds the rest), the full-screen pass when the scene has planes. The same fit.
TILES_NS_FRAME = 11.86e6
TILES_NS_PAIR = 566.0
TILES_NS_TILE_PIXEL = 0.0
TILES_NS_PLANE_PIXEL = 50.3


def tiles_ms(pairs: float, tile_pixels: float, pixels: float, planes: bool) -> float:
    """The trace stage of a frame whose first hits come from tile lists, in ms: ``pairs`` (tile, sphere)
    entries and ``tile_pixels`` pixels in listed tiles over all its passes, ``pixels`` its passes' pixels."""
    return (
        TILES_NS_FRAME
        + TILES_NS_PAIR * pairs
        + TILES_NS_TILE_PIXEL * tile_pixels
        + (TILES_NS_PLANE_PIXEL * pixels if planes else 0.0)
    ) / 1e6


def traversal_ms(method: str, stats: dict[str, Any], scene: Scene, settings, model: CostModel = DEFAULT_MODEL) -> float:
    """The trace stage of the same frame by the method's traversal, in ms (:func:`estimate` less its
    per-frame part: uploads and read-back are the same either way)."""
    return estimate(method, stats, scene, settings, model).ms - model.ns_frame / 1e6


@dataclass(frozen=True)
class FrameCost:
    """The estimate of one frame. ``ms`` is the whole frame; ``ms_per_pixel`` one fragment
    of one pass (what a band of rows costs per pixel)."""

    passes: int
    pixels: int  # fragments per pass
    rays_per_pixel: float  # radiance and shadow rays of one fragment
    nodes_per_ray: float
    tests_per_ray: float
    coverage: float  # share of the primary rays that enter the scene's box
    ms: float
    ms_per_pixel: float
    bound_ms: float  # what 90 % of such frames stay below: ms × the model's ``upper``
    degenerate: bool  # the hierarchy tests (nearly) every sphere on every ray

    def to_json(self) -> dict[str, Any]:
        return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in self.__dict__.items()}


def structures(stats: dict[str, Any]) -> list[dict[str, Any]]:
    """The hierarchies a build reported the SAH's terms of (``sah_tests`` …): the tree itself, or
    each level of a two-level method (its statistics hold one entry per level); none for a
    method without a structure (brute force, the ray engines), whose rays test every primitive."""
    if "sah_tests" in stats:
        return [stats]
    return [v for v in stats.values() if isinstance(v, dict) and "sah_tests" in v]


def traversal_work(method: str, stats: dict[str, Any], n_primitives: int) -> tuple[float, float, float]:
    """(node visits, primitive tests, of those in big leaves) a ray through the scene's box can
    expect from the structure a build reported (the SAH's terms; a method without a
    structure tests all)."""
    parts = structures(stats)
    if not parts:
        return 0.0, float(n_primitives), float(n_primitives)
    nodes, tests, big_tests = (
        sum(float(p.get(k, 0.0)) for p in parts) for k in ("sah_nodes", "sah_tests", "sah_big_tests")
    )
    return nodes, tests, big_tests


# The path integrator: expected segments of one sample (its shadow rays counted, as docs/SHADING.md
# counts a path's segments) at max_recursion_depth D, S(D) = LIMIT − (LIMIT − 1) · RATE^(D − 1): one
# segment at D = 1, each further one adding a share RATE of what is left. Fitted by the path
# experiment (bench/experiments/path.py; docs/RESULTS.md, "Path integrator") to the scene whose
# paths trace the most rays, the closed Cornell box; the open scenes measured trace about half.
PATH_SEGMENTS_LIMIT = 6.58
PATH_SEGMENTS_RATE = 0.644


def path_segments(depth: int) -> float:
    """Expected segments (rays, shadow rays included) one path sample traces at max_recursion_depth
    ``depth``: the fit above, never more than the path can have (one bounce and one shadow ray per
    vertex: 2·depth − 1)."""
    d = max(1, int(depth))
    return min(2.0 * d - 1.0, PATH_SEGMENTS_LIMIT - (PATH_SEGMENTS_LIMIT - 1.0) * PATH_SEGMENTS_RATE ** (d - 1))


def request_work(width: int, height: int, max_recursion_depth: int, samples_per_pixel: int, path: bool) -> float:
    """What ``POCKETRAY_MAX_WORK`` caps, before any build: the Whitted tracer's width × height ×
    max_recursion_depth × samples_per_pixel (a ray tree's levels); the path integrator's expected
    segments, width × height × samples_per_pixel × :func:`path_segments` (a path's length saturates
    with depth where the ray tree's levels do not)."""
    if path:
        return width * height * samples_per_pixel * path_segments(max_recursion_depth)
    return float(width * height * max_recursion_depth * samples_per_pixel)


def ray_tree(
    scene: Scene, settings, decay: float = DEFAULT_MODEL.level_decay, level_rays: tuple[float, ...] | None = None
) -> tuple[int, float]:
    """(levels, radiance rays per pixel) of the ray tree the settings trace in this scene. ``level_rays``:
    the radiance rays per pixel each level traces, counted on a sample of the frame's pixels
    (:func:`renderer.frame.prepare.sampled_level_rays`): where given, the tree is theirs (its first ``levels``
    levels) — a scene whose few glass or mirror surfaces cover few pixels branches on those alone —
    and otherwise every ray is taken to meet the scene's most reflective material and branch where
    any material both reflects and transmits (``decay`` of them going on each level)."""
    if settings.mode not in RAY_TREE_MODES:
        return 1, 1.0
    features = (scene_features(scene) if settings.specialize else GENERIC).with_integrator(
        settings.integrator, settings.mode
    )
    levels = features.recursion_depth(settings.max_recursion_depth)
    if features.path:  # each sample one path of path_segments(levels) rays, shadow rays included
        return levels, settings.samples_per_pixel * path_segments(levels)
    if level_rays is not None:
        return levels, float(sum(level_rays[:levels]))
    used = (
        set(np.unique(scene.sphere_materials).tolist())
        | {p.material for p in scene.planes}
        | {m.material for m in scene.meshes}
    )
    mats = [scene.materials[i] for i in used] or list(scene.materials)
    k_max = max((_max_weight(m) for m in mats), default=0.0)
    if settings.min_weight > 0 and 0 < k_max < 1:  # ε stops a path once its weight k_max^(L−1) < ε
        levels = min(levels, 1 + int(math.floor(math.log(settings.min_weight) / math.log(k_max) + 1e-9)))
    if k_max == 0:
        levels = 1
    branching = 2.0 if any(m.reflects and m.transmits for m in mats) else 1.0
    g = branching * decay
    return levels, sum(g**level for level in range(levels))


def _branching(scene: Scene) -> int:
    """Child layers a ray-engine layer makes: 2 where some material reflects and another (or
    the same) transmits, else 1."""
    used = (
        set(np.unique(scene.sphere_materials).tolist())
        | {p.material for p in scene.planes}
        | {m.material for m in scene.meshes}
    )
    mats = [scene.materials[i] for i in used]
    return 2 if any(m.reflects for m in mats) and any(m.transmits for m in mats) else 1


def _max_weight(m: AnyMaterial) -> float:
    """The largest weight of a ray a hit on ``m`` spawns (Whitted): kr or kt; a PBR material's
    reflected ray is weighted at most (1 − roughness)² (Fresnel ≤ 1), its refracted one by its
    transmissive share."""
    if isinstance(m, Material):
        return max(m.reflective, m.transmissive)
    return max((1.0 - m.roughness) ** 2 if m.reflects else 0.0, m.transmission * (1.0 - m.metallic))


def coverage(scene: Scene, width: int, height: int) -> float:
    """The share of the image whose primary rays enter the primitives' bounding box: the box's
    projection onto the image (1 when the camera is inside or beside it, 0 for none)."""
    boxes = []
    if scene.n_spheres:
        boxes += [
            scene.sphere_centers - scene.sphere_radii[:, None],
            scene.sphere_centers + scene.sphere_radii[:, None],
        ]
    if scene.n_triangles:
        boxes.append(scene.triangle_corners.reshape(-1, 3))
    if scene.n_shapes:
        boxes.append(shape_bounds(scene.shapes).reshape(-1, 3))
    if not boxes:
        return 0.0
    points = np.concatenate(boxes)
    lo, hi = points.min(axis=0), points.max(axis=0)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    cam = scene.camera
    right, up, forward = cam.basis()
    v = corners - np.asarray(cam.position, dtype=np.float64)
    z = v @ forward
    if (z <= 0).any():
        return 1.0
    s = math.tan(math.radians(cam.fov_y) / 2.0)
    x = (v @ right) / z / (s * width / height)
    y = (v @ up) / z / s
    w_ = max(0.0, min(1.0, x.max()) - max(-1.0, x.min()))
    h_ = max(0.0, min(1.0, y.max()) - max(-1.0, y.min()))
    return float(w_ * h_ / 4.0)


def terms(
    method: str,
    stats: dict[str, Any],
    scene: Scene,
    settings,
    decay: float,
    multi_pass: bool = False,
    level_rays: tuple[float, ...] | None = None,
) -> tuple[np.ndarray, dict[str, Any]]:
    """The frame's work in the model's units (:attr:`CostModel.TERMS`), and what it is made of
    (``level_rays``: :func:`ray_tree`'s)."""
    k = settings.supersampling
    averaged = settings.mode in AVERAGED_MODES
    w, h = settings.width, settings.height
    levels, radiance = ray_tree(scene, settings, decay, level_rays)
    # A path's shadow rays are among its counted segments (path_segments); Whitted's are one per light.
    path = getattr(settings, "integrator", Integrator.WHITTED) == Integrator.PATH
    lights = len(scene.lights) if settings.mode == "color" and not path else 0
    rays = radiance * (1 + lights)
    # A triangle test costs as a sphere's; so, unmeasured, does an analytic shape's (a torus's is dearer).
    n, planes = scene.n_tree_primitives, len(scene.planes)
    nodes, tests, big = traversal_work(method, stats, n)
    c = coverage(scene, w, h)
    # Primary rays enter the box where it covers the image; the others start on surfaces in it.
    primary = float(settings.samples_per_pixel) if path else 1.0  # a path sample's camera ray
    rays_in_box = (c * primary + max(0.0, radiance - primary)) * (1 + lights)
    t = np.zeros(len(CostModel.TERMS))
    t[0] = 1.0
    if multi_pass:
        # Per layer — a whole grid of rays per branch path, however few are live: each level
        # has one layer per reflected and per transmitted parent — the full-screen passes
        # (mask, surface, shade, one per light) and every primitive drawn over the grid once,
        # and once more per light.
        grid = w * h * (k * k if averaged else 1)
        centre = w * h if averaged and k > 1 else 0  # the pixel-centre frame of the arrays
        layers = sum(_branching(scene) ** level for level in range(levels)) if settings.mode in RAY_TREE_MODES else 1
        t[1] = grid * rays + centre
        t[6] = grid * layers * (4 + lights) + 4 * centre
        t[7] = (grid * layers * (1 + lights) + centre) * (n + planes)
        meta = {
            "passes": 1 + (1 if centre else 0),
            "pixels": grid,
            "rays": rays,
            "nodes": 0.0,
            "tests": float(n + planes),
            "coverage": c,
        }
        return t, meta
    passes = 1 + (k * k if averaged and k > 1 else 0)
    px = passes * w * h
    t[1] = px * rays
    if not structures(stats):  # every ray tests every primitive
        t[5] = px * rays * n
        t[3] = px * rays * planes
    else:
        t[2] = px * rays_in_box * nodes
        t[3] = px * (rays_in_box * (tests - big) + rays * planes)
        t[4] = px * rays_in_box * big
        # Woop et al.'s test (three records, more arithmetic) and the shapes' dearer ones: their share of the tests.
        t[8] = px * rays_in_box * tests * (scene.n_triangles + scene.n_shapes) / max(1, n)
    meta = {"passes": passes, "pixels": w * h, "rays": rays, "nodes": nodes, "tests": tests + planes, "coverage": c}
    return t, meta


def estimate(
    method: str,
    stats: dict[str, Any],
    scene: Scene,
    settings,
    model: CostModel = DEFAULT_MODEL,
    multi_pass: bool = False,
    level_rays: tuple[float, ...] | None = None,
) -> FrameCost:
    """The cost of tracing ``scene`` with ``settings`` by ``method`` whose build reported ``stats``
    (``level_rays``: the ray tree's rays per level, where sampled: :func:`ray_tree`)."""
    t, m = terms(method, stats, scene, settings, model.level_decay, multi_pass, level_rays)
    total = float(t @ model.vector())
    frags = m["passes"] * m["pixels"]
    n = scene.n_tree_primitives
    degenerate = not multi_pass and bool(structures(stats)) and n >= 64 and m["tests"] >= 0.5 * n
    return FrameCost(
        m["passes"],
        m["pixels"],
        m["rays"],
        m["nodes"],
        m["tests"],
        m["coverage"],
        total / 1e6,
        (total - model.ns_frame) / max(1, frags) / 1e6,
        total / 1e6 * model.upper,
        degenerate,
    )


def largest_accepted(
    method: str,
    stats: dict[str, Any],
    scene: Scene,
    settings,
    limit_ms: float,
    model: CostModel = DEFAULT_MODEL,
    multi_pass: bool = False,
    estimator: Callable[[Any], FrameCost] | None = None,
) -> dict[str, Any]:
    """For each setting that makes a frame cheaper without a new build, the value closest to
    the requested one whose frame fits ``limit_ms``: the largest width, height, samples per
    pixel and recursion depth (None where even the smallest does not fit). ``estimator``: the
    cost of the frame with other settings (default: :func:`estimate`, the traversal's;
    :meth:`renderer.frame.prepare.PreparedFrame.estimate` costs rasterised first hits as the frame does)."""

    def fits(**kw) -> bool:
        changed = replace(settings, **kw)
        if estimator is not None:
            return estimator(changed).bound_ms <= limit_ms
        return estimate(method, stats, scene, changed, model, multi_pass).bound_ms <= limit_ms

    out: dict[str, Any] = {}
    for name in ("width", "height"):
        lo, hi = 0, getattr(settings, name)
        while lo < hi:  # cost grows with the side: bisect the largest that fits
            mid = (lo + hi + 1) // 2
            if fits(**{name: mid}):
                lo = mid
            else:
                hi = mid - 1
        out[name] = lo or None
    if getattr(settings, "integrator", Integrator.WHITTED) == Integrator.PATH:  # any count: bisect it as the sides
        lo, hi = 0, settings.samples_per_pixel
        while lo < hi:
            mid = (lo + hi + 1) // 2
            lo, hi = (mid, hi) if fits(samples_per_pixel=mid) else (lo, mid - 1)
        out["samples_per_pixel"] = lo or None
    else:
        out["samples_per_pixel"] = next(
            (s for s in (16, 9, 4, 1) if s <= settings.samples_per_pixel and fits(samples_per_pixel=s)), None
        )
    out["max_recursion_depth"] = next(
        (d for d in range(settings.max_recursion_depth, 0, -1) if fits(max_recursion_depth=d)), None
    )
    return out

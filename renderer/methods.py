"""The registry of acceleration methods: names → implementations (:mod:`renderer.accel`).

Adding a method is its own files under ``renderer/accel/`` (and ``shaders/`` for a
single-pass traversal) plus one line below; the README's "Adding a method" shows how.
Every method is behind the interface of :mod:`renderer.accel.base` and declares its
:class:`~renderer.accel.base.Capabilities`.
"""

from __future__ import annotations

from .accel.base import AccelerationMethod, Capabilities, PreparedMethod  # noqa: F401  (the interface)
from .accel.bih import BoundingIntervalHierarchy
from .accel.bruteforce import BruteForce
from .accel.bvh import BVHMethod
from .accel.kdtree import KdTreeMethod
from .accel.ray_engine import HierarchicalRayEngine, RayEngine
from .accel.twolevel import TwoLevelMethod

METHODS: dict[str, AccelerationMethod] = {m.name: m for m in (
    BoundingIntervalHierarchy(),
    BruteForce(),
    RayEngine(),
    HierarchicalRayEngine(),
    BVHMethod(),
    KdTreeMethod(),
    TwoLevelMethod(),
)}

AUTO_METHOD = "auto"
# Below this many spheres brute force traces a frame faster than the BIH
# (bench/experiments: crossover per scenario; the smallest is taken).
AUTO_CROSSOVER_N = 16


def resolve_method(name: str, n_spheres: int) -> str:
    """The concrete method for a request: ``auto`` → brute force below the crossover, else BIH."""
    if name != AUTO_METHOD:
        return name
    return BruteForce.name if n_spheres < AUTO_CROSSOVER_N else BoundingIntervalHierarchy.name


def capabilities(name: str, n_spheres: int = 0) -> Capabilities:
    """What the method a request names (``auto`` resolved for ``n_spheres``) can do."""
    return METHODS[resolve_method(name, n_spheres)].capabilities

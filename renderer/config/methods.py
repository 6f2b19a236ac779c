"""The registry of acceleration methods: names → implementations (:mod:`renderer.accel`).

Adding a method is its own files under ``renderer/accel/`` (and ``shaders/`` for a
single-pass traversal) plus one line below; the README's "Adding a method" shows how.
Every method is behind the interface of :mod:`renderer.accel.base` and declares its
:class:`~renderer.accel.base.Capabilities`.
"""

from __future__ import annotations

from ..accel.base import AccelerationMethod, Capabilities, PreparedMethod  # noqa: F401 - re-exported: the interface
from ..accel.bih import BoundingIntervalHierarchy
from ..accel.bruteforce import BruteForce
from ..accel.bvh import BVHMethod
from ..accel.kdtree import KdTreeMethod
from ..accel.ray_engine import HierarchicalRayEngine, RayEngine
from ..accel.twolevel import TwoLevelMethod
from ..geometry.scene import SceneError

METHODS: dict[str, AccelerationMethod] = {
    m.name: m
    for m in (
        BoundingIntervalHierarchy(),
        BruteForce(),
        RayEngine(),
        HierarchicalRayEngine(),
        BVHMethod(),
        KdTreeMethod(),
        TwoLevelMethod(),
    )
}

AUTO_METHOD = "auto"
AUTO_LABEL = "Auto (brute force below the crossover, else BIH)"
# Below this many spheres brute force traces a frame faster than the BIH
# (bench/experiments: crossover per scenario; the smallest is taken).
AUTO_CROSSOVER_N = 16


def resolve_method(name: str, tree_primitives: int) -> str:
    """The concrete method for a request: ``auto`` → brute force below the crossover, else BIH.
    ``tree_primitives`` counts the primitives a tree would hold: spheres, triangles and analytic
    shapes (:attr:`renderer.geometry.scene.Scene.n_tree_primitives`)."""
    if name != AUTO_METHOD:
        return name
    return BruteForce.name if tree_primitives < AUTO_CROSSOVER_N else BoundingIntervalHierarchy.name


def capabilities(name: str, tree_primitives: int = 0) -> Capabilities:
    """What the method a request names (``auto`` resolved for ``tree_primitives``) can do."""
    return METHODS[resolve_method(name, tree_primitives)].capabilities


def integrator_methods(integrator: str) -> list[str]:
    """The method names (``auto`` included) that can trace frames with ``integrator``."""
    names = [n for n, m in METHODS.items() if integrator in m.capabilities.integrators]
    return names + [AUTO_METHOD] if integrator in capabilities(AUTO_METHOD).integrators else names


def mesh_methods() -> list[str]:
    """The method names whose GPU layouts hold triangles (``Capabilities.meshes_on_gpu``), ``auto``
    among them when every method it resolves to does."""
    names = [n for n, m in METHODS.items() if m.capabilities.meshes_on_gpu]
    picks = {resolve_method(AUTO_METHOD, n) for n in (0, AUTO_CROSSOVER_N)}
    return names + [AUTO_METHOD] if all(METHODS[p].capabilities.meshes_on_gpu for p in picks) else names


def not_on_gpu() -> str:
    """Why a method whose layout holds no triangles traces no frame of a scene with meshes, and
    which methods do (:func:`mesh_methods`)."""
    return (
        "this method's GPU layout holds spheres only: its frames of a scene with triangle meshes are "
        f"not traced on the GPU; the methods that trace meshes are {', '.join(mesh_methods())}"
    )


def check_primitives(name: str, scene) -> None:
    """Refuse (SceneError ``method``) a scene with a kind of primitive the method does not
    trace (``Capabilities.primitives``): the ray engines draw spheres and planes only, so a
    scene with triangle meshes or analytic shapes needs a one-pass method."""
    caps = METHODS[name].capabilities
    if scene.n_shapes and "shapes" not in caps.primitives:
        able = [m for m, x in METHODS.items() if "shapes" in x.capabilities.primitives]
        raise SceneError(
            "method",
            f"method {name!r} traces {' and '.join(caps.primitives)} only; this scene has "
            f"{scene.n_shapes:,} analytic shape(s) "
            f"({', '.join(f'{n} {k}' for k, n in scene.shapes.counts().items() if n)}): use one of "
            f"{', '.join(able)}",
        )
    if scene.n_triangles and "triangles" not in caps.primitives:
        able = [m for m, x in METHODS.items() if "triangles" in x.capabilities.primitives]
        raise SceneError(
            "method",
            f"method {name!r} traces {' and '.join(caps.primitives)} only; this scene has "
            f"{len(scene.meshes)} mesh(es) of {scene.n_triangles:,} triangles: use one of "
            f"{', '.join(able)}",
        )
    if caps.shader is None and any(m.KIND != "phong" for m in scene.materials):
        able = [m for m, x in METHODS.items() if x.capabilities.shader]
        raise SceneError(
            "method",
            f"method {name!r} shades Phong materials only (its passes read the Phong record); this scene "
            f"has glTF metallic-roughness (pbr) materials: use one of {', '.join(able)}",
        )
    n = scene.n_tree_primitives
    if caps.max_primitives is not None and n > caps.max_primitives:
        raise SceneError(
            "method",
            f"method {name!r} traces at most {caps.max_primitives:,} primitives (one shader loop "
            f"over them all; llvmpipe ends longer loops early); this scene has {n:,}: use a "
            f"hierarchy (bih, bvh, kdtree, twolevel)",
        )

"""Boxes of primitives, shared by every hierarchy's build, and the trees' primitive index space.

A tree holds the scene's spheres and triangles (the planes stay outside every tree and are
tested on their own): tree primitive ``i`` is sphere ``i`` for ``i < n_spheres`` and
triangle ``i − n_spheres`` (in the scene's flattened id order) otherwise. Its scene
primitive id (docs/FORMATS.md) is ``i`` for a sphere and ``i + n_planes`` for a triangle
(:func:`tree_to_scene_ids`), since the planes' ids come between.
"""

from __future__ import annotations

import numpy as np


def sphere_aabbs(centers: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float32 AABBs, rounded outwards, that hold each sphere in both precisions.

    The GPU sees the sphere rounded to float32, the reference tracer and the
    CPU traversal see it in float64; the two differ by up to one float32 step
    when a centre is not representable, so the box bounds the union of both.
    """
    c64 = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r64 = np.asarray(radii, dtype=np.float64).reshape(-1, 1)
    c32, r32 = c64.astype(np.float32), r64.astype(np.float32)
    down, up = np.float32(-np.inf), np.float32(np.inf)
    lo = np.minimum(np.nextafter(c32 - r32, down), np.nextafter((c64 - r64).astype(np.float32), down))
    hi = np.maximum(np.nextafter(c32 + r32, up), np.nextafter((c64 + r64).astype(np.float32), up))
    return lo, hi


def triangle_aabbs(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float32 AABBs, rounded outwards, that hold each triangle ``corners`` (T, 3, 3) in both precisions.

    A triangle is the convex hull of its corners, so its box is theirs. Each float64 corner
    rounds to a float32 at most half a step away, on either side; one more step outwards
    (``nextafter``) from the float32 extremes covers both the float32 triangle the GPU sees
    and the float64 one of the reference and the CPU traversal.
    """
    c = np.asarray(corners, dtype=np.float64).reshape(-1, 3, 3).astype(np.float32)
    # (corner by corner: the same values as c.min(axis=1), several times faster on NumPy's
    # middle-axis reduction, which a million-triangle build pays on every request)
    lo = np.nextafter(np.minimum(np.minimum(c[:, 0], c[:, 1]), c[:, 2]), np.float32(-np.inf))
    hi = np.nextafter(np.maximum(np.maximum(c[:, 0], c[:, 1]), c[:, 2]), np.float32(np.inf))
    return lo, hi


def scene_aabbs(scene) -> tuple[np.ndarray, np.ndarray]:
    """The boxes of a scene's tree primitives: its spheres, then its triangles (float32, (n + T, 3))."""
    slo, shi = sphere_aabbs(scene.sphere_centers, scene.sphere_radii)
    if not scene.n_triangles:
        return slo, shi
    tlo, thi = triangle_aabbs(scene.triangle_corners)
    return np.concatenate([slo, tlo]), np.concatenate([shi, thi])


def tree_to_scene_ids(tree_ids: np.ndarray, n_spheres: int, n_planes: int) -> np.ndarray:
    """Scene primitive ids of tree primitive indices (−1 stays −1)."""
    i = np.asarray(tree_ids, dtype=np.int64)
    return np.where(i >= n_spheres, i + n_planes, i)


def scene_to_tree_ids(ids: np.ndarray, n_spheres: int, n_planes: int) -> np.ndarray:
    """Tree primitive indices of scene ids (−1 for a plane or no primitive)."""
    i = np.asarray(ids, dtype=np.int64)
    return np.where(i < 0, -1, np.where(i < n_spheres, i, np.where(i < n_spheres + n_planes, -1, i - n_planes)))

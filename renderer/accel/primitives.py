"""Boxes of primitives, shared by every hierarchy's build, and the trees' primitive index space.

A tree holds the scene's spheres, triangles and analytic shapes (the planes stay outside
every tree and are tested on their own): tree primitive ``i`` is sphere ``i`` for
``i < n_spheres``, triangle ``i − n_spheres`` (in the scene's flattened id order) for
``i < n_spheres + n_triangles``, and analytic shape ``i − n_spheres − n_triangles`` after
them. Its scene primitive id (docs/FORMATS.md) is ``i`` for a sphere and ``i + n_planes``
for a triangle or a shape (:func:`tree_to_scene_ids`), since the planes' ids come between
and the shapes' ids follow the triangles' in both spaces.
"""

from __future__ import annotations

import numpy as np

from ..geometry.shapes import bounds as shape_bounds


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


def shape_aabbs(shapes) -> tuple[np.ndarray, np.ndarray]:
    """float32 AABBs of analytic shapes (renderer/geometry/shapes.py ``bounds``), widened so that they hold
    each shape in both precisions and every root the float32 tests find.

    The GPU sees the record rounded to float32 (origin, unit axis, radii: a relative 6e-8
    each, the axis's error moved by the height) and finds its roots to a relative 1e-7 of
    the shape's size (the torus's Newton tolerance); a widening of 1e-5 of the shape's
    extent plus its distance from the origin is far beyond both and still a tight box."""
    box = shape_bounds(shapes)
    size = np.abs(box).max(axis=(1, 2)) + (box[:, 1] - box[:, 0]).max(axis=1)
    slack = (1e-5 * size)[:, None]
    lo = np.nextafter((box[:, 0] - slack).astype(np.float32), np.float32(-np.inf))
    hi = np.nextafter((box[:, 1] + slack).astype(np.float32), np.float32(np.inf))
    return lo, hi


def scene_aabbs(scene) -> tuple[np.ndarray, np.ndarray]:
    """The boxes of a scene's tree primitives: its spheres, then its triangles, then its analytic
    shapes (float32, (n + T + S, 3))."""
    slo, shi = sphere_aabbs(scene.sphere_centers, scene.sphere_radii)
    if not scene.n_triangles and not scene.n_shapes:
        return slo, shi
    los, his = [slo], [shi]
    if scene.n_triangles:
        tlo, thi = triangle_aabbs(scene.triangle_corners)
        los.append(tlo)
        his.append(thi)
    if scene.n_shapes:
        klo, khi = shape_aabbs(scene.shapes)
        los.append(klo)
        his.append(khi)
    return np.concatenate(los), np.concatenate(his)


def tree_to_scene_ids(tree_ids: np.ndarray, n_spheres: int, n_planes: int) -> np.ndarray:
    """Scene primitive ids of tree primitive indices (−1 stays −1)."""
    i = np.asarray(tree_ids, dtype=np.int64)
    return np.where(i >= n_spheres, i + n_planes, i)


def scene_to_tree_ids(ids: np.ndarray, n_spheres: int, n_planes: int) -> np.ndarray:
    """Tree primitive indices of scene ids (−1 for a plane or no primitive)."""
    i = np.asarray(ids, dtype=np.int64)
    return np.where(i < 0, -1, np.where(i < n_spheres, i, np.where(i < n_spheres + n_planes, -1, i - n_planes)))

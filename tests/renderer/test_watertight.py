"""Watertightness of the triangle test on closed meshes: no ray that enters a closed mesh's
silhouette gets through it (docs/SHADING.md, "Triangles").

The rays are made without the tracer: each aims at a point ``q`` on the surface — a vertex,
a point of a shared edge, a point inside a triangle — from outside, along a direction that
makes a positive angle with every face around ``q`` (so the ray crosses the surface at
``q``, it does not graze it). Such a ray must hit the mesh at or before ``q``. Rays
through the exact edges and vertices of an axis-aligned box, along the axes, make the edge
functions exactly 0 and exercise the exact fallback. A second, independent check: a line
through a closed mesh crosses it an even number of times.

The float64 reference (renderer.reference) and the BIH traversal's CPU mirror
(renderer.accel.bih_traverse) are both checked. The figures (rays, leaks) are printed
with ``-s``.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderer.accel.bih import build_for_scene
from renderer.accel.bih_traverse import traverse
from renderer.meshes import box, icosphere, teapot, torus
from renderer.reference import trace_rays, triangle_hits
from renderer.scene import Camera, Material, Scene

MIN_RAYS = 10_000


def mesh_scene(mesh) -> Scene:
    return Scene(Camera(), (), (Material(),), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32), (), (mesh,))


def face_normals(mesh) -> np.ndarray:
    c = mesh.corners
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def crossing_rays(mesh, rng: np.random.Generator, per_vertex: int, per_edge: int, per_face: int):
    """(origins, directions, distance to the aimed point) of rays that cross the surface at a
    vertex, a shared edge or a face point, each from outside the mesh's bounding ball."""
    v, t = mesh.vertices, mesh.triangles.astype(np.int64)
    fn = face_normals(mesh)
    span = float(np.linalg.norm(v.max(0) - v.min(0)))
    # faces around each vertex and each edge
    around_v: list[list[int]] = [[] for _ in range(len(v))]
    for f, tri in enumerate(t.tolist()):
        for i in tri:
            around_v[i].append(f)
    edges: dict[tuple[int, int], list[int]] = {}
    for f, (a, b, c) in enumerate(t.tolist()):
        for e in ((a, b), (b, c), (c, a)):
            edges.setdefault((min(e), max(e)), []).append(f)
    targets, cones = [], []
    for i, faces in enumerate(around_v):
        targets += [v[i]] * per_vertex
        cones += [fn[faces]] * per_vertex
    for (a, b), faces in edges.items():
        for k in range(per_edge):
            s = 0.5 if k == 0 else rng.uniform(0.05, 0.95)
            targets.append(v[a] + s * (v[b] - v[a]))
            cones.append(fn[faces])
    for f in range(len(t)):
        for _ in range(per_face):
            w = rng.dirichlet((1.0, 1.0, 1.0))
            targets.append(w @ v[t[f]])
            cones.append(fn[[f]])
    origins, dirs, dist = [], [], []
    for q, cone in zip(targets, cones, strict=True):
        mean = cone.sum(axis=0)
        mean /= np.linalg.norm(mean)
        if not (cone @ mean > 0.05).all():
            continue  # no direction crosses every face here transversally (a sharp saddle)
        for _ in range(20):
            m = mean + rng.normal(scale=0.3, size=3)
            m /= np.linalg.norm(m)
            if (cone @ m > 0.05).all():
                break
        else:
            m = mean
        o = q + 2.0 * span * m
        d = q - o
        L = np.linalg.norm(d)
        origins.append(o)
        dirs.append(d / L)
        dist.append(L)
    return np.array(origins), np.array(dirs), np.array(dist)


def leaks(scene: Scene, o: np.ndarray, d: np.ndarray, dist: np.ndarray) -> tuple[int, int]:
    """Rays that miss, or first hit beyond the aimed point: (reference, BIH traversal)."""
    t, prim = trace_rays(scene, o, d)
    bih = build_for_scene(scene, 4, 64)
    tr = traverse(bih, scene.sphere_centers, scene.sphere_radii, o, d, triangles=scene.triangle_corners)
    limit = dist * (1.0 + 1e-12)
    return int((~(t <= limit)).sum()), int((~(tr.t <= limit)).sum())


CLOSED = {
    "icosphere": (lambda: icosphere(3, radius=7.0, center=(1.0, -2.0, 3.0)), 3, 3, 3),
    "teapot-closed": (lambda: teapot(6, size=3.0), 2, 1, 2),
    "torus": (lambda: torus(5.0, 1.5, 32, 16), 5, 3, 3),
    "box": (lambda: box((-1.5, -0.5, -2.0), (2.5, 1.0, 0.25)), 1000, 600, 600),
}


@pytest.mark.parametrize("name", sorted(CLOSED))
def test_no_ray_through_a_closed_mesh_leaks(name):
    make, per_vertex, per_edge, per_face = CLOSED[name]
    mesh = make()
    rng = np.random.default_rng(20)
    o, d, dist = crossing_rays(mesh, rng, per_vertex, per_edge, per_face)
    assert len(o) >= MIN_RAYS, f"{name}: only {len(o)} rays"
    ref, cpu = leaks(mesh_scene(mesh), o, d, dist)
    print(f"\n{name}: {len(o)} rays through vertices, edges and faces; leaks: reference {ref}, BIH traversal {cpu}")
    assert (ref, cpu) == (0, 0)


def test_axis_rays_through_the_exact_edges_and_vertices_of_a_box_hit_it():
    """Along −z through points exactly on the box's edges (face diagonals included) and
    corners: the sheared coordinates are exact, the edge function of that edge is exactly
    0, and the exact fallback keeps the edge in both triangles."""
    mesh = box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
    scene = mesh_scene(mesh)
    s = np.arange(-64, 65) / 64.0  # exact dyadic points along every edge
    pts = [np.stack([s, s], 1), np.stack([s, -s], 1)]  # both diagonals of the top face
    pts += [np.stack([s, np.full_like(s, c)], 1) for c in (-1.0, 1.0)]  # the top face's rim, x along
    pts += [np.stack([np.full_like(s, c), s], 1) for c in (-1.0, 1.0)]  # and y along
    xy = np.unique(np.concatenate(pts), axis=0)
    o = np.concatenate([xy, np.full((len(xy), 1), 5.0)], axis=1)
    d = np.broadcast_to([0.0, 0.0, -1.0], o.shape).copy()
    t, prim = trace_rays(scene, o, d)
    assert (prim >= 0).all() and np.all(t == 4.0), "every axis ray through the top face's edges hits it at z = 1"
    bih = build_for_scene(scene, 1, 64)
    tr = traverse(bih, scene.sphere_centers, scene.sphere_radii, o, d, triangles=scene.triangle_corners)
    assert np.all(tr.t == 4.0)
    # and the edge functions really were 0: the two triangles of the top face both claim the diagonal
    c = scene.triangle_corners
    top = np.flatnonzero((c[:, :, 2] == 1.0).all(axis=1))
    diag = np.flatnonzero(np.abs(xy[:, 0]) == np.abs(xy[:, 1]))
    hits_both = 0
    for i in diag:
        tt = [
            triangle_hits(o[i : i + 1], d[i : i + 1], c[j : j + 1, 0], c[j : j + 1, 1], c[j : j + 1, 2])[0][0]
            for j in top
        ]
        hits_both += all(x == 4.0 for x in tt)
    assert hits_both > 50


@pytest.mark.parametrize("name", ["icosphere", "teapot-closed", "torus"])
def test_lines_cross_a_closed_mesh_an_even_number_of_times(name):
    mesh = CLOSED[name][0]()
    c = mesh.corners
    rng = np.random.default_rng(3)
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    span = float(np.linalg.norm(hi - lo))
    n = 1500
    aim = rng.uniform(lo, hi, (n, 3))
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    o = aim - 2.0 * span * dirs
    ri = np.repeat(np.arange(n), len(c))
    ti = np.tile(np.arange(len(c)), n)
    t, _, _, _ = triangle_hits(o[ri], dirs[ri], c[ti, 0], c[ti, 1], c[ti, 2])
    crossings = np.bincount(ri, weights=np.isfinite(t), minlength=n).astype(int)
    assert (crossings % 2 == 0).all(), f"odd crossings on {(crossings % 2).sum()} of {n} lines"
    assert (crossings > 0).sum() > n // 4

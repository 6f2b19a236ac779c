"""Procedural triangle meshes — nothing to download — and the mesh utilities they share.

Every generator returns a :class:`~renderer.geometry.scene.Mesh` in world space: ``transform`` (a
4 × 4 row-major affine, as in the scene JSON) places it; ``smooth`` gives it vertex
normals (the analytic ones where the surface has them, area-weighted face normals for the
teapot), else it is shaded flat.

- :func:`icosphere` — a subdivided icosahedron on a sphere (closed);
- :func:`torus` — a ring in the xz-plane (closed);
- :func:`box` — an axis-aligned box of 12 triangles (closed; ``inward`` for a room);
- :func:`teapot` — the Utah teapot tessellated from Newell's Bézier patches
  (:mod:`renderer.geometry.teapot_data`), closed by default (below).

**Watertight by construction.** A mesh is watertight for the tracers' intersection test
(docs/SHADING.md, "Triangles") when triangles that share an edge share its two vertices
*bit for bit*. Each generator computes a shared vertex once, and the teapot evaluates
every patch boundary as one canonical curve (:func:`_boundary_curve`), so that two
patches meeting there produce exactly the same points; :func:`weld` then merges equal
positions. :func:`orient_outward` makes every closed piece wound outwards (positive
volume), and :func:`edge_report` checks closedness: every edge used by exactly two
triangles, once in each direction.

**The teapot, closed.** Newell's surface is not closed (:mod:`renderer.geometry.teapot_data`).
``closed=True`` (the default) adds, and documents, what is missing: a flat ring at
z = 2.4 from the lid's edge (radius 1.3) to the rim's opening (radius 1.4), and a flat fan
closing each open end of the handle and the spout (the spout's tip included). The rows of
the lid's top and of the bottom's centre that collapse to one point give zero-area
triangles; they are dropped (the remaining fan around the pole closes it). The result is
three closed pieces — pot (body, rim, lid, bottom, ring), handle, spout — that overlap
where the handle and spout enter the body, as in the original: each piece is watertight,
so a ray that meets the teapot's silhouette always hits it. ``closed=False`` is the
original surface (the same triangles without the ring and the caps).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .scene import Mesh, make_mesh
from .teapot_data import PATCHES, VERTICES

__all__ = [
    "icosphere",
    "torus",
    "box",
    "teapot",
    "weld",
    "orient_outward",
    "vertex_normals",
    "signed_volume",
    "edge_report",
    "EdgeReport",
    "MESH_KINDS",
    "procedural",
]

MAX_SUBDIVISIONS = 7  # an icosphere of 20 · 4^7 = 327,680 triangles
MAX_SEGMENTS = 256  # torus / teapot tessellation per parameter


# ------------------------------------------------------------------------------ utilities


def weld(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices of exactly equal position (bit for bit, after −0.0 → +0.0), drop
    triangles that then repeat an index (zero area) and vertices no triangle uses.

    Exact on purpose: a tolerance would move vertices and could merge distinct ones; the
    generators make shared vertices equal, and the intersection test needs exactly that."""
    v = np.ascontiguousarray(vertices, dtype=np.float64).reshape(-1, 3) + 0.0
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    uniq, inverse = np.unique(v, axis=0, return_inverse=True)
    t = inverse.reshape(-1)[t]
    keep = (t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])
    t = t[keep]
    used = np.unique(t)
    remap = np.full(len(uniq), -1, np.int64)
    remap[used] = np.arange(len(used))
    return uniq[used], remap[t]


def signed_volume(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """Σ det(v0, v1, v2) / 6: the enclosed volume of a closed mesh, positive when wound outwards."""
    c = np.asarray(vertices, dtype=np.float64)[np.asarray(triangles)]
    return float(np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])).sum() / 6.0)


@dataclass(frozen=True)
class EdgeReport:
    """Edges of a triangle list: used once (boundary), more than twice (non-manifold), or
    twice in the same direction (inconsistent winding). ``closed``: none of them."""

    edges: int
    boundary: int
    non_manifold: int
    inconsistent: int

    @property
    def closed(self) -> bool:
        return self.edges > 0 and self.boundary == 0 and self.non_manifold == 0 and self.inconsistent == 0


def _directed_edges(triangles: np.ndarray) -> np.ndarray:
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    return np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])


def edge_report(triangles: np.ndarray) -> EdgeReport:
    d = _directed_edges(triangles)
    und = np.sort(d, axis=1)
    _, count = np.unique(und, axis=0, return_counts=True)
    _, dcount = np.unique(d, axis=0, return_counts=True)
    return EdgeReport(
        edges=len(count),
        boundary=int((count == 1).sum()),
        non_manifold=int((count > 2).sum()),
        inconsistent=int((dcount > 1).sum()),
    )


def orient_outward(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The triangles wound consistently over every edge-connected piece, each piece so that
    its signed volume is positive (outwards, for a closed piece).

    Breadth-first over triangles sharing an edge: a neighbour that runs the shared edge in
    the same direction is flipped. Non-manifold edges (three or more triangles) are left
    as they come."""
    t = np.array(triangles, dtype=np.int64).reshape(-1, 3)
    n = len(t)
    if n == 0:
        return t
    d = _directed_edges(t)
    owner = np.tile(np.arange(n), 3)
    und = np.sort(d, axis=1)
    key = und[:, 0] * (int(und.max()) + 1) + und[:, 1]
    order = np.argsort(key, kind="stable")
    ks = key[order]
    # pairs of triangles on the same undirected edge (manifold edges only)
    starts = np.flatnonzero(np.concatenate([[True], ks[1:] != ks[:-1]]))
    counts = np.diff(np.concatenate([starts, [len(ks)]]))
    pairs = starts[counts == 2]
    a_idx, b_idx = order[pairs], order[pairs + 1]
    adj: list[list[tuple[int, int, int]]] = [[] for _ in range(n)]
    for ea, eb in zip(a_idx.tolist(), b_idx.tolist(), strict=True):
        ta, tb = int(owner[ea]), int(owner[eb])
        if ta == tb:
            continue
        adj[ta].append((tb, ea, eb))
        adj[tb].append((ta, eb, ea))
    flipped = np.zeros(n, dtype=bool)
    seen = np.zeros(n, dtype=bool)
    comps: list[list[int]] = []

    def edge_dir(e: int, tri: int) -> tuple[int, int]:
        i, j = int(d[e, 0]), int(d[e, 1])
        return (j, i) if flipped[tri] else (i, j)

    for root in range(n):
        if seen[root]:
            continue
        seen[root] = True
        comp, queue = [root], deque([root])
        while queue:
            cur = queue.popleft()
            for nb, e_cur, e_nb in adj[cur]:
                if seen[nb]:
                    continue
                seen[nb] = True
                # consistent winding: the neighbour runs the shared edge the other way
                flipped[nb] = edge_dir(e_cur, cur) == (int(d[e_nb, 0]), int(d[e_nb, 1]))
                comp.append(nb)
                queue.append(nb)
        comps.append(comp)
    t[flipped] = t[flipped][:, [0, 2, 1]]
    for comp in comps:
        c = np.asarray(comp)
        if signed_volume(vertices, t[c]) < 0:
            t[c] = t[c][:, [0, 2, 1]]
    return t


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (unit); a vertex whose faces cancel keeps its first
    face's normal."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    c = v[t]
    face = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    out = np.zeros_like(v)
    for k in range(3):
        np.add.at(out, t[:, k], face)
    length = np.linalg.norm(out, axis=1)
    weak = ~(length > 0)
    if weak.any():
        first = np.full(len(v), -1, np.int64)
        first[t[::-1].reshape(-1)] = np.repeat(np.arange(len(t))[::-1], 3)
        for i in np.flatnonzero(weak):
            out[i] = face[first[i]] if first[i] >= 0 else (0.0, 0.0, 1.0)
        length = np.linalg.norm(out, axis=1)
    return out / np.where(length > 0, length, 1.0)[:, None]


def _finish(
    vertices: np.ndarray,
    triangles: np.ndarray,
    normals: np.ndarray | None,
    material: int,
    transform: Any,
    **attributes: np.ndarray,
) -> Mesh:
    return make_mesh(vertices, triangles, material, normals, transform, **attributes)


def _tangents(normals: np.ndarray, along_u: np.ndarray, along_v: np.ndarray) -> np.ndarray:
    """float64 (V, 4): glTF tangents of a parameterised surface: xyz the unit direction of +U
    (``along_u``, ∂P/∂u, made orthogonal to the normal), w = ±1 so that the bitangent
    ``w · (n × t)`` points up the image — towards −V, ``along_v`` being ∂P/∂v."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    t = along_u - np.einsum("ij,ij->i", along_u, n)[:, None] * n
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    w = np.where(np.einsum("ij,ij->i", np.cross(n, t), -along_v) >= 0.0, 1.0, -1.0)
    return np.concatenate([t, w[:, None]], axis=1)


def _seamed(triangles: np.ndarray, u: np.ndarray, poles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A wrapped U coordinate made continuous over every triangle: a triangle spanning more than
    half the range (it crosses the seam) has its corners below ½ moved up by 1, and a corner on a
    pole (where U is undefined) takes the mean U of the triangle's other two. Returns (``source``:
    the original vertex of each new one, its U, the triangles on the new vertices). Positions are
    copied, never recomputed: the seam's two copies of a vertex are equal bit for bit, so the mesh
    stays watertight for the tracers (the module docstring)."""
    tu = u[triangles]
    crosses = tu.max(axis=1) - tu.min(axis=1) > 0.5
    tu = np.where(crosses[:, None] & (tu < 0.5), tu + 1.0, tu)
    on_pole = poles[triangles]
    others = (tu.sum(axis=1, keepdims=True) - tu) / 2.0
    tu = np.where(on_pole, others, tu)
    keys = np.stack([triangles.reshape(-1).astype(np.float64), tu.reshape(-1)], axis=1)
    uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
    return uniq[:, 0].astype(np.int64), uniq[:, 1], inverse.reshape(-1, 3)


def _count(value: Any, name: str, lo: int, hi: int) -> int:
    from .scene import SceneError

    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= int(value) <= hi:
        raise SceneError(name, f"must be an integer in {lo} … {hi}, got {value!r}")
    return int(value)


def _positive(value: Any, name: str) -> float:
    from .scene import finite_number

    return finite_number(value, name, lo=0.0, lo_open=True, hi=1e7)


# ------------------------------------------------------------------------------ generators


def icosphere(
    subdivisions: int = 2,
    radius: float = 1.0,
    center=(0.0, 0.0, 0.0),
    *,
    material: int = 0,
    smooth: bool = True,
    transform: Any = None,
    uvs: bool = False,
) -> Mesh:
    """A sphere of ``radius`` (world units) about ``center``: an icosahedron whose triangles
    are split in four ``subdivisions`` times (20 · 4^s triangles), vertices on the sphere.
    Smooth normals are the exact radial directions.

    ``uvs``: with the spherical (equirectangular) texture coordinates and their tangents —
    U = ½ + atan2(x, z) / 2π, the longitude, increasing eastwards (to the right seen from +z),
    V = acos(y) / π from the north pole (the image's top) down; the vertices on the seam behind
    (−z) and on the poles are doubled where their triangles need another U (:func:`_seamed`),
    so the mesh is closed by position but not by index."""
    s = _count(subdivisions, "subdivisions", 0, MAX_SUBDIVISIONS)
    radius = _positive(radius, "radius")
    g = (1.0 + math.sqrt(5.0)) / 2.0
    v = [
        (-1, g, 0),
        (1, g, 0),
        (-1, -g, 0),
        (1, -g, 0),
        (0, -1, g),
        (0, 1, g),
        (0, -1, -g),
        (0, 1, -g),
        (g, 0, -1),
        (g, 0, 1),
        (-g, 0, -1),
        (-g, 0, 1),
    ]
    verts = [np.array(p, dtype=np.float64) / math.sqrt(1.0 + g * g) for p in v]
    tris = [
        (0, 11, 5),
        (0, 5, 1),
        (0, 1, 7),
        (0, 7, 10),
        (0, 10, 11),
        (1, 5, 9),
        (5, 11, 4),
        (11, 10, 2),
        (10, 7, 6),
        (7, 1, 8),
        (3, 9, 4),
        (3, 4, 2),
        (3, 2, 6),
        (3, 6, 8),
        (3, 8, 9),
        (4, 9, 5),
        (2, 4, 11),
        (6, 2, 10),
        (8, 6, 7),
        (9, 8, 1),
    ]
    for _ in range(s):
        mid: dict[tuple[int, int], int] = {}

        def midpoint(a: int, b: int, mid: dict[tuple[int, int], int] = mid) -> int:  # this step's edges
            k = (a, b) if a < b else (b, a)
            if k not in mid:  # one vertex per edge: both triangles share it exactly
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                mid[k] = len(verts) - 1
            return mid[k]

        new = []
        for a, b, c in tris:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        tris = new
    unit = np.array(verts)
    t = orient_outward(unit, np.array(tris))
    pos = unit * radius + np.asarray(center, dtype=np.float64)
    if not uvs:
        return _finish(pos, t, unit if smooth else None, material, transform)
    longitude = 0.5 + np.arctan2(unit[:, 0], unit[:, 2]) / (2.0 * math.pi)
    poles = (unit[:, 0] == 0.0) & (unit[:, 2] == 0.0)
    source, u, t = _seamed(t, longitude, poles)
    unit, pos = unit[source], pos[source]
    v = np.arccos(np.clip(unit[:, 1], -1.0, 1.0)) / math.pi
    phi = (u - 0.5) * 2.0 * math.pi
    along_u = np.stack([np.cos(phi), np.zeros_like(phi), -np.sin(phi)], axis=1)
    along_v = np.cross(along_u, unit)  # southwards: ∂P/∂v points down the meridian
    return _finish(
        pos,
        t,
        unit if smooth else None,
        material,
        transform,
        uvs=np.stack([u, v], axis=1),
        tangents=_tangents(unit, along_u, along_v),
    )


def torus(
    major: float = 1.0,
    minor: float = 0.35,
    segments: int = 48,
    tube_segments: int = 24,
    *,
    center=(0.0, 0.0, 0.0),
    material: int = 0,
    smooth: bool = True,
    transform: Any = None,
    uvs: bool = False,
) -> Mesh:
    """A torus about the y axis through ``center``: a tube of radius ``minor`` around a circle
    of radius ``major`` in the xz-plane, ``segments × tube_segments`` quads.

    ``uvs``: with the torus's own texture coordinates and their tangents — U = the angle around
    the y axis / 2π (from +x towards +z), V = the angle around the tube / 2π (from the outer
    equator upwards) — on a grid of ``(segments + 1) × (tube_segments + 1)`` vertices whose
    last row and column copy the first's positions bit for bit (closed by position, not by
    index)."""
    from .scene import SceneError

    major, minor = _positive(major, "major"), _positive(minor, "minor")
    if not minor < major:
        raise SceneError("minor", f"must be < major ({major:g}) for a ring with a hole, got {minor:g}")
    nu = _count(segments, "segments", 3, MAX_SEGMENTS * 4)
    nv = _count(tube_segments, "tube_segments", 3, MAX_SEGMENTS * 4)
    u = 2.0 * math.pi * np.arange(nu) / nu
    w = 2.0 * math.pi * np.arange(nv) / nv
    uu, ww = np.meshgrid(u, w, indexing="ij")
    ring = major + minor * np.cos(ww)
    pos = np.stack([ring * np.cos(uu), minor * np.sin(ww), ring * np.sin(uu)], axis=-1).reshape(-1, 3)
    nrm = np.stack([np.cos(ww) * np.cos(uu), np.sin(ww), np.cos(ww) * np.sin(uu)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    t = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    t = orient_outward(pos, t)
    if not uvs:
        return _finish(pos + np.asarray(center, dtype=np.float64), t, nrm if smooth else None, material, transform)
    gi, gj = np.meshgrid(np.arange(nu + 1), np.arange(nv + 1), indexing="ij")
    source = ((gi % nu) * nv + gj % nv).reshape(-1)
    g00 = gi[:-1, :-1] * (nv + 1) + gj[:-1, :-1]
    g10, g11, g01 = g00 + (nv + 1), g00 + (nv + 2), g00 + 1
    seamed = np.concatenate(
        [np.stack([g00, g10, g11], -1).reshape(-1, 3), np.stack([g00, g11, g01], -1).reshape(-1, 3)]
    )
    p, n_src = pos[source], nrm[source]
    c = p[seamed]
    if np.einsum("ij,ij->", np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), n_src[seamed[:, 0]]) < 0.0:
        seamed = seamed[:, [0, 2, 1]]  # wound as orient_outward winds the closed one: outwards
    uu_s, ww_s = uu.reshape(-1)[source], ww.reshape(-1)[source]
    along_u = np.stack([-np.sin(uu_s), np.zeros_like(uu_s), np.cos(uu_s)], axis=1)
    along_v = np.stack([-np.sin(ww_s) * np.cos(uu_s), np.cos(ww_s), -np.sin(ww_s) * np.sin(uu_s)], axis=1)
    return _finish(
        p + np.asarray(center, dtype=np.float64),
        seamed,
        n_src if smooth else None,
        material,
        transform,
        uvs=np.stack([gi.reshape(-1) / nu, gj.reshape(-1) / nv], axis=1),
        tangents=_tangents(n_src, along_u, along_v),
    )


def box(
    lo=(-1.0, -1.0, -1.0),
    hi=(1.0, 1.0, 1.0),
    *,
    inward: bool = False,
    material: int = 0,
    transform: Any = None,
    uvs: bool = False,
) -> Mesh:
    """An axis-aligned box ``[lo, hi]`` of 12 triangles, flat shaded, wound outwards —
    or inwards (``inward``: the walls of a room, seen from inside).

    ``uvs``: each face its own four vertices with texture coordinates and tangents, the whole
    image on every face, seen from the side the face faces: U to the right, the image's top
    towards +y on the sides, towards −z on the top face and +z on the bottom one (a box seen
    from the front and above reads its top the right way up)."""
    from .scene import SceneError

    lo_a, hi_a = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    if lo_a.shape != (3,) or hi_a.shape != (3,) or not (np.isfinite(lo_a).all() and np.isfinite(hi_a).all()):
        raise SceneError("lo", "lo and hi must be 3 finite numbers each")
    if not (lo_a < hi_a).all():
        raise SceneError("hi", f"must be > lo on every axis, got lo {lo_a.tolist()} hi {hi_a.tolist()}")
    corners = np.array(
        [
            [hi_a[0] if k & 1 else lo_a[0], hi_a[1] if k & 2 else lo_a[1], hi_a[2] if k & 4 else lo_a[2]]
            for k in range(8)
        ]
    )
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    t = np.array([tri for a, b, c, d in quads for tri in ((a, b, c), (a, c, d))])
    t = orient_outward(corners, t)
    if inward:
        t = t[:, [0, 2, 1]]
    if not uvs:
        return _finish(corners, t, None, material, transform)
    # quad q's triangles are rows 2q and 2q + 1; their corners become vertices 4q … 4q + 3
    order = np.array([corner for quad in quads for corner in quad])
    slot = {(q, int(c)): 4 * q + k for q, quad in enumerate(quads) for k, c in enumerate(quad)}
    faces = np.array([[slot[(k // 2, int(c))] for c in tri] for k, tri in enumerate(t)])
    pos = corners[order]
    c = pos[faces[0::2]]
    facing = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    facing /= np.linalg.norm(facing, axis=1, keepdims=True)
    ups = np.where(
        np.abs(facing[:, 1:2]) > 0.5, np.array([0.0, 0.0, -1.0]) * np.sign(facing[:, 1:2]), np.array([0.0, 1.0, 0.0])
    )
    rights = np.cross(ups, facing)
    n, up, right = (np.repeat(a, 4, axis=0) for a in (facing, ups, rights))
    along = np.einsum("ij,ij->i", pos, right), np.einsum("ij,ij->i", pos, up)
    span = [(a.reshape(6, 4).min(axis=1).repeat(4), a.reshape(6, 4).max(axis=1).repeat(4)) for a in along]
    u = (along[0] - span[0][0]) / (span[0][1] - span[0][0])
    v = (span[1][1] - along[1]) / (span[1][1] - span[1][0])
    return _finish(
        pos, faces, None, material, transform, uvs=np.stack([u, v], axis=1), tangents=_tangents(n, right, -up)
    )


# ------------------------------------------------------------------------------ teapot


def _bernstein(n: int) -> np.ndarray:
    """(n + 1, 4) cubic Bernstein weights at u = k / n (exactly [1,0,0,0] and [0,0,0,1] at the ends)."""
    u = np.arange(n + 1, dtype=np.float64) / n
    w = 1.0 - u
    return np.stack([w * w * w, 3.0 * u * w * w, 3.0 * u * u * w, u * u * u], axis=1)


def _boundary_curve(ctrl: np.ndarray, n: int) -> np.ndarray:
    """The ``n + 1`` points of the cubic Bézier curve of ``ctrl`` (4, 3), evaluated in a
    canonical direction (the lexicographically smaller end first), so that two patches
    sharing this boundary — in either direction — get bitwise the same points."""
    fwd = [tuple(p) for p in ctrl]
    if len(set(fwd)) == 1:
        # a collapsed row (the lid's top, the bottom's centre) is one point exactly; the
        # weights' sum is not exactly 1 in floating point and would scatter it
        return np.repeat(ctrl[:1], n + 1, axis=0)
    rev = fwd[::-1]
    if rev < fwd:
        return _boundary_curve(ctrl[::-1], n)[::-1]
    b = _bernstein(n)
    return (b[:, 0:1] * ctrl[0] + b[:, 1:2] * ctrl[1]) + (b[:, 2:3] * ctrl[2] + b[:, 3:4] * ctrl[3])


def _patch_grid(p: np.ndarray, n: int) -> np.ndarray:
    """(n + 1, n + 1, 3) points of the bicubic patch ``p`` (4, 4, 3) at (u, v) = (a/n, b/n);
    the four boundaries by :func:`_boundary_curve`."""
    b = _bernstein(n)
    g = np.einsum("ai,bj,ijc->abc", b, b, p)
    g[0, :], g[n, :] = _boundary_curve(p[0], n), _boundary_curve(p[3], n)
    g[:, 0], g[:, n] = _boundary_curve(p[:, 0], n), _boundary_curve(p[:, 3], n)
    return g


def _grid_triangles(n: int) -> np.ndarray:
    a, b = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    i00 = a * (n + 1) + b
    i10, i11, i01 = i00 + (n + 1), i00 + (n + 2), i00 + 1
    return np.concatenate([np.stack([i00, i10, i11], -1).reshape(-1, 3), np.stack([i00, i11, i01], -1).reshape(-1, 3)])


# z-up (the data) to y-up (pocketray's floor): (x, y, z) → (x, z, −y), a rotation.
_Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def teapot_surface(segments: int = 8, closed: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The teapot's welded, outward-wound (vertices, triangles), y up, in the data's units
    (height 3.15, standing on y = 0). See the module docstring for ``closed``."""
    n = _count(segments, "segments", 2, MAX_SEGMENTS)  # 1: a tube end of two points has no cap
    ctrl = np.asarray(VERTICES, dtype=np.float64)
    grids = [_patch_grid(ctrl[np.asarray(p) - 1].reshape(4, 4, 3), n) for p in PATCHES]
    pts, tris, extra = [], [], []
    base = 0

    def add(points: np.ndarray, triangles: np.ndarray, added: bool) -> None:
        nonlocal base
        pts.append(points.reshape(-1, 3))
        tris.append(triangles + base)
        extra.append(np.full(len(triangles), added))
        base += len(points.reshape(-1, 3))

    grid_tris = _grid_triangles(n)
    for g in grids:
        add(g, grid_tris, False)

    def strip(inner: list[np.ndarray], outer: list[np.ndarray]) -> None:
        """Quads between two loops of the same sampling (the gap ring at z = 2.4)."""
        for a_row, b_row in zip(inner, outer, strict=True):
            k = np.arange(n)
            quad = np.concatenate([np.stack([k, k + 1, n + 2 + k], -1), np.stack([k, n + 2 + k, n + 1 + k], -1)])
            add(np.concatenate([a_row, b_row]), quad, True)

    def cap(rows: list[np.ndarray]) -> None:
        """A fan from the centroid closing the loop that ``rows`` (open curves end to end) form."""
        loop = np.concatenate([r[:-1] for r in rows])
        centre = loop.mean(axis=0)
        m = len(loop)
        k = np.arange(m)
        add(np.concatenate([loop, centre[None]]), np.stack([k, (k + 1) % m, np.full(m, m)], -1), True)

    # the lid's edge (its patches' last row) to the rim's opening (the rim's first row)
    strip([grids[p][n] for p in range(24, 28)], [grids[p][0] for p in range(0, 4)])
    cap([grids[12][0], grids[13][0]])  # handle, upper end
    cap([grids[14][n], grids[15][n]])  # handle, lower end
    cap([grids[16][0], grids[17][0]])  # spout, base
    cap([grids[18][n], grids[19][n]])  # spout, tip
    v = np.concatenate(pts)
    t = np.concatenate(tris)
    added = np.concatenate(extra)
    # weld, remembering which triangles were added (weld drops zero-area ones in order)
    v_all = v + 0.0
    uniq, inverse = np.unique(v_all, axis=0, return_inverse=True)
    t = inverse.reshape(-1)[t]
    keep = (t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])
    t, added = t[keep], added[keep]
    t = orient_outward(uniq, t)
    if not closed:
        t = t[~added]
    uniq, t = weld(uniq[np.unique(t)], np.searchsorted(np.unique(t), t))
    return uniq @ _Z_UP_TO_Y_UP.T, t


def teapot(
    segments: int = 8,
    *,
    closed: bool = True,
    size: float = 1.0,
    material: int = 0,
    smooth: bool = True,
    transform: Any = None,
) -> Mesh:
    """The Utah teapot standing on y = 0, spout towards +x, scaled by ``size`` (height
    3.15 · size), ``segments`` × ``segments`` quads per patch; smooth normals are the
    area-weighted face normals. ``closed``: the watertight version (module docstring)."""
    size = _positive(size, "size")
    v, t = teapot_surface(segments, closed)
    v = v * size
    return _finish(v, t, vertex_normals(v, t) if smooth else None, material, transform)


# The procedural meshes by name (the scene builders and the service's recipes).
MESH_KINDS = ("icosphere", "torus", "box", "teapot")


def procedural(kind: str, **kw: Any) -> Mesh:
    """A procedural mesh by name (:data:`MESH_KINDS`) with its generator's keyword arguments."""
    from .scene import SceneError

    makers: dict[str, Callable[..., Mesh]] = {"icosphere": icosphere, "torus": torus, "box": box, "teapot": teapot}
    if kind not in makers:
        raise SceneError("kind", f"unknown mesh {kind!r}; one of {', '.join(MESH_KINDS)}")
    return makers[kind](**kw)

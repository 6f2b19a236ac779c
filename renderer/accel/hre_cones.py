"""Enclosing cones of ray tiles: the hierarchical ray engine's hierarchy (Szécsi 2006, §4).

The GPU builds the cones in ``shaders/rayengine_cones.frag``; this module is the same
algorithm in NumPy (vectorised over tiles, rays of a tile in sequence), used by the
tests to check the construction and by the method to read the cone texture.

A cone is ``(apex a, unit axis x, half-angle φ, slack)``: the region of points ``q``
with ``angle(q − a, x) ≤ φ``, and every ray of the tile lies within distance
``slack`` of it. ``φ = NO_RAYS`` (−2): the tile holds no live ray; ``φ = NO_CULL``
(−1): no useful cone (wider than ``PHI_MAX``, or a degenerate step).

Construction, per tile, rays in raster order (row by row, left to right):

1. Incremental (§4): start with the zero-angle cone of the first ray. For each further
   ray (origin p, direction r):

   a. if ``x·r < cos φ`` the direction is outside: ``q = normalize((x·r) x − r)``, far
      generator ``e = x cos φ + q sin φ``, ``x ← normalize(e + r)``, ``cos φ ← x·r``;
   b. if the origin is outside (``x·c < cos φ |c|``, ``c = p − a``): ``q =
      normalize((x·c) x − c)``, far and near generators ``e, n = x cos φ ± q sin φ``,
      ``g = c − (n·c) n`` (from the near generator to p), and the apex moves back along
      the far generator, ``a ← a − e t`` with ``t = |g|² / −(e·g)``, so that the near
      generator passes through p. (The paper prints ``t = g²/(e·g)``; ``e·g`` is
      negative, and moving *backwards* — keeping the old cone inside the new one — needs
      the minus sign.) A cone of (almost) zero angle cannot take a parallel ray by
      moving: it first opens to ``SIN_MIN``.

2. Certification (ours): in float32 the incremental steps are only approximately what
   they claim, so with the final apex and axis, ``φ`` becomes the largest angle from the
   axis of any ray direction and of any ray origin seen from the apex (plus
   ``ANGLE_MARGIN``), and ``slack`` the largest rounding error of ``origin − apex``.
   Then every ray is inside the cone up to ``slack``: its origin is (the cone is a
   convex set for φ < π/2), and so is every point ``p + s r``, ``s ≥ 0``, because ``r``
   is. A cone wider than ``PHI_MAX`` is not convex enough to help: ``NO_CULL``.

The cull test (end of §4): the cone meets the sphere (centre v, radius r) only if
``φ > ∠(v − a, x) − arcsin(r / |v − a|)``; :func:`cone_misses_sphere` is the shader's
version with the sphere inflated by the slack and by rounding, and an angular margin.
"""

from __future__ import annotations

import numpy as np

NO_RAYS = -2.0
NO_CULL = -1.0
PHI_MAX = 1.4  # radians; must stay below π/2 (convexity)
SIN_MIN = 1.0e-3
ANGLE_MARGIN = 1.0e-5  # certification margin (radians)
CONE_ANGLE_MARGIN = 1.0e-4  # the vertex shader's test margin (radians)
EPS32 = float(np.finfo(np.float32).eps)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _normalize(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n


def angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle between vectors (rows), accurate for small angles: atan2(|u×v|, u·v)."""
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), _dot(u, v))


def _perpendicular(x: np.ndarray) -> np.ndarray:
    y = np.where((np.abs(x[..., 0]) < 0.5)[..., None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    return _normalize(np.cross(x, y))


def build_cones(origins: np.ndarray, dirs: np.ndarray, live: np.ndarray) -> np.ndarray:
    """Cones of tiles of rays: ``origins``, ``dirs`` (T, K, 3), ``live`` (T, K) bool.

    ``K`` rays per tile in raster order. Returns (T, 8) float64:
    ``apex.xyz, φ, axis.xyz, slack`` (φ = ``NO_RAYS`` / ``NO_CULL`` as the module says).
    """
    o = np.asarray(origins, dtype=np.float64)
    d = np.asarray(dirs, dtype=np.float64)
    live = np.asarray(live, dtype=bool)
    n_tiles, k = live.shape
    a = np.zeros((n_tiles, 3))
    x = np.tile([0.0, 0.0, 1.0], (n_tiles, 1))
    cphi = np.ones(n_tiles)
    sphi = np.zeros(n_tiles)
    count = np.zeros(n_tiles, np.int64)
    give_up = np.zeros(n_tiles, bool)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for i in range(k):
            p, r, on = o[:, i], d[:, i], live[:, i]
            first = on & (count == 0)
            count += on
            a[first], x[first] = p[first], r[first]
            act = on & ~first & ~give_up
            # (a) widen
            xr = _dot(x, r)
            wid = act & (xr < cphi)
            if wid.any():
                q = xr[:, None] * x - r
                ql = np.linalg.norm(q, axis=1)
                bad = wid & ~(ql > 0.0)
                q = q / np.where(ql > 0.0, ql, 1.0)[:, None]
                e = x * cphi[:, None] + q * sphi[:, None]
                s = e + r
                sl = np.linalg.norm(s, axis=1)
                bad |= wid & ~(sl > 1e-6)
                ok = wid & ~bad
                x[ok] = s[ok] / sl[ok, None]
                cphi[ok] = np.minimum(_dot(x[ok], r[ok]), 1.0)
                sphi[ok] = np.sqrt(np.maximum(0.0, 1.0 - cphi[ok] ** 2))
                bad |= ok & (cphi < np.cos(PHI_MAX))
                give_up |= bad
                act &= ~bad
            # (b) translate
            c = p - a
            cl = np.linalg.norm(c, axis=1)
            xc = _dot(x, c)
            mov = act & (cl > 0.0) & (xc < cphi * cl)
            if mov.any():
                small = mov & (sphi < SIN_MIN)
                sphi[small] = SIN_MIN
                cphi[small] = np.sqrt(1.0 - SIN_MIN**2)
                q = xc[:, None] * x - c
                ql = np.linalg.norm(q, axis=1)
                q = np.where((ql > 1e-7 * cl)[:, None], q / np.where(ql > 0, ql, 1.0)[:, None], _perpendicular(x))
                e = x * cphi[:, None] + q * sphi[:, None]
                nn = x * cphi[:, None] - q * sphi[:, None]
                g = c - _dot(nn, c)[:, None] * nn
                eg = _dot(e, g)
                bad = mov & ~(eg < 0.0)
                ok = mov & ~bad
                a[ok] -= e[ok] * (_dot(g[ok], g[ok]) / -eg[ok])[:, None]
                give_up |= bad
    return certify(o, d, live, a, x, give_up, count)


def certify(
    o: np.ndarray, d: np.ndarray, live: np.ndarray, a: np.ndarray, x: np.ndarray, give_up: np.ndarray, count: np.ndarray
) -> np.ndarray:
    """Step 2: the φ and slack for which every live ray lies in the cone (a, x)."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        x = _normalize(x)
        ang_d = angle_between(x[:, None, :], d)
        c = o - a[:, None, :]
        tol = 4.0 * EPS32 * (np.linalg.norm(o, axis=2) + np.linalg.norm(a, axis=1)[:, None])
        ang_o = np.where(np.linalg.norm(c, axis=2) > tol, angle_between(x[:, None, :], c), 0.0)
        phi = np.where(live, np.maximum(ang_d, ang_o), -np.inf).max(axis=1) + ANGLE_MARGIN
        slack = np.where(live, tol, 0.0).max(axis=1)
        useless = give_up | ~(phi <= PHI_MAX) | ~np.isfinite(a).all(axis=1) | ~(slack < 1e30)
    phi = np.where(count == 0, NO_RAYS, np.where(useless, NO_CULL, phi))
    return np.concatenate([a, phi[:, None], x, slack[:, None]], axis=1)


def cone_misses_sphere(cones: np.ndarray, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """The vertex shader's cull test (float64): (T, S) True where tile T may skip sphere S."""
    a, phi, x, slack = cones[:, None, 0:3], cones[:, None, 3], cones[:, None, 4:7], cones[:, None, 7]
    v = np.asarray(centers, dtype=np.float64)[None, :, :]
    rad = np.asarray(radii, dtype=np.float64)[None, :]
    w = v - a
    dist = np.linalg.norm(w, axis=2)
    r = rad + slack + 8.0 * EPS32 * (np.linalg.norm(v, axis=2) + np.linalg.norm(a, axis=2) + rad)
    with np.errstate(invalid="ignore", divide="ignore"):
        ang = angle_between(w, np.broadcast_to(x, w.shape))
        half = np.arcsin(np.minimum(r / dist, 1.0))
        miss = (dist > r) & (ang - half > phi + CONE_ANGLE_MARGIN)
    return miss & (phi >= 0.0)


def distance_to_cone(points: np.ndarray, apex: np.ndarray, axis: np.ndarray, phi: float) -> np.ndarray:
    """Euclidean distance (float64) of points (k, 3) from the cone region (0 inside)."""
    w = np.asarray(points, dtype=np.float64) - apex
    lw = np.linalg.norm(w, axis=1)
    ang = angle_between(w, np.broadcast_to(axis, w.shape))
    beyond = ang - phi
    out = np.where(beyond <= 0.0, 0.0, np.where(beyond >= np.pi / 2, lw, lw * np.sin(np.minimum(beyond, np.pi / 2))))
    return np.where(lw == 0.0, 0.0, out)


def tiles_of(image: np.ndarray, tile: int) -> np.ndarray:
    """(Hp, Wp, C) texel array → (T, tile², C), tiles in row-major order, rays in raster order."""
    hp, wp, ch = image.shape
    ty, tx = hp // tile, wp // tile
    return image.reshape(ty, tile, tx, tile, ch).transpose(0, 2, 1, 3, 4).reshape(ty * tx, tile * tile, ch)

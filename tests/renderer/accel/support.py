"""Helpers shared by the tests of renderer.accel: random sphere scenes (hypothesis
strategies), the BIH's node words decoded, and the cone checks of the hierarchical ray
engine (used by the NumPy tests in ``test_hre_cones.py`` and the GPU ones in
``tests/renderer/gl/test_ray_engine.py``)."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from renderer.accel import bih_layout as L, hre_cones

# ---------------------------------------------------------------------------
# BIH nodes


def decode(bih):
    w0 = bih.nodes[:, 0]
    leaf = L.is_leaf(w0)
    axis = L.axis_of(w0)
    left = L.left_child(w0)
    cl, cr = L.clips(bih.nodes)
    off = bih.nodes[:, 1].astype(np.int64)
    cnt = bih.nodes[:, 2].astype(np.int64)
    return leaf, axis, left, cl, cr, off, cnt


# ---------------------------------------------------------------------------
# scenes of the BIH tests (scale, offset and radius extremes)

SCALES = [1e-3, 1.0, 20.0, 1e6]
SPECIALS = [0.0, 1.0, -1.0, 0.5, -0.5, 2.0, 1e-3, -1e-3]


@st.composite
def scenes(draw, max_n=300, f32=False):
    n = draw(st.integers(0, max_n))
    kind = draw(st.sampled_from(["uniform", "same", "dups", "line", "grid", "specials", "cluster"]))
    scale = draw(st.sampled_from(SCALES))
    shift = draw(st.sampled_from([0.0, 0.0, 1e6, -20.0]))
    rkind = draw(st.sampled_from(["const", "uniform", "loguniform"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if kind == "uniform":
        c = rng.uniform(-scale, scale, (n, 3))
    elif kind == "same":
        c = np.broadcast_to(rng.uniform(-scale, scale, 3), (n, 3)).copy()
    elif kind == "dups":
        pts = rng.uniform(-scale, scale, (draw(st.integers(1, 5)), 3))
        c = pts[rng.integers(0, len(pts), n)]
    elif kind == "line":
        p0 = rng.uniform(-scale, scale, 3)
        dirn = draw(
            st.sampled_from(
                [np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([1.0, 1.0, 1.0]), rng.normal(size=3)]
            )
        )
        c = p0 + rng.uniform(-scale, scale, (n, 1)) * dirn
    elif kind == "grid":
        c = rng.integers(-4, 5, (n, 3)) * (scale / 4)
    elif kind == "specials":
        c = rng.choice(np.array(SPECIALS) * scale, (n, 3))
    else:  # a dense cluster far from the origin
        c = rng.normal(size=(n, 3)) * scale * 1e-3
    c = c + shift
    if rkind == "const":
        r = np.full(n, draw(st.sampled_from([1e-3, 1.0, scale, 0.1 * scale])))
    elif rkind == "uniform":
        r = rng.uniform(1e-3, max(2e-3, 0.2 * scale), n)
    else:
        r = 10.0 ** rng.uniform(-3, np.log10(max(1.0, scale)), n)
    if f32:
        c = c.astype(np.float32).astype(np.float64)
        r = r.astype(np.float32).astype(np.float64)
    return c, r


# ---------------------------------------------------------------------------
# scenes of the BVH and kd-tree tests


@st.composite
def sphere_sets(draw, max_n: int = 120):
    """Random, clustered and degenerate sphere sets (centres, radii)."""
    n = draw(st.integers(0, max_n))
    kind = draw(st.sampled_from(["uniform", "clustered", "one_centre", "duplicates", "line", "scales"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if kind == "uniform":
        c = rng.uniform(-20, 20, (n, 3))
        r = rng.uniform(0.05, 3.0, n)
    elif kind == "clustered":
        c = rng.normal(0, 1, (n, 3)) * rng.choice([0.01, 1.0, 10.0], (n, 1)) + rng.choice([-15.0, 15.0], (n, 3))
        r = rng.uniform(0.01, 1.0, n)
    elif kind == "one_centre":
        c = np.broadcast_to(rng.uniform(-5, 5, 3), (n, 3)).copy()
        r = rng.uniform(0.5, 4.0, n)
    elif kind == "duplicates":
        base = rng.uniform(-10, 10, ((n + 1) // 2, 3))
        c = np.concatenate([base, base])[:n]
        r = np.full(n, 1.0)
    elif kind == "line":
        c = np.zeros((n, 3))
        c[:, 0] = np.linspace(-10, 10, n)
        r = np.full(n, 0.5)
    else:
        c = rng.uniform(-1, 1, (n, 3)) * 10.0 ** rng.integers(-3, 4, (n, 1))
        r = 10.0 ** rng.uniform(-3, 2, n)
    return c, r


# ---------------------------------------------------------------------------
# hierarchical ray engine: cones


def check_contained(o, d, live, cones, scale_points=(0.0, 1e-3, 0.1, 1.0, 10.0, 100.0, 1e4)):
    """Brute force: points p + s·r of every live ray lie within the slack of their tile's cone."""
    for t in range(len(cones)):
        a, phi, x, slack = cones[t, 0:3], cones[t, 3], cones[t, 4:7], cones[t, 7]
        if not live[t].any():
            assert phi == hre_cones.NO_RAYS
            continue
        if phi < 0:
            continue  # no cull: nothing is promised
        p = o[t][live[t]]
        r = d[t][live[t]]
        pts = (p[:, None, :] + np.asarray(scale_points)[None, :, None] * r[:, None, :]).reshape(-1, 3)
        dist = hre_cones.distance_to_cone(pts, a, x, phi)
        tol = slack * 1.001 + 1e-9 * (np.linalg.norm(pts, axis=1) + np.linalg.norm(a))
        assert (dist <= tol).all(), f"tile {t}: a ray leaves its cone by {(dist - tol).max():.3e}"


def any_hit(o, d, c, r):
    """Rays (k, 3) that meet the sphere at some t > 0 (float64, either root)."""
    oc = o - c
    b = np.einsum("ij,ij->i", oc, d)
    f = oc - b[:, None] * d
    h2 = r * r - np.einsum("ij,ij->i", f, f)
    return (h2 >= 0.0) & (-b + np.sqrt(np.maximum(h2, 0.0)) > 0.0)

"""Analytic shapes (renderer/geometry/shapes.py; docs/FORMATS.md, "Analytic shapes"): closed forms, the
torus quartic against exact rational arithmetic, tight boxes, JSON validation, ids, motions, the
float64 reference tracer, the Mitsuba conversion and the GPU methods' refusal.

Expected values come from the geometry by hand, from an exact solver written here (the torus:
the quartic's coefficients as Fractions of the float64 inputs, its real roots isolated by a
Sturm sequence and bisected in exact arithmetic; mpmath is not installed), from NumPy's own
polynomial roots on hand-derived equations, or from Mitsuba 3's ray intersection — never
from the code under test. The figures (the largest errors) are printed with ``-s``.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from renderer import limits
from renderer.config.methods import METHODS, check_primitives
from renderer.config.settings import RenderSettings
from renderer.frame.prepare import prepare_frame
from renderer.geometry.scene import Scene, SceneError
from renderer.geometry.shapes import CONE, CYLINDER, DISK, TORUS, Shapes, bounds, intersect, normals
from renderer.oracle.reference import render_reference, trace_rays
from renderer.scenes.animation import animated_scene_from_json, pose

MAT = {"color": [0.5, 0.5, 0.5], "ambient": 0.2, "diffuse": 0.8, "specular": 0.0, "reflective": 0.0}


def shapes_of(**kinds) -> Shapes:
    return Shapes.from_json(kinds)


def one(o, d, shapes, **kw):
    t, i, n = intersect(shapes, np.array([o], float), np.array([d], float), **kw)
    return float(t[0]), int(i[0]), n[0]


# ---------------------------------------------------------------------------- closed forms


def test_a_ray_along_a_cylinders_axis_hits_its_cap_and_an_open_one_lets_it_through():
    cyl = {"base": [1.0, 2.0, 3.0], "axis": [0, 0, 2], "radius": 0.5, "height": 4.0}
    closed = shapes_of(cylinders=[cyl])
    t, i, n = one([1.0, 2.0, 10.0], [0, 0, -1], closed)
    assert (t, i) == (3.0, 0) and n.tolist() == [0.0, 0.0, 1.0]  # the top cap at z = 7
    t, i, n = one([1.2, 2.0, -7.0], [0, 0, 1], closed)
    assert t == 10.0 and n.tolist() == [0.0, 0.0, -1.0]  # the base cap at z = 3
    opened = shapes_of(cylinders=[{**cyl, "caps": False}])
    assert one([1.0, 2.0, 10.0], [0, 0, -1], opened)[1] == -1  # down the tube, touching nothing
    # Across the axis: the side at distance 0.5 from it, outward normal −x.
    t, i, n = one([-9.0, 2.0, 5.0], [1, 0, 0], opened)
    assert t == 9.5 and np.allclose(n, [-1, 0, 0], atol=1e-15)
    # From inside the open tube along a diameter: the wall at 0.5.
    assert one([1.0, 2.0, 5.0], [0, 1, 0], opened)[0] == 0.5


def test_a_cone_side_cap_and_normal_are_the_closed_forms():
    # Base radius 2 at z = 0, top radius 1 at z = 2 (k = −1/2): radius 2 − z/2.
    cone = {"base": [0, 0, 0], "axis": [0, 0, 1], "base_radius": 2.0, "top_radius": 1.0, "height": 2.0}
    s = shapes_of(cones=[cone])
    t, i, n = one([10.0, 0.0, 1.0], [-1, 0, 0], s)
    assert i == 0 and t == pytest.approx(8.5, abs=1e-14)  # radius 1.5 at z = 1
    assert np.allclose(n, np.array([1.0, 0.0, 0.5]) / math.sqrt(1.25), atol=1e-15)
    t, i, n = one([0.3, 0.0, 9.0], [0, 0, -1], s)
    assert t == 7.0 and n.tolist() == [0.0, 0.0, 1.0]  # the top cap
    t, i, n = one([1.9, 0.0, -5.0], [0, 0, 1], s)
    assert t == 5.0 and n.tolist() == [0.0, 0.0, -1.0]  # the base cap (radius 2)
    # A point cone (top radius 0), no caps, seen from below along x = 0.5: the side where 2 − z = 0.5.
    point = shapes_of(cones=[{**cone, "top_radius": 0.0, "height": 4.0, "caps": False}])
    # Its radius is 2 − z/2: the ray passes the open base inside it and meets the side from
    # within where 2 − z/2 = 0.5, at z = 3.
    t, _, _ = one([0.5, 0.0, -10.0], [0, 0, 1], point)
    assert t == pytest.approx(13.0, abs=1e-13)


def test_an_annulus_lets_rays_through_its_hole_and_a_tilted_disk_is_hit_at_the_plane():
    s = shapes_of(disks=[{"center": [0, 0, 0], "normal": [0, 0, 1], "radius": 3.0, "inner_radius": 1.0}])
    assert one([0.5, 0.0, 5.0], [0, 0, -1], s)[1] == -1  # the hole
    t, i, n = one([2.0, 0.0, 5.0], [0, 0, -1], s)
    assert (t, i) == (5.0, 0) and n.tolist() == [0.0, 0.0, 1.0]
    assert one([3.5, 0.0, 5.0], [0, 0, -1], s)[1] == -1  # beyond the rim
    # A disk through (0, 0, 0) facing (1, 0, 1)/√2: the ray down z from (0.5, 0, 9) meets x + z = 0 at z = −0.5.
    tilted = shapes_of(disks=[{"center": [0, 0, 0], "normal": [1, 0, 1], "radius": 1.0}])
    t, _, n = one([0.5, 0.0, 9.0], [0, 0, -1], tilted)
    assert t == pytest.approx(9.5, abs=1e-14) and np.allclose(n, [math.sqrt(0.5), 0, math.sqrt(0.5)], atol=1e-15)


def test_a_torus_hit_along_its_equator_gives_its_four_roots_and_none_along_its_axis():
    s = shapes_of(tori=[{"center": [0, 0, 0], "axis": [0, 0, 1], "major_radius": 3.0, "minor_radius": 1.0}])
    hits = all_hits(s, [-10.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    assert np.allclose(hits, [6.0, 8.0, 12.0, 14.0], atol=1e-13, rtol=0)
    assert one([0.0, 0.0, 10.0], [0, 0, -1], s)[1] == -1  # down the axis, through the hole
    assert one([1.9, 0.0, 10.0], [0, 0, -1], s)[1] == -1  # parallel to it, inside the hole
    t, _, n = one([3.0, 0.0, 10.0], [0, 0, -1], s)  # down the tube's core: its top
    assert t == pytest.approx(9.0, abs=1e-13) and np.allclose(n, [0, 0, 1], atol=1e-12)
    t, _, n = one([-10.0, 0.0, 0.0], [1, 0, 0], s)
    assert np.allclose(n, [-1, 0, 0], atol=1e-12)


def test_a_ray_leaving_a_shape_ignores_only_its_root_at_the_origin():
    cyl = shapes_of(cylinders=[{"base": [0, 0, -5], "axis": [0, 0, 1], "radius": 2.0, "height": 10.0}])
    # On the wall at x = 2, inwards: the far wall, 4 away (the root at 0 is the ray's own).
    t, i, _ = one([2.0, 0.0, 0.0], [-1, 0, 0], cyl, src=np.array([0]))
    assert (t, i) == (4.0, 0)
    # Outwards from the wall: nothing else of a convex tube.
    assert one([2.0, 0.0, 0.0], [1, 0, 0], cyl, src=np.array([0]))[1] == -1
    # From the wall inwards, slanted down: the base cap at z = −5.
    t, _, n = one([2.0, 0.0, 0.0], [-0.6, 0.0, -0.8], cyl, src=np.array([0]))
    assert t == pytest.approx(6.25, abs=1e-14) and n.tolist() == [0.0, 0.0, -1.0]
    tor = shapes_of(tori=[{"center": [0, 0, 0], "axis": [0, 0, 1], "major_radius": 3.0, "minor_radius": 1.0}])
    # Leaving the torus's outer equator at x = −4 inwards: the inner wall at −2 (t = 2), not t ≈ 0.
    t, _, _ = one([-4.0, 0.0, 0.0], [1, 0, 0], tor, src=np.array([0]))
    assert t == pytest.approx(2.0, abs=1e-13)
    # … and through the hole to the other side of the ring (x = 2): t = 6.
    t, _, _ = one([-2.0, 0.0, 0.0], [1, 0, 0], tor, src=np.array([0]))
    assert t == pytest.approx(4.0, abs=1e-13)
    # The same ray without src starts on the surface: its root at 0 is not > 0 unless rounding says so.
    t, _, _ = one([-4.0, 0.0, 0.0], [1, 0, 0], tor, t_min=1e-9)
    assert t == pytest.approx(2.0, abs=1e-13)


def test_ties_go_to_the_lower_index_and_t_min_t_max_bound_the_hits():
    disk = {"center": [0, 0, 0], "normal": [0, 0, 1], "radius": 1.0}
    s = shapes_of(disks=[disk, disk])
    assert one([0.0, 0.0, 3.0], [0, 0, -1], s)[:2] == (3.0, 0)
    tube = shapes_of(cylinders=[{"base": [0, 0, -5], "axis": [0, 0, 1], "radius": 2.0, "height": 10.0}])
    assert one([-9.0, 0.0, 0.0], [1, 0, 0], tube, t_min=7.0)[0] == 11.0
    assert one([-9.0, 0.0, 0.0], [1, 0, 0], tube, t_max=7.0)[1] == -1
    # A direction that is not a unit vector: t is along it (half the distance).
    assert one([-9.0, 0.0, 0.0], [2, 0, 0], tube)[0] == 3.5


# ------------------------------------------------------------- the torus quartic, exactly


def _pmul(a: list, b: list) -> list:
    out = [Fraction(0)] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] += x * y
    return out


def _padd(a: list, b: list) -> list:
    n = max(len(a), len(b))
    return [(a[i] if i < len(a) else 0) + (b[i] if i < len(b) else 0) for i in range(n)]


def _trim(a: list) -> list:
    while len(a) > 1 and a[-1] == 0:
        a = a[:-1]
    return a


def _rem(a: list, b: list) -> list:
    a = list(a)
    while len(a) >= len(b) and any(a):
        f = a[-1] / b[-1]
        shift = len(a) - len(b)
        for i, y in enumerate(b):
            a[i + shift] -= f * y
        a = _trim(a[:-1]) if len(a) > 1 else a
    return _trim(a)


def _ev(a: list, x: Fraction) -> Fraction:
    v = Fraction(0)
    for c in reversed(a):
        v = v * x + c
    return v


def _sign_changes(chain: list, x: Fraction) -> int:
    signs = [s for s in (_ev(p, x) for p in chain) if s != 0]
    return sum(1 for a, b in zip(signs, signs[1:], strict=False) if (a > 0) != (b > 0))


def exact_torus_roots(o, d, c, a, big_r, r) -> list[float]:
    """All real roots t of the torus quartic of ray (o, d), exactly from the float64 inputs:
    (|X|² + R² − r²)²·|a|² − 4R²(|X|²·|a|² − (X·a)²) = 0, X = o − c + t d (a need not be unit)."""
    q = [Fraction(x) - Fraction(y) for x, y in zip(o, c, strict=True)]
    dd = [Fraction(x) for x in d]
    aa = [Fraction(x) for x in a]
    x2 = [sum(x * x for x in q), 2 * sum(x * y for x, y in zip(q, dd, strict=True)), sum(y * y for y in dd)]
    xa = [sum(x * y for x, y in zip(q, aa, strict=True)), sum(x * y for x, y in zip(dd, aa, strict=True))]
    na = sum(y * y for y in aa)
    r2, m2 = Fraction(big_r) ** 2, Fraction(r) ** 2
    s = _padd(x2, [r2 - m2])
    p = _padd(_pmul(_pmul(s, s), [na]), [-4 * r2 * v for v in _padd([na * v for v in x2], [-v for v in _pmul(xa, xa)])])
    p = _trim(p)
    chain = [p, _trim([i * v for i, v in enumerate(p)][1:])]
    while len(chain[-1]) > 1:
        nxt = [-v for v in _rem(chain[-2], chain[-1])]
        if not any(nxt):
            break
        chain.append(nxt)
    bound = 1 + max(abs(v / p[-1]) for v in p[:-1])
    stack, roots = [(-bound, bound)], []
    while stack:
        lo, hi = stack.pop()
        k = _sign_changes(chain, lo) - _sign_changes(chain, hi)
        if k == 0:
            continue
        if k == 1 and (_ev(p, lo) > 0) != (_ev(p, hi) > 0):
            for _ in range(200):  # to far below a float64's last bit
                mid = (lo + hi) / 2
                if (_ev(p, mid) > 0) == (_ev(p, lo) > 0):
                    lo = mid
                else:
                    hi = mid
            roots.append(float((lo + hi) / 2))
            continue
        mid = (lo + hi) / 2
        stack += [(lo, mid), (mid, hi)]
    return sorted(roots)


def all_hits(shapes: Shapes, o, d, t_min: float = 0.0) -> list[float]:
    """Every hit t > t_min of one ray, in order (intersect again past each)."""
    out: list[float] = []
    for _ in range(8):
        t, i, _ = one(o, d, shapes, t_min=t_min)
        if i < 0:
            return out
        out.append(t)
        t_min = t
    raise AssertionError("more hits than a torus has")


def _torus_rays(rng: np.random.Generator, center: np.ndarray, axis: np.ndarray, big_r: float, r: float, far: float):
    """(origin, direction, kind) rays at a torus: random ones through its box, grazing ones (just
    inside and just outside the tube's top and its outer equator), along and parallel to the
    axis, through the hole."""
    axis = axis / np.linalg.norm(axis)
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    out = []
    for _ in range(12):
        target = center + rng.uniform(-1, 1, 3) * (big_r + r)
        origin = center + rng.normal(size=3) * far / math.sqrt(3)
        out.append((origin, target - origin, "random"))
    for delta in (1e-4, 1e-6, -1e-6, -1e-4):
        # Along e2 at height r(1 − δ) over the circle's point R·e1: grazing the top of the tube.
        p = center + big_r * e1 + r * (1 - delta) * axis
        out.append((p - far * e2, e2, f"graze top {delta:+g}"))
        # In the equatorial plane, offset R + r − δr sideways: grazing the outer equator.
        p = center + (big_r + r * (1 - delta)) * e1
        out.append((p - far * e2, e2, f"graze equator {delta:+g}"))
    out.append((center + far * axis, -axis, "along the axis"))
    out.append((center + 0.5 * (big_r - r) * e1 + far * axis, -axis, "parallel, in the hole"))
    out.append((center + big_r * e1 + far * axis, -axis, "parallel, down the tube"))
    out.append((center - far * e1, e1, "equator through the centre"))
    out.append((center - far * e1 + 0.3 * r * axis, e1 + 0.01 * axis, "oblique through the hole"))
    return out


@pytest.mark.parametrize(
    "center, axis, big_r, r, far",
    [
        ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0, 0.3, 10.0),
        ((0.3, -0.2, 0.1), (1.0, 2.0, 0.5), 2.5, 0.7, 40.0),
        ((1e4, -1e4, 5e3), (0.2, 1.0, -0.3), 3.0, 1.0, 1.5e4),  # 1e4 from the origin, rays from afar
        ((2.0, 1.0, -3.0), (0.0, 1.0, 0.0), 5.0, 5e-3, 50.0),  # minor / major = 1e-3
    ],
    ids=["unit", "tilted", "far", "thin"],
)
def test_the_torus_quartic_matches_exact_arithmetic(center, axis, big_r, r, far):
    rng = np.random.default_rng(7)
    c, a = np.array(center), np.array(axis)
    s = shapes_of(tori=[{"center": list(center), "axis": list(axis), "major_radius": big_r, "minor_radius": r}])
    unit_axis = s.params[0, 4:7]  # the axis as stored (normalised in float64): the exact quartic's too
    worst, worst_graze = 0.0, 0.0
    for o, d, what in _torus_rays(rng, c, a, big_r, r, far):
        exact = [t for t in exact_torus_roots(o, d, c, unit_axis, big_r, r) if t > 0]
        got = all_hits(s, o, d)
        assert len(got) == len(exact), f"{what}: {got} against the exact {exact}"
        if what.startswith("graze"):  # just inside the tube (δ > 0): two close roots; outside: none
            assert (len(exact) >= 2) == ("+" in what), what
        scale = float(np.linalg.norm(o - c)) + big_r
        # Distinct roots: to ~1e-13 of the distance. Grazing ones within √ of it (a near-double
        # root moves as the square root of the rounding of the inputs).
        tol = 1e-12 * scale if "graze" not in what else 1e-7 * big_r
        for g, e in zip(got, exact, strict=True):
            assert abs(g - e) <= tol, f"{what}: {g!r} against the exact {e!r}"
            if "graze" in what:
                worst_graze = max(worst_graze, abs(g - e) / big_r)
            else:
                worst = max(worst, abs(g - e) / scale)
    print(f"torus R={big_r} r={r} at {center}: error / distance {worst:.2e}, grazing error / R {worst_graze:.2e}")


def test_grazing_rays_that_just_miss_the_torus_miss_it():
    s = shapes_of(tori=[{"center": [0, 0, 0], "axis": [0, 0, 1], "major_radius": 1.0, "minor_radius": 0.25}])
    for delta in (1e-9, 1e-12):
        assert one([-5.0, 1.0, 0.25 * (1 + delta)], [1, 0, 0], s)[1] == -1
        assert one([-5.0, 1.25 * (1 + delta), 0.0], [1, 0, 0], s)[1] == -1
        assert one([-5.0, 1.0, 0.25 * (1 - delta)], [1, 0, 0], s)[1] == 0


# --------------------------------------------------------------------------------- bounds


def _surface_points(p: np.ndarray, kind: int, n: int, rng: np.random.Generator, inner: bool = False) -> np.ndarray:
    """Points on a shape's surface, from its parameters (not from the code under test): a
    cylinder's or cone's side and rims, or (``inner``) its side and caps away from the rims."""
    c, a, r0, r1, h = p[0:3], p[4:7], p[3], p[7], p[8]
    e1 = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    phi = rng.uniform(0, 2 * np.pi, n)
    ring = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    u = rng.uniform(0, 1, n)[:, None]
    if kind in (CYLINDER, CONE):
        if inner:
            u = 0.05 + 0.9 * u
        side = c + u * h * a + (r0 + (r1 - r0) * u) * ring
        f = 0.9 * u if inner else 1.0
        ends = np.concatenate([c + f * r0 * ring, c + h * a + f * r1 * ring])
        return np.concatenate([side, ends])
    if kind == DISK:
        return c + (r1 + (r0 - r1) * u) * ring
    theta = rng.uniform(0, 2 * np.pi, n)[:, None]
    return c + (r0 + r1 * np.cos(theta)) * ring + r1 * np.sin(theta) * a


def _extreme_points(p: np.ndarray, kind: int) -> np.ndarray:
    """For each axis i and side ±, a surface point where the shape reaches furthest that way (by
    hand: a circle (c, n, ρ) reaches furthest along ±e_i at c ± ρ·(e_i − n_i n)/|e_i − n_i n|)."""
    c, a, r0, r1, h = p[0:3], p[4:7], p[3], p[7], p[8]
    pts = []
    for i in range(3):
        for sign in (1.0, -1.0):
            e = np.zeros(3)
            e[i] = sign
            w = e - (e @ a) * a
            w = w / np.linalg.norm(w) if np.linalg.norm(w) > 0 else np.zeros(3)
            if kind in (CYLINDER, CONE):
                cands = [c + r0 * w, c + h * a + r1 * w]
            elif kind == DISK:
                cands = [c + r0 * w]
            else:
                cands = [c + r0 * w + r1 * e]
            pts.append(max(cands, key=lambda x, e=e: float(x @ e)))
    return np.array(pts)


def test_bounds_hold_every_surface_point_and_touch_the_shape_on_every_side():
    rng = np.random.default_rng(3)
    s = shapes_of(
        cylinders=[{"base": [1, 2, 3], "axis": [0.3, -1, 0.2], "radius": 0.7, "height": 3.0}],
        cones=[
            {"base": [-4, 0, 1], "axis": [1, 1, 1], "base_radius": 2.0, "top_radius": 0.5, "height": 1.5},
            {"base": [0, 0, 0], "axis": [0, 0, 1], "base_radius": 0.0, "top_radius": 1.0, "height": 1.0},
        ],
        disks=[
            {"center": [5, 5, 5], "normal": [0.1, 0.2, 1.0], "radius": 2.0, "inner_radius": 0.5},
            {"center": [0, 0, 0], "normal": [0, 1, 0], "radius": 1.0},
        ],
        tori=[{"center": [-2, 3, -1], "axis": [0.5, -0.2, 1], "major_radius": 2.0, "minor_radius": 0.4}],
    )
    box = bounds(s)
    assert box.shape == (len(s), 2, 3)
    for k in range(len(s)):
        p, kind = s.params[k], int(s.kind[k])
        pts = _surface_points(p, kind, 4000, rng)
        size = float(np.abs(box[k]).max())
        assert (pts >= box[k, 0] - 1e-12 * size).all() and (pts <= box[k, 1] + 1e-12 * size).all()
        ext = _extreme_points(p, kind)
        reached = np.array([ext[2 * i, i] for i in range(3)]), np.array([ext[2 * i + 1, i] for i in range(3)])
        assert np.allclose(reached[0], box[k, 1], rtol=0, atol=1e-12 * size), s.where(k)
        assert np.allclose(reached[1], box[k, 0], rtol=0, atol=1e-12 * size), s.where(k)


def test_normals_point_out_of_the_solid():
    rng = np.random.default_rng(5)
    s = shapes_of(
        cylinders=[{"base": [0, 0, 0], "axis": [0, 1, 0], "radius": 1.0, "height": 2.0}],
        cones=[{"base": [0, 0, 0], "axis": [1, 0, 0], "base_radius": 1.5, "top_radius": 0.5, "height": 2.0}],
        tori=[{"center": [0, 0, 0], "axis": [0, 0, 1], "major_radius": 2.0, "minor_radius": 0.5}],
    )
    for k in range(len(s)):
        p = s.params[k]
        pts = _surface_points(p, int(s.kind[k]), 200, rng, inner=True)
        n = normals(s, np.full(len(pts), k), pts)
        assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
        # A step out along the normal leaves the solid, a step in enters it (by its own definition).
        for sign, inside in ((1e-6, False), (-1e-6, True)):
            q = pts + sign * n - p[0:3]
            z = q @ p[4:7]
            rho = np.linalg.norm(q - z[:, None] * p[4:7], axis=1)
            if s.kind[k] == TORUS:
                solid = (rho - p[3]) ** 2 + z**2 < p[7] ** 2
            else:
                solid = (z > 0) & (z < p[8]) & (rho < p[3] + (p[7] - p[3]) * z / p[8])
            assert (solid == inside).all(), s.where(k)


# ------------------------------------------------------------------------------------ JSON

BASE = {"camera": {"position": [0, 0, 20], "target": [0, 0, 0]}, "materials": [MAT]}
CYL = {"base": [0, 0, 0], "axis": [0, 1, 0], "radius": 1.0, "height": 2.0}
CONE_ = {"base": [0, 0, 0], "axis": [0, 1, 0], "base_radius": 1.0, "top_radius": 0.5, "height": 2.0}
DISK_ = {"center": [0, 0, 0], "normal": [0, 0, 1], "radius": 1.0}
TORUS_ = {"center": [0, 0, 0], "axis": [0, 0, 1], "major_radius": 2.0, "minor_radius": 0.5}


@pytest.mark.parametrize(
    "key, item, field, says",
    [
        ("cylinders", {**CYL, "radius": 0.0}, "cylinders[1].radius", "must be > 0 and <= 1e+07, got 0"),
        ("cylinders", {**CYL, "height": -1.0}, "cylinders[1].height", "must be > 0 and <= 1e+07"),
        ("cylinders", {**CYL, "axis": [0, 0, 0]}, "cylinders[1].axis", "non-zero"),
        ("cylinders", {**CYL, "base": [0, 2e7, 0]}, "cylinders[1].base", "within ±1e+07"),
        ("cylinders", {**CYL, "base": [0, "x", 0]}, "cylinders[1].base[1]", "expected a number"),
        ("cylinders", {**CYL, "radius": float("nan")}, "cylinders[1].radius", "finite"),
        ("cylinders", {**CYL, "caps": 1}, "cylinders[1].caps", "true or false"),
        ("cylinders", {**CYL, "colour": 1}, "cylinders[1].colour", "unknown field (allowed: axis, base, caps"),
        ("cylinders", {k: v for k, v in CYL.items() if k != "height"}, "cylinders[1].height", "required"),
        ("cones", {**CONE_, "top_radius": -0.5}, "cones[1].top_radius", "must be >= 0"),
        ("cones", {**CONE_, "base_radius": 0.0, "top_radius": 0.0}, "cones[1].base_radius", "must be > 0"),
        ("disks", {**DISK_, "inner_radius": 1.0}, "disks[1].inner_radius", "must be >= 0 and < radius (1)"),
        ("disks", {**DISK_, "normal": [0, 0, 0]}, "disks[1].normal", "non-zero"),
        ("disks", {**DISK_, "material": 3}, "disks[1].material", "out of range (scene has 1 materials)"),
        ("tori", {**TORUS_, "minor_radius": 0.0}, "tori[1].minor_radius", "must be > 0 and < major_radius (2)"),
        ("tori", {**TORUS_, "minor_radius": 2.0}, "tori[1].minor_radius", "must be > 0 and < major_radius (2)"),
        ("tori", {**TORUS_, "major_radius": 1e8}, "tori[1].major_radius", "must be > 0 and <= 1e+07"),
    ],
)
def test_a_bad_shape_is_refused_naming_its_field_and_the_range(key, item, field, says):
    good = {"cylinders": CYL, "cones": CONE_, "disks": DISK_, "tori": TORUS_}[key]
    with pytest.raises(SceneError) as e:
        Scene.from_json({**BASE, key: [good, item]})
    assert e.value.field == field
    assert says in e.value.message


def test_records_made_as_arrays_are_checked_as_json_is():
    good = shapes_of(cylinders=[CYL], tori=[TORUS_])
    p = good.params.copy()
    p[0, 7] = 2.0  # a cylinder's number 7 must repeat its radius
    with pytest.raises(SceneError) as e:
        Shapes(good.kind, p, good.material)
    assert e.value.field == "cylinders[0].radius"
    p = good.params.copy()
    p[1, 7] = 3.0  # the torus's minor radius past its major one
    with pytest.raises(SceneError) as e:
        Shapes(good.kind, p, good.material)
    assert e.value.field == "tori[0].minor_radius"
    with pytest.raises(SceneError) as e:
        Shapes(good.kind[::-1].copy(), good.params[::-1], good.material)
    assert e.value.field == "shapes" and "id order" in e.value.message
    p = good.params.copy()
    p[1, 4:7] = [0.0, 0.0, 2.0]
    assert Shapes(good.kind, p, good.material).params[1, 4:7].tolist() == [0.0, 0.0, 1.0]


def test_too_many_shapes_are_refused(monkeypatch):
    monkeypatch.setattr(limits, "MAX_SHAPES", 3)
    with pytest.raises(SceneError) as e:
        Scene.from_json({**BASE, "disks": [DISK_] * 2, "tori": [TORUS_] * 2})
    assert e.value.field == "tori" and "3" in e.value.message


def test_json_round_trips_bit_for_bit_and_ids_follow_the_triangles():
    d = {
        **BASE,
        "spheres": [{"center": [0, 0, 0], "radius": 1}],
        "planes": [{"point": [0, -5, 0], "normal": [0, 1, 0]}],
        "meshes": [{"vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]]}],
        "tori": [{**TORUS_, "axis": [0.1, 0.7, 0.3]}],  # a non-unit axis, normalised once
        "disks": [{**DISK_, "inner_radius": 0.25}],
        "cones": [{**CONE_, "caps": False}],
        "cylinders": [CYL],
    }
    scene = Scene.from_json(d)
    assert scene.shape_id_base == 1 + 1 + 1 and scene.n_primitives == 3 + 4
    assert scene.shapes.kind.tolist() == [CYLINDER, CONE, DISK, TORUS]  # id order, whatever the JSON's
    again = Scene.from_json(scene.to_json())
    assert np.array_equal(again.shapes.params, scene.shapes.params)
    assert again.to_json() == scene.to_json()
    assert abs(np.linalg.norm(scene.shapes.params[3, 4:7]) - 1.0) < 1e-15
    assert scene.shapes.params[1].tolist()[7:11] == [0.5, 2.0, 0.0, 1.0]
    assert not scene.shapes.params.flags.writeable
    assert "cylinders" not in Scene.from_json(BASE).to_json()  # no shapes: the JSON as it was


# -------------------------------------------------------------------------- the reference


def _pixel_ray(cam_pos, fov_y, w, h, x, y):
    """The primary ray of pixel (x, y) for a camera looking down −z with +y up (SHADING.md)."""
    s = math.tan(math.radians(fov_y) / 2)
    u = (2 * (x + 0.5) / w - 1) * s * w / h
    v = (1 - 2 * (y + 0.5) / h) * s
    d = np.array([u, v, -1.0])
    return np.array(cam_pos, float), d / np.linalg.norm(d)


def _nearest_root(coeffs, ok=lambda t: True) -> float:
    """The smallest positive real root of a polynomial (NumPy's roots) for which ok(t) holds."""
    r = np.roots(coeffs)
    r = [float(x.real) for x in r if abs(x.imag) < 1e-9 and x.real > 0 and ok(float(x.real))]
    return min(r, default=math.inf)


def test_reference_depth_and_ids_of_each_kind_are_the_closed_forms():
    w = h = 15
    cam = [0.0, 0.0, 20.0]
    scene = Scene.from_json(
        {
            "camera": {"position": cam, "target": [0, 0, 0], "fov_y": 40},
            "materials": [MAT],
            "spheres": [{"center": [0, 100, 0], "radius": 1}],  # out of view: ids start at 2
            "planes": [{"point": [0, 0, -10], "normal": [0, 0, 1]}],
            "cylinders": [{"base": [-20, 4, 0], "axis": [1, 0, 0], "radius": 1.5, "height": 40.0}],
            "cones": [{"base": [0, -3, -4], "axis": [0, 0, 1], "base_radius": 2.0, "top_radius": 1.0, "height": 2.0}],
            "disks": [{"center": [-4, 0, 0], "normal": [0, 0, 1], "radius": 1.5, "inner_radius": 0.5}],
            "tori": [{"center": [4, 0, 0], "axis": [0, 0, 1], "major_radius": 1.5, "minor_radius": 0.5}],
        }
    )
    base = scene.shape_id_base
    assert base == 2
    res = render_reference(scene, RenderSettings(width=w, height=h, mode="depth"))
    # The centre pixel looks down −z: x = 0, y = 0 meets nothing but the plane.
    assert res.primid[7, 7] == 1 and res.depth[7, 7] == pytest.approx(30.0, rel=1e-6)
    checked = 0
    for y in range(h):
        for x in range(w):
            o, d = _pixel_ray(cam, 40, w, h, x, y)
            cands = {1: (-10 - o[2]) / d[2]}  # the plane
            # Cylinder about the line y = 4, z = 0 (radius 1.5): (o_y + t d_y − 4)² + (o_z + t d_z)² = 1.5².
            qy, qz = o[1] - 4, o[2]
            cands[base] = _nearest_root([d[1] ** 2 + d[2] ** 2, 2 * (qy * d[1] + qz * d[2]), qy**2 + qz**2 - 2.25])
            # Cone: top cap z = −2 (radius 1) first from the camera, else the side r = 2 − (z + 4)/2.
            t = (-2 - o[2]) / d[2]
            p = o + t * d
            if math.hypot(p[0], p[1] + 3) <= 1.0:
                cands[base + 1] = t
            else:
                # x² + (y + 3)² = (2 − (z + 4)/2)², z ∈ [−4, −2]: a quadratic in t.
                ox, oy, oz = o[0], o[1] + 3, o[2]
                k0, k1 = 2 - (oz + 4) / 2, -d[2] / 2
                cands[base + 1] = _nearest_root(
                    [d[0] ** 2 + d[1] ** 2 - k1**2, 2 * (ox * d[0] + oy * d[1] - k0 * k1), ox**2 + oy**2 - k0**2],
                    lambda t, o=o, d=d: -4 <= o[2] + t * d[2] <= -2,
                )
            t = -o[2] / d[2]
            p = o + t * d
            if 0.5 <= math.hypot(p[0] + 4, p[1]) <= 1.5:
                cands[base + 2] = t
            # Torus about (4, 0, 0): (|X|² + R² − r²)² = 4R²(X_x² + X_y²).
            q = o - [4, 0, 0]
            a2, a1, a0 = d @ d, 2 * q @ d, q @ q + 1.5**2 - 0.5**2
            b2, b1, b0 = d[0] ** 2 + d[1] ** 2, 2 * (q[0] * d[0] + q[1] * d[1]), q[0] ** 2 + q[1] ** 2
            quartic = np.polymul([a2, a1, a0], [a2, a1, a0]) - np.concatenate([[0, 0], 9.0 * np.array([b2, b1, b0])])
            cands[base + 3] = _nearest_root(quartic)
            best = min(cands, key=lambda k: cands[k])
            assert res.primid[y, x] == best, (x, y, cands)
            assert res.depth[y, x] == pytest.approx(cands[best], rel=1e-6), (x, y)
            checked += best >= base
    assert checked >= 12  # every kind is seen by several pixels
    seen = set(np.unique(res.primid).tolist())
    assert {base, base + 1, base + 2, base + 3} <= seen


def test_reference_shadow_rays_and_rays_leaving_a_shape_see_the_shapes():
    mats = [MAT, {**MAT, "reflective": 1.0, "diffuse": 0.0, "ambient": 0.0}]
    scene = Scene.from_json(
        {
            "camera": {"position": [0, 0, 20], "target": [0, 0, 0], "fov_y": 30},
            "materials": mats,
            "lights": [{"position": [0, 0, 50]}],
            "planes": [{"point": [0, 0, -10], "normal": [0, 0, 1]}],
            "disks": [{"center": [0, 0, 5], "normal": [0, 0, 1], "radius": 1.0, "inner_radius": 0.5}],
        }
    )
    res = render_reference(scene, RenderSettings(width=41, height=41, mode="color", max_recursion_depth=2))
    # The plane straight below sees the light through the hole: ambient + diffuse, 0.2·0.5 + 0.8·1·0.5.
    assert res.image[20, 20] == pytest.approx([0.5, 0.5, 0.5], abs=1e-6)
    # A plane point at radius ρ is seen from the camera through z = 5 at radius ρ/2 (the hole when
    # ρ < 1) and its shadow ray toward (0, 0, 50) crosses z = 5 at 0.75·ρ (the ring when ρ ≥ 2/3).
    shadowed = 0
    for x in range(21, 41):
        o, d = _pixel_ray([0, 0, 20], 30, 41, 41, x, 20)
        rho = abs((o + (-10 - o[2]) / d[2] * d)[0])
        if 0.7 < rho < 0.95:
            assert res.image[20, x] == pytest.approx([0.1, 0.1, 0.1], abs=1e-6), x  # ambient only
            shadowed += 1
        if 1.2 < rho < 1.8:  # the ring itself (ρ/2 in [0.5, 1]), lit from above: 0.1 + 0.8·cos·0.5, cos > 0.99
            assert res.image[20, x][0] > 0.49 and res.primid[20, x] == scene.shape_id_base
    assert shadowed >= 1
    # A mirror cylinder: a ray from inside its wall reflects off the far wall (the source's other root).
    mirror = Scene.from_json(
        {
            **BASE,
            "materials": mats,
            "cylinders": [{"base": [0, 0, -5], "axis": [0, 0, 1], "radius": 2.0, "height": 10.0, "material": 1}],
        }
    )
    t, ids = trace_rays(mirror, [[2.0, 0.0, 0.0]], [[-1.0, 0.0, 0.0]], src=[mirror.shape_id_base])
    assert t.tolist() == [4.0] and ids.tolist() == [mirror.shape_id_base]


# ------------------------------------------------------------------------------- motions


def test_motions_move_shape_ranges_rigidly_and_by_the_wave():
    d = {
        **BASE,
        "spheres": [{"center": [9, 9, 9], "radius": 1}],
        "cylinders": [CYL],
        "tori": [{**TORUS_, "center": [5, 0, 0]}],
        "motions": [
            {"kind": "rigid", "over": "shapes", "first": 0, "count": 1, "axis": [0, 0, 1]}
            | {"angular_velocity": math.pi / 2, "period": 4.0, "pivot": [0, 0, 0], "amplitude": [0, 0, 0]},
            {"kind": "deformable", "over": "shapes", "first": 1, "count": 1, "amplitude": 0.5},
            {"kind": "rigid", "first": 0, "count": 1},  # the sphere, as always
        ],
    }
    anim = animated_scene_from_json(d)
    assert anim.moving_shapes.tolist() == [True, True]
    posed = pose(anim, 1.0).scene
    # A quarter turn about z: the cylinder's axis +y becomes −x; its base at the pivot stays.
    assert np.allclose(posed.shapes.params[0, 4:7], [-1, 0, 0], atol=1e-15)
    assert np.allclose(posed.shapes.params[0, 0:3], [0, 0, 0], atol=1e-15)
    # The wave of the rest origin (5, 0, 0), k = 2π/10, ω = k·4: the torus keeps its axis.
    k, wt = 2 * math.pi / 10, 2 * math.pi / 10 * 4 * 1.0
    wave = [math.sin(k * 0 - wt), math.sin(k * 5 - wt + 2.1), math.sin(k * 5 - wt + 4.2)]
    assert np.allclose(posed.shapes.params[1, 0:3], np.array([5, 0, 0]) + 0.5 * np.array(wave), atol=1e-14)
    assert posed.shapes.params[1, 4:7].tolist() == [0.0, 0.0, 1.0]
    assert anim.to_json()["motions"][0]["over"] == "shapes" and "over" not in anim.to_json()["motions"][2]
    assert animated_scene_from_json(anim.to_json()).to_json() == anim.to_json()


@pytest.mark.parametrize(
    "motion, field",
    [
        ({"kind": "incoherent", "over": "shapes", "first": 0, "count": 1}, "motions[0].over"),
        ({"kind": "rigid", "over": "shapes", "first": 0, "count": 3}, "motions[0].count"),
        ({"kind": "rigid", "over": "things", "first": 0, "count": 1}, "motions[0].over"),
        ({"kind": "rigid", "over": "shapes", "mesh": 0}, "motions[0].over"),
    ],
)
def test_a_bad_shape_motion_is_refused_naming_its_field(motion, field):
    with pytest.raises(SceneError) as e:
        animated_scene_from_json({**BASE, "cylinders": [CYL, CYL], "motions": [motion]})
    assert e.value.field == field


# ------------------------------------------------------------------ Mitsuba and the GPU side


def test_mitsuba_intersects_converted_cylinders_and_disks_where_we_do():
    import mitsuba as mi

    from renderer.oracle import mitsuba_scene

    scene = Scene.from_json(
        {
            **BASE,
            "cylinders": [
                {"base": [-8, -3, 0], "axis": [0.3, 1, 0.2], "radius": 2, "height": 5},
                {"base": [0, -3, 0], "axis": [0, 1, 0], "radius": 1, "height": 2, "caps": False},
            ],
            "disks": [{"center": [4, 0, -5], "normal": [0.2, 0.1, 1], "radius": 3}],
        }
    )
    loaded = mitsuba_scene.load(scene, 8, 8, 1, 2)
    rng = np.random.default_rng(1)
    o = np.array([0, 5, 30.0]) + rng.normal(size=(300, 3))
    d = rng.uniform([-10, -3, -6], [8, 4, 2], size=(300, 3)) - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, ids, n = intersect(scene.shapes, o, d)
    theirs_t, theirs_n = np.full(len(o), np.inf), np.zeros((len(o), 3))
    for k in range(len(o)):
        si = loaded.ray_intersect(mi.Ray3f(o[k].tolist(), d[k].tolist()))
        if si.is_valid():
            theirs_t[k], theirs_n[k] = si.t, list(si.n)
    hit = np.isfinite(t)
    assert hit.sum() > 100 and set(ids[hit].tolist()) == {0, 1, 2}
    # Mitsuba's scalar_rgb traces in float32: agreement to its precision, rims aside (a ray that
    # grazes a rim may be a hit in one and a miss in the other).
    both = hit & np.isfinite(theirs_t)
    assert (hit != np.isfinite(theirs_t)).sum() <= 2
    assert np.abs(t[both] - theirs_t[both]).max() < 1e-4
    # Mitsuba's cylinder normal faces out of the tube as ours; its disk faces the given normal.
    assert np.abs(n[both] - theirs_n[both]).max() < 1e-4


@pytest.mark.parametrize(
    "key, item, field",
    [
        ("cones", CONE_, "cones[0]"),
        ("tori", TORUS_, "tori[0]"),
        ("disks", {**DISK_, "inner_radius": 0.5}, "disks[0].inner_radius"),
    ],
)
def test_mitsuba_has_no_cone_torus_nor_annulus_and_says_so(key, item, field):
    from renderer.oracle import mitsuba_scene

    scene = Scene.from_json({**BASE, key: [item]})
    with pytest.raises(mitsuba_scene.NoMitsubaShape) as e:
        mitsuba_scene.scene_dict(scene, 8, 8, 1, 2)
    assert e.value.field == field and "Mitsuba 3 has no" in e.value.message


def test_the_one_pass_methods_take_shapes_and_the_ray_engines_refuse_them():
    scene = Scene.from_json({**BASE, "spheres": [{"center": [0, 0, 0], "radius": 1}], "tori": [TORUS_]})
    for name, m in METHODS.items():
        if m.capabilities.multi_pass:
            with pytest.raises(SceneError) as e:
                check_primitives(name, scene)
            assert e.value.field == "method" and "1 tori" in e.value.message and "bih" in e.value.message
        else:
            check_primitives(name, scene)
    with pytest.raises(SceneError) as e:
        prepare_frame(scene, RenderSettings(width=8, height=8, method="rayengine"))
    assert e.value.field == "method"
    prepare_frame(scene, RenderSettings(width=8, height=8))

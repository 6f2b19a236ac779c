"""Tests of the float64 reference tracer (renderer/oracle/reference.py) against SHADING.md.

Expected values are computed here by hand / analytically from the camera and scene
parameters, not with the tracer's own helpers, except where a test says otherwise.
Images are small (a few thousand pixels) so that each test takes well under a second.

The float64 reference tracer on triangles (docs/SHADING.md, "Triangles"): every output mode,
flat and smooth shading, both sides, exclusion of the source triangle, refraction through a
closed mesh. Expected values are computed here from the geometry, not with the tracer.

Watertightness of the triangle test on closed meshes: no ray that enters a closed mesh's
silhouette gets through it (docs/SHADING.md, "Triangles").

The rays are made without the tracer: each aims at a point ``q`` on the surface — a vertex,
a point of a shared edge, a point inside a triangle — from outside, along a direction that
makes a positive angle with every face around ``q`` (so the ray crosses the surface at
``q``, it does not graze it). Such a ray must hit the mesh at or before ``q``. Rays
through the exact edges and vertices of an axis-aligned box, along the axes, make the edge
functions exactly 0 and exercise the exact fallback. A second, independent check: a line
through a closed mesh crosses it an even number of times.

The float64 reference (renderer.oracle.reference) and the BIH traversal's CPU mirror
(renderer.accel.bih_traverse) are both checked. The figures (rays, leaks) are printed
with ``-s``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from renderer.accel.bih import build_for_scene
from renderer.accel.bih_traverse import traverse
from renderer.config.settings import RenderSettings
from renderer.geometry.meshes import box, icosphere, teapot, torus
from renderer.geometry.scene import Camera, Light, Material, Mesh, Plane, Scene
from renderer.modes import RECURSION_COLORS
from renderer.oracle.reference import (
    RayBatch,
    _Frame,
    _Geometry,
    _trace_batch,
    primary_rays,
    reflect,
    render_reference,
    trace_rays,
    transmitted_directions,
    triangle_hits,
)
from renderer.scenes.scenarios import scenario

# Fig. 4.2f, written out independently of the module.
RECURSION_TABLE = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1), (0, 1, 1), (1, 1, 1), (1, 0.5, 0)]
BLACK = Material(color=(0.0, 0.0, 0.0), ambient=0.0, diffuse=0.0, specular=0.0, reflective=0.0)


def make_scene(spheres=(), planes=(), materials=(BLACK,), lights=(), camera=None) -> Scene:
    """Scene from [(center, radius, material)] and Plane objects."""
    c = np.array([s[0] for s in spheres], dtype=np.float64).reshape(-1, 3)
    r = np.array([s[1] for s in spheres], dtype=np.float64)
    m = np.array([s[2] for s in spheres], dtype=np.int32)
    return Scene(camera or Camera(), tuple(lights), tuple(materials), c, r, m, tuple(planes))


def settings(w: int, h: int, **kw) -> RenderSettings:
    kw.setdefault("method", "bruteforce")
    return RenderSettings(width=w, height=h, **kw)


def pixel_uv(cam: Camera, w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) image-plane coordinates of every pixel, (H, W), straight from SHADING.md."""
    s = math.tan(math.radians(cam.fov_y) / 2)
    x, y = np.meshgrid(np.arange(w), np.arange(h))
    return (2 * (x + 0.5) / w - 1) * s * w / h, (1 - 2 * (y + 0.5) / h) * s


# ------------------------------------------------------------------ primary rays


def test_primary_rays_unit_centre_and_orientation():
    cam = Camera(position=(1.0, 2.0, 30.0), target=(0.0, -1.0, 0.0), up=(0.0, 1.0, 0.0), fov_y=50.0)
    w, h = 33, 21  # odd: the centre pixel is on the axis
    o, d = primary_rays(cam, w, h)
    right, up, forward = cam.basis()
    assert o.shape == d.shape == (w * h, 3) and o.dtype == d.dtype == np.float64
    np.testing.assert_allclose(o, np.broadcast_to(cam.position, o.shape))
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=0, atol=1e-14)
    centre = (h // 2) * w + w // 2
    np.testing.assert_allclose(d[centre], forward, rtol=0, atol=1e-15)
    grid = d.reshape(h, w, 3)
    assert (grid[0] @ up > 0).all() and (grid[-1] @ up < 0).all()  # row 0 looks up
    assert (grid[:, 0] @ right < 0).all() and (grid[:, -1] @ right > 0).all()
    # Corner ray: forward + u right + v up, normalised, with the spec's u, v.
    u, v = pixel_uv(cam, w, h)
    expect = forward + u[0, 0] * right + v[0, 0] * up
    np.testing.assert_allclose(d[0], expect / np.linalg.norm(expect), rtol=0, atol=1e-15)
    # Vertical field of view: the top edge of the image is fov_y / 2 above the axis.
    top_edge = math.degrees(math.atan(math.tan(math.radians(25.0)) * (1 - 1 / h)))
    assert math.degrees(math.asin(grid[0, w // 2] @ up)) == pytest.approx(top_edge, abs=1e-9)


# --------------------------------------------------------------------- geometry


def test_single_sphere_exact_geometry_and_disc():
    dist, radius = 100.0, 20.0
    cam = Camera(position=(0.0, 0.0, dist), target=(0.0, 0.0, 0.0), fov_y=60.0)
    scene = make_scene([((0.0, 0.0, 0.0), radius, 0)], camera=cam)
    w, h = 95, 63
    res = render_reference(scene, settings(w, h, mode="depth"))
    assert res.depth.dtype == np.float32 and res.primid.dtype == np.int32 and res.normal.dtype == np.float32
    assert res.primid[h // 2, w // 2] == 0
    assert res.depth[h // 2, w // 2] == pytest.approx(dist - radius, rel=1e-9)
    # Float64 t of the centre ray (t = D − R exactly).
    o, d = primary_rays(cam, w, h)
    t, prim = trace_rays(scene, o, d)
    assert t[(h // 2) * w + w // 2] == pytest.approx(dist - radius, rel=1e-12)
    # Angle α of every pixel ray from the axis; the sphere subtends sin α ≤ R / D.
    u, v = pixel_uv(cam, w, h)
    sin_a = np.sqrt((u * u + v * v) / (1 + u * u + v * v))
    cos_a = np.sqrt(1 / (1 + u * u + v * v))
    inside = sin_a < radius / dist * (1 - 1e-9)
    outside = sin_a > radius / dist * (1 + 1e-9)
    assert inside.sum() > 100 and outside.sum() > 100
    assert (res.primid[outside] == -1).all() and np.isinf(res.depth[outside]).all()
    assert (res.normal[outside] == 0).all() and (res.image[outside] == 0).all()
    assert (res.primid[inside] == 0).all()
    t_exact = dist * cos_a - np.sqrt(np.maximum(radius**2 - (dist * sin_a) ** 2, 0))
    np.testing.assert_allclose(t.reshape(h, w)[inside], t_exact[inside], rtol=1e-9)
    # Normals are unit, outward (towards the camera); depth image is D / (D + t).
    n = res.normal[inside]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    assert (n[:, 2] > 0).all()
    np.testing.assert_allclose(res.image[inside][:, 0], dist / (dist + t_exact[inside]), rtol=1e-6)


def test_plane_only_depth_is_analytic():
    cam = Camera(position=(3.0, 5.0, 50.0), target=(0.0, 0.0, 0.0), fov_y=70.0)
    point, normal = np.array([0.0, -7.0, 0.0]), np.array([0.0, 1.0, 0.2]) / math.hypot(1.0, 0.2)
    scene = make_scene(planes=[Plane(point=tuple(point), normal=tuple(normal))], camera=cam)
    w, h = 64, 48
    res = render_reference(scene, settings(w, h, mode="primid"))
    right, up, forward = cam.basis()
    u, v = pixel_uv(cam, w, h)
    d = forward + u[..., None] * right + v[..., None] * up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    t = (point - np.array(cam.position)) @ normal / (d @ normal)
    hit = t > 0
    assert hit.sum() > 100 and (~hit).sum() > 100
    assert (res.primid[hit] == 0).all() and (res.primid[~hit] == -1).all()
    np.testing.assert_allclose(res.depth[hit], t[hit], rtol=1e-6)
    o, dd = primary_rays(cam, w, h)
    t64, _ = trace_rays(scene, o, dd)
    np.testing.assert_allclose(t64.reshape(h, w)[hit], t[hit], rtol=1e-12)
    np.testing.assert_allclose(res.normal[hit], np.broadcast_to(normal, (hit.sum(), 3)), atol=1e-7)


def test_ties_go_to_the_lower_id():
    # Two identical spheres and two identical planes: every hit is an exact tie.
    scene = make_scene(
        [((0.0, 0.0, 0.0), 30.0, 0), ((0.0, 0.0, 0.0), 30.0, 0)], planes=[Plane((0.0, -20.0, 0.0), (0.0, 1.0, 0.0))] * 2
    )
    res = render_reference(scene, settings(32, 24, mode="primid"))
    ids = set(np.unique(res.primid).tolist())
    assert ids == {-1, 0, 2}


def test_cull_matches_dense_brute_force():
    """The tiled, culled search returns bitwise what testing every pair returns."""
    from renderer.oracle.reference import sphere_t

    rng = np.random.default_rng(1)
    for offset, scale in ((0.0, 1.0), (1e6, 1e-3)):
        n = 300
        centres = offset + rng.uniform(-10, 10, (n, 3)) * scale
        radii = rng.uniform(0.2, 3.0, n) * scale
        scene = make_scene([(c, r, 0) for c, r in zip(centres, radii, strict=True)])
        o = offset + rng.uniform(-15, 15, (700, 3)) * scale
        d = rng.normal(size=(700, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        t, prim = trace_rays(scene, o, d)
        tt = sphere_t(
            np.repeat(o, n, 0), np.repeat(d, n, 0), np.tile(centres, (700, 1)), np.tile(radii * radii, 700)
        ).reshape(700, n)
        expect = np.where(np.isfinite(tt.min(1)), tt.argmin(1), -1)  # argmin: first = lowest id
        assert (prim == expect).all()
        assert np.array_equal(t, tt.min(1))
        assert (prim >= 0).sum() > 300


# ---------------------------------------------------------------------- shading


@pytest.mark.parametrize("offset,radius", [(0.0, 10.0), (1e6, 1e-3), (-3e5, 1e3)])
def test_lit_sphere_centre_pixel_by_hand(offset, radius):
    c = np.array([offset, offset, offset])
    cam = Camera(position=tuple(c + [0, 0, 10 * radius]), target=tuple(c), fov_y=40.0)
    mat = Material(
        color=(0.8, 0.5, 0.2), ambient=0.1, diffuse=0.6, specular=0.3, shininess=10.0, reflective=0.0, transmissive=0.0
    )
    lp, lc = c + np.array([3.0, 4.0, 10.0]) * radius, np.array([1.0, 0.9, 0.8])
    scene = make_scene(
        [(tuple(c), radius, 0)], materials=[mat], camera=cam, lights=[Light(position=tuple(lp), color=tuple(lc))]
    )
    res = render_reference(scene, settings(31, 21, mode="color", max_recursion_depth=5))
    # By hand: p = c + (0, 0, R), N = (0, 0, 1), d = (0, 0, −1).
    N = np.array([0.0, 0.0, 1.0])
    L = np.array([3.0, 4.0, 9.0]) / math.sqrt(9 + 16 + 81)
    cos = L @ N
    r = 2 * cos * N - L
    spec = max(r @ N, 0.0) ** 10.0
    col = np.array(mat.color)
    expect = 0.1 * col + lc * (0.6 * cos * col + 0.3 * spec)
    np.testing.assert_allclose(res.image[10, 15], expect, atol=1e-6)
    assert res.image[10, 15, 0] > 0.1 * col[0] + 0.05  # clearly lit, not self-shadowed


def test_shadow_of_another_sphere_leaves_only_ambient():
    floor = Material(color=(0.2, 0.7, 0.4), ambient=0.25, diffuse=0.7, specular=0.5, shininess=5.0, reflective=0.0)
    ball_c, ball_r = np.array([0.0, 0.0, 0.0]), 6.0
    lp = np.array([4.0, 40.0, 5.0])
    cam = Camera(position=(0.0, 30.0, 60.0), target=(0.0, -10.0, 0.0), fov_y=50.0)
    scene = make_scene(
        [(tuple(ball_c), ball_r, 0)],
        planes=[Plane((0.0, -10.0, 0.0), (0.0, 1.0, 0.0), 0)],
        materials=[floor],
        lights=[Light(position=tuple(lp))],
        camera=cam,
    )
    w, h = 64, 48
    res = render_reference(scene, settings(w, h, mode="color"))
    o, d = primary_rays(cam, w, h)
    on_plane = (res.primid == 1).reshape(-1)
    p = o + res.depth.reshape(-1)[:, None].astype(np.float64) * d
    # Distance from the ball's centre to the segment p → light, analytically.
    seg = lp - p
    s = np.clip(((ball_c - p) * seg).sum(1) / (seg * seg).sum(1), 0, 1)
    gap = np.linalg.norm(p + s[:, None] * seg - ball_c, axis=1)
    shadow = on_plane & (gap < ball_r * 0.98)
    lit = on_plane & (gap > ball_r * 1.02)
    assert shadow.sum() > 20 and lit.sum() > 200
    img = res.image.reshape(-1, 3)
    np.testing.assert_allclose(img[shadow], np.broadcast_to(0.25 * np.array(floor.color), (shadow.sum(), 3)), atol=1e-7)
    assert (img[lit, 1] > 0.25 * 0.7 + 1e-3).all()


def test_shading_uses_the_normal_facing_the_ray():
    """Nf: a plane lit and seen from the side its normal points away from shades the same."""
    floor = Material(color=(0.2, 0.7, 0.4), ambient=0.1, diffuse=0.7, specular=0.5, shininess=5.0, reflective=0.0)
    cam = Camera(position=(0.0, 30.0, 60.0), target=(0.0, -10.0, 0.0), fov_y=50.0)

    def render(normal: tuple[float, float, float]) -> np.ndarray:
        scene = make_scene(
            planes=[Plane((0.0, -10.0, 0.0), normal, 0)],
            materials=[floor],
            lights=[Light(position=(4.0, 40.0, 5.0))],
            camera=cam,
        )
        return render_reference(scene, settings(32, 24, mode="color")).image

    up, down = render((0.0, 1.0, 0.0)), render((0.0, -1.0, 0.0))
    np.testing.assert_allclose(down, up, atol=1e-7)
    assert (up[-1, :, 1] > 0.1 * 0.7 + 0.05).all()  # bottom row: on the plane, lit


# ------------------------------------------------------------------- refraction


def test_ior_one_transmission_is_straight():
    """A primary ray through a sphere with ior 1 lands where the straight line does."""
    glass = Material(
        color=(1.0, 1.0, 1.0), ambient=0.0, diffuse=0.0, specular=0.0, reflective=0.0, transmissive=1.0, ior=1.0
    )
    scene = make_scene(
        [((0.3, -0.2, 0.0), 10.0, 0)], planes=[Plane((0.0, 0.0, -40.0), (0.0, 0.2, 1.0), 1)], materials=[glass, BLACK]
    )
    rng = np.random.default_rng(5)
    o = np.tile([0.0, 0.0, 100.0], (50, 1))
    # Within the sphere's disc (sin α < R / D = 0.1), so every ray enters it.
    d = np.column_stack([rng.uniform(-0.065, 0.065, (50, 2)), -np.ones(50)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    c = np.array([0.3, -0.2, 0.0])
    t1, p1 = trace_rays(scene, o, d)
    assert (p1 == 0).all()
    x1 = o + t1[:, None] * d
    n1 = (x1 - c) / 10.0
    d1, tir = transmitted_directions(d, n1, np.ones(50))
    assert not tir.any()
    t2, p2 = trace_rays(scene, x1, d1, src=np.zeros(50), far_only=(d1 * n1).sum(1) < 0)
    assert (p2 == 0).all() and (t2 > 1.0).all()  # the far side of the same sphere
    x2 = x1 + t2[:, None] * d1
    n2 = (x2 - c) / 10.0
    d2, tir = transmitted_directions(d1, n2, np.ones(50))
    assert not tir.any()
    t3, p3 = trace_rays(scene, x2, d2, src=np.zeros(50), far_only=(d2 * n2).sum(1) < 0)
    assert (p3 == 1).all()
    plane_n = np.array([0.0, 0.2, 1.0]) / math.hypot(0.2, 1.0)
    t_straight = ((np.array([0.0, 0.0, -40.0]) - o) @ plane_n) / (d @ plane_n)
    np.testing.assert_allclose(x2 + t3[:, None] * d2, o + t_straight[:, None] * d, atol=1e-9)


def test_ior_one_sphere_is_invisible_in_a_render():
    """Whole render: a pure kt = 1, ior = 1 sphere leaves the image unchanged; ior 1.5 does not."""
    red = Material(color=(1.0, 0.0, 0.0), ambient=1.0, diffuse=0.0, specular=0.0, reflective=0.0)
    green = Material(color=(0.0, 1.0, 0.0), ambient=1.0, diffuse=0.0, specular=0.0, reflective=0.0)
    cam = Camera(position=(0.0, 5.0, 80.0), target=(0.0, 0.0, 0.0), fov_y=40.0)
    base = [((4.0, 2.0, -30.0), 6.0, 0)]
    plane = [Plane((0.0, -10.0, 0.0), (0.0, 1.0, 0.0), 1)]

    def image(ior: float | None) -> np.ndarray:
        glass = Material(
            color=(1.0, 1.0, 1.0),
            ambient=0.0,
            diffuse=0.0,
            specular=0.0,
            reflective=0.0,
            transmissive=1.0,
            ior=ior or 1.0,
        )
        spheres = base + ([((0.0, 0.0, 0.0), 15.0, 2)] if ior else [])
        scene = make_scene(spheres, planes=plane, materials=[red, green, glass], camera=cam)
        return render_reference(scene, settings(48, 36, mode="color", max_recursion_depth=3)).image

    without = image(None)
    assert (without[..., 0] == 1).sum() > 20  # the red ball is visible (behind the glass)
    np.testing.assert_allclose(image(1.0), without, atol=1e-6)
    assert np.abs(image(1.5) - without).max() > 0.5


def test_total_internal_reflection_beyond_critical_angle():
    ior = 1.5
    critical = math.degrees(math.asin(1 / ior))  # 41.8°
    normal = np.array([[0.0, 0.0, 1.0]] * 4)  # outward normal; the ray is inside, leaving
    angles = np.array([20.0, critical - 0.5, critical + 0.5, 70.0])
    a = np.radians(angles)
    d = np.column_stack([np.sin(a), np.zeros(4), np.cos(a)])
    out, tir = transmitted_directions(d, normal, np.full(4, ior))
    assert tir.tolist() == [False, False, True, True]
    np.testing.assert_allclose(out[2:], reflect(d[2:], normal[2:]), atol=1e-15)
    assert (out[2:, 2] < 0).all()  # reflected back inside
    # Below the critical angle: Snell, sin θt = ior · sin θi, leaving along +z.
    np.testing.assert_allclose(out[:2, 0], ior * np.sin(a[:2]), atol=1e-12)
    assert (out[:2, 2] > 0).all()
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-14)
    # Entering from outside: sin θt = sin θi / ior, always transmitted.
    out, tir = transmitted_directions(-d, normal, np.full(4, ior))
    assert not tir.any()
    np.testing.assert_allclose(out[:, 0], -np.sin(a) / ior, atol=1e-12)


# ---------------------------------------------------------------- robustness


def mirror_box() -> Scene:
    mirror = Material(color=(0.6, 0.6, 0.9), ambient=0.05, diffuse=0.2, specular=0.3, shininess=20.0, reflective=0.9)
    ball = Material(
        color=(0.9, 0.4, 0.1), ambient=0.2, diffuse=0.5, specular=0.5, reflective=0.5, transmissive=0.3, ior=1.3
    )
    planes = [Plane(tuple(-10.0 * n), tuple(n), 0) for n in np.vstack([np.eye(3), -np.eye(3)])]
    return make_scene(
        [((2.0, -3.0, -1.0), 3.0, 1), ((-4.0, 3.0, 2.0), 2.0, 0)],
        planes=planes,
        materials=[mirror, ball],
        lights=[Light(position=(0.0, 8.0, 0.0))],
        camera=Camera(position=(1.0, 1.0, 8.0), target=(0.0, 0.0, 0.0), fov_y=90.0),
    )


def test_mirror_box_depth_8():
    scene = mirror_box()
    col = render_reference(scene, settings(40, 30, mode="color", max_recursion_depth=8))
    assert np.isfinite(col.image).all()
    assert col.image.max() > 0.2
    one = render_reference(scene, settings(40, 30, mode="color", max_recursion_depth=1))
    assert (col.image >= one.image - 1e-6).all() and (col.image > one.image + 0.05).mean() > 0.5
    # A closed box: every ray hits something, so every pixel's deepest level is 8 (orange).
    rec = render_reference(scene, settings(40, 30, mode="recursion", max_recursion_depth=8))
    np.testing.assert_array_equal(rec.image.reshape(-1, 3), np.tile([1.0, 0.5, 0.0], (1200, 1)))


def test_scenario3_color_is_finite():
    res = render_reference(scenario(3, 64), settings(80, 136, mode="color", max_recursion_depth=5))
    assert res.image.shape == (136, 80, 3) and res.image.dtype == np.float32
    assert np.isfinite(res.image).all()
    assert (res.image >= 0).all() and (res.image <= 1).all()
    assert (res.primid >= 0).mean() > 0.3 and res.image.max() > 0.3
    assert set(res.timings) == {"trace"} and res.stats is None


# ------------------------------------------------------------------- modes


def test_recursion_mode_one_reflective_sphere():
    shiny = Material(color=(0.5, 0.5, 0.5), reflective=0.8)
    matte = Material(color=(0.3, 0.3, 0.3), reflective=0.0)
    cam = Camera(position=(0.0, 0.0, 60.0), target=(0.0, -5.0, 0.0), fov_y=60.0)
    scene = make_scene(
        [((0.0, 0.0, 0.0), 10.0, 0)],
        planes=[Plane((0.0, -20.0, 0.0), (0.0, 1.0, 0.0), 1)],
        materials=[shiny, matte],
        lights=[Light((0.0, 40.0, 0.0))],
        camera=cam,
    )
    w, h = 64, 48
    res = render_reference(scene, settings(w, h, mode="recursion", max_recursion_depth=4))
    img = res.image.reshape(-1, 3).astype(np.float64)
    table = np.array(RECURSION_TABLE)
    assert np.isin(np.abs(img[:, None, :] - table[None]).max(2).min(1), [0.0]).all()
    _, d = primary_rays(cam, w, h)
    prim, n = res.primid.reshape(-1), res.normal.reshape(-1, 3).astype(np.float64)
    r = d - 2 * (d * n).sum(1, keepdims=True) * n
    sphere = prim == 0
    down, up = sphere & (r[:, 1] < -1e-3), sphere & (r[:, 1] > 1e-3)
    assert down.sum() > 50 and up.sum() > 50
    assert (img[down] == [0, 1, 0]).all()  # reflection hits the plane: level 2
    assert (img[up] == [1, 0, 0]).all()  # reflection escapes: level 1
    assert (img[prim == 1] == [1, 0, 0]).all()  # matte plane: no secondary ray
    assert (img[prim == -1] == 0).all() and (prim == -1).any()
    # With max depth 1 nothing can be deeper than level 1.
    res1 = render_reference(scene, settings(w, h, mode="recursion", max_recursion_depth=1))
    assert (res1.image.reshape(-1, 3)[prim >= 0] == [1, 0, 0]).all()


def test_primid_normal_depth_images():
    scene = scenario(1, 27)
    out = {m: render_reference(scene, settings(40, 30, mode=m)) for m in ("primid", "normal", "depth")}
    res = out["primid"]
    hit = res.primid >= 0
    assert hit.any() and (~hit).any() and (res.primid == 27).any()  # plane id = n
    ids = res.primid[hit].astype(np.float64)
    for k, f in enumerate((0.6180340, 0.7548777, 0.5698403)):
        x = ids * f
        np.testing.assert_allclose(out["primid"].image[hit][:, k], (x - np.floor(x)) * 0.8 + 0.2, atol=1e-6)
    np.testing.assert_allclose(out["normal"].image[hit], 0.5 * (res.normal[hit] + 1), atol=1e-6)
    assert (out["normal"].image[~hit] == 0).all() and (out["primid"].image[~hit] == 0).all()
    np.testing.assert_allclose(out["depth"].image[hit][:, 1], 100.0 / (100.0 + res.depth[hit]), rtol=1e-6)
    for m in out.values():  # depth/primid/normal arrays do not depend on the mode
        np.testing.assert_array_equal(m.primid, res.primid)
        np.testing.assert_array_equal(m.depth, res.depth)


def test_method_does_not_change_the_color():
    scene = scenario(2, 40, seed=3)
    a = render_reference(scene, settings(32, 40, method="bruteforce"))
    b = render_reference(scene, settings(32, 40, method="bih"), chunk_rays=100)  # chunking neither
    np.testing.assert_array_equal(a.image, b.image)
    np.testing.assert_array_equal(a.depth, b.depth)


def test_heat_bruteforce_is_red_by_sphere_count():
    for n, red in ((8, 0.4), (40, 1.0)):
        res = render_reference(scenario(1, n), settings(24, 16, mode="heat", method="bruteforce"))
        np.testing.assert_allclose(res.image.reshape(-1, 3), np.tile([red, 0, 0], (24 * 16, 1)), atol=1e-7)


def test_heat_bih_uses_traversal_counts():
    from renderer.accel import bih_traverse as bt
    from renderer.accel.bih import build_for_spheres

    scene = scenario(2, 200, seed=1)
    s = settings(40, 64, mode="heat", method="bih", max_prims=4)
    res = render_reference(scene, s)
    o, d = primary_rays(scene.camera, 40, 64)
    tr = bt.traverse(
        build_for_spheres(scene.sphere_centers, scene.sphere_radii, 4, s.max_tree_depth),
        scene.sphere_centers,
        scene.sphere_radii,
        o,
        d,
    )
    expect = np.minimum(np.column_stack([0.05 * tr.tests, 0.2 * tr.gaps, 0.2 * tr.nodes_visited]), 1.0)
    np.testing.assert_allclose(res.image.reshape(-1, 3), expect, atol=1e-7)
    assert (tr.nodes_visited > 0).any() and (tr.tests < 200).all()
    # Spheres only: the traversal's nearest sphere is the reference's, where no plane is nearer.
    spheres_only = Scene(
        scene.camera, scene.lights, scene.materials, scene.sphere_centers, scene.sphere_radii, scene.sphere_materials
    )
    t, prim = trace_rays(spheres_only, o, d)
    assert (prim >= 0).sum() > 50
    np.testing.assert_array_equal(np.asarray(tr.prim), prim)
    np.testing.assert_allclose(np.asarray(tr.t)[prim >= 0], t[prim >= 0], rtol=1e-12)


CAM = Camera(position=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=60.0)
# one big triangle in the plane z = 0 around the view axis, wound counter-clockwise seen from +z
TRI = np.array([[-8.0, -6.0, 0.0], [8.0, -6.0, 0.0], [0.0, 9.0, 0.0]])


def scene_of(meshes=(), spheres=(), planes=(), materials=(BLACK,), lights=(), camera=CAM) -> Scene:
    c = np.array([s[0] for s in spheres], dtype=np.float64).reshape(-1, 3)
    r = np.array([s[1] for s in spheres], dtype=np.float64)
    m = np.array([s[2] for s in spheres], dtype=np.int32)
    return Scene(camera, tuple(lights), tuple(materials), c, r, m, tuple(planes), tuple(meshes))


def inside_triangle(p: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(strictly inside by a margin, barycentric weights) of points p (k, 3) in the plane of tri."""
    a, b, c = tri
    n = np.cross(b - a, c - a)
    area = np.dot(n, n)
    w0 = np.einsum("ij,j->i", np.cross(c - b, p - b), n) / area
    w1 = np.einsum("ij,j->i", np.cross(a - c, p - c), n) / area
    w2 = 1.0 - w0 - w1
    w = np.stack([w0, w1, w2], axis=1)
    return (w > 1e-6).all(axis=1), w


def test_depth_primid_and_normal_of_a_flat_triangle_from_both_sides():
    w, h = 48, 40
    o, d = primary_rays(CAM, w, h)
    t_plane = -o[:, 2] / d[:, 2]  # z = 0
    inside, _ = inside_triangle(o + t_plane[:, None] * d, TRI)
    outside = ~inside & ~inside_triangle(o + t_plane[:, None] * d, TRI)[1].min(axis=1).__ge__(-1e-6)
    assert inside.sum() > 500 and outside.sum() > 100
    for order, normal_z in (([0, 1, 2], 1.0), ([0, 2, 1], -1.0)):  # facing the camera, then away: both hit
        scene = scene_of([Mesh(TRI, [order])])
        for mode in ("depth", "primid", "normal"):
            res = render_reference(scene, settings(w, h, mode=mode))
            assert (res.primid.ravel()[inside] == 0).all() and (res.primid.ravel()[outside] == -1).all()
            np.testing.assert_allclose(res.depth.ravel()[inside], t_plane[inside], rtol=1e-6)
            # the normal mode shows the outward normal of the winding, whichever side is seen
            np.testing.assert_array_equal(res.normal.reshape(-1, 3)[inside], [[0.0, 0.0, normal_z]] * inside.sum())
        img = render_reference(scene, settings(w, h, mode="normal")).image.reshape(-1, 3)
        np.testing.assert_allclose(img[inside], [[0.5, 0.5, 0.5 * (normal_z + 1)]] * inside.sum(), atol=1e-7)
    t64, _ = trace_rays(scene_of([Mesh(TRI, [[0, 1, 2]])]), o, d)
    np.testing.assert_allclose(t64[inside], t_plane[inside], rtol=1e-14)


def test_triangle_ids_follow_the_spheres_and_planes_and_degenerate_ones_are_never_hit():
    far_plane = Plane((0.0, 0.0, -50.0), (0.0, 0.0, 1.0))
    flat = Mesh(np.array([[-1.0, 0, 0], [0, 0, 0], [1.0, 0, 0], [0, 1, 0]]), [[0, 1, 2], [0, 2, 3]])
    big = Mesh(TRI * 2 + [0, 0, -1.0], [[0, 1, 2]])
    scene = scene_of([flat, big], spheres=[((30.0, 30.0, 0.0), 1.0, 0)], planes=[far_plane])
    assert scene.n_degenerate_triangles == 1
    res = render_reference(scene, settings(32, 24, mode="primid"))
    ids = set(np.unique(res.primid).tolist())
    # sphere 0 (out of view), plane 1, then triangles 2 (degenerate: never), 3, 4
    assert ids == {1, 3, 4}


def test_smooth_normals_are_the_normalised_barycentric_blend():
    normals = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, -1.0, 2.0]])
    scene = scene_of([Mesh(TRI, [[0, 1, 2]], 0, normals)])
    w, h = 40, 40
    res = render_reference(scene, settings(w, h, mode="normal"))
    o, d = primary_rays(CAM, w, h)
    p = o + (-o[:, 2] / d[:, 2])[:, None] * d
    inside, bary = inside_triangle(p, TRI)
    unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    blend = bary @ unit
    blend /= np.linalg.norm(blend, axis=1, keepdims=True)
    np.testing.assert_allclose(res.normal.reshape(-1, 3)[inside], blend[inside], atol=2e-6)
    # corners' directions are reached near the corners, so the blend really varies
    assert np.ptp(res.normal.reshape(-1, 3)[inside][:, 0]) > 0.3


def phong(c, ka, kd, ks, q, n, ldir, view):
    """SHADING.md's local term for one light of colour 1 in direction ldir, n facing the viewer."""
    cos = max(np.dot(n, ldir), 0.0)
    r = 2 * cos * n - ldir
    x = np.dot(r, view)
    return ka * c + kd * cos * c + ks * (x**q if x > 0 and cos > 0 else 0.0)


@pytest.mark.parametrize("smooth", [False, True])
def test_color_uses_the_shading_normal_turned_to_the_geometric_side(smooth):
    mat = Material(color=(0.8, 0.6, 0.4), ambient=0.1, diffuse=0.6, specular=0.3, shininess=20.0, reflective=0.0)
    light = Light((3.0, 4.0, 8.0), (1.0, 1.0, 1.0))
    normals = np.array([[0.2, 0.0, 1.0], [0.0, 0.3, 1.0], [-0.1, -0.1, 1.0]]) if smooth else None
    # wound away from the camera: the geometric normal is −z, the camera sees its back, so
    # Nf is the (smooth or flat) normal flipped to +z
    back = [[0, 2, 1]]
    scene = scene_of([Mesh(TRI, back, 0, None if normals is None else -normals)], materials=[mat], lights=[light])
    w, h = 24, 20
    res = render_reference(scene, settings(w, h, mode="color", max_recursion_depth=1))
    o, d = primary_rays(CAM, w, h)
    p = o + (-o[:, 2] / d[:, 2])[:, None] * d
    inside, bary = inside_triangle(p, TRI)
    img = res.image.reshape(-1, 3)
    for i in np.flatnonzero(inside)[::7]:
        if smooth:
            unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
            n = bary[i] @ unit
            n /= np.linalg.norm(n)
        else:
            n = np.array([0.0, 0.0, 1.0])
        ldir = np.array(light.position) - p[i]
        ldir /= np.linalg.norm(ldir)
        expect = phong(np.array(mat.color), mat.ambient, mat.diffuse, mat.specular, mat.shininess, n, ldir, -d[i])
        np.testing.assert_allclose(img[i], np.clip(expect, 0, 1), atol=2e-6)


def test_a_triangle_casts_a_shadow_and_a_shadow_ray_leaving_a_triangle_ignores_it():
    mat = Material(color=(1.0, 1.0, 1.0), ambient=0.2, diffuse=0.8, specular=0.0, reflective=0.0)
    cam = Camera(position=(0.0, 30.0, 0.01), target=(0.0, 0.0, 0.0), fov_y=60.0)
    light = Light((0.0, 20.0, 0.0), (1.0, 1.0, 1.0))
    floor = Plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 0)
    roof = Mesh(np.array([[-3.0, 10.0, -3.0], [3.0, 10.0, -3.0], [0.0, 10.0, 4.0]]), [[0, 2, 1]])  # faces +y
    scene = scene_of([roof], planes=[floor], materials=[mat], lights=[light], camera=cam)
    w = h = 32
    res = render_reference(scene, settings(w, h, mode="color", max_recursion_depth=1))
    prim = render_reference(scene, settings(w, h, mode="primid")).primid
    img = res.image.reshape(h, w, 3)
    o, d = primary_rays(cam, w, h)
    floor_pix = prim.ravel() == 0
    t = -o[:, 1] / d[:, 1]
    q = o + t[:, None] * d
    # seen from the floor point the light is blocked iff the segment to it crosses the roof at y = 10
    s = (10.0 - q[:, 1]) / (20.0 - q[:, 1])
    x = q + s[:, None] * (np.array(light.position) - q)
    blocked, _ = inside_triangle(x, roof.corners[0])
    shadowed = floor_pix & blocked
    lit = floor_pix & ~inside_triangle(x, roof.corners[0])[1].min(axis=1).__ge__(-1e-3)
    assert shadowed.sum() > 10 and lit.sum() > 100
    np.testing.assert_allclose(img.reshape(-1, 3)[shadowed], 0.2, atol=1e-12)
    assert (img.reshape(-1, 3)[lit][:, 0] > 0.2 + 1e-3).all()
    # the roof itself is lit from above: its shadow ray starts exactly on it and ignores it
    roof_pix = prim.ravel() == 1
    assert roof_pix.sum() > 10 and (img.reshape(-1, 3)[roof_pix][:, 0] > 0.9).all()


def test_a_reflected_ray_leaves_its_triangle_and_sees_what_is_in_front():
    mirror_mat = Material(color=(0.0, 0.0, 0.0), ambient=0.0, diffuse=0.0, specular=0.0, reflective=1.0)
    red = Material(color=(1.0, 0.0, 0.0), ambient=1.0, diffuse=0.0, specular=0.0, reflective=0.0)
    mirror = Mesh(TRI * 3 + [0.0, 0.0, -2.0], [[0, 1, 2]])
    # a red sphere behind the camera: only the mirror shows it
    scene = scene_of([mirror], spheres=[((0.0, 0.0, 14.0), 3.0, 1)], materials=[mirror_mat, red])
    res = render_reference(scene, settings(16, 16, mode="color", max_recursion_depth=2))
    centre = res.image[8, 8]
    np.testing.assert_allclose(centre, [1.0, 0.0, 0.0])
    rec = render_reference(scene, settings(16, 16, mode="recursion", max_recursion_depth=2)).image[8, 8]
    np.testing.assert_array_equal(rec, RECURSION_COLORS[2])


def test_refraction_through_a_closed_box_enters_then_leaves_parallel():
    """A slab of glass (ior 1.5): the transmitted ray bends in at the front face (entering
    by the geometric normal), hits the back face from inside and leaves parallel to the
    primary ray — both refractions are right only if entering and leaving are told apart."""
    glass = Material(
        color=(1.0, 1.0, 1.0), ambient=0.0, diffuse=0.0, specular=0.0, reflective=0.0, transmissive=1.0, ior=1.5
    )
    slab = box((-10.0, -10.0, -1.0), (10.0, 10.0, 1.0), material=0)
    g = _Geometry.of(scene_of([slab], materials=[glass]))
    d0 = np.array([[0.3, -0.2, -1.0]])
    d0 /= np.linalg.norm(d0)
    batch = RayBatch(
        np.array([[0.0, 0.0, 10.0]]), d0, np.array([0]), np.ones((1, 3)), 1, np.array([-1]), np.array([False])
    )
    frame = _Frame.empty(1)
    inside = _trace_batch(g, batch, frame, 4, shade=False)
    assert inside is not None and len(inside) == 1
    # Snell at the front face z = 1: sin θt = sin θi / 1.5
    sin_i = math.hypot(d0[0, 0], d0[0, 1])
    sin_t = math.hypot(inside.dirs[0, 0], inside.dirs[0, 1])
    assert sin_t == pytest.approx(sin_i / 1.5, rel=1e-12) and inside.dirs[0, 2] < 0
    out = _trace_batch(g, inside, frame, 4, shade=False)
    assert out is not None and out.origins[0, 2] == pytest.approx(-1.0, abs=1e-12)
    np.testing.assert_allclose(out.dirs[0], d0[0], atol=1e-12)
    # and transmitted_directions honours an explicit entering flag (a smooth normal's side)
    n = np.array([[0.0, 0.0, 1.0]])
    a, _ = transmitted_directions(d0, n, np.array([1.5]), np.array([True]))
    b, _ = transmitted_directions(d0, n, np.array([1.5]))
    np.testing.assert_array_equal(a, b)
    c, _ = transmitted_directions(d0, n, np.array([1.5]), np.array([False]))
    assert not np.allclose(a, c)


def test_recursion_through_a_closed_glass_icosphere_counts_both_faces():
    glass = Material(
        color=(1.0, 1.0, 1.0), ambient=0.0, diffuse=0.0, specular=0.0, reflective=0.0, transmissive=0.9, ior=1.3
    )
    wall = Plane((0.0, 0.0, -30.0), (0.0, 0.0, 1.0), 0)
    scene = scene_of([icosphere(3, radius=4.0, material=0)], planes=[wall], materials=[glass])
    res = render_reference(scene, settings(16, 16, mode="recursion", max_recursion_depth=4))
    # the centre ray: sphere front (1), back from inside (2), the wall (3)
    np.testing.assert_array_equal(res.image[8, 8], RECURSION_COLORS[3])


def test_heat_counts_triangle_tests_like_sphere_tests():
    from renderer.accel.bih import build_for_scene
    from renderer.accel.bih_traverse import traverse

    scene = scene_of([icosphere(2, radius=3.0)], spheres=[((6.0, 0.0, 0.0), 1.0, 0)])
    n = scene.n_spheres + scene.n_triangles
    bf = render_reference(scene, settings(8, 8, mode="heat"))
    np.testing.assert_allclose(bf.image[..., 0], min(1.0, 0.05 * n))
    s = settings(24, 24, mode="heat", method="bih", max_prims=2)
    res = render_reference(scene, s)
    o, d = primary_rays(scene.camera, 24, 24)
    tr = traverse(
        build_for_scene(scene, 2, s.max_tree_depth),
        scene.sphere_centers,
        scene.sphere_radii,
        o,
        d,
        triangles=scene.triangle_corners,
    )
    np.testing.assert_allclose(res.image.reshape(-1, 3)[:, 0], np.minimum(0.05 * tr.tests, 1.0))
    assert tr.tests.max() > 0 and tr.tests.max() < n


def test_the_side_seen_is_the_geometric_one_even_when_the_normals_disagree():
    """Vertex normals towards +z on a triangle wound towards −z, seen from +z: the ray sees
    the back (geometric rule), Nf is the shading normal turned away (−z), and a light at
    +z adds nothing: ambient only. Deciding the side by the shading normal would light it."""
    mat = Material(color=(1.0, 1.0, 1.0), ambient=0.25, diffuse=0.75, specular=0.0, reflective=0.0)
    up = np.array([[0.0, 0.0, 1.0]] * 3)
    scene = scene_of([Mesh(TRI, [[0, 2, 1]], 0, up)], materials=[mat], lights=[Light((0.0, 0.0, 8.0))])
    img = render_reference(scene, settings(9, 9, mode="color", max_recursion_depth=1)).image
    np.testing.assert_allclose(img[4, 4], [0.25, 0.25, 0.25])
    # the normal mode still shows the (outward, smooth) shading normal
    np.testing.assert_allclose(render_reference(scene, settings(9, 9, mode="normal")).normal[4, 4], [0, 0, 1])


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

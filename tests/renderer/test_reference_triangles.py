"""The float64 reference tracer on triangles (docs/SHADING.md, "Triangles"): every output mode,
flat and smooth shading, both sides, exclusion of the source triangle, refraction through a
closed mesh. Expected values are computed here from the geometry, not with the tracer."""

from __future__ import annotations

import math

import numpy as np
import pytest

from renderer.meshes import box, icosphere
from renderer.modes import RECURSION_COLORS
from renderer.reference import (
    RayBatch,
    _Frame,
    _Geometry,
    _trace_batch,
    primary_rays,
    render_reference,
    trace_rays,
    transmitted_directions,
)
from renderer.scene import Camera, Light, Material, Mesh, Plane, Scene
from renderer.settings import RenderSettings

BLACK = Material(color=(0.0, 0.0, 0.0), ambient=0.0, diffuse=0.0, specular=0.0, reflective=0.0)
CAM = Camera(position=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=60.0)
# one big triangle in the plane z = 0 around the view axis, wound counter-clockwise seen from +z
TRI = np.array([[-8.0, -6.0, 0.0], [8.0, -6.0, 0.0], [0.0, 9.0, 0.0]])


def scene_of(meshes=(), spheres=(), planes=(), materials=(BLACK,), lights=(), camera=CAM) -> Scene:
    c = np.array([s[0] for s in spheres], dtype=np.float64).reshape(-1, 3)
    r = np.array([s[1] for s in spheres], dtype=np.float64)
    m = np.array([s[2] for s in spheres], dtype=np.int32)
    return Scene(camera, tuple(lights), tuple(materials), c, r, m, tuple(planes), tuple(meshes))


def settings(w: int, h: int, **kw) -> RenderSettings:
    kw.setdefault("method", "bruteforce")
    return RenderSettings(width=w, height=h, **kw)


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

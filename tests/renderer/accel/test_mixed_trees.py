"""The hierarchies over spheres and triangles together, on the CPU (issue #20).

Every method's ``prepare`` builds its tree over the scene's spheres then triangles
(renderer.accel.primitives); the trees are traversed on the CPU (renderer.accel.cpu_trace,
renderer.accel.bih_traverse) and must give the ids of brute force on ≥ 99.99 % of the
rays and of the float64 reference on ≥ 99.9 % of the pixels. For such a scene the GPU data
of every method holds the triangles (leaf-order slots decoding to the tree's order, the
triangle records; a method without ``meshes_on_gpu`` would be refused naming the methods
that trace meshes); a sphere scene packs as before, with no triangle binding.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderer.accel.base import NotOnGPU
from renderer.accel.bih_traverse import brute_force, traverse
from renderer.accel.cpu_trace import TreePrimitives, trace_tree, traverse_bvh, traverse_kdtree
from renderer.accel.primitives import scene_aabbs, scene_to_tree_ids, tree_to_scene_ids, triangle_aabbs
from renderer.meshes import icosphere, teapot, torus
from renderer.methods import METHODS
from renderer.reference import primary_rays, render_reference, trace_rays
from renderer.scenarios import mesh_scene, scenario
from renderer.scene import Camera, Mesh, SceneError
from renderer.settings import RenderSettings
from renderer.tree_update import TreeUpdate

TREE_METHODS = ("bih", "bvh", "kdtree", "twolevel", "bruteforce")
W, H = 100, 100  # 10,000 primary rays: 99.99 % allows one ray


def mixed_scene():
    """27 spheres, the floor plane, a teapot, two icospheres and two tori, some overlapping
    each other and the spheres, filling most of the view."""
    base = mesh_scene("mixed", detail=2)
    pot = teapot(4, size=4.0, material=0, transform=[[1, 0, 0, 0.0], [0, 1, 0, -20.0], [0, 0, 1, 0.0], [0, 0, 0, 1]])
    meshes = (
        pot,
        icosphere(2, radius=6.0, center=(-10.0, -4.0, 8.0), material=1),
        torus(6.0, 2.0, 24, 12, center=(9.0, -9.0, 6.0)),
        icosphere(1, radius=2.5, center=(12.0, 2.0, 12.0)),
        torus(3.0, 1.0, 16, 8, center=(0.0, 6.0, 6.0)),
    )
    cam = Camera((0.0, 2.0, 40.0), (0.0, -6.0, 0.0), (0.0, 1.0, 0.0), 62.0)
    return base.with_geometry(base.sphere_centers, base.sphere_radii, base.sphere_materials, meshes).with_camera(cam)


@pytest.fixture(scope="module")
def scene():
    return mixed_scene()


@pytest.fixture(scope="module")
def brute(scene):
    o, d = primary_rays(scene.camera, W, H)
    return o, d, trace_tree(None, scene, o, d)


@pytest.fixture(scope="module")
def reference_ids(scene):
    return render_reference(scene, RenderSettings(width=W, height=H, mode="primid")).primid.ravel()


def prepared(name, scene, **kw):
    update = TreeUpdate()
    if name == "twolevel":  # the first mesh and every third sphere "move": both trees hold both kinds
        moving = np.zeros(scene.n_spheres + scene.n_triangles, bool)
        moving[: scene.n_spheres : 3] = True
        r = scene.mesh_triangle_range(0)
        moving[scene.n_spheres + r.start : scene.n_spheres + r.stop] = True
        update = TreeUpdate(moving=moving)
    return METHODS[name].prepare(scene, kw.get("max_prims", 4), kw.get("max_tree_depth", 64), update=update)


@pytest.mark.parametrize("name", TREE_METHODS)
def test_primary_ids_through_each_tree_match_brute_force_and_the_reference(name, scene, brute, reference_ids):
    o, d, (t_bf, id_bf) = brute
    prep = prepared(name, scene)
    # brute force has no tree: trace_tree(None, …) is the brute fixture's own trace, made once
    t, ids = (t_bf, id_bf) if prep.tree is None else trace_tree(prep.tree, scene, o, d)
    # the view shows every kind of primitive, triangles on a good share of it
    assert (id_bf >= scene.triangle_id_base).sum() > 2000 and ((id_bf >= 0) & (id_bf < scene.n_spheres)).sum() > 500
    assert (id_bf == scene.n_spheres).sum() > 500 and (id_bf == -1).sum() > 100
    assert np.mean(ids == id_bf) >= 0.9999, f"{name}: {np.sum(ids != id_bf)} of {len(ids)} rays differ"
    np.testing.assert_array_equal(t[ids == id_bf], t_bf[ids == id_bf])
    assert np.mean(ids == reference_ids) >= 0.999, f"{name}: {np.sum(ids != reference_ids)} differ from the reference"
    # the statistics count the triangles; the GPU data holds them (the triangle records)
    assert prep.stats["triangles"] == scene.n_triangles
    assert METHODS[name].capabilities.meshes_on_gpu
    assert not isinstance(prep.packed, NotOnGPU)
    tex = prep.packed.textures
    tri = tex["u_triangles"].data.reshape(-1, 4)[: 3 * scene.n_triangles]
    corners = tri[:, :3].copy().view(np.float32).reshape(-1, 3, 3)
    np.testing.assert_array_equal(corners, scene.triangle_corners.astype(np.float32))
    assert prep.packed.uniforms["u_tri_base"] == scene.triangle_id_base
    if name == "bih":  # the leaf-order records decode to the tree's own order
        from renderer import gpu_layout
        from renderer.accel import bih_layout

        order, last = bih_layout.leaf_order(prep.tree)
        per = 1 if gpu_layout.equal_radii(scene) else 2
        rec = tex["u_bih_spheres"].data.reshape(-1, 4)[: per * len(order)]
        key = rec[:, 3] if per == 1 else rec[1::2, 0]
        is_tri = (key & np.uint32(gpu_layout.TRI_SLOT)) != 0
        np.testing.assert_array_equal(is_tri, order >= scene.n_spheres)
        index = np.where(
            is_tri,
            (key & np.uint32(gpu_layout.TRI_INDEX_MASK)).astype(np.int64) + scene.n_spheres,
            (key & np.uint32(gpu_layout.SPHERE_ID_MASK)).astype(np.int64),
        )
        np.testing.assert_array_equal(index, order)
        np.testing.assert_array_equal((key & np.uint32(gpu_layout.SPHERE_LAST)) != 0, last)


@pytest.fixture(scope="module")
def inside_rays(scene):
    """Rays from everywhere (inside the spheres and meshes too), in every direction, including
    axis-aligned ones (d = ±0 components), and their brute-force hits (made once for the methods)."""
    rng = np.random.default_rng(7)
    n = 6000
    o = rng.uniform(-22, 22, (n, 3))
    d = rng.normal(size=(n, 3))
    aim = scene.triangle_corners[rng.integers(0, scene.n_triangles, n // 2)].mean(axis=1)
    d[n // 2 :] = aim - o[n // 2 :]  # half of them towards a triangle
    d[:600, 1:] = 0.0
    d[600:1200, :2] = 0.0
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    prims = TreePrimitives.of(scene)
    t_bf, p_bf = brute_force(prims.centers, prims.radii, o, d, triangles=prims.corners)
    return o, d, prims, p_bf


@pytest.mark.parametrize("name", ["bih", "bvh", "kdtree"])
def test_rays_from_inside_the_scene_match_brute_force(name, scene, inside_rays):
    o, d, prims, p_bf = inside_rays
    tree = prepared(name, scene, max_prims=2).tree
    if name == "bih":
        res = traverse(tree, prims.centers, prims.radii, o, d, triangles=prims.corners)
        t, p = res.t, res.prim
    elif name == "bvh":
        t, p = traverse_bvh(tree, prims, o, d)
    else:
        t, p = traverse_kdtree(tree, prims, o, d)
    assert (p_bf >= scene.n_spheres).sum() > 1000
    assert np.mean(p == p_bf) >= 0.9999, f"{name}: {np.sum(p != p_bf)} differ"


def test_a_ray_leaving_a_triangle_ignores_it_in_the_traversal_and_in_the_reference(scene):
    c = scene.triangle_corners
    rng = np.random.default_rng(2)
    j = rng.choice(np.flatnonzero(~scene.triangle_degenerate), 500, replace=False)
    w = rng.dirichlet((1, 1, 1), len(j))
    p = np.einsum("ik,ikj->ij", w, c[j])
    n = np.cross(c[j, 1] - c[j, 0], c[j, 2] - c[j, 0])
    d = n / np.linalg.norm(n, axis=1, keepdims=True)  # straight off the surface, outwards
    ignore = scene.n_spheres + j
    res = traverse(
        METHODS["bih"].prepare(scene, 4, 64).tree,
        scene.sphere_centers,
        scene.sphere_radii,
        p,
        d,
        ignore=ignore,
        triangles=c,
    )
    assert not (res.prim == ignore).any()
    t_ref, id_ref = trace_rays(scene, p, d, src=scene.triangle_id_base + j)
    not_plane = id_ref != scene.n_spheres  # the plane (id n) is outside the BIH
    assert not_plane.sum() > 100
    np.testing.assert_array_equal(
        tree_to_scene_ids(res.prim, scene.n_spheres, len(scene.planes))[not_plane], id_ref[not_plane]
    )


def test_triangle_boxes_hold_the_triangle_in_both_precisions():
    rng = np.random.default_rng(0)
    c = rng.uniform(-1, 1, (500, 3, 3)) * 10.0 ** rng.integers(-3, 7, (500, 1, 1)) + rng.choice([0.0, 1e6], (500, 1, 1))
    lo, hi = triangle_aabbs(c)
    assert lo.dtype == hi.dtype == np.float32
    for corners in (c, c.astype(np.float32).astype(np.float64)):
        assert (lo[:, None, :] <= corners).all() and (corners <= hi[:, None, :]).all()
    assert (lo < c.min(axis=1)).all() and (hi > c.max(axis=1)).all()  # strictly: rounded outwards


def test_the_tree_index_space_is_spheres_then_triangles_and_maps_to_scene_ids(scene):
    lo, hi = scene_aabbs(scene)
    assert len(lo) == scene.n_spheres + scene.n_triangles
    tree_ids = np.array([-1, 0, scene.n_spheres - 1, scene.n_spheres, scene.n_spheres + 5])
    ids = tree_to_scene_ids(tree_ids, scene.n_spheres, len(scene.planes))
    np.testing.assert_array_equal(ids, [-1, 0, scene.n_spheres - 1, scene.triangle_id_base, scene.triangle_id_base + 5])
    np.testing.assert_array_equal(scene_to_tree_ids(ids, scene.n_spheres, len(scene.planes)), tree_ids)
    assert scene_to_tree_ids(np.array([scene.n_spheres]), scene.n_spheres, 1)[0] == -1  # a plane


def test_a_method_whose_layout_packs_spheres_only_would_refuse_meshes(scene):
    """NotOnGPU (no method needs it since every layout holds triangles): reading it raises
    SceneError("meshes") naming the method and the methods that trace meshes."""
    from renderer.accel.base import MESH_METHODS, gpu_data

    packed = gpu_data(scene, lambda: None, meshes_on_gpu=False, method="newtree")
    assert isinstance(packed, NotOnGPU)
    with pytest.raises(SceneError) as e:
        _ = packed.textures
    assert e.value.field == "meshes" and "'newtree'" in e.value.message
    assert ", ".join(MESH_METHODS) in e.value.message and f"{scene.n_triangles:,} triangles" in e.value.message
    assert gpu_data(scenario(2, 8), lambda: "packed", meshes_on_gpu=False) == "packed"  # spheres only: packed


@pytest.mark.parametrize("name", TREE_METHODS)
def test_a_sphere_scene_still_packs_its_gpu_data(name):
    s = scenario(2, 200, seed=3)
    prep = METHODS[name].prepare(s, 4, 64)
    assert not isinstance(prep.packed, NotOnGPU) and isinstance(prep.packed.textures, dict)
    assert "triangles" not in prep.stats
    assert not {"u_triangles", "u_tri_normals", "u_tri_base"} & (set(prep.packed.textures) | set(prep.packed.uniforms))


def test_a_mask_of_the_wrong_length_is_refused_by_twolevel(scene):
    with pytest.raises(ValueError, match="triangles"):
        METHODS["twolevel"].prepare(scene, 4, 64, update=TreeUpdate(moving=np.zeros(scene.n_spheres, bool)))


def test_degenerate_triangles_sit_in_the_trees_but_are_never_hit():
    flat = Mesh(np.array([[-5.0, 0, 0], [0, 0, 0], [5.0, 0, 0]]), [[0, 1, 2]] * 3)
    s = scenario(1, 8).with_geometry(np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32), [flat])
    o = np.array([[0.0, 5.0, 0.0], [1.0, 5.0, 0.0]])
    d = np.array([[0.0, -1.0, 0.0], [0.0, -1.0, 0.0]])
    for name in ("bih", "bvh", "kdtree"):
        t, ids = trace_tree(prepared(name, s).tree, s, o, d)
        np.testing.assert_array_equal(ids, [0, 0])  # the floor plane (id 0), through the segment


def test_prepare_frame_refuses_the_ray_engines_on_a_scene_with_meshes_and_resolves_auto_with_triangles(scene):
    from renderer.prepare import prepare_frame

    for name in ("rayengine", "hre"):
        assert "triangles" not in METHODS[name].capabilities.primitives
        with pytest.raises(SceneError) as e:
            prepare_frame(scene, RenderSettings(width=8, height=8, method=name))
        assert e.value.field == "method" and "spheres and planes only" in e.value.message
    few_spheres = scene.with_geometry(np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32))
    frame = prepare_frame(few_spheres, RenderSettings(width=8, height=8, method="auto"))
    assert frame.method == "bih"  # thousands of triangles: past the brute-force crossover
    assert frame.cost.ms > 0 and frame.stats["triangles"] == scene.n_triangles

"""The CPU traversals of the trees over spheres and triangles together (renderer.accel.cpu_trace).

The hierarchies over spheres and triangles together, on the CPU.

Every method's ``prepare`` builds its tree over the scene's spheres then triangles
(renderer.accel.primitives); the trees are traversed on the CPU (renderer.accel.cpu_trace,
renderer.accel.bih_traverse) and must give the ids of brute force on ≥ 99.99 % of the
rays and of the float64 reference on ≥ 99.9 % of the pixels. For such a scene the GPU data
of every method holds the triangles (leaf-order slots decoding to the tree's order, the
triangle records); a sphere scene packs as before, with no triangle binding.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderer.accel.bih_traverse import brute_force, traverse
from renderer.accel.cpu_trace import TreePrimitives, trace_tree, traverse_bvh, traverse_kdtree
from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Mesh
from renderer.oracle.reference import primary_rays, render_reference
from renderer.scenes.scenarios import scenario
from renderer.scenes.tree_update import TreeUpdate

TREE_METHODS = ("bih", "bvh", "kdtree", "twolevel", "bruteforce")
W, H = 100, 100  # 10,000 primary rays: 99.99 % allows one ray


@pytest.fixture(scope="module")
def brute(mixed_trees_scene):
    o, d = primary_rays(mixed_trees_scene.camera, W, H)
    return o, d, trace_tree(None, mixed_trees_scene, o, d)


@pytest.fixture(scope="module")
def reference_ids(mixed_trees_scene):
    return render_reference(mixed_trees_scene, RenderSettings(width=W, height=H, mode="primid")).primid.ravel()


def prepared(name, mixed_trees_scene, **kw):
    update = TreeUpdate()
    if name == "twolevel":  # the first mesh and every third sphere "move": both trees hold both kinds
        moving = np.zeros(mixed_trees_scene.n_spheres + mixed_trees_scene.n_triangles, bool)
        moving[: mixed_trees_scene.n_spheres : 3] = True
        r = mixed_trees_scene.mesh_triangle_range(0)
        moving[mixed_trees_scene.n_spheres + r.start : mixed_trees_scene.n_spheres + r.stop] = True
        update = TreeUpdate(moving=moving)
    return METHODS[name].prepare(mixed_trees_scene, kw.get("max_prims", 4), kw.get("max_tree_depth", 64), update=update)


@pytest.mark.parametrize("name", TREE_METHODS)
def test_primary_ids_through_each_tree_match_brute_force_and_the_reference(
    name, mixed_trees_scene, brute, reference_ids
):
    o, d, (t_bf, id_bf) = brute
    prep = prepared(name, mixed_trees_scene)
    # brute force has no tree: trace_tree(None, …) is the brute fixture's own trace, made once
    t, ids = (t_bf, id_bf) if prep.tree is None else trace_tree(prep.tree, mixed_trees_scene, o, d)
    # the view shows every kind of primitive, triangles on a good share of it
    assert (id_bf >= mixed_trees_scene.triangle_id_base).sum() > 2000 and (
        (id_bf >= 0) & (id_bf < mixed_trees_scene.n_spheres)
    ).sum() > 500
    assert (id_bf == mixed_trees_scene.n_spheres).sum() > 500 and (id_bf == -1).sum() > 100
    assert np.mean(ids == id_bf) >= 0.9999, f"{name}: {np.sum(ids != id_bf)} of {len(ids)} rays differ"
    np.testing.assert_array_equal(t[ids == id_bf], t_bf[ids == id_bf])
    assert np.mean(ids == reference_ids) >= 0.999, f"{name}: {np.sum(ids != reference_ids)} differ from the reference"
    # the statistics count the triangles; the GPU data holds them (the triangle records)
    assert prep.stats["triangles"] == mixed_trees_scene.n_triangles
    assert METHODS[name].capabilities.meshes_on_gpu
    tex = prep.packed.textures
    tri = tex["u_triangles"].data.reshape(-1, 4)[: 3 * mixed_trees_scene.n_triangles]
    corners = tri[:, :3].copy().view(np.float32).reshape(-1, 3, 3)
    np.testing.assert_array_equal(corners, mixed_trees_scene.triangle_corners.astype(np.float32))
    assert prep.packed.uniforms["u_tri_base"] == mixed_trees_scene.triangle_id_base
    if name == "bih":  # the leaf-order records decode to the tree's own order
        from renderer.accel import bih_layout
        from renderer.gpu import gpu_layout

        order, last = bih_layout.leaf_order(prep.tree)
        per = 1 if gpu_layout.equal_radii(mixed_trees_scene) else 2
        rec = tex["u_bih_spheres"].data.reshape(-1, 4)[: per * len(order)]
        key = rec[:, 3] if per == 1 else rec[1::2, 0]
        is_tri = (key & np.uint32(gpu_layout.TRI_SLOT)) != 0
        np.testing.assert_array_equal(is_tri, order >= mixed_trees_scene.n_spheres)
        index = np.where(
            is_tri,
            (key & np.uint32(gpu_layout.TRI_INDEX_MASK)).astype(np.int64) + mixed_trees_scene.n_spheres,
            (key & np.uint32(gpu_layout.SPHERE_ID_MASK)).astype(np.int64),
        )
        np.testing.assert_array_equal(index, order)
        np.testing.assert_array_equal((key & np.uint32(gpu_layout.SPHERE_LAST)) != 0, last)


@pytest.fixture(scope="module")
def inside_rays(mixed_trees_scene):
    """Rays from everywhere (inside the spheres and meshes too), in every direction, including
    axis-aligned ones (d = ±0 components), and their brute-force hits (made once for the methods)."""
    rng = np.random.default_rng(7)
    n = 6000
    o = rng.uniform(-22, 22, (n, 3))
    d = rng.normal(size=(n, 3))
    aim = mixed_trees_scene.triangle_corners[rng.integers(0, mixed_trees_scene.n_triangles, n // 2)].mean(axis=1)
    d[n // 2 :] = aim - o[n // 2 :]  # half of them towards a triangle
    d[:600, 1:] = 0.0
    d[600:1200, :2] = 0.0
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    prims = TreePrimitives.of(mixed_trees_scene)
    t_bf, p_bf = brute_force(prims.centers, prims.radii, o, d, triangles=prims.corners)
    return o, d, prims, p_bf


@pytest.mark.parametrize("name", ["bih", "bvh", "kdtree"])
def test_rays_from_inside_the_scene_match_brute_force(name, mixed_trees_scene, inside_rays):
    o, d, prims, p_bf = inside_rays
    tree = prepared(name, mixed_trees_scene, max_prims=2).tree
    if name == "bih":
        res = traverse(tree, prims.centers, prims.radii, o, d, triangles=prims.corners)
        t, p = res.t, res.prim
    elif name == "bvh":
        t, p = traverse_bvh(tree, prims, o, d)
    else:
        t, p = traverse_kdtree(tree, prims, o, d)
    assert (p_bf >= mixed_trees_scene.n_spheres).sum() > 1000
    assert np.mean(p == p_bf) >= 0.9999, f"{name}: {np.sum(p != p_bf)} differ"


def test_degenerate_triangles_sit_in_the_trees_but_are_never_hit():
    flat = Mesh(np.array([[-5.0, 0, 0], [0, 0, 0], [5.0, 0, 0]]), [[0, 1, 2]] * 3)
    s = scenario(1, 8).with_geometry(np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32), [flat])
    o = np.array([[0.0, 5.0, 0.0], [1.0, 5.0, 0.0]])
    d = np.array([[0.0, -1.0, 0.0], [0.0, -1.0, 0.0]])
    for name in ("bih", "bvh", "kdtree"):
        t, ids = trace_tree(prepared(name, s).tree, s, o, d)
        np.testing.assert_array_equal(ids, [0, 0])  # the floor plane (id 0), through the segment


@pytest.mark.parametrize("name", TREE_METHODS)
def test_trees_over_analytic_shapes_trace_as_the_reference(name, every_shape_scene):
    """Every kind of shape in the trees (after the spheres, tree ids as scene ids), the CPU
    traversals on them against the float64 reference's ids; the leaf slots decode to shapes."""
    scene = every_shape_scene
    o, d = primary_rays(scene.camera, 64, 48)
    ref = render_reference(scene, RenderSettings(width=64, height=48, mode="primid")).primid.ravel()
    prep = METHODS[name].prepare(scene, 2, 64)
    t, ids = trace_tree(prep.tree, scene, o, d)
    assert set(range(scene.shape_id_base, scene.shape_id_base + scene.n_shapes)) <= set(ids.tolist())
    assert np.mean(ids == ref) >= 0.9999, f"{name}: {np.sum(ids != ref)} differ"
    assert prep.packed.uniforms["u_shape_base"] == scene.shape_id_base
    rec = prep.packed.textures["u_shapes"].data.reshape(-1, 4)[: 3 * scene.n_shapes].reshape(-1, 3, 4)
    np.testing.assert_array_equal(
        rec[:, :, :4].copy().view(np.float32).reshape(-1, 12)[:, :11], scene.shapes.params.astype(np.float32)[:, :11]
    )
    np.testing.assert_array_equal(rec[:, 2, 3], scene.shapes.material)
    if name == "bih":
        from renderer.accel import bih_layout
        from renderer.gpu import gpu_layout

        order, _ = bih_layout.leaf_order(prep.tree)
        key = prep.packed.textures["u_bih_spheres"].data.reshape(-1, 4)[: len(order) * 2][1::2, 0]  # radii differ
        is_shape = (key & np.uint32(gpu_layout.SHAPE_SLOT)) != 0
        np.testing.assert_array_equal(is_shape, order >= scene.n_spheres)
        np.testing.assert_array_equal(
            (key[is_shape] & np.uint32(gpu_layout.SHAPE_INDEX_MASK)).astype(np.int64), order[is_shape] - scene.n_spheres
        )


def test_rays_leaving_a_shape_on_the_cpu_drop_only_its_root_at_the_origin(every_shape_scene):
    """From points on the torus and the open cylinder, inwards and outwards: brute force with
    ``ignore`` = the shape left finds what the reference's nearest_hit finds."""
    from renderer.oracle.reference import trace_rays

    scene = every_shape_scene
    o, d = primary_rays(scene.camera, 48, 36)
    t0, p0 = trace_rays(scene, o, d)
    on = np.flatnonzero(p0 >= scene.shape_id_base)
    assert len(on) > 100
    x = o[on] + t0[on, None] * d[on]
    rng = np.random.default_rng(3)
    nd = rng.normal(size=(len(on), 3))
    nd /= np.linalg.norm(nd, axis=1, keepdims=True)
    src = p0[on]
    t_ref, p_ref = trace_rays(scene, x, nd, src)
    prims = TreePrimitives.of(scene)
    tree_src = src - len(scene.planes)  # (shapes: tree index = scene id − planes)
    t, p = brute_force(prims.centers, prims.radii, x, nd, ignore=tree_src, shapes=prims.shapes)
    ids = np.where(p >= scene.n_spheres, p + len(scene.planes), p)
    planes_hit = (p_ref >= scene.n_spheres) & (p_ref < scene.shape_id_base)
    assert np.mean((ids == p_ref)[~planes_hit]) >= 0.999
    assert (ids == src).sum() > 10  # some rays meet the shape they leave again

"""Preparing a frame (renderer.frame.prepare): the method resolved and its data built, or the frame refused."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.geometry.scene import SceneError


def test_prepare_frame_refuses_the_ray_engines_on_a_scene_with_meshes_and_resolves_auto_with_triangles(
    mixed_trees_scene,
):
    from renderer.frame.prepare import prepare_frame

    for name in ("rayengine", "hre"):
        assert "triangles" not in METHODS[name].capabilities.primitives
        with pytest.raises(SceneError) as e:
            prepare_frame(mixed_trees_scene, RenderSettings(width=8, height=8, method=name))
        assert e.value.field == "method" and "spheres and planes only" in e.value.message
    few_spheres = mixed_trees_scene.with_geometry(np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32))
    frame = prepare_frame(few_spheres, RenderSettings(width=8, height=8, method="auto"))
    assert frame.method == "bih"  # thousands of triangles: past the brute-force crossover
    assert frame.cost.ms > 0 and frame.stats["triangles"] == mixed_trees_scene.n_triangles


# ---- frames costed by what they will really do ------------------------------------------------
def coincident_spheres(n: int):
    """``n`` spheres at one place, each covering the whole frame of scenario 1's camera (every pixel
    meets all of them): the overdraw of every rasterised quad, one leaf of n on every ray."""
    import dataclasses

    from renderer.scenes.scenarios import scenario

    base = scenario(1, 1)
    cam = base.camera
    dist = float(np.linalg.norm(np.subtract(cam.target, cam.position)))
    return dataclasses.replace(
        base,
        sphere_centers=np.tile(np.asarray(cam.target, dtype=np.float64), (n, 1)),
        sphere_radii=np.full(n, 0.9 * dist),
        sphere_materials=np.zeros(n, np.int32),
        planes=(),
    )


def max_frame_cost() -> float:
    from server.config import ServerConfig

    return float(ServerConfig.model_fields["max_frame_cost"].default)


@pytest.fixture(scope="module", params=[20_000, 100_000])
def coincident(request):
    return coincident_spheres(request.param)


@pytest.mark.parametrize("how", ["raster", "tiles", "auto", "trace"])
def test_coincident_spheres_over_the_frame_are_refused_up_front(coincident, how):
    """Spheres that all cover the same pixels: each pixel tests every one, whether its first hits are
    rasterised (every quad's fragments), listed per tile or traced (one leaf of all of them on every
    ray) — estimated over the default cap, so the service refuses the frame before any GL work."""
    from renderer.frame.prepare import prepare_frame

    st = RenderSettings(width=1024, height=1024, mode="depth", first_hits=how)
    frame = prepare_frame(coincident, st)
    assert frame.cost.tests_per_ray >= 0.5 * coincident.n_spheres
    assert frame.cost.bound_ms > max_frame_cost(), frame.cost


def test_a_rasterised_frame_is_costed_by_its_quads_and_auto_by_the_cheapest():
    """first_hits=raster is costed by its fragments and tiles by their pairs; auto picks the cheaper
    of those and the traversal, and its estimate is that choice's."""
    from renderer.frame import first_hits as fh
    from renderer.frame.prepare import prepare_frame

    scene = coincident_spheres(500)
    st = RenderSettings(width=256, height=256, mode="depth")
    costs = {how: prepare_frame(scene, st.with_(first_hits=how)).cost.ms for how in ("raster", "tiles", "trace")}
    quads = fh.instances(scene, (256, 256), (256, 256))
    assert fh.covered_fragments(quads, (256, 256)) >= 0.9 * 500 * 256 * 256  # every quad the whole frame
    assert costs["raster"] > costs["trace"] > 0
    auto = prepare_frame(scene, st.with_(first_hits="auto")).cost.ms
    assert auto == min(costs.values())


def test_the_tree_counts_the_tests_of_coincident_spheres():
    """A BIH leaf's tests are counted over the region its clip planes bound: spheres at one point
    (which shrink the build's box to nothing) are n tests for every ray through the root, as the CPU
    traversal counts them."""
    from renderer.accel.bih import build_for_scene
    from renderer.accel.bih_traverse import traverse
    from renderer.oracle.reference import primary_rays

    scene = coincident_spheres(300)
    bih = build_for_scene(scene, 8, 64)
    o, d = primary_rays(scene.camera, 16, 16)
    counted = np.asarray(traverse(bih, scene.sphere_centers, scene.sphere_radii, o, d).tests).mean()
    assert counted == pytest.approx(300, rel=0.01)
    assert 0.5 * counted <= bih.stats.sah_tests <= 2.0 * counted


def rays_through_box(scene, width: int, height: int):
    """The primary rays of a grid that enter the primitives' bounding box (what the tree's
    statistics are per ray of)."""
    from renderer.accel.primitives import scene_aabbs
    from renderer.oracle.reference import primary_rays

    lo, hi = scene_aabbs(scene)
    lo, hi = lo.min(axis=0).astype(np.float64), hi.max(axis=0).astype(np.float64)
    o, d = primary_rays(scene.camera, width, height)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - o) / d, (hi - o) / d
    near = np.nanmax(np.minimum(t0, t1), axis=1)
    far = np.nanmin(np.maximum(t0, t1), axis=1)
    inside = far >= np.maximum(near, 0.0)
    return o[inside], d[inside]


@pytest.mark.parametrize("kind", ["room", "mixed"])
def test_the_model_inputs_of_the_demo_meshes_match_cpu_counts(kind):
    """The cost model's inputs for the demo mesh scenes against counts on the CPU: the tests and node
    visits a ray through the box makes (the BIH's statistics against its traversal on the rays of a
    grid), and the radiance rays a pixel's tree traces (the estimate's ray tree against the reference
    tracer's on a finer grid than the one sampled) — each within 2×."""
    from renderer.accel.bih_traverse import traverse
    from renderer.frame.prepare import prepare_frame
    from renderer.frame.profiles import STILL
    from renderer.oracle.reference import ray_tree_counts
    from renderer.scenes.scenarios import mesh_scene

    scene = mesh_scene(kind)
    st = RenderSettings(width=640, height=1088, **{k: v for k, v in STILL.items() if k != "resolution_scale"})
    frame = prepare_frame(scene, st)
    tree = frame.prepared.tree
    o, d = rays_through_box(scene, 48, 82)
    res = traverse(tree, scene.sphere_centers, scene.sphere_radii, o, d, triangles=scene.triangle_corners)
    tests, nodes = np.asarray(res.tests).mean(), np.asarray(res.nodes_visited).mean()
    assert 0.5 * tests <= frame.stats["sah_tests"] <= 2.0 * tests, (frame.stats["sah_tests"], tests)
    assert 0.5 * nodes <= frame.stats["sah_nodes"] <= 2.0 * nodes, (frame.stats["sah_nodes"], nodes)
    counted = sum(ray_tree_counts(scene, 64, 109, st.max_recursion_depth, st.min_weight)) / (64 * 109)
    radiance = frame.cost.rays_per_pixel / (1 + len(scene.lights))
    assert 0.5 * counted <= radiance <= 2.0 * counted, (radiance, counted)


@pytest.mark.parametrize("kind", ["room", "mixed"])
@pytest.mark.parametrize("profile", ["interactive", "still"])
def test_the_demo_meshes_are_admitted_at_the_phone_default_size(kind, profile):
    """The client's full frame (client_web/js/settings.js fitResolution: 640 × 1088 by default) of the
    demo mesh scenes with either profile, as the client asks for them, is under the default cap."""
    from renderer.frame.prepare import prepare_frame
    from renderer.frame.profiles import PROFILES
    from renderer.scenes.scenarios import mesh_scene

    p = {k: v for k, v in PROFILES[profile].items() if k != "resolution_scale"}
    frame = prepare_frame(mesh_scene(kind), RenderSettings(width=640, height=1088, **p))
    assert frame.cost.bound_ms <= max_frame_cost(), frame.cost


@pytest.mark.parametrize("kind", ["spheres", "room"])
def test_a_demo_scenes_sampled_ray_tree_counts_the_rays_a_dense_count_finds(kind):
    """The cost's ray tree of a demo scene framed for a phone (503 × 1088, Whitted) comes from the
    reference tracer's count on a coarse grid, spheres-only scenes included: within 2× of the rays a
    grid 16 times as dense counts (the materials' tree, every ray branching, says 21.9 rays a pixel
    for the spheres where the dense count finds about 5: enough to refuse the default scene on a phone)."""
    from renderer.frame.prepare import sampled_level_rays
    from renderer.oracle.reference import ray_tree_counts
    from renderer.scenes.scenarios import framed, mesh_scene

    settings = RenderSettings(width=503, height=1088)
    scene = framed(mesh_scene(kind), 503 / 1088)
    coarse = sampled_level_rays(scene, settings)
    assert coarse is not None
    sw, sh = 44, 96
    dense = sum(ray_tree_counts(scene, sw, sh, settings.max_recursion_depth, settings.min_weight)) / (sw * sh)
    assert 0.5 <= sum(coarse) / dense <= 2.0, (coarse, dense)


def test_a_drags_next_view_reuses_the_ray_tree_counted_for_a_near_one(monkeypatch):
    """A drag's frames see the scene from nearly the same place: the count of the last view stands in
    within RAY_TREE_REUSE_DEG and RAY_TREE_REUSE_MOVE, and a view beyond them is counted afresh."""
    from renderer.frame import prepare
    from renderer.geometry.scene import Camera
    from renderer.scenes.scenarios import mesh_scene

    calls = []
    counts = prepare.ray_tree_counts
    monkeypatch.setattr(prepare, "ray_tree_counts", lambda *a: calls.append(1) or counts(*a))
    scene = mesh_scene("room")
    cam = scene.camera
    settings = RenderSettings(width=64, height=48)

    def turned(deg: float) -> Camera:
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        d = np.subtract(cam.target, cam.position)
        target = cam.position + np.array([c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]])
        return Camera(cam.position, tuple(target), cam.up, cam.fov_y)

    first = prepare.sampled_level_rays(scene.with_camera(turned(0.0)), settings)
    again = prepare.sampled_level_rays(scene.with_camera(turned(2.0)), settings)
    assert len(calls) == 1 and again == first
    prepare.sampled_level_rays(scene.with_camera(turned(30.0)), settings)
    assert len(calls) == 2

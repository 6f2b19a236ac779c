"""A frame's plan (renderer.frame.plan): auto resolved on the tree's primitives, the method checked, the
one-pass variant's features chosen — one function every reader of a plan calls."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.config.methods import AUTO_CROSSOVER_N
from renderer.config.settings import RenderSettings
from renderer.frame.plan import plan_frame, plan_method
from renderer.geometry.scene import SceneError
from renderer.scenes.scenarios import mesh_scene, scenario

SMALL = dict(width=8, height=8)


def test_the_tree_primitives_are_spheres_triangles_and_shapes():
    teapot, table, cornell = (mesh_scene(k, 0) for k in ("teapot", "table", "cornell"))
    assert (teapot.n_spheres, teapot.n_shapes, teapot.n_tree_primitives) == (0, 0, teapot.n_triangles)
    assert (table.n_spheres, table.n_triangles, table.n_tree_primitives) == (0, 0, table.n_shapes)
    assert cornell.n_tree_primitives == cornell.n_spheres + cornell.n_triangles > cornell.n_spheres > 0


def test_auto_chooses_by_every_tree_primitive_not_the_spheres_alone():
    auto = RenderSettings(**SMALL, method="auto")
    teapot = mesh_scene("teapot", 0)  # no sphere, hundreds of triangles
    assert teapot.n_spheres == 0 and teapot.n_tree_primitives >= AUTO_CROSSOVER_N
    assert plan_method(auto, teapot.n_tree_primitives) == "bih"
    assert plan_frame(teapot, auto).method == "bih"
    assert plan_method(auto, AUTO_CROSSOVER_N - 1) == "bruteforce"
    few = scenario(1, 8)  # 8 spheres: brute force, unless the count given is the animation's at rest
    assert plan_frame(few, auto).method == "bruteforce"
    assert plan_frame(few, auto, tree_primitives=AUTO_CROSSOVER_N).method == "bih"
    assert plan_method(RenderSettings(**SMALL, method="kdtree"), 1) == "kdtree"


def test_the_plan_names_the_variant_a_frame_of_its_settings_compiles():
    cornell = mesh_scene("cornell", 0)
    whitted = plan_frame(cornell, RenderSettings(**SMALL, method="bih"))
    assert not whitted.multi_pass and "PATH" not in whitted.defines and "TRIANGLES" in whitted.defines
    path = RenderSettings(**SMALL, method="bih", integrator="path", max_recursion_depth=12, samples_per_pixel=3)
    plain = plan_frame(cornell, path.with_(denoise="off"))
    guided = plan_frame(cornell, path.with_(denoise="atrous"))
    assert "PATH" in plain.defines and "GUIDES" not in plain.defines and "GUIDES" in guided.defines
    assert plain.recursion_depth == 12  # a path's segments, not Whitted's levels
    v = guided.variant(image_only=False)
    assert (v.method, v.mode, v.depth, v.features, v.blocks) == ("bih", "color", 12, guided.defines, ())


def test_a_ray_engine_is_planned_without_a_variant_and_refused_for_meshes():
    spheres = plan_frame(scenario(1, 8), RenderSettings(**SMALL, method="rayengine"))
    assert spheres.multi_pass and spheres.features is None and spheres.defines == ()
    with pytest.raises(ValueError, match="passes of its own"):
        spheres.variant()
    with pytest.raises(SceneError) as e:
        plan_frame(mesh_scene("teapot", 0), RenderSettings(**SMALL, method="hre"))
    assert e.value.field == "method"


def test_brute_force_past_its_loop_is_refused_by_the_plan():
    from renderer.limits import MAX_LOOP_PRIMITIVES

    big = scenario(1, 8).with_geometry(
        np.zeros((MAX_LOOP_PRIMITIVES + 1, 3)),
        np.ones(MAX_LOOP_PRIMITIVES + 1),
        np.zeros(MAX_LOOP_PRIMITIVES + 1, np.int32),
    )
    with pytest.raises(SceneError) as e:
        plan_frame(big, RenderSettings(**SMALL, method="bruteforce"))
    assert e.value.field == "method" and "at most" in e.value.message

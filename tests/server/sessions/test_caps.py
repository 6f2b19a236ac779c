"""The caps that need no build (server/sessions/caps.py): POCKETRAY_MAX_WORK counts a Whitted frame's
ray-tree levels and a path frame's expected segments (renderer/cost.py, ``request_work``)."""

from __future__ import annotations

import pytest

from renderer.cost import path_segments
from renderer.settings import RenderSettings
from server.config import ServerConfig
from server.faults import InputError
from server.sessions.caps import InputCaps


@pytest.fixture(scope="module")
def caps(tmp_path_factory):
    return InputCaps(ServerConfig(sqlite_path=tmp_path_factory.mktemp("caps") / "s.db"))


def path(w: int, h: int, spp: int, depth: int) -> RenderSettings:
    return RenderSettings(width=w, height=h, integrator="path", samples_per_pixel=spp, max_recursion_depth=depth)


@pytest.mark.parametrize("depth", [8, 16])
def test_a_phone_sized_path_frame_is_admitted_at_any_depth(caps, depth):
    # 360 × 640 at 24 spp: width × height × depth × spp (the Whitted count) is over the default cap at depth 8
    # (44 M > 37.9 M) and twice that at 16; a path's expected segments saturate with depth.
    st = path(360, 640, 24, depth)
    assert 360 * 640 * depth * 24 > caps.config.max_work
    caps.check_work(st, 1)


def test_a_runaway_path_request_is_refused_naming_samples_per_pixel(caps):
    with pytest.raises(InputError) as e:
        caps.check_work(path(1088, 1088, 4096, 16), 1)
    assert e.value.loc == ("samples_per_pixel",)
    assert "POCKETRAY_MAX_WORK" in e.value.message and f"{path_segments(16):.2f}" in e.value.message
    # … and the limit sits where the expected segments reach the cap.
    spp = int(caps.config.max_work // (200 * 200 * path_segments(8)))
    caps.check_work(path(200, 200, spp, 8), 1)
    with pytest.raises(InputError):
        caps.check_work(path(200, 200, spp + 1, 8), 1)


def test_whitted_frames_keep_the_levels_count(caps):
    caps.check_work(RenderSettings(width=1088, height=1088, max_recursion_depth=8, samples_per_pixel=4), 1)
    with pytest.raises(InputError) as e:
        caps.check_work(RenderSettings(width=1088, height=1088, max_recursion_depth=8, samples_per_pixel=9), 1)
    assert e.value.loc == ("width",)


def test_the_caps_resolve_auto_on_the_tree_primitives_of_the_stored_scene(caps):
    """The method the caps check is the one the frames use: ``auto`` over the spheres, triangles and
    shapes a session's scene_info counts (a scene of meshes alone has no sphere, and hundreds of tree
    primitives)."""
    from renderer.methods import AUTO_CROSSOVER_N
    from renderer.scenarios import mesh_scene
    from server.sessions.scenes import scene_info, tree_primitives

    auto = RenderSettings(width=8, height=8, method="auto")
    teapot, table = scene_info(mesh_scene("teapot", 0)), scene_info(mesh_scene("table", 0))
    assert teapot["n_spheres"] == 0 and tree_primitives(teapot) == teapot["n_triangles"] >= AUTO_CROSSOVER_N
    assert caps.check_work(auto, tree_primitives(teapot)) == "bih"
    assert tree_primitives(table) == table["n_shapes"] < AUTO_CROSSOVER_N
    assert caps.check_work(auto, tree_primitives(table)) == "bruteforce"
    assert caps.check_work(auto.with_(method="bvh"), 1) == "bvh"

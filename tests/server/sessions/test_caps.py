"""The caps that need no build (server/sessions/caps.py): POCKETRAY_MAX_WORK counts a Whitted frame's
ray-tree levels and a path frame's expected segments (renderer/frame/cost.py, ``request_work``)."""

from __future__ import annotations

import pytest

from renderer.config.settings import RenderSettings
from renderer.frame.cost import path_segments
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
    from renderer.config.methods import AUTO_CROSSOVER_N
    from renderer.scenes.scenarios import mesh_scene
    from server.sessions.scenes import scene_info, tree_primitives

    auto = RenderSettings(width=8, height=8, method="auto")
    teapot, table = scene_info(mesh_scene("teapot", 0)), scene_info(mesh_scene("table", 0))
    assert teapot["n_spheres"] == 0 and tree_primitives(teapot) == teapot["n_triangles"] >= AUTO_CROSSOVER_N
    assert caps.check_work(auto, tree_primitives(teapot)) == "bih"
    assert tree_primitives(table) == table["n_shapes"] < AUTO_CROSSOVER_N
    assert caps.check_work(auto, tree_primitives(table)) == "bruteforce"
    assert caps.check_work(auto.with_(method="bvh"), 1) == "bvh"


def _textured(sides: list[int]):
    import numpy as np

    from renderer.geometry.scene import Camera, Scene, make_mesh
    from renderer.materials.pbr import PbrMaterial
    from renderer.materials.texture import Texture

    quad = make_mesh([[0, 0, 0], [1, 0, 0], [0, 0, 1]], [[0, 2, 1]], uvs=[[0, 0], [1, 0], [0, 1]])
    return Scene(
        Camera((0.0, 2.0, 0.01), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0),
        (),
        (PbrMaterial(base_color_texture=0),),
        np.zeros((0, 3)),
        np.zeros(0),
        np.zeros(0, np.int32),
        meshes=(quad,),
        textures=tuple(Texture(np.zeros((s, s, 4), np.uint8)) for s in sides),
    )


def test_a_scene_over_the_session_texture_budget_is_refused_naming_it(tmp_path):
    """4 × 4 RGBA8 with its levels is 4 · (16 + 4 + 1) = 84 bytes: two fit a budget of 168, three do not."""
    caps = InputCaps(ServerConfig(sqlite_path=tmp_path / "s.db", max_session_texture_bytes=168))
    caps.check_textures(_textured([4, 4]), ("scene", "textures"))
    with pytest.raises(InputError) as e:
        caps.check_textures(_textured([4, 4, 4]), ("scene", "textures"))
    assert e.value.loc == ("scene", "textures")
    assert "252 bytes" in e.value.message and "POCKETRAY_MAX_SESSION_TEXTURE_BYTES" in e.value.message
    InputCaps(ServerConfig(sqlite_path=tmp_path / "t.db", max_session_texture_bytes=0)).check_textures(
        _textured([64] * 8), ("textures",)
    )  # 0: no budget

"""The materials demo scene (renderer.scenes.scenarios, ``mesh_scene("materials")``) traced on the GPU: its
textures reach the image — the checkerboard is two colours where the same board with its texture's
average is one, and the tiled wall's normal map shades its bevels."""

from __future__ import annotations

import dataclasses

import numpy as np

from renderer.config.settings import RenderSettings
from renderer.materials.pbr import PbrMaterial
from renderer.scenes.scenarios import framed, materials_scene_parts

W, H = 96, 192


def _luminance(image: np.ndarray) -> np.ndarray:
    return image[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def _pixels_of(scene, result, mesh: int) -> np.ndarray:
    """The frame's pixels whose primary hit is on ``scene.meshes[mesh]`` (its triangles' ids)."""
    first = scene.triangle_id_base + sum(m.n_triangles for m in scene.meshes[:mesh])
    ids = result.primid
    return (ids >= first) & (ids < first + scene.meshes[mesh].n_triangles)


def test_the_checkerboard_and_the_tiles_normal_map_show_in_a_whitted_frame(gl_renderer):
    scene, parts = materials_scene_parts(detail=0)
    scene = framed(scene, W / H)
    board = scene.materials[scene.meshes[parts["board"]].material]
    wall = scene.materials[scene.meshes[parts["tiles"]].material]
    assert isinstance(board, PbrMaterial) and isinstance(wall, PbrMaterial)
    # the same scene with the board's texture and the wall's normal map taken away
    plain = list(scene.materials)
    plain[scene.meshes[parts["board"]].material] = dataclasses.replace(
        board, base_color=(0.44, 0.44, 0.44), base_color_texture=-1
    )
    plain[scene.meshes[parts["tiles"]].material] = dataclasses.replace(wall, normal_texture=-1)
    untextured = dataclasses.replace(scene, materials=tuple(plain))
    settings = RenderSettings(width=W, height=H, samples_per_pixel=1, max_recursion_depth=1, format="npy")
    # (the session's renderer: a second GL context made current in this thread would leave the
    # session's renderer drawing into a context that is no longer current)
    textured, flat = gl_renderer.render(scene, settings), gl_renderer.render(untextured, settings)
    np.testing.assert_array_equal(textured.primid, flat.primid)  # the same geometry seen
    on_board = _pixels_of(scene, textured, parts["board"])
    assert on_board.sum() > 0.1 * W * H
    lit = _luminance(textured.image)[on_board]
    # a checker: its light squares several times its dark ones, in about equal shares
    dark, light = np.percentile(lit, [25, 75])
    assert light > 3.0 * dark and np.mean(lit > (dark + light) / 2) > 0.25
    lit_flat = _luminance(flat.image)[on_board]
    assert np.percentile(lit_flat, 75) < 1.5 * np.percentile(lit_flat, 25)  # one colour, lit a little unevenly
    on_wall = _pixels_of(scene, textured, parts["tiles"])
    assert on_wall.sum() > 0.05 * W * H
    # the bevels (about a third of a tile) turn the shading normal; the tiles' flat tops and the
    # joints keep the wall's own (the map's (0, 0, 1))
    changed = np.abs(_luminance(textured.image) - _luminance(flat.image))[on_wall] > 0.02
    assert 0.15 < changed.mean() < 0.8, changed.mean()

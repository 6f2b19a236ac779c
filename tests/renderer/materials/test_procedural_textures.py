"""The project's own textures (renderer.materials.procedural_textures): the ranges each channel claims,
patterns that repeat without a seam, unit normals, the same texels for the same arguments."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.geometry.scene import SceneError
from renderer.materials import procedural_textures as P


def _decoded_normals(texture) -> np.ndarray:
    return texture.pixels[..., :3].astype(np.float64) / 255.0 * 2.0 - 1.0


def test_the_checker_has_two_colours_in_squares_and_wraps_as_it_alternates():
    t = P.checker(64, squares=4)
    p = t.pixels
    assert t.srgb and p.shape == (64, 64, 4) and np.all(p[..., 3] == 255)
    colours = np.unique(p.reshape(-1, 4), axis=0)
    assert len(colours) == 2
    light, dark = p[0, 0], p[0, 16]
    assert light[:3].astype(int).sum() > dark[:3].astype(int).sum()
    # a square's neighbour across the wrap is the other colour, as inside: one period is two squares
    np.testing.assert_array_equal(np.roll(p, 32, axis=0), p)
    np.testing.assert_array_equal(np.roll(p, 32, axis=1), p)
    assert not np.array_equal(p[:, -1], p[:, 0]) and not np.array_equal(p[-1], p[0])


@pytest.mark.parametrize("squares", [3, 5, 7])
def test_a_checker_that_would_not_wrap_is_refused(squares):
    with pytest.raises(SceneError) as e:
        P.checker(64, squares=squares)
    assert e.value.field == "squares"


def test_the_tiles_normal_map_is_unit_length_tilts_out_at_the_bevels_and_wraps():
    base, normal = P.tiles(128, count=4, grout=0.05, bevel=0.15)
    assert base.srgb and not normal.srgb
    n = _decoded_normals(normal)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=0.015)  # 8-bit quantisation
    assert n[..., 2].min() > 0.0  # never below the surface
    middle = n[16, 16]  # a tile's flat top: straight up
    np.testing.assert_allclose(middle, [0.0, 0.0, 1.0], atol=0.01)
    # one tile is 32 px: grout 1.6 px, bevel 4.8 px. Left bevel tilts left (−x), right one right,
    # the top one up the image (+y), the bottom one down
    assert n[16, 4, 0] < -0.2 and n[16, 27, 0] > 0.2
    assert n[4, 16, 1] > 0.2 and n[27, 16, 1] < -0.2
    # one tile's period: the map across the wrap is the map inside
    np.testing.assert_array_equal(np.roll(normal.pixels, 32, axis=0), normal.pixels)
    np.testing.assert_array_equal(np.roll(normal.pixels, 32, axis=1), normal.pixels)
    grout = base.pixels[0, 0, :3].astype(int)
    assert np.all(base.pixels[16, 16, :3].astype(int) > grout)  # the glaze is lighter than the joint


def test_wood_and_brushed_metal_keep_their_channels_in_range():
    base, mr = P.wood(64)
    assert base.srgb and not mr.srgb
    r, g, b = (mr.pixels[..., k].astype(np.float64) / 255.0 for k in range(3))
    assert np.all(b == 0.0) and 0.44 <= g.min() < g.max() <= 0.66 and np.all(r == 0.0)
    rgb = base.pixels[..., :3].astype(int)
    assert np.all(rgb[..., 0] >= rgb[..., 1]) and np.all(rgb[..., 1] >= rgb[..., 2])  # browns
    assert rgb.std() > 5  # rings, not a flat colour
    metal = P.brushed_metal(64, roughness=0.3, spread=0.2)
    g, b = metal.pixels[..., 1] / 255.0, metal.pixels[..., 2] / 255.0
    assert np.all(b == 1.0) and 0.2 - 0.01 <= g.min() and g.max() <= 0.3 + 0.1 + 0.1 + 0.01


def test_brushed_metal_streaks_run_along_u_and_across_the_wrap():
    g = P.brushed_metal(128).pixels[..., 1].astype(np.float64)
    along = np.abs(np.diff(g, axis=1)).mean()  # neighbours in a row: along the stroke
    across = np.abs(np.diff(g, axis=0)).mean()
    assert across > 3.0 * along
    # across the wrap no larger a step than between neighbours inside
    assert np.abs(g[:, 0] - g[:, -1]).mean() < 2.0 * along
    assert np.abs(g[0] - g[-1]).mean() < 2.0 * across


def test_the_same_arguments_give_the_same_texels_and_the_seed_changes_them():
    for make in (P.checker, P.brushed_metal, lambda s: P.wood(s)[0], lambda s: P.tiles(s)[0]):
        np.testing.assert_array_equal(make(64).pixels, make(64).pixels)
    assert not np.array_equal(P.wood(64, seed=1)[0].pixels, P.wood(64, seed=2)[0].pixels)
    assert not np.array_equal(P.brushed_metal(64, seed=1).pixels, P.brushed_metal(64, seed=2).pixels)


def test_tinted_glass_transmits_and_attenuates_without_a_texture():
    m = P.tinted_glass((0.2, 0.8, 0.5), distance=2.0)
    assert (m.transmission, m.ior, m.metallic, m.attenuation_distance) == (1.0, 1.5, 0.0, 2.0)
    assert m.textures() == ()


def test_the_mean_factor_of_an_srgb_texture_is_linear():
    t = P.checker(16, squares=2, light=(1.0, 1.0, 1.0), dark=(0.0, 0.0, 0.0))
    np.testing.assert_allclose(P.mean_factor(t), [0.5, 0.5, 0.5, 1.0], atol=1e-9)
    grey = P.checker(16, squares=2, light=(0.2, 0.2, 0.2), dark=(0.2, 0.2, 0.2))
    np.testing.assert_allclose(P.mean_factor(grey)[:3], 0.2, atol=0.003)  # not the sRGB code 0.48

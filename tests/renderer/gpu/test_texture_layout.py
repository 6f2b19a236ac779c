"""renderer/gpu/texture_layout.py: what a textured scene packs for the GPU (the GPU's reading of it is
tests/renderer/gl/test_textures_gpu.py), and the reference's texture lookups it is held to."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.frame.features import SceneFeatures
from renderer.geometry.scene import Camera, Material, Scene, make_mesh
from renderer.gpu import gpu_layout, texture_layout as tl
from renderer.materials.pbr import PbrMaterial
from renderer.materials.texture import Texture
from renderer.oracle import reference

QUAD = ([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], [[0, 3, 2], [0, 2, 1]])
CAM = Camera((0.0, 3.0, 0.01), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0)


def _scene(meshes, materials, textures=()) -> Scene:
    return Scene(
        CAM, (), tuple(materials), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32), meshes=tuple(meshes),
        textures=tuple(textures),
    )  # fmt: skip


def _rgba(h: int, w: int, value: int = 255) -> np.ndarray:
    return np.full((h, w, 4), value, np.uint8)


def test_an_srgb_mip_level_is_the_mean_in_linear_light():
    """Black and white sRGB texels average to linear 0.5, sRGB byte 188, not the bytes' 128; alpha and a
    linear texture average their bytes."""
    px = np.zeros((1, 2, 4), np.uint8)
    px[0, 1] = 255
    assert tl.mip_chain(px, srgb=True)[1][0, 0].tolist() == [188, 188, 188, 128]
    assert tl.mip_chain(px, srgb=False)[1][0, 0].tolist() == [128, 128, 128, 128]


@pytest.mark.parametrize("w, h, levels", [(1, 1, 1), (2, 1, 2), (5, 3, 4), (8, 8, 4), (7, 16, 5)])
def test_levels_halve_rounding_up_to_one_texel(w, h, levels):
    chain = tl.mip_chain(_rgba(h, w), srgb=False)
    assert tl.levels_of(w, h) == len(chain) == levels
    assert chain[-1].shape[:2] == (1, 1)
    for a, b in zip(chain, chain[1:], strict=False):
        assert b.shape[:2] == (-(-a.shape[0] // 2), -(-a.shape[1] // 2))


def test_the_array_packs_square_slots_in_morton_order_with_their_records():
    """Slots (the longer side rounded up to a power of two) largest first: a 7 × 5 texture takes an 8²
    slot, 2 × 16 a 16² one, 3 × 3 a 4² one; the layers are 16² (the largest slot): the 16² fills
    layer 0, the 8² and the 4² share layer 1 at (0, 0) and (8, 0); each level l at (x0 >> l, y0 >> l)."""
    t0 = Texture(_rgba(5, 7, 10), srgb=True, wrap_s="mirror", wrap_t="clamp", filter="nearest")
    t1 = Texture(_rgba(16, 2, 20))
    t2 = Texture(_rgba(3, 3, 30))
    packed = tl.pack_texture_array([t0, t1, t2])
    arr = packed.array
    assert arr.size == (16, 16) and arr.layers == 2 and len(arr.levels) == 5
    assert (arr.levels[0][0, :16, :2] == 20).all() and (arr.levels[0][0, :, 2:] == 0).all()
    assert (arr.levels[0][1, :5, :7] == 10).all() and (arr.levels[0][1, :3, 8:11] == 30).all()
    assert (arr.levels[1][1, :3, :4] == 10).all() and (arr.levels[1][1, :2, 4:6] == 30).all()  # ⌈/2⌉, at x0 >> 1
    assert (arr.levels[3][1, 0, 0] == 10).all() and (arr.levels[2][1, 0, 2] == 30).all()
    rec = tl.TEXTURE_RECORD.unpack(packed.records)
    assert rec["width"].tolist() == [7, 2, 3] and rec["height"].tolist() == [5, 16, 3]
    assert rec["layer"].tolist() == [1, 0, 1] and rec["x0"].tolist() == [0, 0, 8] and rec["y0"].tolist() == [0, 0, 0]
    assert rec["levels"].tolist() == [4, 5, 3]
    assert rec["wrap_s"].tolist() == [2, 0, 0] and rec["wrap_t"].tolist() == [1, 0, 0]
    assert rec["nearest"].tolist() == [1, 0, 0] and rec["srgb"].tolist() == [1, 0, 0]
    assert packed.nbytes == tl.texture_array_bytes(16, 16, 2) == sum(level.nbytes for level in arr.levels)
    assert tl.array_bytes([t0, t1, t2]) == packed.nbytes


def test_morton_slots_never_overlap_at_any_level():
    rng = np.random.default_rng(7)
    sizes = [(int(w), int(h)) for w, h in rng.integers(1, 300, (40, 2))]
    side, places = tl.layout_of(sizes)
    for lv in range(tl.levels_of(side, side)):
        taken: dict[tuple[int, int, int], int] = {}
        for i, ((w, h), (layer, x0, y0)) in enumerate(zip(sizes, places, strict=True)):
            if lv >= tl.levels_of(w, h):
                continue
            lw, lh = -(-w // (1 << lv)), -(-h // (1 << lv))
            assert (x0 >> lv) + lw <= max(1, side >> lv) and (y0 >> lv) + lh <= max(1, side >> lv)
            for x in range((x0 >> lv), (x0 >> lv) + lw):
                for y in range((y0 >> lv), (y0 >> lv) + lh):
                    assert taken.setdefault((layer, x, y), i) == i, (lv, i, taken[(layer, x, y)])


def test_a_texture_beyond_the_devices_size_is_halved_with_a_notice_never_refused():
    big = Texture(_rgba(64, 48), name="wall.png")
    packed = tl.pack_texture_array([big, Texture(_rgba(4, 4))], max_size=16)
    assert packed.array.size == (16, 16) and packed.array.layers == 2
    assert tl.TEXTURE_RECORD.unpack(packed.records)["width"].tolist() == [12, 4]
    assert packed.notices == [
        "textures[0] (wall.png) 48 × 64 resized to 12 × 16 for the device's largest texture side, 16"
    ]


def test_the_array_stays_within_its_texel_bound_by_halving_the_largest():
    big, small = Texture(_rgba(64, 64)), Texture(_rgba(8, 8))
    packed = tl.pack_texture_array([big, small, small, small], max_texels=4 * 32 * 32)
    assert packed.array.size == (32, 32) and packed.array.layers == 2  # the 64² halved; the 8²s in layer 1
    assert len(packed.notices) == 1 and "MAX_TEXTURE_ARRAY_TEXELS" in packed.notices[0]


def test_generated_tangents_follow_u_with_the_handedness_of_the_uv_winding():
    """A quad in y = 0 (normal +y) with U along +x and V along +z: t = +x, and w = +1 (n × t = −z is the
    image's up, −dP/dv); U mirrored (along −x): t = −x, w = −1."""
    up = make_mesh(*QUAD, normals=[[0, 1, 0]] * 4, uvs=[[0, 0], [1, 0], [1, 1], [0, 1]])
    np.testing.assert_allclose(tl.mesh_tangents(up), [[1.0, 0.0, 0.0, 1.0]] * 4, atol=1e-12)
    mirrored = make_mesh(*QUAD, normals=[[0, 1, 0]] * 4, uvs=[[1, 0], [0, 0], [0, 1], [1, 1]])
    np.testing.assert_allclose(tl.mesh_tangents(mirrored), [[-1.0, 0.0, 0.0, -1.0]] * 4, atol=1e-12)


def test_tangents_are_orthogonal_to_the_vertex_normal():
    from renderer.geometry.meshes import icosphere

    s = icosphere(2)
    v = np.asarray(s.vertices)
    uvs = np.stack([np.arctan2(v[:, 0], v[:, 2]) / (2 * np.pi) + 0.5, np.arccos(np.clip(v[:, 1], -1, 1)) / np.pi], 1)
    mesh = make_mesh(s.vertices, s.triangles, normals=s.normals, uvs=uvs)
    t = tl.mesh_tangents(mesh)
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1.0, atol=1e-12)
    assert np.abs(np.einsum("ij,ij->i", t[:, :3], np.asarray(mesh.normals))).max() < 1e-12
    assert set(np.unique(t[:, 3])) <= {-1.0, 1.0}


def test_the_level_term_is_half_the_log_of_uv_over_world_area():
    corners = np.array([[[0, 0, 0], [2, 0, 0], [0, 0, 2]], [[0, 0, 0], [1, 0, 0], [2, 0, 0]]], float)
    uvs = np.array([[[0, 0], [0.5, 0], [0, 0.5]], [[0, 0], [1, 0], [0, 1]]], float)
    np.testing.assert_allclose(tl.triangle_lod_terms(corners, uvs), [0.5 * np.log2(1 / 16), tl.DEGENERATE_LOD])
    # A 256² texture over a 2 × 2 world patch seen by a cone 1/128 wide: one texel per footprint, level 0.
    assert tl.level_for(1 / 128, 0.5 * np.log2(1 / 4), 256, 256) == pytest.approx(0.0)


def test_a_scene_without_pbr_textures_packs_nothing_and_carries_no_surface_format():
    phong = _scene([make_mesh(*QUAD, uvs=[[0, 0]] * 4, colors=[[1, 0, 0, 1]] * 4)], [Material()])
    assert not (tl.uses_textures(phong) or tl.uses_vertex_colors(phong) or tl.uses_tangents(phong))
    assert tl.pack_surface_data(phong).packed.textures == {}
    assert not {"TEXTURES", "VERTEX_COLORS", "TANGENTS"} & set(SceneFeatures(True, True, True).defines())


def test_a_textured_scene_packs_each_part_it_uses():
    tex = Texture(_rgba(4, 4))
    mesh = make_mesh(*QUAD, uvs=[[0, 0], [1, 0], [1, 1], [0, 1]], colors=[[1, 0.5, 0.25, 1]] * 4)
    scene = _scene([mesh], [PbrMaterial(base_color_texture=0, normal_texture=0)], [tex])
    data = tl.pack_surface_data(scene)
    names = {b.name for b in gpu_layout.SURFACE_BINDINGS}
    assert set(data.packed.textures) == names and set(data.nbytes) == names
    assert data.nbytes["u_textures"] == tl.texture_array_bytes(4, 4, 1)
    uv = tl.TRI_UV_RECORD.unpack(data.packed.textures["u_tri_uvs"].data.reshape(-1, 4)[: 2 * tl.TRI_UV_TEXELS])
    assert uv["uv0_a"].tolist() == [[0, 0], [0, 0]] and uv["uv0_b"].tolist() == [[0, 1], [1, 1]]
    np.testing.assert_allclose(uv["lod"][:, 0], 0.5 * np.log2(1 / 4))
    features = SceneFeatures(True, True, True, textures=True, vertex_colors=True, tangents=True)
    assert {"TEXTURES", "VERTEX_COLORS", "TANGENTS"} <= set(features.defines())
    assert {"TEXTURES", "VERTEX_COLORS", "TANGENTS"} <= set(features.generic().defines())


def test_the_reference_lookup_wraps_each_mode_and_decodes_srgb_before_it_mixes():
    px = np.zeros((1, 4, 4), np.uint8)
    px[0, :, 0] = [0, 85, 170, 255]
    px[..., 3] = 255
    levels = [px]
    near = Texture(px, filter="nearest", wrap_s="repeat")
    u = np.array([[-0.1, 0.5], [1.1, 0.5], [0.3, 0.5]])
    assert (reference.texture_sample(levels, near, u)[:, 0] * 255).round().tolist() == [255, 0, 85]
    clamp = Texture(px, filter="nearest", wrap_s="clamp")
    assert (reference.texture_sample(levels, clamp, u)[:, 0] * 255).round().tolist() == [0, 255, 85]
    mirror = Texture(px, filter="nearest", wrap_s="mirror")
    assert (reference.texture_sample(levels, mirror, u)[:, 0] * 255).round().tolist() == [0, 255, 85]
    srgb = Texture(px, filter="linear", srgb=True)
    mid = reference.texture_sample(levels, srgb, np.array([[0.25, 0.5]]))[0, 0]  # halfway between texels 0 and 1
    assert mid == pytest.approx(0.5 * tl.srgb_to_linear(85 / 255))


def test_formats_md_holds_the_texture_records_tables():
    from pathlib import Path

    text = (Path(__file__).resolve().parents[3] / "docs" / "FORMATS.md").read_text()
    start = text.index("<!-- texture-records")
    block = text[text.index("\n", start) + 1 : text.index("<!-- /texture-records -->")].strip()
    assert block == tl.formats_markdown(), "docs/FORMATS.md's texture records differ; paste:\n" + tl.formats_markdown()

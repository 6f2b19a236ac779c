"""OBJ files with their MTL libraries and textures (renderer.io.obj_model): geometry (corner forms,
negative indices, polygons, vertex colours, V flipped), one part per material used, the MTL →
PbrMaterial mapping of docs/FORMATS.md, textures as exporters name them, what is missing said in
the model's notices, malformed lines refused naming their number; then assimp's corpus."""

from __future__ import annotations

import io
import math
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from renderer import limits
from renderer.geometry.scene import SceneError
from renderer.io.mesh_io import model_files
from renderer.io.model_archive import ArchiveFiles, ModelFiles
from renderer.io.obj_model import BUMP_DEPTH, load_obj_model

CORPUS = Path("/usr/share/assimp/models/OBJ")
BIG = {"max_triangles": limits.MAX_TRIANGLES, "max_vertices": limits.MAX_MESH_VERTICES}


def srgb(c: float) -> float:
    """IEC 61966-2-1's decoding, written out here so the expected values are not the module's."""
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def png(pixels: np.ndarray) -> bytes:
    buf = io.BytesIO()
    mode = {1: "L", 3: "RGB", 4: "RGBA"}[1 if pixels.ndim == 2 else pixels.shape[2]]
    Image.fromarray(pixels.astype(np.uint8), mode).save(buf, format="PNG")
    return buf.getvalue()


def load(obj: str, side: dict[str, bytes] | None = None, **bounds: int):
    """The model of OBJ text, its side files ``side`` (None: sent alone)."""
    data = obj.encode()
    files = (
        ModelFiles("model.obj", "obj", data)
        if side is None
        else ModelFiles("model.obj", "obj", data, ArchiveFiles(side))
    )
    return load_obj_model(files, **{**BIG, **bounds})


SQUARE = """
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
"""


# ---- geometry -----------------------------------------------------------------------------------
def test_every_corner_form_and_negative_indices_give_the_same_square():
    forms = [
        "f 1 2 3 4",
        "f 1/1 2/2 3/3 4/4",
        "f 1//1 2//1 3//1 4//1",
        "f 1/1/1 2/2/1 3/3/1 4/4/1",
        "f -4/-4/-1 -3/-3/-1 -2/-2/-1 -1/-1/-1",
        "f 1 2/2 3//1 -1/-1/-1",  # mixed forms: read corner by corner
    ]
    for face in forms:
        m = load(SQUARE + face + "\n")
        (part,) = m.parts
        assert part.n_triangles == 2, face
        corners = part.vertices[part.triangles]
        # fanned from the first corner: (0, 1, 2), (0, 2, 3)
        np.testing.assert_array_equal(corners[0], [[0, 0, 0], [1, 0, 0], [1, 1, 0]])
        np.testing.assert_array_equal(corners[1], [[0, 0, 0], [1, 1, 0], [0, 1, 0]])


def test_uvs_are_flipped_to_v_down_and_a_vertex_is_its_triple():
    m = load(SQUARE + "vt 0.25 0.1\nf 1/1/1 2/2/1 3/3/1\nf 1/5/1 3/3/1 4/4/1\n")
    (part,) = m.parts
    # vertex 1 with vt 1 and with vt 5: two vertices of the model
    assert len(part.vertices) == 5
    uv = part.attributes["uvs"]
    at_origin = uv[(part.vertices == 0).all(axis=1)]
    assert sorted(map(tuple, at_origin.round(6))) == [(0.0, 1.0), (0.25, 0.9)]
    np.testing.assert_array_equal(part.normals, np.tile([0.0, 0.0, 1.0], (5, 1)))


def test_a_polygon_is_fanned_and_quads_count_two_triangles():
    m = load("v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 2 0\nv -1 1 0\nf 1 2 3 4 5\nf 1 2 3 4\n")
    (part,) = m.parts
    assert part.n_triangles == 3 + 2
    first = part.vertices[part.triangles[:3]]
    np.testing.assert_array_equal(first[:, 0], np.zeros((3, 3)))  # every triangle from corner 1


def test_vertex_colours_are_srgb_decoded_and_uncoloured_vertices_white():
    m = load("v 0 0 0 1 0.5 0\nv 1 0 0 0 0 1\nv 0 1 0\nf 1 2 3\n")
    (part,) = m.parts
    colors = part.attributes["colors"]
    by_x = {tuple(v): c for v, c in zip(part.vertices.tolist(), colors.tolist(), strict=True)}
    assert by_x[(0.0, 0.0, 0.0)] == pytest.approx([1.0, srgb(0.5), 0.0, 1.0])
    assert by_x[(1.0, 0.0, 0.0)] == pytest.approx([0.0, 0.0, 1.0, 1.0])
    assert by_x[(0.0, 1.0, 0.0)] == pytest.approx([1.0, 1.0, 1.0, 1.0])


def test_a_zero_normal_in_the_file_costs_only_its_vertex():
    m = load("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 0\nf 1//1 2//1 3//2\n")
    (part,) = m.parts
    np.testing.assert_allclose(part.normals, np.tile([0.0, 0.0, 1.0], (3, 1)))


def test_a_backslash_continues_a_line():
    m = load("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \\\n 3\n")
    assert m.n_triangles == 1


@pytest.mark.parametrize(
    "text, line, says",
    [
        ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", 2, "x y z"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 zero\nf 1 2 3\n", 3, "'zero' is not a number"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 x 3\n", 5, "'x' is not a whole number"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n", 5, "vt 2 of the 1"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", 4, "3 corners or more"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 1 0\nf 1 2 3\n", 4, "a normal is x y z"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nf 1 2 3\n", 4, "not finite"),
        ("v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n", 3, "counts back past the 2"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n", 4, "is not a corner"),
    ],
)
def test_a_malformed_line_is_refused_naming_its_number(text, line, says):
    with pytest.raises(SceneError) as e:
        load(text)
    assert e.value.field == "file"
    assert f"line {line}" in e.value.message and says in e.value.message, e.value.message


def test_the_bounds_are_the_services():
    text = SQUARE + "f 1 2 3 4\n"
    with pytest.raises(SceneError, match="at most 1 allowed"):
        load(text, max_triangles=1)
    with pytest.raises(SceneError, match="at most 3"):
        load(text, max_vertices=3)  # 4 distinct vertices in the part
    with pytest.raises(SceneError, match="has 4 vertices; at most 3"):
        load(text, max_vertices=1)  # the v lines, before any face is read
    with pytest.raises(SceneError, match="holds no triangle"):
        load("v 0 0 0\nl 1 1\n")


# ---- parts and materials ------------------------------------------------------------------------
MTL = """
newmtl red plastic
Kd 0.5 0.1 0.0
Ks 0.5 0.5 0.5
Ns 98
newmtl Matte
Kd 0.2
Ks 0 0 0
Ns 500
newmtl never used
Kd 1 1 1
"""


def test_one_part_per_material_used_in_the_order_of_first_use():
    obj = (
        "mtllib lib.mtl\n"
        + SQUARE
        + "f 1 2 3\nusemtl Matte\nf 1 3 4\nusemtl red plastic   \nf 2 3 4\n"
        + "usemtl Matte\nf 1 2 4\nusemtl nowhere\nf 1 2 3\n"
    )
    m = load(obj, {"lib.mtl": MTL.encode()})
    assert [p.material for p in m.parts] == [-1, 0, 1]  # faces before usemtl and 'nowhere': the scene's
    assert [p.n_triangles for p in m.parts] == [2, 2, 1]
    matte, red = m.materials
    assert red.base_color == pytest.approx((srgb(0.5), srgb(0.1), 0.0))
    assert matte.base_color == pytest.approx((srgb(0.2),) * 3)
    assert red.roughness == pytest.approx((2 / 100) ** 0.25)  # Ns 98: α = √(2/100), roughness = √α
    assert matte.roughness == 1.0  # black Ks: no highlight
    assert red.metallic == 0.0 and red.double_sided
    assert any("'nowhere'" in n for n in m.notices)


@pytest.mark.parametrize(
    "lines, expect",
    [
        ("d 0.5", {"alpha": 0.5, "alpha_mode": "blend"}),
        ("Tr 0.25", {"alpha": 0.75, "alpha_mode": "blend"}),
        ("d -halo 0.4", {"alpha": 0.4, "alpha_mode": "blend"}),
        ("Tr 1", {"alpha": 1.0, "alpha_mode": "opaque"}),  # a lone Tr 1: the inverted d, opaque
        ("d 1\nTr 0.5", {"alpha": 1.0, "alpha_mode": "opaque"}),  # d wins
        ("illum 7\nd 0.2", {"alpha": 1.0, "transmission": 0.8, "alpha_mode": "opaque"}),
        ("illum 2\nd 0.2", {"alpha": 0.2, "transmission": 0.0}),
        ("Ni 0", {"ior": 1.5}),
        ("Ni 1", {"ior": 1.5}),
        ("Ni 1.33", {"ior": 1.33}),
        ("Ni 40", {"ior": limits.MAX_IOR}),
        ("Ns 0", {"roughness": 1.0}),
        ("Ns 1000", {"roughness": (2 / 1002) ** 0.25}),
        ("Ns 10", {"roughness": (2 / 12) ** 0.25}),
        ("Ns 10\nPr 0.3\nPm 0.9", {"roughness": 0.3, "metallic": 0.9}),
        ("Ks 1 1 1", {"metallic": 0.0, "roughness": 1.0}),
        ("Ke 0.5 0 0", {"emissive": (srgb(0.5), 0.0, 0.0), "emissive_strength": 1.0}),
        ("Ke 5 2 0", {"emissive": (1.0, 0.4, 0.0), "emissive_strength": 5.0}),
        ("", {"base_color": (0.8, 0.8, 0.8), "alpha": 1.0, "ior": 1.5}),
    ],
)
def test_the_mtl_mapping(lines, expect):
    m = load("mtllib m.mtl\nusemtl a\n" + SQUARE + "f 1 2 3\n", {"m.mtl": f"newmtl a\n{lines}\n".encode()})
    (material,) = m.materials
    for k, v in expect.items():
        got = getattr(material, k)
        assert got == (pytest.approx(v) if not isinstance(v, str) else v), (lines, k, got)


def test_several_libraries_on_one_line_and_a_library_name_with_spaces():
    obj = "mtllib a.mtl my lib.mtl\nusemtl A\n" + SQUARE + "f 1 2 3\nusemtl B\nf 1 3 4\n"
    m = load(obj, {"a.mtl": b"newmtl A\nKd 1 0 0\n", "my lib.mtl": b"newmtl B\nKd 0 1 0\n"})
    assert [mat.base_color for mat in m.materials] == [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]
    assert m.notices == ()


def test_a_library_that_is_not_there_and_a_model_sent_alone_are_said():
    obj = "mtllib gone.mtl\nusemtl A\n" + SQUARE + "f 1 2 3\n"
    m = load(obj, {})
    assert [p.material for p in m.parts] == [-1] and "'gone.mtl' is not beside the model" in m.notices[0]
    alone = load(obj)
    assert "format=zip" in alone.notices[0]


def test_a_malformed_mtl_line_is_refused_naming_the_file_and_line():
    with pytest.raises(SceneError) as e:
        load("mtllib m.mtl\nusemtl a\n" + SQUARE + "f 1 2 3\n", {"m.mtl": b"newmtl a\n\nKd red\n"})
    assert "MTL 'm.mtl' line 3" in e.value.message and "Kd" in e.value.message


# ---- textures -----------------------------------------------------------------------------------
def checker(w: int, h: int) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w]
    rgb = np.zeros((h, w, 3), np.uint8)
    rgb[..., 0] = (x * 255) // max(w - 1, 1)
    rgb[..., 1] = ((x + y) % 2) * 255
    rgb[..., 2] = 40
    return rgb


def textured(mtl: str, side: dict[str, bytes]):
    files = {"m.mtl": mtl.encode(), **side}
    return load("mtllib m.mtl\nusemtl a\n" + SQUARE + "f 1/1 2/2 3/3 4/4\n", files)


def test_a_windows_path_with_spaces_in_another_case_finds_its_texture():
    image = checker(6, 4)
    m = textured(
        "newmtl a\nKd 1 1 1\nmap_Kd -s 2 3 1 -o 0.5 0.25 -clamp on textures\\My Wood.PNG\n",
        {"Textures/my wood.png": png(image)},
    )
    (material,) = m.materials
    (texture,) = m.textures
    assert material.base_color_texture == 0 and texture.srgb
    assert (texture.width, texture.height) == (6, 4) and texture.wrap_s == texture.wrap_t == "clamp"
    np.testing.assert_array_equal(texture.pixels[..., :3], image)
    # -s 2 3, -o 0.5 0.25 in V-down UVs: V' = 3·V + (1 − 3 − 0.25)
    assert material.base_color_uv_matrix == (2.0, 0.0, 0.0, 3.0)
    assert material.base_color_uv_offset == pytest.approx((0.5, -2.25))
    assert m.notices == ()


def test_options_after_the_file_name_are_read_too():
    m = textured("newmtl a\nmap_Kd my wood.png -s 2 2 -clamp on\n", {"my wood.png": png(checker(2, 2))})
    (material,) = m.materials
    assert material.base_color_texture == 0 and material.base_color_uv_matrix == (2.0, 0.0, 0.0, 2.0)
    assert m.textures[0].wrap_s == "clamp" and m.notices == ()


def test_a_missing_texture_leaves_the_material_without_it_and_a_notice():
    m = textured("newmtl a\nKd 0.5 0.5 0.5\nmap_Kd wood.png\nmap_Ke glow.jpg\n", {})
    (material,) = m.materials
    assert material.base_color_texture == -1 and material.emissive_texture == -1 and m.textures == ()
    assert material.base_color == pytest.approx((srgb(0.5),) * 3)
    assert len(m.notices) == 2 and "'wood.png'" in m.notices[0] and "not beside the model" in m.notices[0]


def test_an_image_that_is_no_png_or_jpeg_or_does_not_decode_is_a_notice():
    m = textured(
        "newmtl a\nmap_Kd a.tga\nmap_Ke b.png\n", {"a.tga": b"\0\0\2" + bytes(40), "b.png": png(checker(4, 4))[:60]}
    )
    assert m.textures == () and len(m.notices) == 2
    assert "not a PNG or JPEG" in m.notices[0] and "cannot be decoded" in m.notices[1]


def test_a_texture_outside_the_models_folder_is_refused():
    with pytest.raises(SceneError, match="outside the model's folder"):
        textured("newmtl a\nmap_Kd ../../etc/passwd\n", {})


def test_an_image_bomb_is_refused_before_it_is_decoded():
    header = (
        b"\x89PNG\r\n\x1a\n"
        + struct.pack(">I", 13)
        + b"IHDR"
        + struct.pack(">IIBBBBB", 100_000, 100_000, 8, 6, 0, 0, 0)
    )
    bomb = header + struct.pack(">I", zlib.crc32(header[12:]) & 0xFFFFFFFF) + b"\0" * 64
    with pytest.raises(SceneError, match="MAX_MODEL_IMAGE_SIDE"):
        textured("newmtl a\nmap_Kd bomb.png\n", {"bomb.png": bomb})


def test_a_texture_past_the_gpus_side_is_scaled_down():
    wide = np.zeros((2, limits.MAX_TEXTURE_SIDE * 2, 3), np.uint8)
    m = textured("newmtl a\nmap_Kd wide.png\n", {"wide.png": png(wide)})
    (texture,) = m.textures
    assert texture.width == limits.MAX_TEXTURE_SIDE and texture.height == 1


def test_map_d_becomes_the_alpha_of_the_base_colour_texture():
    color = checker(8, 8)
    matte = np.tile(np.arange(0, 256, 32, dtype=np.uint8), (8, 1))  # greyscale, no alpha channel
    m = textured("newmtl a\nKd 1 1 1\nmap_Kd c.png\nmap_d a.png\n", {"c.png": png(color), "a.png": png(matte)})
    (material,) = m.materials
    (texture,) = m.textures
    assert material.alpha_mode == "blend" and material.base_color_texture == 0
    np.testing.assert_array_equal(texture.pixels[..., :3], color)
    np.testing.assert_array_equal(texture.pixels[..., 3], matte)
    # map_d alone: a white texture with that alpha
    alone = textured("newmtl a\nmap_d a.png\n", {"a.png": png(matte)})
    np.testing.assert_array_equal(alone.textures[0].pixels[..., :3], 255)
    np.testing.assert_array_equal(alone.textures[0].pixels[..., 3], matte)


def test_bump_becomes_a_tangent_space_normal_map():
    w = 64
    ramp = np.tile((np.arange(w) * 4).clip(0, 255).astype(np.uint8), (w, 1))  # rises along +x by 4/255 a texel
    m = textured("newmtl a\nbump -bm 2 -clamp on h.png\n", {"h.png": png(ramp)})
    (material,) = m.materials
    (texture,) = m.textures
    assert material.normal_texture == 0 and not texture.srgb
    # heights in units of the texture's side: the white lies 2 × BUMP_DEPTH above the black
    slope = 2 * BUMP_DEPTH * w * (4 / 255)
    n = np.array([-slope, 0.0, 1.0]) / math.hypot(slope, 1.0)
    expect = np.rint((n * 0.5 + 0.5) * 255)
    np.testing.assert_array_equal(texture.pixels[10, 5:40, :3], np.tile(expect, (35, 1)))
    # a height rising down the image tilts the normal up it (+Y, glTF's convention)
    down = textured("newmtl a\nmap_Bump h.png\n", {"h.png": png(ramp.T.copy())})
    assert down.textures[0].pixels[5:40, 10, 1].min() > 128 and (down.textures[0].pixels[5:40, 10, 0] == 128).all()


def test_norm_is_the_normal_texture_with_its_scale():
    m = textured(
        "newmtl a\nnorm -bm 0.5 n.png\nbump h.png\n", {"n.png": png(checker(4, 4)), "h.png": png(checker(4, 4))}
    )
    (material,) = m.materials
    assert material.normal_texture == 0 and material.normal_scale == 0.5 and len(m.textures) == 1


def test_map_pr_and_map_pm_combine_into_one_metallic_roughness_texture():
    rough = np.full((4, 4), 200, np.uint8)
    metal = np.full((2, 2), 50, np.uint8)  # another size: scaled to the first
    m = textured("newmtl a\nmap_Pr r.png\nmap_Pm m.png\n", {"r.png": png(rough), "m.png": png(metal)})
    (material,) = m.materials
    (texture,) = m.textures
    assert material.metallic_roughness_texture == 0 and material.roughness == 1.0 and material.metallic == 1.0
    assert (texture.width, texture.height) == (4, 4)
    assert (texture.pixels[..., 1] == 200).all() and (texture.pixels[..., 2] == 50).all()


def test_an_image_two_materials_read_is_one_texture():
    obj = "mtllib m.mtl\n" + SQUARE + "usemtl a\nf 1 2 3\nusemtl b\nf 1 3 4\n"
    m = load(obj, {"m.mtl": b"newmtl a\nmap_Kd t.png\nnewmtl b\nmap_Kd T.PNG\n", "t.png": png(checker(4, 4))})
    assert len(m.textures) == 1 and [x.base_color_texture for x in m.materials] == [0, 0]


def test_the_model_is_placed_into_a_scene():
    m = textured("newmtl a\nKd 1 0 0\nmap_Kd t.png\n", {"t.png": png(checker(4, 4))})
    meshes, materials = m.placed(default_material=0, material_base=3, texture_base=2)
    (mesh,) = meshes
    assert mesh.material == 3 and materials[0].base_color_texture == 2
    assert mesh.uvs is not None and mesh.uvs.shape == (4, 2)


# ---- assimp's corpus ----------------------------------------------------------------------------
def corpus(name: str):
    return load_obj_model(model_files(CORPUS / name), **BIG)


def test_the_spider_arrives_with_its_materials_and_textures():
    m = corpus("spider.obj")
    # spider.mtl defines 5 materials; its faces use 4 (Brusttex never): one part each
    assert len(m.parts) == 4 and len(m.materials) == 4 and len(m.textures) == 4
    names = sorted(t.name for t in m.textures)
    assert names == ["SpiderTex.jpg", "drkwood2.jpg", "engineflare1.jpg", "wal67ar_small.jpg"]
    sizes = {t.name: (t.width, t.height) for t in m.textures}
    assert sizes["SpiderTex.jpg"] == (249, 250) and sizes["drkwood2.jpg"] == (768, 768)
    # the first material used is HLeibTex: Kd 0.690196 0.639216 0.615686, map_Kd .\SpiderTex.jpg
    first = m.materials[m.parts[0].material]
    assert first.base_color == pytest.approx(tuple(srgb(c) for c in (0.690196, 0.639216, 0.615686)))
    assert m.textures[first.base_color_texture].name == "SpiderTex.jpg"
    assert all(t.srgb for t in m.textures) and m.notices == ()
    assert all("uvs" in p.attributes for p in m.parts)


def test_the_corpus_materials_and_their_names():
    usemtl = corpus("cube_usemtl.obj")
    # mtl (Ns 200), mtl2 (Ns 16); mtl3 is used but defined nowhere: the scene's material, said
    assert sorted(p.material for p in usemtl.parts) == [-1, 0, 1]
    assert sorted(x.roughness for x in usemtl.materials) == pytest.approx(sorted([(2 / 202) ** 0.25, (2 / 18) ** 0.25]))
    assert any("'mtl3'" in n for n in usemtl.notices)
    spaces = corpus("box_mat_with_spaces.obj")  # "Material name with many, many spaces " (trailing blanks)
    assert [p.material for p in spaces.parts] == [0]
    assert spaces.materials[0].base_color == pytest.approx((srgb(0.2),) * 3)
    concave = corpus("concave_polygon.obj")  # Ni 1 ("unset"); Ks 0 0 0 (no highlight) whatever its Ns 400
    assert concave.materials[0].ior == 1.5 and concave.materials[0].roughness == 1.0
    empty = corpus("empty_mat.obj")  # 'newmtl ' and 'usemtl ' with an empty name
    assert [p.material for p in empty.parts] == [0] and empty.materials[0].base_color == pytest.approx((srgb(0.8),) * 3)


def test_the_corpus_vertex_colours():
    m = corpus("cube_with_vertexcolors.obj")  # v 0.0 0.0 0.0 0.48627 0.43137 0.47059 first
    (part,) = m.parts
    at = (part.vertices == 0).all(axis=1)
    np.testing.assert_allclose(part.attributes["colors"][at][0], [srgb(0.48627), srgb(0.43137), srgb(0.47059), 1.0])


def test_the_utf16_file_of_the_corpus_reads():
    assert corpus("box_UTF16BE.obj").n_triangles == 12


# ---- hostile material libraries (bench/hostile_parts/obj_mtl.py sends them to a server) ---------
def test_a_library_or_texture_outside_the_folder_is_refused_and_nothing_outside_is_read():
    for obj, mtl in (
        ("mtllib ../../../etc/passwd\nusemtl a\n", None),
        ("mtllib m.mtl\nusemtl a\n", "newmtl a\nmap_Kd ..\\..\\..\\etc\\passwd\n"),
        ("mtllib m.mtl\nusemtl a\n", "newmtl a\nbump -bm 1 ../secret.png\n"),
    ):
        side = {"m.mtl": mtl.encode()} if mtl else {}
        with pytest.raises(SceneError) as e:
            load(obj + SQUARE + "f 1 2 3\n", side)
        assert e.value.field == "file" and "outside the model's folder" in e.value.message


def test_a_library_of_100000_materials_parses_only_those_used_and_too_many_used_is_refused():
    names = [f"m{i}" for i in range(100_000)]
    mtl = "".join(f"newmtl {n}\nKd 0.5 0.5 0.5\n" for n in names).encode()
    one = load("mtllib big.mtl\nusemtl m99999\n" + SQUARE + "f 1 2 3\n", {"big.mtl": mtl})
    assert len(one.materials) == 1 and one.materials[0].base_color == pytest.approx((srgb(0.5),) * 3)
    uses = "".join(f"usemtl {n}\nf 1 2 3\n" for n in names[: limits.MAX_MATERIALS + 1])
    with pytest.raises(SceneError, match="MAX_MATERIALS"):
        load("mtllib big.mtl\n" + SQUARE + uses, {"big.mtl": mtl})


def test_libraries_past_max_mtl_bytes_are_refused():
    half = b"#" * (limits.MAX_MTL_BYTES // 2 + 1) + b"\nnewmtl a\n"
    with pytest.raises(SceneError, match="MAX_MTL_BYTES"):
        load("mtllib a.mtl b.mtl\nusemtl a\n" + SQUARE + "f 1 2 3\n", {"a.mtl": half, "b.mtl": half})


def test_more_textures_than_a_scene_holds_are_refused():
    n = limits.MAX_TEXTURES + 1
    mtl = "".join(f"newmtl m{i}\nmap_Kd t{i}.png\n" for i in range(n)).encode()
    side = {"m.mtl": mtl, **{f"t{i}.png": png(np.full((1, 1, 3), i, np.uint8)) for i in range(n)}}
    uses = "".join(f"usemtl m{i}\nf 1 2 3\n" for i in range(n))
    with pytest.raises(SceneError, match="MAX_TEXTURES"):
        load("mtllib m.mtl\n" + SQUARE + uses, side)


def test_50000_usemtl_names_no_library_defines_cost_one_lookup_each_and_a_bounded_list_of_notices():
    mtl = "".join(f"newmtl M{i}\n" for i in range(20_000)).encode()
    uses = "".join(f"usemtl x{i}\nf 1 2 3\n" for i in range(50_000))
    m = load("mtllib m.mtl\n" + SQUARE + uses, {"m.mtl": mtl})
    assert [p.material for p in m.parts] == [-1]
    assert len(m.notices) == limits.MAX_MODEL_NOTICES and m.notices[-1] == "… and 49,985 more like these"


def test_more_parts_than_a_scene_holds_meshes_are_refused():
    n = limits.MAX_MATERIALS  # each its own part, and the faces before any usemtl one more
    mtl = "".join(f"newmtl m{i}\n" for i in range(n)).encode()
    uses = "".join(f"usemtl m{i}\nf 1 2 3\n" for i in range(n))
    assert len(load("mtllib m.mtl\n" + SQUARE + uses, {"m.mtl": mtl}).parts) == n
    with pytest.raises(SceneError, match="MAX_MESHES"):
        load("mtllib m.mtl\n" + SQUARE + "f 1 2 3\n" + uses, {"m.mtl": mtl})


def test_vertex_colours_written_as_bytes_are_scaled():
    m = load("v 0 0 0 255 128 0\nv 1 0 0 0 0 255\nv 0 1 0 0 0 0\nf 1 2 3\n")
    colors = m.parts[0].attributes["colors"]
    np.testing.assert_allclose(colors[(m.parts[0].vertices == 0).all(axis=1)][0], [1.0, srgb(128 / 255), 0.0, 1.0])


def test_usemtl_names_differing_in_case_from_the_definition_share_its_material():
    obj = "mtllib m.mtl\n" + SQUARE + "usemtl oak\nf 1 2 3\nusemtl OAK\nf 1 3 4\n"
    m = load(obj, {"m.mtl": b"newmtl Oak\nKd 0.5 0.25 0\n"})
    assert len(m.materials) == 1 and [p.material for p in m.parts] == [0] and m.parts[0].n_triangles == 2


def test_a_library_in_a_subfolder_finds_its_maps_beside_it_first():
    obj = "mtllib materials/m.mtl\nusemtl a\n" + SQUARE + "f 1/1 2/2 3/3\n"
    here, there = png(np.zeros((2, 2, 3), np.uint8)), png(np.full((3, 3, 3), 255, np.uint8))
    side = {"materials/m.mtl": b"newmtl a\nmap_Kd wood.png\nmap_Ke ..\\glow.png\n", "wood.png": here}
    m = load(obj, {**side, "materials/wood.png": there, "glow.png": here})
    # wood.png beside the library wins over the one beside the model; ..\glow.png is the model's
    assert sorted((t.width, t.name) for t in m.textures) == [(2, "glow.png"), (3, "wood.png")]
    assert load(obj, {**side, "glow.png": here}).textures[0].width == 2  # else the model's folder


def test_the_spider_makes_a_valid_scene_that_round_trips_through_json():
    from renderer.geometry.scene import Camera, Light, Scene
    from renderer.io.mesh_io import FLOOR, MODEL

    m = corpus("spider.obj")
    meshes, materials = m.placed(default_material=1, material_base=2, texture_base=0)
    scene = Scene(
        Camera((0.0, 0.0, 100.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0),
        (Light((20.0, 40.0, 30.0), (1.0, 1.0, 1.0)),),
        (FLOOR, MODEL, *materials),
        np.zeros((0, 3)),
        np.zeros(0),
        np.zeros(0, np.int32),
        meshes=tuple(meshes),
        textures=m.textures,
    )
    again = Scene.from_json(scene.to_json())
    assert len(again.textures) == 4 and [t.name for t in again.textures] == [t.name for t in m.textures]
    assert again.materials[2] == scene.materials[2] and again.meshes[0].uvs is not None

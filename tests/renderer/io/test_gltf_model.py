"""glTF and GLB files read from their JSON (renderer/io/gltf_model.py, through renderer.io.mesh_io.load_model):
node transforms, instances, vertex attributes, materials and textures, each on a tiny file built
here whose expected values are written out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from renderer import limits
from renderer.geometry.scene import SceneError
from renderer.io.mesh_io import load_mesh, load_model
from renderer.io.model_archive import ModelFiles
from renderer.materials.pbr import PbrMaterial
from tests.renderer.gltf_files import Gltf, data_uri, png, triangle

BIG = {"max_triangles": limits.MAX_TRIANGLES, "max_vertices": limits.MAX_MESH_VERTICES}
RED_GREEN = np.array([[[255, 0, 0, 255], [0, 255, 0, 128]]], np.uint8)  # 2 × 1: red, half-transparent green


def glb_model(g: Gltf):
    return load_model(g.glb(), "glb")


def one_node(g: Gltf, prim: dict, **node) -> None:
    g.add("nodes", {"mesh": g.mesh(prim), **node})
    g.scene(0)


def placed(part) -> np.ndarray:
    return part.to_mesh(0).vertices


def test_trs_and_matrix_nodes_place_alike():
    """translation (1, 2, 3), a quarter turn about z, scale 2: (x, y, z) → (1 − 2y, 2 + 2x, 3 + 2z)."""
    expected = np.array([[1, 2, 3], [1, 4, 3], [-1, 2, 3]], float)
    s = math.sqrt(0.5)
    trs = Gltf()
    one_node(trs, triangle(trs), translation=[1, 2, 3], rotation=[0, 0, s, s], scale=[2, 2, 2])
    # the same map as glTF's column-major matrix
    columns = [0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, 1, 2, 3, 1]
    mat = Gltf()
    one_node(mat, triangle(mat), matrix=columns)
    for g in (trs, mat):
        (part,) = glb_model(g).parts
        np.testing.assert_allclose(placed(part), expected, atol=1e-12)


def test_transforms_compose_down_the_tree():
    g = Gltf()
    mesh = g.mesh(triangle(g))
    g.add("nodes", {"mesh": mesh, "translation": [0, 0, 5]})  # 0: the child
    g.add("nodes", {"children": [0], "scale": [3, 3, 3]})  # 1: its parent
    g.scene(1)
    (part,) = glb_model(g).parts
    np.testing.assert_allclose(placed(part), [[0, 0, 15], [3, 0, 15], [0, 3, 15]])


def test_a_mirroring_node_reverses_the_winding_and_turns_normals_and_tangents():
    g = Gltf()
    n = g.accessor([[0, 0, 1]] * 3)
    t = g.accessor([[1, 0, 0, 1]] * 3)
    one_node(g, triangle(g, NORMAL=n, TANGENT=t), scale=[-1, 1, 1])
    mesh = glb_model(g).parts[0].to_mesh(0)
    c = mesh.vertices[mesh.triangles[0]]
    # mirrored in x the corners run clockwise seen from +z; the winding is reversed so that the
    # geometric normal still faces +z, as the file's normal does
    assert np.cross(c[1] - c[0], c[2] - c[0])[2] > 0
    np.testing.assert_allclose(mesh.normals, [[0, 0, 1]] * 3)
    np.testing.assert_allclose(mesh.tangents, [[-1, 0, 0, -1]] * 3)


def test_a_mesh_on_two_nodes_is_read_once():
    g = Gltf()
    mesh = g.mesh(triangle(g))
    g.add("nodes", {"mesh": mesh, "translation": [10, 0, 0]})
    g.add("nodes", {"mesh": mesh, "translation": [-10, 0, 0]})
    g.scene(0, 1)
    model = glb_model(g)
    a, b = model.parts
    assert a.vertices is b.vertices and a.triangles is b.triangles  # one geometry, two instances
    assert (a.mesh, a.node, b.mesh, b.node) == (0, 0, 0, 1)
    assert model.n_triangles == 2 and model.n_unique_triangles == 1
    assert placed(a)[0, 0] == 10 and placed(b)[0, 0] == -10
    assert load_mesh(g.glb(), "glb").n_triangles == 2


def test_a_node_scaled_to_nothing_is_skipped_with_a_notice():
    g = Gltf()
    mesh = g.mesh(triangle(g))
    g.add("nodes", {"mesh": mesh})
    g.add("nodes", {"mesh": mesh, "scale": [0, 0, 0]})
    g.scene(0, 1)
    model = glb_model(g)
    assert len(model.parts) == 1 and "scaled to zero" in model.notices[0]


def test_normalized_texture_coordinates_and_colours():
    g = Gltf()
    uv0 = g.accessor([[0, 0], [65535, 0], [0, 65535]], np.uint16, normalized=True)
    uv1 = g.accessor([[0, 0], [255, 51], [0, 255]], np.uint8, normalized=True)
    col = g.accessor([[255, 0, 0], [0, 255, 0], [0, 0, 255]], np.uint8, normalized=True)
    one_node(g, triangle(g, TEXCOORD_0=uv0, TEXCOORD_1=uv1, COLOR_0=col))
    (part,) = glb_model(g).parts
    np.testing.assert_allclose(part.attributes["uvs"], [[0, 0], [1, 0], [0, 1]])
    np.testing.assert_allclose(part.attributes["uvs1"], [[0, 0], [1, 0.2], [0, 1]], atol=1e-7)
    np.testing.assert_allclose(part.attributes["colors"], [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]])


def test_strips_and_fans_become_triangles_wound_as_the_specification_says():
    g = Gltf()
    pos = g.accessor([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    strip = g.mesh({"attributes": {"POSITION": pos}, "mode": 5})
    fan = g.mesh({"attributes": {"POSITION": pos}, "mode": 6})
    g.add("nodes", {"mesh": strip})
    g.add("nodes", {"mesh": fan})
    g.scene(0, 1)
    a, b = glb_model(g).parts
    assert a.triangles.tolist() == [
        [0, 1, 2],
        [1, 3, 2],
    ]  # p_i = (v_i, v_{i+1+i%2}, v_{i+2-i%2}): both counter-clockwise
    assert b.triangles.tolist() == [[1, 2, 0], [2, 3, 0]]


def test_points_and_lines_are_skipped_with_a_notice_and_refused_alone():
    g = Gltf()
    pos = g.accessor([[0, 0, 0], [1, 0, 0]])
    one_node(g, {"attributes": {"POSITION": pos}, "mode": 1})
    with pytest.raises(SceneError, match="holds no triangle mesh.*lines skipped"):
        glb_model(g)
    g = Gltf()
    pos = g.accessor([[0, 0, 0], [1, 0, 0]])
    g.add("nodes", {"mesh": g.mesh({"attributes": {"POSITION": pos}, "mode": 0}, triangle(g))})
    g.scene(0)
    model = glb_model(g)
    assert len(model.parts) == 1 and "points skipped" in model.notices[0]


def textured(g: Gltf, material: dict, image: dict | None = None, sampler: dict | None = None) -> None:
    g.add("images", image or {"uri": data_uri(png(RED_GREEN), "image/png")})
    tex: dict = {"source": 0}
    if sampler is not None:
        tex["sampler"] = g.add("samplers", sampler)
    g.add("textures", tex)
    uv = g.accessor([[0, 0], [1, 0], [0, 1]])
    one_node(g, triangle(g, TEXCOORD_0=uv, TEXCOORD_1=uv) | {"material": g.add("materials", material)})


def test_a_base_colour_texture_from_a_data_uri_with_its_sampler():
    g = Gltf()
    textured(
        g,
        {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "baseColorFactor": [1, 0.5, 0.25, 1]}},
        sampler={"wrapS": 33071, "wrapT": 33648, "magFilter": 9728},
    )
    model = glb_model(g)
    (m,) = model.materials
    (t,) = model.textures
    assert m.base_color == (1.0, 0.5, 0.25) and m.base_color_texture == 0
    assert t.srgb and (t.wrap_s, t.wrap_t, t.filter) == ("clamp", "mirror", "nearest")
    np.testing.assert_array_equal(t.pixels, RED_GREEN)


def test_an_image_in_the_glb_and_one_read_both_as_colour_and_as_data_is_stored_twice():
    g = Gltf()
    view = g.view(png(RED_GREEN))
    textured(
        g,
        {
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0},
                "metallicRoughnessTexture": {"index": 0, "texCoord": 1},
            }
        },
        image={"bufferView": view, "mimeType": "image/png"},
    )
    model = glb_model(g)
    (m,) = model.materials
    assert [t.srgb for t in model.textures] == [True, False]
    assert (m.base_color_texture, m.metallic_roughness_texture, m.metallic_roughness_texcoord) == (0, 1, 1)
    assert model.texture_bytes == 2 * 2 * 4


def test_material_fields_and_extensions():
    g = Gltf()
    textured(
        g,
        {
            "pbrMetallicRoughness": {"metallicFactor": 0.25, "roughnessFactor": 0.5},
            "normalTexture": {"index": 0, "scale": 0.5},
            "occlusionTexture": {"index": 0, "strength": 0.75},
            "emissiveTexture": {
                "index": 0,
                "extensions": {
                    "KHR_texture_transform": {"offset": [0.5, 0.25], "rotation": math.pi / 2, "scale": [2, 3]}
                },
            },
            "emissiveFactor": [1, 1, 0],
            "alphaMode": "MASK",
            "alphaCutoff": 0.3,
            "doubleSided": True,
            "extensions": {
                "KHR_materials_emissive_strength": {"emissiveStrength": 5},
                "KHR_materials_ior": {"ior": 1.33},
                "KHR_materials_transmission": {"transmissionFactor": 0.9},
                "KHR_materials_volume": {"attenuationColor": [0.5, 0.6, 0.7], "attenuationDistance": 2},
            },
        },
    )
    (m,) = glb_model(g).materials
    assert (m.metallic, m.roughness, m.normal_scale, m.occlusion_strength) == (0.25, 0.5, 0.5, 0.75)
    assert (m.emissive, m.emissive_strength, m.ior, m.transmission) == ((1.0, 1.0, 0.0), 5.0, 1.33, 0.9)
    assert (m.attenuation_color, m.attenuation_distance) == ((0.5, 0.6, 0.7), 2.0)
    assert (m.alpha_mode, m.alpha_cutoff, m.double_sided) == ("mask", 0.3, True)
    # uv' = T R S uv: a quarter turn of (2, 3)-scaled UVs, R = [[cos, sin], [−sin, cos]]
    np.testing.assert_allclose(m.emissive_uv_matrix, (0.0, 3.0, -2.0, 0.0), atol=1e-12)
    assert m.emissive_uv_offset == (0.5, 0.25)
    assert m.normal_texture == m.occlusion_texture != m.emissive_texture  # linear once, sRGB once


def test_texture_transform_texcoord_overrides_the_texture_info():
    g = Gltf()
    info = {"index": 0, "texCoord": 0, "extensions": {"KHR_texture_transform": {"texCoord": 1}}}
    textured(g, {"pbrMetallicRoughness": {"baseColorTexture": info}})
    (m,) = glb_model(g).materials
    assert m.base_color_texcoord == 1


def test_a_primitive_without_material_gets_the_gltf_default():
    g = Gltf()
    one_node(g, triangle(g))
    model = glb_model(g)
    assert model.materials == (PbrMaterial(),) and model.parts[0].material == 0


def test_a_missing_side_image_is_dropped_and_named(tmp_path):
    """As an OBJ's: the model loads without the texture it lacks, and the notice names the file."""
    g = Gltf()
    textured(g, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}, image={"uri": "skin.png"})
    (tmp_path / "model.gltf").write_bytes(g.gltf())
    lacking = load_model(tmp_path / "model.gltf")
    assert lacking.textures == () and lacking.materials[0].base_color_texture == -1
    assert "'skin.png', which is not beside the model: texture dropped" in lacking.notices[0]
    alone = load_model(g.gltf(), "gltf")
    assert alone.textures == () and "format=zip" in alone.notices[0]
    (tmp_path / "skin.png").write_bytes(png(RED_GREEN))
    (t,) = load_model(tmp_path / "model.gltf").textures
    assert t.name == "skin.png"


def test_an_image_beside_a_glb_is_read_from_the_models_folder(tmp_path):
    g = Gltf()
    textured(g, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}, image={"uri": "maps%20a/skin.png"})
    (tmp_path / "maps a").mkdir()
    (tmp_path / "maps a" / "skin.png").write_bytes(png(RED_GREEN))
    (tmp_path / "m.glb").write_bytes(g.glb())
    np.testing.assert_array_equal(load_model(tmp_path / "m.glb").textures[0].pixels, RED_GREEN)


@pytest.mark.parametrize("required", [["KHR_materials_clearcoat"], ["KHR_texture_transform", "EXT_texture_webp"]])
def test_a_required_extension_not_read_is_refused_naming_it(required):
    g = Gltf()
    one_node(g, triangle(g))
    g.doc["extensionsRequired"] = g.doc["extensionsUsed"] = required
    with pytest.raises(SceneError, match=f"requires '{required[-1]}', which is not read"):
        glb_model(g)
    g.doc["extensionsRequired"] = ["KHR_texture_transform", "KHR_materials_volume"]  # both read
    assert glb_model(g).n_triangles == 1


def test_an_image_larger_than_a_texture_is_reduced_with_a_notice():
    g = Gltf()
    wide = np.zeros((2, limits.MAX_TEXTURE_SIDE + 4, 4), np.uint8)
    textured(g, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}, image={"uri": data_uri(png(wide))})
    model = glb_model(g)
    assert model.textures[0].width <= limits.MAX_TEXTURE_SIDE and "reduced" in model.notices[0]


def test_an_image_declaring_too_many_pixels_is_refused_before_decoding():
    """A PNG header that declares 9,000² pixels and holds none: refused by its header."""
    from tests.renderer.io.test_model_archive import png_header

    for image in ({"uri": data_uri(png_header(9000, 9000))}, None):
        g = Gltf()
        if image is None:
            image = {"bufferView": g.view(png_header(9000, 9000)), "mimeType": "image/png"}
        textured(g, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}, image=image)
        with pytest.raises(SceneError, match="9,000 × 9,000 pixels.*MAX_MODEL_IMAGE_SIDE"):
            glb_model(g)


def test_textures_beyond_the_scenes_texel_budget_are_refused_before_decoding(monkeypatch):
    """Two 2 × 1 images (4 texels) against a budget of 3: refused by their headers, none decoded."""
    from renderer.io import gltf_model

    def no_decoding(*args):
        raise AssertionError("an image was decoded")

    monkeypatch.setattr(limits, "MAX_TEXTURE_TEXELS", 3)
    monkeypatch.setattr(gltf_model._Reader, "_decode", no_decoding)
    g = Gltf()
    textured(g, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "emissiveTexture": {"index": 0}})
    g.doc["images"].append({"uri": data_uri(png(RED_GREEN))})
    g.doc["textures"].append({"source": 1})
    g.doc["materials"][0]["emissiveTexture"] = {"index": 1}
    with pytest.raises(SceneError, match="its textures declare 4 texels; at most 3 .MAX_TEXTURE_TEXELS"):
        glb_model(g)


def test_indices_out_of_range_and_attribute_counts_are_refused():
    g = Gltf()
    idx = g.accessor([0, 1, 7], np.uint16)
    one_node(g, triangle(g) | {"indices": idx})
    with pytest.raises(SceneError, match=r"indices reach vertex 7; POSITION holds 3"):
        glb_model(g)
    g = Gltf()
    uv = g.accessor([[0, 0], [1, 1]])
    one_node(g, triangle(g, TEXCOORD_0=uv))
    with pytest.raises(SceneError, match="TEXCOORD_0 holds 2 elements"):
        glb_model(g)


def test_the_reader_takes_model_files_as_the_archive_gives_them():
    from renderer.io.gltf_model import load_gltf_model

    g = Gltf()
    one_node(g, triangle(g))
    model = load_gltf_model(ModelFiles("m.gltf", "gltf", g.gltf()), **BIG)
    assert model.n_triangles == 1 and model.parts[0].transform is None


def test_more_parts_than_the_bound_are_refused(monkeypatch):
    monkeypatch.setattr(limits, "MAX_MODEL_PARTS", 3)
    g = Gltf()
    mesh = g.mesh(triangle(g), triangle(g))
    g.add("nodes", {"mesh": mesh})
    g.add("nodes", {"mesh": mesh, "translation": [2, 0, 0]})
    g.scene(0, 1)
    with pytest.raises(SceneError, match="more than 3 parts .primitives × the nodes that place them"):
        glb_model(g)

"""The glTF material kind, textures and vertex attributes as scene data: checked on construction,
through the scene JSON and back."""

import json

import numpy as np
import pytest

from renderer import limits
from renderer.geometry.scene import Scene, SceneError, make_mesh
from renderer.materials import record_value
from renderer.materials.kinds import material_from_json
from renderer.materials.pbr import PbrMaterial
from renderer.materials.phong import Material
from renderer.materials.texture import Texture

MIRROR_X = [[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]


def _scene_json(material: dict, textures: list[dict], **mesh) -> dict:
    return {
        "camera": {"position": [0, 0, 5], "target": [0, 0, 0]},
        "materials": [{"color": [1, 0, 0]}, material],
        "textures": textures,
        "meshes": [{"vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]], "material": 1, **mesh}],
    }


def test_a_pbr_material_takes_the_specifications_defaults_and_names_its_kind_in_json():
    m = PbrMaterial()
    assert (m.base_color, m.metallic, m.roughness, m.ior, m.alpha_mode) == ((1.0, 1.0, 1.0), 1.0, 1.0, 1.5, "opaque")
    assert m.to_json()["kind"] == "pbr" and "base_color_texture" not in m.to_json()
    assert "kind" not in Material().to_json()
    assert material_from_json({"kind": "pbr", "metallic": 0.25}, "m") == PbrMaterial(metallic=0.25)
    assert isinstance(material_from_json({"color": [0, 1, 0]}, "m"), Material)


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"alpha_mode": "MASK"}, "alpha_mode"),
        ({"double_sided": 1}, "double_sided"),
        ({"base_color_texture": 0.5}, "base_color_texture"),
        ({"normal_texcoord": 2}, "normal_texcoord"),
        ({"roughness": 1.5}, "roughness"),
        ({"ior": 0.5}, "ior"),
    ],
)
def test_a_bad_pbr_parameter_names_its_field(kw, field):
    with pytest.raises(SceneError) as e:
        PbrMaterial(**kw)
    assert e.value.field == field


def test_a_choice_is_recorded_as_its_position():
    assert record_value(PbrMaterial(alpha_mode="blend"), "alpha_mode") == 2.0
    assert record_value(PbrMaterial(double_sided=True), "double_sided") == 1.0


def test_an_unknown_kind_is_refused_with_the_kinds_accepted():
    with pytest.raises(SceneError, match="phong, pbr") as e:
        material_from_json({"kind": "toon"}, "materials[2]")
    assert e.value.field == "materials[2].kind"


def test_a_scene_with_textures_and_vertex_attributes_survives_its_json():
    pixels = np.arange(3 * 5 * 4, dtype=np.uint8).reshape(3, 5, 4)
    material = PbrMaterial(base_color_texture=0, normal_texture=0, normal_texcoord=1).to_json()
    texture = Texture(pixels, srgb=True, wrap_s="mirror", filter="nearest", name="a.png").to_json()
    d = _scene_json(
        material,
        [texture],
        uvs=[[0, 0], [1, 0], [0, 1]],
        uvs1=[[0, 0], [2, 0], [0, 2]],
        colors=[[1, 1, 1, 1], [0.5, 0.5, 0.5, 1], [0, 0, 0, 0.5]],
        tangents=[[1, 0, 0, 1]] * 3,
    )
    scene = Scene.from_json(json.loads(json.dumps(Scene.from_json(d).to_json())))
    t = scene.textures[0]
    assert np.array_equal(t.pixels, pixels)
    assert (t.srgb, t.wrap_s, t.filter, t.name) == (True, "mirror", "nearest", "a.png")
    assert scene.materials[1] == PbrMaterial(base_color_texture=0, normal_texture=0, normal_texcoord=1)
    mesh = scene.meshes[0]
    assert mesh.uvs1 is not None and mesh.uvs1[1].tolist() == [2, 0]
    assert mesh.colors is not None and mesh.colors[2].tolist() == [0, 0, 0, 0.5]


def test_a_material_naming_a_missing_texture_is_refused():
    d = _scene_json(PbrMaterial(emissive_texture=1).to_json(), [Texture(np.zeros((1, 1, 4), np.uint8)).to_json()])
    with pytest.raises(SceneError) as e:
        Scene.from_json(d)
    assert e.value.field == "materials[1].emissive_texture"


def test_a_mirroring_transform_flips_the_tangents_handedness_and_turns_them():
    m = make_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], tangents=[[1, 0, 0, 1]] * 3, transform=MIRROR_X)
    assert m.tangents is not None and m.tangents.tolist() == [[-1, 0, 0, -1]] * 3


@pytest.mark.parametrize(
    ("mesh", "field"),
    [
        ({"uvs": [[0, 0], [1, 0]]}, "meshes[0].uvs"),
        ({"colors": [[1, 1, 1, 1], [1, 1, 1, 1], [1, 1, 2, 1]]}, "meshes[0].colors[2]"),
        ({"tangents": [[1, 0, 0, 0.5]] * 3}, "meshes[0].tangents[0][3]"),
    ],
)
def test_a_bad_vertex_attribute_names_its_row(mesh, field):
    with pytest.raises(SceneError) as e:
        Scene.from_json(_scene_json(Material().to_json(), [], **mesh))
    assert e.value.field == field


def test_a_texture_too_large_is_refused_from_its_header():
    import base64
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("L", (limits.MAX_TEXTURE_SIDE + 1, 1)).save(buf, format="PNG")
    with pytest.raises(SceneError, match="MAX_TEXTURE_SIDE") as e:
        Texture.from_json({"png": base64.b64encode(buf.getvalue()).decode()}, "textures[0]")
    assert e.value.field == "textures[0].png"

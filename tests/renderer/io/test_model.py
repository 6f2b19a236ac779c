"""A parsed model (renderer/io/model.py): its bounds with its parts' transforms, its placing into a
scene (material and texture indices moved past the scene's), and its parts of one material
joined when a scene has room for few meshes."""

from __future__ import annotations

import numpy as np

from renderer.io.model import Model, ModelPart
from renderer.materials.pbr import PbrMaterial
from renderer.materials.texture import Texture

TRI = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)


def shifted(x: float) -> np.ndarray:
    m = np.eye(4)
    m[0, 3] = x
    return m


def part(material: int, transform=None, **attributes) -> ModelPart:
    return ModelPart(TRI, np.array([[0, 1, 2]]), None, attributes, material, transform=transform)


def test_bounds_take_each_parts_transform():
    model = Model((part(0), part(0, shifted(10.0))))
    lo, hi = model.bounds()
    assert lo.tolist() == [0, 0, 0] and hi.tolist() == [11, 1, 0]


def test_placed_moves_material_and_texture_indices_past_the_scenes():
    texture = Texture(np.zeros((1, 1, 4), np.uint8))
    model = Model(
        (part(0), part(1), part(-1)),
        (PbrMaterial(base_color_texture=0), PbrMaterial(metallic=0.0)),
        (texture,),
    )
    meshes, materials = model.placed(5, 10, 3)
    assert [m.material for m in meshes] == [10, 11, 5]  # −1: the scene's material given
    assert materials[0].base_color_texture == 3 and materials[1].base_color_texture == -1


def test_parts_of_one_material_are_joined_when_the_scene_has_room_for_few_meshes():
    uvs = np.array([[0, 0], [1, 0], [0, 1]], float)
    parts = (part(0, uvs=uvs), part(1), part(0, shifted(5.0), uvs=uvs), part(1, shifted(9.0)))
    model = Model(parts, (PbrMaterial(), PbrMaterial()))
    apart, _ = model.placed(0, 0, 0, max_meshes=4)
    joined, _ = model.placed(0, 0, 0, max_meshes=2)
    assert len(apart) == 4 and [m.material for m in joined] == [0, 1]
    assert joined[0].vertices[:, 0].max() == 6 and joined[1].vertices[:, 0].max() == 10
    assert joined[0].triangles.tolist() == [[0, 1, 2], [3, 4, 5]] and joined[0].uvs.shape == (6, 2)
    assert sum(m.n_triangles for m in joined) == model.n_triangles == 4

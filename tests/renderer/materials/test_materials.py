"""The material declaration (renderer/materials): the Phong kind's GPU record as the tracers read it,
and a kind with more parameters laid out, packed, named for GLSL, validated and written as JSON from
its declaration alone."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from renderer.geometry.scene import Material, SceneError, Vec3
from renderer.materials import Slot, glsl_accessors, material_params, pack_records, param, record_layout, record_texels


@dataclass(frozen=True)
class Sheened(Material):
    """A Phong material with two more parameters: a scalar (fits the record's free float) and an RGB
    triple (does not: a fourth texel)."""

    sheen: float = param(0.25, lo=0.0, hi=1.0, doc="sheen weight")
    tint: Vec3 = param((1.0, 0.5, 0.25), lo=0.0, hi=2.0, doc="sheen tint", omit_default=True)


def test_the_phong_record_is_the_thesis_layout():
    """Three texels: (r, g, b, ambient), (diffuse, specular, shininess, reflective), (transmissive, ior,
    roughness, 0); emission is not in it (its own texture, for emitting scenes only)."""
    assert record_texels(Material) == 3
    assert record_layout(Material) == {
        "color": Slot(0, 0, 3),
        "ambient": Slot(0, 3, 1),
        "diffuse": Slot(1, 0, 1),
        "specular": Slot(1, 1, 1),
        "shininess": Slot(1, 2, 1),
        "reflective": Slot(1, 3, 1),
        "transmissive": Slot(2, 0, 1),
        "ior": Slot(2, 1, 1),
        "roughness": Slot(2, 2, 1),
    }
    m = Material(color=(0.1, 0.2, 0.3), ambient=0.4, diffuse=0.5, specular=0.6, shininess=7.0)
    n = Material(reflective=0.8, transmissive=0.9, ior=1.5, roughness=0.25, emission=(1.0, 2.0, 3.0))
    got = pack_records([m, n], Material)
    want = np.float32(
        [
            [0.1, 0.2, 0.3, 0.4],
            [0.5, 0.6, 7.0, 0.3],
            [0.0, 1.0, 0.0, 0.0],
            [0.9, 0.3, 0.3, 0.3],
            [0.3, 0.1, 40.0, 0.8],
            [0.9, 1.5, 0.25, 0.0],
        ]
    )
    np.testing.assert_array_equal(got, want)


def test_every_phong_parameter_is_declared_with_a_range_and_a_doc():
    params = material_params(Material)
    assert list(params) == [
        "color",
        "ambient",
        "diffuse",
        "specular",
        "shininess",
        "reflective",
        "transmissive",
        "ior",
        "emission",
        "roughness",
    ]
    for name, p in params.items():
        assert p.doc, name
        assert p.lo < p.hi, name
        assert getattr(Material(), name) == p.default, f"{name}: the dataclass default is the declared one"


def test_a_declaration_with_more_parameters_makes_its_record():
    """The scalar takes the free float of the third texel; the triple starts a fourth; the packer and
    the GLSL accessors follow."""
    layout = record_layout(Sheened)
    assert layout["sheen"] == Slot(2, 3, 1)
    assert layout["tint"] == Slot(3, 0, 3)
    assert record_texels(Sheened) == 4
    got = pack_records([Sheened(sheen=0.5, tint=(0.1, 0.2, 0.3), roughness=0.75)], Sheened)
    assert got.shape == (4, 4)
    np.testing.assert_array_equal(got[2], np.float32([0.0, 1.0, 0.75, 0.5]))
    np.testing.assert_array_equal(got[3], np.float32([0.1, 0.2, 0.3, 0.0]))
    text = glsl_accessors(Sheened)
    assert "#define material_sheen(m) (MATERIAL_TEXEL(m, 2).w)\n" in text
    assert "#define material_tint(m) (MATERIAL_TEXEL(m, 3).xyz)\n" in text
    assert "material_emission" not in text, "emission has its own texture"


def test_a_declaration_with_more_parameters_validates_and_round_trips_json():
    s = Sheened(sheen=0.5, tint=(0.1, 0.2, 0.3))
    assert Sheened.from_json(s.to_json(), "materials[0]") == s
    assert s.to_json()["sheen"] == 0.5 and s.to_json()["tint"] == [0.1, 0.2, 0.3]
    assert "tint" not in Sheened().to_json(), "omit_default: left out while it holds its default"
    with pytest.raises(SceneError) as e:
        Sheened.from_json({"sheen": 1.5}, "materials[2]")
    assert e.value.field == "materials[2].sheen"
    with pytest.raises(SceneError) as e:
        Sheened.from_json({"tint": [0.1, 3.0, 0.0]}, "materials[1]")
    assert e.value.field == "materials[1].tint[1]"
    with pytest.raises(SceneError) as e:
        Sheened.from_json({"tint": [0.1, 0.2]}, "materials[0]")
    assert e.value.field == "materials[0].tint"
    with pytest.raises(SceneError):
        Material.from_json({"sheen": 0.5}, "materials[0]")  # the Phong kind has no such parameter


def test_the_phong_json_leaves_out_emission_and_roughness_at_their_defaults():
    assert set(Material().to_json()) == {
        "color",
        "ambient",
        "diffuse",
        "specular",
        "shininess",
        "reflective",
        "transmissive",
        "ior",
    }
    m = Material(emission=(0.0, 2.0, 0.0), roughness=0.3)
    assert m.to_json()["emission"] == [0.0, 2.0, 0.0] and m.to_json()["roughness"] == 0.3
    with pytest.raises(SceneError) as e:
        Material(ior=0.0)
    assert e.value.field == "ior" and ">" in e.value.message

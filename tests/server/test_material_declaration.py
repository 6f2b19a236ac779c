"""The API's material model is made from the material's declaration (renderer/materials): the Phong
kind's OpenAPI names, ranges and descriptions, and a declaration with one more parameter makes a model
that has it, with its default, range and doc, and refuses a value out of it."""

from __future__ import annotations

from dataclasses import dataclass

import pytest
from pydantic import ValidationError

from renderer.geometry.scene import Material
from renderer.limits import MAX_EMISSION, MAX_IOR, MAX_SHININESS
from renderer.materials import param
from server.contract.scene import MaterialModel, material_model


@dataclass(frozen=True)
class Sheened(Material):
    sheen: float = param(0.25, lo=0.0, hi=1.0, doc="sheen weight")


def test_the_phong_model_keeps_its_openapi_fields():
    schema = MaterialModel.model_json_schema()
    props = schema["properties"]
    assert list(props) == [
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
    assert schema["title"] == "MaterialModel" and schema["additionalProperties"] is False
    assert props["color"]["items"] == {"type": "number", "minimum": 0.0, "maximum": 1.0}
    assert (props["color"]["minItems"], props["color"]["maxItems"]) == (3, 3)
    assert props["shininess"]["maximum"] == MAX_SHININESS and props["shininess"]["description"] == "Phong exponent"
    assert props["ior"]["exclusiveMinimum"] == 0.0 and props["ior"]["maximum"] == MAX_IOR
    assert props["ior"]["description"] == "refraction index inside / outside"
    assert props["emission"]["items"]["maximum"] == MAX_EMISSION
    assert props["emission"]["description"].startswith("radiance emitted on the side the normal faces")
    assert props["roughness"]["description"].startswith("GGX α of the path integrator's reflective")
    for name in ("ambient", "diffuse", "specular", "reflective", "transmissive", "roughness"):
        assert (props[name]["minimum"], props[name]["maximum"]) == (0.0, 1.0), name
    assert MaterialModel().model_dump() == Material().to_json() | {"emission": [0.0, 0.0, 0.0], "roughness": 0.0}


def test_a_declared_parameter_reaches_the_api_model():
    model = material_model(Sheened)
    prop = model.model_json_schema()["properties"]["sheen"]
    assert (prop["minimum"], prop["maximum"], prop["default"], prop["description"]) == (0.0, 1.0, 0.25, "sheen weight")
    assert model.model_validate({"sheen": 0.5}).model_dump()["sheen"] == 0.5
    with pytest.raises(ValidationError) as e:
        model.model_validate({"sheen": 1.5})
    assert e.value.errors()[0]["loc"] == ("sheen",)
    body = model.model_validate({"sheen": 0.5, "color": [0.1, 0.2, 0.3]}).model_dump()
    assert Sheened.from_json(body, "materials[0]") == Sheened(sheen=0.5, color=(0.1, 0.2, 0.3))
    with pytest.raises(ValidationError):
        MaterialModel.model_validate({"sheen": 0.5})  # not a Phong parameter

"""Scene model (renderer.scene): SPEC's JSON in and out, validation messages that name the field.

Render settings are tested in ``test_settings.py``, the generated scenarios in ``test_scenarios.py``.
"""

from __future__ import annotations

import json
import math

import pytest

from renderer.scene import Scene, SceneError

SPEC_EXAMPLE = {
    "camera": {"position": [0, 0, 100], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 60},
    "lights": [{"position": [0, 40, 0], "color": [1, 1, 1]}],
    "materials": [
        {
            "color": [0.9, 0.3, 0.3],
            "ambient": 0.3,
            "diffuse": 0.3,
            "specular": 0.1,
            "shininess": 40,
            "reflective": 0.3,
            "transmissive": 0.0,
            "ior": 1.0,
        }
    ],
    "spheres": [{"center": [0, 0, 0], "radius": 1, "material": 0}],
    "planes": [{"point": [0, -20, 0], "normal": [0, 1, 0], "material": 0}],
}


def test_spec_example_round_trips():
    scene = Scene.from_json(SPEC_EXAMPLE)
    out = scene.to_json()
    assert json.loads(json.dumps(out)) == out
    assert Scene.from_json(out).to_json() == out
    assert out["spheres"] == [{"center": [0.0, 0.0, 0.0], "radius": 1.0, "material": 0}]
    assert out["camera"]["fov_y"] == 60.0 and scene.n_primitives == 2


def bad(path: list, value):
    d = json.loads(json.dumps(SPEC_EXAMPLE))
    node = d
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value
    return d


@pytest.mark.parametrize(
    "path,value,field",
    [
        (["spheres", 0, "radius"], -1, "spheres[0].radius"),
        (["spheres", 0, "radius"], 0, "spheres[0].radius"),
        (["spheres", 0, "center"], [0, math.nan, 0], "spheres[0].center[1]"),
        (["spheres", 0, "center"], [0, math.inf, 0], "spheres[0].center[1]"),
        (["spheres", 0, "material"], 3, "spheres[0].material"),
        (["planes", 0, "normal"], [0, 0, 0], "planes[0].normal"),
        (["camera", "up"], [0, 0, 0], "camera.up"),
        (["camera", "target"], [0, 0, 100], "camera.target"),
        (["camera", "fov_y"], 180, "camera.fov_y"),
        (["camera", "fov_y"], 0, "camera.fov_y"),
        (["camera", "up"], [0, 0, -1], "camera.up"),
        (["materials", 0, "ior"], 0, "materials[0].ior"),
        (["materials", 0, "color"], [2, 0, 0], "materials[0].color[0]"),
        (["spheres", 0, "colour"], 1, "spheres[0].colour"),
    ],
)
def test_validation_names_the_field(path, value, field):
    with pytest.raises(SceneError) as e:
        Scene.from_json(bad(path, value))
    assert e.value.field == field, str(e.value)
    assert field in str(e.value)

"""Scene model and settings: SPEC's JSON in and out, validation messages that name the field."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from renderer.scenarios import scenario
from renderer.scene import Scene, SceneError
from renderer.settings import RenderSettings

SPEC_EXAMPLE = {
    "camera": {"position": [0, 0, 100], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 60},
    "lights": [{"position": [0, 40, 0], "color": [1, 1, 1]}],
    "materials": [{"color": [0.9, 0.3, 0.3], "ambient": 0.3, "diffuse": 0.3, "specular": 0.1,
                   "shininess": 40, "reflective": 0.3, "transmissive": 0.0, "ior": 1.0}],
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


def test_scenario_round_trips_and_is_inside_the_cube():
    s = scenario(3, 100, seed=7)
    again = Scene.from_json(s.to_json())
    np.testing.assert_array_equal(again.sphere_centers, s.sphere_centers)
    lo = s.sphere_centers - s.sphere_radii[:, None]
    hi = s.sphere_centers + s.sphere_radii[:, None]
    assert lo.min() >= -20 and hi.max() <= 20
    np.testing.assert_array_equal(scenario(2, 64, seed=3).sphere_centers, scenario(2, 64, seed=3).sphere_centers)
    assert not np.array_equal(scenario(2, 64, seed=3).sphere_centers, scenario(2, 64, seed=4).sphere_centers)
    assert len(scenario(1, 4096).sphere_centers) == 4096 and len(np.unique(scenario(1, 4096).sphere_centers, axis=0)) == 4096


def bad(path: list, value):
    d = json.loads(json.dumps(SPEC_EXAMPLE))
    node = d
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value
    return d


@pytest.mark.parametrize("path,value,field", [
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
])
def test_validation_names_the_field(path, value, field):
    with pytest.raises(SceneError) as e:
        Scene.from_json(bad(path, value))
    assert e.value.field == field, str(e.value)
    assert field in str(e.value)


def test_settings_validation_and_json():
    s = RenderSettings.from_json({"width": 320, "height": 544, "mode": "heat"})
    assert RenderSettings.from_json(s.to_json()) == s
    for kw, field in [({"width": 0}, "width"), ({"height": 4097}, "height"), ({"mode": "x"}, "mode"),
                      ({"format": "gif"}, "format"), ({"max_tree_depth": 65}, "max_tree_depth"),
                      ({"max_recursion_depth": 9}, "max_recursion_depth"), ({"width": True}, "width")]:
        with pytest.raises(SceneError) as e:
            RenderSettings(**kw)
        assert e.value.field == field
    with pytest.raises(SceneError) as e:
        RenderSettings.from_json({"widht": 3})
    assert e.value.field == "widht"


def test_scenario_arguments_are_validated():
    for kw, field in [({"number": 4, "n": 8}, "scenario"), ({"number": 1, "n": -1}, "n"),
                      ({"number": 1, "n": 8, "radius": 0.0}, "radius"), ({"number": 1, "n": 8, "seed": -2}, "seed")]:
        with pytest.raises(SceneError) as e:
            scenario(**kw)
        assert e.value.field == field

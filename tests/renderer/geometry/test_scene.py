"""Scene model (renderer.geometry.scene): SPEC's JSON in and out, validation messages that name the field.

Render settings are tested in ``test_settings.py``, the generated scenarios in ``test_scenarios.py``.

Meshes in the scene model (renderer.geometry.scene): JSON in and out, the transform, ids, and
validation that names the JSON path.
"""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from renderer.geometry.scene import MAX_COORDINATE, Mesh, Scene, SceneError, make_mesh

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


QUAD = {"vertices": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "triangles": [[0, 1, 2], [0, 2, 3]], "material": 1}
BASE = {
    "materials": [{}, {"color": [0.2, 0.8, 0.2]}],
    "spheres": [{"center": [0, 0, 0], "radius": 1}, {"center": [3, 0, 0], "radius": 1}],
    "planes": [{"point": [0, -20, 0], "normal": [0, 1, 0]}],
    "meshes": [
        QUAD,
        {
            "vertices": [[0, 0, 5], [1, 0, 5], [0, 1, 5]],
            "triangles": [[0, 1, 2]],
            "normals": [[0, 0, 2], [0, 0, 1], [0.1, 0, 1]],
        },
    ],
}


def scene_json(**changes) -> dict:
    d = copy.deepcopy(BASE)
    d.update(changes)
    return d


def test_ids_spheres_then_planes_then_triangles_in_mesh_order():
    s = Scene.from_json(scene_json())
    assert (s.n_spheres, len(s.planes), s.n_triangles) == (2, 1, 3)
    assert s.triangle_id_base == 3 and s.n_primitives == 6
    np.testing.assert_array_equal(s.triangle_mesh, [0, 0, 1])
    np.testing.assert_array_equal(s.triangle_materials, [1, 1, 0])
    np.testing.assert_array_equal(s.triangle_smooth, [False, False, True])
    assert list(s.mesh_triangle_range(1)) == [2]
    # corner k of triangle j is vertex triangles[j][k] of its mesh, in world space
    np.testing.assert_array_equal(s.triangle_corners[1], [[0, 0, 0], [1, 1, 0], [0, 1, 0]])
    np.testing.assert_array_equal(s.triangle_normals[2, 0], [0, 0, 2])  # as given: normalised when shading
    assert (s.triangle_normals[:2] == 0).all()


def test_round_trip_is_exact_and_a_sphere_scene_has_no_meshes_key():
    s = Scene.from_json(scene_json())
    out = s.to_json()
    assert json.loads(json.dumps(out)) == out
    again = Scene.from_json(out)
    assert again.to_json() == out
    np.testing.assert_array_equal(again.triangle_corners, s.triangle_corners)
    assert "meshes" not in Scene.from_json(scene_json(meshes=[])).to_json()


def test_transform_is_applied_once_with_normals_and_mirrors_keep_the_winding_outward():
    # scale x by 2, mirror y, translate z by 10 (row-major, last column = translation)
    m = [[2, 0, 0, 0], [0, -1, 0, 0], [0, 0, 1, 10], [0, 0, 0, 1]]
    tri = {
        "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
        "triangles": [[0, 1, 2]],
        "normals": [[1, 1, 0], [0, 0, 1], [0, 0, 1]],
        "transform": m,
    }
    s = Scene.from_json(scene_json(meshes=[tri]))
    mesh = s.meshes[0]
    np.testing.assert_array_equal(mesh.vertices, [[0, 0, 10], [2, 0, 10], [0, -1, 10]])
    # a mirror reverses the order of every triangle, so (v1 − v0) × (v2 − v0) keeps pointing
    # the way the untransformed triangle's did (+z here: the transform does not flip z)
    c = s.triangle_corners[0]
    assert np.cross(c[1] - c[0], c[2] - c[0])[2] > 0
    # normals by the inverse transpose: (1, 1, 0) → (1/2, −1, 0)
    np.testing.assert_allclose(mesh.normals[0], [0.5, -1.0, 0.0])
    # to_json is world space without the transform: it round-trips to the same mesh
    out = s.to_json()["meshes"][0]
    assert "transform" not in out
    np.testing.assert_array_equal(Scene.from_json(s.to_json()).meshes[0].vertices, mesh.vertices)


def test_degenerate_triangles_are_counted_kept_and_not_fatal():
    d = scene_json(
        meshes=[
            {"vertices": [[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2], [0, 0, 3], [0, 1, 3]]}
        ]
    )
    s = Scene.from_json(d)
    assert s.n_triangles == 3 and s.n_degenerate_triangles == 2
    np.testing.assert_array_equal(s.triangle_degenerate, [True, True, False])


def bad_mesh(**fields) -> dict:
    mesh = {**copy.deepcopy(QUAD), **fields}
    return scene_json(meshes=[copy.deepcopy(QUAD), mesh])


@pytest.mark.parametrize(
    "fields,path",
    [
        ({"vertices": [[0, 0, 0], [1, 0, math.nan], [1, 1, 0], [0, 1, 0]]}, "meshes[1].vertices[1]"),
        ({"vertices": [[0, 0, 0], [1, 0, math.inf], [1, 1, 0], [0, 1, 0]]}, "meshes[1].vertices[1]"),
        ({"vertices": [[0, 0, 0], [2e7, 0, 0], [1, 1, 0], [0, 1, 0]]}, "meshes[1].vertices[1]"),
        ({"vertices": [[0, 0, 0], [1, 0], [1, 1, 0], [0, 1, 0]]}, "meshes[1].vertices[1]"),
        ({"vertices": [[0, 0, 0], [1, 0, "x"], [1, 1, 0], [0, 1, 0]]}, "meshes[1].vertices[1][2]"),
        ({"vertices": [[0, 0, 0], [1, 0, True], [1, 1, 0], [0, 1, 0]]}, "meshes[1].vertices[1][2]"),
        ({"triangles": [[0, 1, 2], [0, 2, 4]]}, "meshes[1].triangles[1]"),
        ({"triangles": [[0, 1, 2], [0, -1, 3]]}, "meshes[1].triangles[1]"),
        ({"triangles": [[0, 1, 2], [0, 1.5, 3]]}, "meshes[1].triangles[1]"),
        ({"triangles": [[0, 1, 2], [0, 2]]}, "meshes[1].triangles[1]"),
        ({"triangles": [[0, 1, 2], [0, 2, 3, 1]]}, "meshes[1].triangles[1]"),
        ({"material": 2}, "meshes[1].material"),
        ({"material": True}, "meshes[1].material"),
        ({"normals": [[0, 0, 1]] * 3}, "meshes[1].normals"),
        ({"normals": [[0, 0, 1], [0, 0, 0], [0, 0, 1], [0, 0, 1]]}, "meshes[1].normals[1]"),
        ({"normals": [[0, 0, 1], [0, 0, math.nan], [0, 0, 1], [0, 0, 1]]}, "meshes[1].normals[1]"),
        ({"transform": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]}, "meshes[1].transform"),
        ({"transform": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]}, "meshes[1].transform[3]"),
        ({"transform": [[1, 0, 0, 0], [0, 1, 0, math.nan], [0, 0, 1, 0], [0, 0, 0, 1]]}, "meshes[1].transform[1][3]"),
        ({"transform": [[1, 0, 0, 0], [0, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}, "meshes[1].transform"),
        ({"transform": [[1.5e7, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}, "meshes[1].vertices[1]"),
        ({"colour": 1}, "meshes[1].colour"),
    ],
)
def test_validation_names_the_json_path(fields, path):
    with pytest.raises(SceneError) as e:
        Scene.from_json(bad_mesh(**fields))
    assert e.value.field == path, str(e.value)


def test_missing_fields_and_scene_caps():
    with pytest.raises(SceneError) as e:
        Scene.from_json(scene_json(meshes=[{"vertices": []}]))
    assert e.value.field == "meshes[0].triangles"
    with pytest.raises(SceneError) as e:
        Scene.from_json(scene_json(meshes=[QUAD] * (Scene.MAX_MESHES + 1)))
    assert e.value.field == "meshes"
    big = Mesh(np.zeros((3, 3)), np.zeros((Scene.MAX_TRIANGLES // 2 + 1, 3), np.int32))
    s = Scene.from_json(scene_json(meshes=[]))
    with pytest.raises(SceneError, match="at most"):
        s.with_geometry(s.sphere_centers, s.sphere_radii, s.sphere_materials, [big, big])


def test_arrays_are_read_only_and_numpy_input_is_accepted():
    m = make_mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]), 0)
    for a in (m.vertices, m.triangles):
        with pytest.raises(ValueError):
            a[0, 0] = 5
    assert m.triangles.dtype == np.int32 and m.vertices.dtype == np.float64
    assert MAX_COORDINATE == 1e7

"""glTF metallic-roughness materials through the service: the scene JSON's materials are a union
told apart by ``"kind"`` (absent: Phong), both in the OpenAPI schema; a PBR material is stored,
streamed back and rendered; a bad one is 422 naming its field and commits nothing; the ray engines
refuse a scene with one, naming the method."""

from __future__ import annotations

import copy

import pytest
from pocketray_server_support import SMALL

SCENE = {
    "camera": {"position": [0, 1, 8], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 50},
    "lights": [{"position": [5, 10, 10], "color": [1, 1, 1]}],
    "materials": [
        {"color": [0.8, 0.3, 0.3]},
        {"kind": "pbr", "base_color": [0.9, 0.6, 0.2], "metallic": 1.0, "roughness": 0.3},
    ],
    "spheres": [{"center": [0, 0, 0], "radius": 1, "material": 1}],
    "planes": [{"point": [0, -1, 0], "normal": [0, 1, 0], "material": 0}],
}


def post(client, scene: dict, **settings):
    return client.post("/api/sessions", json={"scene": scene, "settings": {**SMALL, **settings}})


def test_a_pbr_material_is_stored_streamed_back_and_rendered(client):
    r = post(client, SCENE)
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    got = client.get(f"/api/sessions/{sid}/scene").json()
    want = {"kind": "pbr", "base_color": [0.9, 0.6, 0.2], "alpha": 1.0, "metallic": 1.0, "roughness": 0.3, "ior": 1.5}
    assert got["materials"][1] == want
    assert "kind" not in got["materials"][0]
    assert client.put(f"/api/sessions/{sid}/scene", json=got).status_code == 200
    for integrator in ("whitted", "path"):
        frame = client.get(f"/api/sessions/{sid}/frame", params={"format": "png", "integrator": integrator})
        assert frame.status_code == 200, frame.text


@pytest.mark.parametrize(
    "change,field",
    [
        ({"metallic": 1.5}, "metallic"),
        ({"alpha_mode": "cutout"}, "alpha_mode"),
        ({"base_color_texture": 0.5}, "base_color_texture"),
        ({"kind": "glossy"}, "kind"),
        ({"shininess": 3}, "shininess"),  # a Phong parameter is no PBR one
    ],
)
def test_a_bad_pbr_material_is_refused_naming_the_field_and_commits_nothing(client, change, field):
    sid = post(client, SCENE).json()["id"]
    before = client.get(f"/api/sessions/{sid}/scene").json()
    bad = copy.deepcopy(SCENE)
    bad["materials"][1].update(change)
    for r in (post(client, bad), client.put(f"/api/sessions/{sid}/scene", json=bad)):
        assert r.status_code == 422, r.text
        assert field in r.text and "materials" in r.text
    assert client.get(f"/api/sessions/{sid}/scene").json() == before


def test_the_ray_engines_refuse_a_pbr_scene_naming_the_method(client):
    r = post(client, SCENE, method="rayengine")
    assert r.status_code == 422 and "method" in r.text and "pbr" in r.text


def test_openapi_shows_both_kinds(client):
    schemas = client.get("/openapi.json").json()["components"]["schemas"]
    assert {"MaterialModel", "PbrMaterialModel"} <= set(schemas)
    pbr = schemas["PbrMaterialModel"]["properties"]
    assert pbr["kind"]["const"] == "pbr" and pbr["metallic"]["maximum"] == 1.0
    assert pbr["alpha_mode"]["enum"] == ["opaque", "mask", "blend"]


def _textured_scene() -> dict:
    """A quad with UVs, vertex colours and a 4 × 4 checker texture on a PBR material."""
    import base64
    import io

    import numpy as np
    from PIL import Image

    checker = np.zeros((4, 4, 4), np.uint8)
    checker[..., 3] = 255
    checker[::2, ::2, :3] = checker[1::2, 1::2, :3] = 230
    buf = io.BytesIO()
    Image.fromarray(checker, "RGBA").save(buf, format="PNG")
    scene = copy.deepcopy(SCENE)
    scene["materials"].append({"kind": "pbr", "metallic": 0.0, "roughness": 0.8, "base_color_texture": 0})
    scene["textures"] = [{"png": base64.b64encode(buf.getvalue()).decode(), "srgb": True, "filter": "nearest"}]
    scene["meshes"] = [
        {
            "vertices": [[-2, -1, -1], [2, -1, -1], [2, 1, -1], [-2, 1, -1]],
            "triangles": [[0, 1, 2], [0, 2, 3]],
            "material": 2,
            "uvs": [[0, 1], [2, 1], [2, 0], [0, 0]],
            "colors": [[1, 1, 1, 1], [1, 0.5, 0.5, 1], [1, 1, 1, 1], [0.5, 0.5, 1, 1]],
        }
    ]
    return scene


def test_a_textured_scene_is_taken_streamed_back_and_put_again(client):
    """Textures and vertex attributes travel through the API's scene contract both ways: what GET
    gives, PUT takes (an uploaded textured model's scene round-trips)."""
    r = post(client, _textured_scene())
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    got = client.get(f"/api/sessions/{sid}/scene").json()
    assert (
        len(got["textures"]) == 1 and got["textures"][0]["srgb"] is True and got["textures"][0]["filter"] == "nearest"
    )
    assert got["meshes"][0]["uvs"][1] == [2, 1] and got["meshes"][0]["colors"][1] == [1, 0.5, 0.5, 1]
    assert client.put(f"/api/sessions/{sid}/scene", json=got).status_code == 200
    frame = client.get(f"/api/sessions/{sid}/frame", params={"format": "png"})
    assert frame.status_code == 200, frame.text


@pytest.mark.parametrize(
    "change,field",
    [
        (lambda s: s["textures"][0].update(png="not base64!"), "png"),
        (lambda s: s["textures"][0].update(wrap_s="tile"), "wrap_s"),
        (lambda s: s["meshes"][0].update(uvs=[[0, 0]]), "uvs"),
        (lambda s: s["meshes"][0]["colors"][0].__setitem__(0, 2.0), "colors"),
        (lambda s: s["materials"][2].update(base_color_texture=3), "base_color_texture"),
    ],
)
def test_a_bad_texture_or_vertex_attribute_is_refused_naming_it_and_commits_nothing(client, change, field):
    sid = post(client, SCENE).json()["id"]
    before = client.get(f"/api/sessions/{sid}/scene").json()
    bad = _textured_scene()
    change(bad)
    r = client.put(f"/api/sessions/{sid}/scene", json=bad)
    assert r.status_code == 422, r.text
    assert field in r.text
    assert client.get(f"/api/sessions/{sid}/scene").json() == before

"""Analytic shapes through the service: a scene of every kind (cylinders, cones, disks, tori) is
accepted, stored, streamed back and rendered — its primitive ids where the float64 reference tracer
(renderer/oracle/reference.py) puts them —; bad shapes are 422 naming the field and the accepted range, and
commit nothing; the ray engines refuse a scene with shapes naming the method; the demo scene
``table`` (analytic shapes only) is a recipe that renders in both integrators."""

from __future__ import annotations

import copy
import io
import json

import numpy as np
import pytest
from pocketray_server_support import MAX_BODY, SMALL, assert_422, make_config, snapshot
from scipy.ndimage import binary_erosion

from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Scene
from renderer.geometry.shapes import KINDS
from renderer.limits import MAX_SHAPES
from renderer.oracle.reference import render_reference
from renderer.scenes.scenarios import mesh_scene
from server.api.schemas import SceneModel
from server.faults import InputError
from server.sessions.caps import InputCaps

W, H = 48, 64
SCENE = {
    "camera": {"position": [0, 1, 14], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 50},
    "lights": [{"position": [5, 10, 10], "color": [1, 1, 1]}],
    "materials": [{"color": [0.8, 0.3, 0.3]}, {"color": [0.3, 0.8, 0.3]}],
    "spheres": [{"center": [0, 3.2, -2], "radius": 1, "material": 0}],
    "planes": [{"point": [0, -4, 0], "normal": [0, 1, 0], "material": 1}],
    "cylinders": [{"base": [-3.5, -2, 0], "axis": [0, 1, 0], "radius": 1, "height": 3, "caps": True, "material": 0}],
    "cones": [
        {"base": [3.5, -2, 0], "axis": [0, 1, 0], "base_radius": 1.2, "top_radius": 0.3, "height": 3}
        | {"caps": False, "material": 1}
    ],
    "disks": [{"center": [0, -2.5, 0], "normal": [0, 0, 1], "radius": 1.5, "inner_radius": 0.5, "material": 0}],
    "tori": [{"center": [0, 0.8, 0], "axis": [0, 0, 1], "major_radius": 1.5, "minor_radius": 0.4, "material": 1}],
}


def post(client, scene: dict, **settings):
    return client.post("/api/sessions", json={"scene": scene, "settings": {**SMALL, **settings}})


def with_shape(key: str, **change) -> dict:
    scene = copy.deepcopy(SCENE)
    scene[key][0].update(change)
    return scene


@pytest.fixture(scope="module")
def session(client) -> dict:
    r = post(client, SCENE)
    assert r.status_code == 201, r.text
    return r.json()


def test_a_scene_of_every_kind_is_stored_counted_and_streamed_back(client, session):
    info = session["scene_info"]
    assert (info["n_shapes"], info["n_spheres"], info["n_planes"], info.get("n_triangles", 0)) == (4, 1, 1, 0)
    got = client.get(f"/api/sessions/{session['id']}/scene").json()
    want = Scene.from_json(SCENE).to_json()
    assert {k: got[k] for k in KINDS} == {k: want[k] for k in KINDS}
    assert got["cones"][0]["caps"] is False and got["disks"][0]["inner_radius"] == 0.5
    # what comes back goes in again as the same scene (PUT), counted as it was
    put = client.put(f"/api/sessions/{session['id']}/scene", json=got)
    assert put.status_code == 200, put.text
    assert client.get(f"/api/sessions/{session['id']}").json()["scene_info"]["n_shapes"] == 4
    assert client.get(f"/api/sessions/{session['id']}/scene").json() == got


def test_the_frame_carries_each_shape_where_the_reference_sees_it(client, session):
    sid = session["id"]
    png = client.get(f"/api/sessions/{sid}/frame", params={"format": "png"})
    assert png.status_code == 200 and png.headers["content-type"] == "image/png"
    r = client.get(f"/api/sessions/{sid}/frame", params={"mode": "primid", "format": "npy", "method": "bih"})
    assert r.status_code == 200, r.text
    got = np.load(io.BytesIO(r.content))
    scene = Scene.from_json(SCENE)
    ref = render_reference(scene, RenderSettings(width=W, height=H, mode="primid")).primid
    assert got.shape == ref.shape == (H, W)
    for k in range(scene.n_shapes):
        sid_k = scene.shape_id_base + k
        inside = binary_erosion(ref == sid_k, iterations=1)  # away from its silhouette
        assert inside.sum() >= 3, (k, inside.sum())
        assert (got[inside] == sid_k).all(), (k, np.unique(got[inside]))
    assert (got == ref).mean() >= 0.97


@pytest.mark.parametrize(
    "key,change,field,words",
    [
        ("tori", {"minor_radius": 2.0}, "scene.tori[0].minor_radius", "< major_radius (1.5)"),
        ("tori", {"minor_radius": -0.1}, "scene.tori[0].minor_radius", "greater than 0"),
        ("tori", {"axis": [0, 0, 0]}, "scene.tori[0].axis", "non-zero"),
        ("disks", {"inner_radius": 1.5}, "scene.disks[0].inner_radius", "< radius (1.5)"),
        ("cones", {"base_radius": 0, "top_radius": 0}, "scene.cones[0].base_radius", "must be > 0"),
        ("cylinders", {"height": 0}, "scene.cylinders[0].height", "greater than 0"),
        ("cylinders", {"radius": 2e7}, "scene.cylinders[0].radius", "less than or equal to 10000000"),
        ("cylinders", {"caps": "yes"}, "scene.cylinders[0].caps", "boolean"),
        ("cylinders", {"colour": 1}, "scene.cylinders[0].colour", "Extra inputs"),
        ("disks", {"material": 2}, "scene.disks[0].material", "out of range"),
    ],
)
def test_bad_shapes_are_refused_naming_the_field_and_commit_nothing(client, session, key, change, field, words):
    before = snapshot(client, session["id"])
    r = post(client, with_shape(key, **change))
    assert_422(r, field)
    assert any(words in d["msg"] for d in r.json()["detail"]), r.text
    put = client.put(f"/api/sessions/{session['id']}/scene", json=with_shape(key, **change))
    assert_422(put, field.removeprefix("scene."))
    assert snapshot(client, session["id"]) == before


def test_too_many_shapes_are_refused(client, tmp_path):
    # The body limit comes first for a client's JSON (MAX_SHAPES records are megabytes) …
    many = {**SCENE, "disks": [SCENE["disks"][0]] * 4000}
    assert len(json.dumps(many, separators=(",", ":"))) > MAX_BODY and post(client, many).status_code == 413
    # … the cap counts all kinds together (renderer.limits.MAX_SHAPES): checked by the service's
    # own validation of the scene model, as a larger body allowed by POCKETRAY_MAX_BODY_BYTES meets it.
    half = MAX_SHAPES // 2 + 1
    disk = {"center": [0, 0, 0], "normal": [0, 0, 1], "radius": 1}
    torus = {"center": [0, 0, 0], "axis": [0, 0, 1], "major_radius": 1, "minor_radius": 0.5}
    model = SceneModel.model_validate({**SCENE, "disks": [disk] * half, "tori": [torus] * half})
    with pytest.raises(InputError) as e:
        InputCaps(make_config(tmp_path)).checked_scene(model, ("scene",))
    assert e.value.loc == ("scene", "tori") and f"at most {MAX_SHAPES} analytic shapes" in str(e.value)


def test_the_ray_engines_refuse_a_scene_with_shapes_naming_the_method(client, session):
    for method in ("rayengine", "hre"):
        r = post(client, SCENE, method=method)
        assert_422(r, "method")
        assert "analytic shape" in r.text and "bih" in r.text
    before = snapshot(client, session["id"])
    assert_422(client.patch(f"/api/sessions/{session['id']}/settings", json={"method": "hre"}), "method")
    assert snapshot(client, session["id"]) == before


def test_a_motion_over_shapes_is_counted_and_stored(client):
    scene = {**SCENE, "motions": [{"kind": "rigid", "over": "shapes", "first": 1, "count": 2}]}
    r = post(client, scene)
    assert r.status_code == 201, r.text
    info = r.json()["scene_info"]
    assert info["animated"] and info["n_moving_shapes"] == 2 and info["n_moving"] == 0
    got = client.get(f"/api/sessions/{r.json()['id']}/scene").json()
    assert got["motions"][0]["over"] == "shapes" and got["motions"][0]["first"] == 1
    frame = client.get(f"/api/sessions/{r.json()['id']}/frame", params={"time": 1.0, "format": "npy"})
    assert frame.status_code == 200, frame.text
    bad = {**SCENE, "motions": [{"kind": "incoherent", "over": "shapes", "first": 0, "count": 1}]}
    assert_422(post(client, bad), "scene.motions[0].over")


def test_the_table_is_a_recipe_of_shapes_that_renders_in_both_integrators(client):
    r = client.post("/api/sessions", json={"mesh_scene": {"kind": "table"}, "settings": SMALL})
    assert r.status_code == 201, r.text
    info = r.json()["scene_info"]
    want = mesh_scene("table")
    assert info["mesh_scene"]["kind"] == "table"
    assert info["n_shapes"] == want.n_shapes >= 10 and info.get("n_triangles", 0) == 0
    counts = want.shapes.counts()
    assert all(counts[k] >= 1 for k in KINDS), counts
    assert any(m.emits for m in want.materials) and want.lights  # a bulb for paths, a light for Whitted
    sid = r.json()["id"]
    ids = np.load(
        io.BytesIO(client.get(f"/api/sessions/{sid}/frame", params={"mode": "primid", "format": "npy"}).content)
    )
    ref = render_reference(want, RenderSettings(width=W, height=H, mode="primid")).primid
    assert (ids == ref).mean() >= 0.97
    seen = set(np.unique(ids).tolist())
    assert len(seen & set(range(want.shape_id_base, want.shape_id_base + want.n_shapes))) >= 8
    whitted = client.get(f"/api/sessions/{sid}/frame", params={"format": "npy"})
    assert whitted.status_code == 200
    lit = np.load(io.BytesIO(whitted.content))
    assert np.isfinite(lit).all() and lit.max() > 0.2
    path = client.get(
        f"/api/sessions/{sid}/frame",
        params={"format": "npy", "integrator": "path", "samples_per_pixel": 4, "max_recursion_depth": 4}
        | {"width": 24, "height": 32},  # within the test app's POCKETRAY_MAX_WORK
    )
    assert path.status_code == 200, path.text
    radiance = np.load(io.BytesIO(path.content))
    assert np.isfinite(radiance).all() and (radiance >= 0).all()
    # the bulb is seen through the shade's open bottom, or lights the table: some pixels far above the faint sky
    assert (radiance.max(axis=2) > 0.2).mean() > 0.01
    # the recipe's sky keeps the shapes
    sky = client.post("/api/sessions", json={"mesh_scene": {"kind": "table", "sky": True}, "settings": SMALL})
    assert sky.status_code == 201 and sky.json()["scene_info"]["n_shapes"] == want.n_shapes

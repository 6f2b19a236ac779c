"""The path integrator through the API: the ray engines refuse it with 422 naming the methods that
trace it, format=npy answers float32 linear radiance H × W × 3 (row 0 at the top), /api/info
declares the settings, and scenes with emission, an environment and no lights are valid."""

from __future__ import annotations

import io

import numpy as np

FURNACE = {
    "camera": {"position": [0, 0, 4], "target": [0, 0, 0], "fov_y": 34},
    "lights": [],
    "materials": [{"color": [0.5, 0.5, 0.5], "diffuse": 1, "reflective": 0, "emission": [0, 0, 0], "roughness": 0.0}],
    "spheres": [{"center": [0, 0, 0], "radius": 1}],
    "environment": {"color": [1, 1, 1]},
}


def test_path_frames_through_the_api(ready_client):
    c = ready_client
    for method in ("rayengine", "hre"):
        r = c.post("/api/render", json={"scene": FURNACE, "settings": {"method": method, "integrator": "path"}})
        assert r.status_code == 422, r.text
        detail = r.json()["detail"][0]
        assert detail["loc"][-1] == "integrator"
        assert "bih, bruteforce, bvh, kdtree, twolevel, auto" in detail["msg"]
    settings = {
        "integrator": "path",
        "width": 16,
        "height": 12,
        "format": "npy",
        "samples_per_pixel": 24,
        "max_recursion_depth": 4,
    }
    r = c.post("/api/render", json={"scene": FURNACE, "settings": settings})
    assert r.status_code == 200, r.text
    a = np.load(io.BytesIO(r.content))
    assert a.dtype == np.float32 and a.shape == (12, 16, 3)
    assert np.allclose(a[0, 0], 1.0) and np.allclose(a[6, 8], 0.5)  # the environment; the sphere's albedo
    r = c.post("/api/render", json={"scene": FURNACE, "settings": {**settings, "format": "png", "tone_map": "aces"}})
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    declared = {s["name"]: s for s in c.get("/api/info").json()["settings"]}
    assert declared["integrator"]["choices"] == ["whitted", "path"]
    assert declared["samples_per_pixel"]["maximum"] == 4096 and declared["max_recursion_depth"]["maximum"] == 16
    assert {"tone_map", "exposure"} <= set(declared)


def test_the_path_settings_contract_through_the_api(ready_client):
    """integrator ∈ {whitted, path}; with path any samples_per_pixel 1 … 4096 and max_recursion_depth
    1 … 16, each refused past its bound with a 422 naming it, and refused as a whole when width ×
    height × depth × samples exceeds POCKETRAY_MAX_WORK (a 422 naming that cap); a material's
    roughness ∈ [0, 1] and emission ≥ 0 refused naming the field; rough glass renders."""
    c = ready_client
    base = {"integrator": "path", "width": 8, "height": 8, "format": "npy", "samples_per_pixel": 4}

    def post(settings=None, material=None):
        scene = {**FURNACE, "materials": [{**FURNACE["materials"][0], **(material or {})}]}
        return c.post("/api/render", json={"scene": scene, "settings": {**base, **(settings or {})}})

    for ok in ({"samples_per_pixel": 1}, {"samples_per_pixel": 37}, {"max_recursion_depth": 16}):
        assert post(ok).status_code == 200, (ok, post(ok).text)
    refused = {
        ("integrator", "bidirectional"): "integrator",
        ("samples_per_pixel", 4097): "samples_per_pixel",
        ("samples_per_pixel", 0): "samples_per_pixel",
        ("max_recursion_depth", 17): "max_recursion_depth",
    }
    for (name, value), field in refused.items():
        r = post({name: value})
        assert r.status_code == 422 and r.json()["detail"][0]["loc"][-1] == field, (name, value, r.text)
    r = post({"integrator": "whitted", "samples_per_pixel": 37})  # Whitted's supersampling grids only
    assert r.status_code == 422 and "samples_per_pixel" in r.json()["detail"][0]["msg"]
    r = post({"samples_per_pixel": 4096, "max_recursion_depth": 16})  # 8 × 8 × 16 × 4096 > the test cap
    assert r.status_code == 422 and "POCKETRAY_MAX_WORK" in r.json()["detail"][0]["msg"], r.text
    for material, loc in (
        ({"roughness": 1.5}, ["materials", 0, "phong", "roughness"]),  # named within its kind's model
        ({"roughness": -0.1}, ["materials", 0, "phong", "roughness"]),
        ({"emission": [1, -1, 0]}, ["materials", 0, "phong", "emission", 1]),
    ):
        r = post(material=material)
        assert r.status_code == 422 and r.json()["detail"][0]["loc"][-len(loc) :] == loc, (material, r.text)
    r = post(material={"diffuse": 0, "transmissive": 1, "ior": 1.5, "roughness": 1.0})
    assert r.status_code == 200 and np.isfinite(np.load(io.BytesIO(r.content))).all()


def test_denoise_applies_to_the_images_and_to_npy_only_when_asked(ready_client):
    """``denoise=off`` is the frame as traced (byte for byte); ``oidn`` changes png and, when
    the query names it, npy; a session's own ``denoise`` leaves its npy and exr radiance as traced."""
    c = ready_client
    settings = {"integrator": "path", "width": 16, "height": 12, "samples_per_pixel": 8, "max_recursion_depth": 4}
    r = c.post("/api/sessions", json={"scene": {**FURNACE, "lights": []}, "settings": settings})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]

    def frame(**params) -> bytes:
        r = c.get(f"/api/sessions/{sid}/frame", params=params)
        assert r.status_code == 200, r.text
        return r.content

    plain = frame(format="png")
    assert frame(format="png", denoise="off") == plain
    assert frame(format="png", denoise="oidn") != plain
    raw = np.load(io.BytesIO(frame(format="npy")))
    denoised = np.load(io.BytesIO(frame(format="npy", denoise="oidn")))
    assert denoised.shape == raw.shape and not np.array_equal(denoised, raw)
    assert c.patch(f"/api/sessions/{sid}/settings", json={"denoise": "oidn"}).status_code == 200
    assert np.array_equal(np.load(io.BytesIO(frame(format="npy"))), raw), "npy: the radiance as traced"
    assert frame(format="png") == frame(format="png", denoise="oidn") != plain
    r = c.get(f"/api/sessions/{sid}/frame", params={"denoise": "nlm"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["query", "denoise"]

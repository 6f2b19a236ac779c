"""The path integrator through the API: the ray engines refuse it with 422 naming the methods that
trace it, format=npy answers float32 linear radiance H × W × 3 (row 0 at the top), /api/info
declares the settings, and scenes with emission, an environment and no lights are valid."""

from __future__ import annotations

import io

import numpy as np
import pytest

pytestmark = pytest.mark.gl

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


def test_denoise_applies_to_the_images_and_to_npy_only_when_asked(ready_client):
    """``denoise=off`` is the frame as it always was (byte for byte); ``oidn`` changes png and, when
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

"""Environment images through the API: PUT /api/sessions/{id}/environment (the file as the body)
answers the new version and the image's reference, which the scene JSON then names; a refused file
is a 422 naming it and commits nothing; DELETE goes back to a colour; the sky of the scenario and
mesh_scene recipes; device-data carries the image's textures."""

from __future__ import annotations

import io
import json
import struct

import numpy as np

from renderer.materials.envmap import write_hdr

TEXELS = np.linspace(0.0, 2.0, 8 * 16 * 3, dtype=np.float32).reshape(8, 16, 3)


def new_session(c, **body) -> str:
    r = c.post("/api/sessions", json=body or {"scenario": 1, "n": 8})
    assert r.status_code == 201, r.text
    return r.json()["id"]


def test_upload_names_the_image_and_a_refusal_commits_nothing(ready_client):
    c = ready_client
    sid = new_session(c)
    version = c.get(f"/api/sessions/{sid}").json()["version"]
    r = c.put(f"/api/sessions/{sid}/environment?format=hdr&scale=2&rotation_deg=30", content=write_hdr(TEXELS))
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["version"] > version and (out["width"], out["height"]) == (16, 8)
    env = c.get(f"/api/sessions/{sid}/scene").json()["environment"]
    assert env == {"image": out["image"], "scale": 2.0, "rotation_deg": 30.0}
    # refused files: a 422 naming the body (or the format), and the scene as it was
    for query, body, where in (
        ("format=hdr", b"#?RADIANCE\n\n-Y 100000 +X 100000\n", "body"),
        ("format=exr", write_hdr(TEXELS), "body"),
        ("format=png", write_hdr(TEXELS), "format"),
    ):
        r = c.put(f"/api/sessions/{sid}/environment?{query}", content=body)
        assert r.status_code == 422, r.text
        assert r.json()["detail"][0]["loc"][-1] == where
    assert c.get(f"/api/sessions/{sid}").json()["version"] == out["version"]
    # the reference names the held image in a replaced scene; an unknown one is refused
    scene = c.get(f"/api/sessions/{sid}/scene").json()
    assert c.put(f"/api/sessions/{sid}/scene", json=scene).status_code == 200
    scene["environment"]["image"] = "image-0000000000000000"
    r = c.put(f"/api/sessions/{sid}/scene", json=scene)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][-2:] == ["environment", "image"], r.text
    # a frame of it, path traced: the image lights the spheres
    r = c.get(f"/api/sessions/{sid}/frame?integrator=path&width=16&height=16&format=npy&samples_per_pixel=4")
    assert r.status_code == 200, r.text
    assert np.load(io.BytesIO(r.content)).mean() > 0
    r = c.delete(f"/api/sessions/{sid}/environment")
    assert r.status_code == 200
    assert "environment" not in c.get(f"/api/sessions/{sid}/scene").json()


def test_the_sky_of_the_recipes(ready_client):
    c = ready_client
    sid = new_session(c, scenario=2, n=16, sky=True)
    info = c.get(f"/api/sessions/{sid}").json()["scene_info"]
    assert info["sky"] is True and info["scenario"] == 2
    assert c.get(f"/api/sessions/{sid}/scene").json()["environment"]["image"] == "sky"
    sid = new_session(c, mesh_scene={"kind": "teapot", "detail": 0, "sky": True})
    assert c.get(f"/api/sessions/{sid}/scene").json()["environment"]["image"] == "sky"
    r = c.get(f"/api/sessions/{sid}/frame?width=16&height=16&format=npy")  # Whitted sees it on misses
    assert r.status_code == 200 and np.load(io.BytesIO(r.content))[0, 0].min() > 0.1


def test_device_data_carries_the_image(ready_client):
    c = ready_client
    sid = new_session(c, scenario=1, n=8, sky=True)
    r = c.get(f"/api/sessions/{sid}/device-data?max_texture_size=4096")
    assert r.status_code == 200, r.text
    (n,) = struct.unpack_from("<I", r.content, 8)  # server/frames/device_data.py's layout
    header = json.loads(r.content[12 : 12 + n])
    assert {"u_env_map", "u_env_cdf"} <= {t["name"] for t in header["textures"]}
    assert header["uniforms"]["u_env_size"] == [256, 128]


def test_an_image_counts_against_the_store_quota(tmp_path):
    """The image is stored beside the scene: one the quota cannot hold is a 507, and nothing is written."""
    from fastapi.testclient import TestClient
    from pocketray_server_support import make_config

    from server.app import create_app

    app = create_app(make_config(tmp_path, warmup=False, max_store_bytes=16 * 1024))
    noise = np.random.default_rng(0).random((64, 128, 3)).astype(np.float32)  # ~100 kB: does not compress
    with TestClient(app) as c:
        sid = new_session(c)
        used = app.state.store.used_bytes()
        r = c.put(f"/api/sessions/{sid}/environment?format=hdr", content=write_hdr(noise))
        assert r.status_code == 507, r.text
        assert c.get(f"/api/sessions/{sid}").json()["version"] == 1 and app.state.store.used_bytes() == used
        r = c.put(f"/api/sessions/{sid}/environment?format=hdr", content=write_hdr(TEXELS))  # small: fits
        assert r.status_code == 200 and app.state.store.used_bytes() > used


def quota_app(tmp_path, **settings):
    from pocketray_server_support import make_config

    from server.app import create_app

    return create_app(make_config(tmp_path, warmup=False, **settings))


def test_the_quota_counts_the_texels_the_service_holds(tmp_path):
    """A flat image compresses to almost nothing, but the service holds 12 bytes a texel of it:
    what the store's quota counts."""
    from fastapi.testclient import TestClient

    flat = np.full((128, 256, 3), 0.5, np.float32)
    app = quota_app(tmp_path)
    with TestClient(app) as c:
        sid = new_session(c)
        used = app.state.store.used_bytes()
        r = c.put(f"/api/sessions/{sid}/environment?format=hdr", content=write_hdr(flat))
        assert r.status_code == 200, r.text
        assert app.state.store.used_bytes() - used >= flat.nbytes


def test_an_image_the_quota_cannot_hold_is_refused_by_its_header(tmp_path, monkeypatch):
    """The size the file declares is checked against the room the quota leaves before the file is
    read: a 507 without a parse (a file cut short after its header, which the reader would refuse
    with a 422, is answered so), and nothing is written."""
    from fastapi.testclient import TestClient

    from server.sessions import service as service_module

    parsed = []
    monkeypatch.setattr(service_module, "load_env_image", lambda *a, **k: parsed.append(1))
    app = quota_app(tmp_path, max_store_bytes=1 << 20)  # 1 MiB: 512 × 256 texels are 1.5 MiB
    with TestClient(app) as c:
        sid = new_session(c)
        used = app.state.store.used_bytes()
        head = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 256 +X 512\n" + bytes([2, 2, 2, 0, 0x81])
        r = c.put(f"/api/sessions/{sid}/environment?format=hdr", content=head)
        assert r.status_code == 507, r.text
        assert "POCKETRAY_MAX_STORE_BYTES" in r.json()["detail"] and r.headers["Retry-After"]
        assert parsed == [] and app.state.store.used_bytes() == used
        assert c.get(f"/api/sessions/{sid}").json()["version"] == 1


def test_the_upload_parses_as_its_client_address(tmp_path, monkeypatch):
    """The route hands the client's address to the parse (the workers' per-address share)."""
    from fastapi.testclient import TestClient

    from server.sessions import service as service_module
    from server.sessions.model_worker import parse_client

    seen = []

    def load(config, data, fmt, busy):
        seen.append(parse_client.get())
        return np.ones((4, 8, 3), np.float32)

    monkeypatch.setattr(service_module, "load_env_image", load)
    app = quota_app(tmp_path)
    with TestClient(app) as c:
        sid = new_session(c)
        r = c.put(f"/api/sessions/{sid}/environment?format=hdr", content=write_hdr(TEXELS))
        assert r.status_code == 200, r.text
    assert seen == ["testclient"]

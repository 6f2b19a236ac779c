"""Animated scenes through the API (issue #9): museum sessions and scenes with motions, frames
posed at ``time``, update schemes per session, Server-Timing ``pose``/``update``, 422s that
name the field with nothing half-applied, and the animation surviving the store."""

from __future__ import annotations

import io

import numpy as np
import pytest
from pocketray_server_support import SMALL, make_config, wait_ready

from renderer.animation import museum, pose
from renderer.scenarios import scenario
from server.frames.device_data import decode_blob

FRAME = {"width": 40, "height": 56, "format": "npy", "mode": "primid", "max_recursion_depth": 2}


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    """The test app, with room for brute-force frames of the museum's ~600 spheres (the reference here)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from fastapi.testclient import TestClient
    from server.app import create_app

    with TestClient(create_app(make_config(tmp_path_factory.mktemp("anim"), max_frame_cost=10**6))) as c:
        yield c


@pytest.fixture(scope="module")
def ready_client(client):
    wait_ready(client.get)
    return client


def timing(header: str) -> dict[str, float]:
    return {e.split(";")[0].strip(): float(e.split("dur=")[1]) for e in header.split(",")}


def museum_session(client, n: int = 48, kind: str = "deformable", **settings) -> dict:
    r = client.post(
        "/api/sessions", json={"museum": {"n": n, "kind": kind, "seed": 2}, "settings": {**SMALL, **settings}}
    )
    assert r.status_code == 201, r.text
    return r.json()


def ids(r) -> np.ndarray:
    assert r.status_code == 200, r.text
    return np.load(io.BytesIO(r.content))


@pytest.mark.parametrize(
    "kind,method,scheme",
    [("rigid", "bvh", "refit"), ("incoherent", "bvh", "selective"), ("mixed", "twolevel", "refit")],
)
def test_session_frames_follow_the_animation_exactly(ready_client, kind, method, scheme):
    """Each frame of a session, updated from the previous one, shows what brute force shows."""
    c = ready_client
    s = museum_session(c, kind=kind, method=method, update=scheme)
    sid = s["id"]
    assert s["scene_info"]["animated"] and s["scene_info"]["n_moving"] == 48
    assert s["scene_info"]["n_spheres"] == 576 + 48
    previous = None
    for t in (0.0, 0.3, 0.6, 0.9):
        r = c.get(f"/api/sessions/{sid}/frame", params={**FRAME, "time": t})
        got = ids(r)
        stats = r.headers["x-stats"]
        assert f'"time":{t}' in stats.replace(" ", "")
        bf = ids(c.get(f"/api/sessions/{sid}/frame", params={**FRAME, "time": t, "method": "bruteforce"}))
        assert (got == bf).mean() >= 0.9999, f"{kind} t={t}"
        st = timing(r.headers["server-timing"])
        assert {"pose", "update", "trace"} <= set(st) and st["update"] >= 0
        if previous is not None:
            assert (got != previous).any(), "the scene moved between frames"
        previous = got


def test_a_frame_is_the_posed_scene(ready_client):
    """A session frame at t equals a stateless brute-force render of ``pose(museum, t)``."""
    c = ready_client
    sid = museum_session(c, n=32, kind="incoherent")["id"]
    t = 1.7
    frame = ids(c.get(f"/api/sessions/{sid}/frame", params={**FRAME, "time": t}))
    posed = pose(museum(32, "incoherent", seed=2), t).scene
    assert posed.n_spheres < 576 + 32  # incoherent: some spheres are away at t
    body = {"scene": posed.to_json(), "settings": {**FRAME, "method": "bruteforce"}}
    ref = ids(c.post("/api/render", json=body))
    assert (frame == ref).mean() >= 0.9999


def test_uploaded_scene_with_motions_round_trips(ready_client):
    c = ready_client
    d = scenario(1, 27, 0, 1.0).to_json()
    d["motions"] = [
        {"kind": "rigid", "first": 0, "count": 9, "angular_velocity": 1.0},
        {"kind": "deformable", "first": 9, "count": 9, "amplitude": 0.5},
    ]
    r = c.post("/api/sessions", json={"scene": d, "settings": SMALL})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    assert r.json()["scene_info"]["n_moving"] == 18
    back = c.get(f"/api/sessions/{sid}/scene").json()
    assert [m["kind"] for m in back["motions"]] == ["rigid", "deformable"]
    assert back["motions"][0]["angular_velocity"] == 1.0 and len(back["spheres"]) == 27
    a = ids(c.get(f"/api/sessions/{sid}/frame", params={**FRAME, "time": 0.0}))
    b = ids(c.get(f"/api/sessions/{sid}/frame", params={**FRAME, "time": 1.0}))
    assert (a != b).any()


@pytest.mark.parametrize(
    "params,field",
    [
        ({"time": -1}, "time"),
        ({"time": "nan"}, "time"),
        ({"update": "sometimes"}, "update"),
        ({"update_threshold": -0.5}, "update_threshold"),
    ],
)
def test_bad_frame_settings_are_422_naming_the_field(ready_client, params, field):
    c = ready_client
    sid = museum_session(c)["id"]
    r = c.get(f"/api/sessions/{sid}/frame", params=params)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["query", field]
    v = c.get(f"/api/sessions/{sid}").json()["version"]
    r = c.patch(f"/api/sessions/{sid}/settings", json={"time": -1e9} if field == "time" else params)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][-1] == field
    assert c.get(f"/api/sessions/{sid}").json()["version"] == v  # nothing applied


@pytest.mark.parametrize(
    "motion,loc",
    [
        ({"kind": "rigid", "first": 0, "count": 4, "axis": [0, 0, 0]}, ["body", "scene", "motions", 0, "axis"]),
        (
            {"kind": "rigid", "first": 0, "count": 4, "pivot": [9e6, 0, 0], "amplitude": [5e6, 0, 0]},
            ["body", "scene", "motions", 0],
        ),
        ({"kind": "deformable", "first": 4, "count": 40}, ["body", "scene", "motions", 0, "count"]),
        (
            {"kind": "incoherent", "first": 0, "count": 4, "box_min": [0, 0, 0], "box_max": [1, -1, 1]},
            ["body", "scene", "motions", 0, "box_max", 1],
        ),
        ({"kind": "wobble", "first": 0, "count": 4}, ["body", "scene", "motions", 0]),
    ],
)
def test_bad_motions_are_422_naming_the_field(client, motion, loc):
    d = scenario(1, 8, 0, 1.0).to_json()
    d["motions"] = [motion]
    r = client.post("/api/sessions", json={"scene": d, "settings": SMALL})
    assert r.status_code == 422, r.text
    got = r.json()["detail"][0]["loc"]
    assert got[: len(loc)] == loc, got
    # PUT scene: the same error one level up, and the session keeps its scene.
    sid = museum_session(client, n=8)["id"]
    before = client.get(f"/api/sessions/{sid}").json()
    r = client.put(f"/api/sessions/{sid}/scene", json=d)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][: len(loc) - 1] == ["body", *loc[2:]]
    assert client.get(f"/api/sessions/{sid}").json() == before


def test_one_scene_source_per_session(client):
    r = client.post("/api/sessions", json={"museum": {"n": 8}, "scenario": 1, "n": 8})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "scenario"]
    r = client.post("/api/sessions", json={"museum": {"n": 8, "kind": "sideways"}})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][:3] == ["body", "museum", "kind"]


def test_stats_and_device_data_pose_the_scene(ready_client):
    c = ready_client
    sid = museum_session(c, n=32, kind="incoherent", method="twolevel")["id"]
    st = c.get(f"/api/sessions/{sid}/stats", params={"time": 1.7}).json()
    assert st["method"] == "twolevel" and st["moving"] < 32 and st["static"] == 576
    r = c.get(f"/api/sessions/{sid}/device-data", params={"time": 1.7, "method": "bvh"})
    assert r.status_code == 200, r.text
    header, _ = decode_blob(r.content)
    assert header["settings"]["time"] == 1.7
    assert header["stats"]["primitives"] == pose(museum(32, "incoherent", seed=2), 1.7).scene.n_spheres


def test_sessions_stored_before_animation_still_work(ready_client):
    """A session whose stored settings predate time/update (an older process wrote it) renders,
    builds statistics and packs device data with the defaults."""
    import dataclasses

    c = ready_client
    sid = c.post("/api/sessions", json={"scenario": 1, "n": 8, "settings": SMALL}).json()["id"]
    new_keys = ("time", "update", "update_threshold")
    c.app.state.service.store.update(
        sid, lambda old: dataclasses.replace(old, settings={k: v for k, v in old.settings.items() if k not in new_keys})
    )
    s = c.get(f"/api/sessions/{sid}").json()["settings"]
    assert (s["time"], s["update"]) == (0.0, "rebuild")
    assert c.get(f"/api/sessions/{sid}/stats").status_code == 200
    assert c.get(f"/api/sessions/{sid}/device-data").status_code == 200
    assert c.get(f"/api/sessions/{sid}/frame", params={"format": "npy"}).status_code == 200

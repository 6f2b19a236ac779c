"""The liveness, readiness and info routes (server/api/routes/meta.py)."""

from __future__ import annotations

import math

import pytest
from pocketray_server_support import MAX_TRIANGLES


def test_health_ready_info(ready_client):
    c = ready_client
    assert c.get("/api/health").json() == {"status": "ok"}
    r = c.get("/api/ready")
    assert r.status_code == 200
    body = r.json()
    assert body["ready"] is True and body["gl_renderer"] and body["gl_version"]
    info = c.get("/api/info").json()
    assert "bih" in info["methods"] and info["limits"]["max_work"] == 96 * 128 * 2
    # What the client's form needs to show only the settings that apply.
    ms = info["method_settings"]
    assert set(ms) == set(info["methods"])
    # (integrator: the one-pass methods trace paths too; the ray engines do not)
    assert ms["bih"]["settings"] == ["max_prims", "max_tree_depth", "integrator"] and ms["bih"]["device"] is True
    assert ms["kdtree"]["settings"] == ["max_tree_depth", "integrator"]  # the SAH decides the leaves
    assert ms["bvh"]["settings"] == ["max_prims", "max_tree_depth", "update", "integrator"]
    assert ms["bruteforce"]["settings"] == ["integrator"] and ms["rayengine"]["settings"] == []
    assert ms["hre"]["settings"] == ["tile_size"] and ms["hre"]["device"] is False and "cones" in ms["hre"]["modes"]
    assert ms["auto"]["auto"] is True and ms["auto"]["settings"] == ms["bih"]["settings"]
    assert ms["bruteforce"]["tests_every_sphere"] and not ms["bih"]["tests_every_sphere"]
    assert info["samples_per_pixel"] == [1, 4, 9, 16] and info["render_timeout_s"] > 0
    assert info["museum_room_spheres"] == 576


def test_info_gives_the_legend_the_colors_of_the_modes(client):
    """The client's legend shows the colours of renderer.modes, which the shader is assembled with."""
    from renderer.modes import HEAT_SCALE, RECURSION_COLOR_NAMES, RECURSION_COLORS

    info = client.get("/api/info").json()
    assert [c["rgb"] for c in info["recursion_colors"]] == RECURSION_COLORS.tolist()
    assert [c["name"] for c in info["recursion_colors"]] == list(RECURSION_COLOR_NAMES)
    assert info["recursion_colors"][0] == {"rgb": [0.0, 0.0, 0.0], "name": "black"}  # level 0: a miss
    assert info["heat_scale"] == HEAT_SCALE


def test_info_labels_each_method_as_it_is_declared(client):
    """The client's method picker shows these labels: each is the method's own (and auto's)."""
    from renderer.config.methods import AUTO_LABEL, AUTO_METHOD, METHODS

    labels = {n: x["label"] for n, x in client.get("/api/info").json()["method_settings"].items()}
    assert labels == {**{n: m.label for n, m in METHODS.items()}, AUTO_METHOD: AUTO_LABEL}
    assert labels["bih"] == "BIH (thesis)" and len(set(labels.values())) == len(labels)


def test_info_labels_every_mode_and_names_the_averaged_ones(client):
    """The client's mode menu and device mode read these: every mode labelled, none twice."""
    from renderer.modes import AVERAGED_MODES, MODES

    info = client.get("/api/info").json()
    assert set(info["mode_labels"]) == set(MODES) == set(info["modes"])
    assert len(set(info["mode_labels"].values())) == len(MODES)
    assert info["averaged_modes"] == list(AVERAGED_MODES)


def test_info_hands_out_the_measured_profiles(client):
    from renderer.config.settings import RenderSettings
    from renderer.frame.profiles import INTERACTIVE, STILL

    info = client.get("/api/info").json()
    assert info["profiles"] == {"interactive": INTERACTIVE, "still": STILL}
    for _name, profile in info["profiles"].items():  # each is a valid set of render settings
        RenderSettings(**{k: v for k, v in profile.items() if k != "resolution_scale"})


def test_info_states_the_triangle_cap_and_what_each_method_traces(api):
    info = api.get("/api/info").json()
    assert info["limits"]["max_triangles"] == MAX_TRIANGLES
    assert info["method_settings"]["rayengine"]["primitives"] == ["spheres", "planes"]
    assert "triangles" in info["method_settings"]["bih"]["primitives"]
    assert {m for m, x in info["method_settings"].items() if x["meshes_on_gpu"]} == {
        "bih",
        "bruteforce",
        "bvh",
        "kdtree",
        "twolevel",
        "auto",
    }
    assert math.isfinite(api.get("/api/info").json()["limits"]["max_frame_cost"])


def test_info_gives_a_client_the_path_counts_and_how_the_service_counts_a_path_frames_work(client):
    """A settings sheet offers the path integrator's sample counts and depths and refuses what the work
    cap refuses: the segments a sample traces at each depth, computed from /api/info's numbers as the
    client does (ui/limits.js), are renderer/frame/cost.py's, the cap's count."""
    from renderer.frame.cost import path_segments, request_work

    info = client.get("/api/info").json()
    p = info["path"]
    assert p["samples_per_pixel"] == [1, 4, 16, 64, 256, 1024] and p["max_depth"] == 16 and p["max_samples"] == 4096
    assert info["max_recursion_depth"] == 8
    for d in range(1, p["max_depth"] + 1):
        mine = min(2 * d - 1, p["segments_limit"] - (p["segments_limit"] - 1) * p["segments_rate"] ** (d - 1))
        assert mine == pytest.approx(path_segments(d), rel=1e-12)
        assert 126 * 272 * 64 * mine == pytest.approx(request_work(126, 272, d, 64, path=True), rel=1e-12)


def test_info_lists_the_demo_scenes_in_picker_order_with_their_settings(client):
    from renderer.scenes.scenarios import DEMO_SCENES

    scenes = client.get("/api/info").json()["scenes"]
    assert [s["value"] for s in scenes] == [d.value for d in DEMO_SCENES]
    by = {s["value"]: s for s in scenes}
    assert by["mesh:cornell"]["settings"] == {"integrator": "path", "denoise": "oidn"}
    assert by["mesh:table"]["settings"]["integrator"] == "path" and by["sky:2"]["settings"]["integrator"] == "path"
    assert by[1]["settings"] == {} and by[1]["recipe"]["scenario"] == 1
    assert [s["value"] for s in scenes if s.get("default")] == ["mesh:spheres"]
    # each recipe is a body POST /api/sessions takes
    for s in scenes:
        r = client.post("/api/sessions", json={**s["recipe"], "settings": {"width": 48, "height": 64}, "aspect": 0.5})
        assert r.status_code == 201, (s["value"], r.text)
        assert all(r.json()["settings"][k] == v for k, v in s["settings"].items())


def test_info_declares_what_each_integrator_accepts_and_the_older_keys_agree(client):
    """settings[].integrators (what the client's sheet lists and bounds) says Whitted's sub-pixel grids
    and the path integrator's counts; the keys a client read before (samples_per_pixel, path) say the same."""
    info = client.get("/api/info").json()
    by = {s["name"]: s for s in info["settings"]}
    spp = by["samples_per_pixel"]["integrators"]
    assert spp["whitted"]["choices"] == spp["whitted"]["offered"] == info["samples_per_pixel"] == [1, 4, 9, 16]
    assert spp["whitted"]["subpixel_grid"] and not spp["path"]["subpixel_grid"]
    assert (spp["path"]["minimum"], spp["path"]["maximum"]) == (1, info["path"]["max_samples"])
    assert spp["path"]["offered"] == info["path"]["samples_per_pixel"]
    depth = by["max_recursion_depth"]["integrators"]
    assert (depth["whitted"]["maximum"], depth["path"]["maximum"]) == (
        info["max_recursion_depth"],
        info["path"]["max_depth"],
    )
    assert "recursion" not in depth["path"]["modes"] and "color" in depth["path"]["modes"]
    assert by["width"]["integrators"] is None

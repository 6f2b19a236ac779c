"""``pocketray`` (server/tools/cli.py): scenario → scene JSON as the API writes it, render with the
API's settings and validation (png, jpeg, npy, exr), the serve flags from ServerConfig, the
GPU list, and ``serve --workers 2`` (uvicorn by import string: two processes, two GL
contexts, one /metrics summing both)."""

from __future__ import annotations

import argparse
import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
import pytest
from PIL import Image
from pocketray_server_support import ROOT, free_port, pocketray, pocketray_batch

from server.frames.exr import decode_exr
from server.tools import cli

pytestmark = [pytest.mark.gl, pytest.mark.long]  # render runs GLRenderer, serve a GL worker

# Commands whose subject is what they write or refuse run several to a process (pocketray_batch:
# server.tools.cli.main as ``python -m server`` calls it, the start-up paid once); ``pocketray`` itself as
# a process of its own (its exit status from sys.exit included) is run by the serve and devices
# tests below.


def test_scenario_writes_the_scene_json_the_api_serves(tmp_path, client):
    written, museum, sky, no_sky = pocketray_batch(
        [
            ("scenario", "3", "--n", "100", "--seed", "7", "-o", "s.json"),
            ("scenario", "museum", "--n", "32", "--kind", "rigid"),
            ("scenario", "2", "--n", "16", "--sky", "-o", "sky.json"),
            ("scenario", "museum", "--n", "32", "--sky"),
        ],
        cwd=tmp_path,
    )
    assert written.returncode == 0, written.stderr
    written = json.loads((tmp_path / "s.json").read_text())
    sid = client.post("/api/sessions", json={"scenario": 3, "n": 100, "seed": 7}).json()["id"]
    assert written == client.get(f"/api/sessions/{sid}/scene").json()
    # the sky: the same scene JSON as the API's recipe; not for the museum
    assert sky.returncode == 0, sky.stderr
    sid = client.post("/api/sessions", json={"scenario": 2, "n": 16, "sky": True}).json()["id"]
    assert json.loads((tmp_path / "sky.json").read_text()) == client.get(f"/api/sessions/{sid}/scene").json()
    assert no_sky.returncode != 0 and "not the museum" in no_sky.stderr
    doc = json.loads(museum.stdout)
    assert doc["motions"] and doc["motions"][0]["kind"] == "rigid" and len(doc["spheres"]) > 32


def test_render_writes_each_format_and_agrees_with_the_api(tmp_path, client):
    scene = {"materials": [{}], "spheres": [{"center": [0, 0, 0], "radius": 20}, {"center": [25, 5, 0], "radius": 6}]}
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    common = ["--width", "40", "--height", "30", "--depth", "2", "--spp", "1"]
    outs = ("a.png", "a.jpg", "a.npy", "p.npy", "z.exr", "n.exr", "c.exr", "i.exr")
    modes = [{"p": "primid", "z": "depth", "n": "normal", "i": "primid"}.get(out[0], "color") for out in outs]
    done = pocketray_batch(
        [
            ("render", "scene.json", "-o", out, "--mode", mode, *common, "--quiet")
            for out, mode in zip(outs, modes, strict=True)
        ],
        cwd=tmp_path,
    )
    for out, r in zip(outs, done, strict=True):
        assert r.returncode == 0 and r.stderr == "", (out, r.stderr)
    assert Image.open(tmp_path / "a.png").size == (40, 30) and Image.open(tmp_path / "a.jpg").format == "JPEG"
    api = client.post(
        "/api/render",
        json={
            "scene": scene,
            "settings": {"width": 40, "height": 30, "max_recursion_depth": 2, "samples_per_pixel": 1, "format": "npy"},
        },
    )
    assert np.array_equal(np.load(tmp_path / "a.npy"), np.load(io.BytesIO(api.content)))
    primid = np.load(tmp_path / "p.npy")
    assert np.array_equal(decode_exr((tmp_path / "i.exr").read_bytes())["id"].view(np.int32), primid)
    z = decode_exr((tmp_path / "z.exr").read_bytes())["Z"]
    assert z.shape == (30, 40) and np.isinf(z[primid < 0]).all() and np.isfinite(z[primid >= 0]).all()
    assert decode_exr((tmp_path / "n.exr").read_bytes())["RGB"].shape == (30, 40, 3)
    color = decode_exr((tmp_path / "c.exr").read_bytes())["RGB"]
    assert (
        color.dtype == np.float32
        and np.abs(np.floor(np.clip(color, 0, 1) * 255 + 0.5) - np.load(tmp_path / "a.npy")).max() == 0
    )


def test_render_rejects_what_the_api_rejects_naming_the_field(tmp_path):
    (tmp_path / "s.json").write_text(json.dumps({"materials": [{}], "spheres": [{"center": [0, 0, 0], "radius": 1}]}))
    cases = {
        ("--width", "0"): "width",
        ("--spp", "3"): "samples_per_pixel",
        ("--method", "nope"): "method",
        ("--mode", "cones"): "mode",
        ("--min-weight", "nan"): "min_weight",
    }
    *refused, bad, gif = pocketray_batch(
        [("render", "s.json", "-o", "x.png", *flags) for flags in cases]
        + [
            (
                ("render", "-", "-o", "x.png"),
                json.dumps({"materials": [{}], "spheres": [{"center": [0, 0, 0], "radius": -1}]}),
            ),
            ("render", "s.json", "-o", "x.gif"),
        ],
        cwd=tmp_path,
    )
    for (flags, field), r in zip(cases.items(), refused, strict=True):
        assert r.returncode == 2 and field in r.stderr, (flags, r.stderr)
    assert bad.returncode == 2 and "scene.spheres.0.radius" in bad.stderr
    assert gif.returncode == 2
    assert not (tmp_path / "x.png").exists()


def test_serve_has_a_flag_for_every_config_field_and_validates_them_before_starting(tmp_path):
    text = cli.parser().format_help() + pocketray("serve", "--help", cwd=tmp_path).stdout
    for name in (
        "--workers",
        "--host",
        "--port",
        "--state-backend",
        "--gpu",
        "--cors-origins",
        "--drain-s",
        "--queue-size",
        "--log-format",
    ):
        assert name in text
    r = pocketray("serve", "--state-backend", "mongodb", cwd=tmp_path)  # a process's exit status 2
    assert r.returncode == 2 and "state_backend" in r.stderr


def test_gpus_lists_the_gpu_the_context_uses(tmp_path):
    r = pocketray("gpus", "--probe", "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    found = json.loads(r.stdout)
    assert found and found[0]["index"] == 0 and found[0]["gl_renderer"]
    old = pocketray("devices", "--json", cwd=tmp_path)  # the command's old name still works
    assert old.returncode == 0 and [d["index"] for d in json.loads(old.stdout)] == [d["index"] for d in found]


def test_the_gpu_index_keeps_its_old_names(monkeypatch):
    """POCKETRAY_GPU / --gpu were POCKETRAY_GL_DEVICE / --gl-device: deployed configurations
    that set the old names keep working ("device" is the browser's own tracer now)."""
    from server.config import ServerConfig

    for name in ("POCKETRAY_GPU", "POCKETRAY_GL_DEVICE"):
        monkeypatch.delenv(name, raising=False)
    assert ServerConfig().gpu is None and ServerConfig(gpu=2).gpu == 2
    monkeypatch.setenv("POCKETRAY_GL_DEVICE", "1")
    assert ServerConfig().gpu == 1
    monkeypatch.setenv("POCKETRAY_GPU", "3")  # the new name wins
    assert ServerConfig().gpu == 3
    p = cli.parser()
    assert p.parse_args(["serve", "--gl-device", "1"]).cfg_gpu == "1"
    assert p.parse_args(["serve", "--gpu", "2"]).cfg_gpu == "2"
    commands = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction)).choices
    assert "--gpu" in commands["serve"].format_help() and "--gl-device" not in commands["serve"].format_help()


def test_serve_with_two_workers_runs_two_gl_processes_and_one_metrics_endpoint(tmp_path):
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("POCKETRAY_")}
    log = open(tmp_path / "serve.log", "wb")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "server",
            "serve",
            "--workers",
            "2",
            "--port",
            str(port),
            "--sqlite-path",
            str(tmp_path / "s.sqlite3"),
            "--default-render",
            '{"width": 32, "height": 32, "max_recursion_depth": 2, "samples_per_pixel": 1}',
        ],
        cwd=ROOT,
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 120
        while True:
            text = (tmp_path / "serve.log").read_text()
            if text.count('"OpenGL: ') >= 2 and text.count("warm-up render took") >= 2:
                break
            assert proc.poll() is None and time.monotonic() < deadline, text[-3000:]
            time.sleep(0.2)
        children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()
        workers = [pid for pid in children if b"resource_tracker" not in Path(f"/proc/{pid}/cmdline").read_bytes()]
        assert len(workers) == 2
        frames = 6
        with httpx.Client(base_url=url, timeout=60) as c:
            sid = c.post("/api/sessions", json={"scenario": 1, "n": 8}).json()["id"]
            for _ in range(frames):
                assert c.get(f"/api/sessions/{sid}/frame").status_code == 200
        rendered = 0.0
        for _ in range(4):  # whichever worker answers the scrape, it reports both
            with httpx.Client(base_url=url, timeout=30) as c:  # a new connection: maybe the other worker
                text = c.get("/metrics").text
            rendered = sum(
                float(line.rsplit(" ", 1)[1])
                for line in text.splitlines()
                if line.startswith("pocketray_renders_total{")
            )
            assert rendered == frames, text
        lines = [json.loads(line) for line in (tmp_path / "serve.log").read_text().splitlines() if line.startswith("{")]
        assert any(line.get("logger", "").startswith("uvicorn") for line in lines)  # uvicorn's lines are JSON too
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()


def test_render_traces_paths_to_exr(tmp_path):
    """``pocketray render scene.json --integrator path --spp 64 -o out.exr``: linear radiance, the
    environment where rays miss, a diffuse sphere's albedo in the white furnace (no variance: every
    bounce leaves the convex sphere); the ray engines and Whitted's bounds refuse it naming the field."""
    scene = {
        "camera": {"position": [0, 0, 4], "target": [0, 0, 0], "fov_y": 34},
        "lights": [],
        "materials": [{"color": [0.5, 0.6, 0.7], "diffuse": 1, "reflective": 0, "ambient": 0}],
        "spheres": [{"center": [0, 0, 0], "radius": 1}],
        "environment": {"color": [1, 1, 1]},
    }
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    size = ("--width", "16", "--height", "12")
    done, engine, whitted = pocketray_batch(
        [
            ("render", "scene.json", "--integrator", "path", "--spp", "64", "-o", "out.exr", *size, "--quiet"),
            ("render", "scene.json", "--integrator", "path", "--method", "hre", "-o", "no.exr", *size),
            ("render", "scene.json", "--spp", "64", "-o", "no.exr", *size),
        ],
        cwd=tmp_path,
    )
    assert done.returncode == 0 and done.stderr == "", done.stderr
    rgb = decode_exr((tmp_path / "out.exr").read_bytes())["RGB"]
    assert rgb.dtype == np.float32 and rgb.shape == (12, 16, 3)
    assert np.allclose(rgb[0, 0], 1.0) and np.allclose(rgb[6, 8], [0.5, 0.6, 0.7], rtol=1e-5)
    assert engine.returncode == 2 and "integrator" in engine.stderr and "bih" in engine.stderr
    assert whitted.returncode == 2 and "samples_per_pixel" in whitted.stderr
    assert not (tmp_path / "no.exr").exists()


def test_scenario_help_lists_every_demo_scene_and_writes_each(tmp_path):
    from renderer.scenes.scenarios import DEMO_SCENES

    text = pocketray("scenario", "--help", cwd=tmp_path).stdout
    for name in ("spheres", "teapot", "mixed", "room", "cornell", "table", "museum"):
        assert name in text, name
    for d in DEMO_SCENES:
        assert d.label in text, d.label
    assert "--integrator path --denoise oidn" in text  # the Cornell box's and the table's recommendation
    spheres = pocketray_batch([("scenario", "spheres", "-o", str(tmp_path / "s.json"))], cwd=tmp_path)[0]
    assert spheres.returncode == 0, spheres.stderr
    assert json.loads((tmp_path / "s.json").read_text())["environment"]["image"] == "sky"


def test_render_help_states_the_spp_default_and_the_side_limit(tmp_path):
    text = " ".join(pocketray("render", "--help", cwd=tmp_path).stdout.split())
    assert "Default 4" in text and "≤ 4096 pixels" in text and "16 needs a side ≤ 1024" in text


def test_the_start_line_names_the_address_to_open():
    assert cli.start_line("127.0.0.1", 8000) == "pocketray: open http://127.0.0.1:8000/ (API: /docs)"
    assert "http://127.0.0.1:8123/" in cli.start_line("0.0.0.0", 8123)
    assert "this machine's address" in cli.start_line("0.0.0.0", 8123)
    assert cli.start_line("::1", 9) == "pocketray: open http://[::1]:9/ (API: /docs)"


def test_serve_prints_the_address_before_its_json_logs(tmp_path):
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("POCKETRAY_")}
    proc = subprocess.Popen(
        [sys.executable, "-m", "server", "serve", "--port", str(port), "--sqlite-path", str(tmp_path / "s.sqlite3")],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stderr is not None
        first = proc.stderr.readline().strip()
    finally:
        # SIGTERM, not SIGINT: a shell starts a background job with SIGINT ignored, and a child keeps
        # that until uvicorn installs its handlers, so a Ctrl-C sent during start-up would go unseen.
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    assert first == f"pocketray: open http://127.0.0.1:{port}/ (API: /docs)"

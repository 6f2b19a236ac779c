"""``pip install .`` as a new user does it: the wheel is built from the tracked files alone, holds
every module, the shaders and the client, and — installed into a fresh virtual environment —
renders from the command line and serves the client and the API from a directory outside the
source tree, keeping its state there.

The fresh venv gets the wheel itself with ``--no-deps``; its dependencies are this project's
``.venv`` site-packages, appended to its path by a ``.pth`` file (the tests run offline and in
seconds; the editable install there is not on that path: a ``.pth`` line adds a directory, it
does not run that directory's own ``.pth`` files). Every ``renderer``/``server`` module the
commands import must come from the fresh venv — the test checks.
"""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import time
import zipfile
from pathlib import Path

import httpx
import numpy as np
import pytest

from tests.helpers import ROOT

pytestmark = pytest.mark.gl  # the installed commands render


def tracked(*dirs: str) -> list[str]:
    out = subprocess.run(["git", "ls-files", *dirs], cwd=ROOT, capture_output=True, text=True, check=True)
    return [line for line in out.stdout.splitlines() if line]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel of a clean copy of the tracked files (no build/ or egg-info of the checkout)."""
    src = tmp_path_factory.mktemp("src")
    for rel in tracked():
        if (ROOT / rel).is_file():
            (src / rel).parent.mkdir(parents=True, exist_ok=True)
            (src / rel).write_bytes((ROOT / rel).read_bytes())
    out = tmp_path_factory.mktemp("wheel")
    run = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(src)],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    (whl,) = out.glob("pocketray-*.whl")
    return whl


@pytest.fixture(scope="module")
def venv(wheel, tmp_path_factory) -> Path:
    env_dir = tmp_path_factory.mktemp("venv")
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(env_dir)], check=True)
    py = env_dir / "bin" / "python"
    site = Path(
        subprocess.run(
            [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    )
    (site / "pocketray-deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    run = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "-q", str(wheel)],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    return env_dir


def test_the_wheel_holds_every_module_the_shaders_and_the_client(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    want = {p for p in tracked("renderer", "server") if p.endswith(".py")}
    want |= {"renderer/shaders/" + Path(p).name for p in tracked("shaders")}
    want |= {"server/client_web/" + p[len("client_web/") :] for p in tracked("client_web")}
    assert want - names == set()
    entry = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith("entry_points.txt"))).decode()
    assert "pocketray = server.tools.cli:main" in entry
    assert not any(n.startswith(("tests/", "bench/", "shaders/", "client_web/")) for n in names)


def run_cmd(venv: Path, cwd: Path, *args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("POCKETRAY_") and k != "PYTHONPATH"}
    return subprocess.run(
        [str(venv / "bin" / "pocketray"), *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout
    )


def test_installed_pocketray_renders_from_the_command_line_outside_the_source_tree(venv, tmp_path):
    r = run_cmd(venv, tmp_path, "scenario", "2", "--n", "512", "--seed", "3", "-o", "scene.json")
    assert r.returncode == 0, r.stderr
    r = run_cmd(
        venv,
        tmp_path,
        "render",
        "scene.json",
        "-o",
        "frame.png",
        "--width",
        "64",
        "--height",
        "96",
        "--depth",
        "2",
        "--spp",
        "1",
    )
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "frame.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    r = run_cmd(
        venv, tmp_path, "render", "scene.json", "-o", "depth.npy", "--mode", "depth", "--width", "32", "--height", "32"
    )
    assert r.returncode == 0, r.stderr
    assert np.load(tmp_path / "depth.npy").shape == (32, 32)
    # where the modules and the shaders came from
    where = subprocess.run(
        [
            str(venv / "bin" / "python"),
            "-c",
            "import renderer.frame.shader_source as s, server.tools.cli, server.resources as r; "
            "print(s.__file__); print(s.SHADER_DIR); print(r.client_dir()); print(server.tools.cli.__file__)",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    for path in where:
        assert Path(path).is_relative_to(venv), where


def test_installed_pocketray_serves_the_client_and_keeps_state_in_the_working_directory(venv, tmp_path):
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {k: v for k, v in os.environ.items() if not k.startswith("POCKETRAY_") and k != "PYTHONPATH"}
    log = open(tmp_path / "serve.log", "wb")
    proc = subprocess.Popen(
        [str(venv / "bin" / "pocketray"), "serve", "--port", str(port), "--log-level", "warning"],
        cwd=tmp_path,
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 90
        while True:
            assert proc.poll() is None, (tmp_path / "serve.log").read_text()[-3000:]
            try:
                if httpx.get(url + "/api/ready", timeout=2).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            assert time.monotonic() < deadline, (tmp_path / "serve.log").read_text()[-3000:]
            time.sleep(0.2)
        with httpx.Client(base_url=url, timeout=60) as c:
            index = c.get("/")
            assert index.status_code == 200 and "<html" in index.text.lower()
            assert c.get("/js/api.js").status_code == 200
            assert "void main" in c.get("/shaders/raytrace.frag").text
            sid = c.post(
                "/api/sessions",
                json={
                    "scenario": 1,
                    "n": 27,
                    "settings": {"width": 32, "height": 48, "max_recursion_depth": 2, "samples_per_pixel": 1},
                },
            ).json()["id"]
            frame = c.get(f"/api/sessions/{sid}/frame")
            assert frame.status_code == 200 and frame.headers["content-type"] == "image/png"
            assert c.get("/docs").status_code == 200
            assert "pocketray_renders_total" in c.get("/metrics").text
        assert (tmp_path / "var" / "sessions.sqlite3").is_file()
    finally:
        proc.terminate()
        proc.wait(timeout=30)
        log.close()

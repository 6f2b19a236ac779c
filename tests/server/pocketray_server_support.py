"""Helpers of the server tests (imported by conftest.py and the test modules)."""

from __future__ import annotations

import io
import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import httpx
import numpy as np
import pytest

from renderer.geometry.meshes import box, icosphere
from renderer.scenes.scenarios import scenario
from server.config import ServerConfig

ROOT = Path(__file__).resolve().parents[2]

# Small caps for tests: renders of at most 96×128 pixels at depth 2 (or 64×96 at 4).
# One sample per pixel and no cut-off (not the service's "still" default): frames comparable with references.
SMALL = {"width": 48, "height": 64, "max_recursion_depth": 2, "samples_per_pixel": 1, "min_weight": 0.0}
TEST_CAPS = dict(
    max_work=96 * 128 * 2,
    max_spheres=4096,
    max_frame_cost=2_000.0,
    queue_size=4,
    max_body_bytes=256 * 1024,
    default_render=SMALL,
)
# A refinement stream a generated request asks for (the schemathesis test) ends within 2 s.
TEST_CAPS["max_refine_ms"] = 2000
# A test module creates sessions from one address faster than a client does: no creation rate here
# (tests/server/sessions/test_ratelimit.py sets and tests it).
TEST_CAPS["session_create_per_min"] = 0
# … and its sessions walk through more shader variants than a client does: no rate of new variants
# here either (tests/server/test_variant_rate.py sets and tests it).
TEST_CAPS["new_variants_per_min"] = 0


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def make_config(tmp: Path, **overrides) -> ServerConfig:
    kw = dict(TEST_CAPS, sqlite_path=tmp / "sessions.sqlite3")
    kw.update(overrides)
    return ServerConfig(**kw)


def wait_ready(get: Callable[[str], httpx.Response], timeout_s: float = 60.0) -> dict:
    """Wait for /api/ready; fail (never skip) when GL does not come up."""
    deadline = time.monotonic() + timeout_s
    last = None
    while time.monotonic() < deadline:
        r = get("/api/ready")
        last = r
        if r.status_code == 200:
            return r.json()
        body = r.json()
        if body.get("detail", "").startswith(("OpenGL unavailable", "warm-up render failed")):
            break
        time.sleep(0.1)
    pytest.fail(f"the service never became ready (OpenGL is required): {last.text if last else 'no answer'}")


def new_session(client, **body) -> dict:
    payload = {"scenario": 3, "n": 64, "seed": 1, "radius": 1.0, "settings": dict(SMALL)}
    payload.update(body)
    r = client.post("/api/sessions", json=payload)
    assert r.status_code == 201, r.text
    return r.json()


class ServerProcess:
    """One ``python -m server`` child process."""

    def __init__(self, env: dict[str, str], log_path: Path):
        self.port = int(env["POCKETRAY_PORT"])
        self.url = f"http://127.0.0.1:{self.port}"
        self.env = env
        self.log_path = log_path
        self.proc: subprocess.Popen | None = None

    def start(self, timeout_s: float = 60.0) -> ServerProcess:
        self.log = open(self.log_path, "ab")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "server"], cwd=ROOT, env=self.env, stdout=self.log, stderr=subprocess.STDOUT
        )
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                pytest.fail(f"server exited with {self.proc.returncode}: {self.log_path.read_text()[-3000:]}")
            try:
                if httpx.get(self.url + "/api/health", timeout=1.0).status_code == 200:
                    return self
            except httpx.HTTPError:
                pass
            time.sleep(0.1)
        pytest.fail(f"server did not answer /api/health: {self.log_path.read_text()[-3000:]}")

    def wait_ready(self) -> dict:
        return wait_ready(lambda p: httpx.get(self.url + p, timeout=5.0))

    def kill(self, sig: int = signal.SIGKILL) -> None:
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if getattr(self, "log", None):
            self.log.close()


def cli_env() -> dict[str, str]:
    """The environment of a ``python -m server`` command: no POCKETRAY_* of ours, this checkout first."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("POCKETRAY_")}
    env["PYTHONPATH"] = str(ROOT)  # this checkout's server, not whichever one the environment installed
    return env


def pocketray(*args: str, cwd: Path, stdin: str | None = None) -> subprocess.CompletedProcess:
    """``pocketray ARGS`` as a user runs it: ``python -m server ARGS``, a process of its own."""
    return subprocess.run(
        [sys.executable, "-m", "server", *args],
        cwd=cwd,
        env=cli_env(),
        input=stdin,
        capture_output=True,
        text=True,
        timeout=300,
    )


# One process running several commands one after the other, each through server.tools.cli.main as
# ``python -m server`` runs it (server/__main__.py: sys.exit(main(argv))): its exit status is
# main's return value, or SystemExit's code (argparse's usage errors), or 1 with the traceback
# on stderr for any other exception; stdin, stdout and stderr are the command's own.
_BATCH = r"""
import contextlib, io, json, sys, traceback
from server.tools import cli
out = []
for argv, stdin in json.loads(sys.stdin.read()):
    so, se = io.TextIOWrapper(io.BytesIO(), encoding="utf-8"), io.StringIO()   # stdout has a .buffer
    sys.stdin = io.StringIO(stdin or "")
    with contextlib.redirect_stdout(so), contextlib.redirect_stderr(se):
        try:
            code = cli.main(argv)
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
        except BaseException:
            traceback.print_exc()
            code = 1
    so.flush()
    out.append({"returncode": code, "stdout": so.buffer.getvalue().decode(), "stderr": se.getvalue()})
sys.stdout = sys.__stdout__
print(json.dumps(out))
"""


def pocketray_batch(
    commands: list[tuple[str, ...] | tuple[tuple[str, ...], str]], cwd: Path
) -> list[subprocess.CompletedProcess]:
    """``pocketray`` commands run in order in one ``python -m``-like process (its start-up, the
    imports, paid once): each gives what :func:`pocketray` would, a CompletedProcess with its
    exit status, stdout and stderr. A command is its arguments, or (arguments, stdin text)."""
    calls = [(list(c[0]), c[1]) if len(c) == 2 and isinstance(c[0], tuple) else (list(c), None) for c in commands]
    proc = subprocess.run(
        [sys.executable, "-c", _BATCH],
        cwd=cwd,
        env=cli_env(),
        input=json.dumps(calls),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    results = json.loads(proc.stdout.strip().splitlines()[-1])
    return [
        subprocess.CompletedProcess(["pocketray", *argv], r["returncode"], r["stdout"], r["stderr"])
        for (argv, _), r in zip(calls, results, strict=True)
    ]


def server_env(sqlite_path: Path, port: int | None = None, **settings) -> dict[str, str]:
    """The environment of a test server process: TEST_CAPS plus ``settings`` as POCKETRAY_*."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("POCKETRAY_")}
    conf = {**TEST_CAPS, "sqlite_path": str(sqlite_path), "log_level": "warning", **settings}
    env.update({f"POCKETRAY_{k.upper()}": json.dumps(v) if isinstance(v, dict) else str(v) for k, v in conf.items()})
    env["POCKETRAY_PORT"] = str(port or free_port())
    env["POCKETRAY_HOST"] = "127.0.0.1"
    return env


# ---- helpers of the route and body tests ------------------------------------------------------------


def timing(header: str) -> dict[str, float]:
    out = {}
    for entry in header.split(","):
        name, *params = entry.strip().split(";")
        for p in params:
            k, v = p.split("=")
            if k == "dur":
                out[name] = float(v)
    return out


def small_scene_json(n: int = 8) -> dict:
    return scenario(1, n, 0, 1.0).to_json()


GOOD_CAMERA = {"position": [0, 0, 100], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 60}


def scene_with(**camera) -> dict:
    s = scenario(1, 2, 0, 1.0).to_json()
    s["camera"] = {**GOOD_CAMERA, **camera}
    return s


def raw(text: str) -> dict:
    """A JSON body the way a careless client writes it (NaN / Infinity literals allowed)."""
    return {"content": text.encode(), "headers": {"content-type": "application/json"}}


def assert_422(r, field: str) -> None:
    """422 naming ``field`` in a message (a list of errors with loc/msg/type, or one detail)."""
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    msgs = [d["msg"] for d in detail] if isinstance(detail, list) else [detail]
    assert any(field in m for m in msgs), f"{field!r} not named in {msgs}"
    if isinstance(detail, list):
        assert all({"loc", "msg", "type"} <= set(d) for d in detail)


def snapshot(client, sid: str) -> tuple:
    s = client.get(f"/api/sessions/{sid}").json()
    scene = client.get(f"/api/sessions/{sid}/scene").json()
    return s, scene


def state_of(c, sid: str) -> dict:
    return c.get(f"/api/sessions/{sid}").json()


def raw_json(text: str | bytes) -> dict:
    return {
        "content": text.encode() if isinstance(text, str) else text,
        "headers": {"content-type": "application/json"},
    }


def assert_422_listing(r, field: str, kind: str | None = None) -> list[dict]:
    """422 whose list of errors names ``field`` (and has one of type ``kind``); the list back."""
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert any(field in d["msg"] for d in detail), f"{field!r} not named in {detail}"
    if kind is not None:
        assert any(d["type"] == kind for d in detail), detail
    return detail


# ---- the meshes and the museum through the API (api/routes/conftest.py's apps) ------------------------

MAX_TRIANGLES = 3000  # POCKETRAY_MAX_TRIANGLES of the meshes app (api/routes/conftest.py's ``api``)
MAX_BODY = 256 * 1024  # and its POCKETRAY_MAX_BODY_BYTES


def mesh_scene_json(**mesh) -> dict:
    ball = icosphere(1, radius=5.0).to_json()
    cube = {
        "vertices": box((-1, -1, -1), (1, 1, 1)).vertices.tolist(),
        "triangles": box((-1, -1, -1), (1, 1, 1)).triangles.tolist(),
        "material": 1,
        "transform": [[2, 0, 0, 10], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]],
    }
    cube.update(mesh)
    return {
        "materials": [{}, {"color": [0.2, 0.5, 0.9]}],
        "spheres": [{"center": [-12, 0, 0], "radius": 2}],
        "planes": [{"point": [0, -20, 0], "normal": [0, 1, 0]}],
        "meshes": [ball, cube],
    }


def create(api, scene: dict, **settings):
    return api.post("/api/sessions", json={"scene": scene, "settings": {**SMALL, **settings}})


def assert_422_msgs(r, field: str) -> None:
    """422 whose list of errors names ``field`` in a message."""
    assert r.status_code == 422, r.text
    msgs = [d["msg"] for d in r.json()["detail"]]
    assert any(field in m for m in msgs), f"{field!r} not named in {msgs}"


MUSEUM_FRAME = {"width": 40, "height": 56, "format": "npy", "mode": "primid", "max_recursion_depth": 2}


def museum_session(client, n: int = 48, kind: str = "deformable", **settings) -> dict:
    r = client.post(
        "/api/sessions", json={"museum": {"n": n, "kind": kind, "seed": 2}, "settings": {**SMALL, **settings}}
    )
    assert r.status_code == 201, r.text
    return r.json()


def ids(r) -> np.ndarray:
    assert r.status_code == 200, r.text
    return np.load(io.BytesIO(r.content))

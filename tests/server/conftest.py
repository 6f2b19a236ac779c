"""Fixtures of the server tests (helpers live in pocketray_server_support.py).

- ``client``: one in-process app (httpx via Starlette's TestClient, lifespan run)
  on a temporary SQLite file, shared by the module that asks for it; its caps
  are small so every render stays cheap.
- ``sid``: one session of that app, shared by the module.
- ``spawn_server``: real ``python -m server`` processes (uvicorn) on free
  loopback ports, configured through POCKETRAY_* variables; killed at the end.
- ``redis_url``: a local redis-server on a free loopback port in a temp dir.

GL is required: a test that renders asserts 200 and fails when no OpenGL
context can be made (there is no skip anywhere, in CI or elsewhere).
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import time
import warnings
from collections.abc import Callable, Iterator

import pytest

with warnings.catch_warnings():  # Starlette nudges towards httpx2; the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import ServerProcess, free_port, make_config, new_session, server_env, wait_ready

from server.app import create_app


@pytest.fixture(scope="module")
def client(tmp_path_factory) -> Iterator[TestClient]:
    tmp = tmp_path_factory.mktemp("app")
    with TestClient(create_app(make_config(tmp))) as c:
        yield c


@pytest.fixture(scope="module")
def ready_client(client) -> TestClient:
    wait_ready(client.get)
    return client


@pytest.fixture(scope="module")
def sid(client) -> str:
    """A session of the module's ``client``, for tests that check a refusal changes nothing."""
    return new_session(client)["id"]


@pytest.fixture
def spawn_server(tmp_path) -> Iterator[Callable[..., ServerProcess]]:
    """Factory: spawn_server(port=None, **POCKETRAY settings) → a started ServerProcess.

    All processes of one test share ``tmp_path/sessions.sqlite3`` unless told otherwise.
    """
    started: list[ServerProcess] = []

    def spawn(port: int | None = None, **settings) -> ServerProcess:
        env = server_env(tmp_path / "sessions.sqlite3", port, **settings)
        proc = ServerProcess(env, tmp_path / f"server-{len(started)}.log")
        started.append(proc)
        return proc.start()

    yield spawn
    for p in started:
        p.kill(signal.SIGTERM)


@pytest.fixture(scope="session")
def redis_url(tmp_path_factory) -> Iterator[str]:
    """A throw-away redis-server on a free loopback port (no persistence), killed at the end."""
    exe = shutil.which("redis-server")
    if exe is None:
        pytest.fail("redis-server is required for the scale-out tests (./dev installs it)")
    tmp = tmp_path_factory.mktemp("redis")
    port = free_port()
    log = open(tmp / "redis.log", "wb")
    proc = subprocess.Popen(
        [exe, "--port", str(port), "--bind", "127.0.0.1", "--dir", str(tmp), "--save", "", "--appendonly", "no"],
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    import redis

    client = redis.Redis(host="127.0.0.1", port=port)
    deadline = time.monotonic() + 20
    while True:
        try:
            if client.ping():
                break
        except redis.RedisError:
            if time.monotonic() > deadline or proc.poll() is not None:
                proc.kill()
                pytest.fail(f"redis-server did not start: {(tmp / 'redis.log').read_text()[-2000:]}")
            time.sleep(0.05)
    client.close()
    try:
        yield f"redis://127.0.0.1:{port}/0"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        log.close()

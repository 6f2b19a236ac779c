"""Apps of the route tests with settings of their own, each shared by the route files (package scope).

- ``api``: meshes through the API — scenes with meshes in and out, model files uploaded as
  bytes, bad meshes refused with 422 naming the field (413 for bodies too large), frames served
  by the methods that trace triangles on the GPU and refused by those that do not; its triangle
  cap and body limit are small (``MAX_TRIANGLES``, ``MAX_BODY`` of pocketray_server_support).
- ``museum_client`` / ``museum_ready_client``: animated scenes through the API — museum sessions
  and scenes with motions, frames posed at ``time``; room for brute-force frames of the museum's
  ~600 spheres (the reference there).

Their users are marked ``gl`` by tests/conftest.py: each app's lifespan starts the GL worker.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator

import pytest

with warnings.catch_warnings():  # as in tests/server/conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import MAX_BODY, MAX_TRIANGLES, make_config, wait_ready

from server.app import create_app


@pytest.fixture(scope="package")
def api(tmp_path_factory) -> Iterator[TestClient]:
    tmp = tmp_path_factory.mktemp("meshes")
    with TestClient(create_app(make_config(tmp, max_triangles=MAX_TRIANGLES, max_body_bytes=MAX_BODY))) as c:
        yield c


@pytest.fixture(scope="package")
def museum_client(tmp_path_factory) -> Iterator[TestClient]:
    """The test app, with room for brute-force frames of the museum's ~600 spheres (the reference here)."""
    with TestClient(create_app(make_config(tmp_path_factory.mktemp("anim"), max_frame_cost=10**6))) as c:
        yield c


@pytest.fixture(scope="package")
def museum_ready_client(museum_client) -> TestClient:
    wait_ready(museum_client.get)
    return museum_client

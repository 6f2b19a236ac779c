"""The service's shader programs: POCKETRAY_MAX_PROGRAMS bounds the GL thread's program cache, and
POCKETRAY_NEW_VARIANTS_PER_MIN / _BURST answer 429 with Retry-After to a session's frame that would
compile one more new variant than its bucket holds — nothing traced, the session unchanged — while
the variants already compiled stay free."""

from __future__ import annotations

import warnings

import pytest

with warnings.catch_warnings():  # as in conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import make_config, new_session, wait_ready

from server.app import create_app
from server.config import ServerConfig

pytestmark = pytest.mark.gl  # the app's GL thread renders

# A colour frame of two programs: the generic variant of its depth and its background.
FRAME = {"format": "npy", "specialize": False}


@pytest.fixture(scope="module")
def limited(tmp_path_factory):
    """An app whose sessions may have 4 new programs compiled at once (two frames' of a variant and
    its background), then one every 100 minutes, keeping at most 4 programs."""
    tmp = tmp_path_factory.mktemp("variants")
    config = make_config(tmp, warmup=False, new_variants_per_min=0.01, new_variants_burst=4, max_programs=4)
    with TestClient(create_app(config)) as c:
        wait_ready(c.get)
        yield c


def test_the_settings_are_read_from_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("POCKETRAY_MAX_PROGRAMS", "7")
    monkeypatch.setenv("POCKETRAY_NEW_VARIANTS_PER_MIN", "3.5")
    monkeypatch.setenv("POCKETRAY_NEW_VARIANTS_BURST", "9")
    config = ServerConfig(sqlite_path=tmp_path / "s.db")
    assert (config.max_programs, config.new_variants_per_min, config.new_variants_burst) == (7, 3.5, 9)


def test_the_renderer_keeps_at_most_max_programs(limited):
    assert limited.app.state.worker.renderer.programs.max_programs == 4


def test_a_new_variant_over_the_sessions_rate_is_429_and_a_compiled_one_is_free(limited):
    sid = new_session(limited)["id"]
    frame = f"/api/sessions/{sid}/frame"
    programs = limited.app.state.worker.renderer.programs
    for depth in (1, 2):
        r = limited.get(frame, params={**FRAME, "max_recursion_depth": depth})
        assert r.status_code == 200, r.text
    compiled = programs.compiled
    assert compiled == 4
    version = limited.get(f"/api/sessions/{sid}").json()["version"]
    r = limited.get(frame, params={**FRAME, "max_recursion_depth": 3})
    assert r.status_code == 429, r.text
    assert int(r.headers["retry-after"]) >= 1
    assert "POCKETRAY_NEW_VARIANTS_PER_MIN" in r.json()["detail"]
    assert programs.compiled == compiled  # refused before compiling
    assert limited.get(f"/api/sessions/{sid}").json()["version"] == version
    assert limited.get(frame, params={**FRAME, "max_recursion_depth": 1}).status_code == 200  # held: free
    other = new_session(limited)["id"]  # another session has its own bucket
    assert limited.get(f"/api/sessions/{other}/frame", params={**FRAME, "max_recursion_depth": 3}).status_code == 200

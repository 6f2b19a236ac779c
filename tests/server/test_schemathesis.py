"""Property-based API test: schemathesis over /openapi.json of a real server process.

Every operation gets generated requests (small counts, the test app's low work
caps keep renders tiny); every answer must be no 5xx, a documented status code
and content type, and a body and headers that match the schema. Path
``session_id`` values are replaced by a live session most of the time, so the
session operations are exercised past their 404.
"""

from __future__ import annotations

import signal
import tempfile
import zlib
from pathlib import Path

import httpx
import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (content_type_conformance, response_headers_conformance,
                                               response_schema_conformance, status_code_conformance)

from pocketray_server_support import ServerProcess, make_config, new_session, server_env
from server.app import create_app

CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance, response_schema_conformance,
          response_headers_conformance]


@pytest.fixture(scope="module")
def api_server():
    with tempfile.TemporaryDirectory() as tmp:
        env = server_env(Path(tmp) / "sessions.sqlite3", queue_size=8, max_spheres=256,
                         max_body_bytes=64 * 1024)
        proc = ServerProcess(env, Path(tmp) / "server.log").start()
        proc.wait_ready()
        try:
            yield proc
        finally:
            proc.kill(signal.SIGTERM)


@pytest.fixture(scope="module")
def live_session(api_server) -> dict:
    with httpx.Client(base_url=api_server.url, timeout=30) as c:
        return {"id": new_session(c)["id"], "url": api_server.url}


# The schema is the app's own /openapi.json, loaded at collection (the same document the
# process serves: test_served_schema_is_the_tested_one checks that); requests go to the process.
SPEC = create_app(make_config(Path(tempfile.gettempdir()))).openapi()
schema = schemathesis.openapi.from_dict(SPEC)


def test_served_schema_is_the_tested_one(api_server):
    assert httpx.get(api_server.url + "/openapi.json").json() == SPEC


@schema.parametrize()
@settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
def test_api_conforms_to_its_schema(case, live_session):
    params = case.path_parameters or {}
    if "session_id" in params and zlib.crc32(repr((case.body, case.query)).encode()) % 5:  # 4 of 5: live
        if case.method.upper() == "DELETE":
            with httpx.Client(base_url=live_session["url"], timeout=30) as c:
                params["session_id"] = new_session(c)["id"]
        else:
            params["session_id"] = live_session["id"]
    case.call_and_validate(base_url=live_session["url"], checks=CHECKS)

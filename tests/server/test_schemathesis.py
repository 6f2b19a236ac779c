"""Property-based API test: schemathesis over /openapi.json of a real server process.

Every operation gets generated requests (small counts, the test app's low work
caps keep renders tiny); every answer must be no 5xx, a documented status code
and content type, and a body and headers that match the schema. Path
``session_id`` values are replaced by a live session most of the time, so the
session operations are exercised past their 404.

And the schema must say exactly what is accepted (``--checks all`` of the
CLI, less what does not apply — no authentication, no resources to link):

- a request the schema refuses is refused (``negative_data_rejection``; a 413 for a
  body over POCKETRAY_MAX_BODY_BYTES is a refusal too), methods the schema does not
  list are 405 with an ``Allow`` that lists exactly its methods;
- a request the schema allows is refused only by what a schema cannot say: a 422 whose
  every entry is ``value_error``, the service's cross-field checks (docs/API.md, "What
  the schema cannot say": the camera's vectors, a mode the method cannot draw, the work
  caps, one of scenario/museum/scene) — never a type, range or format the schema states.
"""

from __future__ import annotations

import functools
import json
import signal
import tempfile
import zlib
from pathlib import Path
from typing import Any

import httpx
import jsonschema_rs
import pytest
from pocketray_server_support import ServerProcess, make_config, new_session, server_env

from server.app import create_app

pytestmark = pytest.mark.long  # thousands of generated requests to a server process

REFUSALS = ["400", "404", "405", "409", "413", "415", "422", "429", "503"]


_VALIDATORS: dict[str, Any] = {}


def schema_allows(schema: dict, value: Any) -> bool:
    """``value`` is valid by ``schema`` (refs into the app's own components); raw bytes as their JSON."""
    if isinstance(value, (bytes, str)):
        try:
            value = json.loads(value)
        except ValueError:
            return False
    key = json.dumps(schema, sort_keys=True)
    if key not in _VALIDATORS:
        _VALIDATORS[key] = jsonschema_rs.validator_for({**schema, "components": spec()["components"]})
    return _VALIDATORS[key].is_valid(value)


def query_allows(case, name: str) -> bool:
    """The query parameter ``name`` as generated is valid by its schema (read as the service reads
    text: a number or a boolean where the schema says so)."""
    params = {p["name"]: p for p in case.operation.definition.raw.get("parameters", []) if p["in"] == "query"}
    if name not in params or name not in (case.query or {}):
        return False
    value = case.query[name]
    if schema_allows(params[name]["schema"], value):
        return True
    try:
        return isinstance(value, str) and schema_allows(params[name]["schema"], json.loads(value))
    except ValueError:
        return False


def refused_only_across_fields(ctx, response, case) -> None:
    """A request the schema allows, refused with 422, is refused by cross-field checks alone: an entry
    of another type must point at a part of the request that breaks the schema (schemathesis marks
    cases "positive" that it mutated afterwards, so the parts are checked here themselves)."""
    if response.status_code != 422:
        return None
    body_schema = (
        case.operation.definition.raw.get("requestBody", {})
        .get("content", {})
        .get("application/json", {})
        .get("schema")
    )
    sent_as = {k.lower(): v for k, v in (case.headers or {}).items()}.get("content-type", case.media_type)
    body_allowed = (
        body_schema is not None
        and case.body is not None
        and sent_as == "application/json"
        and schema_allows(body_schema, case.body)
    )
    # "too_many_errors" counts the entries past the first 20 (server/contract/fields.py); the listed ones are judged.
    mismatches = [
        d
        for d in response.json()["detail"]
        if d.get("type") not in ("value_error", "too_many_errors")
        and (
            (d["loc"][0] == "body" and body_allowed)
            or (d["loc"][0] == "query" and len(d["loc"]) > 1 and query_allows(case, d["loc"][1]))
        )
    ]
    assert not mismatches, f"a request the schema allows was refused by a schema rule: {mismatches}"
    return None


# schemathesis (~110 modules) is imported where it is used: every xdist worker collects this module
# and only one runs it.
@functools.cache
def checks() -> list:
    """The checks of ``--checks all`` that apply, and this module's own."""
    from schemathesis.checks import not_a_server_error
    from schemathesis.specs.openapi.checks import (
        allow_header_conformance,
        content_type_conformance,
        missing_required_header,
        negative_data_rejection,
        response_headers_conformance,
        response_schema_conformance,
        status_code_conformance,
        unsupported_method,
    )

    return [
        not_a_server_error,
        status_code_conformance,
        content_type_conformance,
        response_schema_conformance,
        response_headers_conformance,
        negative_data_rejection,
        unsupported_method,
        allow_header_conformance,
        missing_required_header,
        refused_only_across_fields,
    ]


@pytest.fixture(scope="module")
def api_server():
    with tempfile.TemporaryDirectory() as tmp:
        env = server_env(Path(tmp) / "sessions.sqlite3", queue_size=8, max_spheres=256, max_body_bytes=64 * 1024)
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


@functools.cache
def spec() -> dict:
    """The app's own /openapi.json: the same document the process serves
    (test_served_schema_is_the_tested_one checks that); requests go to the process."""
    return create_app(make_config(Path(tempfile.gettempdir()))).openapi()


@pytest.fixture(scope="module")
def api_schema(live_session):
    """Loaded when the test runs, not at collection: every xdist worker collects this module, one
    runs it (the schema's operations are the test's subtests, one per operation)."""
    import schemathesis
    from schemathesis.config import SchemathesisConfig

    config = SchemathesisConfig.from_dict({"checks": {"negative_data_rejection": {"expected-statuses": REFUSALS}}})
    return schemathesis.openapi.from_dict(spec(), config=config)


def test_served_schema_is_the_tested_one(api_server):
    assert httpx.get(api_server.url + "/openapi.json").json() == spec()


def test_every_operation_of_the_schema_is_tested(api_schema):
    operations = [r.ok() for r in api_schema.get_all_operations()]
    paths = set(spec()["paths"])
    assert {o.path for o in operations} == paths and len(operations) >= 20


def test_api_conforms_to_its_schema(api_schema, live_session, subtests):
    """Every operation, each a subtest: the tests schemathesis.parametrize() would make, made when
    this runs (schemathesis.pytest.lazy's, whose own wrapper does not run under this pytest)."""
    from hypothesis import HealthCheck, settings
    from schemathesis.checks import load_all_checks
    from schemathesis.pytest.lazy import get_all_tests

    load_all_checks()
    schema = api_schema.clone(test_function=check_case)
    explicit = settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
    ran = 0
    for result in get_all_tests(schema=schema, test_func=check_case, settings=explicit, given_kwargs={}):
        operation, sub_test = result.ok()
        with subtests.test(msg=operation.label):
            sub_test(live_session=live_session)
        ran += 1
    assert ran >= 20


def check_case(case, live_session) -> None:
    from schemathesis.core.parameters import ParameterLocation
    from schemathesis.generation import GenerationMode

    params = case.path_parameters or {}
    # A session id made invalid on purpose (a negative path) stays as generated: replaced by the live
    # one, the request would be valid while schemathesis still expects it refused.
    meta = case.meta
    path_info = meta.components.get(ParameterLocation.PATH) if meta is not None else None
    negative_path = path_info is not None and path_info.mode is GenerationMode.NEGATIVE
    if (
        "session_id" in params and not negative_path and zlib.crc32(repr((case.body, case.query)).encode()) % 5
    ):  # 4 of 5: live
        if case.method.upper() == "DELETE":
            with httpx.Client(base_url=live_session["url"], timeout=30) as c:
                params["session_id"] = new_session(c)["id"]
        else:
            params["session_id"] = live_session["id"]
    case.call_and_validate(base_url=live_session["url"], checks=checks())

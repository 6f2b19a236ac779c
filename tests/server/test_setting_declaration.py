"""A render setting is declared once (renderer.config.settings.SETTINGS, and its typed field of RenderSettings):
one entry added to the table is validated by the API (body and query), kept by sessions, listed by GET
/api/info and offered by ``pocketray render --help`` — with no other file touched.

The table and the class are patched in a fresh interpreter before the service is imported, so that
everything made from the table (the API's models, the routes, the CLI's flags) is made with the new entry;
the client's settings sheet is checked with the same entry in tests/browser/test_ui.py.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

from pocketray_server_support import ROOT

from renderer.config.settings import SETTINGS, SettingSpec

# The setting the test declares: a number with bounds, read in one mode, offered by the sheet.
EXTRA = dict(
    name="gain",
    type="number",
    default=1.0,
    doc="brightness factor of the image (a test's setting)",
    label="Exposure",
    unit="×",
    bounds=(0.0, 4.0),
    modes=("color",),
    sheet=True,
    client=True,
)

SCRIPT = textwrap.dedent("""
    import contextlib, io, json, sys, tempfile, warnings
    from pathlib import Path

    sys.path[:0] = ["tests/server"]
    import renderer.config.settings as declared

    spec = declared.SettingSpec(**{**json.loads(sys.argv[1]), "bounds": tuple(json.loads(sys.argv[1])["bounds"]),
                                   "modes": tuple(json.loads(sys.argv[1])["modes"])})
    declared.SETTINGS = (*declared.SETTINGS, spec)          # the declaration
    import dataclasses                                       # and its field, typed as declared
    declared.RenderSettings = dataclasses.make_dataclass(
        "RenderSettings", [(spec.name, float, dataclasses.field(default=spec.default))],
        bases=(declared.RenderSettings,), frozen=True,
    )
    declared.check_declaration(declared.RenderSettings)
    # From here on, everything made from the table is made at import.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from fastapi.testclient import TestClient
    from pocketray_server_support import make_config
    from server.tools import cli
    from server.app import create_app

    from server.frames.pipeline import render_settings

    # the engine's settings: a field with its default, validated
    out = {"engine": [declared.RenderSettings().gain, render_settings({"gain": 2.5}).gain]}
    try:
        declared.RenderSettings(gain=9.0)
    except declared.SceneError as e:
        out["engine_refuses"] = [e.field, e.message]
    with TestClient(create_app(make_config(Path(tempfile.mkdtemp())))) as c:
        out["info"] = [s for s in c.get("/api/info").json()["settings"] if s["name"] == spec.name]
        schema = c.get("/openapi.json").json()["components"]["schemas"]
        out["patch_schema"] = schema["SettingsPatch"]["properties"].get(spec.name)
        out["response_schema"] = schema["FullSettings"]["properties"].get(spec.name)
        s = c.post("/api/sessions", json={"scenario": 1, "n": 8, "settings": {"width": 32, "height": 32}}).json()
        out["created"] = s["settings"].get(spec.name)
        base = f"/api/sessions/{s['id']}"
        r = c.patch(base + "/settings", json={spec.name: 2.5})
        out["patched"] = [r.status_code, r.json().get(spec.name)]
        r = c.patch(base + "/settings", json={spec.name: 5})
        out["patched_over"] = [r.status_code, r.json()]
        r = c.patch(base + "/settings", json={spec.name: "2"})
        out["patched_text"] = [r.status_code, r.json()]
        r = c.get(base + f"/frame?{spec.name}=-1")
        out["query_under"] = [r.status_code, r.json()]
        out["session"] = c.get(base).json()["settings"].get(spec.name)
    help_text = io.StringIO()
    with contextlib.redirect_stdout(help_text), contextlib.suppress(SystemExit):
        cli.main(["render", "--help"])
    out["help"] = help_text.getvalue()
    Path(sys.argv[2]).write_text(json.dumps(out))
""")


def test_a_setting_added_to_the_declaration_reaches_the_api_info_and_cli(tmp_path):
    assert EXTRA["name"] not in {s.name for s in SETTINGS}
    SettingSpec(**{**EXTRA, "bounds": tuple(EXTRA["bounds"]), "modes": tuple(EXTRA["modes"])})  # a valid entry
    result = tmp_path / "out.json"
    p = subprocess.run(
        [sys.executable, "-c", SCRIPT, json.dumps(EXTRA), str(result)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "COLUMNS": "200", "PYTHONPATH": str(ROOT)},
    )
    assert p.returncode == 0, p.stderr[-4000:]
    out = json.loads(result.read_text())

    # RenderSettings (what the renderer gets) has it, validated
    assert out["engine"] == [1.0, 2.5]
    assert out["engine_refuses"] == ["gain", "must be a number in [0, 4], got 9.0"]
    # GET /api/info lists it with what the sheet builds its field from
    [info] = out["info"]
    assert {
        k: info[k]
        for k in (
            "name",
            "type",
            "default",
            "minimum",
            "maximum",
            "label",
            "doc",
            "unit",
            "sheet",
            "client",
            "modes",
            "choices",
        )
    } == {
        **{k: EXTRA[k] for k in ("name", "type", "default", "label", "doc", "unit", "sheet", "client")},
        "minimum": 0.0,
        "maximum": 4.0,
        "modes": ["color"],
        "choices": None,
    }
    assert "bih" in info["methods"] and "hre" in info["methods"]  # read by every method
    # the API's models: an optional bounded number in the patch (and the query), a field of the settings
    assert {"type": "number", "maximum": 4.0, "minimum": 0.0}.items() <= out["patch_schema"]["anyOf"][0].items()
    assert out["patch_schema"]["description"] == EXTRA["doc"]
    assert out["response_schema"]["type"] == "number" and out["response_schema"]["default"] == 1.0
    # validated and kept by a session
    assert out["created"] == 1.0
    assert out["patched"] == [200, 2.5]
    status, body = out["patched_over"]
    assert status == 422 and body["detail"][0]["loc"] == ["body", "gain"]
    assert body["detail"][0]["msg"] == "gain: Input should be less than or equal to 4"
    status, body = out["patched_text"]
    assert status == 422 and body["detail"][0]["loc"] == ["body", "gain"]  # a body is strict JSON
    status, body = out["query_under"]
    assert status == 422 and body["detail"][0]["loc"] == ["query", "gain"]
    assert body["detail"][0]["msg"] == "gain: Input should be greater than or equal to 0"
    assert out["session"] == 2.5
    # offered by pocketray render --help, with its doc
    assert "--gain GAIN" in out["help"]
    assert EXTRA["doc"] in " ".join(out["help"].split())


def test_the_declaration_agrees_with_the_service_defaults():
    """The service's own setting (quality) has the table's default as its configured default."""
    from renderer.config.settings import setting
    from server.config import ServerConfig

    assert ServerConfig().default_jpeg_quality == setting("quality").default
    assert set(ServerConfig().default_settings()) == {s.name for s in SETTINGS}

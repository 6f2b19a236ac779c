"""The deployment files, checked statically (no container engine here): compose.yaml against
the Compose Specification's JSON schema (tests/deploy/compose-spec.json, from
github.com/compose-spec/compose-spec, Apache 2.0), its topology, deploy/haproxy.cfg against
its generator and HAProxy's own check, the Dockerfile, and the lock files. The same topology
runs for real, on loopback, in tests/server/tools/test_stack.py."""

from __future__ import annotations

import json
import re
import subprocess
from importlib.metadata import PackageNotFoundError, version

import jsonschema_rs
import yaml
from packaging.markers import default_environment
from packaging.requirements import Requirement

from server.tools.stack import compose_haproxy_config, find_executable, haproxy_config
from tests.helpers import ROOT

COMPOSE = ROOT / "compose.yaml"
HAPROXY_CFG = ROOT / "deploy" / "haproxy.cfg"


def compose() -> dict:
    return yaml.safe_load(COMPOSE.read_text())


def render_services(doc: dict) -> dict[str, dict]:
    return {name: s for name, s in doc["services"].items() if re.fullmatch(r"render\d+", name)}


def test_compose_file_is_valid_under_the_compose_specification():
    schema = json.loads((ROOT / "tests" / "deploy" / "compose-spec.json").read_text())
    errors = [
        f"{'/'.join(map(str, e.instance_path))}: {e.message}"
        for e in jsonschema_rs.validator_for(schema).iter_errors(compose())
    ]
    assert errors == []


def test_compose_topology_redis_with_aof_one_render_service_per_gpu_and_the_balancer():
    doc = compose()
    redis = doc["services"]["redis"]
    cmd = redis["command"]
    assert cmd[cmd.index("--appendonly") + 1] == "yes" and cmd[cmd.index("--appendfsync") + 1] == "always"
    assert any(v.endswith(":/data") for v in redis["volumes"])
    renders = render_services(doc)
    assert len(renders) >= 2
    gpus = []
    for _name, s in sorted(renders.items()):
        assert s["command"][0] == "serve"
        gpus.append(int(s["command"][s["command"].index("--gpu") + 1]))
        env = s["environment"]
        assert env["POCKETRAY_STATE_BACKEND"] == "redis" and env["POCKETRAY_REDIS_URL"].startswith("redis://redis:")
        assert env["POCKETRAY_HOST"] == "0.0.0.0" and float(env["POCKETRAY_DRAIN_S"]) > 0
        # behind the balancer every connection is the balancer's: the per-address cap is kept there
        assert env["POCKETRAY_MAX_CONNECTIONS_PER_CLIENT"] == "0"
        assert env["POCKETRAY_MAX_UNSENT_BYTES_PER_CLIENT"] == "0"
        assert env["FORWARDED_ALLOW_IPS"] == "*"  # the client's address comes from the balancer
        assert "graphics" in env["NVIDIA_DRIVER_CAPABILITIES"]
        assert s["depends_on"]["redis"]["condition"] == "service_healthy"
        assert "/api/ready" in " ".join(s["healthcheck"]["test"])
        gpu = s["deploy"]["resources"]["reservations"]["devices"][0]
        assert gpu["driver"] == "nvidia" and gpu["capabilities"] == ["gpu"]
    assert sorted(gpus) == list(range(len(renders)))  # one service per GPU, each its own
    balancer = doc["services"]["balancer"]
    assert balancer["image"].startswith("haproxy:")
    assert "./deploy/haproxy.cfg:/usr/local/etc/haproxy/haproxy.cfg:ro" in balancer["volumes"]
    assert "8000:8000" in balancer["ports"]
    assert set(balancer["depends_on"]) == set(renders)


def test_the_balancer_configuration_is_its_generator_output_and_haproxy_accepts_it():
    renders = render_services(compose())
    assert HAPROXY_CFG.read_text() == compose_haproxy_config(len(renders)), (
        "deploy/haproxy.cfg is stale: write it with server.tools.stack.compose_haproxy_config()"
    )
    cfg = HAPROXY_CFG.read_text()
    for name in renders:
        assert f"server {name} {name}:8000" in cfg
    for line in (
        "balance hash var(txn.session)",
        "hash-type consistent",
        "hash-balance-factor 150",
        "option httpchk GET /api/ready",
        "req.hdr(X-Session-Id)",
        "retry-on conn-failure",
        "http-request disable-l7-retry if !METH_GET",
        "observe layer4 error-limit 1 on-error mark-down",
        "http-request deny deny_status 429 if { sc_conn_cur(0) gt 32 }",
        "http-error status 503 content-type application/json",
        "option forwardfor",
    ):
        assert line in cfg
    haproxy = find_executable("haproxy")
    check = subprocess.run([haproxy, "-c", "-f", str(HAPROXY_CFG)], capture_output=True, text=True)
    assert check.returncode == 0, check.stdout + check.stderr


def test_haproxy_accepts_the_loopback_stacks_configuration(tmp_path):
    cfg = tmp_path / "haproxy.cfg"
    cfg.write_text(haproxy_config("127.0.0.1:18080", [("render0", "127.0.0.1:18001"), ("render1", "127.0.0.1:18002")]))
    check = subprocess.run([find_executable("haproxy"), "-c", "-f", str(cfg)], capture_output=True, text=True)
    assert check.returncode == 0, check.stdout + check.stderr


def test_dockerfile_installs_the_lock_then_the_package_and_runs_pocketray():
    text = (ROOT / "Dockerfile").read_text()
    assert "pip install --no-cache-dir -r requirements.lock" in text
    assert "pip install --no-cache-dir --no-deps ." in text
    assert 'ENTRYPOINT ["pocketray"]' in text
    for path in ("renderer", "server", "shaders", "client_web"):
        assert f"COPY {path} ./{path}" in text


def _pins(name: str) -> dict[str, tuple[str, str | None]]:
    out = {}
    for line in (ROOT / name).read_text().splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        req = Requirement(line)
        (spec,) = req.specifier
        assert spec.operator == "==", line
        out[req.name.lower().replace("_", "-")] = (spec.version, str(req.marker) if req.marker else None)
    return out


def test_lock_files_pin_every_dependency_within_pyproject_ranges_and_the_venv_has_them():
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    runtime, full = _pins("requirements.lock"), _pins("requirements-test.lock")
    env = default_environment()
    for reqs, pins in (
        (project["dependencies"], runtime),
        (project["dependencies"] + project["optional-dependencies"]["test"], full),
    ):
        for text in reqs:
            req = Requirement(text)
            name = req.name.lower().replace("_", "-")
            assert name in pins, f"{name} is not locked (scripts/lock.sh)"
            assert req.specifier.contains(pins[name][0], prereleases=True), (text, pins[name])
    for name, (v, _) in runtime.items():
        assert full.get(name, (v,))[0] == v, f"{name}: the two locks disagree"
    # scripts/bootstrap.sh installs requirements-test.lock: what is installed is what is locked.
    wrong = {}
    for name, (v, marker) in full.items():
        if marker and not Requirement(f"x; {marker}").marker.evaluate(env):
            continue
        try:
            have = version(name)
        except PackageNotFoundError:
            have = None
        if have != v:
            wrong[name] = (have, v)
    assert wrong == {}, f"installed ≠ locked (run ./dev test, which re-installs): {wrong}"

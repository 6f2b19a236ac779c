"""The Kubernetes manifests (deploy/k8s), checked without a cluster: each overlay as `kubectl
kustomize` renders it, against the Kubernetes API's schemas (kubernetes-validate, strict: an unknown
field fails); the balancer's configuration against its generator and HAProxy's own check; the
settings of the ConfigMap against the service's configuration; and what ties the objects together —
probes on routes the app serves, the preStop sleep and the drain, the NetworkPolicy in front of
Redis, the autoscaler's metric, the memory requests and the measured budget (docs/DEPLOY.md,
"Cluster")."""

from __future__ import annotations

import copy
import functools
import os
import subprocess
from pathlib import Path

import kubernetes_validate
import pytest
import yaml

from server.config import ServerConfig
from server.tools.stack import (
    CHECK_FALL,
    CHECK_INTERVAL_MS,
    CLUSTER_RENDER,
    CLUSTER_RENDER_SLOTS,
    cluster_haproxy_config,
    find_executable,
)
from tests.helpers import ROOT

K8S = ROOT / "deploy" / "k8s"
OVERLAYS = ("gpu", "cpu")
# The oldest and the newest Kubernetes whose schemas the pinned kubernetes-validate ships: the
# manifests hold for every release from 1.30 on (preStop's sleep action is beta and on from 1.30).
SCHEMA_VERSIONS = ("1.30.0", kubernetes_validate.latest_version())
# Environment variables of the render pods that are not the service's settings, and who reads them.
OTHER_ENV = {
    "FORWARDED_ALLOW_IPS": "uvicorn",
    "MALLOC_ARENA_MAX": "glibc",
    "LP_NUM_THREADS": "Mesa's llvmpipe",
    "NVIDIA_DRIVER_CAPABILITIES": "the NVIDIA container toolkit",
}
MIB = 1 << 20
# The measured memory budget (docs/API.md, "Memory budget"): the idle process, the largest
# requests at once (3 GiB for POCKETRAY_QUEUE_SIZE = 8 of them: per admitted request, an eighth),
# and the scene cache outside the bounded settings.
IDLE_BYTES = 170 * MIB
LARGEST_REQUEST_BYTES = (3 << 30) // 8
SCENE_CACHE_BYTES = 290 * MIB
QUANTITY = {"Ki": 1 << 10, "Mi": 1 << 20, "Gi": 1 << 30, "Ti": 1 << 40, "k": 10**3, "M": 10**6, "G": 10**9}


@functools.cache
def rendered(overlay: str) -> tuple[dict, ...]:
    """The objects `kubectl kustomize deploy/k8s/overlays/<overlay>` makes (what `kubectl apply -k` sends)."""
    out = subprocess.run(
        [find_executable("kubectl"), "kustomize", str(K8S / "overlays" / overlay)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    return tuple(d for d in yaml.safe_load_all(out.stdout) if d)


def one(docs: tuple[dict, ...], kind: str, name: str) -> dict:
    (doc,) = [d for d in docs if d["kind"] == kind and d["metadata"]["name"] == name]
    return doc


def config_map(docs: tuple[dict, ...], name: str) -> dict:
    """The generated ConfigMap ``name`` (kustomize appends a hash of its content to the name)."""
    (doc,) = [d for d in docs if d["kind"] == "ConfigMap" and d["metadata"]["name"].startswith(name + "-")]
    return doc


def render_set(docs: tuple[dict, ...]) -> dict:
    return one(docs, "StatefulSet", CLUSTER_RENDER[0])


def container(workload: dict, name: str) -> dict:
    (c,) = [c for c in workload["spec"]["template"]["spec"]["containers"] if c["name"] == name]
    return c


def settings(docs: tuple[dict, ...]) -> dict[str, str]:
    return config_map(docs, "pocketray-config")["data"]


def quantity(text: str | int) -> float:
    """A Kubernetes quantity (4Gi, 250m, 2) as a number."""
    text = str(text)
    for suffix, factor in QUANTITY.items():
        if text.endswith(suffix):
            return float(text[: -len(suffix)]) * factor
    return float(text[:-1]) / 1000 if text.endswith("m") else float(text)


def selects(selector: dict, labels: dict) -> bool:
    return all(labels.get(k) == v for k, v in selector["matchLabels"].items())


def pod_labels(workload: dict) -> dict:
    return workload["spec"]["template"]["metadata"]["labels"]


@pytest.mark.parametrize("version", SCHEMA_VERSIONS)
@pytest.mark.parametrize("overlay", OVERLAYS)
def test_every_manifest_of_each_overlay_is_valid_against_the_kubernetes_schemas(overlay, version):
    docs = rendered(overlay)
    kinds = {d["kind"] for d in docs}
    assert {"Namespace", "ConfigMap", "Service", "StatefulSet", "Deployment", "PodDisruptionBudget"} <= kinds
    assert {"HorizontalPodAutoscaler", "NetworkPolicy"} <= kinds
    errors = []
    for doc in docs:
        try:
            kubernetes_validate.validate(doc, version, strict=True)
        except kubernetes_validate.ValidationError as e:
            where = "/".join(map(str, getattr(e.caught, "absolute_path", ())))
            errors.append(f"{doc['kind']}/{doc['metadata']['name']}: {where}: {getattr(e.caught, 'message', e.caught)}")
    assert errors == []
    # strict: a misspelt field is refused, not dropped (the check above could fail)
    wrong = copy.deepcopy(render_set(docs))
    wrong["spec"]["template"]["spec"]["containers"][0]["readinesProbe"] = {}
    with pytest.raises(kubernetes_validate.ValidationError):
        kubernetes_validate.validate(wrong, version, strict=True)


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_every_container_names_a_tagged_image_and_a_numeric_user_where_it_must_not_be_root(overlay):
    workloads = [d for d in rendered(overlay) if d["kind"] in ("Deployment", "StatefulSet")]
    assert len(workloads) == 3
    for workload in workloads:
        pod = workload["spec"]["template"]["spec"]
        for c in pod["containers"]:
            name, tag = c["image"].rsplit(":", 1)
            assert name and tag and tag != "latest", c["image"]
            context = {**pod.get("securityContext", {}), **c.get("securityContext", {})}
            # the schemas accept runAsNonRoot alone, but the kubelet refuses to start a container whose
            # image names its user (haproxy, redis) unless runAsUser gives the number
            if context.get("runAsNonRoot"):
                assert isinstance(context.get("runAsUser"), int) and context["runAsUser"] > 0, workload["metadata"]


def test_the_balancer_configuration_is_its_generator_output_and_haproxy_accepts_it(tmp_path):
    committed = (K8S / "base" / "haproxy.cfg").read_text()
    assert committed == cluster_haproxy_config(), (
        "deploy/k8s/base/haproxy.cfg is stale: write it with server.tools.stack.cluster_haproxy_config()"
    )
    for overlay in OVERLAYS:
        docs = rendered(overlay)
        cfg = config_map(docs, "pocketray-balancer")["data"]["haproxy.cfg"]
        assert cfg == committed
        # the balancer's pods read that ConfigMap where the haproxy image looks for its file
        balancer = one(docs, "Deployment", "pocketray-balancer")
        spec = balancer["spec"]["template"]["spec"]
        (volume,) = [v for v in spec["volumes"] if "configMap" in v]
        assert volume["configMap"]["name"] == config_map(docs, "pocketray-balancer")["metadata"]["name"]
        mount = next(m for m in container(balancer, "haproxy")["volumeMounts"] if m["name"] == volume["name"])
        assert mount["mountPath"] == "/usr/local/etc/haproxy"
        # one server line per render pod name the StatefulSet can have, under its headless Service,
        # in the namespace the objects are applied to; the autoscaler stays within those lines
        render = render_set(docs)
        namespace = one(docs, "Namespace", render["metadata"]["namespace"])["metadata"]["name"]
        service = one(docs, "Service", render["spec"]["serviceName"])
        assert service["spec"]["clusterIP"] == "None" and selects(
            {"matchLabels": service["spec"]["selector"]}, pod_labels(render)
        )
        port = container(render, "render")["ports"][0]["containerPort"]
        hosts = [line.split()[2] for line in cfg.splitlines() if line.strip().startswith("server ")]
        name = render["metadata"]["name"]
        assert hosts == [
            f"{name}-{i}.{service['metadata']['name']}.{namespace}.svc.cluster.local:{port}"
            for i in range(CLUSTER_RENDER_SLOTS)
        ]
        hpa = one(docs, "HorizontalPodAutoscaler", name)
        assert render["spec"]["replicas"] <= hpa["spec"]["maxReplicas"] <= CLUSTER_RENDER_SLOTS
        assert "parse-resolv-conf" in cfg and "resolvers kube" in cfg  # names resolved again as pods come and go
    path = tmp_path / "haproxy.cfg"
    path.write_text(committed)
    check = subprocess.run(
        [find_executable("haproxy"), "-c", "-f", str(path)], capture_output=True, text=True, timeout=120
    )
    assert check.returncode == 0, check.stdout + check.stderr


def _env_names() -> set[str]:
    """Every environment variable ServerConfig reads (its fields' POCKETRAY_ names and aliases)."""
    names = set()
    for field_name, field in ServerConfig.model_fields.items():
        names.add(f"POCKETRAY_{field_name}".upper())
        alias = field.validation_alias
        names.update(a.upper() for a in getattr(alias, "choices", ()) if isinstance(a, str))
    return names


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_the_configmap_settings_are_the_services_own_and_its_configuration_accepts_them(overlay, monkeypatch):
    docs = rendered(overlay)
    data = settings(docs)
    render = container(render_set(docs), "render")
    env = {**data, **{e["name"]: e["value"] for e in render.get("env", [])}}
    known = _env_names()
    unknown = sorted(k for k in env if k not in known and k not in OTHER_ENV)
    assert unknown == [], f"not a setting of server/config.py: {unknown}"
    assert all(isinstance(v, str) for v in env.values())  # a ConfigMap holds strings only
    # the pods take the whole ConfigMap as their environment, read by the service as at start-up
    assert {"configMapRef": {"name": config_map(docs, "pocketray-config")["metadata"]["name"]}} in render["envFrom"]
    for key in list(os.environ):
        if key.startswith("POCKETRAY_"):
            monkeypatch.delenv(key)
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    config = ServerConfig()
    assert config.state_backend == "redis" and config.host == "0.0.0.0"
    for key, value in data.items():
        if key.startswith("POCKETRAY_"):
            field = key.removeprefix("POCKETRAY_").lower()
            parsed = getattr(config, field)
            assert str(parsed) == value or float(parsed) == float(value), (key, value, parsed)
    # behind the balancer, as in compose.yaml: the cap per client address is the balancer's
    compose = yaml.safe_load((ROOT / "compose.yaml").read_text())["x-render"]["environment"]
    for key in ("POCKETRAY_MAX_CONNECTIONS_PER_CLIENT", "POCKETRAY_MAX_UNSENT_BYTES_PER_CLIENT", "FORWARDED_ALLOW_IPS"):
        assert data[key] == compose[key]
    # Redis is the Service of this manifest
    host_port = data["POCKETRAY_REDIS_URL"].removeprefix("redis://").split("/")[0]
    host, port = host_port.split(":")
    redis = one(docs, "Service", host)
    assert int(port) == redis["spec"]["ports"][0]["port"]


def test_the_settings_check_knows_the_names_and_aliases_and_the_service_refuses_a_bad_value(monkeypatch):
    # ServerConfig ignores unknown POCKETRAY_ variables: the test above compares the names itself
    assert "POCKETRAY_DRAIN_SECONDS" not in _env_names() and "POCKETRAY_DRAIN_S" in _env_names()
    assert "POCKETRAY_GL_DEVICE" in _env_names()  # an alias is a setting too
    monkeypatch.setenv("POCKETRAY_QUEUE_SIZE", "0")
    with pytest.raises(ValueError, match="queue_size"):
        ServerConfig()


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_probes_and_the_scrape_path_are_routes_the_app_serves(overlay, tmp_path):
    from server.app import create_app

    paths = create_app(ServerConfig(sqlite_path=tmp_path / "sessions.sqlite3")).openapi()["paths"]
    routes = {path for path, operations in paths.items() if "get" in operations}
    render_pod = render_set(rendered(overlay))
    c = container(render_pod, "render")
    assert c["readinessProbe"]["httpGet"]["path"] == "/api/ready"
    assert c["livenessProbe"]["httpGet"]["path"] == "/api/health"
    for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
        assert c[probe]["httpGet"]["path"] in routes, probe
        assert c[probe]["httpGet"]["port"] in {p["name"] for p in c["ports"]}
    annotations = render_pod["spec"]["template"]["metadata"]["annotations"]
    assert annotations["prometheus.io/path"] in routes
    assert int(annotations["prometheus.io/port"]) == c["ports"][0]["containerPort"]
    # the balancer's own health check asks the same route
    assert "option httpchk GET /api/ready" in cluster_haproxy_config()


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_the_prestop_sleep_is_the_drain_and_the_grace_period_covers_both(overlay):
    docs = rendered(overlay)
    drain_s = float(settings(docs)["POCKETRAY_DRAIN_S"])
    pod = render_set(docs)["spec"]["template"]["spec"]
    pre_stop_s = container(render_set(docs), "render")["lifecycle"]["preStop"]["sleep"]["seconds"]
    assert pre_stop_s == drain_s
    # Kubernetes counts the grace period from the preStop hook on: the sleep, the drain, and renders in flight
    assert pod["terminationGracePeriodSeconds"] > pre_stop_s + drain_s
    # the drain outlasts the balancer's checks that take a draining pod out
    assert drain_s * 1000 > CHECK_FALL * CHECK_INTERVAL_MS
    # no Service's link variables: a Service named pocketray would set POCKETRAY_PORT=tcp://…
    assert pod["enableServiceLinks"] is False
    assert any(d["kind"] == "Service" and d["metadata"]["name"] == "pocketray" for d in docs)


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_the_network_policy_lets_only_the_render_pods_reach_redis(overlay):
    docs = rendered(overlay)
    redis = one(docs, "StatefulSet", "pocketray-redis")
    render = render_set(docs)
    balancer = one(docs, "Deployment", "pocketray-balancer")
    policies = [
        d for d in docs if d["kind"] == "NetworkPolicy" and selects(d["spec"]["podSelector"], pod_labels(redis))
    ]
    assert len(policies) == 1
    (policy,) = policies
    assert "Ingress" in policy["spec"]["policyTypes"]
    redis_port = container(redis, "redis")["ports"][0]["containerPort"]
    peers = []
    for rule in policy["spec"]["ingress"]:
        assert [p["port"] for p in rule["ports"]] == [redis_port]
        peers += rule["from"]
    assert peers
    for peer in peers:
        # a pod selector alone (this namespace), one that the render pods match and no other workload does
        assert set(peer) == {"podSelector"}, peer
        assert selects(peer["podSelector"], pod_labels(render))
        assert not selects(peer["podSelector"], pod_labels(balancer))
        assert not selects(peer["podSelector"], pod_labels(redis))
    # and the policy selects Redis only
    assert not selects(policy["spec"]["podSelector"], pod_labels(render))


def test_redis_keeps_an_append_only_file_fsynced_on_its_own_volume():
    docs = rendered("gpu")
    redis = one(docs, "StatefulSet", "pocketray-redis")
    c = container(redis, "redis")
    args = c["args"]
    assert args[args.index("--appendonly") + 1] == "yes" and args[args.index("--appendfsync") + 1] == "always"
    data_dir = args[args.index("--dir") + 1]
    (claim,) = redis["spec"]["volumeClaimTemplates"]
    assert {"name": claim["metadata"]["name"], "mountPath": data_dir} in c["volumeMounts"]
    # the store's quota of scene sources fits in Redis' memory request
    max_store = int(settings(docs)["POCKETRAY_MAX_STORE_BYTES"])
    assert 0 < max_store < quantity(c["resources"]["requests"]["memory"])
    assert quantity(claim["spec"]["resources"]["requests"]["storage"]) >= 2 * max_store


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_the_autoscaler_scales_the_render_pods_on_the_queue_gauge_that_metrics_exports(overlay):
    from server.http.metrics import METRIC_NAMES, RENDERS_WAITING

    docs = rendered(overlay)
    render = render_set(docs)
    hpa = one(docs, "HorizontalPodAutoscaler", render["metadata"]["name"])
    target = hpa["spec"]["scaleTargetRef"]
    assert (target["apiVersion"], target["kind"], target["name"]) == (
        "apps/v1",
        "StatefulSet",
        render["metadata"]["name"],
    )
    (metric,) = hpa["spec"]["metrics"]
    assert metric["type"] == "Pods"
    name = metric["pods"]["metric"]["name"]
    assert name == RENDERS_WAITING._name and name in METRIC_NAMES and RENDERS_WAITING._type == "gauge"
    # the Prometheus adapter's rule turns that series into the pods metric of that name
    adapter = yaml.safe_load((K8S / "prometheus-adapter" / "values.yaml").read_text())
    (rule,) = adapter["rules"]["custom"]
    assert rule["seriesQuery"].startswith(name + "{")
    assert rule["name"]["as"] == name
    assert rule["resources"]["overrides"]["pod"] == {"resource": "pod"}
    assert "<<.Series>>" in rule["metricsQuery"] and "<<.GroupBy>>" in rule["metricsQuery"]
    # a disruption takes one render pod at a time
    pdb = one(docs, "PodDisruptionBudget", render["metadata"]["name"])
    assert selects(pdb["spec"]["selector"], pod_labels(render)) and pdb["spec"]["maxUnavailable"] == 1
    assert hpa["spec"]["minReplicas"] > pdb["spec"]["maxUnavailable"]


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_render_memory_requests_and_limits_come_from_the_measured_budget(overlay):
    docs = rendered(overlay)
    data = settings(docs)
    resources = container(render_set(docs), "render")["resources"]
    held = (
        IDLE_BYTES
        + int(data["POCKETRAY_QUEUE_SIZE"]) * LARGEST_REQUEST_BYTES
        + SCENE_CACHE_BYTES
        + int(data["POCKETRAY_MAX_TARGET_BYTES"])
        + int(data["POCKETRAY_MAX_ACCUMULATION_BYTES"])
    )
    workers = int(data["POCKETRAY_MODEL_WORKERS"]) * int(data["POCKETRAY_MODEL_MEMORY_BYTES"])
    request, limit = quantity(resources["requests"]["memory"]), quantity(resources["limits"]["memory"])
    assert held <= request < held + 256 * MIB  # what the bounds let the process hold, rounded up
    assert held + workers <= limit < held + workers + 256 * MIB  # and its model-file workers' address space


def test_the_gpu_overlay_gives_each_render_pod_one_gpu_and_the_cpu_overlay_none():
    gpu = container(render_set(rendered("gpu")), "render")
    assert quantity(gpu["resources"]["limits"]["nvidia.com/gpu"]) == 1
    env = {e["name"]: e["value"] for e in gpu["env"]}
    assert "graphics" in env["NVIDIA_DRIVER_CAPABILITIES"].split(",")  # the driver's EGL library is mounted
    cpu_docs = rendered("cpu")
    assert "nvidia.com/gpu" not in yaml.safe_dump_all(cpu_docs)
    cpu = container(render_set(cpu_docs), "render")
    env = {e["name"]: e["value"] for e in cpu["env"]}
    # llvmpipe's threads are the cores the pod asks for
    assert int(env["LP_NUM_THREADS"]) == quantity(cpu["resources"]["requests"]["cpu"])
    assert quantity(cpu["resources"]["limits"]["cpu"]) == quantity(cpu["resources"]["requests"]["cpu"])


def test_kubectl_and_the_validator_are_installed_by_the_project():
    bootstrap = (ROOT / "scripts" / "bootstrap.sh").read_text()
    assert "command -v kubectl" in bootstrap and "kubernetes-client" in bootstrap
    import tomllib

    test_extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]["test"]
    # pinned exactly: the schemas it ships are the ones the manifests are checked against
    assert f"kubernetes-validate=={kubernetes_validate.__version__}" in test_extra
    assert Path(find_executable("kubectl")).exists()

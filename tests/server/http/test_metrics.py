"""Metrics labels come from closed sets: no request adds series to /metrics.

A label value is a series for the life of the process and in every scrape; the HTTP method
was one verbatim, so requests with made-up methods grew /metrics without bound (4,000 of
them: 38 → 36,074 series).
"""

from __future__ import annotations

import random
import re
import string

from server.http import metrics

SERIES = re.compile(r"^(pocketray_http_[a-z_]+)\{(.*)\} ", re.M)  # a route template has braces too
LABEL = re.compile(r'(\w+)="((?:[^"\\]|\\.)*)"')
PATHS = (
    "/api/sessions",
    "/api/sessions/{r}",
    "/api/sessions/{r}/frame",
    "/api/{r}",
    "/{r}",
    "/shaders/{r}",
    "/{r}/{r}/{r}",
)


def http_series(client) -> set[tuple[str, tuple[tuple[str, str], ...]]]:
    text = client.get("/metrics").text
    return {(name, tuple(sorted(LABEL.findall(labels)))) for name, labels in SERIES.findall(text)}


def token(rnd: random.Random, n: int = 8) -> str:
    return "".join(rnd.choices(string.ascii_letters + string.digits, k=n))


def requests(client, rnd: random.Random, count: int) -> None:
    for i in range(count):
        method = token(rnd).upper() if i % 4 else rnd.choice(("GET", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"))
        client.request(method, rnd.choice(PATHS).format(r=token(rnd)))


def test_random_methods_and_paths_add_no_series(client):
    # every kind of path with every kind of method once, so that what follows can only repeat them
    for path in PATHS:
        for method in ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS", "BREW", "get"):
            client.request(method, path.format(r="x"))
    requests(client, random.Random(1), 60)
    client.get("/metrics")  # the scrape's own series
    before = http_series(client)
    requests(client, random.Random(2), 300)  # 225 made-up methods, 300 made-up paths
    after = http_series(client)
    assert after - before == set(), sorted(after - before)[:10]
    labels = [dict(lab) for _, lab in after]
    assert {lab["method"] for lab in labels} <= metrics.HTTP_METHODS | {"other"}
    assert "other" in {lab["method"] for lab in labels}
    routes = set(client.app.openapi()["paths"]) | {
        r.path_format for r in client.app.routes if getattr(r, "path_format", None)
    }
    assert {lab["route"] for lab in labels} <= routes | {"static", "other"}
    assert all(lab["status"].isdigit() for lab in labels if "status" in lab)


def test_render_labels_come_from_the_renderer_names():
    metrics.observe_stages("made-up-method", "made-up-mode", {"trace": 1.0, "made-up-stage": 2.0})
    metrics.observe_stages("bih", "color", {"total": 1.0})
    text = metrics.exposition(object()).decode()
    assert 'method="made-up-method"' not in text and 'mode="made-up-mode"' not in text
    assert "made-up-stage" not in text
    assert 'pocketray_renders_total{method="other",mode="other"}' in text
    assert 'pocketray_render_stage_seconds_count{method="other",mode="other",stage="trace"}' in text


def test_the_label_functions_map_what_is_not_theirs_to_one_value():
    assert metrics.method_label("GET") == "GET" and metrics.method_label("get") == "other"
    assert metrics.method_label("X" * 10_000) == "other"
    assert metrics.route_label("/api/sessions/{session_id}") == "/api/sessions/{session_id}"
    assert metrics.route_label("/" * 1000) == "other"
    assert metrics.status_label(404) == "404" and metrics.status_label(1234) == "other"

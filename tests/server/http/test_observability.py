"""/metrics in the Prometheus text format, JSON log lines with request and session ids however
the app is started, and /api/ready during shutdown (server/http/metrics.py, server/http/observability.py,
server/http/drain.py)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import httpx
import pytest
from pocketray_server_support import ROOT, new_session, server_env
from prometheus_client.parser import text_string_to_metric_families

from server.api import errors
from server.frames.trace import QueueFull
from server.http import metrics


def families(text: str) -> dict:
    return {f.name: f for f in text_string_to_metric_families(text)}


def sample(fams: dict, family: str, name: str, **labels) -> float:
    return sum(
        s.value for s in fams[family].samples if s.name == name and all(s.labels.get(k) == v for k, v in labels.items())
    )


def test_metrics_scrape_with_every_documented_name(ready_client):
    sid = new_session(ready_client)["id"]
    before = families(ready_client.get("/metrics").text)
    r = ready_client.get(f"/api/sessions/{sid}/frame", params={"mode": "depth", "format": "npy"})
    assert r.status_code == 200
    scrape = ready_client.get("/metrics")
    assert scrape.status_code == 200 and scrape.headers["content-type"].startswith("text/plain")
    fams = families(scrape.text)
    for name in metrics.METRIC_NAMES:
        family = name.removesuffix("_total")
        assert family in fams, name
    method = r.headers["x-method"]
    for stage in ("queue", "build", "upload", "trace", "read", "encode", "total"):
        got = sample(
            fams,
            "pocketray_render_stage_seconds",
            "pocketray_render_stage_seconds_count",
            method=method,
            mode="depth",
            stage=stage,
        )
        was = (
            sample(
                before,
                "pocketray_render_stage_seconds",
                "pocketray_render_stage_seconds_count",
                method=method,
                mode="depth",
                stage=stage,
            )
            if "pocketray_render_stage_seconds" in before
            else 0
        )
        assert got == was + 1, stage
    assert (
        sample(
            fams,
            "pocketray_http_requests",
            "pocketray_http_requests_total",
            route="/api/sessions/{session_id}/frame",
            status="200",
        )
        >= 1
    )
    assert fams["pocketray_sessions"].samples[0].value >= 1
    assert fams["pocketray_ready"].samples[0].value == 1
    # the gauge is the process's (every app a test suite makes in it): the frame gave back what it took
    admitted_before = sample(before, "pocketray_renders_admitted", "pocketray_renders_admitted")
    assert sample(fams, "pocketray_renders_admitted", "pocketray_renders_admitted") == admitted_before
    assert not any(f.name.endswith("_created") for f in fams.values())


def test_503_answers_are_counted_by_cause(ready_client):
    def count(cause: str) -> float:
        fams = families(ready_client.get("/metrics").text)
        return (
            sample(fams, "pocketray_unavailable", "pocketray_unavailable_total", cause=cause)
            if "pocketray_unavailable" in fams
            else 0.0
        )

    worker = ready_client.app.state.worker
    before = count("queue_full")
    # the gauges are the process's (every app a test suite makes in it): counted from what they say now
    now = families(ready_client.get("/metrics").text)
    admitted = sample(now, "pocketray_renders_admitted", "pocketray_renders_admitted")
    waiting = sample(now, "pocketray_renders_waiting", "pocketray_renders_waiting")
    held = [worker.admit() for _ in range(worker.queue_size)]  # every slot taken: the next render is refused
    try:
        sid = new_session(ready_client)["id"]
        r = ready_client.get(f"/api/sessions/{sid}/frame")
        assert r.status_code == 503 and "queue" in r.json()["detail"]
        fams = families(ready_client.get("/metrics").text)
        assert sample(fams, "pocketray_renders_admitted", "pocketray_renders_admitted") == admitted + worker.queue_size
        assert sample(fams, "pocketray_renders_waiting", "pocketray_renders_waiting") == waiting + worker.queue_size
    finally:
        for ticket in held:
            ticket.__exit__(None, None, None)
    assert count("queue_full") == before + 1
    assert errors.answer(QueueFull(2), ready_client.app.state.config, "test").status == 503
    assert count("queue_full") == before + 2


def start(args: list[str], env: dict[str, str], log_path) -> subprocess.Popen:
    return subprocess.Popen(args, cwd=ROOT, env=env, stdout=open(log_path, "wb"), stderr=subprocess.STDOUT)


def wait_ready(url: str, proc: subprocess.Popen, log_path, timeout_s: float = 90) -> None:
    deadline = time.monotonic() + timeout_s
    while True:
        assert proc.poll() is None and time.monotonic() < deadline, log_path.read_text()[-3000:]
        try:
            if httpx.get(url + "/api/ready", timeout=2).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.1)


def log_lines(log_path) -> list[dict]:
    return [json.loads(line) for line in log_path.read_text().splitlines() if line.startswith("{")]


@pytest.mark.gl
def test_json_logs_carry_request_and_session_ids_under_a_bare_uvicorn(tmp_path):
    env = server_env(tmp_path / "s.sqlite3", log_level="info")
    port = int(env["POCKETRAY_PORT"])
    log = tmp_path / "uvicorn.log"
    proc = start([sys.executable, "-m", "uvicorn", "server.app:app", "--port", str(port)], env, log)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_ready(url, proc, log)
        with httpx.Client(base_url=url, timeout=30) as c:
            sid = new_session(c)["id"]
            r = c.get(f"/api/sessions/{sid}/frame", headers={"X-Request-ID": "trace-me-42"})
            assert r.status_code == 200 and r.headers["x-request-id"] == "trace-me-42"
            assert len(c.get("/api/health").headers["x-request-id"]) >= 8
        time.sleep(0.3)
        lines = log_lines(log)
        assert any(line["logger"] == "pocketray.gl" and line["message"].startswith("OpenGL:") for line in lines)
        assert any(line["logger"] == "pocketray.gl" and "warm-up" in line["message"] for line in lines)
        (access,) = [line for line in lines if line.get("request_id") == "trace-me-42"]
        assert access["session_id"] == sid and access["status"] == 200 and access["logger"] == "pocketray.access"
        assert access["route"] == "/api/sessions/{session_id}/frame" and access["duration_ms"] > 0
        assert {"time", "level", "message"} <= set(access)
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def test_ready_answers_503_from_the_moment_shutdown_begins(tmp_path):
    env = server_env(tmp_path / "s.sqlite3", drain_s=4, log_level="info")
    port = int(env["POCKETRAY_PORT"])
    log = tmp_path / "serve.log"
    proc = start([sys.executable, "-m", "server", "serve"], env, log)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_ready(url, proc, log)
        proc.send_signal(signal.SIGTERM)
        t0 = time.monotonic()
        r = httpx.get(url + "/api/ready", timeout=5)
        assert r.status_code == 503 and r.json()["detail"].startswith("draining") and r.headers["retry-after"]
        with httpx.Client(base_url=url, timeout=30) as c:  # still serving while it drains
            assert new_session(c)["version"] == 1
            m = families(c.get("/metrics").text)
            assert m["pocketray_ready"].samples[0].value == 0
            assert sample(m, "pocketray_unavailable", "pocketray_unavailable_total", cause="draining") >= 1
        assert proc.wait(timeout=30) in (0, -signal.SIGTERM)  # uvicorn re-raises the signal it handled
        assert time.monotonic() - t0 >= 3.5
        assert any("shutdown begins (SIGTERM)" in line["message"] for line in log_lines(log))
    finally:
        if proc.poll() is None:
            proc.kill()


def test_sigint_hands_over_at_once_and_without_a_main_thread_nothing_is_installed():
    from server.http.drain import Drain

    d = Drain(drain_s=100)
    called = []
    d._previous[signal.SIGINT] = lambda s, f: called.append(s)
    d._handler(signal.SIGINT, None)
    assert d.draining.is_set() and called == [signal.SIGINT]
    import threading

    out = []
    t = threading.Thread(target=lambda: out.append(Drain().install()))
    t.start()
    t.join()
    assert out == [False]

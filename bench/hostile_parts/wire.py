"""The wire: request framing, strict WebSocket messages, the WebSocket's camera, security headers.

- ``wire_smuggle``: on a raw kept-alive connection, a POST with both ``Content-Length`` and
  ``Transfer-Encoding: chunked`` whose ``Content-Length`` counts an empty chunked body plus a
  second request (``GET /api/smuggled``): the answers that come back, whether the second request
  was answered and whether the connection stayed open — straight to the render process, then
  through HAProxy with the configuration of ``server/tools/stack.py`` (when ``haproxy`` is installed);
- ``wire_ws_typo``: WebSocket ``{"type": "frame", "acumulate": true}`` and ``{"type": "refine",
  "target_sample": 4}``: the answer to each;
- ``wire_ws_camera``: one WebSocket asks ``--wire-frames`` frames (``{"type": "frame"}``, 48 × 64)
  while an HTTP client pans the same session as fast as it is answered: how many frame messages
  name a camera that is not their version's (the pans' answers say each version's camera);
- ``wire_headers``: the security headers of ``/``, ``/js/app.js`` and ``/docs``.

Usage::

    .venv/bin/python -m bench.hostile wire_smuggle wire_ws_typo wire_ws_camera wire_headers
    .venv/bin/python -m bench.hostile --root /tmp/base wire_smuggle wire_ws_typo wire_ws_camera wire_headers

Loopback only; every loop is bounded.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import socket
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import httpx

SMUGGLED_PATH = "/api/smuggled"
HEADERS = ("content-security-policy", "x-content-type-options", "x-frame-options", "referrer-policy")


def add_arguments(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--wire-frames", type=int, default=150, help="wire_ws_camera: WebSocket frames asked for")


def _session(url: str) -> str:
    body = {
        "scenario": 3,
        "n": 64,
        "seed": 1,
        "settings": {"width": 48, "height": 64, "max_recursion_depth": 2, "samples_per_pixel": 1},
    }
    r = httpx.post(url + "/api/sessions", json=body, timeout=60)
    r.raise_for_status()
    return r.json()["id"]


def _smuggle(port: int) -> dict:
    """The CL+TE request on a raw connection: the status lines that come back, and whether the
    connection was still open 3 s after the last byte."""
    smuggled = f"GET {SMUGGLED_PATH} HTTP/1.1\r\nHost: t\r\n\r\n".encode()
    body = b"0\r\n\r\n" + smuggled
    head = (
        "POST /api/sessions HTTP/1.1\r\nHost: t\r\ncontent-type: application/json\r\n"
        f"content-length: {len(body)}\r\ntransfer-encoding: chunked\r\n\r\n"
    ).encode()
    with socket.create_connection(("127.0.0.1", port), timeout=3) as sock:
        sock.sendall(head + body)
        got, still_open = b"", False
        try:
            while chunk := sock.recv(65536):
                got += chunk
        except TimeoutError:
            still_open = True
        except ConnectionResetError:
            pass
    statuses = [m.decode(errors="replace") for m in re.findall(rb"HTTP/1\.[01] \d{3}[^\r\n]*", got)]
    return {
        "statuses": statuses,
        "second_request_answered": len(statuses) > 1,
        "connection_open_after": still_open,
        "first_detail": _first_body(got)[:160],
    }


def _first_body(raw: bytes) -> str:
    _, _, rest = raw.partition(b"\r\n\r\n")
    return rest.split(b"HTTP/1.", 1)[0].decode(errors="replace")


def _haproxy_in_front(backend_port: int, work: Path) -> tuple[subprocess.Popen, int] | None:
    """HAProxy (the stack's configuration, one backend) on a free port, or None when not installed."""
    from bench.child import free_port
    from server.tools.stack import haproxy_config

    exe = shutil.which("haproxy")
    if exe is None:
        return None
    port = free_port()
    cfg = work / "haproxy.cfg"
    cfg.write_text(haproxy_config(f"127.0.0.1:{port}", [("render0", f"127.0.0.1:{backend_port}")], client_cap=0))
    log = open(work / "haproxy.log", "ab")
    proc = subprocess.Popen([exe, "-db", "-f", str(cfg)], stdout=log, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"http://127.0.0.1:{port}/api/ready", timeout=2).status_code == 200:
                return proc, port
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    proc.terminate()
    proc.wait(10)
    raise RuntimeError(f"haproxy not ready: {(work / 'haproxy.log').read_text()[-1000:]}")


def part_smuggle(root: Path, args) -> dict:
    from bench.hostile import Server

    s = Server(root)
    try:
        out = {"direct": _smuggle(s.port)}
        with tempfile.TemporaryDirectory() as tmp:
            started = _haproxy_in_front(s.port, Path(tmp))
            if started is None:
                out["haproxy"] = "not installed"
            else:
                proc, port = started
                try:
                    out["haproxy"] = _smuggle(port)
                finally:
                    proc.terminate()
                    proc.wait(10)
        return out
    finally:
        s.close()


def part_ws_typo(root: Path, args) -> dict:
    from websockets.sync.client import connect

    from bench.hostile import Server

    s = Server(root)
    try:
        sid = _session(s.url)
        out = {}
        with connect(f"ws://127.0.0.1:{s.port}/api/sessions/{sid}/ws", open_timeout=30) as ws:
            for name, msg in (
                ("frame", {"type": "frame", "acumulate": True}),
                ("refine", {"type": "refine", "target_sample": 4}),
            ):
                ws.send(json.dumps(msg))
                head = json.loads(ws.recv(timeout=60))
                if "status" in head:
                    out[name] = {"status": head["status"], "detail": head["detail"]}
                    continue
                frames = 1
                ws.recv(timeout=60)
                while "refine" in head and not head["refine"]["done"]:  # the stream runs to its end
                    head = json.loads(ws.recv(timeout=60))
                    ws.recv(timeout=60)
                    frames += 1
                out[name] = {"ran": True, "frames": frames, "samples": head.get("samples")}
        return out
    finally:
        s.close()


def part_ws_camera(root: Path, args) -> dict:
    from websockets.sync.client import connect

    from bench.hostile import Server

    s = Server(root)
    try:
        sid = _session(s.url)
        cameras = {1: httpx.get(f"{s.url}/api/sessions/{sid}", timeout=30).json()["camera"]}
        stop = threading.Event()
        pans = [0]

        def pan() -> None:
            with httpx.Client(base_url=s.url, timeout=30) as c:
                dx = 1
                while not stop.is_set() and pans[0] < 100_000:
                    r = c.post(f"/api/sessions/{sid}/gesture", json={"type": "pan", "dx": dx, "dy": 0})
                    if r.status_code == 200:
                        state = r.json()
                        cameras[state["version"]] = state["camera"]
                        pans[0] += 1
                    dx = -dx

        mover = threading.Thread(target=pan)
        mover.start()
        heads = []
        try:
            with connect(f"ws://127.0.0.1:{s.port}/api/sessions/{sid}/ws", open_timeout=30) as ws:
                for _ in range(args.wire_frames):
                    ws.send(json.dumps({"type": "frame"}))
                    head = json.loads(ws.recv(timeout=60))
                    if "status" not in head:
                        ws.recv(timeout=60)
                        heads.append(head)
                    time.sleep(0.07)  # under the socket's message rate (20/s)
        finally:
            stop.set()
            mover.join(60)
        named = [h for h in heads if h["version"] in cameras]
        wrong = sum(h["camera"] != cameras[h["version"]] for h in named)
        return {
            "frames": len(heads),
            "pans": pans[0],
            "checked": len(named),
            "camera_not_its_version": wrong,
            "share": round(wrong / max(1, len(named)), 3),
        }
    finally:
        s.close()


def part_headers(root: Path, args) -> dict:
    from bench.hostile import Server

    s = Server(root)
    try:
        out = {}
        for path in ("/", "/js/app.js", "/docs"):
            r = httpx.get(s.url + path, timeout=30)
            out[path] = {h: r.headers.get(h) for h in HEADERS}
        return out
    finally:
        s.close()


PARTS = {
    "wire_smuggle": part_smuggle,
    "wire_ws_typo": part_ws_typo,
    "wire_ws_camera": part_ws_camera,
    "wire_headers": part_headers,
}

"""Helpers of the browser tests (conftest.py holds the fixtures): the service in a
subprocess, a client page with what tests observe, camera geometry.

Failures to start (server, Chromium) are pytest failures, never skips.
"""

from __future__ import annotations

import base64
import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
ARTIFACTS = REPO / "test-artifacts"
CHROMIUM = os.environ.get("POCKETRAY_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
# WebGL2 in headless Chromium without a GPU: ANGLE on SwiftShader (explicit, so that a
# Chromium that stops falling back to it by itself still gets it).
GL_ARGS = [*CHROMIUM_ARGS, "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
SERVER_START_S = 120.0

# Small, quick renders: full 320×544 png, preview 160×272 jpeg, two recursion levels.
# (refine_samples=16: a resting view refines until its samples, so the tests that wait for rest ask few)
FAST_QUERY = (
    "scenario=1&n=64&seed=1&radius=1&width=320&height=544&preview_scale=0.5&max_recursion_depth=2&refine_samples=16"
)
# Chromium's own log line for a failed load (expected where a test makes requests fail).
FAILED_LOAD = "Failed to load resource"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _python() -> str:
    venv = REPO / ".venv" / "bin" / "python"
    return str(venv) if venv.exists() else sys.executable


def http_json(method: str, url: str, body: dict | None = None, timeout: float = 30.0) -> dict:
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method=method, headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=timeout) as r:
        return json.loads(r.read())


class Server:
    def __init__(self, tmp: Path):
        self.tmp = tmp
        self.port = _free_port()
        self.base = f"http://127.0.0.1:{self.port}"
        self.log_path = tmp / "server.log"
        self.proc: subprocess.Popen | None = None

    def start(self) -> None:
        env = {
            **os.environ,
            "POCKETRAY_PORT": str(self.port),
            "POCKETRAY_HOST": "127.0.0.1",
            "POCKETRAY_SQLITE_PATH": str(self.tmp / "s.db"),
            "POCKETRAY_LOG_LEVEL": "warning",
            # One sample, no cut-off: the client's frames stay comparable with the device's and cheap
            # (the service's own default is the 'still' profile, tested in tests/server).
            "POCKETRAY_DEFAULT_RENDER": '{"samples_per_pixel": 1, "min_weight": 0.0}',
        }
        log = open(self.log_path, "ab")
        self.proc = subprocess.Popen(
            [_python(), "-m", "server"], cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT
        )
        deadline = time.monotonic() + SERVER_START_S
        while True:
            if self.proc.poll() is not None:
                pytest.fail(f"the server exited with {self.proc.returncode}:\n{self.log_tail()}")
            try:
                with urllib.request.urlopen(self.base + "/api/ready", timeout=2) as r:
                    if r.status == 200:
                        return
            except (urllib.error.URLError, ConnectionError, TimeoutError, OSError):
                pass
            if time.monotonic() > deadline:
                self.stop()
                pytest.fail(f"the server was not ready within {SERVER_START_S} s:\n{self.log_tail()}")
            time.sleep(0.2)

    def stop(self) -> None:
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5)
        self.proc = None

    def log_tail(self, n: int = 4000) -> str:
        try:
            return self.log_path.read_text(errors="replace")[-n:]
        except OSError:
            return ""

    def session(self, sid: str) -> dict:
        return http_json("GET", f"{self.base}/api/sessions/{sid}")


MOBILE = dict(viewport={"width": 360, "height": 640}, device_scale_factor=1, is_mobile=True, has_touch=True)
DESKTOP = dict(viewport={"width": 960, "height": 640}, device_scale_factor=1)
# The phone layouts: a phone upright and on its side (390 × 844 CSS px at 3 device pixels
# per CSS pixel), and a desktop window.
PORTRAIT = dict(viewport={"width": 390, "height": 844}, device_scale_factor=3, is_mobile=True, has_touch=True)
LANDSCAPE = dict(viewport={"width": 844, "height": 390}, device_scale_factor=3, is_mobile=True, has_touch=True)
WIDE = dict(viewport={"width": 1280, "height": 800}, device_scale_factor=1)
PROFILES = {"mobile": MOBILE, "desktop": DESKTOP, "portrait": PORTRAIT, "landscape": LANDSCAPE, "wide": WIDE}


class Touch:
    """Touch input through CDP's Input.dispatchTouchEvent (not synthetic DOM events)."""

    def __init__(self, page):
        self.cdp = page.context.new_cdp_session(page)

    def send(self, kind: str, points) -> None:
        self.cdp.send(
            "Input.dispatchTouchEvent",
            {
                "type": kind,
                "touchPoints": [
                    {"x": x, "y": y, "id": i, "radiusX": 5, "radiusY": 5, "force": 1} for i, (x, y) in enumerate(points)
                ],
            },
        )

    def gesture(self, starts, ends, steps: int = 8) -> None:
        """Fingers from `starts` to `ends` (lists of (x, y)), in `steps` moves, then lifted."""
        self.send("touchStart", starts)
        for k in range(1, steps + 1):
            a = k / steps
            self.send(
                "touchMove",
                [(x0 + (x1 - x0) * a, y0 + (y1 - y0) * a) for (x0, y0), (x1, y1) in zip(starts, ends, strict=True)],
            )
        self.send("touchEnd", [])

    def path(self, frames) -> None:
        """Fingers through `frames` (a list of point lists, the first is where they go down), then lifted."""
        self.send("touchStart", frames[0])
        for pts in frames[1:]:
            self.send("touchMove", pts)
        self.send("touchEnd", [])

    def tap(self, x: float, y: float) -> None:
        self.send("touchStart", [(x, y)])
        self.send("touchEnd", [])


class Client:
    """One page on the client, with what tests need to observe it."""

    def __init__(self, server: Server, context, page):
        self.server = server
        self.context = context
        self.page = page
        self.console_errors: list[str] = []
        page.on("console", lambda m: m.type == "error" and self.console_errors.append(m.text))
        page.on("pageerror", lambda e: self.console_errors.append(f"pageerror: {e}"))

    def open(self, query: str = FAST_QUERY) -> Client:
        self.page.goto(f"{self.server.base}/?{query}")
        self.wait_idle(min_frames=1)
        return self

    def hook(self, expr: str):
        return self.page.evaluate(f"() => window.pocketray.{expr}")

    @property
    def frame_count(self) -> int:
        return self.hook("frameCount")

    def wait_idle(self, min_frames: int = 0, timeout: float = 30_000) -> None:
        """Until a frame count ≥ min_frames, nothing in flight, and the full frame shown."""
        from playwright.sync_api import TimeoutError as PlaywrightTimeout

        try:
            self.page.wait_for_function(
                """n => { const p = window.pocketray;
                          return p && p.idle && p.frameCount >= n && p.lastFrame && p.lastFrame.level === 'full'; }""",
                arg=min_frames,
                timeout=timeout,
            )
        except PlaywrightTimeout:
            state = self.page.evaluate("""() => { const p = window.pocketray; return p && {
                status: p.status, idle: p.idle, frameCount: p.frameCount, lastFrame: p.lastFrame && p.lastFrame.level,
                requests: p.requests, errors: p.errors, notices: p.notices, sessionId: p.sessionId}; }""")
            raise AssertionError(
                f"no idle full frame #{min_frames} within {timeout / 1000} s: {state}\n"
                f"console: {self.console_errors}\nserver log:\n{self.server.log_tail(2000)}"
            ) from None

    def wait_rest(self, timeout: float = 60_000) -> None:
        """:meth:`wait_idle`, then until the resting view's refinement stream (a colour view's, Whitted's
        too) has ended: from then on no frame comes without a gesture or a change."""
        self.wait_idle(timeout=timeout)
        self.page.wait_for_function("() => !window.pocketray.refining", timeout=timeout)

    def camera(self) -> dict:
        return self.server.session(self.hook("sessionId"))["camera"]

    def errors(self, allow: tuple[str, ...] = ()) -> list[str]:
        return [e for e in self.console_errors if not any(a in e for a in allow)]


# ---- camera geometry -----------------------------------------------------------------
def basis(cam: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p, t, up = (np.array(cam[k], dtype=float) for k in ("position", "target", "up"))
    f = (t - p) / np.linalg.norm(t - p)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    return r, np.cross(r, f), f


def distance(cam: dict) -> float:
    return float(np.linalg.norm(np.subtract(cam["target"], cam["position"])))


def moved(before: dict, after: dict) -> np.ndarray:
    return np.subtract(after["position"], before["position"])


def canvas_rgb(c: Client) -> np.ndarray:
    """The picture on the page's #view canvas, H×W×3 uint8."""
    w, h, data = c.page.evaluate("""() => { const cv = document.getElementById('view');
        const d = cv.getContext('2d').getImageData(0, 0, cv.width, cv.height).data;
        let s = ''; for (let i = 0; i < d.length; i += 0x8000) s += String.fromCharCode(...d.subarray(i, i + 0x8000));
        return [cv.width, cv.height, btoa(s)]; }""")
    return np.frombuffer(base64.b64decode(data), np.uint8).reshape(h, w, 4)[..., :3]

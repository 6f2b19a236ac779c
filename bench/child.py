"""A ``python -m server`` child process for the benchmarks: the one place that starts one.

On a free loopback port (or a given one, to restart on the same), with the caller's
``POCKETRAY_*`` settings and none inherited, a temporary SQLite file unless one is given,
its output in a log; the constructor returns once ``/api/ready`` says 200 (``RuntimeError``
with the log's tail if it exits first or takes longer than ``timeout_s``).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_ready(proc: subprocess.Popen, url: str, log: Path, timeout_s: float = 180) -> None:
    """Until the child's ``/api/ready`` says 200; RuntimeError with its log's tail if it exits or
    is not ready within ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"server exited: {log.read_text()[-2000:]}")
        try:
            if httpx.get(url + "/api/ready", timeout=2).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    raise RuntimeError(f"server not ready after {timeout_s:g} s: {log.read_text()[-2000:]}")


class ServerChild:
    """``python -m server`` run in ``cwd`` with settings ``POCKETRAY_<KEY>=value``.

    ``sqlite`` / ``log``: where its database and output go (a temporary directory otherwise);
    ``port``: a fixed port (a restart on the same address); ``pythonpath``: put first on the
    child's import path (another checkout's ``renderer/`` beside this ``server/``).
    """

    def __init__(
        self,
        cwd: Path,
        settings: dict[str, object] | None = None,
        *,
        sqlite: Path | None = None,
        log: Path | None = None,
        port: int | None = None,
        pythonpath: str | None = None,
        timeout_s: float = 180,
    ):
        self.tmp = tempfile.TemporaryDirectory()
        self.port = port or free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.log_path = log or Path(self.tmp.name) / "server.log"
        env = {k: v for k, v in os.environ.items() if not k.startswith("POCKETRAY_")}
        env.update(
            POCKETRAY_PORT=str(self.port),
            POCKETRAY_HOST="127.0.0.1",
            POCKETRAY_LOG_LEVEL="warning",
            POCKETRAY_SQLITE_PATH=str(sqlite or Path(self.tmp.name) / "bench.sqlite3"),
        )
        env.update({f"POCKETRAY_{k.upper()}": str(v) for k, v in (settings or {}).items()})
        if pythonpath:
            env["PYTHONPATH"] = pythonpath
        self.log = open(self.log_path, "ab")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "server"], cwd=cwd, env=env, stdout=self.log, stderr=subprocess.STDOUT
        )
        try:
            wait_ready(self.proc, self.url, self.log_path, timeout_s)
        except RuntimeError:
            self.close()
            raise

    def memory(self) -> dict[str, float]:
        """VmRSS and VmHWM of the server process, MiB."""
        out = {}
        for line in Path(f"/proc/{self.proc.pid}/status").read_text().splitlines():
            key, _, value = line.partition(":")
            if key in ("VmRSS", "VmHWM"):
                out[key] = int(value.split()[0]) / 1024
        return out

    def kill(self, sig: int) -> None:
        """Send ``sig`` and wait for the exit (the log and temporary files stay: a restart may use them)."""
        self.proc.send_signal(sig)
        self.proc.wait(30)
        self.log.close()

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.log.close()
        self.tmp.cleanup()

"""The scale-out topology on one machine, without containers: Redis, N render processes and
HAProxy on loopback ports (``./dev stack``, ``pocketray stack``; its test drives sessions
through it). ``compose.yaml`` runs the same topology in containers, one render service per
GPU, and ``deploy/k8s`` on a Kubernetes cluster; all use the HAProxy configuration made by
:func:`haproxy_config` (``deploy/haproxy.cfg`` is its output for compose,
``deploy/k8s/base/haproxy.cfg`` for the cluster, and tests keep them equal). docs/DEPLOY.md
explains it.

- **Redis** with the append-only file, fsynced at every write (``appendfsync always``): an
  acknowledged change survives a crash of Redis too.
- **Render processes**: ``pocketray serve --state-backend redis`` each, with their own GL
  context, scene cache and refit trees; ``POCKETRAY_DRAIN_S`` lets a stopping process fail its
  health check before its port closes; ``POCKETRAY_MAX_CONNECTIONS_PER_CLIENT=0``: every
  connection they see is the balancer's.
- **HAProxy**: consistent hashing on the ``X-Session-Id`` header (else the session id of the
  path), with bounded load (``hash-balance-factor``: no process takes more than 150 % of the
  mean); at most ``POCKETRAY_MAX_CONNECTIONS_PER_CLIENT`` connections per client address (429);
  health checks on ``/api/ready`` every 0.5 s, and a process whose connection fails is out at
  once; a request that never reached a process (and a GET that one dropped) is re-sent to
  another; its own errors are JSON with ``Retry-After``; ``X-Served-By`` names the process
  that answered.
- **The supervisor** (a thread of :class:`Stack`) starts a child that exits again, on the same
  port, with back-off; nothing else stops the stack but ``stop()`` (Ctrl-C).

Nothing here is a target but the loopback interface.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import httpx

SESSION_HEADER = "X-Session-Id"
SERVED_BY_HEADER = "X-Served-By"
HASH_BALANCE_FACTOR = 150  # % of the mean load a server may take before the next one is used
CHECK_INTERVAL_MS = 500
CONNECT_TIMEOUT_MS = 250  # a render process on this host or the LAN accepts within a millisecond
CHECK_TIMEOUT_MS = 2000  # /api/ready answers from the event loop; slower than this is a hung process
CHECK_FALL = 2  # failed checks before a server is taken out
CHECK_RISE = 1
DRAIN_S = 3.0  # > CHECK_FALL × CHECK_INTERVAL (a draining process fails its checks at once)
RENDER_TIMEOUT_S = 120  # POCKETRAY_RENDER_TIMEOUT_S's default: the server timeout is above it
RESOLV_CONF = "resolv.conf"  # haproxy_config(resolvers=…): the balancer's own nameservers
# The cluster's render pods (deploy/k8s): their StatefulSet (and headless Service) and namespace, and
# the most pods the balancer sends to (the autoscaler's maxReplicas fits in these slots).
CLUSTER_RENDER = ("pocketray-render", "pocketray")
CLUSTER_RENDER_SLOTS = 16
RETRY_AFTER_S = 1  # the balancer's own 429/502/503/504: a process is back or the other takes over
CAP_ENV = "POCKETRAY_MAX_CONNECTIONS_PER_CLIENT"
UNSENT_ENV = "POCKETRAY_MAX_UNSENT_BYTES_PER_CLIENT"
RESTART_BACKOFF_S = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 30.0)  # a child's n-th restart in a row waits [n]
STABLE_S = 30.0  # a child up this long has its restart count reset
SUPERVISE_EVERY_S = 0.1

# The balancer's own answers, JSON like the service's ({"detail": …}); Retry-After where a retry helps.
# (A malformed request's 400 and a slow one's 408 come from HAProxy's connection layer, which keeps its own
# pages; neither is worth a retry.)
BALANCER_ERRORS = {
    429: ("balancer: too many connections from this address (at most {cap}); reuse one", True),
    502: (
        "balancer: the render process stopped before it answered; this request may have been applied: "
        "read the session before repeating it",
        True,
    ),
    503: ("balancer: no render process is available; retry", True),
    504: ("balancer: the render process did not answer in time; retry", True),
}


def default_client_cap() -> int:
    """POCKETRAY_MAX_CONNECTIONS_PER_CLIENT's default (server/config.py), the balancer's per-address cap."""
    from ..config import ServerConfig

    return ServerConfig.model_fields["max_connections_per_client"].default


def haproxy_config(
    bind: str,
    servers: Sequence[tuple[str, str]],
    stats_bind: str | None = None,
    resolvers: str | None = None,
    client_cap: int | None = None,
) -> str:
    """HAProxy's configuration: the frontend on ``bind``, a backend of ``servers`` (name,
    host:port), the stats page on ``stats_bind``; ``resolvers``: a DNS server for container
    names (compose: Docker's ``127.0.0.11:53``), or :data:`RESOLV_CONF` (the nameservers of
    the balancer's own ``/etc/resolv.conf``: a Kubernetes pod's), so a render service that starts
    late or moves is found again; ``client_cap``: open connections per client address (0: none;
    default POCKETRAY_MAX_CONNECTIONS_PER_CLIENT's), which the render processes cannot count
    behind it."""
    cap = default_client_cap() if client_cap is None else client_cap
    lines = [
        "# pocketray's balancer (server/tools/stack.py:haproxy_config writes this; docs/DEPLOY.md explains it)",
        "global",
        "    maxconn 4096",
        "",
    ]
    resolvers_name = "kube" if resolvers == RESOLV_CONF else "docker"
    if resolvers == RESOLV_CONF:
        # HAProxy applies no search domain: the template's name is a full one (…svc.cluster.local)
        lines += [f"resolvers {resolvers_name}", "    parse-resolv-conf", "    hold valid 10s"]
        lines += ["    accepted_payload_size 8192", ""]  # one A record per render pod, beyond 512 bytes
    elif resolvers:
        lines += [f"resolvers {resolvers_name}", f"    nameserver dns {resolvers}", "    hold valid 10s", ""]
    lines += [
        "defaults",
        "    mode http",
        "    # also the pause before a refused connection is tried elsewhere: HAProxy waits min(1 s, this)",
        f"    timeout connect {CONNECT_TIMEOUT_MS}ms",
        "    timeout http-request 10s",
        f"    timeout client {RENDER_TIMEOUT_S + 15}s",
        f"    timeout server {RENDER_TIMEOUT_S + 10}s",
        f"    timeout check {CHECK_TIMEOUT_MS}ms",
        "    timeout tunnel 1h",
        "    option http-keep-alive",
        "    # the client's address in X-Forwarded-For: the render processes trust it from the balancer",
        "    # (uvicorn's forwarded-allow-ips), so the limits they keep per client address — sessions created,",
        "    # large-body slots — count each client, not the balancer",
        "    option forwardfor",
        "    # the balancer's own answers read like the service's: JSON {\"detail\"}, Retry-After where a retry helps;",
        "    # it closes the connection after them (Connection: close says so, or a client reuses it and fails)",
    ]
    for status, (detail, retry) in BALANCER_ERRORS.items():
        body = json.dumps({"detail": detail.format(cap=cap)})
        lines.append(
            f"    http-error status {status} content-type application/json string '{body}'"
            + (f" hdr Retry-After {RETRY_AFTER_S}" if retry else "")
            + " hdr Connection close"
        )
    lines += [
        "",
        "frontend pocketray",
        f"    bind {bind}",
    ]
    if cap:
        lines += [
            "    # the render processes see only this balancer's address (they run with",
            f"    # {CAP_ENV}=0): the cap on each client address is kept here",
            "    stick-table type ip size 100k expire 60s store conn_cur",
            "    tcp-request connection track-sc0 src",
            f"    http-request deny deny_status 429 if {{ sc_conn_cur(0) gt {cap} }}",
        ]
    lines += [
        "    default_backend render",
        "",
        "backend render",
        f"    # one session → one process (its scene cache and refit trees), by the {SESSION_HEADER} header,",
        "    # else the session id of the path; no key (POST /api/sessions, /api/info): round robin",
        f"    http-request set-var(txn.session) req.hdr({SESSION_HEADER})",
        "    http-request set-var(txn.session) path,field(4,/) if !{ var(txn.session) -m found } "
        "{ path_beg /api/sessions/ }",
        "    balance hash var(txn.session)",
        "    hash-type consistent",
        f"    hash-balance-factor {HASH_BALANCE_FACTOR}",
        "    # a request that never reached a process (connection refused: it was killed) goes to another; a",
        "    # GET or HEAD also when the process closed without an answer (killed mid-request): reading twice",
        "    # is harmless, a gesture twice is not, so other methods are re-sent only when nothing was sent",
        "    retries 2",
        "    option redispatch 1",
        "    retry-on conn-failure empty-response junk-response",
        "    http-request disable-l7-retry if !METH_GET",
        "    option httpchk GET /api/ready",
        "    http-check expect status 200",
        f"    http-response set-header {SERVED_BY_HEADER} %[srv_name]",
        "    # a refused or broken connection takes the process out at once (observe layer4), not after the",
        "    # checks fail; the checks bring it back when its /api/ready says 200",
        f"    default-server check inter {CHECK_INTERVAL_MS}ms fall {CHECK_FALL} rise {CHECK_RISE} "
        "observe layer4 error-limit 1 on-error mark-down "
        + (f"init-addr last,libc,none resolvers {resolvers_name}" if resolvers else "init-addr last,libc,none"),
    ]
    lines += [f"    server {name} {address}" for name, address in servers]
    if stats_bind:
        lines += [
            "",
            "frontend stats",
            f"    bind {stats_bind}",
            "    stats enable",
            "    stats uri /",
            "    stats refresh 5s",
        ]
    return "\n".join(lines) + "\n"


def compose_haproxy_config(renders: int = 2) -> str:
    """``deploy/haproxy.cfg``: the balancer of compose.yaml (services render0 … render{n−1} on 8000)."""
    return haproxy_config(
        ":8000",
        [(f"render{i}", f"render{i}:8000") for i in range(renders)],
        stats_bind=":8404",
        resolvers="127.0.0.11:53",
    )


def cluster_haproxy_config(slots: int = CLUSTER_RENDER_SLOTS) -> str:
    """``deploy/k8s/base/haproxy.cfg``: the balancer of the Kubernetes manifests. The render pods are
    a StatefulSet's, so each has a stable DNS name (``pocketray-render-I`` under the headless Service,
    present while the pod is ready): one server line per name, ``slots`` of them (the autoscaler's
    maxReplicas stays within it; a name without a pod is a server that is down). Every balancer
    replica then hashes a session onto the same ring of names, whichever pods run."""
    statefulset, namespace = CLUSTER_RENDER
    servers = [
        (f"render{i}", f"{statefulset}-{i}.{statefulset}.{namespace}.svc.cluster.local:8000") for i in range(slots)
    ]
    return haproxy_config(":8000", servers, stats_bind=":8404", resolvers=RESOLV_CONF)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def find_executable(name: str) -> str:
    exe = shutil.which(name) or next(
        (p for p in (f"/usr/sbin/{name}", f"/usr/bin/{name}") if os.access(p, os.X_OK)), None
    )
    if exe is None:
        raise RuntimeError(f"{name} is not installed (scripts/bootstrap.sh installs it: apt-get install {name})")
    return exe


@dataclass
class Child:
    name: str
    args: list[str]
    log_path: Path
    env: dict[str, str] | None = None
    proc: subprocess.Popen | None = None
    port: int = 0
    started_at: float = 0.0
    restarts: int = 0  # restarts in a row (reset once it stayed up STABLE_S)
    restart_at: float | None = None

    def start(self) -> Child:
        log = open(self.log_path, "ab")
        self.proc = subprocess.Popen(
            self.args, stdout=log, stderr=subprocess.STDOUT, env=self.env, start_new_session=True
        )
        log.close()
        self.started_at = time.monotonic()
        return self

    @property
    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    @property
    def returncode(self) -> int | None:
        return None if self.proc is None else self.proc.returncode

    def log_tail(self, chars: int = 3000) -> str:
        try:
            return self.log_path.read_text(errors="replace")[-chars:]
        except OSError:
            return ""

    def stop(self, sig: int = signal.SIGTERM, timeout_s: float = 20.0) -> None:
        proc = self.proc  # this process, not one the supervisor may start meanwhile
        if proc is None or proc.poll() is not None:
            return
        proc.send_signal(sig)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@dataclass
class Stack:
    """Redis + ``processes`` render processes + HAProxy on loopback; ``start()`` / ``stop()``."""

    processes: int = 2
    port: int = 0  # the balancer's (0: a free one)
    workdir: Path | None = None  # logs, redis' AOF, haproxy.cfg (default: a temp dir)
    env: dict[str, str] = field(default_factory=dict)  # extra POCKETRAY_* for the render processes
    drain_s: float = DRAIN_S
    supervise: bool = True  # restart a child that exits (with back-off) until stop()
    say: Callable[[str], None] = field(default=lambda line: print(line, file=sys.stderr, flush=True))
    redis: Child | None = None
    renders: list[Child] = field(default_factory=list)
    haproxy: Child | None = None
    restarted: list[tuple[str, int | None]] = field(default_factory=list)  # (child, its exit status), in order
    _own_dir: bool = False
    _stopping: threading.Event = field(default_factory=threading.Event)
    _supervisor: threading.Thread | None = None

    @property
    def client_cap(self) -> int:
        """Open connections per client address, kept by the balancer: POCKETRAY_MAX_CONNECTIONS_PER_CLIENT
        of ``env`` or of this process's environment (default: the service's default); 0: none. The
        render processes run with 0: every connection they see is the balancer's."""
        raw = self.env.get(CAP_ENV, os.environ.get(CAP_ENV))
        if raw is None:
            return default_client_cap()
        cap = int(raw)
        if cap < 0:
            raise ValueError(f"{CAP_ENV}: {cap} is not a number of connections (0: no cap)")
        return cap

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def _dir(self) -> Path:
        assert self.workdir is not None, "start() makes it"
        return self.workdir

    @property
    def redis_url(self) -> str:
        assert self.redis is not None, "the stack is started"
        return f"redis://127.0.0.1:{self.redis.port}/0"

    def start(self, timeout_s: float = 120.0) -> Stack:
        if self.workdir is None:
            self.workdir = Path(tempfile.mkdtemp(prefix="pocketray-stack-"))
            self._own_dir = True
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.port = self.port or free_port()
        try:
            self._start_redis(timeout_s)
            for i in range(self.processes):
                self.renders.append(self._start_render(i))
            for child in self.renders:
                self._wait(child, "/api/ready", timeout_s)
            self._start_haproxy(timeout_s)
        except BaseException:
            self.stop()
            raise
        if self.supervise:
            self._supervisor = threading.Thread(target=self._supervise, name="stack-supervisor", daemon=True)
            self._supervisor.start()
        return self

    def children(self) -> list[Child]:
        return [c for c in (self.redis, *self.renders, self.haproxy) if c is not None]

    def _supervise(self) -> None:
        """A child that exits is started again, on the same port with the same arguments: the balancer's
        checks bring a render process back once its /api/ready says 200, Redis reloads its AOF. The
        n-th restart in a row waits RESTART_BACKOFF_S[n] (a child that keeps failing is not a busy loop)."""
        while not self._stopping.wait(SUPERVISE_EVERY_S):
            now = time.monotonic()
            for child in self.children():
                if child.alive:
                    if child.restarts and now - child.started_at >= STABLE_S:
                        child.restarts = 0
                    continue
                if child.restart_at is None:
                    delay = RESTART_BACKOFF_S[min(child.restarts, len(RESTART_BACKOFF_S) - 1)]
                    child.restart_at = now + delay
                    self.say(
                        f"stack: {child.name} exited with {child.returncode}; restarting it"
                        + (f" in {delay:g} s" if delay else "")
                    )
                if now >= child.restart_at and not self._stopping.is_set():
                    self.restarted.append((child.name, child.returncode))
                    child.restarts += 1
                    child.restart_at = None
                    try:
                        child.start()
                    except OSError as e:
                        self.say(f"stack: {child.name} did not start: {e}")

    def _start_redis(self, timeout_s: float) -> None:
        import redis

        port = free_port()
        self.redis = Child(
            "redis",
            [
                find_executable("redis-server"),
                "--port",
                str(port),
                "--bind",
                "127.0.0.1",
                "--dir",
                str(self.workdir),
                "--appendonly",
                "yes",
                "--appendfsync",
                "always",
                "--save",
                "",
                "--protected-mode",
                "yes",
            ],
            self._dir / "redis.log",
            port=port,
        ).start()
        client = redis.Redis(host="127.0.0.1", port=port)
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                if client.ping():
                    break
            except redis.RedisError:
                if not self.redis.alive or time.monotonic() > deadline:
                    raise RuntimeError(f"redis-server did not start: {self.redis.log_tail()}") from None
                time.sleep(0.05)
        client.close()

    def _start_render(self, i: int) -> Child:
        port = free_port()
        # Every connection a render process sees is the balancer's: its per-address cap is the balancer's job.
        # So is the count of answer bytes not taken per address (the balancer buffers answers).
        env = {**os.environ, **self.env, CAP_ENV: "0", UNSENT_ENV: "0"}
        args = [
            sys.executable,
            "-m",
            "server",
            "serve",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--state-backend",
            "redis",
            "--redis-url",
            self.redis_url,
            "--drain-s",
            str(self.drain_s),
        ]
        return Child(f"render{i}", args, self._dir / f"render{i}.log", env=env, port=port).start()

    def _start_haproxy(self, timeout_s: float) -> None:
        cfg = self._dir / "haproxy.cfg"
        cfg.write_text(
            haproxy_config(
                f"127.0.0.1:{self.port}",
                [(c.name, f"127.0.0.1:{c.port}") for c in self.renders],
                client_cap=self.client_cap,
            )
        )
        exe = find_executable("haproxy")
        check = subprocess.run([exe, "-c", "-f", str(cfg)], capture_output=True, text=True)
        if check.returncode != 0:
            raise RuntimeError(f"haproxy rejects its configuration: {check.stdout}{check.stderr}")
        self.haproxy = Child("haproxy", [exe, "-db", "-f", str(cfg)], self._dir / "haproxy.log").start()
        self.haproxy.port = self.port
        self._wait(self.haproxy, "/api/ready", timeout_s)
        # Every process in rotation: each answers through the balancer (health checks passed).
        deadline = time.monotonic() + timeout_s
        seen: set[str] = set()
        while seen != {c.name for c in self.renders}:
            if time.monotonic() > deadline:
                raise RuntimeError(
                    f"the balancer never reached every process (saw {sorted(seen)}): {self.haproxy.log_tail()}"
                )
            try:
                r = httpx.get(self.url + "/api/health", timeout=5.0)
                seen.add(r.headers.get(SERVED_BY_HEADER, ""))
                seen &= {c.name for c in self.renders}
            except httpx.HTTPError:
                time.sleep(0.1)

    def _wait(self, child: Child, path: str, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if not child.alive:
                raise RuntimeError(f"{child.name} exited with {child.returncode}: {child.log_tail()}")
            try:
                if httpx.get(f"http://127.0.0.1:{child.port}{path}", timeout=5.0).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(0.1)
        raise RuntimeError(f"{child.name} did not answer {path} within {timeout_s:g} s: {child.log_tail()}")

    def kill(self, i: int) -> None:
        """SIGKILL render process ``i`` (a crash: nothing of it runs any more)."""
        self.renders[i].stop(signal.SIGKILL)

    def stop(self) -> None:
        """The supervisor, HAProxy, then the render processes (SIGTERM: they drain), then Redis; the temp
        dir goes too."""
        self._stopping.set()
        if self._supervisor is not None:
            self._supervisor.join()
        if self.haproxy is not None:
            self.haproxy.stop(signal.SIGTERM)  # haproxy -db: SIGTERM is a hard stop, SIGUSR1 a soft one
        for child in self.renders:
            if child.proc is not None and child.alive:
                child.proc.send_signal(signal.SIGINT)  # no drain needed: the balancer is gone
        for child in self.renders:
            child.stop(signal.SIGTERM, timeout_s=30)
        if self.redis is not None:
            self.redis.stop(signal.SIGTERM)
        if self._own_dir and self.workdir is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)

    def __enter__(self) -> Stack:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="pocketray stack", description="Redis, render processes and HAProxy on loopback ports, until Ctrl-C"
    )
    p.add_argument("--processes", type=int, default=2, help="render processes (default 2)")
    p.add_argument("--port", type=int, default=8080, help="the balancer's port (default 8080)")
    p.add_argument("--dir", type=Path, default=None, help="logs, Redis' AOF, haproxy.cfg (default: var/stack)")
    args = p.parse_args(argv)
    stack = Stack(processes=args.processes, port=args.port, workdir=args.dir or Path.cwd() / "var" / "stack")
    print(f"stack: starting redis, {args.processes} render processes and haproxy in {stack.workdir} …", file=sys.stderr)
    stack.start()
    print(
        f"stack: the balancer is {stack.url} (Redis {stack.redis_url}; render processes "
        + ", ".join(f"{c.name} :{c.port}" for c in stack.renders)
        + "); Ctrl-C stops everything",
        file=sys.stderr,
    )
    stop = {"now": False}

    def on_signal(signum: int, frame: object) -> None:
        stop["now"] = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        while not stop["now"]:  # the supervisor restarts a child that exits
            time.sleep(0.2)
    finally:
        stack.stop()
        print("stack: stopped", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Model files parsed in worker processes, each with a deadline and resource limits.

An uploaded model file (``POST /api/meshes``, ``POST /api/sessions/{id}/meshes``) is parsed
by :func:`renderer.io.mesh_io.load_model` into a :class:`renderer.io.model.Model` — parts, materials and
decoded textures — (a zip of a model's folder opened there too, its bounds
checked before anything is inflated) in one of ``POCKETRAY_MODEL_WORKERS`` processes kept
warm (started at the first upload; numpy and trimesh imported once), never in the service
process: a parser that a file sends into a long computation or a large allocation cannot be
stopped from a thread, but a process can be killed. Each worker runs under
``RLIMIT_AS = POCKETRAY_MODEL_MEMORY_BYTES`` (an allocation beyond it fails inside the worker:
the file is refused, the service's memory does not move) and a CPU limit of
``POCKETRAY_MODEL_TIMEOUT_S`` per file (``RLIMIT_CPU``, raised before each file); the service
waits at most ``POCKETRAY_MODEL_TIMEOUT_S`` for the answer, then kills the worker and starts
another. The file's declared counts are checked first in the worker
(:mod:`renderer.io.model_guard`), so most malformed files are refused in milliseconds.

Environment images (``PUT /api/sessions/{id}/environment``: ``.hdr``, ``.exr``) are read by
:func:`renderer.materials.envmap.read_image` in the same workers, under the same limits: even a
run-length encoded ``.hdr`` of one-byte runs is cut into packets in C and decoded by NumPy, but a
16 MB file is still a second of CPU, which the per-address share keeps to its own address.

The protocol is a pipe each way: 8-byte length, then a pickle — the job ``(bytes, format,
max_triangles, max_vertices)`` or ``("image", bytes, format)`` one way, ``("ok", model)``,
``("ok", texels)`` or ``("error", field, message)`` the other (pickles only between this module
and the processes it started; the parts of one mesh on several nodes share their arrays, and the
pickle carries them once). A worker is ``python -m
server.sessions.model_worker``: it imports the renderer's core and nothing of the service.

One client address holds at most ``POCKETRAY_MODEL_WORKERS_PER_ADDRESS`` of the workers at once
(the address is :data:`parse_client`, set by the upload routes); a further file of that address is
answered 503 at once, so its slowest files cannot keep another client's upload waiting.

Every upload pays the copy of its bytes to the worker and of the arrays back (a few ms per MB;
docs/API.md, "Hardening", gives the measured overhead).
"""

from __future__ import annotations

import atexit
import os
import pickle
import queue
import select
import signal
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from contextvars import ContextVar
from pathlib import Path
from typing import Any

_HEADER = struct.Struct("<Q")
# The client address whose file is parsed (server.sessions.ratelimit.client_key), set by the upload
# routes before they hand the work to a thread (which runs in a copy of their context); None: no share.
parse_client: ContextVar[str | None] = ContextVar("parse_client", default=None)
START_TIMEOUT_S = 60.0  # a fresh worker imports numpy and trimesh: seconds on a loaded machine


class ParsersBusy(Exception):
    """Every worker stayed busy (or one could not start): a 503 with Retry-After. The service
    passes its own ``Busy`` (``busy=``), which its error handlers answer so."""

    def __init__(self, message: str, retry_after_s: int = 1):
        super().__init__(message)
        self.retry_after_s = retry_after_s


class _Worker:
    """One worker process and its two pipes."""

    def __init__(self, memory_bytes: int, cpu_s: float):
        root = str(Path(__file__).resolve().parent.parent)  # where the renderer and server packages are
        env = dict(
            os.environ,
            OPENBLAS_NUM_THREADS="1",
            OMP_NUM_THREADS="1",
            MKL_NUM_THREADS="1",
            MALLOC_ARENA_MAX="2",
            PYTHONPATH=os.pathsep.join([root] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])),
        )
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "server.sessions.model_worker", str(memory_bytes), repr(cpu_s)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            env=env,
            close_fds=True,
        )
        assert self.proc.stdin is not None and self.proc.stdout is not None  # both piped
        self.stdin, self.stdout = self.proc.stdin, self.proc.stdout
        self.ready = False

    def _read(self, n: int, deadline: float) -> bytes:
        fd = self.stdout.fileno()
        out = bytearray()
        while len(out) < n:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                raise TimeoutError
            chunk = os.read(fd, min(n - len(out), 1 << 20))
            if not chunk:
                raise EOFError
            out += chunk
        return bytes(out)

    def wait_ready(self) -> bool:
        """Whether the worker has started (imported what it needs) within START_TIMEOUT_S."""
        if not self.ready:
            try:
                self.ready = self._read(1, time.monotonic() + START_TIMEOUT_S) == b"R"
            except (TimeoutError, EOFError):
                return False
        return self.ready

    def run(self, job: tuple, timeout_s: float) -> Any:
        """The worker's answer to ``job``; TimeoutError past ``timeout_s``, EOFError when the
        worker died."""
        deadline = time.monotonic() + timeout_s
        payload = pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL)
        try:
            self.stdin.write(_HEADER.pack(len(payload)))
            self.stdin.write(payload)
            self.stdin.flush()
        except (BrokenPipeError, OSError):
            raise EOFError from None
        del payload
        size = _HEADER.unpack(self._read(_HEADER.size, deadline))[0]
        return pickle.loads(self._read(size, deadline))

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        for f in (self.stdin, self.stdout):
            try:
                f.close()
            except OSError:
                pass


class ModelWorkers:
    """``workers`` warm worker processes; :meth:`load` parses a file in one of them."""

    def __init__(self, workers: int, timeout_s: float, memory_bytes: int, per_address: int = 0):
        self.timeout_s, self.memory_bytes = timeout_s, memory_bytes
        self.per_address = per_address  # workers one client address may hold at once (0: no share)
        self._held: dict[str, int] = {}  # client address → files of it being parsed or waiting
        self._idle: queue.LifoQueue[_Worker] = queue.LifoQueue()
        self._all: set[_Worker] = set()
        self._lock = threading.Lock()
        self._closed = False
        for _ in range(workers):
            self._idle.put(self._start())

    def _start(self) -> _Worker:
        w = _Worker(self.memory_bytes, self.timeout_s)
        with self._lock:
            self._all.add(w)
        return w

    def load(
        self,
        data: bytes,
        fmt: str | None,
        max_triangles: int,
        max_vertices: int,
        busy: Callable[..., Exception] = ParsersBusy,
    ):
        """The :class:`renderer.io.model.Model` of the file, or SceneError (``format`` or ``file``:
        what is wrong, a limit it exceeds, or the deadline it missed); ``busy`` (503) when every
        worker stays busy for ``timeout_s``."""
        from renderer.io.mesh_io import file_type_of

        ft = file_type_of(data, fmt)
        answer = self._run((bytes(data), ft, max_triangles, max_vertices), f"the {ft.upper()} model", busy)
        return answer[1]

    def load_image(self, data: bytes, fmt: str, busy: Callable[..., Exception] = ParsersBusy):
        """:func:`renderer.materials.envmap.read_image` of the file in a worker: texels, or SceneError as
        :meth:`load` (``body``, ``format``; the deadline, the memory limit)."""
        from renderer.geometry.scene import SceneError
        from renderer.materials.envmap import ENV_FORMATS

        if fmt not in ENV_FORMATS:  # (refused here: no worker needed)
            raise SceneError("format", f"unknown image format {fmt!r}; accepted: {', '.join(ENV_FORMATS)}")
        return self._run(("image", bytes(data), fmt), f"the {fmt.upper()} image", busy, field="body")[1]

    def _run(self, job: tuple, what: str, busy: Callable[..., Exception], field: str = "file") -> tuple:
        """``job`` in an idle worker: its ``("ok", …)`` answer, else SceneError (the worker's own,
        or ``field`` naming the deadline or memory limit ``what`` passed)."""
        client = parse_client.get()
        if client is None or not self.per_address:
            return self._in_worker(job, what, busy, field)
        with self._lock:
            held = self._held.get(client, 0)
            if held >= self.per_address:
                raise busy(
                    f"uploads: this address has {held} file(s) being parsed already, its share of the "
                    f"{len(self._all)} parsers (POCKETRAY_MODEL_WORKERS_PER_ADDRESS = {self.per_address}); "
                    "retry when they are done",
                    retry_after_s=1,
                )
            self._held[client] = held + 1
        try:
            return self._in_worker(job, what, busy, field)
        finally:
            with self._lock:
                left = self._held.pop(client) - 1
                if left:
                    self._held[client] = left

    def _in_worker(self, job: tuple, what: str, busy: Callable[..., Exception], field: str) -> tuple:
        from renderer.geometry.scene import SceneError

        try:
            w = self._idle.get(timeout=self.timeout_s)
        except queue.Empty:
            raise busy(
                f"model files: all {len(self._all)} parsers busy (POCKETRAY_MODEL_WORKERS); retry",
                retry_after_s=max(1, round(self.timeout_s)),
            ) from None
        healthy = False
        try:
            if not w.wait_ready():
                raise busy(
                    f"model files: a parser process did not start (exit status {w.proc.poll()}; "
                    f"POCKETRAY_MODEL_MEMORY_BYTES = {self.memory_bytes >> 20} MiB must hold its imports); "
                    "retry",
                    retry_after_s=5,
                )
            answer = w.run(job, self.timeout_s)
            healthy = True
        except TimeoutError:
            raise SceneError(
                field,
                f"parsing {what} took longer than {self.timeout_s:g} s (POCKETRAY_MODEL_TIMEOUT_S): refused",
            ) from None
        except EOFError:
            try:  # its pipe closes a moment before it has exited: its status says why
                code = w.proc.wait(timeout=1.0)
            except subprocess.TimeoutExpired:
                code = None
            why = (
                f"more than {self.timeout_s:g} s of CPU (POCKETRAY_MODEL_TIMEOUT_S)"
                if code == -signal.SIGXCPU
                else f"more than the parser's {self.memory_bytes >> 20} MiB of memory (POCKETRAY_MODEL_MEMORY_BYTES)"
                if code == -signal.SIGKILL
                else f"a parser that stopped (exit status {code})"
            )
            raise SceneError(field, f"{what} needs {why}: refused") from None
        finally:
            if healthy:
                self._idle.put(w)
            else:
                w.kill()
                with self._lock:
                    self._all.discard(w)
                if not self._closed:
                    self._idle.put(self._start())
        if answer[0] == "error":
            raise SceneError(answer[1], answer[2])
        return answer

    def close(self) -> None:
        self._closed = True
        with self._lock:
            workers, self._all = list(self._all), set()
        for w in workers:
            w.kill()


_pools: dict[tuple, ModelWorkers] = {}
_pools_lock = threading.Lock()


def workers_for(config) -> ModelWorkers | None:
    """The process's workers for ``config``'s settings (started at the first call); None when
    ``model_workers`` is 0 (files parsed in the service's own process, without a deadline)."""
    key = (config.model_workers, config.model_timeout_s, config.model_memory_bytes, config.model_workers_per_address)
    if not key[0]:
        return None
    with _pools_lock:
        pool = _pools.get(key)
        if pool is None:
            pool = _pools[key] = ModelWorkers(*key)
        return pool


def load_model(
    config,
    data: bytes,
    fmt: str | None,
    *,
    max_triangles: int,
    max_vertices: int | None = None,
    busy: Callable[..., Exception] = ParsersBusy,
):
    """:func:`renderer.io.mesh_io.load_model` of an uploaded file (a :class:`renderer.io.model.Model`), in
    a worker process (above); ``busy(message, retry_after_s=)`` is raised when no worker is free."""
    from renderer.io.mesh_io import load_model as parse
    from renderer.limits import MAX_MESH_VERTICES

    max_vertices = MAX_MESH_VERTICES if max_vertices is None else max_vertices
    pool = workers_for(config)
    if pool is None:
        return parse(data, fmt, max_triangles=max_triangles, max_vertices=max_vertices)
    return pool.load(data, fmt, max_triangles, max_vertices, busy)


def load_env_image(config, data: bytes, fmt: str, *, busy: Callable[..., Exception] = ParsersBusy):
    """:func:`renderer.materials.envmap.read_image` of an uploaded environment image, in a worker process as
    model files are (in this process when ``model_workers`` is 0)."""
    from renderer.materials.envmap import read_image

    pool = workers_for(config)
    if pool is None:
        return read_image(data, fmt)
    return pool.load_image(data, fmt, busy)


@atexit.register
def _close_all() -> None:
    with _pools_lock:
        pools = list(_pools.values())
        _pools.clear()
    for pool in pools:
        pool.close()


# ---- the worker process ------------------------------------------------------------------------
def _serve(memory_bytes: int, cpu_s: float) -> None:
    import resource

    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # whatever a library prints goes to stderr, not into the answers
    src = os.fdopen(0, "rb")
    resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))
    import gc

    import PIL.Image  # noqa: F401 - imported once, before the first file
    import trimesh  # noqa: F401

    import renderer.io.gltf_model  # noqa: F401
    from renderer.geometry.scene import SceneError
    from renderer.io.mesh_io import load_model as parse
    from renderer.materials.envmap import read_image

    try:
        import ctypes

        trim = ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):
        trim = None
    out.write(b"R")
    out.flush()
    while True:
        head = src.read(_HEADER.size)
        if len(head) < _HEADER.size:
            return  # the service closed the pipe: it is gone or closing
        try:
            job = pickle.loads(src.read(_HEADER.unpack(head)[0]))
        except MemoryError:  # the file's own bytes do not fit: said as the parse's would be
            _answer(
                out,
                (
                    "error",
                    "file",
                    f"the file needs more than the parser's {memory_bytes >> 20} MiB of memory "
                    "(POCKETRAY_MODEL_MEMORY_BYTES)",
                ),
            )
            continue
        image = job[0] == "image"
        if image:
            _, data, ft = job
        else:
            data, ft, max_triangles, max_vertices = job
        del job
        what = f"the {ft.upper()} {'image' if image else 'model'}"
        large = len(data) > 1 << 20
        used = sum(resource.getrusage(resource.RUSAGE_SELF)[:2])
        resource.setrlimit(resource.RLIMIT_CPU, (int(used + cpu_s) + 1, resource.RLIM_INFINITY))
        m = None
        try:
            if image:
                answer: tuple = ("ok", read_image(data, ft))
            else:
                m = parse(data, ft, max_triangles=max_triangles, max_vertices=max_vertices)
                answer = ("ok", m)
        except SceneError as e:
            message = e.message
            if "MemoryError" in message:
                message = (
                    f"{what} needs more than the parser's {memory_bytes >> 20} MiB of memory "
                    "(POCKETRAY_MODEL_MEMORY_BYTES)"
                )
            answer = ("error", e.field, message)
        except MemoryError:
            answer = (
                "error",
                "body" if image else "file",
                f"{what} needs more than the parser's {memory_bytes >> 20} MiB of memory "
                "(POCKETRAY_MODEL_MEMORY_BYTES)",
            )
        del data, m
        try:
            _answer(out, answer)
        except MemoryError:  # a model's arrays and textures fit, their pickle does not
            del answer
            _answer(
                out,
                (
                    "error",
                    "body" if image else "file",
                    f"{what} needs more than the parser's {memory_bytes >> 20} MiB of memory "
                    "(POCKETRAY_MODEL_MEMORY_BYTES)",
                ),
            )
        else:
            del answer
        if large:  # give a large file's arrays back to the system (~0.1 s: not for small ones)
            gc.collect()
            if trim is not None:
                trim(0)


def _answer(out, answer: tuple) -> None:
    """One answer down the pipe: its length, then its pickle."""
    payload = pickle.dumps(answer, protocol=pickle.HIGHEST_PROTOCOL)
    out.write(_HEADER.pack(len(payload)))
    out.write(payload)
    out.flush()


if __name__ == "__main__":
    _serve(int(sys.argv[1]), float(sys.argv[2]))

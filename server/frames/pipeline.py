"""The frame pipeline: plan → admit → trace → encode, one entry point for every frame.

:meth:`FramePipeline.run` takes a :class:`FrameRequest` — a scene, its settings, the session it
belongs to (if any), whether the preview comes first, what to commit when the final image is
ready — and yields the frame's parts: a session's frame, a gesture's frame, a progressive frame,
a WebSocket frame and a stateless render are all one request to it (the session's side,
:class:`server.sessions.service.SessionService`, makes the requests).

A frame is planned on the request's thread — the scene posed, the method's structure built, the
frame's cost estimated (:mod:`renderer.frame.prepare`, :mod:`renderer.frame.cost`); over
``POCKETRAY_MAX_FRAME_COST`` it is a 422 — then, its estimated bytes reserved in
``POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT`` (:class:`FrameBytes`) until it is encoded, admitted to the
GL worker's bounded queue (503 when full) and traced there in slices. A newer frame of a session
supersedes its older ones (latest wins). A gesture's frame is rendered with its new camera
*before* the gesture is committed (``commit`` runs once the final image is ready; docs/API.md,
"Gestures with a frame").

A session's frame asked with ``accumulate`` (a colour frame: the path integrator's radiance, or one
jittered slice of Whitted's sub-pixel grid, :func:`accumulates`) goes on from the samples its
session's accumulation holds and commits the new sum once it is done (:mod:`server.frames.accumulate`);
it is a *background* frame: it gets GL slices only when no interactive frame waits, it supersedes
only the session's older accumulation frames, and any newer interactive frame of the session
supersedes it.

The statistics of the builds are kept here too (:meth:`FramePipeline.stats`): the last frame's
build answers ``GET …/stats`` without building again.
"""

from __future__ import annotations

import ctypes
import json
import math
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable, Iterable, Iterator, Mapping
from concurrent.futures import TimeoutError as FutureTimeout
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, NamedTuple

from renderer.config.methods import METHODS, capabilities, not_on_gpu
from renderer.config.settings import RenderSettings
from renderer.frame.cost import largest_accepted
from renderer.frame.plan import plan_method
from renderer.frame.prepare import PreparedFrame, band_rows, batch_size, prepare_frame
from renderer.geometry.scene import Scene, SceneError
from renderer.image.denoise import denoise_nbytes, denoise_result
from renderer.image.result import traced_nbytes
from renderer.integrators import Denoiser
from renderer.limits import DEFAULT_TEXTURE_WIDTH
from renderer.scenes.animation import AnimatedScene, pose
from renderer.scenes.tree_update import TreeUpdate

from ..config import ServerConfig
from ..faults import Busy, FrameTooLarge, InputError, RenderTimeout, Superseded, input_error
from ..http import metrics
from .accumulate import AccumulationKey, Accumulations, accumulation_key
from .encode import MEDIA_TYPES, Frame, encode, encoded_nbytes
from .trace import FrameCancelled, FrameHandle, GLWorker, Ticket


def render_settings(settings: Mapping[str, Any]) -> RenderSettings:
    """RenderSettings of a stored settings dict (keys a session predates take their defaults; the
    service's own, such as quality, are not the engine's)."""
    return RenderSettings(**{k: settings[k] for k in RenderSettings.names() if k in settings})


@dataclass(frozen=True)
class FrameSettings:
    """A frame's settings, typed: the engine's (RenderSettings) and the service's own (the JPEG
    quality; None: POCKETRAY_DEFAULT_JPEG_QUALITY). A session keeps its settings as the JSON the API
    answers with; a frame request carries them typed."""

    render: RenderSettings
    quality: int | None = None

    @classmethod
    def of(cls, settings: Mapping[str, Any]) -> FrameSettings:
        """Of a session's (or a request's merged) settings, validated already."""
        return cls(render_settings(settings), settings.get("quality"))


class FrameBytes:
    """The bytes the frames admitted at once may hold together (POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT).

    Eight 4096² normal npy frames held their render targets at once (the GL thread starts every
    admitted frame before it traces any slice), then their read-backs, arrays and bodies: 5.5 GB
    resident for a budget of 3 GiB. A frame reserves its estimated bytes here before it is handed
    to the GL thread and gives them back once it is encoded; one that does not fit waits. A frame
    never asks for more than POCKETRAY_MAX_FRAME_BYTES (:meth:`FramePipeline.check_size` refuses it
    before): one frame alone never holds the whole budget against everyone else."""

    def __init__(self, limit: int):
        self.limit = int(limit)
        self.used = 0
        self._cv = threading.Condition()

    def acquire(self, nbytes: int, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        with self._cv:
            while self.used + nbytes > self.limit:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cv.wait(left)
            self.used += nbytes
            return True

    def release(self, nbytes: int) -> None:
        with self._cv:
            self.used -= nbytes
            self._cv.notify_all()


def frame_nbytes(settings: RenderSettings, accumulate: bool = False) -> int:
    """What one frame of these settings holds at most, from its render target to its encoded body:
    the target, its read-back and the result's arrays (:func:`renderer.image.result.traced_nbytes`), a
    path (or accumulation) frame's float64 sum and the float64 quotient its mean is cut from, the
    denoiser's guides and the denoiser itself (:func:`renderer.image.denoise.denoise_nbytes`), the tone
    mapping of radiance or the 8-bit copy of a float image, and the encoding (``accumulate``: and
    the new float32 sum it hands to its session's accumulation, with a Whitted accumulation's
    float64 total). The samples an accumulation holds already are counted in
    POCKETRAY_MAX_ACCUMULATION_BYTES, not here."""
    s = settings
    path = radiance(s)
    only_image = image_only(s) and not accumulate
    per_pixel = (
        (PATH_SUM_BYTES_PER_PIXEL + MEAN_BYTES_PER_PIXEL if path or accumulate else 0)
        + (ACCUMULATION_BYTES_PER_PIXEL if accumulate else 0)
        + (WHITTED_TOTAL_BYTES_PER_PIXEL if accumulate and not path else 0)
        + (GUIDE_BYTES_PER_PIXEL if path and s.denoise != Denoiser.OFF else 0)
        + (DISPLAY_BYTES_PER_PIXEL[path] if s.format in ("png", "jpeg") and not only_image else 0)
    )
    return (
        traced_nbytes(s.width, s.height, s.supersampling, only_image)
        + encoded_nbytes(s.format, "radiance" if path else s.mode, s.width, s.height)
        + s.width * s.height * per_pixel
        + (denoise_nbytes(s.denoise, s.width, s.height) if path else 0)
    )


PATH_SUM_BYTES_PER_PIXEL = (
    3 * 8
)  # a path (or Whitted accumulation) frame's float64 sum of its passes (renderer/gl/frame.py)
MEAN_BYTES_PER_PIXEL = 3 * 8  # … the sum divided by the count, float64, before the mean's float32 cast
ACCUMULATION_BYTES_PER_PIXEL = 3 * 4  # an accumulation's float32 sum (server/frames/accumulate.py)
WHITTED_TOTAL_BYTES_PER_PIXEL = 3 * 8  # a Whitted accumulation's held sum plus its own, float64
# The denoiser's guides (renderer/image/denoise.py): two more RGBA32F attachments, their read-backs, their
# float64 sums and the float32 means (the denoiser's own working memory: renderer.image.denoise.denoise_nbytes).
GUIDE_BYTES_PER_PIXEL = 2 * 16 + 2 * 16 + 2 * 24 + 2 * 12
# png/jpeg of a float image: the uint8 copy made of it (result.image_u8) — of a float frame, its
# clipped float32 copy and the bytes (12 + 3); of radiance, the tone mapping's float64 temporaries
# (renderer/image/tonemap.py: display_u8), measured 144.3–144.7 B/px of VmHWM at 1024² and 512².
DISPLAY_BYTES_PER_PIXEL = {False: 12 + 3, True: 145}


# A frame that reserved this much gives glibc's free heap back to the system once it is done: its
# arrays under glibc's mmap threshold (which grows to 32 MiB as large arrays are freed) come from the
# heap arenas, which glibc otherwise keeps: three 1349² denoised accumulation frames left 325 MiB
# resident above the idle process without it, 219 MiB with it (181 MiB of it their accumulations and
# the kept render target; docs/API.md, "Memory budget").
TRIM_AFTER_BYTES = 64 << 20
_libc: Any = None


def trim_heap() -> None:
    """glibc's ``malloc_trim(0)``: the free memory of every arena back to the system (nothing where
    the C library is not glibc)."""
    global _libc
    if _libc is None:
        try:
            _libc = ctypes.CDLL("libc.so.6")
            _libc.malloc_trim.argtypes = [ctypes.c_size_t]
        except (OSError, AttributeError):
            _libc = False
    if _libc:
        _libc.malloc_trim(0)


def radiance(settings: RenderSettings) -> bool:
    """Whether the frame's image is the path integrator's float radiance (npy: 12 bytes a pixel)."""
    return settings.path_traced


def accumulates(settings: RenderSettings) -> bool:
    """Whether a frame of these settings adds samples to an accumulation: colour, of either
    integrator (Whitted's: a jittered slice of its sub-pixel grid; docs/API.md, "Accumulation");
    the data modes and heat and recursion images stay one frame."""
    return settings.mode == "color"


def image_only(settings: RenderSettings) -> bool:
    """Whether the frame is traced into one 8-bit target (renderer.gl.frame.image_only, which the
    service may not import: png or jpeg at one sample per pixel, not the path integrator's radiance)."""
    return settings.format in ("png", "jpeg") and settings.samples_per_pixel == 1 and not radiance(settings)


class FrameOwner(NamedTuple):
    """The session a frame belongs to, as the pipeline needs it: its id (latest wins among its
    frames; fair scheduling), its scene revision (a tree kept from its previous frame) and the
    version to report."""

    id: str
    scene_rev: str
    version: int


@dataclass(frozen=True)
class FrameRequest:
    """One frame to make. ``progressive``: the preview (a supersampled
    frame's pixel-centre pass) first when there is one; ``commit(result)`` runs when the final image
    is ready and returns the session version to report; ``cancel`` (set when the client goes away)
    stops the frame. ``accumulate``: a session's colour frame goes on from (and adds to) its
    accumulation, as a background frame (:mod:`server.frames.accumulate`); other frames ignore it.
    ``slices``: of a Whitted accumulation frame, the jittered slices of its grid it adds (the
    refinement stream sizes them to its time per frame; a path frame's count is its samples)."""

    scene: Scene | AnimatedScene
    settings: FrameSettings
    owner: FrameOwner | None = None
    progressive: bool = False
    commit: Callable[[Any], int] | None = None
    cancel: threading.Event | None = None
    accumulate: bool = False
    slices: int = 1


def final(parts: Iterable[Frame]) -> Frame:
    """The last part of a frame (its final image), every part before it run and dropped."""
    (last,) = deque(parts, maxlen=1)  # a frame has at least its final image
    return last


class StatsKey(NamedTuple):
    """What a build's statistics depend on: the geometry (session, scene revision) and the build."""

    session: str
    rev: str
    method: str
    max_prims: int
    max_tree_depth: int
    time: float  # an animated scene's pose (0 for a static one)


class FramePipeline:
    """The View's frames for one process: every frame through :meth:`run`, and the builds' statistics."""

    PLAN_WAIT_S = 1.0  # a burst of small frames waits this long for a planning slot; then 503
    FRAME_BYTES_WAIT_S = 1.0  # a frame waits this long for room in POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT; then 503
    # A ray through a good hierarchy tests a few dozen spheres; this many means they crowd it.
    CROWDED_TESTS = 1000

    def __init__(self, config: ServerConfig, worker: GLWorker):
        self.config = config
        self.worker = worker
        self._stats: OrderedDict[StatsKey, dict] = OrderedDict()
        self._stats_lock = threading.Lock()
        # Planning (a scene made from a recipe, posed, its structure built, the frame's cost) holds
        # the memory of the largest requests — ~500 MB for 2^21 spheres — on the request's thread,
        # before the GL queue bounds anything: at most POCKETRAY_QUEUE_SIZE plan at once.
        self._planning = threading.BoundedSemaphore(config.queue_size)
        self._planning_depth = threading.local()
        self.frame_bytes = FrameBytes(config.max_frame_bytes_in_flight)
        self.accumulations = Accumulations(config.max_accumulation_bytes)

    # ---- the one entry point ----------------------------------------------------------------
    def run(self, request: FrameRequest) -> Iterator[Frame]:
        """Plan, admit, trace and encode the frame; yields its parts in order — the preview when
        ``request.progressive`` and there is one, then the final image. Timings in ms.

        A session's frames are one animation (key: session and scene revision), so ``bvh``
        and ``twolevel`` can refit the tree of its previous frame. A frame without a session
        has no previous frame: it always rebuilds.
        """
        scene, settings, owner, cancel = request.scene, request.settings, request.owner, request.cancel
        t_admit = time.perf_counter()
        key = (owner.id, owner.scene_rev) if owner is not None else None
        frame = self.plan(scene, settings.render, key=key)
        self.check_traceable(frame)
        accumulate = request.accumulate and owner is not None and accumulates(settings.render) and not frame.multi_pass
        nbytes = self.check_size(frame.settings, accumulate)  # before anything of the session changes
        acc_key: AccumulationKey | None = None
        held: tuple[Any, int] | None = None
        if accumulate:
            assert owner is not None, "only a session accumulates"
            camera = json.dumps(frame.scene.camera.to_json(), sort_keys=True)
            acc_key = accumulation_key(owner.scene_rev, camera, settings.render)
            held = self.accumulations.start(owner.id, acc_key)
        with self.frame_memory(frame.settings, nbytes):  # from before its target exists to its body
            t_queued = time.perf_counter()
            slices = 1 if radiance(settings.render) else max(1, int(request.slices))
            handle = self.start_frame(frame, owner=owner, accumulated=held, slices=slices)
            version = owner.version if owner is not None else None
            first = None
            try:
                if request.progressive:
                    first = self.wait(handle, t_admit, preview=True, cancel=cancel)
                    if first is not None:
                        yield self.encode_frame(
                            first,
                            frame,
                            settings,
                            t_admit,
                            handle.started_at,
                            version=version,
                            final=False,
                            t_queued=t_queued,
                        )
                result = self.wait(handle, t_admit, cancel=cancel)
            except BaseException:
                handle.cancel("disconnected")
                raise
            if request.commit is not None:
                version = request.commit(result)
            if owner is not None and result.stats:
                rs = frame.settings
                self._remember_stats(
                    StatsKey(
                        owner.id,
                        owner.scene_rev,
                        frame.method,
                        rs.max_prims,
                        rs.max_tree_depth,
                        self._pose_time(scene, rs.time),
                    ),
                    result.stats,
                )
            last = self.encode_frame(
                result, frame, settings, t_admit, handle.started_at, version=version, t_queued=t_queued
            )
            if acc_key is not None and held is not None and result.sample_sum is not None:
                assert owner is not None, "only a session accumulates"
                self.accumulations.commit(owner.id, acc_key, held[1], result.sample_sum, result.samples)
            result = handle = first = None  # type: ignore[assignment]  # the arrays go now, not when the generator does
        if nbytes >= TRIM_AFTER_BYTES:
            trim_heap()
        yield last

    # ---- plan -------------------------------------------------------------------------------
    @contextmanager
    def planning(self):
        """One of the POCKETRAY_QUEUE_SIZE planning slots for the work inside (re-entrant per thread);
        :class:`Busy` when none frees within PLAN_WAIT_S."""
        depth = getattr(self._planning_depth, "n", 0)
        if depth == 0 and not self._planning.acquire(timeout=self.PLAN_WAIT_S):
            raise Busy(
                f"busy: {self.config.queue_size} frames are being planned (POCKETRAY_QUEUE_SIZE); retry after 1 s"
            )
        self._planning_depth.n = depth + 1
        try:
            yield
        finally:
            self._planning_depth.n = depth
            if depth == 0:
                self._planning.release()

    @property
    def max_texture_width(self) -> int:
        renderer = self.worker.renderer
        return getattr(renderer, "max_texture_width", DEFAULT_TEXTURE_WIDTH)

    def plan(
        self,
        scene: Scene | AnimatedScene,
        settings: RenderSettings,
        *,
        key: Any = None,
        n_field: tuple | None = None,
    ) -> PreparedFrame:
        """Pose, build and estimate the frame on this thread; 422 when its estimated cost is
        over POCKETRAY_MAX_FRAME_COST, naming the setting to change and its accepted value
        (``n_field``: where the request names the sphere count, when it does: a scene whose
        spheres crowd every ray is refused there). Its refusals are relative to the part of the
        request that holds the settings (:class:`server.faults.InputError`)."""
        rs = settings
        if key is None:
            rs = rs.with_(update="rebuild")  # no animation to follow: never touch a kept tree
        try:
            with self.planning():
                frame = prepare_frame(scene, rs, key=key, max_width=self.max_texture_width)
        except SceneError as e:
            raise input_error(e) from None
        limit = self.config.max_frame_cost
        if frame.cost.bound_ms > limit:
            raise InputError(*self._too_costly(frame, limit, n_field))
        return frame

    @staticmethod
    def check_traceable(frame: PreparedFrame) -> None:
        """422 (``meshes``) before admission for a frame its method cannot trace on the GPU: one
        with triangles for a one-pass method whose layout holds spheres only
        (``Capabilities.meshes_on_gpu`` False — none since every one-pass layout holds triangles,
        the check stays for a method added without them; its trees are built, its
        cost is known, the GL frame would refuse it too). The ray engines refuse meshes
        earlier, naming the ``method`` (prepare_frame's check_primitives)."""
        if frame.scene.n_triangles and not frame.multi_pass and not METHODS[frame.method].capabilities.meshes_on_gpu:
            raise InputError(
                ("meshes",),
                f"method {frame.method!r}: {not_on_gpu()}; this scene has "
                f"{len(frame.scene.meshes)} mesh(es) of "
                f"{frame.scene.n_triangles:,} triangles — its scene, statistics and "
                f"meshes are served, its frames with those methods",
            )

    def _too_costly(self, frame: PreparedFrame, limit: float, n_field: tuple | None = None) -> tuple[tuple, str]:
        """Where to point and what to say of a frame estimated over the cost cap."""
        s, c = frame.settings, frame.cost
        n = frame.scene.n_spheres
        head = (
            f"this frame of {n:,} primitives is estimated at up to {c.bound_ms:,.0f} ms of GL time, over the "
            f"limit of {limit:,.0f} ms (POCKETRAY_MAX_FRAME_COST; {c.passes} pass(es) of {c.pixels:,} pixels, "
            f"{c.rays_per_pixel:.1f} rays per pixel, {c.tests_per_ray:,.0f} sphere tests per ray)"
        )
        if n_field is not None and not c.degenerate and c.tests_per_ray > self.CROWDED_TESTS:
            return (
                n_field,
                f"{head}: the spheres crowd every ray even through the hierarchy; lower n "
                f"(or the radius), the resolution, samples_per_pixel or max_recursion_depth",
            )
        # Primitives that overlap (at one point, or all covering the same pixels) are a leaf of them all
        # at any depth: no tree setting helps, the frame's size does (below).
        overlap = frame.stats.get("prims_per_leaf_max", 0) > s.max_prims and frame.stats.get(
            "depth_max", s.max_tree_depth
        ) < min(s.max_tree_depth, max(2, n.bit_length()))
        if c.degenerate and overlap:
            head += f": its spheres overlap, every ray tests {c.tests_per_ray:,.0f} of them whatever the tree"
        elif c.degenerate:
            field = "max_prims" if s.max_prims >= max(2, n // 4) else "max_tree_depth"
            return (
                (field,),
                f"{head}: the {frame.method} tree is (nearly) one leaf of {n:,} spheres — "
                f"a smaller max_prims (≤ 16) or a larger max_tree_depth (≥ "
                f"{max(2, n.bit_length())}) builds a real hierarchy",
            )
        if capabilities(frame.method).tests_every_sphere:
            return (
                ("method",),
                f"{head}: method {frame.method} tests every sphere on every ray; "
                f"use method=bih (a hierarchy) or a smaller frame",
            )
        best = largest_accepted(
            frame.method, frame.stats, frame.scene, s, limit, multi_pass=frame.multi_pass, estimator=frame.estimate
        )
        options = [f"{k} ≤ {v}" for k, v in best.items() if v is not None and v != getattr(s, k)]
        field = next(
            (
                k
                for k in ("width", "samples_per_pixel", "max_recursion_depth", "height")
                if best.get(k) is not None and best[k] != getattr(s, k)
            ),
            "width",
        )
        largest = best.get(field)
        say = f"{field}: at most {largest}" if largest is not None else f"{field}: no value fits"
        return (
            (field,),
            f"{head}; {say} at these settings"
            + (f" (or {', '.join(o for o in options if not o.startswith(field))})" if len(options) > 1 else ""),
        )

    # ---- admit ------------------------------------------------------------------------------
    @property
    def max_frame_bytes(self) -> int:
        """The most one frame may reserve, bytes: POCKETRAY_MAX_FRAME_BYTES, within the budget of all."""
        return min(self.config.max_frame_bytes, self.config.max_frame_bytes_in_flight)

    def check_size(self, settings: RenderSettings, accumulate: bool = False) -> int:
        """The bytes a frame of ``settings`` reserves (:func:`frame_nbytes`); :class:`FrameTooLarge`
        (422, ``width``) when they alone are over :attr:`max_frame_bytes`, naming the largest
        width at its height and the largest square at its other settings (every term of the
        estimate grows with the pixels, so the largest frame is the bytes over the bytes a pixel)."""
        nbytes = frame_nbytes(settings, accumulate)
        limit = self.max_frame_bytes
        if nbytes <= limit:
            return nbytes
        s = settings
        per_pixel = nbytes // (s.width * s.height)
        pixels = limit // per_pixel
        kind = "path" if radiance(s) else s.mode
        extras = [
            x
            for x in (
                "accumulate" if accumulate else "",
                f"denoise={s.denoise}" if radiance(s) and s.denoise != Denoiser.OFF else "",
            )
            if x
        ]
        raise FrameTooLarge(
            ("width",),
            f"this {s.width} × {s.height} {kind} {s.format} frame"
            + (f" ({', '.join(extras)})" if extras else "")
            + f" would hold ~{nbytes:,} bytes ({per_pixel} a pixel: render target, read-back, arrays, sums, "
            f"denoiser, encoding), over the {limit:,} one frame may hold (POCKETRAY_MAX_FRAME_BYTES); at these "
            f"settings at most {pixels:,} pixels: width: at most {pixels // s.height} at height {s.height}, "
            f"or {math.isqrt(pixels)} × {math.isqrt(pixels)}",
        )

    @contextmanager
    def frame_memory(self, settings: RenderSettings, nbytes: int):
        """``nbytes`` (the frame's estimate, :meth:`check_size`) reserved in
        POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT for the work inside; :class:`Busy` (Retry-After: the GL
        work queued ahead) when they do not fit within FRAME_BYTES_WAIT_S."""
        if not self.frame_bytes.acquire(nbytes, self.FRAME_BYTES_WAIT_S):
            retry = self.worker.retry_after()
            raise Busy(
                f"busy: the frames in flight hold the {self.config.max_frame_bytes_in_flight} bytes of "
                f"POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT; this {settings.width} × {settings.height} "
                f"{settings.mode} {settings.format} frame needs ~{nbytes} bytes; retry after {retry} s "
                f"(or ask for a smaller frame)",
                retry,
            )
        try:
            yield
        finally:
            self.frame_bytes.release(nbytes)

    def admit(self) -> Ticket:
        """A slot in the GL queue (QueueFull → 503)."""
        return self.worker.admit()

    # ---- trace ------------------------------------------------------------------------------
    def start_frame(
        self,
        frame: PreparedFrame,
        *,
        owner: FrameOwner | None,
        accumulated: tuple[Any, int] | None = None,
        slices: int = 1,
    ) -> FrameHandle:
        """Admit the planned frame (503 when full), supersede the session's older frames, and
        hand it to the GL thread to be traced in slices. ``accumulated``: the samples an
        accumulation frame goes on from (sum or None, count); such a frame is a background one and
        supersedes only the session's older background frames. ``slices``: a Whitted accumulation
        frame's jittered slices."""
        ticket = self.admit()
        background = accumulated is not None
        if owner is not None:
            for older in self.worker.in_flight(owner.id):  # latest wins
                if older.background or not background:
                    older.cancel("superseded")
        s = frame.settings
        rows = band_rows(frame.cost, self.config.slice_ms, s.width, s.height)
        batch = batch_size(frame.cost, self.config.slice_ms, frame.scene.n_primitives)

        def start(renderer):
            return renderer.start(
                frame,
                band_rows=rows,
                batch=batch,
                slice_ms=self.config.slice_ms,
                accumulated=accumulated,
                slices=slices,
            )

        return ticket.frame(
            start, session=owner.id if owner is not None else None, cost_ms=frame.cost.ms, background=background
        )

    def wait(
        self, handle: FrameHandle, t_admit: float, *, preview: bool = False, cancel: threading.Event | None = None
    ):
        """The frame's result (or, with ``preview``, its first image: None when there is none),
        within what is left of the render timeout; ``cancel`` (set when the client goes
        away) stops it."""
        deadline = t_admit + self.config.render_timeout_s
        while True:
            left = deadline - time.perf_counter()
            if left <= 0:
                handle.cancel("timeout")
                raise RenderTimeout(
                    f"render: not done within {self.config.render_timeout_s:g} s", self.worker.retry_after()
                )
            if cancel is not None and cancel.is_set():
                handle.cancel("disconnected")
            if handle.poll(preview, min(0.25, left)):
                if preview and handle.preview_result() is not None:
                    return handle.preview_result()
                try:
                    result = handle.result()
                except FrameCancelled as e:
                    raise self._cancelled(e) from None
                return None if preview else result

    def _cancelled(self, e: FrameCancelled) -> Exception:
        if e.reason == "timeout":
            return RenderTimeout(
                f"render: not done within {self.config.render_timeout_s:g} s", self.worker.retry_after()
            )
        if e.reason == "shutdown":
            from .trace import GLNotReady

            return GLNotReady("the service is shutting down")
        return Superseded(f"frame: stopped, {e.reason} (a newer frame of this session, or the client went away)")

    # ---- encode -----------------------------------------------------------------------------
    def encode_frame(
        self,
        result,
        frame: PreparedFrame,
        settings: FrameSettings,
        t_admit: float,
        t_started: float | None,
        *,
        version: int | None,
        final: bool = True,
        t_queued: float | None = None,
    ) -> Frame:
        """``queue`` is the wait from ``t_queued`` (the frame handed to the GL thread, after its
        planning, whose pose and build are stages of their own) to its first slice."""
        rs = frame.settings
        t_queued = t_queued if t_queued is not None else t_admit
        if radiance(rs):  # the mean this answer shows (an accumulation keeps its own sum, undenoised)
            result = denoise_result(result, frame.scene, rs.denoise)
        body, encode_ms = encode(
            result,
            rs.format,
            self.config.default_jpeg_quality if settings.quality is None else settings.quality,
            self.config.png_compress_level,
        )
        t_end = time.perf_counter()
        timings = {
            "queue": max(0.0, ((t_started or t_queued) - t_queued) * 1e3),
            **{
                k: float(v)
                for k, v in result.timings.items()
                if k in ("pose", "update", "build", "upload", "trace", "read")
            },
            "encode": encode_ms,
            "total": (t_end - t_admit) * 1e3,
        }
        if frame.pose_ms is not None:
            timings["pose"] = frame.pose_ms
        if final:
            metrics.observe_stages(frame.method, rs.mode, timings)
        return Frame(
            body=body,
            media_type=MEDIA_TYPES[rs.format],
            method=frame.method,
            timings=timings,
            stats=result.stats,
            version=version,
            width=rs.width,
            height=rs.height,
            final=final,
            samples=getattr(result, "samples", None) or rs.samples_per_pixel,
        )

    # ---- poses and statistics ---------------------------------------------------------------
    @staticmethod
    def _pose_time(scene: Scene | AnimatedScene, t: float) -> float:
        return float(t) if isinstance(scene, AnimatedScene) else 0.0

    @staticmethod
    def posed(scene: Scene | AnimatedScene, t: float) -> tuple[Scene, TreeUpdate]:
        """The scene posed at time ``t`` (the settings' ``time``) and a rebuild request that knows which
        spheres move (for a method's ``prepare`` outside a render: stats, device data)."""
        if not isinstance(scene, AnimatedScene):
            return scene, TreeUpdate()
        frame = pose(scene, t)
        return frame.scene, TreeUpdate(moving=frame.moving)

    def _remember_stats(self, key: StatsKey, stats: dict) -> None:
        with self._stats_lock:
            self._stats[key] = stats
            self._stats.move_to_end(key)
            while len(self._stats) > 256:
                self._stats.popitem(last=False)

    def stats(self, request: FrameRequest) -> dict:
        """Statistics of the acceleration structure for the request's settings: the last build's
        of its session, or a build made now (without rendering), by the method its frames use
        (``auto`` resolved as they resolve it, :func:`renderer.frame.plan.plan_method`)."""
        assert request.owner is not None, "statistics are a session's"
        scene, s, owner = request.scene, request.settings.render, request.owner
        try:
            method_name = plan_method(s, scene.n_tree_primitives)
        except SceneError as e:
            raise input_error(e) from None
        key = StatsKey(
            owner.id, owner.scene_rev, method_name, s.max_prims, s.max_tree_depth, self._pose_time(scene, s.time)
        )
        with self._stats_lock:
            cached = self._stats.get(key)
        if cached is not None:
            return cached
        method = METHODS[method_name]

        def job(renderer):
            posed, update = self.posed(scene, s.time)
            return method.prepare(posed, s.max_prims, s.max_tree_depth, renderer.max_texture_width, update).stats

        with self.admit() as ticket:
            try:
                stats = ticket.run(job, self.config.render_timeout_s)
            except FutureTimeout:
                raise RenderTimeout(f"build: not done within {self.config.render_timeout_s:g} s") from None
        self._remember_stats(key, stats)
        return stats

"""Service configuration: environment variables with the prefix ``POCKETRAY_``.

Every field below is read from ``POCKETRAY_<FIELD>`` (case-insensitive), e.g.
``POCKETRAY_PORT=9000`` or ``POCKETRAY_STATE_BACKEND=redis``. docs/API.md lists
them with their meaning; the defaults run the service embedded (SQLite file,
one process) on 127.0.0.1:8000.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, cast

from pydantic import AliasChoices, Field, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from renderer.frame.cost import request_work
from renderer.frame.profiles import STILL
from renderer.integrators import Integrator
from renderer.limits import JPEG_QUALITY_RANGE, MAX_PROGRAMS, MAX_SPHERES, MAX_TREE_DEPTH, MAX_TRIANGLES

from . import resources

if TYPE_CHECKING:
    from renderer.config.settings import SettingValues

FIT_SIDE = 1088  # pixels: the side of the browser client's largest 'fit' frame
QUALITY_MIN, QUALITY_MAX = JPEG_QUALITY_RANGE


class ServerConfig(BaseSettings):
    """Settings of one server process (all units in the field names or docs)."""

    model_config = SettingsConfigDict(env_prefix="POCKETRAY_", extra="ignore", frozen=True, populate_by_name=True)

    # --- network ------------------------------------------------------------
    host: str = Field("127.0.0.1", description="interface uvicorn binds to")
    port: int = Field(8000, ge=0, le=65535, description="TCP port (0 = any free port)")
    log_level: str = Field("info", description="log level (the service's and uvicorn's)")
    log_format: Literal["json", "text"] = Field(
        "json",
        description="json: one JSON object a line (time, level, logger, message, request_id, session_id); "
        "text: plain lines",
    )
    cors_origins: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="origins allowed to call the API from another site (CORS): "
        "comma-separated or a JSON list; '*' allows any; default none",
    )
    drain_s: float = Field(
        0.0,
        ge=0,
        le=600,
        description="on SIGTERM, /api/ready answers 503 at once and the process goes on "
        "serving this many seconds (a balancer's health check notices) "
        "before it shuts down",
    )

    # --- the GPU --------------------------------------------------------------------
    # POCKETRAY_GL_DEVICE (--gl-device) is its old name, still read: deployments set it.
    gpu: int | None = Field(
        None,
        ge=0,
        validation_alias=AliasChoices("POCKETRAY_GPU", "POCKETRAY_GL_DEVICE"),
        description="index of the GPU the GL context uses, in EGL's list (glcontext's "
        "GLCONTEXT_DEVICE_INDEX; `pocketray gpus` lists them); default: the first; "
        "POCKETRAY_GL_DEVICE is a deprecated name of it",
    )

    # --- state (the Model) ----------------------------------------------------
    state_backend: Literal["sqlite", "redis"] = Field(
        "sqlite", description="where sessions live: an embedded SQLite file, or Redis shared by processes"
    )
    sqlite_path: Path = Field(
        default_factory=resources.default_sqlite_path,
        description="SQLite file (sqlite backend); default var/sessions.sqlite3 under the working directory",
    )
    redis_url: str = Field("redis://127.0.0.1:6379/0", description="Redis URL (redis backend)")
    redis_prefix: str = Field("pocketray:", description="key prefix in Redis")
    session_ttl_s: float = Field(24 * 3600.0, gt=0, description="a session expires after this idle time, seconds")

    # --- the GL thread and its queue -------------------------------------------
    queue_size: int = Field(
        8, ge=1, le=1024, description="renders admitted at once (running + waiting); beyond it: 503"
    )
    render_timeout_s: float = Field(120.0, gt=0, description="longest wait for an admitted render, seconds")
    warmup: bool = Field(True, description="render a tiny scene at start-up (compiles the default shader)")

    # --- per-request caps on work -----------------------------------------------
    max_work: int = Field(
        FIT_SIDE * FIT_SIDE * STILL["max_recursion_depth"] * STILL["samples_per_pixel"],
        ge=1,
        description="cap on width × height × max_recursion_depth × samples_per_pixel of one "
        "render; for integrator 'path', on width × height × samples_per_pixel × the expected segments of "
        "a path at its depth (renderer/frame/cost.py, path_segments) "
        f"(default: the 'still' profile — depth {STILL['max_recursion_depth']}, "
        f"{STILL['samples_per_pixel']} spp — on a {FIT_SIDE} × {FIT_SIDE} frame, the "
        "client's largest 'fit' size)",
    )
    max_spheres: int = Field(MAX_SPHERES, ge=0, le=MAX_SPHERES, description="cap on the spheres of one scene")
    max_triangles: int = Field(
        MAX_TRIANGLES,
        ge=0,
        le=MAX_TRIANGLES,
        description="cap on the triangles of one scene (all its meshes; an uploaded model "
        "file counts with the scene it joins)",
    )
    max_frame_cost: float = Field(
        10_000.0,
        gt=0,
        description="cap on the estimated GL time of one frame, milliseconds of the reference machine "
        "(renderer/frame/cost.py; docs/API.md, 'Cost of a frame'): a frame estimated above it is refused "
        "with 422 naming the setting to change and its largest accepted value",
    )
    slice_ms: float = Field(
        40.0,
        gt=0,
        le=10_000,
        description="estimated GL time of one slice of a frame, milliseconds: the GL thread takes slices "
        "round-robin from the sessions' frames (bench/latency.py measures the trade-off)",
    )
    max_refine_ms: int = Field(
        1_800_000,
        ge=1,
        le=3_600_000,
        description="GL time one resting view's refinement may take, milliseconds (its frames' trace time: a "
        "stream waiting its turn behind other sessions' frames spends none of it); a stream ends there whatever "
        "its refine_time_ms (docs/API.md, 'Refinement')",
    )
    refine_slice_ms: float = Field(
        300.0,
        gt=0,
        le=10_000,
        description="GL time one frame of a refinement stream aims at, milliseconds: its samples per pixel "
        "are sized from the stream's previous frame so the image updates about this often (docs/API.md, "
        "'Refinement')",
    )
    shared_refine: bool = Field(
        True,
        description="redis backend: the samples of a resting path-traced view's refinement stream are split into "
        "ranges that every render process with an idle GL thread may claim through Redis, their sums merged by "
        "the stream's process in the order of the ranges (docs/DEPLOY.md, 'Shared refinement'); false, or the "
        "sqlite backend: one process refines its sessions alone",
    )
    shared_refine_range_samples: int = Field(
        16,
        ge=1,
        le=4096,
        description="samples per pixel of one range of a shared refinement: each costs one float32 RGB sum of the "
        "frame through Redis (written once, read once), and a process that dies loses at most one",
    )
    shared_refine_lease_s: float = Field(
        30.0,
        gt=0,
        le=600,
        description="seconds a process may hold a claimed range of a shared refinement before the stream's own "
        "process takes it back and traces it itself (longer than one range takes)",
    )
    max_target_bytes: int = Field(
        256 << 20, ge=0, description="render targets kept for reuse on the GPU, bytes (frames in flight hold their own)"
    )
    max_programs: int = Field(
        MAX_PROGRAMS,
        ge=1,
        le=4096,
        description="compiled shader programs kept for reuse (the tracer's variants and the ray engines' "
        "passes; least recently used out): about 3 MiB resident each on llvmpipe, so this bounds what "
        "a client walking through settings can grow the process by; a variant asked again after it "
        "went out is compiled again (0.5-2 s of GL time on llvmpipe)",
    )
    new_variants_per_min: float = Field(
        20.0,
        ge=0,
        le=1_000_000,
        description="new shader variants (programs the GL thread holds none of) one session's frames may "
        "have compiled per minute, per process (a token bucket refilled at this rate; frames without a "
        "session share one); beyond: 429 with Retry-After, nothing compiled or traced. 0: no limit",
    )
    new_variants_burst: int = Field(
        40,
        ge=1,
        le=1_000_000,
        description="new shader variants one session may have compiled at once before "
        "POCKETRAY_NEW_VARIANTS_PER_MIN applies (the token bucket's size)",
    )
    max_body_bytes: int = Field(16 * 1024 * 1024, ge=1024, description="largest request body, bytes (else 413)")

    # --- hostile clients and faults (docs/API.md, "Hardening") -----------------------
    max_json_depth: int = Field(
        32, ge=8, le=512, description="deepest nesting of a JSON body or message (the API needs 6); deeper: 422"
    )
    parse_workers: int = Field(
        1,
        ge=1,
        le=64,
        description="threads that parse and validate large JSON bodies, off the event loop "
        "(parsing holds the GIL: a second thread parses no faster, and the event "
        "loop waits behind both)",
    )
    switch_interval_s: float = Field(
        0.001,
        gt=0,
        le=0.1,
        description="the process's GIL switch interval, seconds (Python's default: 0.005): the event loop gets "
        "its turn between the threads that parse bodies and plan frames within 1 ms instead of 5 ms per "
        "handoff (/api/health p99 during six 16 MiB bodies: 125 → 73 ms)",
    )
    request_idle_timeout_s: float = Field(
        5.0,
        gt=0,
        le=3600,
        description="longest silence while a request's headers or body arrive, seconds; then 408 and closed",
    )
    header_timeout_s: float = Field(
        10.0, gt=0, le=3600, description="a request's headers must arrive within this, seconds; else 408"
    )
    max_connections_per_client: int = Field(
        32,
        ge=0,
        le=100_000,
        description="open connections per client address (0: no cap); beyond: 429 and closed. Behind a proxy "
        "every client is the proxy's address: raise it or set 0, and let the proxy limit clients",
    )

    # --- WebSockets and slow readers (server/http/wire.py; docs/API.md, "Hardening") -------------
    ws_idle_timeout_s: float = Field(
        60.0,
        gt=0,
        le=86_400,
        description="a WebSocket on which no message came for this long while the service had nothing to "
        "answer is closed with code 1001, seconds",
    )
    ws_messages_per_s: float = Field(
        20.0,
        gt=0,
        le=100_000,
        description="messages (and pings) per second one WebSocket may send, on average; a client over "
        "it (beyond ws_message_burst) is closed with code 1008 and its queued messages dropped",
    )
    ws_message_burst: int = Field(
        40, ge=1, le=1_000_000, description="messages one WebSocket may send at once above ws_messages_per_s"
    )
    write_timeout_s: float = Field(
        30.0,
        gt=0,
        le=3600,
        description="a connection whose client takes less than 64 KiB of its pending answer within this many "
        "seconds is closed and the answer's bytes freed, seconds",
    )
    max_unsent_bytes_per_client: int = Field(
        128 << 20,
        ge=0,
        description="answer bytes of one client address waiting for the client to take them (0: no cap); "
        "beyond: its new requests and WebSocket messages are answered 429 before any work. Behind "
        "a proxy every client is the proxy's address: set 0 and let the proxy buffer",
    )

    # --- memory of frames in flight and large-body slots (docs/API.md, "Memory budget") ---------------
    max_frame_bytes_in_flight: int = Field(
        2 << 30,
        ge=1 << 20,
        description="bytes that the frames admitted at once may hold together, estimated from each frame's "
        "size, mode and format (render target, its read-back, the result's arrays, the encoded "
        "body; a path frame's sums, denoiser and tone mapping); a frame past it waits up to 1 s for "
        "earlier frames to finish, then 503 with Retry-After. One frame alone may take at most "
        "POCKETRAY_MAX_FRAME_BYTES of it",
    )
    max_frame_bytes: int = Field(
        1792 << 20,
        ge=1 << 20,
        description="bytes one frame may reserve in POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT (at most that budget: "
        "the smaller of the two applies), estimated as there and counting what a path frame adds (its sums, "
        "the denoiser's guides and working memory, the tone mapping); a frame over it is refused up front, "
        "422 naming the largest width and square side accepted at its settings. The rest of the budget "
        "stays for the other sessions' frames meanwhile (a 4096² normal npy frame: 1.7 GiB)",
    )
    max_accumulation_bytes: int = Field(
        256 << 20,
        ge=0,
        description="bytes that the sessions' accumulations (frames asked with accumulate=1: a float32 sum "
        "of 12 bytes a pixel each) may hold together; past it the least recently used is dropped "
        "first (0: no accumulation is kept, every accumulate frame starts over)",
    )
    body_min_rate_bytes_s: int = Field(
        16 * 1024,
        ge=1,
        le=1 << 30,
        description="a large JSON body (over 64 KiB), which holds one of the POCKETRAY_QUEUE_SIZE large-body "
        "slots while it arrives, must arrive at least this fast, bytes per second, after its first "
        "POCKETRAY_BODY_GRACE_S seconds; slower: 408, the connection closed and the slot freed",
    )
    body_grace_s: float = Field(
        10.0,
        gt=0,
        le=3600,
        description="seconds a large body may take before POCKETRAY_BODY_MIN_RATE_BYTES_S applies (a body "
        "of n bytes may take body_grace_s + n / body_min_rate_bytes_s seconds in all)",
    )
    body_slots_per_client: int = Field(
        2,
        ge=0,
        le=1024,
        description="of the POCKETRAY_QUEUE_SIZE large-body slots, the most one client address holds at once "
        "(0: no cap); beyond: 429 with Retry-After. Behind a proxy every client is the proxy's "
        "address: set 0 or POCKETRAY_QUEUE_SIZE and let the proxy bound each client",
    )

    # --- model files (server/sessions/model_worker.py): parsed in worker processes with a deadline and a memory limit
    model_workers: int = Field(
        2,
        ge=0,
        le=64,
        description="processes that parse uploaded model files, kept warm (started at the first upload); busy "
        "for POCKETRAY_MODEL_TIMEOUT_S: 503. 0: parse in the service's own process, without deadline "
        "or memory limit",
    )
    model_timeout_s: float = Field(
        20.0,
        gt=0,
        le=3600,
        description="longest parse of one model file, seconds (wall clock, and its CPU time): then the worker is "
        "killed and the file refused with 422",
    )
    model_memory_bytes: int = Field(
        2 << 30,
        ge=512 << 20,
        description="address space of one model-file worker, bytes (RLIMIT_AS, the worker's imports included: "
        "~0.4 GiB); a file that needs more is refused with 422",
    )
    model_workers_per_address: int = Field(
        1,
        ge=1,
        le=64,
        description="of the POCKETRAY_MODEL_WORKERS, the most one client address holds at once (model files and "
        "environment images); beyond: 503 with Retry-After at once, so one address's slow files leave the "
        "other workers to other clients. Behind a proxy every client is the proxy's address: raise it to "
        "POCKETRAY_MODEL_WORKERS and let the proxy bound each client",
    )
    scene_cache_bytes: int = Field(
        1 << 30,
        ge=0,
        description="bytes of the scenes each process keeps decoded between requests (geometry, and environment "
        "images with their sampling tables and upload copies: ~256 MiB for a 4096 × 2048 image), least "
        "recently used dropped first; the scene in use stays however large",
    )

    # --- the session store's faults -------------------------------------------------------
    sqlite_on_corrupt: Literal["move_aside", "refuse"] = Field(
        "move_aside",
        description="a session store file that is not a readable SQLite database at start-up: move_aside (rename "
        "it to <file>.corrupt-<time> and start empty) or refuse (exit with a message)",
    )
    redis_max_retries: int = Field(
        16,
        ge=0,
        le=10_000,
        description="retries of a change whose session another process changed meanwhile (WATCH); then 503",
    )
    redis_timeout_s: float = Field(
        5.0,
        gt=0,
        le=600,
        description="longest wait for an answer of Redis, seconds (redis backend): a Redis that is stopped or "
        "stalled makes a request 503 with Retry-After after this long instead of holding it",
    )

    # --- sessions: creation rate and store quota (docs/API.md, "Hardening") -------------
    session_create_per_min: float = Field(
        60.0,
        ge=0,
        le=1_000_000,
        description="sessions one client address may create per minute, per process (POST /api/sessions; a "
        "token bucket refilled at this rate, IPv6 addresses by /64); beyond: 429 with Retry-After. "
        "0: no limit. Behind a reverse proxy every client is the proxy's address: raise it or set 0, "
        "and let the proxy limit clients",
    )
    session_create_burst: int = Field(
        60,
        ge=1,
        le=1_000_000,
        description="sessions one client address may create at once before POCKETRAY_SESSION_CREATE_PER_MIN "
        "applies (the token bucket's size)",
    )
    max_store_bytes: int = Field(
        1 << 30,
        ge=0,
        description="quota of the session store: bytes of all sessions' scene sources (recipes, uploaded scenes "
        "and the model files added to them), all processes' together; a new session or a scene "
        "change that would pass it: 507 with Retry-After (existing sessions keep working; space "
        "frees as sessions are deleted or expire). 0: no quota",
    )

    max_session_texture_bytes: int = Field(
        256 << 20,
        ge=0,
        description="a session's textures: bytes of their RGBA8 texels with every mip level (each at its own "
        "size; the store keeps their texels, which the store's quota counts too); a scene or a model that "
        "would pass it: 422 naming this setting, nothing stored. 0: no budget",
    )

    # --- gestures ---------------------------------------------------------------
    min_target_distance: float = Field(
        1e-3, gt=0, description="pinch never brings the camera closer to its target, world units"
    )

    default_render: dict[str, Any] = Field(
        default_factory=dict,
        description="JSON object overriding the render defaults of new sessions and of POST /api/render "
        "(renderer.config.settings.RenderSettings: width 640, height 1088, method bih, mode color, "
        f"max_prims 8, max_tree_depth {MAX_TREE_DEPTH}, format png; then the measured 'still' profile "
        f"of renderer.frame.profiles: max_recursion_depth {STILL['max_recursion_depth']}, samples_per_pixel "
        f"{STILL['samples_per_pixel']}, min_weight {STILL['min_weight']}; quality)",
    )

    # --- encoding ---------------------------------------------------------------
    png_compress_level: int = Field(1, ge=0, le=9, description="zlib level of PNG frames (1 = fast)")
    default_jpeg_quality: int = Field(
        85, ge=QUALITY_MIN, le=QUALITY_MAX, description="JPEG quality when a request names none"
    )

    # --- static files ------------------------------------------------------------
    client_dir: Path = Field(
        default_factory=resources.client_dir, description="served at / (default: the client shipped with the package)"
    )
    shader_dir: Path = Field(
        default_factory=resources.shader_dir,
        description="served read-only at /shaders/ (default: the package's shaders)",
    )

    @field_validator("cors_origins", mode="before")
    @classmethod
    def _origins(cls, value: Any) -> Any:
        """``a,b`` or ``["a", "b"]`` (JSON) from the environment; a list as it is."""
        if isinstance(value, str):
            text = value.strip()
            if text.startswith("["):
                import json

                return json.loads(text)
            return [o.strip() for o in text.split(",") if o.strip()]
        return value

    @model_validator(mode="after")
    def _check(self) -> ServerConfig:
        if self.state_backend == "redis" and not self.redis_url:
            raise ValueError("redis_url: required when state_backend is redis")
        from renderer.config.settings import RenderSettings
        from renderer.geometry.scene import SceneError

        d: dict[str, Any] = dict(self.default_settings())
        try:
            RenderSettings(**{k: v for k, v in d.items() if k in RenderSettings.names()})
        except (SceneError, TypeError) as e:
            raise ValueError(f"default_render: {e}") from None
        if not (isinstance(d["quality"], int) and QUALITY_MIN <= d["quality"] <= QUALITY_MAX):
            raise ValueError(f"default_render: quality must be an integer {QUALITY_MIN} … {QUALITY_MAX}")
        path = d.get("integrator", Integrator.WHITTED) == Integrator.PATH
        work = request_work(d["width"], d["height"], d["max_recursion_depth"], d["samples_per_pixel"], path)
        if work > self.max_work:
            what = (
                "width × height × samples_per_pixel × expected segments of a path"
                if path
                else "width × height × max_recursion_depth × samples_per_pixel"
            )
            raise ValueError(f"default_render: {what} = {work:.0f} exceeds max_work = {self.max_work}")
        return self

    def default_settings(self) -> SettingValues:
        """Render defaults of new sessions: RenderSettings' defaults, the 'still' profile the
        speed-against-accuracy experiment recommends (a session's frames are its still frames;
        the client asks for the 'interactive' profile while a finger moves), quality, and
        ``default_render`` last."""
        from renderer.config.settings import SETTINGS, RenderSettings

        still = {k: v for k, v in STILL.items() if k in RenderSettings.names()}
        service_own = {s.name: s.default for s in SETTINGS if not s.engine}  # the encoder's: quality
        out = {
            **RenderSettings().to_json(),
            **still,
            **service_own,
            "quality": self.default_jpeg_quality,
            **self.default_render,
        }
        return cast("SettingValues", out)  # every declared setting; _check validates them

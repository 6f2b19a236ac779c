"""Session operations: validate fully, then change the Model in one atomic write.

Every operation first checks its whole input (pydantic did the per-field part;
here the renderer's own validation and the work caps of
:class:`server.config.ServerConfig`), then hands one ``mutate`` function to the
store, which applies it in a single transaction and bumps the version. A
rejected request therefore changes nothing.

A frame is planned on the request's thread — the scene posed, the method's structure
built, the frame's cost estimated (:mod:`renderer.prepare`, :mod:`renderer.cost`); over
``POCKETRAY_MAX_FRAME_COST`` it is a 422 — then, its estimated bytes reserved in
``POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT`` (:class:`FrameBytes`) until it is encoded, admitted to the
GL worker's bounded queue (503 when full) and traced there in slices. A newer frame of a session supersedes its
older ones (latest wins). A gesture with ``frame=1`` is rendered with its new camera
*before* it is committed, and committed only when the frame is ready and the session has
not changed meanwhile: a refused, failed, timed-out or cancelled frame leaves the session
as it was (docs/API.md, "Gestures with a frame").
"""

from __future__ import annotations

import re
import secrets
import threading
import time
from collections import OrderedDict
from collections.abc import Iterable
from concurrent.futures import TimeoutError as FutureTimeout
from contextlib import contextmanager
from dataclasses import replace
from typing import Any, NamedTuple

from renderer.accel.base import NOT_ON_GPU
from renderer.animation import MUSEUM_ROOM_SPHERES, AnimatedScene, museum, pose
from renderer.cost import largest_accepted
from renderer.limits import DEFAULT_TEXTURE_WIDTH, MAX_TRIANGLES, SAMPLES_PER_PIXEL
from renderer.mesh_io import fit_transform
from renderer.methods import AUTO_METHOD, METHODS, capabilities, resolve_method
from renderer.prepare import PreparedFrame, band_rows, batch_size, prepare_frame
from renderer.result import traced_nbytes
from renderer.scenarios import mesh_scene, scenario
from renderer.scene import Camera, Scene, SceneError
from renderer.settings import RenderSettings
from renderer.tree_update import TreeUpdate

from . import controller, metrics
from .config import ServerConfig
from .gl_worker import FrameCancelled, FrameHandle, GLWorker, QueueFull, Ticket
from .model_worker import load_model
from .models import (
    MeshUploadQuery,
    OrbitGesture,
    PanGesture,
    PinchGesture,
    ResetGesture,
    SceneModel,
    SessionCreate,
    SettingsPatch,
)
from .scenes import (
    SceneCache,
    SessionScene,
    camera_from_model,
    load_source,
    museum_source,
    scenario_source,
    scene_from_model,
    scene_info,
    scene_source,
)
from .store import SessionState, SessionStore, StoreUnavailable
from .view import MEDIA_TYPES, Frame, encode, encoded_nbytes

_PATH_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def field_path(field: str) -> list[str | int]:
    """``"scene.spheres[3].radius"`` → ``["scene", "spheres", 3, "radius"]``."""
    return [int(i) if i else name for name, i in _PATH_TOKEN.findall(field)]


class InputError(SceneError):
    """A rejected input: ``loc`` as FastAPI's errors (``("query", "width")``)."""

    def __init__(self, loc: Iterable[str | int], message: str):
        loc = tuple(loc)
        inner = loc[1:] if loc and loc[0] in ("body", "query", "path") else loc
        field = ""
        for part in inner:  # the JSON path as the renderer writes it: scene.meshes[0].triangles[12]
            field += f"[{part}]" if isinstance(part, int) else (f".{part}" if field else str(part))
        super().__init__(field or "body", message)
        self.loc = loc


def relocate(e: SceneError, where: str) -> InputError:
    """A SceneError from the renderer, placed in the request (``where``: body | query)."""
    if isinstance(e, InputError):
        return e
    return InputError((where, *field_path(e.field)), e.message)


def method_settings(name: str) -> dict[str, Any]:
    """What a client needs to show only the settings that apply to method ``name``: the
    settings its build or passes read, its modes, its update schemes, whether a browser can
    trace it and whether it traces meshes on the GPU (``auto`` answers for the BIH it picks
    above the crossover)."""
    caps = METHODS[resolve_method(name, 1 << 30)].capabilities
    return {
        "settings": list(caps.settings),
        "modes": list(caps.modes),
        "update_schemes": list(caps.update_schemes),
        "device": caps.device,
        "tests_every_sphere": caps.tests_every_sphere,
        "auto": name == AUTO_METHOD,
        "primitives": list(caps.primitives),
        "meshes_on_gpu": caps.meshes_on_gpu,
    }


def info_extras(config: ServerConfig) -> dict[str, Any]:
    """The parts of GET /api/info a client's settings form needs beyond the lists and limits."""
    from renderer.settings import METHOD_NAMES, SETTINGS

    return {
        "samples_per_pixel": list(SAMPLES_PER_PIXEL),
        "render_timeout_s": config.render_timeout_s,
        "museum_room_spheres": MUSEUM_ROOM_SPHERES,
        "method_settings": {name: method_settings(name) for name in METHOD_NAMES},
        "settings": [s.metadata() for s in SETTINGS],
    }


class NotFound(Exception):
    """No such session (never existed, deleted, or expired)."""


class RenderTimeout(Exception):
    """An admitted render did not finish within ``render_timeout_s``."""

    def __init__(self, message: str, retry_after_s: int = 5):
        super().__init__(message)
        self.retry_after_s = retry_after_s


class Busy(Exception):
    """Every slot of a bounded stage is taken (planning frames, reading large bodies): 503 + Retry-After."""

    def __init__(self, message: str, retry_after_s: int = 1):
        super().__init__(message)
        self.retry_after_s = retry_after_s


class FrameBytes:
    """The bytes the frames admitted at once may hold together (POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT).

    Eight 4096² normal npy frames held their render targets at once (the GL thread starts every
    admitted frame before it traces any slice), then their read-backs, arrays and bodies: 5.5 GB
    resident for a budget of 3 GiB. A frame reserves its estimated bytes here before it is handed
    to the GL thread and gives them back once it is encoded; one that does not fit waits, and a
    frame is always admitted when none holds any bytes (else one larger than the budget never
    ran)."""

    def __init__(self, limit: int):
        self.limit = int(limit)
        self.used = 0
        self._cv = threading.Condition()

    def acquire(self, nbytes: int, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        with self._cv:
            while self.used > 0 and self.used + nbytes > self.limit:
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


def frame_nbytes(settings: RenderSettings) -> int:
    """What one frame of these settings holds at most, from its render target to its encoded body."""
    s = settings
    return (
        traced_nbytes(s.width, s.height, s.supersampling, image_only(s))
        + encoded_nbytes(s.format, "radiance" if radiance(s) else s.mode, s.width, s.height)
        + (s.width * s.height * PATH_SUM_BYTES_PER_PIXEL if radiance(s) else 0)
    )


PATH_SUM_BYTES_PER_PIXEL = 3 * 8  # a path frame's float64 sum of its passes (renderer/gl/frame.py)


def radiance(settings: RenderSettings) -> bool:
    """Whether the frame's image is the path integrator's float radiance (npy: 12 bytes a pixel)."""
    return settings.integrator == "path" and settings.mode == "color"


def image_only(settings: RenderSettings) -> bool:
    """Whether the frame is traced into one 8-bit target (renderer.gl.frame.image_only, which the
    service may not import: png or jpeg at one sample per pixel, not the path integrator's radiance)."""
    return settings.format in ("png", "jpeg") and settings.samples_per_pixel == 1 and not radiance(settings)


class Superseded(Exception):
    """A frame stopped because the session asked for a newer one (latest wins), its client
    went away, or the session changed before a gesture's frame could be committed."""


class StatsKey(NamedTuple):
    """What a build's statistics depend on: the geometry (session, scene revision) and the build."""

    session: str
    rev: str
    method: str
    max_prims: int
    max_tree_depth: int
    time: float  # an animated scene's pose (0 for a static one)


class SessionService:
    """The Model's operations plus the renders of the View, for one process."""

    @classmethod
    def render_settings(cls, settings: dict[str, Any]) -> RenderSettings:
        """RenderSettings of a stored settings dict (keys a session predates take their defaults; the
        service's own, such as quality, are not the engine's)."""
        return RenderSettings(**{k: settings[k] for k in RenderSettings.names() if k in settings})

    def __init__(self, config: ServerConfig, store: SessionStore, worker: GLWorker, cache: SceneCache | None = None):
        self.config = config
        self.store = store
        self.worker = worker
        self.cache = cache or SceneCache()
        self._stats: OrderedDict[StatsKey, dict] = OrderedDict()
        self._stats_lock = threading.Lock()
        # Planning (a scene made from a recipe, posed, its structure built, the frame's cost) holds
        # the memory of the largest requests — ~500 MB for 2^21 spheres — on the request's thread,
        # before the GL queue bounds anything: at most POCKETRAY_QUEUE_SIZE plan at once.
        self._planning = threading.BoundedSemaphore(config.queue_size)
        self._planning_depth = threading.local()
        self.frame_bytes = FrameBytes(config.max_frame_bytes_in_flight)

    PLAN_WAIT_S = 1.0  # a burst of small frames waits this long for a planning slot; then 503
    FRAME_BYTES_WAIT_S = 1.0  # a frame waits this long for room in POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT; then 503

    @contextmanager
    def frame_memory(self, settings: RenderSettings):
        """The frame's estimated bytes reserved in POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT for the work
        inside; :class:`Busy` (Retry-After: the GL work queued ahead) when they do not fit within
        FRAME_BYTES_WAIT_S."""
        nbytes = frame_nbytes(settings)
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

    # ---- settings and caps ---------------------------------------------------------------
    def default_settings(self) -> dict[str, Any]:
        return self.config.default_settings()

    def merge_settings(self, base: dict[str, Any], patch: dict[str, Any], where: str) -> dict[str, Any]:
        """``base`` updated by ``patch``, validated by RenderSettings (InputError at ``where``)."""
        merged = {**base, **patch}
        try:
            self.render_settings(merged)
        except SceneError as e:
            raise relocate(e, where) from None
        return merged

    def check_work(self, settings: dict[str, Any], n_spheres: int, where: str) -> None:
        """The caps that need no build: POCKETRAY_MAX_WORK, and the modes the method can draw.
        (The cost of a frame, POCKETRAY_MAX_FRAME_COST, is checked by :meth:`plan`.)"""
        w, h, d = settings["width"], settings["height"], settings["max_recursion_depth"]
        spp = settings.get("samples_per_pixel", 1)
        work = w * h * d * spp
        if work > self.config.max_work:
            raise InputError(
                (where, "width"),
                f"width × height × max_recursion_depth × samples_per_pixel = {w} × {h} × {d} × {spp} "
                f"= {work} exceeds the limit {self.config.max_work} (POCKETRAY_MAX_WORK); lower width, "
                f"height, max_recursion_depth or samples_per_pixel",
            )
        try:
            self.render_settings(settings).check_method(n_spheres)  # the modes the method can draw
        except SceneError as e:
            raise relocate(e, where) from None

    def check_spheres(self, n: int, loc: tuple[str | int, ...]) -> None:
        if n > self.config.max_spheres:
            raise InputError(
                loc, f"at most {self.config.max_spheres} spheres per scene (POCKETRAY_MAX_SPHERES), got {n}"
            )

    def check_triangles(self, n: int, loc: tuple[str | int, ...]) -> None:
        if n > self.config.max_triangles:
            raise InputError(
                loc, f"at most {self.config.max_triangles} triangles per scene (POCKETRAY_MAX_TRIANGLES), got {n}"
            )

    def checked_scene(self, model: SceneModel, loc: tuple[str, ...]) -> SessionScene:
        """The request's scene as arrays. Its sphere models are released here, a chunk at a time:
        nothing reads them after, and the 300,000 of a 16 MiB body, freed at once where the
        request ends (on the event loop), held the GIL ~60 ms."""
        try:
            self.check_spheres(len(model.spheres), (*loc, "spheres"))
            self.check_triangles(sum(len(m.triangles) for m in model.meshes), (*loc, "meshes"))
            return scene_from_model(model, ".".join(loc[1:]) if len(loc) > 1 else "")
        except SceneError as e:
            raise relocate(e, loc[0]) from None
        finally:
            if len(model.spheres) > 2048:
                for stop in range(len(model.spheres) - 2048, -2048, -2048):
                    del model.spheres[max(stop, 0) :]

    # ---- sessions (the Model) -----------------------------------------------------------
    def create(self, body: SessionCreate) -> SessionState:
        """A new session; its scene is made (a recipe's too) and its first frame planned in one
        planning slot."""
        with self.planning():
            return self._create(body)

    def _create(self, body: SessionCreate) -> SessionState:
        recipe_given = [k for k in ("scenario", "n", "seed", "radius") if getattr(body, k) is not None]
        sources = [
            k
            for k, given in (
                ("scenario", bool(recipe_given)),
                ("museum", body.museum is not None),
                ("mesh_scene", body.mesh_scene is not None),
                ("scene", body.scene is not None),
            )
            if given
        ]
        if len(sources) > 1:
            where = recipe_given[0] if recipe_given else sources[1]
            raise InputError(
                ("body", where),
                "give one of a scenario (scenario, n, seed, radius), a museum, "
                f"a mesh_scene or a scene, not {' and '.join(sources)}",
            )
        if body.mesh_scene is not None:
            r = body.mesh_scene
            scene = mesh_scene(r.kind, r.detail, r.smooth)
            if scene.n_triangles > self.config.max_triangles:
                raise InputError(
                    ("body", "mesh_scene", "detail"),
                    f"{scene.n_triangles} triangles; at most {self.config.max_triangles} allowed "
                    "(POCKETRAY_MAX_TRIANGLES)",
                )
            recipe = {"mesh_scene": r.model_dump()}
            source = scene_source(scene)
        elif body.museum is not None:
            m = body.museum
            self.check_spheres(m.n + MUSEUM_ROOM_SPHERES, ("body", "museum", "n"))
            scene = museum(m.n, m.kind, m.seed, m.absent)
            recipe = {"museum": m.model_dump()}
            source = museum_source(m.n, m.kind, m.seed, m.absent)
        elif body.scene is None:
            if body.scenario is None:
                raise InputError(("body", "scenario"), "required: a scenario 1, 2 or 3 with n, or a full scene")
            if body.n is None:
                raise InputError(("body", "n"), "required with scenario: the number of spheres")
            self.check_spheres(body.n, ("body", "n"))
            recipe = {
                "scenario": body.scenario,
                "n": body.n,
                "seed": body.seed or 0,
                "radius": float(body.radius if body.radius is not None else 1.0),
            }
            try:
                scene = scenario(recipe["scenario"], recipe["n"], recipe["seed"], recipe["radius"])
            except SceneError as e:
                raise relocate(e, "body") from None
            source = scenario_source(recipe["scenario"], recipe["n"], recipe["seed"], recipe["radius"])
        else:
            scene = self.checked_scene(body.scene, ("body", "scene"))
            recipe = None
            source = scene_source(scene)
        patch = body.settings.given() if body.settings else {}
        settings = self.merge_settings(self.default_settings(), patch, "body")
        self.check_work(settings, scene.n_spheres, "body")
        # A session no frame could render is refused now (the sphere count named where it was asked for).
        n_field = (
            ("body", "museum", "n")
            if body.museum is not None
            else ("body", "mesh_scene", "detail")
            if body.mesh_scene is not None
            else ("body", "n")
            if recipe
            else None
        )
        self.plan(scene, settings, "body", n_field=n_field)
        camera = scene.camera.to_json()
        state = SessionState(
            id=secrets.token_urlsafe(24),
            version=1,
            camera=camera,
            home_camera=camera,
            settings=settings,
            scene_info=scene_info(scene, recipe),
            scene_rev=secrets.token_hex(8),
        )
        self.store.create(state, source)
        self.cache.put((state.id, state.scene_rev), scene)
        return state

    def get(self, session_id: str) -> SessionState:
        state = self.store.get(session_id)
        if state is None:
            raise NotFound(session_id)
        return state

    def _update(self, session_id: str, mutate, source: bytes | None = None) -> SessionState:
        state = self.store.update(session_id, mutate, source)
        if state is None:
            raise NotFound(session_id)
        return state

    def delete(self, session_id: str) -> None:
        if not self.store.delete(session_id):
            raise NotFound(session_id)
        self.cache.drop_session(session_id)

    def scene(self, state: SessionState) -> SessionScene:
        """The session's scene (animated or not) seen through its current camera (cached per process)."""
        camera = Camera.from_json(state.camera)
        base = self.cache.get((state.id, state.scene_rev))
        if base is None:
            got = self.store.get_source(state.id)
            if got is None:
                raise NotFound(state.id)
            rev, source = got
            try:
                base = load_source(source, camera)
            except Exception as e:  # bytes the store holds that are no scene: a store fault, not a bug
                raise StoreUnavailable(f"holding a scene that does not decode ({type(e).__name__})") from None
            self.cache.put((state.id, rev), base)
        return base if base.camera == camera else base.with_camera(camera)

    def replace_scene(self, session_id: str, model: SceneModel) -> SessionState:
        scene = self.checked_scene(model, ("body",))
        source = scene_source(scene)
        rev = secrets.token_hex(8)
        camera = scene.camera.to_json()

        def mutate(old: SessionState) -> SessionState:
            return replace(old, camera=camera, home_camera=camera, scene_rev=rev, scene_info=scene_info(scene, None))

        state = self._update(session_id, mutate, source)
        self.cache.put((state.id, rev), scene)
        return state

    def add_mesh(self, session_id: str, data: bytes, query: MeshUploadQuery) -> tuple[SessionState, int, int]:
        """Parse a model file (in memory: nothing is written) and add it to the session's scene
        as a new mesh, its last; the camera stays. Returns the state, the mesh's index and its
        first triangle's primitive id. 422 naming ``body`` (the file), ``query.format``,
        ``query.material``, or the triangle cap (POCKETRAY_MAX_TRIANGLES, with the scene's own)."""
        state = self.get(session_id)
        old = self.scene(state)
        rest = old.scene if isinstance(old, AnimatedScene) else old
        room = self.config.max_triangles - rest.n_triangles
        if room <= 0 or not data:
            raise InputError(
                ("body",),
                "the scene already holds the most triangles allowed "
                f"({self.config.max_triangles}, POCKETRAY_MAX_TRIANGLES)"
                if data
                else "empty body: send the model file's bytes",
            )
        try:
            parsed = load_model(self.config, data, query.format, max_triangles=min(room, MAX_TRIANGLES), busy=Busy)
        except SceneError as e:
            where = ("query", "format") if e.field == "format" else ("body",)
            raise InputError(
                where,
                f"{e.message}"
                + (
                    f" (POCKETRAY_MAX_TRIANGLES = {self.config.max_triangles}, {rest.n_triangles} in the scene)"
                    if "triangles" in e.message
                    else ""
                ),
            ) from None
        if query.material >= len(rest.materials):
            raise InputError(
                ("query", "material"),
                f"material index {query.material} out of range (the scene has {len(rest.materials)} materials)",
            )
        try:
            mesh = parsed.to_mesh(
                query.material, fit_transform(parsed, query.size) if query.size else None, query.smooth
            )
            grown = rest.with_geometry(
                rest.sphere_centers, rest.sphere_radii, rest.sphere_materials, (*rest.meshes, mesh)
            )
            scene: SessionScene = AnimatedScene(grown, old.motions) if isinstance(old, AnimatedScene) else grown
        except SceneError as e:
            raise InputError(("body",), f"the model does not fit the scene: {e.field}: {e.message}") from None
        source = scene_source(scene)
        rev = secrets.token_hex(8)

        def mutate(current: SessionState) -> SessionState:
            if current.scene_rev != state.scene_rev:
                raise Superseded("session: its scene changed while the model was read; send it again")
            # no recipe any more: a scenario with a model in it is a scene of its own
            return replace(current, scene_rev=rev, scene_info=scene_info(scene, None))

        new = self._update(session_id, mutate, source)
        self.cache.put((new.id, rev), scene)
        index = len(grown.meshes) - 1
        return new, index, grown.triangle_id_base + grown.mesh_triangle_range(index).start

    def set_camera(self, session_id: str, model) -> SessionState:
        try:
            camera = camera_from_model(model)
        except SceneError as e:
            raise relocate(e, "body") from None
        return self._update(session_id, lambda old: replace(old, camera=camera.to_json()))

    def patch_settings(self, session_id: str, patch: SettingsPatch) -> SessionState:
        """Change render defaults; settings no frame could render (over the frame cost cap
        included, which needs a build) are refused before anything changes."""
        given = patch.given()
        state = self.get(session_id)
        checked = self.merge_settings(state.settings, given, "body")
        self.check_work(checked, state.scene_info.get("n_spheres", 0), "body")
        self.plan(self.scene(state), checked, "body")

        def mutate(old: SessionState) -> SessionState:
            merged = self.merge_settings(old.settings, given, "body")
            self.check_work(merged, old.scene_info.get("n_spheres", 0), "body")
            if merged != checked:  # another change came between: check what is stored now
                self.plan(self.scene(old), merged, "body")
            return replace(old, settings=merged)

        return self._update(session_id, mutate)

    def moved_camera(
        self,
        old: SessionState,
        gesture: PanGesture | PinchGesture | OrbitGesture | ResetGesture,
        frame_patch: dict[str, Any] | None = None,
    ) -> Camera:
        """The camera after ``gesture`` (InputError naming the gesture's field when the move
        would leave the coordinate range)."""
        cam = Camera.from_json(old.camera)
        try:
            if isinstance(gesture, PanGesture):
                height = gesture.viewport_height or (frame_patch or {}).get("height") or old.settings["height"]
                return controller.pan(cam, gesture.dx, gesture.dy, float(height))
            if isinstance(gesture, PinchGesture):
                return controller.pinch(cam, gesture.scale, self.config.min_target_distance)
            if isinstance(gesture, OrbitGesture):
                return controller.orbit(cam, gesture.yaw, gesture.pitch)
            return controller.reset(Camera.from_json(old.home_camera))
        except SceneError as e:
            field = {"pan": "dx", "pinch": "scale", "orbit": "yaw", "reset": "type"}[gesture.type]
            raise InputError(
                ("body", field), f"the {gesture.type} would move the camera out of range ({e.field}: {e.message})"
            ) from None

    def gesture(
        self, session_id: str, gesture: PanGesture | PinchGesture | OrbitGesture | ResetGesture
    ) -> SessionState:
        """Apply a gesture (no frame)."""
        return self._update(session_id, lambda old: replace(old, camera=self.moved_camera(old, gesture).to_json()))

    # ---- renders (the View) -------------------------------------------------------------
    def admit(self) -> Ticket:
        """A slot in the GL queue (QueueFull → 503)."""
        return self.worker.admit()

    def frame_settings(self, state: SessionState, patch: dict[str, Any]) -> dict[str, Any]:
        merged = self.merge_settings(state.settings, patch, "query")
        self.check_work(merged, state.scene_info.get("n_spheres", 0), "query")
        return merged

    @property
    def max_texture_width(self) -> int:
        renderer = self.worker.renderer
        return getattr(renderer, "max_texture_width", DEFAULT_TEXTURE_WIDTH)

    def plan(
        self,
        scene: SessionScene,
        settings: dict[str, Any],
        where: str,
        *,
        key: Any = None,
        n_field: tuple | None = None,
    ) -> PreparedFrame:
        """Pose, build and estimate the frame on this thread; 422 when its estimated cost is
        over POCKETRAY_MAX_FRAME_COST, naming the setting to change and its accepted value
        (``n_field``: where the request names the sphere count, when it does: a scene whose
        spheres crowd every ray is refused there)."""
        rs = self.render_settings(settings)
        if key is None:
            rs = rs.with_(update="rebuild")  # no animation to follow: never touch a kept tree
        try:
            with self.planning():
                frame = prepare_frame(scene, rs, key=key, max_width=self.max_texture_width)
        except SceneError as e:
            raise relocate(e, where) from None
        limit = self.config.max_frame_cost
        if frame.cost.bound_ms > limit:
            raise InputError(*self._too_costly(frame, where, limit, n_field))
        return frame

    @staticmethod
    def check_traceable(frame: PreparedFrame, where: str) -> None:
        """422 (``meshes``) before admission for a frame its method cannot trace on the GPU: one
        with triangles for a one-pass method whose layout holds spheres only
        (``Capabilities.meshes_on_gpu`` False — none since every one-pass layout holds triangles,
        the check stays for a method added without them; its trees are built, its
        cost is known, the GL frame would refuse it too). The ray engines refuse meshes
        earlier, naming the ``method`` (prepare_frame's check_primitives)."""
        if frame.scene.n_triangles and not frame.multi_pass and not METHODS[frame.method].capabilities.meshes_on_gpu:
            raise InputError(
                (where, "meshes"),
                f"method {frame.method!r}: {NOT_ON_GPU}; this scene has "
                f"{len(frame.scene.meshes)} mesh(es) of "
                f"{frame.scene.n_triangles:,} triangles — its scene, statistics and "
                f"meshes are served, its frames with those methods",
            )

    # A ray through a good hierarchy tests a few dozen spheres; this many means they crowd it.
    CROWDED_TESTS = 1000

    def _too_costly(
        self, frame: PreparedFrame, where: str, limit: float, n_field: tuple | None = None
    ) -> tuple[tuple, str]:
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
        if c.degenerate:
            field = "max_prims" if s.max_prims >= max(2, n // 4) else "max_tree_depth"
            return (
                (where, field),
                f"{head}: the {frame.method} tree is (nearly) one leaf of {n:,} spheres — "
                f"a smaller max_prims (≤ 16) or a larger max_tree_depth (≥ "
                f"{max(2, n.bit_length())}) builds a real hierarchy",
            )
        if capabilities(frame.method).tests_every_sphere:
            return (
                (where, "method"),
                f"{head}: method {frame.method} tests every sphere on every ray; "
                f"use method=bih (a hierarchy) or a smaller frame",
            )
        best = largest_accepted(frame.method, frame.stats, frame.scene, s, limit, multi_pass=frame.multi_pass)
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
            (where, field),
            f"{head}; {say} at these settings"
            + (f" (or {', '.join(o for o in options if not o.startswith(field))})" if len(options) > 1 else ""),
        )

    def start_frame(self, frame: PreparedFrame, *, session: SessionState | None) -> FrameHandle:
        """Admit the planned frame (503 when full), supersede the session's older frames, and
        hand it to the GL thread to be traced in slices."""
        ticket = self.admit()
        if session is not None:
            for older in self.worker.in_flight(session.id):  # latest wins
                older.cancel("superseded")
        s = frame.settings
        rows = band_rows(frame.cost, self.config.slice_ms, s.width, s.height)
        batch = batch_size(frame.cost, self.config.slice_ms, frame.scene.n_primitives)

        def start(renderer):
            return renderer.start(frame, band_rows=rows, batch=batch, slice_ms=self.config.slice_ms)

        return ticket.frame(start, session=session.id if session is not None else None, cost_ms=frame.cost.ms)

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
            from .gl_worker import GLNotReady

            return GLNotReady("the service is shutting down")
        return Superseded(f"frame: stopped, {e.reason} (a newer frame of this session, or the client went away)")

    def encode_frame(
        self,
        result,
        frame: PreparedFrame,
        settings: dict[str, Any],
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
        body, encode_ms = encode(
            result, rs.format, settings.get("quality", self.config.default_jpeg_quality), self.config.png_compress_level
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
        )

    def render(
        self,
        scene: SessionScene,
        settings: dict[str, Any],
        *,
        session: SessionState | None = None,
        where: str = "query",
        cancel: threading.Event | None = None,
    ) -> Frame:
        """Plan, admit, trace and encode one frame (the final image). Timings in ms.

        A session's frames are one animation (key: session and scene revision), so ``bvh``
        and ``twolevel`` can refit the tree of its previous frame. A stateless render has
        no previous frame: it always rebuilds.
        """
        return self.frames(scene, settings, session=session, where=where, cancel=cancel, progressive=False)[-1]

    def frames(
        self,
        scene: SessionScene,
        settings: dict[str, Any],
        *,
        session: SessionState | None = None,
        where: str = "query",
        cancel: threading.Event | None = None,
        progressive: bool = True,
        commit=None,
    ) -> list[Frame]:
        """The frame's images in order — the preview (a supersampled frame's pixel-centre
        pass) when ``progressive`` and there is one, then the final image — as an iterator
        (:meth:`iter_frames`) collected here. ``commit(result)`` runs when the final image is
        ready and returns the session version to report."""
        return list(
            self.iter_frames(
                scene, settings, session=session, where=where, cancel=cancel, progressive=progressive, commit=commit
            )
        )

    def iter_frames(
        self,
        scene: SessionScene,
        settings: dict[str, Any],
        *,
        session: SessionState | None = None,
        where: str = "query",
        cancel: threading.Event | None = None,
        progressive: bool = True,
        commit=None,
    ):
        t_admit = time.perf_counter()
        key = (session.id, session.scene_rev) if session is not None else None
        frame = self.plan(scene, settings, where, key=key)
        self.check_traceable(frame, where)
        with self.frame_memory(frame.settings):  # from before its target exists to its encoded body
            t_queued = time.perf_counter()
            handle = self.start_frame(frame, session=session)
            version = session.version if session is not None else None
            first = None
            try:
                if progressive:
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
            if commit is not None:
                version = commit(result)
            if session is not None and result.stats:
                rs = frame.settings
                self._remember_stats(
                    StatsKey(
                        session.id,
                        session.scene_rev,
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
            result = handle = first = None  # the arrays go now, not when the generator does
        yield last

    def session_frame(
        self,
        session_id: str,
        patch: dict[str, Any],
        *,
        cancel: threading.Event | None = None,
        progressive: bool = False,
    ) -> Frame | list[Frame]:
        """The session's current view (the final image; with ``progressive`` every image)."""
        state = self.get(session_id)
        settings = self.frame_settings(state, patch)
        out = self.frames(self.scene(state), settings, session=state, cancel=cancel, progressive=progressive)
        return out if progressive else out[-1]

    def iter_session_frame(self, session_id: str, patch: dict[str, Any], *, cancel: threading.Event | None = None):
        state = self.get(session_id)
        settings = self.frame_settings(state, patch)
        return self.iter_frames(self.scene(state), settings, session=state, cancel=cancel)

    def iter_gesture_frame(
        self,
        session_id: str,
        gesture,
        patch: dict[str, Any],
        *,
        cancel: threading.Event | None = None,
        progressive: bool = True,
    ):
        """A gesture answered with its new frame: rendered with the new camera first, the
        gesture committed when the final image is ready (and only if the session is still
        the version it was computed from; else 409 and nothing changes)."""
        state = self.get(session_id)
        settings = self.frame_settings(state, patch)  # 422 before anything else
        camera = self.moved_camera(state, gesture, patch)  # 422 for a move out of range
        view = self.scene(state)
        view = view if view.camera == camera else view.with_camera(camera)
        moved = replace(state, camera=camera.to_json())

        def commit(_result) -> int:
            def mutate(old: SessionState) -> SessionState:
                if old.version != state.version:
                    raise Superseded(
                        f"session: changed while the frame was traced (version {state.version} → "
                        f"{old.version}); the gesture was not applied — send it again"
                    )
                return replace(old, camera=moved.camera)

            return self._update(session_id, mutate).version

        return self.iter_frames(view, settings, session=state, cancel=cancel, progressive=progressive, commit=commit)

    def gesture_frame(
        self, session_id: str, gesture, patch: dict[str, Any], *, cancel: threading.Event | None = None
    ) -> Frame:
        """One round trip: the gesture's frame, and the gesture committed with it."""
        return list(self.iter_gesture_frame(session_id, gesture, patch, cancel=cancel, progressive=False))[-1]

    def render_stateless(
        self, scene_model: SceneModel, patch: dict[str, Any], *, cancel: threading.Event | None = None
    ) -> Frame:
        scene = self.checked_scene(scene_model, ("body", "scene"))  # its body was bounded by the body parsers
        settings = self.merge_settings(self.default_settings(), patch, "body")
        self.check_work(settings, scene.n_spheres, "body")
        return self.render(scene, settings, where="body", cancel=cancel)

    @staticmethod
    def _pose_time(scene: SessionScene, t: float) -> float:
        return float(t) if isinstance(scene, AnimatedScene) else 0.0

    @staticmethod
    def posed(scene: SessionScene, settings: dict[str, Any]) -> tuple[Scene, TreeUpdate]:
        """The scene posed at the settings' ``time`` and a rebuild request that knows which
        spheres move (for a method's ``prepare`` outside a render: stats, device data)."""
        if not isinstance(scene, AnimatedScene):
            return scene, TreeUpdate()
        frame = pose(scene, settings.get("time", 0.0))
        return frame.scene, TreeUpdate(moving=frame.moving)

    # ---- statistics -----------------------------------------------------------------------
    def _remember_stats(self, key: StatsKey, stats: dict) -> None:
        with self._stats_lock:
            self._stats[key] = stats
            self._stats.move_to_end(key)
            while len(self._stats) > 256:
                self._stats.popitem(last=False)

    def stats(self, session_id: str, patch: dict[str, Any]) -> dict:
        """Statistics of the acceleration structure for the session's current (or given)
        settings: the last build's, or a build made now (without rendering)."""
        state = self.get(session_id)
        settings = self.merge_settings(state.settings, patch, "query")
        method_name = resolve_method(
            settings["method"], state.scene_info.get("n_spheres", 0) + state.scene_info.get("n_triangles", 0)
        )  # auto as prepare_frame does
        scene = self.scene(state)
        key = StatsKey(
            state.id,
            state.scene_rev,
            method_name,
            settings["max_prims"],
            settings["max_tree_depth"],
            self._pose_time(scene, settings.get("time", 0.0)),
        )
        with self._stats_lock:
            cached = self._stats.get(key)
        if cached is not None:
            return cached
        method = METHODS[method_name]

        def job(renderer):
            posed, update = self.posed(scene, settings)
            return method.prepare(
                posed, settings["max_prims"], settings["max_tree_depth"], renderer.max_texture_width, update
            ).stats

        with self.admit() as ticket:
            try:
                stats = ticket.run(job, self.config.render_timeout_s)
            except FutureTimeout:
                raise RenderTimeout(f"build: not done within {self.config.render_timeout_s:g} s") from None
        self._remember_stats(key, stats)
        return stats


__all__ = ["SessionService", "NotFound", "InputError", "RenderTimeout", "QueueFull", "Busy", "field_path"]

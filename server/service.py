"""Session operations: validate fully, then change the Model in one atomic write.

Every operation first checks its whole input (pydantic did the per-field part;
here the renderer's own validation and the work caps of
:class:`server.config.ServerConfig`), then hands one ``mutate`` function to the
store, which applies it in a single transaction and bumps the version. A
rejected request therefore changes nothing. Renders go through the GL worker's
bounded queue; a frame that follows a gesture takes its queue slot *before*
the gesture is applied, so a full queue (503) leaves the camera where it was.
"""

from __future__ import annotations

import re
import secrets
import threading
import time
from collections import OrderedDict
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import replace
from typing import Any, Iterable, NamedTuple

from renderer.animation import MUSEUM_ROOM_SPHERES, AnimatedScene, museum, pose
from renderer.methods import METHODS, capabilities, resolve_method
from renderer.scenarios import scenario
from renderer.scene import Camera, Scene, SceneError
from renderer.settings import RenderSettings
from renderer.tree_update import TreeUpdate

from . import controller, metrics
from .config import ServerConfig
from .gl_worker import GLWorker, QueueFull, Ticket
from .models import (PanGesture, PinchGesture, ResetGesture, SceneModel, SessionCreate, SettingsPatch)
from .scenes import (SceneCache, SessionScene, camera_from_model, load_source, museum_source, scenario_source,
                     scene_from_model, scene_info, scene_source)
from .store import SessionState, SessionStore
from .view import MEDIA_TYPES, Frame, encode

_PATH_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def field_path(field: str) -> list[str | int]:
    """``"scene.spheres[3].radius"`` → ``["scene", "spheres", 3, "radius"]``."""
    return [int(i) if i else name for name, i in _PATH_TOKEN.findall(field)]


class InputError(SceneError):
    """A rejected input: ``loc`` as FastAPI's errors (``("query", "width")``)."""

    def __init__(self, loc: Iterable[str | int], message: str):
        loc = tuple(loc)
        field = ".".join(str(x) for x in loc[1:]) if loc and loc[0] in ("body", "query", "path") else \
            ".".join(str(x) for x in loc)
        super().__init__(field or "body", message)
        self.loc = loc


def relocate(e: SceneError, where: str) -> InputError:
    """A SceneError from the renderer, placed in the request (``where``: body | query)."""
    if isinstance(e, InputError):
        return e
    return InputError((where, *field_path(e.field)), e.message)


class NotFound(Exception):
    """No such session (never existed, deleted, or expired)."""


class RenderTimeout(Exception):
    """An admitted render did not finish within ``render_timeout_s``."""


class StatsKey(NamedTuple):
    """What a build's statistics depend on: the geometry (session, scene revision) and the build."""
    session: str
    rev: str
    method: str
    max_prims: int
    max_tree_depth: int
    time: float          # an animated scene's pose (0 for a static one)


class SessionService:
    """The Model's operations plus the renders of the View, for one process."""

    SETTING_KEYS = ("width", "height", "method", "mode", "max_prims", "max_tree_depth",
                    "max_recursion_depth", "format", "samples_per_pixel", "min_weight", "specialize", "tile_size",
                    "time", "update", "update_threshold")

    @classmethod
    def render_settings(cls, settings: dict[str, Any]) -> RenderSettings:
        """RenderSettings of a stored settings dict (keys a session predates take their defaults)."""
        return RenderSettings(**{k: settings[k] for k in cls.SETTING_KEYS if k in settings})

    def __init__(self, config: ServerConfig, store: SessionStore, worker: GLWorker,
                 cache: SceneCache | None = None):
        self.config = config
        self.store = store
        self.worker = worker
        self.cache = cache or SceneCache()
        self._stats: OrderedDict[StatsKey, dict] = OrderedDict()
        self._stats_lock = threading.Lock()

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
        """The per-request caps (POCKETRAY_MAX_WORK, POCKETRAY_MAX_BRUTEFORCE_WORK)."""
        w, h, d = settings["width"], settings["height"], settings["max_recursion_depth"]
        spp = settings.get("samples_per_pixel", 1)
        work = w * h * d * spp
        if work > self.config.max_work:
            raise InputError((where, "width"),
                             f"width × height × max_recursion_depth × samples_per_pixel = {w} × {h} × {d} × {spp} "
                             f"= {work} exceeds the limit {self.config.max_work} (POCKETRAY_MAX_WORK); lower width, "
                             f"height, max_recursion_depth or samples_per_pixel")
        method = resolve_method(settings["method"], n_spheres)
        if capabilities(method).tests_every_sphere:  # no hierarchy: the cost grows with pixels × spheres
            bf = work * max(1, n_spheres)
            if bf > self.config.max_bruteforce_work:
                raise InputError((where, "method"),
                                 f"method={method} tests every sphere: width × height × max_recursion_depth × "
                                 f"spheres = {bf} exceeds the limit {self.config.max_bruteforce_work} "
                                 f"(POCKETRAY_MAX_BRUTEFORCE_WORK); use method=bih or a smaller image")
        try:
            self.render_settings(settings).check_method(n_spheres)  # the modes the method can draw
        except SceneError as e:
            raise relocate(e, where) from None

    def check_spheres(self, n: int, loc: tuple[str | int, ...]) -> None:
        if n > self.config.max_spheres:
            raise InputError(loc, f"at most {self.config.max_spheres} spheres per scene "
                                  f"(POCKETRAY_MAX_SPHERES), got {n}")

    def checked_scene(self, model: SceneModel, loc: tuple[str, ...]) -> SessionScene:
        self.check_spheres(len(model.spheres), (*loc, "spheres"))
        try:
            return scene_from_model(model, ".".join(loc[1:]) if len(loc) > 1 else "")
        except SceneError as e:
            raise relocate(e, loc[0]) from None

    # ---- sessions (the Model) -----------------------------------------------------------
    def create(self, body: SessionCreate) -> SessionState:
        recipe_given = [k for k in ("scenario", "n", "seed", "radius") if getattr(body, k) is not None]
        sources = [k for k, given in (("scenario", bool(recipe_given)), ("museum", body.museum is not None),
                                      ("scene", body.scene is not None)) if given]
        if len(sources) > 1:
            where = recipe_given[0] if recipe_given else sources[1]
            raise InputError(("body", where), "give one of a scenario (scenario, n, seed, radius), a museum "
                                              f"or a scene, not {' and '.join(sources)}")
        if body.museum is not None:
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
            recipe = {"scenario": body.scenario, "n": body.n, "seed": body.seed or 0,
                      "radius": float(body.radius if body.radius is not None else 1.0)}
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
        camera = scene.camera.to_json()
        state = SessionState(id=secrets.token_urlsafe(24), version=1, camera=camera, home_camera=camera,
                             settings=settings, scene_info=scene_info(scene, recipe),
                             scene_rev=secrets.token_hex(8))
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
            base = load_source(source, camera)
            self.cache.put((state.id, rev), base)
        return base if base.camera == camera else base.with_camera(camera)

    def replace_scene(self, session_id: str, model: SceneModel) -> SessionState:
        scene = self.checked_scene(model, ("body",))
        source = scene_source(scene)
        rev = secrets.token_hex(8)
        camera = scene.camera.to_json()

        def mutate(old: SessionState) -> SessionState:
            return replace(old, camera=camera, home_camera=camera, scene_rev=rev,
                           scene_info=scene_info(scene, None))
        state = self._update(session_id, mutate, source)
        self.cache.put((state.id, rev), scene)
        return state

    def set_camera(self, session_id: str, model) -> SessionState:
        try:
            camera = camera_from_model(model)
        except SceneError as e:
            raise relocate(e, "body") from None
        return self._update(session_id, lambda old: replace(old, camera=camera.to_json()))

    def patch_settings(self, session_id: str, patch: SettingsPatch) -> SessionState:
        given = patch.given()

        def mutate(old: SessionState) -> SessionState:
            merged = self.merge_settings(old.settings, given, "body")
            self.check_work(merged, old.scene_info.get("n_spheres", 0), "body")
            return replace(old, settings=merged)
        return self._update(session_id, mutate)

    def gesture(self, session_id: str, gesture: PanGesture | PinchGesture | ResetGesture,
                frame_patch: dict[str, Any] | None = None) -> SessionState:
        """Apply a gesture; with ``frame_patch`` its settings are checked first (nothing
        changes when the frame that should follow could not be rendered)."""
        def mutate(old: SessionState) -> SessionState:
            if frame_patch is not None:
                merged = self.merge_settings(old.settings, frame_patch, "query")
                self.check_work(merged, old.scene_info.get("n_spheres", 0), "query")
            cam = Camera.from_json(old.camera)
            try:
                if isinstance(gesture, PanGesture):
                    height = gesture.viewport_height or (frame_patch or {}).get("height") or old.settings["height"]
                    new = controller.pan(cam, gesture.dx, gesture.dy, float(height))
                elif isinstance(gesture, PinchGesture):
                    new = controller.pinch(cam, gesture.scale, self.config.min_target_distance)
                else:
                    new = controller.reset(Camera.from_json(old.home_camera))
            except SceneError as e:
                field = {"pan": "dx", "pinch": "scale", "reset": "type"}[gesture.type]
                raise InputError(("body", field), f"the {gesture.type} would move the camera out of range "
                                                  f"({e.field}: {e.message})") from None
            return replace(old, camera=new.to_json())
        return self._update(session_id, mutate)

    # ---- renders (the View) -------------------------------------------------------------
    def admit(self) -> Ticket:
        """A slot in the GL queue (QueueFull → 503)."""
        return self.worker.admit()

    def frame_settings(self, state: SessionState, patch: dict[str, Any]) -> dict[str, Any]:
        merged = self.merge_settings(state.settings, patch, "query")
        self.check_work(merged, state.scene_info.get("n_spheres", 0), "query")
        return merged

    def render(self, ticket: Ticket, scene: SessionScene, settings: dict[str, Any], *,
               session: SessionState | None = None) -> Frame:
        """Render on the GL thread (with ``ticket``), encode here. Timings in ms.

        A session's frames are one animation (key: session and scene revision), so ``bvh``
        and ``twolevel`` can refit the tree of its previous frame. A stateless render has
        no previous frame: it always rebuilds.
        """
        rs = self.render_settings(settings)
        key = (session.id, session.scene_rev) if session is not None else None
        if session is None:
            rs = rs.with_(update="rebuild")
        t_admit = time.perf_counter()
        started: list[float] = []

        def job(renderer):
            started.append(time.perf_counter())
            return renderer.render(scene, rs, key=key)
        try:
            result = ticket.run(job, self.config.render_timeout_s)
        except FutureTimeout:
            raise RenderTimeout(f"render: not done within {self.config.render_timeout_s:g} s") from None
        method = result.stats.get("method") if result.stats else resolve_method(rs.method, scene.n_spheres)
        body, encode_ms = encode(result, rs.format, settings.get("quality", self.config.default_jpeg_quality),
                                 self.config.png_compress_level)
        t_end = time.perf_counter()
        timings = {"queue": ((started[0] if started else t_admit) - t_admit) * 1e3,
                   **{k: float(v) for k, v in result.timings.items()
                      if k in ("pose", "update", "build", "upload", "trace", "read")},
                   "encode": encode_ms, "total": (t_end - t_admit) * 1e3}
        metrics.observe_stages(method, rs.mode, timings)
        if session is not None and result.stats:
            self._remember_stats(StatsKey(session.id, session.scene_rev, method, rs.max_prims,
                                          rs.max_tree_depth, self._pose_time(scene, rs.time)), result.stats)
        return Frame(body=body, media_type=MEDIA_TYPES[rs.format], method=method, timings=timings,
                     stats=result.stats, version=session.version if session else None,
                     width=rs.width, height=rs.height)

    def session_frame(self, session_id: str, patch: dict[str, Any]) -> Frame:
        state = self.get(session_id)
        settings = self.frame_settings(state, patch)
        with self.admit() as ticket:
            return self.render(ticket, self.scene(state), settings, session=state)

    def gesture_frame(self, session_id: str, gesture, patch: dict[str, Any]) -> Frame:
        """One round trip: take a queue slot, apply the gesture, render the new view."""
        state = self.get(session_id)
        self.frame_settings(state, patch)  # 422 before anything else
        with self.admit() as ticket:      # 503 before anything changes
            state = self.gesture(session_id, gesture, frame_patch=patch)
            settings = self.frame_settings(state, patch)
            return self.render(ticket, self.scene(state), settings, session=state)

    def render_stateless(self, scene_model: SceneModel, patch: dict[str, Any]) -> Frame:
        scene = self.checked_scene(scene_model, ("body", "scene"))
        settings = self.merge_settings(self.default_settings(), patch, "body")
        self.check_work(settings, scene.n_spheres, "body")
        with self.admit() as ticket:
            return self.render(ticket, scene, settings)

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
        method_name = resolve_method(settings["method"], state.scene_info.get("n_spheres", 0))
        scene = self.scene(state)
        key = StatsKey(state.id, state.scene_rev, method_name, settings["max_prims"], settings["max_tree_depth"],
                       self._pose_time(scene, settings.get("time", 0.0)))
        with self._stats_lock:
            cached = self._stats.get(key)
        if cached is not None:
            return cached
        method = METHODS[method_name]

        def job(renderer):
            posed, update = self.posed(scene, settings)
            return method.prepare(posed, settings["max_prims"], settings["max_tree_depth"],
                                  renderer.max_texture_width, update).stats
        with self.admit() as ticket:
            try:
                stats = ticket.run(job, self.config.render_timeout_s)
            except FutureTimeout:
                raise RenderTimeout(f"build: not done within {self.config.render_timeout_s:g} s") from None
        self._remember_stats(key, stats)
        return stats


__all__ = ["SessionService", "NotFound", "InputError", "RenderTimeout", "QueueFull", "field_path"]

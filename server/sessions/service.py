"""Session operations: validate fully, then change the Model in one atomic write; and the frames
sessions ask for, as requests to the frame pipeline.

Every operation first checks its whole input (pydantic did the per-field part; here the input
caps, :class:`server.sessions.caps.InputCaps`, and the frame's cost through the pipeline's plan),
then hands one ``mutate`` function to the store, which applies it in a single transaction and bumps
the version. A rejected request therefore changes nothing. A refused input names its field
relative to the part of the request the route names (``("scene", "spheres")``; the route places it in
the body or the query, :func:`server.api.errors.located`); one whose part the route cannot know (a
gesture's field, a model upload's query) is named with its part (:class:`server.faults.Where`).

A frame is one :class:`server.frames.pipeline.FrameRequest` made here (the session's scene and
settings, the frame query's patch merged and checked) and run by
:meth:`server.frames.pipeline.FramePipeline.run`. A gesture's frame is rendered with its new camera
*before* the gesture is committed, and committed only when the frame is ready and the session has not
changed meanwhile: a refused, failed, timed-out or cancelled frame leaves the session as it was
(docs/API.md, "Gestures with a frame").
"""

from __future__ import annotations

import dataclasses
import secrets
import threading
from dataclasses import dataclass, replace
from typing import Any, cast

from renderer.config.settings import SettingValues
from renderer.geometry.scene import Camera, Scene, SceneError
from renderer.io.mesh_io import fit_transform
from renderer.io.model import Model
from renderer.limits import MAX_TEXTURE_TEXELS, MAX_TEXTURES, MAX_TRIANGLES
from renderer.materials.envmap import STORED_TEXEL_BYTES, EnvironmentMap, declared_size, image_ref
from renderer.scenes.animation import MUSEUM_ROOM_SPHERES, AnimatedScene, museum
from renderer.scenes.scenarios import DEFAULT_DEMO, demo_for_recipe, framed, mesh_scene, scenario

from ..config import ServerConfig
from ..contract.scene import SceneModel
from ..contract.sessions import (
    MeshUploadQuery,
    OrbitGesture,
    PanGesture,
    PinchGesture,
    ResetGesture,
    SessionCreate,
)
from ..contract.settings import SettingsPatch
from ..faults import Busy, InputError, NotFound, Superseded, Where, input_error
from ..frames.pipeline import FrameOwner, FramePipeline, FrameRequest, FrameSettings, render_settings
from . import controller
from .caps import InputCaps
from .model_worker import load_env_image, load_model
from .scenes import (
    CLAY,
    SceneCache,
    SessionScene,
    camera_from_model,
    load_source,
    museum_source,
    placed_meshes,
    scenario_source,
    scene_info,
    scene_source,
    tree_primitives,
)
from .store import SessionState, SessionStore, StoreFull, StoreUnavailable

LINEAR_FORMATS = ("npy", "exr")  # radiance as traced: denoised only when a request asks for it


@dataclass(frozen=True)
class MeshPlaced:
    """A model added to a session: the new state, its first mesh's index and first primitive id,
    where its box's bottom centre went (world units), the sentence that says so (and what of the
    file was not read), the meshes it became and the textures it brought."""

    state: SessionState
    index: int
    first_id: int
    placed: tuple[float, float, float]
    notice: str
    n_meshes: int = 1
    n_textures: int = 0


def _framed(scene: SessionScene, aspect: float, camera: Camera | None = None) -> SessionScene:
    """``scene`` (animated or not: its rest pose) seen through a camera fitted for ``aspect``."""
    rest = scene.scene if isinstance(scene, AnimatedScene) else scene
    return scene.with_camera(framed(rest, aspect, camera).camera)


def owner(state: SessionState) -> FrameOwner:
    """The session as its frames know it."""
    return FrameOwner(state.id, state.scene_rev, state.version)


class SessionService:
    """The Model's operations for one process, and the frame requests of its sessions."""

    def __init__(
        self, config: ServerConfig, store: SessionStore, frames: FramePipeline, cache: SceneCache | None = None
    ):
        self.config = config
        self.store = store
        self.frames = frames
        self.cache = cache or SceneCache(config.scene_cache_bytes)
        self.caps = InputCaps(config)
        # The refinement streams' ranges shared with the other processes: a
        # server.sessions.shared_refine.SharedRefine (redis backend; server.app sets it), typed loosely
        # because that module builds on this one.
        self.shared_refine: Any = None

    def default_settings(self) -> SettingValues:
        return self.config.default_settings()

    # ---- sessions (the Model) -----------------------------------------------------------
    def create(self, body: SessionCreate) -> SessionState:
        """A new session; its scene is made (a recipe's too) and its first frame planned in one
        planning slot."""
        with self.frames.planning():
            return self._create(body)

    def _create(self, body: SessionCreate) -> SessionState:
        named = ("scenario", "n", "seed", "radius", "sky", "museum", "mesh_scene", "scene")
        if all(getattr(body, k) is None for k in named):  # no scene named: the default demo scene
            body = SessionCreate.model_validate({**DEFAULT_DEMO.recipe, **body.model_dump(exclude_none=True)})
        recipe_given = [k for k in ("scenario", "n", "seed", "radius", "sky") if getattr(body, k) is not None]
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
            field = recipe_given[0] if recipe_given else sources[1]
            raise InputError(
                (field,),
                "give one of a scenario (scenario, n, seed, radius), a museum, "
                f"a mesh_scene or a scene, not {' and '.join(sources)}",
            )
        scene: Scene | AnimatedScene
        recipe: dict[str, Any] | None
        if body.mesh_scene is not None:
            r = body.mesh_scene
            scene = mesh_scene(r.kind, r.detail, r.smooth, r.sky)
            self.caps.check_spheres(scene.n_spheres, ("mesh_scene", "kind"))
            if scene.n_triangles > self.config.max_triangles:
                raise InputError(
                    ("mesh_scene", "detail"),
                    f"{scene.n_triangles} triangles; at most {self.config.max_triangles} allowed "
                    "(POCKETRAY_MAX_TRIANGLES)",
                )
            recipe = {"mesh_scene": r.model_dump()}
            source = scene_source(scene)
        elif body.museum is not None:
            m = body.museum
            self.caps.check_spheres(m.n + MUSEUM_ROOM_SPHERES, ("museum", "n"))
            scene = museum(m.n, m.kind, m.seed, m.absent)
            recipe = {"museum": m.model_dump()}
            source = museum_source(m.n, m.kind, m.seed, m.absent)
        elif body.scene is None:
            if body.scenario is None:
                raise InputError(("scenario",), "required: a scenario 1, 2 or 3 with n, or a full scene")
            if body.n is None:
                raise InputError(("n",), "required with scenario: the number of spheres")
            self.caps.check_spheres(body.n, ("n",))
            recipe = {
                "scenario": body.scenario,
                "n": body.n,
                "seed": body.seed or 0,
                "radius": float(body.radius if body.radius is not None else 1.0),
            }
            if body.sky:  # (absent otherwise: the scene info stays as it was)
                recipe["sky"] = True
            try:
                scene = scenario(recipe["scenario"], recipe["n"], recipe["seed"], recipe["radius"], bool(body.sky))
            except SceneError as e:
                raise input_error(e) from None
            source = scenario_source(recipe["scenario"], recipe["n"], recipe["seed"], recipe["radius"], bool(body.sky))
        else:
            scene = self.caps.checked_scene(body.scene, ("scene",))
            self.caps.check_textures(scene, ("scene", "textures"))
            recipe = None
            source = scene_source(scene)
        demo = demo_for_recipe(
            body.scenario,
            bool(body.sky),
            body.museum is not None,
            body.mesh_scene.kind if body.mesh_scene is not None else None,
        )
        # the demo scene's recommended settings, under the body's own
        recommended = cast(SettingValues, demo.settings if demo else {})  # names of SETTINGS (test_scenarios)
        patch: SettingValues = {**recommended, **(body.settings.given() if body.settings else {})}
        settings = self.caps.merge_settings(self.default_settings(), patch)
        rs = render_settings(settings)
        self.caps.check_work(rs, scene.n_tree_primitives)
        # A session no frame could render is refused now (the sphere count named where it was asked for).
        n_field = (
            ("museum", "n")
            if body.museum is not None
            else ("mesh_scene", "detail")
            if body.mesh_scene is not None
            else ("n",)
            if recipe
            else None
        )
        if body.aspect is not None and recipe:  # a full scene's camera is its author's
            scene = _framed(scene, body.aspect)
        self.frames.plan(scene, rs, n_field=n_field)
        camera = scene.camera.to_json()
        state = SessionState(
            id=secrets.token_urlsafe(24),
            version=1,
            camera=camera,
            home_camera=camera,
            settings=settings,
            scene_info=scene_info(scene, recipe),
            scene_rev=secrets.token_hex(8),
            aspect=body.aspect if recipe else None,  # (a full scene's camera stays its author's, on reset too)
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
        self.frames.accumulations.drop_session(session_id)

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
        # An environment image the session holds may be named by its reference (GET …/scene gives it).
        old = self.scene(self.get(session_id))
        held = (old.scene if isinstance(old, AnimatedScene) else old).environment_map
        images = {held.ref: held.texels} if held is not None else None
        scene = self.caps.checked_scene(model, (), images)
        self.caps.check_textures(scene, ("textures",))
        source = scene_source(scene)
        rev = secrets.token_hex(8)
        camera = scene.camera.to_json()

        def mutate(old: SessionState) -> SessionState:
            return replace(
                old, camera=camera, home_camera=camera, scene_rev=rev, scene_info=scene_info(scene, None), aspect=None
            )

        state = self._update(session_id, mutate, source)
        self.cache.put((state.id, rev), scene)
        return state

    def add_mesh(self, session_id: str, data: bytes, query: MeshUploadQuery) -> MeshPlaced:
        """Parse a model file (in memory: nothing is written) and add it to the session's scene
        as a new mesh, its last, standing on free floor beside the scene's objects (its box
        overlaps none of theirs), in a clay material of its own unless ``query.material`` names
        one; the camera is framed again to show it and the scene (for the session's aspect, else
        its settings' width / height). 422 naming ``body`` (the file), ``query.format``,
        ``query.material``, or the triangle cap (POCKETRAY_MAX_TRIANGLES, with the scene's own)."""
        state = self.get(session_id)
        old = self.scene(state)
        rest = old.scene if isinstance(old, AnimatedScene) else old
        room = self.config.max_triangles - rest.n_triangles
        if room <= 0 or not data:
            raise InputError(
                (Where.BODY,),
                "the scene already holds the most triangles allowed "
                f"({self.config.max_triangles}, POCKETRAY_MAX_TRIANGLES)"
                if data
                else "empty body: send the model file's bytes",
            )
        try:
            parsed = load_model(self.config, data, query.format, max_triangles=min(room, MAX_TRIANGLES), busy=Busy)
        except SceneError as e:
            loc = (Where.QUERY, "format") if e.field == "format" else (Where.BODY,)
            raise InputError(
                loc,
                f"{e.message}"
                + (
                    f" (POCKETRAY_MAX_TRIANGLES = {self.config.max_triangles}, {rest.n_triangles} in the scene)"
                    if "triangles" in e.message
                    else ""
                ),
            ) from None
        materials, textures = rest.materials, rest.textures
        if query.material is not None and query.material >= len(materials):
            raise InputError(
                (Where.QUERY, "material"),
                f"material index {query.material} out of range (the scene has {len(materials)} materials)",
            )
        material = query.material
        if material is not None:  # the material named takes every part: the model's own are not added
            parsed = dataclasses.replace(
                parsed,
                parts=tuple(dataclasses.replace(p, material=-1) for p in parsed.parts),
                materials=(),
                textures=(),
            )
        # the parts without a material of their own take the clay, added once: later models share it
        if material is None and any(p.material < 0 for p in parsed.parts):
            if CLAY not in materials:
                if len(materials) >= Scene.MAX_MATERIALS:
                    raise InputError(
                        (Where.QUERY, "material"),
                        f"the scene holds {len(materials)} materials, the most allowed: name one of them (0 … "
                        f"{len(materials) - 1}) for the model",
                    )
                materials = (*materials, CLAY)
            material = materials.index(CLAY)
        self._check_model_room(session_id, parsed, materials, textures)
        try:
            fit = fit_transform(parsed, query.size) if query.size else None
            meshes, own = parsed.placed(
                -1 if material is None else material,
                len(materials),
                len(textures),
                fit,
                query.smooth,
                max_meshes=max(1, Scene.MAX_MESHES - len(rest.meshes)),
            )
            meshes, spot = placed_meshes(rest, meshes)
            grown = Scene(
                rest.camera,
                rest.lights,
                (*materials, *own),
                rest.sphere_centers,
                rest.sphere_radii,
                rest.sphere_materials,
                rest.planes,
                (*rest.meshes, *meshes),
                rest.environment,
                rest.environment_map,
                rest.shapes,
                (*textures, *parsed.textures),
            )
            aspect = state.aspect or state.settings["width"] / state.settings["height"]
            grown = framed(grown, aspect)
            scene: SessionScene = AnimatedScene(grown, old.motions) if isinstance(old, AnimatedScene) else grown
        except SceneError as e:
            raise InputError((Where.BODY,), f"the model does not fit the scene: {e.field}: {e.message}") from None
        unique = state.scene_info.get("n_unique_triangles", rest.n_triangles) + parsed.n_unique_triangles
        # no recipe any more: a scenario with a model in it is a scene of its own; the model's meshes,
        # materials and textures are written with it in one change, or not at all
        new = self._replace_scene(state, scene, "the model", camera=grown.camera.to_json(), unique_triangles=unique)
        index = len(rest.meshes)
        x, y, z = (round(float(v), 1) for v in spot)
        said = [f"placed at x {x:g}, z {z:g} beside the scene, standing on y {y:g}; the camera shows it"]
        if len(meshes) > 1 or own or parsed.textures:
            said.append(
                f"{len(meshes)} mesh(es), {len(own)} material(s) and {len(parsed.textures)} texture(s) of the file"
            )
        said.extend(parsed.notices)  # (each reader keeps them within MAX_MODEL_NOTICES)
        return MeshPlaced(
            new,
            index,
            grown.triangle_id_base + grown.mesh_triangle_range(index).start,
            (x, y, z),
            "; ".join(said),
            len(meshes),
            len(parsed.textures),
        )

    def _check_model_room(self, session_id: str, model: Model, materials: tuple, textures: tuple) -> None:
        """422 (body) when the model's materials or textures do not fit the scene's bounds beside
        the scene's own; 507 (StoreFull) when its textures do not fit the store's quota."""
        if len(materials) + len(model.materials) > Scene.MAX_MATERIALS:
            raise InputError(
                (Where.BODY,),
                f"the model has {len(model.materials)} materials and the scene {len(materials)}; at most "
                f"{Scene.MAX_MATERIALS} together (MAX_MATERIALS)",
            )
        if len(textures) + len(model.textures) > MAX_TEXTURES:
            raise InputError(
                (Where.BODY,),
                f"the model has {len(model.textures)} textures and the scene {len(textures)}; at most "
                f"{MAX_TEXTURES} together (MAX_TEXTURES)",
            )
        texels = sum(t.width * t.height for t in (*textures, *model.textures))
        if texels > MAX_TEXTURE_TEXELS:
            raise InputError(
                (Where.BODY,),
                f"the model's textures and the scene's hold {texels:,} texels; at most {MAX_TEXTURE_TEXELS:,} "
                "together (MAX_TEXTURE_TEXELS)",
            )
        # the store keeps the texels as they are: refused now, before the scene is written
        wanted, room = model.texture_bytes, self.store.room(session_id)
        if room is not None and wanted > room:
            raise StoreFull(self.config.max_store_bytes - room, wanted, self.config.max_store_bytes)

    def set_environment(
        self, session_id: str, data: bytes, fmt: str, scale: float, rotation_deg: float
    ) -> tuple[SessionState, EnvironmentMap]:
        """An equirectangular HDR image (the file's bytes, ``hdr`` or ``exr``) as the session's
        environment, stored beside its scene (the store's quota counts it); the camera stays. 422
        naming ``body`` (the file) or ``query.format``; nothing is written when the file is refused."""
        state = self.get(session_id)
        try:
            width, height = declared_size(data, fmt)
            # the store keeps the texels as they are: an image the quota cannot hold is refused now,
            # by its header, not after it was decoded
            wanted, room = STORED_TEXEL_BYTES * width * height, self.store.room(session_id)
            if room is not None and wanted > room:
                raise StoreFull(self.config.max_store_bytes - room, wanted, self.config.max_store_bytes)
            texels = load_env_image(self.config, data, fmt, busy=Busy)
            env = EnvironmentMap(image_ref(texels), texels, scale, rotation_deg)
        except SceneError as e:
            raise InputError((Where.QUERY, "format") if e.field == "format" else (Where.BODY,), e.message) from None
        return self._with_environment(state, env), env

    def clear_environment(self, session_id: str) -> SessionState:
        """The session's environment back to a colour: black."""
        return self._with_environment(self.get(session_id), None)

    def _with_environment(self, state: SessionState, env: EnvironmentMap | None) -> SessionState:
        old = self.scene(state)
        rest = old.scene if isinstance(old, AnimatedScene) else old
        lit = Scene(
            rest.camera,
            rest.lights,
            rest.materials,
            rest.sphere_centers,
            rest.sphere_radii,
            rest.sphere_materials,
            rest.planes,
            rest.meshes,
            (0.0, 0.0, 0.0),
            env,
            rest.shapes,
            rest.textures,
        )
        scene: SessionScene = AnimatedScene(lit, old.motions) if isinstance(old, AnimatedScene) else lit
        # no recipe any more: a scenario under another environment is a scene of its own
        return self._replace_scene(state, scene, "the image")

    def _replace_scene(
        self,
        state: SessionState,
        scene: SessionScene,
        read: str,
        camera: dict[str, Any] | None = None,
        unique_triangles: int | None = None,
    ) -> SessionState:
        """``scene`` (made from ``state``'s scene and something ``read`` meanwhile: a model file, an
        image) as the session's scene, recipe-less, unless its scene changed since ``state``
        (Superseded: nothing is written); ``camera``: the session's camera with it;
        ``unique_triangles``: its triangles with each instanced mesh counted once (None: as
        ``state``'s scene had them: its meshes are the same)."""
        self.caps.check_textures(scene, ("file",))
        source = scene_source(scene)
        rev = secrets.token_hex(8)

        def mutate(current: SessionState) -> SessionState:
            if current.scene_rev != state.scene_rev:
                raise Superseded(f"session: its scene changed while {read} was read; send it again")
            info = scene_info(scene, None)
            if "n_unique_triangles" in info:
                kept = current.scene_info.get("n_unique_triangles", info["n_unique_triangles"])
                info["n_unique_triangles"] = kept if unique_triangles is None else unique_triangles
            moved = replace(current, scene_rev=rev, scene_info=info)
            return moved if camera is None else replace(moved, camera=camera)

        new = self._update(state.id, mutate, source)
        self.cache.put((new.id, rev), scene)
        return new

    def set_camera(self, session_id: str, model) -> SessionState:
        try:
            camera = camera_from_model(model)
        except SceneError as e:
            raise input_error(e) from None
        return self._update(session_id, lambda old: replace(old, camera=camera.to_json()))

    def patch_settings(self, session_id: str, patch: SettingsPatch) -> SessionState:
        """Change render defaults; settings no frame could render (over the frame cost cap
        included, which needs a build) are refused before anything changes."""
        given = patch.given()
        state = self.get(session_id)
        checked = self.caps.merge_settings(state.settings, given)
        rs = render_settings(checked)
        self.caps.check_work(rs, tree_primitives(state.scene_info))
        self.frames.plan(self.scene(state), rs)

        def mutate(old: SessionState) -> SessionState:
            merged = self.caps.merge_settings(old.settings, given)
            rs = render_settings(merged)
            self.caps.check_work(rs, tree_primitives(old.scene_info))
            if merged != checked:  # another change came between: check what is stored now
                self.frames.plan(self.scene(old), rs)
            return replace(old, settings=merged)

        return self._update(session_id, mutate)

    def moved_camera(
        self,
        old: SessionState,
        gesture: PanGesture | PinchGesture | OrbitGesture | ResetGesture,
        frame_patch: SettingValues | None = None,
    ) -> Camera:
        """The camera after ``gesture`` (InputError naming the gesture's field, in the body, when the
        move would leave the coordinate range: the frame a gesture asks for has its settings in the query)."""
        cam = Camera.from_json(old.camera)
        try:
            if isinstance(gesture, PanGesture):
                height = gesture.viewport_height or (frame_patch or {}).get("height") or old.settings["height"]
                return controller.pan(cam, gesture.dx, gesture.dy, float(height))
            if isinstance(gesture, PinchGesture):
                return controller.pinch(cam, gesture.scale, self.config.min_target_distance)
            if isinstance(gesture, OrbitGesture):
                return controller.orbit(cam, gesture.yaw, gesture.pitch)
            home = controller.reset(Camera.from_json(old.home_camera))
            aspect = gesture.aspect or old.aspect
            if aspect is None:
                return home
            scene = self.scene(old)
            return framed(scene.scene if isinstance(scene, AnimatedScene) else scene, aspect, home).camera
        except SceneError as e:
            field = {"pan": "dx", "pinch": "scale", "orbit": "yaw", "reset": "type"}[gesture.type]
            raise InputError(
                (Where.BODY, field), f"the {gesture.type} would move the camera out of range ({e.field}: {e.message})"
            ) from None

    def gesture(
        self, session_id: str, gesture: PanGesture | PinchGesture | OrbitGesture | ResetGesture
    ) -> SessionState:
        """Apply a gesture (no frame)."""
        return self._update(session_id, lambda old: replace(old, camera=self.moved_camera(old, gesture).to_json()))

    # ---- the frames a session asks for (run by the frame pipeline) --------------------------
    def frame_settings(self, state: SessionState, patch: SettingValues) -> FrameSettings:
        """The session's settings with the frame query's ``patch``, checked against the caps. The
        linear formats (npy, exr) are denoised only when the query itself names ``denoise``: the
        session's ``denoise`` is for the images it shows."""
        merged = self.caps.merge_settings(state.settings, patch)
        if merged.get("format") in LINEAR_FORMATS and "denoise" not in patch:
            merged = {**merged, "denoise": "off"}
        settings = FrameSettings.of(merged)
        self.caps.check_work(settings.render, tree_primitives(state.scene_info))
        return settings

    def frame_request(
        self,
        session_id: str,
        patch: SettingValues,
        *,
        cancel: threading.Event | None = None,
        progressive: bool = False,
        accumulate: bool = False,
        slices: int = 1,
    ) -> FrameRequest:
        """The session's current view with the query's ``patch`` (the final image; with
        ``progressive`` its preview first; with ``accumulate`` added to the session's accumulation,
        a Whitted frame by ``slices`` jittered slices of its grid)."""
        state = self.get(session_id)
        settings = self.frame_settings(state, patch)
        return FrameRequest(
            self.scene(state),
            settings,
            owner(state),
            progressive=progressive,
            cancel=cancel,
            accumulate=accumulate,
            slices=slices,
        )

    def gesture_request(
        self,
        session_id: str,
        gesture,
        patch: SettingValues,
        *,
        cancel: threading.Event | None = None,
        progressive: bool = False,
    ) -> FrameRequest:
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

        return FrameRequest(view, settings, owner(state), progressive=progressive, commit=commit, cancel=cancel)

    def stateless_request(
        self, scene_model: SceneModel, patch: SettingValues, *, cancel: threading.Event | None = None
    ) -> FrameRequest:
        """A frame of a scene sent with the request, no session (its settings are the body's)."""
        scene = self.caps.checked_scene(scene_model, ("scene",))  # its body was bounded by the body parsers
        settings = FrameSettings.of(self.caps.merge_settings(self.default_settings(), patch))
        self.caps.check_work(settings.render, scene.n_tree_primitives)
        return FrameRequest(scene, settings, None, cancel=cancel)

    def stats(self, session_id: str, patch: SettingValues) -> dict:
        """Statistics of the acceleration structure for the session's current (or given)
        settings: the last build's, or a build made now (without rendering)."""
        state = self.get(session_id)
        settings = FrameSettings.of(self.caps.merge_settings(state.settings, patch))
        return self.frames.stats(FrameRequest(self.scene(state), settings, owner(state)))

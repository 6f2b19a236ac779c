"""The input caps: the renderer's own validation of a request's settings and scene, and the work caps of
:class:`server.config.ServerConfig` that need no build (POCKETRAY_MAX_WORK, _MAX_SPHERES,
_MAX_TRIANGLES). pydantic did the per-field part; what is refused here is refused before anything
changes. (The cost of a frame, POCKETRAY_MAX_FRAME_COST, needs a build: the frame pipeline's plan.)

Every refusal is an :class:`server.faults.InputError` relative to the part of the request the route
names (``("width",)``, ``("scene", "spheres")``): the route places it in the body or the query."""

from __future__ import annotations

import numpy as np

from renderer.config.settings import RenderSettings, SettingValues
from renderer.frame.cost import path_segments, request_work
from renderer.frame.plan import plan_method
from renderer.geometry.scene import SceneError
from renderer.gpu import texture_layout
from renderer.integrators import Integrator
from renderer.scenes.animation import AnimatedScene

from ..config import ServerConfig
from ..contract.scene import SceneModel
from ..faults import InputError, input_error
from ..frames.pipeline import render_settings
from .scenes import SessionScene, scene_from_model


class InputCaps:
    """A request's settings and scene, checked against the renderer and the service's caps."""

    def __init__(self, config: ServerConfig):
        self.config = config

    def merge_settings(self, base: SettingValues, patch: SettingValues) -> SettingValues:
        """``base`` updated by ``patch``, validated by RenderSettings (InputError at the setting)."""
        merged: SettingValues = {**base, **patch}
        try:
            render_settings(merged)
        except SceneError as e:
            raise input_error(e) from None
        return merged

    def check_work(self, settings: RenderSettings, tree_primitives: int) -> str:
        """The caps that need no build: POCKETRAY_MAX_WORK (a path frame's expected segments,
        ``renderer.frame.cost.request_work``), and the modes the method can draw; the method the frames of
        ``settings`` use over a scene of ``tree_primitives`` (``auto`` resolved as every frame resolves
        it, :func:`renderer.frame.plan.plan_method`). (The cost of a frame, POCKETRAY_MAX_FRAME_COST, is
        checked by the pipeline's plan.)"""
        w, h, d, spp = settings.width, settings.height, settings.max_recursion_depth, settings.samples_per_pixel
        path = settings.integrator == Integrator.PATH
        work = request_work(w, h, d, spp, path)
        if work > self.config.max_work:
            if path:  # the expected segments of its paths (renderer/frame/cost.py, path_segments)
                raise InputError(
                    ("samples_per_pixel",),
                    f"width × height × samples_per_pixel × expected segments of a path at max_recursion_depth "
                    f"{d} = {w} × {h} × {spp} × {path_segments(d):.2f} = {work:,.0f} exceeds the limit "
                    f"{self.config.max_work} (POCKETRAY_MAX_WORK); lower samples_per_pixel, width or height",
                )
            raise InputError(
                ("width",),
                f"width × height × max_recursion_depth × samples_per_pixel = {w} × {h} × {d} × {spp} "
                f"= {work:.0f} exceeds the limit {self.config.max_work} (POCKETRAY_MAX_WORK); lower width, "
                f"height, max_recursion_depth or samples_per_pixel",
            )
        try:
            return plan_method(settings, tree_primitives)  # the modes the method can draw
        except SceneError as e:
            raise input_error(e) from None

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

    def check_textures(self, scene: SessionScene, loc: tuple[str | int, ...]) -> None:
        """POCKETRAY_MAX_SESSION_TEXTURE_BYTES: the scene's textures with their mip levels."""
        rest = scene.scene if isinstance(scene, AnimatedScene) else scene
        budget = self.config.max_session_texture_bytes
        total = sum(texture_layout.texture_bytes(t) for t in rest.textures)
        if budget and total > budget:
            raise InputError(
                loc,
                f"the scene's {len(rest.textures)} textures take {total:,} bytes with their mip levels; a session "
                f"holds at most {budget:,} (POCKETRAY_MAX_SESSION_TEXTURE_BYTES): use fewer or smaller textures",
            )

    def checked_scene(
        self, model: SceneModel, loc: tuple[str, ...], images: dict[str, np.ndarray] | None = None
    ) -> SessionScene:
        """The request's scene (at ``loc`` in its part of the request) as arrays. Its sphere models
        are released here, a chunk at a time: nothing reads them after, and the 300,000 of a 16 MiB
        body, freed at once where the request ends (on the event loop), held the GIL ~60 ms."""
        try:
            self.check_spheres(len(model.spheres), (*loc, "spheres"))
            self.check_triangles(sum(len(m.triangles) for m in model.meshes), (*loc, "meshes"))
            return scene_from_model(model, ".".join(loc), images)
        except SceneError as e:
            raise input_error(e) from None
        finally:
            if len(model.spheres) > 2048:
                for stop in range(len(model.spheres) - 2048, -2048, -2048):
                    del model.spheres[max(stop, 0) :]

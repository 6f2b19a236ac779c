"""The moderngl renderer: one frame = rebuild → upload → draw → read back.

A ``GLRenderer`` owns one OpenGL context. A context is not thread-safe: call a
renderer from the thread that created it only (the server runs all renders on
one dedicated thread).
"""

from __future__ import annotations

import time
from typing import Hashable

import moderngl
import numpy as np

from .. import gpu_layout
from ..animation import AnimatedScene, pose
from ..features import GENERIC, scene_features
from ..limits import DEFAULT_TEXTURE_WIDTH
from ..methods import METHODS, PreparedMethod, resolve_method
from ..result import RenderResult
from ..scene import Scene, SceneError
from ..settings import RenderSettings
from ..gpu_layout import PackedScene, Variant
from ..shader_source import known_bindings, tracer_bindings, tracer_source, vertex_source
from ..tree_update import TreeUpdate
from .context import GLUnavailable, create_context  # noqa: F401  (re-exported)
from .ray_engine import RayEnginePasses
from .textures import upload_textures


class GLRenderer:
    """Renders scenes with the GLSL ES 3.00 tracer. Programs are cached per variant."""

    def __init__(self, ctx: moderngl.Context | None = None,
                 max_texture_width: int = DEFAULT_TEXTURE_WIDTH):
        self.ctx = ctx or create_context()
        self.max_texture_width = min(max_texture_width, self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        self._programs: dict[tuple, moderngl.Program] = {}
        self._vaos: dict[tuple, moderngl.VertexArray] = {}
        self._fbos: dict[tuple[int, int], moderngl.Framebuffer] = {}
        quad = np.array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1], dtype=np.float32)
        self._quad = self.ctx.buffer(quad.tobytes())
        self._ray_engine: RayEnginePasses | None = None

    @property
    def ray_engine(self) -> RayEnginePasses:
        """The passes of the multi-pass methods (made on first use: their programs and targets)."""
        if self._ray_engine is None:
            self._ray_engine = RayEnginePasses(self.ctx, self.max_texture_width)
        return self._ray_engine

    @property
    def info(self) -> dict[str, str]:
        return {"renderer": self.ctx.info["GL_RENDERER"], "version": self.ctx.info["GL_VERSION"]}

    def program(self, method: str, mode: str, max_recursion_depth: int, features: tuple[str, ...] = ()
                ) -> tuple[moderngl.Program, moderngl.VertexArray]:
        """The compiled variant, cached by method × mode × recursion depth × feature set."""
        key = (method, mode, max_recursion_depth, features)
        if key not in self._programs:
            prog = self.ctx.program(vertex_shader=vertex_source(),
                                    fragment_shader=tracer_source(method, mode, max_recursion_depth, features))
            self._programs[key] = prog
            self._vaos[key] = self.ctx.vertex_array(prog, [(self._quad, "2f", "a_position")])
        return self._programs[key], self._vaos[key]

    def _framebuffer(self, width: int, height: int) -> moderngl.Framebuffer:
        key = (width, height)
        if key not in self._fbos:
            if len(self._fbos) > 8:  # bound the cache: release the oldest size
                old = self._fbos.pop(next(iter(self._fbos)))
                for att in old.color_attachments:
                    att.release()
                old.release()
            attachments = [self.ctx.texture((width, height), 4, dtype="f4") for _ in range(2)]
            self._fbos[key] = self.ctx.framebuffer(color_attachments=attachments)
        return self._fbos[key]

    def _bind(self, prog: moderngl.Program, variant: Variant, parts: list[PackedScene],
              textures: list[moderngl.Texture]) -> None:
        """Upload and bind exactly the textures and uniforms the variant declares.

        Every packed name must be a binding some layout declares (KeyError otherwise: a
        misspelt name is an error, never skipped); those the variant does not read are not
        uploaded; a binding it reads that nothing packed is an error too. A declared binding
        the compiler found unused is not an active uniform: nothing to set (the test of the
        bindings checks that on this driver every declared one is active).
        """
        known = known_bindings()
        declared = {b.name for b in tracer_bindings(variant)}
        tex, uni = {}, {}
        for part in parts:
            for name in (*part.textures, *part.uniforms):
                if name not in known:
                    raise KeyError(f"{name!r} is packed but no layout declares it (renderer/gpu_layout.py, "
                                   f"renderer/accel/*_layout.py)")
            tex.update((n, t) for n, t in part.textures.items() if n in declared)
            uni.update((n, v) for n, v in part.uniforms.items() if n in declared)
        missing = declared - set(tex) - set(uni)
        if missing:
            raise KeyError(f"the {variant.method} shader reads {sorted(missing)} but nothing packed them")
        for name, unit in upload_textures(self.ctx, PackedScene(tex), textures).items():
            if name in prog:
                prog[name].value = unit
        for name, value in uni.items():
            if name in prog:
                prog[name].value = value

    def render(self, scene: Scene | AnimatedScene, settings: RenderSettings, *, key: Hashable | None = None,
               prepared: PreparedMethod | None = None) -> RenderResult:
        """Trace one frame. Timings in ms: build, upload, trace, read, total.

        An :class:`AnimatedScene` is first posed at ``settings.time`` (timing ``pose``);
        a method that keeps its tree between frames then follows the motion with
        ``settings.update`` from the previous frame rendered with the same ``key``
        (the animation: a session and its scene revision), and timing ``update`` is
        the time it took — for every other method the same as ``build``.
        ``prepared``: acceleration data made beforehand (``method.prepare``) to render
        with instead of preparing here (``build`` is then its time).

        ``stats`` holds the acceleration structure's statistics plus the
        concrete ``method``, the ``recursion_depth`` traced, the shader
        ``features`` removed for this scene and, when animated, the ``time``.
        """
        t_start = time.perf_counter()
        moving = None
        pose_ms = None
        if isinstance(scene, AnimatedScene):
            frame = pose(scene, settings.time)
            scene, moving, pose_ms = frame.scene, frame.moving, frame.pose_ms
        result = self._render_posed(scene, settings, TreeUpdate(settings.update, settings.update_threshold,
                                                                key, moving), prepared)
        if pose_ms is not None:
            result.timings["pose"] = pose_ms
            result.timings["total"] = (time.perf_counter() - t_start) * 1e3
            if result.stats is not None:
                result.stats["time"] = settings.time
        return result

    def _render_posed(self, scene: Scene, settings: RenderSettings, update: TreeUpdate,
                      prepared: PreparedMethod | None) -> RenderResult:
        t_start = time.perf_counter()
        method_name = resolve_method(settings.method, scene.n_spheres)
        method = METHODS[method_name]
        if method.capabilities.multi_pass:  # the ray engines draw the frame in passes of their own
            return self.ray_engine.render_frame(method, scene, settings)
        if settings.mode not in method.capabilities.modes:
            raise SceneError("mode", f"mode {settings.mode!r} is not available with method {method_name!r}")
        if prepared is None:
            prepared = method.prepare(scene, settings.max_prims, settings.max_tree_depth,
                                      self.max_texture_width, update)
        t_built = time.perf_counter()

        features = scene_features(scene) if settings.specialize else GENERIC
        depth = features.recursion_depth(settings.max_recursion_depth)
        prog, vao = self.program(method_name, settings.mode, depth, features.defines())
        variant = Variant(method_name, settings.mode, depth, features.defines())
        k = settings.supersampling
        w, h = settings.width * k, settings.height * k
        textures: list[moderngl.Texture] = []
        try:
            frame = PackedScene({}, {**gpu_layout.camera_uniforms(scene.camera, w, h),
                                     gpu_layout.MIN_WEIGHT.name: float(settings.min_weight)})
            self._bind(prog, variant, [gpu_layout.pack_primitives(scene, self.max_texture_width), prepared.packed,
                                       frame], textures)
            fbo = self._framebuffer(w, h)
            fbo.use()
            self.ctx.finish()
            t_uploaded = time.perf_counter()
            vao.render(moderngl.TRIANGLES)
            self.ctx.finish()
            t_traced = time.perf_counter()
            img = np.frombuffer(fbo.read(components=4, dtype="f4", attachment=0), np.float32).reshape(h, w, 4)[::-1]
            hit = np.frombuffer(fbo.read(components=4, dtype="f4", attachment=1), np.float32).reshape(h, w, 4)[::-1]
        finally:
            for t in textures:
                t.release()
        colour = img[..., :3]
        if k > 1:
            # Box filter over the k×k sub-pixels; ids and depth from the one nearest the centre.
            colour = colour.reshape(settings.height, k, settings.width, k, 3).mean(axis=(1, 3))
            img, hit = img[k // 2::k, k // 2::k], hit[k // 2::k, k // 2::k]
        primid = img[..., 3].astype(np.int32)
        depth_t = np.where(primid >= 0, hit[..., 3], np.float32(np.inf)).astype(np.float32)
        t_end = time.perf_counter()
        ms = lambda a, b: (b - a) * 1e3  # noqa: E731
        # "update" is the method's build or update (rebuild, refit, selective): the same time as "build".
        timings = {"build": prepared.build_ms, "update": prepared.build_ms, "upload": ms(t_built, t_uploaded),
                   "trace": ms(t_uploaded, t_traced), "read": ms(t_traced, t_end), "total": ms(t_start, t_end)}
        stats = {**prepared.stats, "method": method_name, "recursion_depth": depth,
                 "features_removed": list(features.defines()), "n_spheres": scene.n_spheres}
        return RenderResult(image=np.ascontiguousarray(colour, dtype=np.float32), depth=depth_t, primid=primid,
                            normal=np.ascontiguousarray(hit[..., :3]), mode=settings.mode,
                            timings=timings, stats=stats)

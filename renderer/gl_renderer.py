"""The moderngl renderer: one frame = rebuild → upload → draw → read back.

A ``GLRenderer`` owns one OpenGL context. A context is not thread-safe: call a
renderer from the thread that created it only (the server runs all renders on
one dedicated thread).
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Hashable

import moderngl
import numpy as np

from . import gpu_layout
from .animation import AnimatedScene, pose
from .gl_context import GLUnavailable, create_context  # noqa: F401  (re-exported)
from .features import GENERIC, scene_features
from .methods import METHODS, PreparedMethod, resolve_method
from .result import RenderResult
from .scene import Scene, SceneError
from .settings import RenderSettings
from .tree_update import TreeUpdate

# Modes raytrace.frag implements ("cones" belongs to the hierarchical ray engine).
SINGLE_PASS_MODES = ("color", "depth", "primid", "normal", "recursion", "heat")

SHADER_DIR = Path(__file__).resolve().parent.parent / "shaders"
HEADER_MARK = "//@HEADER@"
METHOD_MARK = "//@METHOD@"
INCLUDE_MARK = "//@INCLUDE "   # a line "//@INCLUDE method_bvh.glsl" in a method file inlines that file


def shader_source(method: str, mode: str, max_recursion_depth: int,
                  extra_defines: tuple[str, ...] = ()) -> str:
    """The fragment shader of one variant.

    ``raytrace.frag`` with the layout header and the variant's defines after
    ``#version`` and the method's ``method_<name>.glsl`` spliced in at
    ``//@METHOD@``. The same assembly serves moderngl and the browser (WebGL2).
    """
    src = (SHADER_DIR / "raytrace.frag").read_text()
    method_src = _with_includes((SHADER_DIR / f"method_{method}.glsl").read_text())
    defines = [f"#define METHOD_{method.upper()}", f"#define MODE_{mode.upper()}",
               f"#define MAX_RECURSION_DEPTH {int(max_recursion_depth)}", *(f"#define {d}" for d in extra_defines)]
    header = gpu_layout.glsl_header() + "\n".join(defines) + "\n"
    return src.replace(HEADER_MARK, header).replace(METHOD_MARK, method_src)


def _with_includes(text: str) -> str:
    """Inline ``//@INCLUDE file`` lines (one level: a method built from other methods)."""
    lines = []
    for line in text.splitlines(keepends=True):
        if line.startswith(INCLUDE_MARK):
            name = line[len(INCLUDE_MARK):].strip()
            lines.append(f"// ---- {name} ----\n" + (SHADER_DIR / name).read_text() + "\n")
        else:
            lines.append(line)
    return "".join(lines)


def vertex_source() -> str:
    return (SHADER_DIR / "fullscreen.vert").read_text()


def upload_textures(ctx: moderngl.Context, packed: gpu_layout.PackedScene,
                    textures: list[moderngl.Texture]) -> dict[str, int]:
    """Create the packed textures and bind them to the next free units.

    Appends them to ``textures`` (the caller releases them after the frame) and
    returns sampler name → texture unit.
    """
    units = {}
    for name, tex in packed.textures.items():
        gl_tex = ctx.texture(tex.size, tex.components, tex.data.tobytes(), dtype=tex.dtype)
        # Integer textures are incomplete with LINEAR filtering; texelFetch ignores it otherwise.
        gl_tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        unit = len(textures)
        gl_tex.use(unit)
        textures.append(gl_tex)
        units[name] = unit
    return units


class GLRenderer:
    """Renders scenes with the GLSL ES 3.00 tracer. Programs are cached per variant."""

    def __init__(self, ctx: moderngl.Context | None = None,
                 max_texture_width: int = gpu_layout.DEFAULT_TEXTURE_WIDTH):
        self.ctx = ctx or create_context()
        self.max_texture_width = min(max_texture_width, self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        self._programs: dict[tuple, moderngl.Program] = {}
        self._vaos: dict[tuple, moderngl.VertexArray] = {}
        self._fbos: dict[tuple[int, int], moderngl.Framebuffer] = {}
        quad = np.array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1], dtype=np.float32)
        self._quad = self.ctx.buffer(quad.tobytes())

    @property
    def info(self) -> dict[str, str]:
        return {"renderer": self.ctx.info["GL_RENDERER"], "version": self.ctx.info["GL_VERSION"]}

    def program(self, method: str, mode: str, max_recursion_depth: int, features: tuple[str, ...] = ()
                ) -> tuple[moderngl.Program, moderngl.VertexArray]:
        """The compiled variant, cached by method × mode × recursion depth × feature set."""
        key = (method, mode, max_recursion_depth, features)
        if key not in self._programs:
            prog = self.ctx.program(vertex_shader=vertex_source(),
                                    fragment_shader=shader_source(method, mode, max_recursion_depth, features))
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

    def _upload(self, prog: moderngl.Program, packed: gpu_layout.PackedScene, units: dict[str, int],
                textures: list[moderngl.Texture]) -> None:
        for name, unit in upload_textures(self.ctx, packed, textures).items():
            if name in prog:
                prog[name].value = unit
            units[name] = unit
        for name, value in packed.uniforms.items():
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
        if hasattr(method, "render_frame"):  # multi-pass methods draw the frame themselves
            return method.render_frame(self, scene, settings)
        if settings.mode not in SINGLE_PASS_MODES:
            raise SceneError("mode", f"mode {settings.mode!r} is not available with method {method_name!r}")
        if prepared is None:
            prepared = method.prepare(scene, settings.max_prims, settings.max_tree_depth,
                                      self.max_texture_width, update)
        t_built = time.perf_counter()

        features = scene_features(scene) if settings.specialize else GENERIC
        depth = features.recursion_depth(settings.max_recursion_depth)
        prog, vao = self.program(method_name, settings.mode, depth, features.defines())
        k = settings.supersampling
        w, h = settings.width * k, settings.height * k
        textures: list[moderngl.Texture] = []
        try:
            units: dict[str, int] = {}
            self._upload(prog, gpu_layout.pack_primitives(scene, self.max_texture_width), units, textures)
            self._upload(prog, prepared.packed, units, textures)
            self._bind_dummies(prog, units, textures)
            self._set_camera(prog, scene, w, h)
            if "u_min_weight" in prog:
                prog["u_min_weight"].value = float(settings.min_weight)
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

    def _bind_dummies(self, prog: moderngl.Program, units: dict[str, int], textures: list[moderngl.Texture]) -> None:
        """Samplers the variant declares but this method does not fill get a 1×1 texture."""
        for name in ("u_spheres", "u_sphere_mat", "u_materials"):
            if name in prog and name not in units:
                dummy = self.ctx.texture((1, 1), 1, np.zeros(1, np.uint32).tobytes(), dtype="u4")
                dummy.filter = (moderngl.NEAREST, moderngl.NEAREST)
                dummy.use(len(textures))
                prog[name].value = len(textures)
                textures.append(dummy)

    @staticmethod
    def _set_camera(prog: moderngl.Program, scene: Scene, width: int, height: int) -> None:
        cam = scene.camera
        right, up, forward = cam.basis()
        s = math.tan(math.radians(cam.fov_y) / 2.0)
        values = {
            "u_cam_pos": tuple(cam.position), "u_cam_right": tuple(right), "u_cam_up": tuple(up),
            "u_cam_forward": tuple(forward),
            "u_half_extent": (s * width / height, s),
            "u_resolution": (float(width), float(height)),
            "u_target_distance": float(np.linalg.norm(np.subtract(cam.target, cam.position))),
        }
        for name, value in values.items():
            if name in prog:
                prog[name].value = value

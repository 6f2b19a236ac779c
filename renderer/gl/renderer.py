"""The moderngl renderer: one frame = rebuild → upload → draw → read back.

The renderer makes the host's choices of a variant: a record array of the
method (nodes, sphere records) whose packed data fit a uniform block (64 KiB, and the
context allows blocks that large) is read from one instead of a texture — textures above
that, and always for device data; a png or jpeg frame at one sample per pixel renders into
one RGBA8 target (``renderer.gl.frame.image_only``); a frame of primary rays (depth,
primid, normal) draws the pixels outside the spheres' projected box with the background
variant, which has no traversal (``renderer.gl.frame``).

A ``GLRenderer`` owns one OpenGL context. A context is not thread-safe: call a
renderer from the thread that created it only (the server runs all renders on
one dedicated thread).
"""

from __future__ import annotations

import time
from collections.abc import Hashable
from dataclasses import replace
from typing import cast

import moderngl
import numpy as np

from ..accel.ray_engine import RayEngine
from ..config.methods import METHODS, PreparedMethod
from ..config.settings import RenderSettings
from ..frame.plan import FramePlan, plan_frame
from ..frame.prepare import PreparedFrame, prepare_frame
from ..frame.shader_source import tracer_bindings, tracer_source, vertex_source
from ..geometry.scene import Scene
from ..gpu import gpu_layout
from ..gpu.gpu_layout import Variant
from ..image.result import RenderResult
from ..limits import DEFAULT_TEXTURE_WIDTH, MAX_PROGRAMS, PATH_SAMPLES_PER_PASS
from ..scenes.animation import AnimatedScene
from ..scenes.tree_update import TreeUpdate
from .context import GLUnavailable, create_context  # noqa: F401 - re-exported
from .frame import TracerFrame, image_only
from .programs import ProgramCache
from .raw_gl import RawGL
from .ray_engine import RayEngineFrame, RayEnginePasses
from .targets import TargetPool


class GLRenderer:
    """Renders scenes with the GLSL ES 3.00 tracer. Programs are cached per variant, a bounded number
    (:mod:`renderer.gl.programs`)."""

    def __init__(
        self,
        ctx: moderngl.Context | None = None,
        max_texture_width: int = DEFAULT_TEXTURE_WIDTH,
        max_target_bytes: int = 256 << 20,
        uniform_blocks: bool = True,
        image_targets: bool = True,
        background: bool = True,
        max_programs: int = MAX_PROGRAMS,
    ):
        """``uniform_blocks``: read record arrays that fit from uniform blocks (False:
        textures only, the device's layout). ``image_targets``: RGBA8 targets for png/jpeg
        frames at one sample per pixel (False: always the float targets). ``background``:
        primary-ray frames draw the pixels whose rays cannot meet a sphere with the
        background variant (False: the whole frame with the tracer). ``max_programs``: compiled
        programs kept, the tracer's variants and the ray engines' passes together (least recently
        used out, :mod:`renderer.gl.programs`)."""
        self.ctx = ctx or create_context()
        self.max_texture_width = min(max_texture_width, self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        self.max_blocks = (
            int(self.ctx.info["GL_MAX_FRAGMENT_UNIFORM_BLOCKS"])
            if uniform_blocks and self.ctx.info["GL_MAX_UNIFORM_BLOCK_SIZE"] >= gpu_layout.BLOCK_BYTES
            else 0
        )
        self.image_targets = image_targets
        self.background = background
        self.programs = ProgramCache(max_programs)
        # Render targets, reused and bounded in bytes (the frames in flight hold their own).
        self.targets = TargetPool(self.ctx, max_target_bytes)
        quad = np.array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1], dtype=np.float32)
        self._quad = self.ctx.buffer(quad.tobytes())
        self._ray_engine: RayEnginePasses | None = None
        self._raw_gl: RawGL | None = None

    @property
    def ray_engine(self) -> RayEnginePasses:
        """The passes of the multi-pass methods (made on first use: their programs and targets)."""
        if self._ray_engine is None:
            self._ray_engine = RayEnginePasses(self.ctx, self.max_texture_width, self.programs)
        return self._ray_engine

    @property
    def raw_gl(self) -> RawGL:
        """The GL calls moderngl does not wrap (a float depth buffer for rasterised first hits)."""
        if self._raw_gl is None:
            self._raw_gl = RawGL()
        return self._raw_gl

    @property
    def info(self) -> dict[str, str]:
        return {"renderer": self.ctx.info["GL_RENDERER"], "version": self.ctx.info["GL_VERSION"]}

    def program(
        self,
        method: str,
        mode: str,
        max_recursion_depth: int,
        features: tuple[str, ...] = (),
        blocks: tuple[str, ...] = (),
        image_only: bool = False,
        spheres: bool = True,
        first_hits: str = "",
    ) -> tuple[moderngl.Program, moderngl.VertexArray | None]:
        """The compiled variant, cached by method × mode × recursion depth × feature set ×
        the host's choices (record arrays in uniform blocks, RGBA8 image, background, a pass of
        rasterised first hits), and its full-screen vertex array (None for the spheres' quads:
        their instances are the frame's, :mod:`renderer.gl.first_hits`)."""
        key = (method, mode, max_recursion_depth, features, tuple(blocks), bool(image_only), bool(spheres), first_hits)

        def compile() -> moderngl.Program:
            src = self.fragment_text(tracer_source(*key), features)
            return self.ctx.program(vertex_shader=vertex_source(first_hits), fragment_shader=src)

        entry = self.programs.get(("tracer", *key), compile)
        if first_hits in ("spheres", "tiles"):
            return entry.program, None
        return entry.program, entry.vao("quad", self._quad_vao)

    def _quad_vao(self, prog: moderngl.Program) -> moderngl.VertexArray:
        return self.ctx.vertex_array(prog, [(self._quad, "2f", "a_position")])

    def fragment_text(self, src: str, features: tuple[str, ...]) -> str:
        """A variant's fragment shader as compiled: ``src`` itself (a benchmark's renderer patches
        it here — bench/path_speed.py, bench/experiments/path.py)."""
        return src

    def render(
        self,
        scene: Scene | AnimatedScene,
        settings: RenderSettings,
        *,
        key: Hashable | None = None,
        prepared: PreparedMethod | None = None,
    ) -> RenderResult:
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
        if prepared is not None:  # the caller built it: trace with it (a static scene)
            return self.begin(cast(Scene, scene), settings, prepared=prepared).run()  # posed by the caller
        frame = self.start(prepare_frame(scene, settings, key=key, max_width=self.max_texture_width), t_start=t_start)
        return frame.run()

    def start(
        self,
        frame: PreparedFrame,
        *,
        band_rows: int | None = None,
        batch: int | None = None,
        t_start: float | None = None,
        slice_ms: float | None = None,
        accumulated: tuple[np.ndarray | None, int] | None = None,
        slices: int = 1,
    ) -> StartedFrame:
        """A prepared frame (:func:`renderer.frame.prepare.prepare_frame`) uploaded and ready to be
        traced slice by slice: bands of ``band_rows`` rows (the tracer) or batches of
        ``batch`` primitives (the ray engines). ``accumulated``: of an accumulation frame, the samples
        held so far (their float32 sum, image rows — None when none yet — and count): the frame goes
        on from them and its result hands the new sum back
        (:class:`~renderer.gl.frame.TracerFrame`)."""
        t_start = t_start if t_start is not None else time.perf_counter()
        inner: RayEngineFrame | TracerFrame
        if frame.multi_pass:  # a ray engine
            inner = self.ray_engine.begin(
                cast(RayEngine, METHODS[frame.method]), frame.scene, frame.settings, batch=batch
            )
        else:
            inner = self.begin(
                frame.scene,
                frame.settings,
                plan=frame.plan,
                prepared=frame.prepared,
                band_rows=band_rows,
                slice_ms=slice_ms,
                accumulated=accumulated,
                slices=slices,
            )
        return StartedFrame(inner, frame, t_start)

    def begin(
        self,
        scene: Scene,
        settings: RenderSettings,
        *,
        update: TreeUpdate = TreeUpdate(),
        plan: FramePlan | None = None,
        prepared: PreparedMethod | None = None,
        band_rows: int | None = None,
        one_shot: bool = False,
        slice_ms: float | None = None,
        samples_per_pass: int = PATH_SAMPLES_PER_PASS,
        accumulated: tuple[np.ndarray | None, int] | None = None,
        slices: int = 1,
    ) -> TracerFrame:
        """A frame of the one-pass tracer for the posed ``scene``, uploaded and ready to be
        traced slice by slice (:class:`~renderer.gl.frame.TracerFrame`); ``band_rows``
        sizes its slices, ``samples_per_pass`` the path integrator's passes, ``accumulated`` the
        samples an accumulation frame goes on from (their float32 sum, image rows, or None, and count;
        a Whitted colour frame's: ``slices`` jittered slices of its grid). Plans the frame
        (:func:`renderer.frame.plan.plan_frame`) unless ``plan`` is given, and builds the method's structure
        first unless ``prepared`` is."""
        t_start = time.perf_counter()
        if plan is None:
            plan = plan_frame(scene, settings)
        if plan.multi_pass or plan.features is None:
            raise ValueError(f"method {plan.method!r} draws its frames in passes of its own: use render()")
        if prepared is None:
            prepared = METHODS[plan.method].prepare(
                scene, settings.max_prims, settings.max_tree_depth, self.max_texture_width, update
            )
        image = self.image_targets and image_only(settings) and accumulated is None  # (a sum needs floats)
        variant = plan.variant(image_only=image)
        variant = replace(variant, blocks=self.blocks_for(variant, prepared))  # the host's choice of blocks
        stats = {
            **prepared.stats,
            "method": plan.method,
            "recursion_depth": plan.recursion_depth,
            "features_removed": plan.features.removed(),
            "shader_features": list(plan.defines),
            "blocks": list(variant.blocks),
            "target": "rgba8" if image else "float",
            "n_spheres": scene.n_spheres,
        }
        return TracerFrame(
            self,
            scene,
            settings,
            variant,
            prepared,
            stats,
            band_rows=band_rows,
            one_shot=one_shot,
            t_start=t_start,
            slice_ms=slice_ms,
            samples_per_pass=samples_per_pass,
            accumulated=accumulated,
            slices=slices,
        )

    def blocks_for(self, variant: Variant, prepared: PreparedMethod) -> tuple[str, ...]:
        """The method's record arrays this variant reads whose packed data fit a uniform
        block, as many as the context allows (in the method's order of bindings)."""
        out: list[str] = []
        for b in tracer_bindings(variant):
            tex = prepared.packed.textures.get(b.name)
            if (
                b.records
                and tex is not None
                and len(out) < self.max_blocks
                and tex.data.shape[0] * tex.data.shape[1] <= gpu_layout.BLOCK_RECORDS
            ):
                out.append(b.name)
        return tuple(out)


class StartedFrame:
    """A frame of either kind in flight, whose results also say how it was posed and what
    it was estimated to cost (``pose`` timing, ``time`` and ``cost`` in the statistics)."""

    def __init__(self, inner, frame: PreparedFrame, t_start: float):
        self.inner, self.frame, self.t_start = inner, frame, t_start

    def step(self) -> bool:
        return self.inner.step()

    @property
    def done(self) -> bool:
        return self.inner.done

    @property
    def pixels_total(self) -> int:
        return getattr(self.inner, "pixels_total", 0)

    @property
    def pixels_left(self) -> int:
        return getattr(self.inner, "pixels_left", 0)

    def _annotate(self, result: RenderResult) -> RenderResult:
        if self.frame.pose_ms is not None:
            result.timings["pose"] = self.frame.pose_ms
            result.timings["total"] = (time.perf_counter() - self.t_start) * 1e3
            if result.stats is not None:
                result.stats["time"] = self.frame.settings.time
        if result.stats is not None:
            result.stats["cost"] = self.frame.cost.to_json()
        return result

    @property
    def preview(self) -> RenderResult | None:
        preview = self.inner.preview
        return None if preview is None else self._annotate(preview)

    def result(self) -> RenderResult:
        return self._annotate(self.inner.result())

    def run(self) -> RenderResult:
        while not self.step():
            pass
        return self.result()

    def release(self) -> None:
        self.inner.release()

"""The interface every acceleration method implements, and what a method declares of itself.

A method turns a posed scene into what the GPU tracer needs for it — its textures and
uniforms, packed with the layout beside its build (``accel/<method>_layout.py``), and
statistics — in ``prepare``, which runs for every frame: the thesis rebuilds its BIH
per request, and so do we, except where a frame of an animation asks a method that keeps
its tree to update it (:mod:`renderer.scenes.tree_update`).

Nothing here imports OpenGL: a single-pass method's traversal is GLSL
(``shaders/<capabilities.shader>``, spliced into ``raytrace.frag``); a multi-pass
method's passes are run by :mod:`renderer.gl.ray_engine`, which the GL renderer finds
from ``capabilities.multi_pass``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from ..geometry.scene import Scene
from ..gpu import gpu_layout
from ..integrators import Integrator
from ..limits import DEFAULT_TEXTURE_WIDTH
from ..modes import SINGLE_PASS_MODES
from ..scenes.tree_update import REBUILD, TreeUpdate

# A ray stops at its nearest hit, so it rarely reaches every leaf the SAH counts, but it tests
# every primitive of a leaf it enters: the builds report the SAH's tests in leaves this big
# apart (``sah_big_tests``), which the cost model (renderer/frame/cost.py) counts in full.
BIG_LEAF = 32


@dataclass
class PreparedMethod:
    """One request's acceleration data: GPU data, build time (ms), statistics, and the
    built structure itself (``tree``: what the CPU traversals of the tests and the
    reference walk; None for a method without one)."""

    packed: gpu_layout.PackedScene
    build_ms: float
    stats: dict[str, Any] = field(default_factory=dict)
    tree: Any = None


def mesh_stats(scene: Scene) -> dict[str, int]:
    """What a build's statistics add for a scene with meshes (nothing for spheres only, whose
    statistics are the sphere build's alone): tree primitives are spheres, triangles, then analytic shapes."""
    if not scene.n_triangles and not scene.n_shapes:
        return {}
    out = {"spheres": scene.n_spheres, "triangles": scene.n_triangles}
    if scene.n_triangles:
        out["degenerate_triangles"] = scene.n_degenerate_triangles
    if scene.n_shapes:
        out["shapes"] = scene.n_shapes
    return out


class NoLayout:
    """Mixin of methods without a layout of their own (no bindings, no defines)."""

    bindings: tuple[gpu_layout.Binding, ...] = ()

    @staticmethod
    def glsl_defines() -> str:
        return ""


@dataclass(frozen=True)
class Capabilities:
    """What a method is, so that nobody has to find out by trying.

    multi_pass: the frame is drawn as several GL passes (the ray engines) instead of one
    pass of ``raytrace.frag``; such a method cannot run on a device (WebGL2 client).
    shader: the GLSL file of a single-pass method's traversal (``shaders/``), defining
    ``method_init()`` and ``intersect_spheres()``.
    modes: the render modes it can draw.
    tests_every_sphere: no hierarchy over the primitives — a frame costs rays × spheres.
    primitives: the kinds of primitive it traces; a scene with another kind is refused with
    422 before anything is built (the ray engines draw spheres and planes only).
    update_schemes: how it can follow an animation from its previous frame
    (:data:`renderer.scenes.tree_update.UPDATE_SCHEMES`); ``("rebuild",)`` = always rebuilds.
    settings: the render settings its build or passes read (``max_prims``,
    ``max_tree_depth``, ``tile_size``, ``update``…): a client shows only these.
    meshes_on_gpu: its GPU layout and traversal hold triangles (bih, bruteforce, bvh, kdtree,
    twolevel), so a scene with meshes is traced on the GPU; the server refuses a scene with
    meshes with 422 ``meshes`` for a one-pass method without it.
    max_primitives: the most primitives (spheres + triangles) it traces; more are refused with
    422 ``method`` (brute force: one shader loop over them all, ``limits.MAX_LOOP_PRIMITIVES``).
    """

    multi_pass: bool = False
    shader: str | None = None
    modes: tuple[str, ...] = SINGLE_PASS_MODES
    tests_every_sphere: bool = False
    update_schemes: tuple[str, ...] = ("rebuild",)
    settings: tuple[str, ...] = ()
    primitives: tuple[str, ...] = ("spheres", "planes", "triangles", "shapes")
    meshes_on_gpu: bool = False
    max_primitives: int | None = None

    @property
    def integrators(self) -> tuple[Integrator, ...]:
        """How it can compute a frame's colour: the Whitted ray tree, and the path integrator where
        it reads the ``integrator`` setting (one pass of ``raytrace.frag``: its paths are traced
        in the same loop as the traversal's rays)."""
        return tuple(Integrator) if "integrator" in self.settings else (Integrator.WHITTED,)

    @property
    def device(self) -> bool:
        """Whether a browser can trace it (one pass of the shared shader)."""
        return not self.multi_pass and self.shader is not None


class AccelerationMethod(Protocol):
    """A method of tracing the spheres: a name, its capabilities, the GPU bindings and layout
    constants its traversal reads (declared into the shader header from here), and ``prepare``."""

    name: str
    label: str  # the client's word for it (GET /api/info's method_settings)
    capabilities: Capabilities

    # Read-only members (a method's class attribute, of a more precise type, satisfies them).
    @property
    def bindings(self) -> tuple[gpu_layout.Binding, ...]:
        """What its traversal reads."""

    @property
    def glsl_defines(self) -> Callable[[], str]:
        """The method's layout constants as ``#define`` lines ("" when it has none): a static method."""

    def prepare(
        self,
        scene: Scene,
        max_prims: int,
        max_tree_depth: int,
        max_width: int = DEFAULT_TEXTURE_WIDTH,
        update: TreeUpdate = REBUILD,
    ) -> PreparedMethod:
        """The frame's acceleration data for the posed ``scene``; ``update`` says whether and
        how the previous frame's tree of the same animation may be updated instead."""

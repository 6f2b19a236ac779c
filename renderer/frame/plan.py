"""One frame planned, GL-free: the method its settings name resolved (``auto``), checked against the
scene, and the one-pass shader variant chosen.

Every reader of a frame's plan reads it here, so they agree: the GL renderer compiles the variant
(:mod:`renderer.gl.renderer`), the device's data names the same variant for a browser
(:mod:`server.frames.device_data`), the build statistics and the input caps resolve ``auto`` alike
(:mod:`server.frames.pipeline`, :mod:`server.sessions.caps`), and a frame's preparation — pose, build,
cost — starts from it (:mod:`renderer.frame.prepare`).

``auto`` chooses by the tree's primitives — spheres, triangles and analytic shapes
(:attr:`renderer.geometry.scene.Scene.n_tree_primitives`) — of the scene at rest: every pose of an animation
is traced by the same method.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..config.methods import METHODS, check_primitives, resolve_method
from ..config.settings import RenderSettings
from ..geometry.scene import Scene
from ..gpu.gpu_layout import Variant
from ..integrators import Denoiser
from .features import SceneFeatures, frame_features


def plan_method(settings: RenderSettings, tree_primitives: int) -> str:
    """The concrete method of a frame of ``settings`` over ``tree_primitives`` tree primitives
    (``auto`` resolved); :class:`SceneError` (``mode`` or ``integrator``) where it cannot draw them."""
    settings.check_method(tree_primitives)
    return resolve_method(settings.method, tree_primitives)


@dataclass(frozen=True)
class FramePlan:
    """What a frame of the posed ``scene`` with ``settings`` traces: its concrete ``method``, whether
    the method draws passes of its own (the ray engines: ``multi_pass``, no variant), and the one-pass
    variant's ``features`` and ``recursion_depth`` (levels, or a path's segments)."""

    scene: Scene
    settings: RenderSettings
    method: str
    multi_pass: bool
    features: SceneFeatures | None  # None: a multi-pass method's frame (no tracer variant)
    recursion_depth: int

    @property
    def defines(self) -> tuple[str, ...]:
        """The variant's feature defines (:meth:`SceneFeatures.defines`); none for a multi-pass frame."""
        return self.features.defines() if self.features is not None else ()

    def variant(self, image_only: bool = False) -> Variant:
        """The one-pass tracer's variant of this frame (the host adds its uniform blocks);
        ``image_only``: it writes one RGBA8 image."""
        if self.multi_pass:
            raise ValueError(f"method {self.method!r} draws its frames in passes of its own: it has no variant")
        return Variant(self.method, self.settings.mode, self.recursion_depth, self.defines, image_only=image_only)


def plan_frame(scene: Scene, settings: RenderSettings, *, tree_primitives: int | None = None) -> FramePlan:
    """The plan of a frame of the posed ``scene`` with ``settings``: ``auto`` resolved by
    ``tree_primitives`` (default: the scene's; an animation's frames pass its count at rest), the
    method checked against the mode, the integrator and the scene's kinds and count of primitives
    (:class:`SceneError` naming the setting), and the variant's features — the denoiser's guides
    written where ``denoise`` is on."""
    n = scene.n_tree_primitives if tree_primitives is None else tree_primitives
    name = plan_method(settings, n)
    check_primitives(name, scene)  # e.g. brute force past the shader's loop limit, a ray engine and meshes
    caps = METHODS[name].capabilities
    if caps.multi_pass:
        return FramePlan(scene, settings, name, True, None, settings.max_recursion_depth)
    features, depth = frame_features(scene, settings, guides=settings.denoise != Denoiser.OFF)
    return FramePlan(scene, settings, name, False, features, depth)

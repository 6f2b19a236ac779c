"""What a scene can use: the basis of "model no more than a scene needs".

A shader variant compiled for a scene without reflective materials has no
reflection code, one without lights no shadow rays, and a scene where nothing
reflects or transmits needs no recursion beyond the primary ray. Each of these
is exact: the image is the one the generic variant renders.

Beside those removals a specialised variant compiles in the scene's counts of planes and
lights (``PLANES_k``, ``LIGHTS_k``: loops of known length instead of loops bounded at run
time) and, when no material both reflects and transmits (``NO_SPLIT``), leaves out the task
stack: every hit then spawns at most one ray, so the ray tree is a path.

Two defines are not choices but the scene's *data formats* (``renderer/gpu/gpu_layout.py``),
carried by every variant, the generic one too, because the packers follow them:
``EQUAL_RADII`` (16-byte sphere records, the radius a uniform) and ``MATERIAL_TEXTURE``
(more materials than the uniform array holds). Two more only scenes with meshes carry:
``TRIANGLES`` (the triangle records, Woop et al.'s test and the triangles' shading compiled
in) and ``SMOOTH_TRIANGLES`` (some mesh has vertex normals: they are read when a hit is
shaded). A sphere-only scene carries neither, so its variants compile no triangle code
(``FEATURE_TRIANGLES`` 0: renderer/frame/shader_source.py).
Likewise ``SHAPES``: the scene has analytic shapes (their records, tests and shading), and ``PBR``:
a material of the scene is glTF's metallic-roughness kind (every material record then holds its kind,
and ``shaders/bsdf_pbr.glsl`` is compiled in, ``FEATURE_PBR`` 1); a scene of Phong materials alone
compiles as before. A PBR material reflects (Whitted's reflected ray) unless its roughness is 1, and
transmits where ``transmission`` > 0 and it is not wholly metal.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from ..geometry.scene import Scene
from ..gpu import gpu_layout, texture_layout
from ..integrators import Integrator
from ..limits import MAX_LIGHTS, MAX_PLANES

# What a specialised variant removes (the stats' ``features_removed``), then the counts.
REMOVALS = ("NO_REFLECTION", "NO_TRANSMISSION", "NO_LIGHTS", "NO_SPLIT")
# What a PBR material reads beside its record, only where a used one does (renderer/gpu/texture_layout.py):
# textures (and the triangles' UVs), vertex colours, tangents for a normal map.
SURFACE_FORMATS = ("TEXTURES", "VERTEX_COLORS", "TANGENTS")
PLANE_COUNTS = tuple(f"PLANES_{k}" for k in range(MAX_PLANES + 1))
LIGHT_COUNTS = tuple(f"LIGHTS_{k}" for k in range(1, MAX_LIGHTS + 1))  # no lights: NO_LIGHTS
DATA_FORMATS = (
    "EQUAL_RADII",
    "MATERIAL_TEXTURE",
    "TRIANGLES",
    "SMOOTH_TRIANGLES",
    "SHAPES",
    "PBR",
    *SURFACE_FORMATS,
)
# What the light of a frame needs beyond the thesis's, never specialised away either (a scene without
# them carries none, so its variants compile none of it, FEATURE_LIGHTING 0): some used material emits
# (EMISSION), the environment is not black (ENVIRONMENT), the frame traces paths (PATH: the
# ``integrator`` setting, in colour frames), the environment is an image (ENVIRONMENT_MAP), and a
# path frame writes the denoiser's guides (GUIDES: ``denoise`` on; renderer/image/denoise.py).
LIGHTING = ("EMISSION", "ENVIRONMENT", "PATH", "ENVIRONMENT_MAP", "GUIDES")
# What a path variant removes beside REMOVALS (the path integrator runs every lane through all of
# its loop's code, so a lobe or a light kind the scene lacks costs every ray): the GGX lobes where no
# used material is rough, next-event estimation of emitting spheres, triangles or analytic shapes where
# none emits. Emitted only where they say something: NO_ROUGHNESS where something reflects or
# transmits, the light kinds where something emits (the shader infers them otherwise), so the
# shader query of a variant stays short.
PATH_REMOVALS = ("NO_ROUGHNESS", "NO_SPHERE_LIGHTS", "NO_TRIANGLE_LIGHTS", "NO_SHAPE_LIGHTS")
# The defines a variant may carry, in the order they are emitted (the server's shader query
# accepts these, in this order).
FEATURE_DEFINES = (*REMOVALS, *PLANE_COUNTS, *LIGHT_COUNTS, *DATA_FORMATS, *LIGHTING, *PATH_REMOVALS)
# Those that are switches: the tracer's header defines each to 1 where the variant carries it, else
# 0 (renderer/frame/shader_source.py); the counts become the numbers N_PLANES and N_LIGHTS.
SWITCHES = (*REMOVALS, *DATA_FORMATS, *LIGHTING, *PATH_REMOVALS)


@dataclass(frozen=True)
class SceneFeatures:
    reflection: bool
    transmission: bool
    lights: bool
    split: bool = True  # a used material both reflects and transmits
    n_planes: int | None = None  # compiled-in counts (None: read from uniforms)
    n_lights: int | None = None
    equal_radii: bool = False  # data formats (gpu_layout), never specialised away
    material_texture: bool = False
    triangles: bool = False
    smooth_triangles: bool = False
    shapes: bool = False
    pbr: bool = False  # a material of the glTF metallic-roughness kind (kinds in the records)
    textures: bool = False
    vertex_colors: bool = False
    tangents: bool = False
    emission: bool = False
    environment: bool = False
    path: bool = False
    environment_map: bool = False
    guides: bool = False
    roughness: bool = True  # a used material is rough (path variants: the GGX lobes)
    emitting_spheres: bool = True  # a sphere emits (path variants: its next-event estimation)
    emitting_triangles: bool = True  # … a triangle emits
    emitting_shapes: bool = True  # … an analytic shape emits

    def defines(self) -> tuple[str, ...]:
        """The variant's defines, in FEATURE_DEFINES order: what the scene cannot use removed,
        its counts compiled in, its data formats."""
        on = set()
        if not self.reflection:
            on.add("NO_REFLECTION")
        if not self.transmission:
            on.add("NO_TRANSMISSION")
        if not self.lights:
            on.add("NO_LIGHTS")
        if self.reflection and self.transmission and not self.split:
            on.add("NO_SPLIT")
        if self.n_planes is not None:
            on.add(f"PLANES_{self.n_planes}")
        if self.n_lights:
            on.add(f"LIGHTS_{self.n_lights}")
        if self.equal_radii:
            on.add("EQUAL_RADII")
        if self.material_texture:
            on.add("MATERIAL_TEXTURE")
        if self.triangles:
            on.add("TRIANGLES")
        if self.smooth_triangles:
            on.add("SMOOTH_TRIANGLES")
        if self.shapes:
            on.add("SHAPES")
        if self.pbr:
            on.add("PBR")
        for name in SURFACE_FORMATS:
            if getattr(self, name.lower()):
                on.add(name)
        for name in LIGHTING:
            if getattr(self, name.lower()):
                on.add(name)
        if self.path and not self.roughness and (self.reflection or self.transmission):
            on.add("NO_ROUGHNESS")
        if self.path and self.emission:
            if not self.emitting_spheres:
                on.add("NO_SPHERE_LIGHTS")
            if not self.emitting_triangles:
                on.add("NO_TRIANGLE_LIGHTS")
            if not self.emitting_shapes:
                on.add("NO_SHAPE_LIGHTS")
        return tuple(d for d in FEATURE_DEFINES if d in on)

    def removed(self) -> list[str]:
        """What the variant leaves out (``features_removed`` of a frame's stats)."""
        return [d for d in self.defines() if d in REMOVALS or d in PATH_REMOVALS]

    def recursion_depth(self, requested: int) -> int:
        """The deepest level a ray tree can reach in this scene (≤ requested); a path bounces off
        every surface, so the path integrator's depth is the one requested."""
        return requested if (self.reflection or self.transmission or self.path) else 1

    def with_integrator(self, integrator: str, mode: str, guides: bool = False) -> SceneFeatures:
        """The features of a frame of this scene with ``integrator`` in ``mode`` (paths: colour only);
        ``guides``: a path frame writes the denoiser's guides too."""
        path = integrator == Integrator.PATH and mode == "color"
        return replace(self, path=path, guides=path and guides)

    def generic(self) -> SceneFeatures:
        """The generic variant for the same data: nothing removed, counts read at run time."""
        return replace(
            GENERIC,
            equal_radii=self.equal_radii,
            material_texture=self.material_texture,
            triangles=self.triangles,
            smooth_triangles=self.smooth_triangles,
            shapes=self.shapes,
            pbr=self.pbr,
            textures=self.textures,
            vertex_colors=self.vertex_colors,
            tangents=self.tangents,
            emission=self.emission,
            environment=self.environment,
            path=self.path,
            environment_map=self.environment_map,
            guides=self.guides,
        )


GENERIC = SceneFeatures(reflection=True, transmission=True, lights=True)


def scene_features(scene: Scene) -> SceneFeatures:
    """Features of the materials that primitives actually use, the counts of planes and
    lights, and the scene's data formats."""
    used = (
        set(np.unique(scene.sphere_materials).tolist())
        | {p.material for p in scene.planes}
        | {m.material for m in scene.meshes}
        | set(np.unique(scene.shapes.material).tolist())
    )
    mats = [scene.materials[i] for i in used]
    spheres = set(np.unique(scene.sphere_materials).tolist())
    return SceneFeatures(
        reflection=any(m.reflects for m in mats),
        transmission=any(m.transmits for m in mats),
        lights=len(scene.lights) > 0,
        split=any(m.reflects and m.transmits for m in mats),
        n_planes=len(scene.planes),
        n_lights=len(scene.lights),
        equal_radii=gpu_layout.equal_radii(scene),
        material_texture=gpu_layout.material_texture(scene),
        triangles=gpu_layout.has_triangles(scene),
        smooth_triangles=gpu_layout.smooth_triangles(scene),
        shapes=gpu_layout.has_shapes(scene),
        pbr=gpu_layout.has_pbr(scene),
        textures=texture_layout.uses_textures(scene),
        vertex_colors=texture_layout.uses_vertex_colors(scene),
        tangents=texture_layout.uses_tangents(scene),
        emission=any(m.emits for m in mats),
        environment=any(scene.environment),
        environment_map=scene.environment_map is not None,
        roughness=any(m.rough for m in mats),
        emitting_spheres=any(scene.materials[i].emits for i in spheres),
        emitting_triangles=any(scene.materials[m.material].emits for m in scene.meshes),
        emitting_shapes=any(scene.materials[int(m)].emits for m in np.unique(scene.shapes.material)),
    )


class FrameSettings(Protocol):
    """What of a frame's settings chooses its variant (:class:`renderer.config.settings.RenderSettings` has
    it; named here so that the core's features need not import the settings and the methods; read-only,
    as a frozen dataclass's fields are)."""

    @property
    def integrator(self) -> str: ...
    @property
    def mode(self) -> str: ...
    @property
    def specialize(self) -> bool: ...
    @property
    def max_recursion_depth(self) -> int: ...


def frame_features(scene: Scene, settings: FrameSettings, guides: bool = False) -> tuple[SceneFeatures, int]:
    """The features and the recursion depth (levels, or a path's segments) of the one-pass
    variant that traces a frame of the posed ``scene`` with ``settings``: the scene's features,
    with the path integrator where the settings ask for it, generic unless ``specialize``. The
    server's frames and the device's data both choose their variant here, so a browser compiles
    the very text the server does. ``guides``: a path frame writes the denoiser's guides too (a server's frame with
    ``denoise`` on, or a device's, whose à-trous filter reads them)."""
    features = scene_features(scene).with_integrator(settings.integrator, settings.mode, guides=guides)
    if not settings.specialize:
        features = features.generic()
    return features, features.recursion_depth(settings.max_recursion_depth)

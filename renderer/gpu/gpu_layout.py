"""What the GPU reads: every texture and uniform of the tracer, defined once.

Each texture or uniform is a :class:`Binding` — its GLSL name, type and purpose —
declared beside what fills it: the scene's and the camera's here, each method's in its
layout module (``renderer/accel/<method>_layout.py``). The packers fill them *by those
constants*, and the shader header declares them *from those constants*
(:mod:`renderer.frame.shader_source`), so a name exists once: a packer cannot fill a
sampler the shader spells differently. What a compiled variant reads (a
:class:`Variant`: method, mode, recursion depth, feature defines, and the host's choices)
decides which bindings its header declares; the GL renderer uploads exactly those, and a
test checks that each of them is an active uniform (or uniform block) of its program.

Arrays longer than one texture row wrap into a 2-D texture: element ``i`` is
texel ``(i % width, i / width)`` where ``width = textureSize(tex, 0).x`` — the
shader reads the width from the texture, so a device with a smaller
``MAX_TEXTURE_SIZE`` only needs a narrower packing.

**Record arrays** (``Binding(records=True)``): arrays of 16-byte ``uvec4`` records (tree
nodes, sphere records) that the host may place in a *uniform block* instead of a texture
when they fit one (:data:`BLOCK_RECORDS` records, 64 KiB): ``Variant.blocks`` names them,
and the header declares either the ``usampler2D`` or ``layout(std140) uniform NAME {
uvec4 NAME_rec[BLOCK_RECORDS]; }`` and the accessor ``NAME_at(i)`` for both, so the
traversal reads ``NAME_at(i)`` whatever the storage. A uniform-block read costs llvmpipe
0.78 ns against 0.96 for an RGBA32UI ``texelFetch``. The device (WebGL2, whose
guaranteed block is 16 KiB) always gets textures.

**Sphere records** (:func:`sphere_records`), in the order a method's leaves list them (a
leaf is a run of records, the last one flagged), so a leaf needs no index array::

    equal radii (EQUAL_RADII), 16 bytes, one record per sphere:
        x, y, z  float32 bits of the centre
        w        key: bits 20..0 sphere id, bits 28..21 material, bit 31 last of its leaf
        (the radius is the uniform u_sphere_radius)                       total: 16 bytes
    otherwise, 32 bytes, records 2p and 2p + 1:
        2p       x, y, z, w  float32 bits of the centre and the radius
        2p + 1   x           key (as above); y, z, w zero                   total: 32 bytes

**Triangles** (scenes with meshes only: the variant carries the data-format define
``TRIANGLES``, and ``SMOOTH_TRIANGLES`` when a mesh has vertex normals; a sphere-only
variant's text is the one before meshes). A method's leaf-order records hold one *slot*
per tree primitive, the size of a sphere record (16 or 32 bytes), so leaves, refs and
the ``last`` flags stay as they were; a triangle's slot is (:func:`leaf_records`)::

    key (where a sphere record has its key): bit 30 TRI_SLOT, bits 29..0 the triangle
        index j (scene order, < MAX_TRIANGLES), bit 31 last of its leaf; the rest zero

and the triangle itself lives in the scene's triangle records (:func:`triangle_records`,
``u_triangles``, a record array indexed by j, read by the traversal's test and once more
by the shading of a hit)::

    3j      x, y, z  float32 bits of corner v0;  w  material (bits 7..0),
                                                    bit 31 TRI_DEGENERATE
    3j + 1  x, y, z  float32 bits of corner v1;  w  0
    3j + 2  x, y, z  float32 bits of corner v2;  w  0                   total: 48 bytes

A zero-area triangle (``Scene.triangle_degenerate``: its float64 cross product is 0) is
flagged TRI_DEGENERATE and the test skips it, as the reference never hits it. (Its float32
corners alone would not do: a collinear triangle's det can round to a nonzero value, and
even three equal corners give E(A, A) = fl(fma(a, b, −fl(b·a))) ≠ 0 where a compiler fuses.)
With ``SMOOTH_TRIANGLES`` the vertex normals follow in
``u_tri_normals``, read only when a hit is shaded::

    3j + k  x, y, z  float32 bits of corner k's unit normal (normalised in float64);
            w  1 for a smooth triangle, 0 for a flat one (its normals are zero)
                                                                        total: 48 bytes

**Analytic shapes** (scenes with cylinders, cones, disks or tori only: the variant carries
the data-format define ``SHAPES``; every other variant's text is the one before them). A
shape's slot among the leaf-order records, the size of a sphere record like a triangle's,
is (:func:`leaf_records`)::

    key (where a sphere record has its key): bit 29 SHAPE_SLOT, bits 28..0 the shape
        index k (scene order, < MAX_SHAPES), bit 31 last of its leaf; the rest zero
        (bit 29 is never set in a sphere key, ids and materials take bits 28..0, nor in a
        triangle's, whose index is below MAX_TRIANGLES = 2^20)

and the shape itself lives in the scene's shape records (:func:`shape_records`,
``u_shapes``, a record array indexed by k; the 12 numbers of renderer/geometry/shapes.py's record as
shaders/shapes.glsl's three vec4)::

    3k      x, y, z  float32 bits of the origin;      w  r0
    3k + 1  x, y, z  float32 bits of the unit axis;   w  r1
    3k + 2  x  height, y  caps (1.0 / 0.0), z  kind (0.0 … 3.0) as float32 bits;
            w  material (bits 7..0, an integer)                        total: 48 bytes

``u_shape_base`` is the scene id of shape 0 (``Scene.shape_id_base``: spheres + planes +
triangles). The methods that trace shapes list :data:`SHAPE_BINDINGS` (brute force also
``u_num_shapes``; a tree's leaves say where its shapes are).

``u_tri_base`` is the scene id of triangle 0 (``Scene.triangle_id_base``: spheres +
planes), so a hit writes scene ids. The methods that trace triangles list
:data:`TRIANGLE_BINDINGS` among their own bindings, so these record arrays, like the
method's, may sit in uniform blocks; the background variant reads none of them.

==============  ========  ==========  ==========================================
texture         format    element     contents
==============  ========  ==========  ==========================================
u_spheres       RGBA32F   sphere id   centre x, y, z, radius (the ray engines)
u_sphere_mat    R32UI     sphere id   material index (the ray engines)
u_materials     RGBA32F   MATERIAL_   the material's record, laid out from its
                          TEXELS per  declaration (renderer.materials:
                          material    record_layout; today (r, g, b, ambient),
                                      (diffuse, specular, shininess,
                                      reflective), (transmissive, ior,
                                      roughness, 0)); the tracer reads the same
                                      texels from the uniform array
                                      u_material_vecs when the scene has at most
                                      MAX_UNIFORM_MATERIALS materials
==============  ========  ==========  ==========================================

Planes and lights are few and go in uniform arrays (``MAX_PLANES``,
``MAX_LIGHTS``); the camera's uniforms are :func:`camera_uniforms`. Each method
packs its own structure with the layout beside its build through :func:`wrap_rows`.
"""

from __future__ import annotations

import math
import threading
import weakref
from dataclasses import dataclass, field

import numpy as np

from ..geometry.scene import Camera, Material, Scene
from ..geometry.shapes import CONE as SHAPE_CONE, CYLINDER as SHAPE_CYLINDER, DISK as SHAPE_DISK, bounds as shape_bounds
from ..limits import (
    DEFAULT_TEXTURE_WIDTH,
    MAX_LIGHTS,
    MAX_MATERIALS,
    MAX_PLANES,
    MAX_SAMPLED_SHAPE_PATCHES,
    MAX_SAMPLED_SPHERES,
    MAX_SAMPLED_TRIANGLES,
    MAX_SHAPES,
    MAX_SPHERES,
    MAX_TRIANGLES,
)
from ..materials import glsl_accessors, pack_records, record_texels
from ..materials.envmap import EnvironmentMap
from ..materials.kinds import KINDS
from ..materials.pbr import WHITTED_AMBIENT, PbrMaterial
from ..modes import RAY_TREE_MODES

MATERIAL_TEXELS = record_texels(Material)  # the material record's texels, from its declaration
# A scene with a kind beside the Phong one (the PBR data format) gives every material the same
# stride: texel 0 its kind's id (KIND_IDS), then its kind's record, as long as the largest kind's.
KIND_IDS = {name: i for i, name in enumerate(KINDS)}
MATERIAL_STRIDE = 1 + max(record_texels(k) for k in KINDS.values())
# The tracer reads materials from a uniform array when the scene has at most this many
# (WebGL2 guarantees 224 fragment uniform vectors; these take 48), else from u_materials.
MAX_UNIFORM_MATERIALS = 16
# Records of a uniform block: 64 KiB of uvec4 (the renderer uses blocks only where
# GL_MAX_UNIFORM_BLOCK_SIZE allows them).
BLOCK_RECORDS = 4096
BLOCK_BYTES = 16 * BLOCK_RECORDS
# The key word of a sphere record.
SPHERE_ID_BITS = 21  # ids < MAX_SPHERES = 2^21
SPHERE_ID_MASK = (1 << SPHERE_ID_BITS) - 1
SPHERE_MAT_SHIFT = SPHERE_ID_BITS
SPHERE_MAT_MASK = 0xFF  # materials < MAX_MATERIALS = 256
SPHERE_LAST = 1 << 31  # the last record of a leaf
assert MAX_SPHERES <= 1 << SPHERE_ID_BITS and MAX_MATERIALS <= SPHERE_MAT_MASK + 1
# A triangle's slot among the leaf-order records (the module's docstring): bit 30 (never set
# in a sphere key: ids take bits 20..0, materials 28..21) and the triangle index below it.
TRI_SLOT = 1 << 30
TRI_INDEX_MASK = TRI_SLOT - 1
TRI_DEGENERATE = 1 << 31  # in the material word of a triangle's first record
TRIANGLE_TEXELS = 3  # records per triangle in u_triangles and u_tri_normals
assert MAX_TRIANGLES <= TRI_SLOT
# An analytic shape's slot (the module's docstring): bit 29, never set in a sphere's key nor in a
# triangle's (its index is below MAX_TRIANGLES), checked before TRI_SLOT by the traversals.
SHAPE_SLOT = 1 << 29
SHAPE_INDEX_MASK = SHAPE_SLOT - 1
SHAPE_TEXELS = 3  # records per shape in u_shapes
SHAPE_MAT_MASK = 0xFF  # the material in w of a shape's third record
assert MAX_TRIANGLES < SHAPE_SLOT and MAX_SHAPES <= SHAPE_SLOT and SPHERE_MAT_SHIFT + 8 <= 29


# ---- bindings and variants -----------------------------------------------------------------
@dataclass(frozen=True)
class Binding:
    """One texture or uniform of the tracer: GLSL name and type (with its precision, so the
    declaration is valid before any default-precision statement), array length, purpose,
    and the group of what a variant reads it for (see :meth:`Variant.reads`).

    ``traversal``: read only by the traversal (not by the background variant).
    ``needs`` / ``unless``: a feature define the variant must / must not carry to read it
    (the data formats: ``EQUAL_RADII``, ``MATERIAL_TEXTURE``); one ending in ``_`` stands
    for every define it begins (``PLANES_``: a compiled-in count). ``tracer``: False for what
    only the ray engines read. ``records``: an array of ``uvec4`` records that the host may
    place in a uniform block (the module's docstring); its GLSL type is then implied."""

    name: str
    glsl_type: str = "highp usampler2D"
    doc: str = ""
    length: str | None = None  # GLSL constant of a uniform array's length
    group: str = "always"
    needs: str | None = None
    unless: str | None = None
    tracer: bool = True
    records: bool = False
    traversal: bool = False

    def declaration(self, block: bool = False) -> str:
        """The GLSL declaration; a record array's also declares ``NAME_at(i)`` (and, as a
        texture, its row shift, set by ``LAYOUT_INIT()``)."""
        doc = f"  // {self.doc}" if self.doc else ""
        if not self.records:
            arr = f"[{self.length}]" if self.length else ""
            return f"uniform {self.glsl_type} {self.name}{arr};" + doc
        if block:
            return (
                f"layout(std140) uniform {self.name} {{ highp uvec4 {self.name}_rec[BLOCK_RECORDS]; }};{doc}\n"
                f"#define {self.name}_at(i) {self.name}_rec[i]"
            )
        return (
            f"uniform highp usampler2D {self.name};{doc}\n"
            f"int {self.name}_shift;\n"
            f"#define {self.name}_at(i) texelFetch({self.name}, texel((i), {self.name}_shift), 0)"
        )


# Groups of bindings a variant may not read; each has a READS_<GROUP> switch (0 or 1) in the shader.
GROUPS = (
    "materials",
    "lights",
    "min_weight",
    "target_distance",
    "emission",
    "environment",
    "path",
    "environment_map",
    "environment_sampling",
    "shading_normals",
)


@dataclass(frozen=True)
class Variant:
    """One compiled tracer: method × mode × recursion depth × feature defines (``NO_*``,
    counts, data formats; :mod:`renderer.frame.features`) × the host's choices: the record arrays
    it reads from uniform blocks (``blocks``), whether it writes one RGBA8 image
    (``image_only``: png/jpeg frames at one sample per pixel), and whether it traces the
    spheres at all (``spheres`` False: the *background* variant of a primary-ray frame,
    drawn where no primary ray can meet a sphere, :func:`primary_rect`; it reads none of
    the method's bindings). ``first_hits``: a pass of a frame whose first hits are rasterised
    (:mod:`renderer.frame.first_hits`; with ``spheres`` False): ``"planes"`` — the planes and misses,
    everywhere — or ``"spheres"`` — one sphere per instance of its screen quad — or ``"tiles"`` —
    one tile of the window per instance, testing its list of spheres; each writes
    the hit's depth."""

    method: str
    mode: str
    depth: int
    features: tuple[str, ...] = ()
    blocks: tuple[str, ...] = ()
    image_only: bool = False
    spheres: bool = True
    first_hits: str = ""

    @property
    def traced_depth(self) -> int:
        """Levels the variant traces: modes other than colour and recursion trace the primary ray."""
        return self.depth if self.mode in RAY_TREE_MODES else 1

    @property
    def spawns(self) -> bool:
        """Whether a hit can spawn a reflected or transmitted ray."""
        return self.traced_depth > 1 and not {"NO_REFLECTION", "NO_TRANSMISSION"} <= set(self.features)

    @property
    def path(self) -> bool:
        """Whether the variant traces paths (the ``integrator`` setting ``path``; colour frames only)."""
        return self.mode == "color" and "PATH" in self.features

    def reads(self, group: str) -> bool:
        """Whether the variant's shader reads the bindings of ``group``."""
        if group == "always":
            return True
        if group == "materials":  # the ambient colour, or kr / kt of the rays a hit spawns
            return self.mode == "color" or (self.mode == "recursion" and self.spawns)
        if group == "lights":  # shadow rays and the diffuse and specular terms
            return self.mode == "color" and "NO_LIGHTS" not in self.features
        if group == "min_weight":  # the ε cut-off of spawned rays
            return self.spawns
        if group == "target_distance":
            return self.mode == "depth"
        # Emitting materials, a non-black environment and the path integrator: only variants of scenes
        # (frames) that have them read these, so no other variant's text changes for them.
        if group == "emission":
            return self.mode == "color" and "EMISSION" in self.features
        if group == "environment":
            return self.mode == "color" and "ENVIRONMENT" in self.features
        if group == "path":
            return self.path
        if group == "environment_map":  # an image seen by rays that meet nothing
            return self.mode == "color" and "ENVIRONMENT_MAP" in self.features
        if group == "environment_sampling":  # … and sampled by the path integrator's NEE
            return self.path and "ENVIRONMENT_MAP" in self.features
        if group == "shading_normals":  # a hit's shading normal: the hit target, or the image
            if not self.image_only:
                return True
            return (
                self.mode == "normal"
                or (self.mode == "color" and (self.reads("lights") or self.spawns))
                or (self.mode == "recursion" and self.spawns)
            )
        raise ValueError(f"unknown binding group {group!r}")

    def reads_binding(self, b: Binding) -> bool:
        """Whether the variant's shader declares and reads ``b``."""

        # The PBR data format keeps its records in u_materials (too large for the uniform array).
        features = (*self.features, "MATERIAL_TEXTURE") if "PBR" in self.features else self.features

        def carries(define: str) -> bool:
            return any(f == define or (define.endswith("_") and f.startswith(define)) for f in features)

        return (
            b.tracer
            and self.reads(b.group)
            and (self.spheres or not b.traversal)
            and (b.needs is None or carries(b.needs))
            and (b.unless is None or not carries(b.unless))
        )


SPHERES = Binding("u_spheres", "highp sampler2D", "(centre.xyz, radius) per sphere id", tracer=False)
SPHERE_MAT = Binding(
    "u_sphere_mat", "highp usampler2D", "material index per sphere id", group="materials", tracer=False
)
MATERIALS = Binding(
    "u_materials", "highp sampler2D", "MATERIAL_TEXELS texels per material", group="materials", needs="MATERIAL_TEXTURE"
)
MATERIAL_VECS = Binding(
    "u_material_vecs",
    "highp vec4",
    "MATERIAL_TEXELS vectors per material",
    length="MATERIAL_VECS",
    group="materials",
    unless="MATERIAL_TEXTURE",
)
SPHERE_RADIUS = Binding(
    "u_sphere_radius",
    "highp float",
    "the radius of every sphere (EQUAL_RADII records)",
    needs="EQUAL_RADII",
    traversal=True,
)
NUM_SPHERES = Binding("u_num_spheres", "highp int")
NUM_PLANES = Binding("u_num_planes", "highp int", unless="PLANES_")
PLANE_POINT = Binding("u_plane_point", "highp vec3", length="MAX_PLANES")
PLANE_NORMAL = Binding("u_plane_normal", "highp vec3", length="MAX_PLANES")
PLANE_MAT = Binding("u_plane_mat", "highp int", length="MAX_PLANES", group="materials")
NUM_LIGHTS = Binding("u_num_lights", "highp int", group="lights", unless="LIGHTS_")
LIGHT_POS = Binding("u_light_pos", "highp vec3", length="MAX_LIGHTS", group="lights")
LIGHT_COLOR = Binding("u_light_color", "highp vec3", length="MAX_LIGHTS", group="lights")
EMISSION = Binding("u_emission", "highp sampler2D", "(emitted radiance rgb, 0) per material", group="emission")
ENVIRONMENT = Binding("u_environment", "highp vec3", "radiance a ray that meets nothing sees", group="environment")
# An environment image (renderer/materials/envmap.py): its texels and sampling tables, each a 1-D array
# wrapped into rows like every other, so a device's MAX_TEXTURE_SIZE only changes the packing.
ENV_MAP = Binding(
    "u_env_map",
    "highp sampler2D",
    "equirect texels (rgb): texel j·W + i is column i of row j, row 0 the zenith",
    group="environment_map",
)
ENV_SIZE = Binding("u_env_size", "highp ivec2", "(W, H) of the environment image", group="environment_map")
ENV_SCALE = Binding("u_env_scale", "highp float", "the environment image's radiance factor", group="environment_map")
ENV_U_OFFSET = Binding(
    "u_env_u_offset", "highp float", "rotation_deg / 360, added to a direction's u", group="environment_map"
)
ENV_CDF = Binding(
    "u_env_cdf",
    "highp sampler2D",
    "(r) CDFs: texel j·W + i of patch row j's conditional, then (H − 1)·W + j the rows' marginal",
    group="environment_sampling",
)
ENV_BINDINGS = (ENV_MAP, ENV_SIZE, ENV_SCALE, ENV_U_OFFSET, ENV_CDF)
# The path integrator: the samples this pass traces of each pixel, and the point lights' scale.
SAMPLE_START = Binding("u_sample_start", "highp int", "index of this pass's first sample of each pixel", group="path")
SAMPLE_COUNT = Binding("u_sample_count", "highp int", "samples of each pixel this pass traces (≥ 1)", group="path")
LIGHT_SCALE = Binding(
    "u_light_scale",
    "highp float",
    "π·d², d = |target − position|: a point light's radiant intensity per unit of its color (docs/SHADING.md)",
    group="path",
)
PATH_BINDINGS = (SAMPLE_START, SAMPLE_COUNT)  # set per pass
# The emitting spheres next-event estimation samples (the first MAX_SAMPLED_SPHERES by id; the others
# are met by BSDF sampling alone).
NUM_EMITTERS = Binding("u_num_emitters", "highp int", "emitting spheres sampled", group="path")
EMITTER_LAST = Binding("u_emitter_last", "highp int", "id of the last sampled emitting sphere (−1: none)", group="path")
EMITTER_SPHERE = Binding(
    "u_emitter_sphere", "highp vec4", "(centre, radius) of each", length="MAX_SAMPLED_SPHERES", group="path"
)
EMITTER_RADIANCE = Binding(
    "u_emitter_radiance", "highp vec3", "emission of each", length="MAX_SAMPLED_SPHERES", group="path"
)
# The emitting triangles next-event estimation samples, one picked by area: all of them when there are
# at most MAX_SAMPLED_TRIANGLES (else none: BSDF sampling alone meets them).
NUM_EMIT_TRIS = Binding("u_num_emit_tris", "highp int", "emitting triangles sampled (0: none)", group="path")
EMIT_TRI_AREA = Binding("u_emit_tri_area", "highp float", "their total area", group="path")
EMIT_TRI_V0 = Binding("u_emit_tri_v0", "highp vec3", "corner v0 of each", length="MAX_SAMPLED_TRIANGLES", group="path")
EMIT_TRI_E1 = Binding("u_emit_tri_e1", "highp vec3", "v1 − v0 of each", length="MAX_SAMPLED_TRIANGLES", group="path")
EMIT_TRI_E2 = Binding("u_emit_tri_e2", "highp vec3", "v2 − v0 of each", length="MAX_SAMPLED_TRIANGLES", group="path")
EMIT_TRI_RADIANCE = Binding(
    "u_emit_tri_radiance", "highp vec3", "emission of each", length="MAX_SAMPLED_TRIANGLES", group="path"
)
EMIT_TRI_CDF = Binding(
    "u_emit_tri_cdf",
    "highp float",
    "area up to and with each, over the total",
    length="MAX_SAMPLED_TRIANGLES",
    group="path",
)
# The surfaces of the emitting analytic shapes next-event estimation samples, one picked by area and a
# point uniform on it (all of them when there are at most MAX_SAMPLED_SHAPE_PATCHES, else none):
# a cylinder's or cone's side and each of its caps, a disk (annulus), a torus (shape_patches).
NUM_EMIT_PATCHES = Binding(
    "u_num_emit_patches", "highp int", "surfaces of emitting shapes sampled (0: none)", group="path"
)
EMIT_PATCH_AREA = Binding("u_emit_patch_area", "highp float", "their total area", group="path")
EMIT_PATCH_A = Binding(
    "u_emit_patch_a",
    "highp vec4",
    "(origin, r0) of each: a side's base centre and radius, a disk's centre and radius, a torus's centre and "
    "major radius",
    length="MAX_SAMPLED_SHAPE_PATCHES",
    group="path",
)
EMIT_PATCH_B = Binding(
    "u_emit_patch_b",
    "highp vec4",
    "(unit axis, r1) of each: a side's axis and top radius, a disk's normal and inner radius, a torus's axis "
    "and minor radius",
    length="MAX_SAMPLED_SHAPE_PATCHES",
    group="path",
)
EMIT_PATCH_C = Binding(
    "u_emit_patch_c",
    "highp vec4",
    "(height, kind, area, 0) of each: kind 0 a side, 1 a disk, 2 a torus (PATCH_SIDE, PATCH_DISK, PATCH_TORUS)",
    length="MAX_SAMPLED_SHAPE_PATCHES",
    group="path",
)
EMIT_PATCH_RADIANCE = Binding(
    "u_emit_patch_radiance", "highp vec3", "emission of each", length="MAX_SAMPLED_SHAPE_PATCHES", group="path"
)
EMIT_PATCH_CDF = Binding(
    "u_emit_patch_cdf",
    "highp float",
    "area up to and with each, over the total",
    length="MAX_SAMPLED_SHAPE_PATCHES",
    group="path",
)
EMITTER_BINDINGS = (
    NUM_EMITTERS,
    EMITTER_LAST,
    EMITTER_SPHERE,
    EMITTER_RADIANCE,
    NUM_EMIT_TRIS,
    EMIT_TRI_AREA,
    EMIT_TRI_V0,
    EMIT_TRI_E1,
    EMIT_TRI_E2,
    EMIT_TRI_RADIANCE,
    EMIT_TRI_CDF,
    NUM_EMIT_PATCHES,
    EMIT_PATCH_AREA,
    EMIT_PATCH_A,
    EMIT_PATCH_B,
    EMIT_PATCH_C,
    EMIT_PATCH_RADIANCE,
    EMIT_PATCH_CDF,
)
# The triangles (only with the TRIANGLES data format): listed among the bindings of each method
# that traces them, packed by its packer with pack_triangles, so that they may be uniform blocks.
TRIANGLES = Binding(
    "u_triangles",
    doc="TRIANGLE_TEXELS records per triangle: corners, material",
    records=True,
    needs="TRIANGLES",
    traversal=True,
)
TRI_NORMALS = Binding(
    "u_tri_normals",
    doc="TRIANGLE_TEXELS records per triangle: vertex normals",
    records=True,
    group="shading_normals",
    needs="SMOOTH_TRIANGLES",
    traversal=True,
)
TRI_BASE = Binding(
    "u_tri_base", "highp int", "scene id of triangle 0 (spheres + planes)", needs="TRIANGLES", traversal=True
)
NUM_TRIANGLES = Binding("u_num_triangles", "highp int", needs="TRIANGLES", traversal=True)
TRIANGLE_BINDINGS = (TRIANGLES, TRI_NORMALS, TRI_BASE, NUM_TRIANGLES)
# The analytic shapes (only with the SHAPES data format): listed among the bindings of each method
# that traces them, packed by its packer with pack_shapes, so that they may be uniform blocks.
SHAPES = Binding(
    "u_shapes",
    doc="SHAPE_TEXELS records per shape: origin r0, axis r1, height caps kind material",
    records=True,
    needs="SHAPES",
    traversal=True,
)
SHAPE_BASE = Binding(
    "u_shape_base", "highp int", "scene id of shape 0 (spheres + planes + triangles)", needs="SHAPES", traversal=True
)
NUM_SHAPES = Binding("u_num_shapes", "highp int", needs="SHAPES", traversal=True)
SHAPE_BINDINGS = (SHAPES, SHAPE_BASE, NUM_SHAPES)
TREE_SHAPE_BINDINGS = (SHAPES, SHAPE_BASE)  # (a tree's leaves say where its shapes are)
# What a material reads beside its record (only with the TEXTURES, VERTEX_COLORS and TANGENTS data
# formats; renderer/gpu/texture_layout.py packs them, shaders/pbr_inputs.glsl reads them): the scene's
# textures as the layers of one array with their mip levels, a record per texture, and per triangle
# the corners' UV sets (with the ray cones' level terms), colours and tangents. Only a hit on a
# triangle reads them, so the background variant declares none.
TEXTURES = Binding(
    "u_textures",
    "highp sampler2DArray",
    "RGBA8 with mip levels: an atlas of square slots, texture k where its record says",
    group="materials",
    needs="TEXTURES",
    traversal=True,
)
TEXTURE_INFO = Binding(
    "u_texture_info",
    doc="one record per texture: size, mip levels, sampler",
    records=True,
    group="materials",
    needs="TEXTURES",
    traversal=True,
)
TRI_UVS = Binding(
    "u_tri_uvs",
    doc="TRI_UV_TEXELS records per triangle: UV sets 0 and 1 of each corner, the level terms",
    records=True,
    group="materials",
    needs="TEXTURES",
    traversal=True,
)
TRI_COLORS = Binding(
    "u_tri_colors",
    doc="TRIANGLE_TEXELS records per triangle: linear RGBA of each corner",
    records=True,
    group="materials",
    needs="VERTEX_COLORS",
    traversal=True,
)
TRI_TANGENTS = Binding(
    "u_tri_tangents",
    doc="TRIANGLE_TEXELS records per triangle: tangent xyz and handedness w of each corner",
    records=True,
    group="materials",
    needs="TANGENTS",
    traversal=True,
)
SURFACE_BINDINGS = (TEXTURES, TEXTURE_INFO, TRI_UVS, TRI_COLORS, TRI_TANGENTS)
# Everything pack_primitives packs (the tracer's and the ray engines' scene data).
SCENE_BINDINGS = (
    SPHERES,
    SPHERE_MAT,
    MATERIALS,
    MATERIAL_VECS,
    SPHERE_RADIUS,
    NUM_SPHERES,
    NUM_PLANES,
    PLANE_POINT,
    PLANE_NORMAL,
    PLANE_MAT,
    NUM_LIGHTS,
    LIGHT_POS,
    LIGHT_COLOR,
    EMISSION,
    ENVIRONMENT,
    *ENV_BINDINGS,
)

CAM_POS = Binding("u_cam_pos", "highp vec3")
CAM_RIGHT = Binding("u_cam_right", "highp vec3")
CAM_UP = Binding("u_cam_up", "highp vec3")
CAM_FORWARD = Binding("u_cam_forward", "highp vec3")
HALF_EXTENT = Binding("u_half_extent", "highp vec2", "(tan(fov_y/2)·W/H, tan(fov_y/2))")
RESOLUTION = Binding("u_resolution", "highp vec2", "(W, H) of the render target")
TARGET_DISTANCE = Binding(
    "u_target_distance", "highp float", "|target − position|, for the depth image", group="target_distance"
)
CAMERA_BINDINGS = (CAM_POS, CAM_RIGHT, CAM_UP, CAM_FORWARD, HALF_EXTENT, RESOLUTION, TARGET_DISTANCE)
MIN_WEIGHT = Binding(
    "u_min_weight", "highp float", "ε: secondary rays of smaller path weight are not traced", group="min_weight"
)
# A frame is traced in passes: the pixel centres (scale 1, offset 0.5), then for supersampled
# images one pass per sub-pixel (sx, sy) of the √s-times finer grid (scale √s, offset s + 0.5);
# a Whitted accumulation's jittered slice moves the 0.5 to its point of the cell (subpixel_cell).
# (The descriptions are the shader's comments: every recorded shader text holds them.)
PASS_SCALE = Binding("u_pass_scale", "highp float", "sub-pixels per pixel side of this pass's grid")
PASS_OFFSET = Binding("u_pass_offset", "highp vec2", "(sx, sy) + 0.5: the sub-pixel this pass traces")
PASS_BINDINGS = (PASS_SCALE, PASS_OFFSET)
TRACER_BINDINGS = (
    *SCENE_BINDINGS,
    *CAMERA_BINDINGS,
    *PASS_BINDINGS,
    MIN_WEIGHT,
    LIGHT_SCALE,
    *EMITTER_BINDINGS,
    *PATH_BINDINGS,
    *SURFACE_BINDINGS,
)
# The ray engines draw planes as instances after the spheres (the instance count carries the
# number of primitives), so they never read u_num_planes; their depth image is made on the CPU.
# Their materials are the texture, their spheres the per-id textures.
RAY_ENGINE_SCENE_BINDINGS = (
    SPHERES,
    SPHERE_MAT,
    MATERIALS,
    NUM_SPHERES,
    PLANE_POINT,
    PLANE_NORMAL,
    PLANE_MAT,
    NUM_LIGHTS,
    LIGHT_POS,
    LIGHT_COLOR,
)
RAY_ENGINE_BINDINGS = (
    *RAY_ENGINE_SCENE_BINDINGS,
    *(b for b in CAMERA_BINDINGS if b is not TARGET_DISTANCE),
    MIN_WEIGHT,
)


def declarations(bindings: tuple[Binding, ...] | list[Binding], blocks: tuple[str, ...] = ()) -> str:
    """GLSL declarations of ``bindings``, one per line; record arrays named in ``blocks`` as
    uniform blocks. A ``LAYOUT_INIT()`` macro follows, always (the tracer calls it first): it
    sets the row shifts of the record arrays that are textures, if any."""
    text = "".join(b.declaration(b.name in blocks) + "\n" for b in bindings)
    shifts = [b.name for b in bindings if b.records and b.name not in blocks]
    if shifts:
        text += (
            "#define LAYOUT_INIT() " + " ".join(f"{n}_shift = row_shift(textureSize({n}, 0));" for n in shifts) + "\n"
        )
    else:
        text += "#define LAYOUT_INIT()\n"
    return text


@dataclass
class PackedTexture:
    """A 1-D array wrapped into rows: ``data`` is (height, width, components)."""

    data: np.ndarray
    dtype: str  # moderngl / numpy dtype code: 'f4' or 'u4'

    @property
    def size(self) -> tuple[int, int]:
        return int(self.data.shape[1]), int(self.data.shape[0])

    @property
    def components(self) -> int:
        return int(self.data.shape[2])


@dataclass
class PackedTextureArray(PackedTexture):
    """Layers of RGBA8 texels with mip levels (a ``sampler2DArray``, renderer/gpu/texture_layout.py):
    ``levels[l]`` uint8 (layers, height_l, width_l, 4); ``data`` is level 0."""

    levels: list[np.ndarray] = field(default_factory=list)

    @property
    def size(self) -> tuple[int, int]:
        return int(self.data.shape[2]), int(self.data.shape[1])

    @property
    def layers(self) -> int:
        return int(self.data.shape[0])

    @property
    def components(self) -> int:
        return 4

    @property
    def nbytes(self) -> int:
        """GPU bytes, every level."""
        return int(sum(level.nbytes for level in self.levels))


def wrap_rows(elements: np.ndarray, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedTexture:
    """Wrap ``elements`` (count, components) into rows of at most ``max_width``.

    The width is a power of two (the shader addresses texel ``(i & (w-1), i >> log2 w)``),
    ``max_width`` is rounded down to one. An empty array becomes a single zero
    texel (textures cannot be empty). Arrays that share an index (spheres and
    their materials) get the same width because the width depends on the count only.
    """
    elements = np.asarray(elements)
    if elements.ndim == 1:
        elements = elements[:, None]
    count, comps = elements.shape
    max_width = 1 << (int(max_width).bit_length() - 1)
    width = min(1 << max(0, count - 1).bit_length(), max_width)  # count 0 → one texel
    height = max(1, -(-count // width))
    if height > max_width:
        raise ValueError(f"{count} elements do not fit a {max_width}×{max_width} texture")
    data = np.zeros((height * width, comps), dtype=elements.dtype)
    data[:count] = elements
    dtype = "f4" if elements.dtype == np.float32 else "u4"
    return PackedTexture(data.reshape(height, width, comps), dtype)


@dataclass
class PackedScene:
    """Textures and uniforms for one frame, independent of any GL context."""

    textures: dict[str, PackedTexture]
    uniforms: dict[str, object] = field(default_factory=dict)

    @property
    def nbytes(self) -> int:
        return sum(t.data.nbytes for t in self.textures.values())


def equal_radii(scene: Scene) -> bool:
    """Whether every sphere has the same float32 radius: the 16-byte sphere records."""
    r = scene.sphere_radii.astype(np.float32)
    return bool(len(r) == 0 or (r == r[0]).all())


def has_pbr(scene: Scene) -> bool:
    """Whether a material of the scene is of the PBR kind: the PBR data format (every material's
    record then holds its kind, :data:`MATERIAL_STRIDE` texels each, in the u_materials texture)."""
    return any(isinstance(m, PbrMaterial) for m in scene.materials)


def material_texture(scene: Scene) -> bool:
    """Whether the tracer reads the materials from u_materials: the scene has more than its uniform
    array holds, or PBR records (too large for the uniform array: WebGL2's 224 vectors)."""
    return len(scene.materials) > MAX_UNIFORM_MATERIALS or has_pbr(scene)


def pack_materials(materials) -> np.ndarray:
    """float32 (texels, 4): the material records. Phong materials alone: Phong records of
    MATERIAL_TEXELS texels; with a PBR one: MATERIAL_STRIDE texels each, the kind's id in texel 0's
    x and its kind's record after it (docs/FORMATS.md, "GPU records")."""
    if not any(isinstance(m, PbrMaterial) for m in materials):
        return pack_records(materials, Material)
    out = np.zeros((len(materials), MATERIAL_STRIDE, 4), dtype=np.float32)
    for i, m in enumerate(materials):
        rec = pack_records([m], type(m))
        out[i, 0, 0] = KIND_IDS[m.KIND]
        out[i, 1 : 1 + len(rec)] = rec
    return out.reshape(-1, 4)


def sphere_keys(scene: Scene, ids: np.ndarray | None = None) -> np.ndarray:
    """The record keys (id | material << SPHERE_MAT_SHIFT) of spheres ``ids`` (default: all,
    in id order), uint32; without the leaf's ``last`` flag."""
    ids = np.arange(scene.n_spheres, dtype=np.int64) if ids is None else ids
    return ids.astype(np.uint32) | (scene.sphere_materials[ids].astype(np.uint32) << np.uint32(SPHERE_MAT_SHIFT))


def sphere_records(scene: Scene, order: np.ndarray, last: np.ndarray | None = None) -> np.ndarray:
    """The records of spheres ``order`` (scene ids, in the order a method's leaves list them),
    ``last`` flagging the last record of each leaf: uint32 (k, 4), or (2k, 4) when the radii
    differ (the module's docstring)."""
    ids = np.asarray(order, dtype=np.int64).reshape(-1)
    k = len(ids)
    key = sphere_keys(scene, ids)
    if last is not None:
        key |= np.where(np.asarray(last, dtype=bool), np.uint32(SPHERE_LAST), np.uint32(0))
    centres = np.ascontiguousarray(scene.sphere_centers[ids], dtype=np.float32).view(np.uint32)
    if equal_radii(scene):
        out = np.empty((k, 4), dtype=np.uint32)
        out[:, :3] = centres
        out[:, 3] = key
        return out
    out = np.zeros((k, 2, 4), dtype=np.uint32)
    out[:, 0, :3] = centres
    out[:, 0, 3] = np.ascontiguousarray(scene.sphere_radii[ids], dtype=np.float32).view(np.uint32)
    out[:, 1, 0] = key
    return out.reshape(2 * k, 4)


def unpack_sphere_records(records: np.ndarray, equal: bool) -> dict[str, np.ndarray]:
    """The inverse of :func:`sphere_records` (tests and the CPU mirrors): ``records`` uint32
    (…, 4) as packed (padding included), ``equal``: the EQUAL_RADII format (then ``radius``
    is NaN: it is the uniform's)."""
    r = np.asarray(records, dtype=np.uint32).reshape(-1, 4)
    if equal:
        centre, radius, key = r[:, :3].copy().view(np.float32), np.full(len(r), np.nan, np.float32), r[:, 3]
    else:
        pairs = r[: len(r) // 2 * 2].reshape(-1, 2, 4)
        centre, radius, key = (
            pairs[:, 0, :3].copy().view(np.float32),
            pairs[:, 0, 3].copy().view(np.float32),
            pairs[:, 1, 0],
        )
    return {
        "centre": centre,
        "radius": radius,
        "id": (key & np.uint32(SPHERE_ID_MASK)).astype(np.int64),
        "material": ((key >> np.uint32(SPHERE_MAT_SHIFT)) & np.uint32(SPHERE_MAT_MASK)).astype(np.int64),
        "last": (key & np.uint32(SPHERE_LAST)) != 0,
    }


def has_triangles(scene: Scene) -> bool:
    """The TRIANGLES data format: the scene has triangles (meshes)."""
    return scene.n_triangles > 0


def smooth_triangles(scene: Scene) -> bool:
    """The SMOOTH_TRIANGLES data format: some mesh has vertex normals."""
    return bool(scene.n_triangles and np.asarray(scene.triangle_smooth, dtype=bool).any())


def has_shapes(scene: Scene) -> bool:
    """The SHAPES data format: the scene has analytic shapes."""
    return scene.n_shapes > 0


def leaf_records(scene: Scene, order: np.ndarray, last: np.ndarray | None = None) -> np.ndarray:
    """The records of tree primitives ``order`` (tree indices in leaf order: ``i < n_spheres``
    sphere ``i``, then the triangles, then the analytic shapes, renderer/accel/primitives.py):
    a sphere's record as :func:`sphere_records`, a triangle's or a shape's slot of the same
    size (the module's docstring). Without either this is :func:`sphere_records` itself."""
    order = np.asarray(order, dtype=np.int64).reshape(-1)
    n = scene.n_spheres
    if not scene.n_triangles and not scene.n_shapes:
        return sphere_records(scene, order, last)
    is_tri = order >= n
    # Spheres' records with a placeholder id where a triangle goes, then the slots overwritten.
    out = sphere_records(scene, np.where(is_tri, 0, order), last) if n else None
    per = 1 if equal_radii(scene) else 2
    if out is None:
        out = np.zeros((per * len(order), 4), dtype=np.uint32)
    key = (order - n).astype(np.uint32) | np.uint32(TRI_SLOT)
    first_shape = n + scene.n_triangles
    is_shape = order >= first_shape
    key = np.where(is_shape, (order - first_shape).astype(np.uint32) | np.uint32(SHAPE_SLOT), key)
    if last is not None:
        key |= np.where(np.asarray(last, dtype=bool), np.uint32(SPHERE_LAST), np.uint32(0))
    rows = np.flatnonzero(is_tri)  # (the shapes' slots too: their tree indices come after the triangles')
    if per == 1:
        out[rows] = 0
        out[rows, 3] = key[rows]
    else:
        out[2 * rows] = 0
        out[2 * rows + 1] = 0
        out[2 * rows + 1, 0] = key[rows]
    return out


def shape_records(scene: Scene) -> np.ndarray:
    """``u_shapes``: uint32 (3 S, 4), the module's docstring."""
    p = np.asarray(scene.shapes.params, dtype=np.float64).reshape(-1, 12)
    out = np.ascontiguousarray(p, dtype=np.float32).view(np.uint32).reshape(-1, 3, 4).copy()
    out[:, 2, 3] = np.asarray(scene.shapes.material, dtype=np.uint32)
    return out.reshape(-1, 4)


def pack_shapes(scene: Scene, max_width: int = DEFAULT_TEXTURE_WIDTH, count: bool = True) -> PackedScene:
    """What :data:`SHAPE_BINDINGS` read: nothing for a scene without shapes (its variant declares
    none of them); ``count`` False leaves out ``u_num_shapes`` (a tree's leaves say where its
    shapes are)."""
    if not scene.n_shapes:
        return PackedScene({}, {})
    uniforms: dict[str, object] = {SHAPE_BASE.name: int(scene.shape_id_base)}
    if count:
        uniforms[NUM_SHAPES.name] = int(scene.n_shapes)
    return PackedScene({SHAPES.name: wrap_rows(shape_records(scene), max_width)}, uniforms)


def triangle_records(scene: Scene) -> np.ndarray:
    """``u_triangles``: uint32 (3 T, 4), the module's docstring."""
    c = np.asarray(scene.triangle_corners, dtype=np.float64).reshape(-1, 3, 3)
    degenerate = np.asarray(scene.triangle_degenerate, dtype=bool)
    out = np.zeros((len(c), 3, 4), dtype=np.uint32)
    out[:, :, :3] = np.ascontiguousarray(c, dtype=np.float32).view(np.uint32)
    out[:, 0, 3] = np.asarray(scene.triangle_materials, dtype=np.uint32) | np.where(
        degenerate, np.uint32(TRI_DEGENERATE), np.uint32(0)
    )
    return out.reshape(-1, 4)


def triangle_normal_records(scene: Scene) -> np.ndarray:
    """``u_tri_normals``: uint32 (3 T, 4), unit vertex normals (float64 normalised, as the
    reference does) and w = 1 for a smooth triangle."""
    vn = np.asarray(scene.triangle_normals, dtype=np.float64).reshape(-1, 3, 3)
    length = np.linalg.norm(vn, axis=2, keepdims=True)
    vn = vn / np.where(length > 0, length, 1.0)
    out = np.zeros((len(vn), 3, 4), dtype=np.uint32)
    out[:, :, :3] = np.ascontiguousarray(vn, dtype=np.float32).view(np.uint32)
    out[:, :, 3] = np.asarray(scene.triangle_smooth, dtype=np.uint32)[:, None]
    return out.reshape(-1, 4)


def pack_triangles(scene: Scene, max_width: int = DEFAULT_TEXTURE_WIDTH, count: bool = True) -> PackedScene:
    """What :data:`TRIANGLE_BINDINGS` read: nothing for a scene without triangles (its variant
    declares none of them), the normals only when some mesh is smooth; ``count`` False
    leaves out ``u_num_triangles`` (a tree's leaves say where its triangles are)."""
    if not scene.n_triangles:
        return PackedScene({}, {})
    textures = {TRIANGLES.name: wrap_rows(triangle_records(scene), max_width)}
    if smooth_triangles(scene):
        textures[TRI_NORMALS.name] = wrap_rows(triangle_normal_records(scene), max_width)
    uniforms: dict[str, object] = {TRI_BASE.name: int(scene.triangle_id_base)}
    if count:
        uniforms[NUM_TRIANGLES.name] = int(scene.n_triangles)
    return PackedScene(textures, uniforms)


def merged(*parts: PackedScene) -> PackedScene:
    """One packed scene of several (names are distinct)."""
    out = PackedScene({}, {})
    for p in parts:
        out.textures.update(p.textures)
        out.uniforms.update(p.uniforms)
    return out


def leaf_ends(starts: np.ndarray, counts: np.ndarray, total: int) -> np.ndarray:
    """The ``last`` flags of :func:`sphere_records` for leaves of ``counts`` records at ``starts``."""
    last = np.zeros(total, dtype=bool)
    counts = np.asarray(counts, dtype=np.int64)
    last[(np.asarray(starts, dtype=np.int64) + counts - 1)[counts > 0]] = True
    return last


def box_uniform(lo, hi) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """A box as two vec3 uniforms; the empty box of no primitives (+inf, −inf) as the finite
    empty box (1, 1, 1)–(−1, −1, −1), which JSON can carry to a device (no ray meets either;
    the traversals do not start without primitives anyway)."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        return (1.0, 1.0, 1.0), (-1.0, -1.0, -1.0)
    return tuple(float(x) for x in lo), tuple(float(x) for x in hi)


def pack_primitives(scene: Scene, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedScene:
    """Spheres, materials, planes and lights (what every method reads): the materials as a
    texture and as the uniform array, the common radius of EQUAL_RADII records."""
    spheres = np.concatenate([scene.sphere_centers, scene.sphere_radii[:, None]], axis=1).astype(np.float32)
    mats = pack_materials(scene.materials)
    textures = {
        SPHERES.name: wrap_rows(spheres, max_width),
        SPHERE_MAT.name: wrap_rows(scene.sphere_materials.astype(np.uint32), max_width),
        MATERIALS.name: wrap_rows(mats, max_width),
    }
    # Only a scene with them packs its emission and environment: every other scene's data stay as before.
    if any(m.emits for m in scene.materials):
        textures[EMISSION.name] = wrap_rows(
            np.array([(*m.emission, 0.0) for m in scene.materials], np.float32), max_width
        )
    planes = scene.planes
    lights = scene.lights
    vecs = np.zeros((MATERIAL_TEXELS * MAX_UNIFORM_MATERIALS, 4), dtype=np.float32)
    vecs[: min(len(mats), len(vecs))] = mats[: len(vecs)]
    radius = float(scene.sphere_radii.astype(np.float32)[0]) if scene.n_spheres and equal_radii(scene) else 0.0
    uniforms: dict[str, object] = {
        MATERIAL_VECS.name: [tuple(float(x) for x in v) for v in vecs],
        SPHERE_RADIUS.name: radius,
        NUM_SPHERES.name: scene.n_spheres,
        NUM_PLANES.name: len(planes),
        PLANE_POINT.name: _fixed([p.point for p in planes], MAX_PLANES, (0.0, 0.0, 0.0)),
        PLANE_NORMAL.name: _fixed([p.normal for p in planes], MAX_PLANES, (0.0, 1.0, 0.0)),
        PLANE_MAT.name: _fixed([p.material for p in planes], MAX_PLANES, 0),
        NUM_LIGHTS.name: len(lights),
        LIGHT_POS.name: _fixed([light.position for light in lights], MAX_LIGHTS, (0.0, 0.0, 0.0)),
        LIGHT_COLOR.name: _fixed([light.color for light in lights], MAX_LIGHTS, (0.0, 0.0, 0.0)),
    }
    if any(scene.environment):
        uniforms[ENVIRONMENT.name] = tuple(float(x) for x in scene.environment)
    env = scene.environment_map
    if env is not None:
        textures[ENV_MAP.name], textures[ENV_CDF.name] = env_textures(env, max_width)
        uniforms[ENV_SIZE.name] = (env.width, env.height)
        uniforms[ENV_SCALE.name] = env.scale
        uniforms[ENV_U_OFFSET.name] = env.rotation_deg / 360.0
    return PackedScene(textures, uniforms)


# The packed textures of the environment images in use (up to 128 MiB each: packed once, not per
# frame), held as long as their image is (a scene in the session cache).
_ENV_PACKED: weakref.WeakKeyDictionary[EnvironmentMap, dict[int, tuple[PackedTexture, PackedTexture]]] = (
    weakref.WeakKeyDictionary()
)
_ENV_LOCK = threading.Lock()


def env_textures(env: EnvironmentMap, max_width: int = DEFAULT_TEXTURE_WIDTH) -> tuple[PackedTexture, PackedTexture]:
    """``u_env_map`` (the texels) and ``u_env_cdf`` (the conditional CDFs, then the marginal) of
    ``env``, wrapped into rows of at most ``max_width``."""
    with _ENV_LOCK:
        got = _ENV_PACKED.get(env, {}).get(max_width)
    if got is None:
        cond, marg = env.sampling_tables
        got = (
            wrap_rows(env.texels.reshape(-1, 3), max_width),
            wrap_rows(np.concatenate([cond.reshape(-1), marg]).astype(np.float32), max_width),
        )
        for t in got:
            t.data.setflags(write=False)  # shared by every frame of the image
        with _ENV_LOCK:
            _ENV_PACKED.setdefault(env, {})[max_width] = got
    return got


def light_scale(scene: Scene) -> float:
    """A point light's radiant intensity per unit of its ``color`` in the path integrator: π·d²
    with d the camera's distance to its target. A Lambertian surface of albedo ρ facing the light
    at distance d then has radiance ρ·color, what Whitted's diffuse term gives it at any distance:
    a thesis scene keeps its exposure when the integrator is switched (docs/SHADING.md)."""
    d = float(np.linalg.norm(np.subtract(scene.camera.target, scene.camera.position)))
    return math.pi * d * d


def emitter_uniforms(scene: Scene) -> dict[str, object]:
    """The emitting spheres the path integrator samples: the first MAX_SAMPLED_SPHERES by id."""
    emits = np.array([m.emits for m in scene.materials], dtype=bool)
    ids = np.flatnonzero(emits[scene.sphere_materials])[:MAX_SAMPLED_SPHERES] if scene.n_spheres else np.zeros(0, int)
    spheres = [(*scene.sphere_centers[i].tolist(), float(scene.sphere_radii[i])) for i in ids]
    radiance = [tuple(scene.materials[scene.sphere_materials[i]].emission) for i in ids]
    out = {
        NUM_EMITTERS.name: len(ids),
        EMITTER_LAST.name: int(ids[-1]) if len(ids) else -1,
        EMITTER_SPHERE.name: _fixed(spheres, MAX_SAMPLED_SPHERES, (0.0, 0.0, 0.0, 1.0)),
        EMITTER_RADIANCE.name: _fixed(radiance, MAX_SAMPLED_SPHERES, (0.0, 0.0, 0.0)),
    }
    tris = np.zeros((0, 3, 3))
    mats = np.zeros(0, dtype=np.int64)
    if scene.n_triangles:
        lit = np.flatnonzero(emits[np.asarray(scene.triangle_materials, dtype=np.int64)])
        tris = np.asarray(scene.triangle_corners, dtype=np.float64)[lit]
        mats = np.asarray(scene.triangle_materials)[lit]
        area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
        keep = area > 0.0
        tris, mats = tris[keep], mats[keep]
        if len(tris) > MAX_SAMPLED_TRIANGLES:
            tris, mats = tris[:0], mats[:0]
    area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    total = float(area.sum())
    cdf = (np.cumsum(area) / total).tolist() if len(area) else []
    if cdf:
        cdf[-1] = 1.0
    vec = lambda a: [tuple(float(x) for x in v) for v in a]
    out.update(
        {
            NUM_EMIT_TRIS.name: len(tris),
            EMIT_TRI_AREA.name: total,
            EMIT_TRI_V0.name: _fixed(vec(tris[:, 0]), MAX_SAMPLED_TRIANGLES, (0.0, 0.0, 0.0)),
            EMIT_TRI_E1.name: _fixed(vec(tris[:, 1] - tris[:, 0]), MAX_SAMPLED_TRIANGLES, (0.0, 0.0, 0.0)),
            EMIT_TRI_E2.name: _fixed(vec(tris[:, 2] - tris[:, 0]), MAX_SAMPLED_TRIANGLES, (0.0, 0.0, 0.0)),
            EMIT_TRI_RADIANCE.name: _fixed(
                [tuple(scene.materials[int(m)].emission) for m in mats], MAX_SAMPLED_TRIANGLES, (0.0, 0.0, 0.0)
            ),
            EMIT_TRI_CDF.name: _fixed([float(c) for c in cdf], MAX_SAMPLED_TRIANGLES, 2.0),
        }
    )
    out.update(_patch_uniforms(scene, emits))
    return out


PATCH_SIDE, PATCH_DISK, PATCH_TORUS = 0, 1, 2  # the kinds of u_emit_patch_c.y


def shape_patches(scene: Scene, emits: np.ndarray) -> list[tuple[tuple, tuple, tuple, tuple]]:
    """The surfaces of the scene's emitting analytic shapes, in id order, each as next-event
    estimation samples it: ((origin, r0), (axis, r1), (height, kind, area, 0), emission). A cylinder
    or cone is its side and, when closed, its caps (a cap's normal points out: −axis at the base,
    +axis at the top); a disk is an annulus; a torus is whole. Surfaces of no area are left out."""
    sh = scene.shapes
    out: list[tuple[tuple, tuple, tuple, tuple]] = []
    for i in np.flatnonzero(emits[np.asarray(sh.material, dtype=np.int64)]) if len(sh) else ():
        p = sh.params[i]
        o, r0, a, r1, h = p[0:3], float(p[3]), p[4:7], float(p[7]), float(p[8])
        radiance = tuple(float(x) for x in scene.materials[int(sh.material[i])].emission)
        kind = int(sh.kind[i])
        parts: list[tuple[np.ndarray, float, np.ndarray, float, float, int, float]] = []
        if kind in (SHAPE_CYLINDER, SHAPE_CONE):
            parts.append((o, r0, a, r1, h, PATCH_SIDE, math.pi * (r0 + r1) * math.hypot(h, r1 - r0)))
            if p[9] != 0.0:
                parts.append((o, r0, -a, 0.0, 0.0, PATCH_DISK, math.pi * r0 * r0))
                parts.append((o + h * a, r1, a, 0.0, 0.0, PATCH_DISK, math.pi * r1 * r1))
        elif kind == SHAPE_DISK:
            parts.append((o, r0, a, r1, 0.0, PATCH_DISK, math.pi * (r0 * r0 - r1 * r1)))
        else:
            parts.append((o, r0, a, r1, 0.0, PATCH_TORUS, 4.0 * math.pi * math.pi * r0 * r1))
        for po, pr0, pa, pr1, ph, pk, area in parts:
            if area > 0.0:
                out.append(
                    (
                        (*(float(x) for x in po), pr0),
                        (*(float(x) for x in pa), pr1),
                        (ph, float(pk), area, 0.0),
                        radiance,
                    )
                )
    return out


def _patch_uniforms(scene: Scene, emits: np.ndarray) -> dict[str, object]:
    patches = shape_patches(scene, emits)
    if len(patches) > MAX_SAMPLED_SHAPE_PATCHES:
        patches = []
    area = np.array([c[2] for _, _, c, _ in patches], dtype=np.float64)
    total = float(area.sum())
    cdf = (np.cumsum(area) / total).tolist() if len(area) else []
    if cdf:
        cdf[-1] = 1.0
    n = MAX_SAMPLED_SHAPE_PATCHES
    return {
        NUM_EMIT_PATCHES.name: len(patches),
        EMIT_PATCH_AREA.name: total,
        EMIT_PATCH_A.name: _fixed([a for a, _, _, _ in patches], n, (0.0, 0.0, 0.0, 0.0)),
        EMIT_PATCH_B.name: _fixed([b for _, b, _, _ in patches], n, (0.0, 0.0, 1.0, 0.0)),
        EMIT_PATCH_C.name: _fixed([c for _, _, c, _ in patches], n, (0.0, 0.0, 0.0, 0.0)),
        EMIT_PATCH_RADIANCE.name: _fixed([e for _, _, _, e in patches], n, (0.0, 0.0, 0.0)),
        EMIT_PATCH_CDF.name: _fixed([float(c) for c in cdf], n, 2.0),
    }


def frame_uniforms(scene: Scene, min_weight: float) -> dict[str, object]:
    """The uniforms of a frame beside the scene's (:func:`pack_primitives`) and the method's packs:
    the ε cut-off and the path integrator's light terms. The server's frames upload them and the
    device-data carries them, so a browser's paths are the server's."""
    return {
        MIN_WEIGHT.name: float(min_weight),
        LIGHT_SCALE.name: light_scale(scene),
        **emitter_uniforms(scene),
    }


def path_uniforms(start: int, count: int) -> dict[str, object]:
    """The path integrator's pass uniforms: samples ``start … start + count − 1`` of every pixel."""
    return {SAMPLE_START.name: int(start), SAMPLE_COUNT.name: int(count)}


def _fixed(items: list, length: int, filler) -> list:
    """Pad a uniform array's values to the fixed length the shader declares."""
    return [tuple(x) if isinstance(x, tuple) else x for x in items] + [filler] * (length - len(items))


def camera_uniforms(camera: Camera, width: int, height: int) -> dict[str, object]:
    """The camera's uniforms for a ``width × height`` render target (pixels).

    The ray through pixel centre (x, y), row 0 at the top, is
    ``normalize(forward + u·right + v·up)`` with ``u = (2x/W − 1)·half_extent.x`` and
    ``v = (1 − 2y/H)·half_extent.y`` (``docs/SHADING.md``); the shader, the ray engines
    and the device client all take these numbers from here.
    """
    right, up, forward = camera.basis()
    s = math.tan(math.radians(camera.fov_y) / 2.0)
    return {
        CAM_POS.name: tuple(camera.position),
        CAM_RIGHT.name: tuple(right),
        CAM_UP.name: tuple(up),
        CAM_FORWARD.name: tuple(forward),
        HALF_EXTENT.name: (s * width / height, s),
        RESOLUTION.name: (float(width), float(height)),
        TARGET_DISTANCE.name: float(np.linalg.norm(np.subtract(camera.target, camera.position))),
    }


def primary_rect(scene: Scene, width: int, height: int, margin: int = 2) -> tuple[int, int, int, int] | None:
    """The window rectangle ``(x, y, w, h)`` (GL coordinates: rows from the bottom) of a
    ``width × height`` grid of primary rays outside which no ray can meet a sphere (or a
    triangle): the bounding rectangle of the spheres' (and triangles') box projected through the camera
    (:func:`camera_uniforms`' pixel mapping), widened by ``margin`` pixels and clipped to
    the grid; ``(0, 0, 0, 0)`` without spheres. None when there is no such bound: a corner
    of the box at or behind the camera's plane (the camera inside or beside the box).

    The box is the float64 one widened by a relative 1e-6, so it holds every sphere as
    float32 stores it; the margin covers the float32 rounding of the rays' directions."""
    if scene.n_spheres == 0 and scene.n_triangles == 0 and scene.n_shapes == 0:
        return (0, 0, 0, 0)
    if scene.n_triangles == 0 and scene.n_shapes == 0:
        c, r = scene.sphere_centers, scene.sphere_radii[:, None]
        slack = 1e-6 * (np.abs(c) + r).max()
        lo, hi = (c - r).min(axis=0) - slack, (c + r).max(axis=0) + slack
    else:
        # The triangles' corners too (a triangle is their convex hull), with the same slack.
        parts = [np.asarray(scene.triangle_corners, dtype=np.float64).reshape(-1, 3)]
        if scene.n_shapes:  # (an analytic shape's exact box: its corners)
            parts.append(shape_bounds(scene.shapes).reshape(-1, 3))
        if scene.n_spheres:
            c, r = scene.sphere_centers, scene.sphere_radii[:, None]
            parts += [c - r, c + r]
        pts = np.concatenate(parts)
        slack = 1e-6 * np.abs(pts).max()
        lo, hi = pts.min(axis=0) - slack, pts.max(axis=0) + slack
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    right, up, forward = scene.camera.basis()
    v = corners - np.asarray(scene.camera.position, dtype=np.float64)
    z = v @ forward
    if not (z > 1e-6 * np.linalg.norm(v, axis=1)).all():
        return None
    s = math.tan(math.radians(scene.camera.fov_y) / 2.0)
    px = ((v @ right) / z / (s * width / height) + 1.0) * width / 2.0  # u = (2 px / W − 1) · hx
    row = (1.0 - (v @ up) / z / s) * height / 2.0  # v = (1 − 2 row / H) · hy
    x0 = max(0, math.floor(px.min()) - margin)
    x1 = min(width, math.ceil(px.max()) + margin)
    y0 = max(0, math.floor(height - row.max()) - margin)  # GL rows grow upwards
    y1 = min(height, math.ceil(height - row.min()) + margin)
    if x1 <= x0 or y1 <= y0:
        return (0, 0, 0, 0)
    return (x0, y0, x1 - x0, y1 - y0)


def frame_regions(
    scene: Scene, width: int, height: int, planes: bool, margin: int = 2
) -> list[tuple[int, int, int, int, bool]] | None:
    """A partition of a ``width × height`` frame into rectangles ``(x, y, w, h, tracer)``
    (GL coordinates, rows from the bottom): ``tracer`` False where no primary ray can meet
    a sphere (outside :func:`primary_rect`) — and, with ``planes``, no plane either — so
    that the background variant (the shader without its traversal) draws the same pixels.
    ``planes`` is for frames whose hits spawn rays (colour, recursion): there a pixel may
    skip the tracer only if its ray meets nothing at all. None: no such split (every pixel
    to the tracer).

    A plane through P with normal N is met by the ray of direction d from the camera C when
    t = dot(P − C, N) / dot(d, N) > 0: never when the signs differ, a linear condition on
    the image plane, so a rectangle misses the plane when its corners (widened by
    ``margin`` pixels) do, with a relative slack; a camera (nearly) on a plane splits nothing."""
    rect = primary_rect(scene, width, height, margin)
    if rect is None:
        return None
    sx, sy, sw, sh = rect
    miss = np.ones(height, dtype=bool)  # GL row y: its whole row may skip the tracer
    if planes and scene.planes:
        right, up, forward = scene.camera.basis()
        cam = np.asarray(scene.camera.position, dtype=np.float64)
        s = math.tan(math.radians(scene.camera.fov_y) / 2.0)
        hx, hy = s * width / height, s
        y = np.arange(height, dtype=np.float64)
        rows = np.stack([height - (y + 0.5 + margin), height - (y + 0.5 - margin)], axis=1)  # from the top
        cols = np.array([0.5 - margin, width - 0.5 + margin])
        u = (2.0 * cols / width - 1.0) * hx
        v = (1.0 - 2.0 * rows / height) * hy  # (H, 2)
        for p in scene.planes:
            n = np.asarray(p.normal, dtype=np.float64)
            side = float(np.dot(np.asarray(p.point, dtype=np.float64) - cam, n))
            if abs(side) <= 1e-6 * (np.abs(cam).max() + np.abs(p.point).max() + 1.0):
                return None
            dn = (forward @ n) + u[None, :, None] * (right @ n) + v[:, None, :] * (up @ n)  # (H, 2, 2)
            norm = 1.0 + abs(hx) + abs(hy)
            miss &= (np.sign(side) * dn < -1e-5 * norm).all(axis=(1, 2))
    out: list[tuple[int, int, int, int, bool]] = []
    y0 = 0
    while y0 < height:  # runs of rows of one kind
        y1 = y0 + 1
        while y1 < height and miss[y1] == miss[y0]:
            y1 += 1
        if not miss[y0]:
            out.append((0, y0, width, y1 - y0, True))
        else:
            a, b = max(y0, sy), min(y1, sy + sh)
            if sw <= 0 or sh <= 0 or b <= a:
                out.append((0, y0, width, y1 - y0, False))
            else:
                out += [
                    (0, y0, width, a - y0, False),
                    (0, b, width, y1 - b, False),
                    (0, a, sx, b - a, False),
                    (sx + sw, a, width - sx - sw, b - a, False),
                    (sx, a, sw, b - a, True),
                ]
        y0 = y1
    return [r for r in out if r[2] > 0 and r[3] > 0]


def pass_uniforms(
    scale: int = 1, sub: tuple[int, int] = (0, 0), cell: tuple[float, float] = (0.5, 0.5)
) -> dict[str, object]:
    """The pass uniforms: the pixel centres (scale 1), or sub-pixel ``sub`` = (sx, sy) of a
    ``scale × scale`` grid per pixel (sy counts from the bottom, as GL's rows do); ``cell``: where
    in its sub-pixel (0 … 1 each side) the ray goes, the centre but in a jittered slice
    (:func:`subpixel_cell`)."""
    return {PASS_SCALE.name: float(scale), PASS_OFFSET.name: (sub[0] + cell[0], sub[1] + cell[1])}


# The R2 sequence's steps (Roberts 2018, the plastic number g: g³ = g + 1): its points
# frac(0.5 + n (1/g, 1/g²)) fill the unit square evenly for every prefix, so any count of slices
# spreads its samples over each sub-pixel, and point 0 is the centre.
_PLASTIC = 1.324717957244746
R2_STEP = (1.0 / _PLASTIC, 1.0 / _PLASTIC**2)


def subpixel_cell(slice_index: int) -> tuple[float, float]:
    """Where in its sub-pixel (0 … 1 each side) slice ``slice_index`` of a Whitted accumulation
    traces every sub-pixel of every pixel: the R2 sequence's point, (0.5, 0.5) for slice 0 (so a
    first slice is the frame of cell centres, bit for bit)."""
    n = int(slice_index)
    return ((0.5 + n * R2_STEP[0]) % 1.0, (0.5 + n * R2_STEP[1]) % 1.0)


def glsl_header() -> str:
    """The scene's layout constants (the tracer's and the ray engines' headers, after ``#version``), and
    the material record's accessors (``material_color(m)``…, renderer.materials.glsl_accessors)."""
    return (
        f"#define MAX_PLANES {MAX_PLANES}\n#define MAX_LIGHTS {MAX_LIGHTS}\n#define MATERIAL_TEXELS {MATERIAL_TEXELS}\n"
        + glsl_accessors(Material)
    )


def tracer_constants() -> str:
    """The tracer's own constants beside :func:`glsl_header`: the uniform material array,
    uniform blocks and the sphere records' key."""
    return (
        f"#define MATERIAL_VECS {MATERIAL_TEXELS * MAX_UNIFORM_MATERIALS}\n"
        f"#define BLOCK_RECORDS {BLOCK_RECORDS}\n"
        f"#define SPHERE_ID_MASK {SPHERE_ID_MASK}u\n"
        f"#define SPHERE_MAT_SHIFT {SPHERE_MAT_SHIFT}u\n"
        f"#define SPHERE_MAT_MASK {SPHERE_MAT_MASK}u\n"
        f"#define SPHERE_LAST {SPHERE_LAST}u\n"
    )


def pbr_constants() -> str:
    """The PBR data format's constants and the PBR record's accessors ``pbr_<name>(m)``: emitted only
    into variants of scenes with a PBR material (no other variant's text changes)."""
    return (
        f"#define MATERIAL_STRIDE {MATERIAL_STRIDE}\n#define PBR_AMBIENT {WHITTED_AMBIENT!r}\n"
        + "".join(f"#define KIND_{name.upper()} {i}\n" for name, i in KIND_IDS.items())
        + glsl_accessors(PbrMaterial, "pbr")
    )


def path_constants() -> str:
    """The path integrator's constants: emitted only into its variants (no other's text changes)."""
    return (
        f"#define MAX_SAMPLED_SPHERES {MAX_SAMPLED_SPHERES}\n#define MAX_SAMPLED_TRIANGLES {MAX_SAMPLED_TRIANGLES}\n"
        f"#define MAX_SAMPLED_SHAPE_PATCHES {MAX_SAMPLED_SHAPE_PATCHES}\n"
        f"#define PATCH_SIDE {PATCH_SIDE}\n#define PATCH_DISK {PATCH_DISK}\n#define PATCH_TORUS {PATCH_TORUS}\n"
    )


def shape_constants() -> str:
    """The shape records' constants: emitted only into variants with the SHAPES data format."""
    return (
        f"#define SHAPE_SLOT {SHAPE_SLOT}u\n"
        f"#define SHAPE_INDEX_MASK {SHAPE_INDEX_MASK}u\n"
        f"#define SHAPE_MAT_MASK {SHAPE_MAT_MASK}u\n"
        f"#define SHAPE_TEXELS {SHAPE_TEXELS}\n"
    )


def triangle_constants() -> str:
    """The triangle records' constants: emitted only into variants with the TRIANGLES data
    format, so a sphere-only variant's text stays what it was before meshes."""
    return (
        f"#define TRI_SLOT {TRI_SLOT}u\n"
        f"#define TRI_INDEX_MASK {TRI_INDEX_MASK}u\n"
        f"#define TRI_DEGENERATE {TRI_DEGENERATE}u\n"
        f"#define TRIANGLE_TEXELS {TRIANGLE_TEXELS}\n"
    )

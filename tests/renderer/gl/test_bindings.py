"""Every GPU name once: what is packed for a shader variant is what the variant reads.

The shader header declares a variant's textures, uniforms and record arrays from the
layout constants (renderer/gpu_layout.py, renderer/accel/*_layout.py) and the renderer
uploads exactly those. Here, for every method and mode, each uploaded texture or uniform
must be an *active* uniform of the compiled program, and each record array the variant
reads from a uniform block an active uniform *block* of that name (a texture otherwise):
a binding packed for nothing, or declared under a name the shader does not use, fails —
with the feature sets, the data formats (EQUAL_RADII, MATERIAL_TEXTURE), the compiled-in
counts, every record array in a block or none, and the RGBA8 image.
"""

from __future__ import annotations

import itertools

import pytest

from renderer import gpu_layout
from renderer.gpu_layout import Variant
from renderer.methods import METHODS
from renderer.modes import SINGLE_PASS_MODES
from renderer.scenarios import mesh_scene, scenario
from renderer.scene import Scene
from renderer.settings import RenderSettings
from renderer.shader_source import known_bindings, tracer_bindings

FEATURES = ("NO_REFLECTION", "NO_TRANSMISSION", "NO_LIGHTS")
FEATURE_SETS = [tuple(f for f, on in zip(FEATURES, bits) if on) for bits in itertools.product((0, 1), repeat=3)]
# Data formats and compiled-in counts, each with some of the removals (features' order).
SHAPES = [
    ("EQUAL_RADII",),
    ("MATERIAL_TEXTURE",),
    ("NO_SPLIT", "PLANES_1", "LIGHTS_2", "EQUAL_RADII"),
    ("NO_LIGHTS", "PLANES_0", "MATERIAL_TEXTURE"),
    ("NO_REFLECTION", "PLANES_3", "LIGHTS_1"),
]
ONE_PASS = [name for name, m in METHODS.items() if not m.capabilities.multi_pass]
MULTI_PASS = [name for name, m in METHODS.items() if m.capabilities.multi_pass]


def active(prog) -> set[str]:
    return {name.split("[")[0] for name in prog}


def check_variant(gl_renderer, variant: Variant) -> None:
    prog, _ = gl_renderer.program(
        variant.method,
        variant.mode,
        variant.depth,
        variant.features,
        variant.blocks,
        variant.image_only,
        variant.spheres,
    )
    declared = full = {b.name for b in tracer_bindings(variant)}
    if variant.image_only and variant.mode == "heat" and METHODS[variant.method].capabilities.tests_every_sphere:
        # Brute force's heat image is n sphere tests whatever the ray, and an image-only
        # variant writes nothing else: the compiler drops the ray and what makes it.
        declared = {
            n
            for n in declared
            if not n.startswith(
                (
                    "u_cam_",
                    "u_plane_",
                    "u_num_planes",
                    "u_half_",
                    "u_resolution",
                    "u_pass_",
                    "u_bf_",
                    "u_sphere_",
                    "u_tri",
                )
            )
        }
    assert declared <= active(prog), (variant, sorted(declared - active(prog)))
    assert active(prog) & known_bindings() <= full, variant
    for b in tracer_bindings(variant):
        if b.records:
            if b.name not in active(prog):
                continue
            kind = "UniformBlock" if b.name in variant.blocks else "Uniform"
            assert type(prog[b.name]).__name__ == kind, (variant, b.name, type(prog[b.name]))


# The triangles' data formats (issue #20), for the methods that trace meshes on the GPU.
TRIANGLE_SHAPES = [
    ("TRIANGLES",),
    ("EQUAL_RADII", "TRIANGLES", "SMOOTH_TRIANGLES"),
    ("NO_SPLIT", "PLANES_1", "LIGHTS_1", "MATERIAL_TEXTURE", "TRIANGLES", "SMOOTH_TRIANGLES"),
]


@pytest.mark.parametrize("method", ONE_PASS)
@pytest.mark.parametrize("mode", SINGLE_PASS_MODES)
def test_every_declared_binding_of_every_variant_is_active(gl_renderer, method, mode):
    records = tuple(b.name for b in METHODS[method].bindings if b.records and b.needs is None)
    for depth, features in itertools.product((1, 2, 8), FEATURE_SETS + SHAPES):
        check_variant(gl_renderer, Variant(method, mode, depth, features))
    for depth, features, image in itertools.product((1, 3), SHAPES[:3], (False, True)):
        check_variant(gl_renderer, Variant(method, mode, depth, features, records, image))
        check_variant(gl_renderer, Variant(method, mode, depth, features, records[:1], image))
        if mode != "heat":  # the background variant reads none of the method's
            check_variant(gl_renderer, Variant(method, mode, depth, features, (), image, spheres=False))
    if not METHODS[method].capabilities.meshes_on_gpu:
        return
    for depth, features, image in itertools.product((1, 3), TRIANGLE_SHAPES, (False, True)):
        v = Variant(method, mode, depth, features, (), image)
        blocks = tuple(b.name for b in tracer_bindings(v) if b.records)  # every record array it reads
        check_variant(gl_renderer, Variant(method, mode, depth, features, (), image))
        check_variant(gl_renderer, Variant(method, mode, depth, features, blocks, image))
        if mode != "heat":
            check_variant(gl_renderer, Variant(method, mode, depth, features, (), image, spheres=False))


def test_record_arrays_in_blocks_are_the_renderers_choice(gl_renderer):
    """A record array that fits 64 KiB is read from a uniform block, a larger one from a
    texture; a renderer without blocks uses textures only; the device's data are textures."""
    from renderer.gl import GLRenderer

    small = gl_renderer.render(scenario(3, 1024), RenderSettings(width=8, height=8, format="npy"))
    assert set(small.stats["blocks"]) == {"u_bih_nodes", "u_bih_spheres"}
    big = gl_renderer.render(scenario(3, 8192), RenderSettings(width=8, height=8, format="npy"))
    assert big.stats["blocks"] == ["u_bih_nodes"], "8,192 sphere records are 128 KiB: a texture"
    bvh = gl_renderer.render(scenario(3, 4096), RenderSettings(width=8, height=8, method="bvh", format="npy"))
    assert bvh.stats["blocks"] == ["u_bvh_spheres"], "4 records per inner node: 4,095 × 64 B is a texture"
    tex = GLRenderer(gl_renderer.ctx, uniform_blocks=False).render(scenario(3, 64), RenderSettings(width=8, height=8))
    assert tex.stats["blocks"] == []


@pytest.mark.parametrize("method", ONE_PASS)
def test_what_a_method_packs_is_what_its_shader_declares(method):
    packed = METHODS[method].prepare(scenario(3, 64), 8, 64).packed
    names = set(packed.textures) | set(packed.uniforms)
    assert names == {b.name for b in METHODS[method].bindings if b.needs is None}, "a sphere scene: no triangles"
    if METHODS[method].capabilities.meshes_on_gpu:  # a smooth mesh scene: the triangles' too
        packed = METHODS[method].prepare(mesh_scene("mixed", 1), 8, 64).packed
        names = set(packed.textures) | set(packed.uniforms)
        assert names == {b.name for b in METHODS[method].bindings}
    prims = gpu_layout.pack_primitives(scenario(3, 64))
    lit = {gpu_layout.EMISSION.name, gpu_layout.ENVIRONMENT.name}  # only a scene with emission, environment
    assert set(prims.textures) | set(prims.uniforms) == {b.name for b in gpu_layout.SCENE_BINDINGS} - lit
    scene = scenario(3, 64).to_json()
    scene["materials"][0]["emission"] = [1.0, 2.0, 3.0]
    scene["environment"] = {"color": [0.5, 0.5, 0.5]}
    prims = gpu_layout.pack_primitives(Scene.from_json(scene))
    assert set(prims.textures) | set(prims.uniforms) == {b.name for b in gpu_layout.SCENE_BINDINGS}


def test_a_misspelt_packed_name_is_an_error(gl_renderer, monkeypatch):
    """The renderer refuses a packed name no layout declares instead of skipping it."""
    real = gpu_layout.pack_primitives

    def misspelt(scene, max_width=gpu_layout.DEFAULT_TEXTURE_WIDTH):
        packed = real(scene, max_width)
        packed.uniforms["u_num_sphere"] = packed.uniforms.pop("u_num_spheres")
        return packed

    monkeypatch.setattr(gpu_layout, "pack_primitives", misspelt)
    with pytest.raises(KeyError, match="u_num_sphere"):
        gl_renderer.render(scenario(1, 8), RenderSettings(width=8, height=8, method="bruteforce"))


@pytest.mark.parametrize("method", MULTI_PASS)
@pytest.mark.parametrize("mode", ["color", "depth", "primid", "normal", "recursion", "heat", "cones"])
@pytest.mark.parametrize("depth", [1, 3])
def test_ray_engine_frames_upload_only_what_their_passes_read(gl_renderer, method, mode, depth):
    if mode not in METHODS[method].capabilities.modes:
        return
    passes = gl_renderer.ray_engine
    gl_renderer.render(
        scenario(3, 64), RenderSettings(width=32, height=32, method=method, mode=mode, max_recursion_depth=depth)
    )
    used = set().union(*(active(passes.programs.progs[k]) for k in passes.programs.used))
    declared = {b.name for b in gpu_layout.RAY_ENGINE_BINDINGS}
    assert used & known_bindings() <= declared
    bound = passes.last_bound
    assert bound <= used, (method, mode, depth, sorted(bound - used))
    # Only the cones of the primary layer need no scene data at all.
    assert bool(bound) == (mode != "cones" or depth > 1)

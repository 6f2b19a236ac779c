"""The record of what users get: every shader text and the device data of scenarios 1–3.

(That the images of these texts are bit for bit the unshaped tracer's is
``tests/renderer/gl/test_base_images.py``'s proof.)

Architecture changes must not change what is compiled or sent to a device. This module
computes, for every single-pass method × mode × recursion depth × feature set, the
sha256 of the assembled fragment shader; for every ray-engine program the sha256 of its
vertex and fragment text; and for scenarios 1–3 at n = 64 and 1,024, per device method
and texture width, the sha256 of the packed textures and uniforms (what device-data
serialises). ``tests/golden/test_golden.py`` compares them with ``shaders.json``.

A change that alters shaders or packing on purpose rewrites the record in the same commit
and says why:  .venv/bin/python -m tests.golden.record --write
"""

from __future__ import annotations

import hashlib
import itertools
import json
import sys
from pathlib import Path

import numpy as np

from renderer.methods import METHODS
from renderer.modes import SINGLE_PASS_MODES as MODES

RECORD = Path(__file__).with_name("record.json")

# Every method with a one-pass traversal: a new method adds its variants to the record.
SINGLE_PASS = tuple(name for name, m in METHODS.items() if m.capabilities.shader)
FEATURES = ("NO_REFLECTION", "NO_TRANSMISSION", "NO_LIGHTS")
# The tracer's defines (data formats, compiled-in counts, no task stack) with some removals,
# and the host's choices (every record array in a uniform block; the RGBA8 image).
SHAPES = (
    ("EQUAL_RADII",),
    ("MATERIAL_TEXTURE",),
    ("NO_SPLIT", "PLANES_1", "LIGHTS_1", "EQUAL_RADII"),
    ("NO_TRANSMISSION", "PLANES_1", "LIGHTS_1", "EQUAL_RADII"),
    ("NO_LIGHTS", "PLANES_0", "MATERIAL_TEXTURE"),
    ("PLANES_8", "LIGHTS_8"),
)


def _sha(text: str | bytes) -> str:
    return hashlib.sha256(text.encode() if isinstance(text, str) else text).hexdigest()


def feature_sets() -> list[tuple[str, ...]]:
    return [
        tuple(f for f, on in zip(FEATURES, bits, strict=True) if on) for bits in itertools.product((0, 1), repeat=3)
    ]


def tracer_shaders() -> dict[str, str]:
    from renderer.shader_source import tracer_source, vertex_source

    out = {"vertex": _sha(vertex_source())}
    for method, mode, depth, feats in itertools.product(SINGLE_PASS, MODES, range(1, 9), feature_sets()):
        out[f"{method}/{mode}/{depth}/{','.join(feats)}"] = _sha(tracer_source(method, mode, depth, feats))
    for method, mode, depth, feats in itertools.product(SINGLE_PASS, MODES, (1, 3, 8), SHAPES):
        # (the sphere variants' record arrays: the triangles' need the TRIANGLES data format)
        records = tuple(b.name for b in METHODS[method].bindings if b.records and b.needs is None)
        out[f"{method}/{mode}/{depth}/{','.join(feats)}"] = _sha(tracer_source(method, mode, depth, feats))
        for blocks, image in ((records, False), ((), True), (records, True)):
            key = f"{method}/{mode}/{depth}/{','.join(feats)}/blocks={','.join(blocks)}/{'rgba8' if image else 'float'}"
            out[key] = _sha(tracer_source(method, mode, depth, feats, blocks, image))
        if mode != "heat":
            for image in (False, True):
                key = f"{method}/{mode}/{depth}/{','.join(feats)}/background/{'rgba8' if image else 'float'}"
                out[key] = _sha(tracer_source(method, mode, depth, feats, (), image, spheres=False))
    return out


def ray_engine_programs() -> list[tuple[str, str, tuple[str, ...]]]:
    progs = [
        ("fullscreen.vert", "rayengine_pass.frag", (p,))
        for p in ("PASS_PRIMARY", "PASS_MASK", "PASS_SURFACE", "PASS_SHADE")
    ]
    for ts in range(2, 65):
        progs += [
            ("fullscreen.vert", "rayengine_cones.frag", (f"TILE {ts}",)),
            ("fullscreen.vert", "rayengine_cones.frag", (f"TILE {ts}", "SHADOW")),
        ]
    for hre, any_hit, count in itertools.product((0, 1), repeat=3):
        d = (("HRE",) if hre else ()) + (("ANY_HIT",) if any_hit else ()) + (("COUNT",) if count else ())
        progs.append(("rayengine_prim.vert", "rayengine_prim.frag", d))
    progs.append(("rayengine_prim.vert", "rayengine_prim.frag", ("CULL_MATRIX",)))
    return progs


def ray_engine_shaders() -> dict[str, str]:
    from renderer.shader_source import pass_source, vertex_source

    out = {}
    for vert, frag, defines in ray_engine_programs():
        vs = vertex_source() if vert == "fullscreen.vert" else pass_source(vert, defines)
        out[f"{vert}+{frag}/{','.join(defines)}"] = _sha(vs + "\0" + pass_source(frag, defines))
    return out


def _uniform_json(uniforms: dict) -> str:
    def plain(v):
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        if isinstance(v, (bool, np.bool_)):
            return bool(v)
        if isinstance(v, (int, np.integer)):
            return int(v)
        return float(v)

    return json.dumps({k: plain(v) for k, v in sorted(uniforms.items())}, sort_keys=True)


def _packed_sha(packed) -> str:
    h = hashlib.sha256()
    for name in sorted(packed.textures):
        t = packed.textures[name]
        h.update(f"{name}:{t.dtype}:{t.data.shape}:{t.data.dtype.str}\0".encode())
        h.update(np.ascontiguousarray(t.data).tobytes())
    h.update(_uniform_json(packed.uniforms).encode())
    return h.hexdigest()


def device_data() -> dict[str, str]:
    from renderer import gpu_layout
    from renderer.scenarios import scenario

    out = {}
    for number, n, width in itertools.product((1, 2, 3), (64, 1024), (4096, 256)):
        scene = scenario(number, n, seed=0)
        out[f"primitives/{number}/{n}/{width}"] = _packed_sha(gpu_layout.pack_primitives(scene, width))
        for name in SINGLE_PASS:
            prepared = METHODS[name].prepare(scene, 8, 64, width)
            out[f"{name}/{number}/{n}/{width}"] = _packed_sha(prepared.packed)
    return out


def record() -> dict[str, dict[str, str]]:
    return {"tracer": tracer_shaders(), "ray_engine": ray_engine_shaders(), "device_data": device_data()}


if __name__ == "__main__":
    if "--write" not in sys.argv:
        sys.exit("usage: python -m tests.golden.record --write   (rewrites tests/golden/record.json)")
    RECORD.write_text(json.dumps(record(), indent=1, sort_keys=True) + "\n")
    print(f"wrote {RECORD}")

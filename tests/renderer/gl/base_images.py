"""The images of the base commit's tracer, as hashes: the record this checkout's must equal.

The traversals, the GPU layouts and the shading loop are shaped for llvmpipe's speed, with
every image bit for bit the base commit's. This module defines the frames that prove it — every
one-pass method × mode × scene (scenarios 1–3 at n = 64, 1,024 and 4,096, equal and
unequal radii, a material that both reflects and transmits with several lights and
planes, no lights, more materials than fit in uniforms, no spheres, planes only, an
animated museum) at 1 and 4 samples per pixel, plus every case of the stability catalogue
in colour — and hashes their arrays (float image, uint8 image, depth, primid, normal).

``--write`` renders them with the base commit's shader: it extracts ``renderer/`` and
``shaders/`` of :data:`BASE_COMMIT` from git into a temporary directory and runs this
module there in a subprocess (``--emit``), so the record cannot come from the code it
checks. ``tests/renderer/gl/test_base_images.py`` renders the same frames now and
compares.

    .venv/bin/python -m tests.renderer.gl.base_images --write
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

RECORD = Path(__file__).with_name("base_images.json")
ROOT = Path(__file__).resolve().parents[3]
# The base commit: the unshaped tracer (the shader, layouts and packers the record comes from).
BASE_COMMIT = "cda5fce"

W, H = 49, 81  # odd: the centre row and column have direction components ±0
METHODS = ("bih", "bruteforce", "bvh", "kdtree", "twolevel")
AVERAGED = ("color", "recursion", "heat")
PRIMARY = ("depth", "primid", "normal")


# ---- scenes --------------------------------------------------------------------------------
def _scenes() -> dict:
    from renderer.geometry.scene import Light, Material, Plane, Scene
    from renderer.scenes.animation import museum
    from renderer.scenes.scenarios import RED, TRANSPARENT, scenario

    def replace(scene, **kw):
        d = dict(
            camera=scene.camera,
            lights=scene.lights,
            materials=scene.materials,
            sphere_centers=scene.sphere_centers,
            sphere_radii=scene.sphere_radii,
            sphere_materials=scene.sphere_materials,
            planes=scene.planes,
        )
        d.update(kw)
        return Scene(**d)

    rng = np.random.default_rng(18)
    s3 = scenario(3, 1024)
    both = Material(
        color=(0.6, 0.8, 1.0),
        ambient=0.1,
        diffuse=0.2,
        specular=0.3,
        shininess=60.0,
        reflective=0.3,
        transmissive=0.6,
        ior=1.3,
    )
    mirror = Material(
        color=(0.8, 0.8, 0.8),
        ambient=0.05,
        diffuse=0.1,
        specular=0.5,
        shininess=200.0,
        reflective=0.8,
        transmissive=0.0,
    )
    s2 = scenario(2, 256, seed=3)
    lights2 = (Light((0.0, 40.0, 0.0), (1.0, 1.0, 1.0)), Light((30.0, 10.0, 40.0), (0.4, 0.3, 0.2)))
    planes2 = (Plane((0.0, -20.0, 0.0), (0.0, 1.0, 0.0), 0), Plane((0.0, 0.0, -30.0), (0.0, 0.0, 1.0), 3))
    many = tuple(
        Material(
            color=(0.2 + 0.03 * i, 0.9 - 0.04 * i, 0.5),
            ambient=0.2,
            diffuse=0.5,
            specular=0.2,
            shininess=10.0 + i,
            reflective=0.05 * (i % 5),
            transmissive=0.1 * (i % 3),
            ior=1.1,
        )
        for i in range(20)
    )
    s1 = scenario(1, 125)
    empty = np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32)
    return {
        "s1_64": scenario(1, 64),
        "s2_1024": scenario(2, 1024),
        "s3_4096": scenario(3, 4096),
        "s3_1024_radii": replace(s3, sphere_radii=rng.uniform(0.3, 1.7, s3.n_spheres)),
        "both_kr_kt": replace(
            s2,
            materials=(RED, TRANSPARENT, both, mirror),
            lights=lights2,
            planes=planes2,
            sphere_materials=(np.arange(256) % 4).astype(np.int32),
        ),
        "no_lights": replace(scenario(1, 64), lights=()),
        "many_materials": replace(
            s1,
            materials=many,
            sphere_materials=(np.arange(125) % 20).astype(np.int32),
            planes=(Plane((0.0, -20.0, 0.0), (0.0, 1.0, 0.0), 19),),
        ),
        "no_spheres": replace(
            scenario(1, 0), sphere_centers=empty[0], sphere_radii=empty[1], sphere_materials=empty[2]
        ),
        "planes_only": replace(
            scenario(1, 0),
            materials=(RED, mirror),
            lights=lights2,
            planes=(
                Plane((0.0, -20.0, 0.0), (0.0, 1.0, 0.0), 0),
                Plane((0.0, 0.0, -30.0), (0.0, 0.0, 1.0), 1),
                Plane((0.0, 25.0, 0.0), (0.0, -1.0, 0.0), 1),
            ),
        ),
        "museum_mixed": museum(96, "mixed"),
    }


def cases() -> list[tuple[str, object, dict]]:
    """(key, scene or animated scene, RenderSettings keywords) of every recorded frame."""
    out = []
    scenes = _scenes()
    for name, scene in scenes.items():
        for method in METHODS:
            base = dict(width=W, height=H, method=method, max_prims=8, format="npy")
            if name == "museum_mixed":
                base["time"] = 0.7
            for mode in AVERAGED:
                for spp in (1, 4):
                    out.append(
                        (
                            f"{name}/{method}/{mode}/spp{spp}",
                            scene,
                            dict(base, mode=mode, max_recursion_depth=5, samples_per_pixel=spp),
                        )
                    )
            for mode in PRIMARY:
                out.append((f"{name}/{method}/{mode}/spp1", scene, dict(base, mode=mode, max_recursion_depth=5)))
            if name in ("s3_4096", "both_kr_kt"):  # the interactive profile's cut-off, and depth 3
                out.append(
                    (
                        f"{name}/{method}/color/d3_w0.3",
                        scene,
                        dict(base, mode="color", max_recursion_depth=3, min_weight=0.3),
                    )
                )
            if name == "both_kr_kt":  # the generic variant (nothing specialised away)
                out.append(
                    (
                        f"{name}/{method}/color/generic",
                        scene,
                        dict(base, mode="color", max_recursion_depth=4, specialize=False),
                    )
                )
    sys.path.insert(0, str(ROOT))  # tests.stability (the catalogue) from this checkout; renderer stays first
    try:
        from tests.stability.cases import CASES
    finally:
        sys.path.pop(0)
    for case in CASES:
        scene = case.build()
        if getattr(scene, "n_triangles", 0) or getattr(scene, "n_shapes", 0):
            # Meshes and analytic shapes came after the base: nothing to compare with;
            # tests/renderer/gl/test_renderer.py and test_shapes_render.py hold them.
            continue
        for method in METHODS:
            out.append(
                (
                    f"catalogue/{case.name}/{method}",
                    scene,
                    dict(
                        width=case.width,
                        height=case.height,
                        method=method,
                        mode="color",
                        format="npy",
                        max_prims=case.max_prims,
                        max_tree_depth=case.max_tree_depth,
                        max_recursion_depth=case.max_recursion_depth,
                    ),
                )
            )
    return out


# ---- hashes --------------------------------------------------------------------------------
def _h(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:24]


def hashes(result, arrays: bool = True) -> dict[str, str]:
    """The hash of each array of a RenderResult (the uint8 image as ``image_u8`` makes it);
    ``arrays=False``: the uint8 image only."""
    if not arrays:
        return {"u8": _h(result.image_u8())}
    return {
        "image": _h(result.image.astype(np.float32)),
        "u8": _h(result.image_u8()),
        "depth": _h(result.depth.astype(np.float32)),
        "primid": _h(result.primid.astype(np.int32)),
        "normal": _h(result.normal.astype(np.float32)),
    }


def emit() -> dict[str, dict[str, str]]:
    """Render every case with the renderer on sys.path (the base commit's, under --write)."""
    from renderer.config.settings import RenderSettings
    from renderer.gl import GLRenderer

    r = GLRenderer()
    return {key: hashes(r.render(scene, RenderSettings(**kw))) for key, scene, kw in cases()}


def write() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(
            ["git", "-C", str(ROOT), "archive", BASE_COMMIT, "renderer", "shaders"], check=True, capture_output=True
        ).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        env = {**os.environ, "PYTHONPATH": tmp}
        out = subprocess.run(
            [sys.executable, str(Path(__file__).resolve()), "--emit"],
            cwd=tmp,
            env=env,
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    data = json.loads(out)
    RECORD.write_text(
        json.dumps({"base_commit": BASE_COMMIT, "size": [W, H], "frames": data}, indent=0, sort_keys=True) + "\n"
    )
    print(f"wrote {RECORD}: {len(data)} frames of {BASE_COMMIT}")


if __name__ == "__main__":
    if "--emit" in sys.argv:
        import renderer

        assert not str(Path(renderer.__file__).resolve()).startswith(str(ROOT)), "not the base commit's renderer"
        print(json.dumps(emit()))
    elif "--write" in sys.argv:
        write()
    else:
        sys.exit("usage: python -m tests.renderer.gl.base_images --write")

"""Textures on the GPU: the GPU bytes of texture configurations on the server and on a phone, the mip
level the ray cones choose against distance on the far checker floor, and the base colour a device
(WebGL2 in headless Chromium) computes against the server's (moderngl on llvmpipe) on that floor.

    PYTHONPATH=. .venv/bin/python bench/textures.py [--no-browser]

The floor is tests/renderer/gl/test_textures_gpu.py's: a 256² single-texel checker, 8 repeats over a
400 × 400 quad seen from 1.5 above it, 64 × 64 rays, fov 60°. Its base colour goes through
shaders/pbr_inputs.glsl on both sides (tests/renderer/gl/texture_probe.py's harness; in the browser
tests/browser/test_textures_webgl.py's), the footprint from the primary ray cone.
"""

from __future__ import annotations

import argparse
import base64
import dataclasses
import math
from types import SimpleNamespace

import numpy as np

from renderer.geometry.scene import Camera, Material, Scene, make_mesh
from renderer.gpu import gpu_layout, texture_layout
from renderer.materials.pbr import PbrMaterial
from renderer.oracle import reference

MiB = 1 << 20
CONFIGS = {
    "1 × 1024² (sRGB)": [(1024, 1024)],
    "4 × 1024²": [(1024, 1024)] * 4,
    "2048² + 3 × 256²": [(2048, 2048)] + [(256, 256)] * 3,
    "1024² + 6 × 256²": [(1024, 1024)] * 1 + [(256, 256)] * 6,
    "2048 × 1024 (2:1)": [(2048, 1024)],
    "1 × 4096²": [(4096, 4096)],
    "8 × 2048² (MAX_TEXTURE_TEXELS)": [(2048, 2048)] * 8,
    "1000 × 600 (NPOT)": [(1000, 600)],
}


def bytes_table(phone_side: int = 2048) -> None:
    phone = f"phone array (MAX_TEXTURE_SIZE {phone_side}), MiB"
    print(f"| textures | own size with mips, MiB | server array, MiB | {phone} |")
    print("|---|---|---|---|")
    for name, sizes in CONFIGS.items():
        ts = [SimpleNamespace(width=w, height=h) for w, h in sizes]
        own = sum(texture_layout.texture_bytes(t) for t in ts)  # type: ignore[arg-type]
        server = texture_layout.array_bytes(ts)  # type: ignore[arg-type]
        phone = texture_layout.array_bytes(ts, phone_side)  # type: ignore[arg-type]
        print(f"| {name} | {own / MiB:.2f} | {server / MiB:.2f} | {phone / MiB:.2f} |")


def checker_scene() -> Scene:
    n = 256
    i = np.add.outer(np.arange(n), np.arange(n)) % 2
    px = np.zeros((n, n, 4), np.uint8)
    px[..., :3] = (255 * i)[..., None]
    px[..., 3] = 255
    from renderer.materials.texture import Texture

    size = 200.0
    quad = make_mesh(
        [[-size, 0, -size], [size, 0, -size], [size, 0, size], [-size, 0, size]],
        [[0, 3, 2], [0, 2, 1]],
        uvs=[[0, 0], [8, 0], [8, 8], [0, 8]],
    )
    cam = Camera((0.0, 1.5, size - 1.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 60.0)
    return Scene(
        cam, (), (PbrMaterial(base_color_texture=0),), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32),
        meshes=(quad,), textures=(Texture(px, filter="nearest"),),
    )  # fmt: skip


def checker_hits(scene: Scene, w: int = 64, h: int = 64):
    o, d = reference.primary_rays(scene.camera, w, h)
    t, ids = reference.trace_rays(dataclasses.replace(scene, materials=(Material(),)), o, d)
    hit = ids >= 0
    p = o[hit] + t[hit, None] * d[hit]
    n = np.tile([0.0, 1.0, 0.0], (hit.sum(), 1))
    spread = math.atan(2.0 * math.tan(math.radians(scene.camera.fov_y) / 2.0) / h)
    cos = np.abs(d[hit] @ np.array([0.0, 1.0, 0.0]))
    return ids[hit], p, n, t[hit], spread * t[hit] / cos


def level_table(scene: Scene) -> None:
    prim, p, n, t, footprint = checker_hits(scene)
    tri = prim - scene.triangle_id_base
    uvs = np.asarray(scene.meshes[0].uvs)[np.asarray(scene.meshes[0].triangles)[tri]]
    lod = texture_layout.triangle_lod_terms(scene.triangle_corners[tri], uvs)
    level = np.array([texture_layout.level_for(f, d, 256, 256) for f, d in zip(footprint, lod, strict=True)])
    print("| distance t | footprint (world units) | level chosen |")
    print("|---|---|---|")
    for lo, hi in ((2, 4), (4, 8), (8, 16), (16, 32), (32, 64), (64, 128), (128, 400)):
        sel = (t >= lo) & (t < hi)
        if sel.any():
            print(f"| {lo}–{hi} | {np.median(footprint[sel]):.3g} | {np.median(level[sel]):.2f} |")


def device_vs_server(scene: Scene) -> None:
    from playwright.sync_api import sync_playwright

    from renderer.gl.context import create_context
    from renderer.materials import pack_records
    from tests.browser.browser_support import CHROMIUM, GL_ARGS
    from tests.browser.test_textures_webgl import PROBE
    from tests.renderer.gl.texture_probe import PBR_TEXELS, VERTEX, fragment_source, probe

    prim, p, n, _, footprint = checker_hits(scene)
    server = probe(create_context(), scene, prim, p, n, footprint)["base"][:, :3]
    count = len(p)
    width, height = 32, -(-count // 32)

    def grid(cols: np.ndarray) -> str:
        out = np.zeros((width * height, 4), np.float32)
        out[:count] = cols
        return base64.b64encode(out.tobytes()).decode()

    b64 = lambda a: base64.b64encode(np.ascontiguousarray(a).tobytes()).decode()
    packed = {
        gpu_layout.TRIANGLES.name: gpu_layout.wrap_rows(gpu_layout.triangle_records(scene)),
        **texture_layout.pack_surface_data(scene).packed.textures,
    }
    textures: list[dict] = []
    for name, tx in packed.items():
        if isinstance(tx, gpu_layout.PackedTextureArray):
            levels = [{"width": lv.shape[2], "height": lv.shape[1], "data": b64(lv)} for lv in tx.levels]
            textures.append({"name": name, "layers": tx.layers, "levels": levels})
        else:
            w, h = tx.size
            textures.append({"name": name, "width": w, "height": h, "dtype": "u4", "data": b64(tx.data)})
    textures += [
        {"name": "u_probe_point", "width": width, "height": height, "dtype": "f4",
         "data": grid(np.concatenate([p, prim[:, None]], axis=1))},
        {"name": "u_probe_normal", "width": width, "height": height, "dtype": "f4",
         "data": grid(np.concatenate([n, footprint[:, None]], axis=1))},
    ]  # fmt: skip
    mats = np.zeros((PBR_TEXELS * 4, 4), np.float32)
    mats[:PBR_TEXELS] = pack_records(scene.materials, PbrMaterial)
    uniforms = {"u_tri_base": scene.triangle_id_base, "u_probe_mats": mats.ravel().tolist()}
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=CHROMIUM, args=GL_ARGS, headless=True)
        args = [VERTEX, fragment_source(False, False), textures, uniforms, width, height, 5]
        res = b.new_page().evaluate(PROBE, args)
        b.close()
    device = np.asarray(res["outputs"][0], dtype=np.float64).reshape(-1, 4)[:count, :3]
    mse = float(np.mean((device - server) ** 2))
    psnr = float("inf") if mse == 0 else 10 * math.log10(1.0 / mse)
    print(f"| {count} hit points | max |Δ| {np.abs(device - server).max():.2e} | PSNR {psnr:.1f} dB |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-browser", action="store_true", help="leave out the device-vs-server comparison")
    args = ap.parse_args()
    bytes_table()
    print()
    scene = checker_scene()
    level_table(scene)
    if not args.no_browser:
        print()
        device_vs_server(scene)


if __name__ == "__main__":
    main()

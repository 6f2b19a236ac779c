"""The glTF metallic-roughness material's figures: the white furnace, the comparison with Mitsuba 3,
and the time of a PBR frame against a Phong frame of the same scene.

    python -m bench.pbr                 # all three tables
    python -m bench.pbr --quick         # smaller frames, fewer samples (smoke)

**Furnace.** A white unit sphere of each metallic × roughness under a uniform environment of
radiance 1, traced by the path integrator (32 × 32, 256 samples, bih): its mean radiance over the
sphere (2 pixels in from its silhouette), and the same mean of the BRDF's directional albedo at each
pixel's view, integrated in NumPy (``renderer/materials/pbr_brdf.py``): what the single-scattering GGX keeps.

**Mitsuba.** ``renderer/oracle/path_scenes.py``'s PBR scenes (a white rough conductor, a rough dielectric of
transmission 1, an ior-1 dielectric), 32 × 32, depth 8: ours at 1,024 samples against Mitsuba 3's at
4,096 (``tests/renderer/gl/test_mitsuba.py``'s budget): PSNR of linear radiance clipped to [0, 1] and
the relative difference of the image means.

**Time.** The same geometry (``mesh_scene("room")``: walls, a teapot, a glass icosphere, spheres)
with its Phong materials, and with each replaced by a PBR one of like look (colour → base colour;
reflective → metallic 1, roughness 0.2; transmissive → transmission 1; else a dielectric of
roughness 0.6): Whitted (320 × 544, 1 sample, depth 5) and path (160 × 272, 16 samples, depth 8)
frames, bih, the median wall clock of ``GLRenderer.render`` over interleaved repetitions after an
untimed first frame of each (its variant's compile). The load average is printed: the machine is shared.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time

import numpy as np
from scipy.ndimage import binary_erosion

from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Scene
from renderer.gl.renderer import GLRenderer
from renderer.materials import pbr_brdf
from renderer.oracle import mitsuba_scene
from renderer.oracle.path_scenes import PBR_MATERIALS, pbr_scene
from renderer.scenes.scenarios import mesh_scene

METALLIC = (0.0, 0.5, 1.0)
ROUGHNESS = (0.0, 0.25, 0.5, 0.75, 1.0)
CAMERA = {"position": [0, 0, 4], "target": [0, 0, 0], "fov_y": 34}


def path(w: int, h: int, spp: int, depth: int = 16) -> RenderSettings:
    return RenderSettings(
        width=w, height=h, integrator="path", samples_per_pixel=spp, max_recursion_depth=depth, format="npy"
    )


def furnace(r: GLRenderer, size: int, spp: int) -> list[tuple[float, float, float, float]]:
    rows = []
    t = math.tan(math.radians(CAMERA["fov_y"]) / 2)
    for metallic in METALLIC:
        for roughness in ROUGHNESS:
            mat = {"kind": "pbr", "base_color": [1, 1, 1], "metallic": metallic, "roughness": roughness}
            scene = Scene.from_json(
                {
                    "camera": CAMERA,
                    "lights": [],
                    "materials": [mat],
                    "spheres": [{"center": [0, 0, 0], "radius": 1.0}],
                    "environment": {"color": [1, 1, 1]},
                }
            )
            res = r.render(scene, path(size, size, spp))
            inside = binary_erosion(res.primid >= 0, iterations=2)
            ys, xs = np.mgrid[:size, :size]
            d = np.stack([(2 * (xs + 0.5) / size - 1) * t, (1 - 2 * (ys + 0.5) / size) * t, -np.ones((size, size))], -1)
            d /= np.linalg.norm(d, axis=-1, keepdims=True)
            want = pbr_brdf.furnace_radiance(-np.sum(d * res.normal, axis=-1), metallic, roughness)
            rows.append((metallic, roughness, float(res.image[inside].mean()), float(want[inside].mean())))
    return rows


def clipped_psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((np.clip(a, 0, 1).astype(np.float64) - np.clip(b, 0, 1)) ** 2))
    return math.inf if mse == 0 else -10.0 * math.log10(mse)


def mitsuba(r: GLRenderer, size: int, spp: int) -> list[tuple[str, float, float]]:
    rows = []
    for name in PBR_MATERIALS:
        scene = pbr_scene(name)
        ref = mitsuba_scene.render(scene, size, size, 4 * spp, 8)
        ours = r.render(scene, path(size, size, spp, 8)).image
        rows.append((name, clipped_psnr(ours, ref), float(ours.mean() / ref.mean() - 1.0)))
    return rows


def as_pbr(scene: Scene) -> Scene:
    """``scene`` with each Phong material replaced by a PBR one of like look (module docstring)."""
    doc = scene.to_json()
    mats = []
    for m in doc["materials"]:
        pbr = {"kind": "pbr", "base_color": m["color"], "metallic": 0.0, "roughness": 0.6}
        if m.get("transmissive", 0) > 0:
            pbr.update(transmission=1.0, roughness=0.0, ior=max(1.0, m.get("ior", 1.5)))
        elif m.get("reflective", 0) > 0.2:
            pbr.update(metallic=1.0, roughness=0.2)
        if any(m.get("emission", [0, 0, 0])):
            pbr.update(emissive=[1.0, 1.0, 1.0], emissive_strength=max(m["emission"]))
        mats.append(pbr)
    doc["materials"] = mats
    return Scene.from_json(doc)


def timing(r: GLRenderer, runs: int, quick: bool) -> list[tuple[str, str, float, float]]:
    phong = mesh_scene("room", 2)
    pbr = as_pbr(phong)
    cases = {
        "whitted": RenderSettings(width=160 if quick else 320, height=272 if quick else 544, max_recursion_depth=5),
        "path": path(80 if quick else 160, 136 if quick else 272, 4 if quick else 16, 8).with_(format="png"),
    }
    rows = []
    for label, s in cases.items():
        times: dict[str, list[float]] = {"phong": [], "pbr": []}
        for scene in (phong, pbr):
            r.render(scene, s)  # the variant's compile, untimed
        for _ in range(runs):
            for kind, scene in (("phong", phong), ("pbr", pbr)):
                t0 = time.perf_counter()
                r.render(scene, s)
                times[kind].append(time.perf_counter() - t0)
        rows.append(
            (
                label,
                f"{s.width} × {s.height}, {s.samples_per_pixel} spp",
                *(1e3 * statistics.median(times[k]) for k in ("phong", "pbr")),
            )
        )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smaller frames, fewer samples")
    ap.add_argument("--runs", type=int, default=5, help="timed repetitions per case (interleaved)")
    args = ap.parse_args()
    r = GLRenderer()
    print(f"load average at start: {' '.join(f'{x:.1f}' for x in os.getloadavg())}\n")
    print("| metallic | roughness | GL furnace | NumPy albedo | GL − NumPy |\n|---|---|---|---|---|")
    for m, ro, gl, want in furnace(r, 16 if args.quick else 32, 32 if args.quick else 256):
        print(f"| {m} | {ro} | {gl:.4f} | {want:.4f} | {gl - want:+.4f} |")
    print("\n| PBR scene vs Mitsuba 3 | PSNR (dB) | mean, ours / Mitsuba − 1 |\n|---|---|---|")
    for name, p, rel in mitsuba(r, 16 if args.quick else 32, 64 if args.quick else 1024):
        print(f"| {name} | {p:.1f} | {100 * rel:+.2f} % |")
    print("\n| frame (room, bih) | size | Phong (ms) | PBR (ms) | PBR / Phong |\n|---|---|---|---|---|")
    for label, size, phong_ms, pbr_ms in timing(r, 1 if args.quick else args.runs, args.quick):
        print(f"| {label} | {size} | {phong_ms:.0f} | {pbr_ms:.0f} | {pbr_ms / phong_ms:.2f} |")
    print(f"\nload average at end: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()

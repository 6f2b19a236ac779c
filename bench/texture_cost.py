"""What textures cost: a textured scene against the same scene untextured, and their memory.

    python -m bench.texture_cost                  # every scene, 7 interleaved runs each (≈ 1.5 min at load 6)
    python -m bench.texture_cost --runs 9 --spp 16
    python -m bench.texture_cost --quick          # tiny frames, 1 run (smoke)
    python -m bench.texture_cost --memory-only

**Time.** Each scene is traced twice: as it is (*textured*) and *untextured* (:func:`untextured`:
the same meshes with their UVs and tangents, the same materials of the same kind, each texture
replaced by its average as the factor it multiplies — a base colour by its mean linear colour,
roughness and metallic by the mean green and blue, the normal map dropped — and no texture in the
scene). Two frames per scene: *primary rays* (Whitted, 1 sample, ``max_recursion_depth`` 1: the
first hit and its shading, the shadow rays of the point lights) and *path samples* (the path
integrator, ``--spp`` samples, ``--depth``). The two versions are interleaved (textured,
untextured, textured …) after one untimed frame each (the variant's compile, the texture array's
mip chain); each figure is the minimum over ``--runs`` frames, of the frame's ``trace`` stage
(``GLRenderer``'s timing: the passes and ``glFinish``, without the tree's build, the upload and the
read-back) and of the whole frame's process CPU time (llvmpipe's threads included: it does not grow
with the machine's other work as the wall clock does). Ratio = textured / untextured, from the
same run. The acceleration structure is the same for both (the same triangles). ``--slots`` adds
the materials scene with its base colour textures only, then with its metallic-roughness ones too
(the rest of its textures averaged): what each slot's lookups add.

Scenes, each framed for a 390 × 844 phone: the ``materials`` demo scene (``mesh_scene("materials")``)
and, where the model reader brings their textures, the corpus's ``BoxTextured.glb`` and
``spider.obj`` (assimp's test models, Debian's ``assimp-testmodels``) as ``pocketray render``
stages a model (``renderer.io.mesh_io.model_scene``).

**Memory** of each scene's textures, RGBA8: per texture its level 0 and its full mip chain
(⌈w / 2^l⌉ × ⌈h / 2^l⌉ texels at level l), then what the GPU holds — one 2D array texture of
square slots with its mip levels (``renderer.gpu.texture_layout``: ``array_bytes``) — on the server and
for the phone (device mode uploads the same array, packed for the device's ``MAX_TEXTURE_SIZE``:
WebGL2's guaranteed 2,048 here, the phone's worst case), and the triangles' attribute records the
textures bring (UVs and their level terms, tangents: ``attribute_bytes``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from renderer.geometry.scene import Scene
from renderer.materials.pbr import SLOTS, PbrMaterial
from renderer.materials.procedural_textures import mean_factor

CORPUS = Path("/usr/share/assimp/models")
CORPUS_MODELS = ("glTF2/BoxTextured-glTF-Binary/BoxTextured.glb", "OBJ/spider.obj")
PHONE_ASPECT = 390 / 844
PRIMARY_SIZE = (390, 844)  # the phone's screen: Whitted's primary rays
PATH_SIZE = (195, 422)  # half of it: the path integrator's samples
QUICK_SIZE = (39, 84)
SPP, DEPTH, RUNS = 8, 4, 7
SLOT_PARTS = ("texture", "texcoord", "uv_matrix", "uv_offset")
# --slots: the textured scene built up a slot at a time, each version keeping the slots named
BREAKDOWN = {
    "base colour": ("base_color",),
    "+ metallic-roughness": ("base_color", "metallic_roughness"),
}
WEBGL2_MAX_TEXTURE_SIZE = 2048  # what WebGL2 guarantees; phones report 4,096 or more


def untextured(scene: Scene, keep: tuple[str, ...] = ()) -> Scene:
    """``scene`` with every texture replaced by its average in the factor it multiplies (the
    module docstring): the same meshes (UVs, tangents and all) and material kinds, no textures.
    ``keep``: texture slots (:data:`renderer.materials.pbr.SLOTS`) left as they are — then the
    scene keeps its textures."""
    texels = scene.textures

    def flat(m: Any) -> Any:
        if not isinstance(m, PbrMaterial) or not m.textures():
            return m
        kept = {f"{slot}_{part}": getattr(m, f"{slot}_{part}") for slot in keep for part in SLOT_PARTS}
        kw: dict[str, Any] = {}
        if m.base_color_texture >= 0:
            mean = mean_factor(texels[m.base_color_texture])
            kw["base_color"] = tuple(float(f * c) for f, c in zip(m.base_color, mean[:3], strict=True))
            kw["alpha"] = float(m.alpha * mean[3])
        if m.metallic_roughness_texture >= 0:
            mean = mean_factor(texels[m.metallic_roughness_texture])
            kw["roughness"], kw["metallic"] = float(m.roughness * mean[1]), float(m.metallic * mean[2])
        if m.emissive_texture >= 0:
            mean = mean_factor(texels[m.emissive_texture])
            kw["emissive"] = tuple(float(f * c) for f, c in zip(m.emissive, mean[:3], strict=True))
        if m.transmission_texture >= 0:
            kw["transmission"] = float(m.transmission * mean_factor(texels[m.transmission_texture])[0])
        for slot in SLOTS:  # every slot back to its default: no texture, set 0, no transform
            for part in SLOT_PARTS:
                name = f"{slot}_{part}"
                kw[name] = PbrMaterial.__dataclass_fields__[name].default
        if kept:  # a kept slot keeps its texture and its factor
            factors = {"base_color": ("base_color", "alpha"), "metallic_roughness": ("roughness", "metallic")}
            kw = {k: v for k, v in kw.items() if not any(k in factors.get(slot, ()) for slot in keep)}
            kw |= kept
        return dataclasses.replace(m, **kw)

    textures = scene.textures if keep else ()
    return dataclasses.replace(scene, materials=tuple(flat(m) for m in scene.materials), textures=textures)


def scenes(aspect: float) -> dict[str, Scene]:
    """The scenes measured (the module docstring), each framed for ``aspect``."""
    from renderer.io.mesh_io import model_scene
    from renderer.scenes.scenarios import framed, mesh_scene

    out = {"materials": framed(mesh_scene("materials"), aspect)}
    for name in CORPUS_MODELS:
        path = CORPUS / name
        model = model_scene(path) if path.exists() else None
        if model is not None and model.textures:  # a reader that drops the textures leaves nothing to compare
            out[path.name] = framed(model, aspect)
    return out


def _load() -> float:
    return round(os.getloadavg()[0], 2)


def timing(
    scene: Scene, frames: dict[str, Any], runs: int, log, slots: bool = False
) -> dict[str, dict[str, dict[str, list[float]]]]:
    """{frame: {version: {"trace": [ms …], "cpu": [s …], "mean": [radiance]}}}, interleaved;
    ``slots``: the :data:`BREAKDOWN` versions too."""
    from renderer.gl.renderer import GLRenderer

    r = GLRenderer()
    versions = {"textured": scene, "untextured": untextured(scene)}
    if slots:
        versions |= {name: untextured(scene, keep) for name, keep in BREAKDOWN.items()}
    out: dict[str, dict[str, dict[str, list[float]]]] = {}
    for fname, settings in frames.items():
        rec: dict[str, dict[str, list[float]]] = {v: {"trace": [], "cpu": [], "mean": []} for v in versions}

        def one(version: str, keep: bool, rec=rec, settings=settings) -> None:
            t0 = time.process_time()
            res = r.render(versions[version], settings)
            cpu = time.process_time() - t0
            if keep:
                rec[version]["trace"].append(float(res.timings["trace"]))
                rec[version]["cpu"].append(cpu)
            rec[version]["mean"] = [float(np.asarray(res.image)[..., :3].mean())]

        for v in versions:
            log(f"{fname} warm-up {v}")
            one(v, False)
        for k in range(runs):
            for v in versions:
                one(v, True)
                log(f"{fname} run {k + 1}/{runs} {v}: trace {rec[v]['trace'][-1]:.1f} ms (load {_load()})")
        out[fname] = rec
    return out


def _mib(b: int) -> str:
    return f"{b / 2**20:.2f} MiB" if b >= 2**20 else f"{b / 2**10:.1f} KiB"


def memory(scene: Scene) -> dict[str, Any]:
    """Per texture: name, size, sRGB, level 0 and mip-chain bytes; the GPU array's bytes on the
    server and for a WebGL2 phone (level 0, and with its mip levels: what device mode uploads too);
    and the triangles' attribute records (UVs, tangents) that come with textures."""
    from renderer import limits
    from renderer.gpu.texture_layout import array_bytes, array_layers, attribute_bytes, fit_textures, texture_bytes

    rows = [
        {"name": t.name, "size": [t.width, t.height], "srgb": t.srgb, "level0": t.nbytes, "mips": texture_bytes(t)}
        for t in scene.textures
    ]
    gpu = {}
    for where, side in (("server", limits.MAX_TEXTURE_SIDE), ("phone", WEBGL2_MAX_TEXTURE_SIZE)):
        fitted, notices = fit_textures(scene.textures, max_size=side)
        layer, layers = array_layers([(t.width, t.height) for t in fitted])
        gpu[where] = {
            "layer": [layer, layer],
            "layers": layers,
            "level0": layer * layer * layers * 4,
            "mips": array_bytes(scene.textures, max_size=side),
            "notices": notices,
        }
    return {"textures": rows, "gpu": gpu, "attributes": attribute_bytes(scene)}


def time_table(name: str, d: dict, sizes: dict[str, str]) -> str:
    rows = [
        f"| {name} | frame | untextured trace (ms) | textured trace (ms) | ratio | untextured CPU (s) "
        "| textured CPU (s) | ratio |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for fname, rec in d.items():
        u, t = rec["untextured"], rec["textured"]
        tu, tt, cu, ct = min(u["trace"]), min(t["trace"]), min(u["cpu"]), min(t["cpu"])
        rows.append(
            f"| | {fname} ({sizes[fname]}) | {tu:.1f} | {tt:.1f} | **{tt / tu:.2f}×** | {cu:.2f} | {ct:.2f} "
            f"| {ct / cu:.2f}× |"
        )
        for part in BREAKDOWN:
            if part in rec:
                p = rec[part]
                tp, cp = min(p["trace"]), min(p["cpu"])
                rows.append(f"| | … {part} only | | {tp:.1f} | {tp / tu:.2f}× | | {cp:.2f} | {cp / cu:.2f}× |")
    return "\n".join(rows)


def memory_table(name: str, m: dict) -> str:
    rows = [f"| {name}: texture | size | sRGB | level 0 | with mips |", "|---|---:|:-:|---:|---:|"]
    for t in m["textures"]:
        w, h = t["size"]
        srgb = "yes" if t["srgb"] else ""
        rows.append(f"| {t['name'] or '(unnamed)'} | {w} × {h} | {srgb} | {_mib(t['level0'])} | {_mib(t['mips'])} |")
    level0 = sum(t["level0"] for t in m["textures"])
    rows.append(
        f"| **all {len(m['textures'])}** | | | **{_mib(level0)}** | **{_mib(sum(t['mips'] for t in m['textures']))}** |"
    )
    for where, g in m["gpu"].items():
        w, h = g["layer"]
        note = f" ({'; '.join(g['notices'])})" if g["notices"] else ""
        rows.append(
            f"| GPU array, {where} | {g['layers']} × {w} × {h} | | {_mib(g['level0'])} | {_mib(g['mips'])}{note} |"
        )
    rows.append(f"| triangles' UV and tangent records (both) | | | {_mib(m['attributes'])} | |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    from renderer.config.settings import RenderSettings

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=RUNS)
    ap.add_argument("--spp", type=int, default=SPP, help="the path frame's samples per pixel")
    ap.add_argument("--depth", type=int, default=DEPTH, help="the path frame's depth")
    ap.add_argument("--quick", action="store_true", help=f"{QUICK_SIZE[0]} × {QUICK_SIZE[1]}, 1 run (smoke)")
    ap.add_argument("--memory-only", action="store_true")
    ap.add_argument("--slots", action="store_true", help="the materials scene built up a texture slot at a time")
    ap.add_argument("--json", type=Path, help="write the raw measurements here")
    ap.add_argument("-v", "--verbose", action="store_true", help="each frame's time on stderr")
    a = ap.parse_args(argv)
    runs = 1 if a.quick else a.runs
    pw, ph = QUICK_SIZE if a.quick else PRIMARY_SIZE
    qw, qh = QUICK_SIZE if a.quick else PATH_SIZE

    def log(msg: str) -> None:
        if a.verbose:
            print(msg, file=sys.stderr, flush=True)

    frames = {
        "primary rays": RenderSettings(
            width=pw, height=ph, integrator="whitted", samples_per_pixel=1, max_recursion_depth=1, format="npy"
        ),
        "path samples": RenderSettings(
            width=qw, height=qh, integrator="path", samples_per_pixel=a.spp, max_recursion_depth=a.depth, format="npy"
        ),
    }
    sizes = {"primary rays": f"{pw} × {ph}, Whitted 1 spp", "path samples": f"{qw} × {qh}, path {a.spp} spp"}
    out: dict[str, Any] = {"runs": runs, "frames": sizes, "load": [_load()]}
    for name, scene in scenes(PHONE_ASPECT).items():
        m = memory(scene)
        out.setdefault("memory", {})[name] = m
        print(f"\n## Texture memory: {name}\n\n{memory_table(name, m)}", flush=True)
        if a.memory_only:
            continue
        load0 = _load()
        d = timing(scene, frames, runs, log, slots=a.slots and name == "materials")
        out.setdefault("time", {})[name] = d
        print(
            f"\n## Textured vs untextured: {name} (min of {runs} interleaved; load {load0} → {_load()})\n\n"
            f"{time_table(name, d, sizes)}",
            flush=True,
        )
        for fname, rec in d.items():
            print(
                f"  {fname}: mean radiance textured {rec['textured']['mean'][0]:.4f}, "
                f"untextured {rec['untextured']['mean'][0]:.4f}"
            )
    out["load"].append(_load())
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Materials and textures: glTF's metallic-roughness BSDF against its own float64 integral (a white
furnace) and Mitsuba 3, a PBR frame's time beside a Phong one, and what textures cost — the time of a
textured scene beside the same scene untextured, and their memory on the server and a phone.

- **furnace**: ``bench/pbr.py``'s white furnace (a white PBR sphere in a uniform environment of
  radiance 1, path integrator) over metallic × roughness, against the BRDF integrated in NumPy
  (``renderer/materials/pbr_brdf.py``);
- **mitsuba**: the PBR scenes whose model Mitsuba 3 has as well (a white rough conductor, a rough
  dielectric, an ior-1 dielectric as Lambert), PSNR of ours against Mitsuba's at 4 × our samples;
- **pbr_time**: the demo room with its Phong materials and with PBR ones of like look (``as_pbr``);
- **texture_time**: ``bench/texture_cost.py``: each scene textured and with its textures replaced by
  their average factors (same geometry, same material kind), interleaved, min of the runs;
- **memory**: each scene's textures (level 0, with mips), the GPU array they are packed into on the
  server and for a WebGL2 phone (MAX_TEXTURE_SIZE 2048), and the triangles' attribute records.

Quick mode: the furnace at 16² and 16 spp, one Mitsuba scene at 16², small frames, one run.
"""

from __future__ import annotations

import os
from typing import Any

from bench import pbr as P, texture_cost as T

from .context import Context, RunInfo

NAME = "materials"
TITLE = "Materials and textures — the glTF BSDF against its integral and Mitsuba 3, what textures cost"


def measure(ctx: Context) -> dict:
    from renderer.config.settings import RenderSettings
    from renderer.integrators import Integrator

    r = ctx.renderer
    out: dict[str, Any] = {}
    size, spp = (16, 16) if ctx.quick else (32, 256)
    out["furnace"] = {"size": size, "spp": spp, "rows": P.furnace(r, size, spp)}
    out["furnace"]["load_average"] = os.getloadavg()
    msize, mspp = (16, 16) if ctx.quick else (32, 1024)
    out["mitsuba"] = {"size": msize, "spp": mspp, "rows": P.mitsuba(r, msize, mspp)[: 1 if ctx.quick else None]}
    out["mitsuba"]["load_average"] = os.getloadavg()
    out["pbr_time"] = {"rows": P.timing(r, 1 if ctx.quick else ctx.runs, ctx.quick)}
    out["pbr_time"]["load_average"] = os.getloadavg()
    w, h = T.QUICK_SIZE if ctx.quick else T.PRIMARY_SIZE
    pw, ph = T.QUICK_SIZE if ctx.quick else T.PATH_SIZE
    frames = {
        "primary rays": RenderSettings(width=w, height=h, max_recursion_depth=1),
        "path": RenderSettings(
            width=pw,
            height=ph,
            integrator=Integrator.PATH,
            samples_per_pixel=2 if ctx.quick else T.SPP,
            max_recursion_depth=T.DEPTH,
        ),
    }
    sizes = {
        k: f"{s.width} × {s.height}" + (f", {s.samples_per_pixel} spp" if k == "path" else "")
        for k, s in frames.items()
    }
    out["texture_time"], out["memory"] = {}, {}
    for name, scene in T.scenes(T.PHONE_ASPECT).items():
        out["texture_time"][name] = T.timing(scene, frames, 1 if ctx.quick else T.RUNS, ctx.log)
        out["memory"][name] = T.memory(scene)
    out["texture_sizes"] = sizes
    out["texture_load_average"] = os.getloadavg()
    return out


def _load(la: Any) -> str:
    return "—" if not la else " / ".join(f"{x:.1f}" for x in la)


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    f = data["furnace"]
    furnace = ["| metallic | roughness | GL furnace | NumPy albedo | GL − NumPy |", "|---:|---:|---:|---:|---:|"]
    furnace += [f"| {m:g} | {ro:g} | {gl:.4f} | {want:.4f} | {gl - want:+.4f} |" for m, ro, gl, want in f["rows"]]
    worst = max((row[2] for row in f["rows"]), default=0.0)
    m = data["mitsuba"]
    mits = ["| PBR scene | PSNR against Mitsuba 3 (dB) | mean, ours / Mitsuba − 1 |", "|---|---:|---:|"]
    mits += [f"| {name} | {p:.1f} | {100 * rel:+.2f} % |" for name, p, rel in m["rows"]]
    pt = ["| frame (demo room, bih) | size | Phong (ms) | PBR (ms) | PBR / Phong |", "|---|---|---:|---:|---:|"]
    pt += [f"| {lab} | {size} | {a:.0f} | {b:.0f} | {b / a:.2f}× |" for lab, size, a, b in data["pbr_time"]["rows"]]
    tex = "\n\n".join(T.time_table(name, d, data["texture_sizes"]) for name, d in data["texture_time"].items())
    mem = "\n\n".join(T.memory_table(name, d) for name, d in data["memory"].items())
    ratios = [
        min(rec["textured"]["trace"]) / min(rec["untextured"]["trace"])
        for d in data["texture_time"].values()
        for rec in d.values()
    ]
    verdict = (
        f"Textured against untextured, trace stage: {min(ratios):.2f}× … {max(ratios):.2f}× (target ≤ 1.3×: "
        + (
            "met)."
            if max(ratios) <= 1.3
            else "**not met**: every lookup filters by hand in the shader, eight "
            'texel fetches and sRGB decodes for a trilinear sample, docs/SHADING.md, "Textures").'
        )
        if ratios
        else ""
    )
    return f"""## {TITLE}

### The BSDF in a white furnace

A white sphere of each metallic × roughness in a uniform environment of radiance 1, path integrator,
{f["size"]}² at {f["spp"]} samples, the mean over the sphere's inside pixels; beside it the same
BRDF integrated in float64 NumPy (`renderer/materials/pbr_brdf.py`). No row exceeds 1 beyond noise (largest
{worst:.4f}): the BSDF creates no energy; what it loses at high roughness is the single-scattering
GGX lobe's missing multiple scattering (docs/SHADING.md, "PBR"). Load average at the end:
{_load(f.get("load_average"))}.

{chr(10).join(furnace)}

### Against Mitsuba 3 where the models coincide

{m["size"]}², ours {m["spp"]:,} samples, Mitsuba's llvm variant 4 × as many; PSNR of linear radiance
clipped to [0, 1]. Load average at the end: {_load(m.get("load_average"))}.

{chr(10).join(mits)}

### A PBR frame beside a Phong one

The demo room with its Phong materials, and with PBR materials of like look (`bench/pbr.py`'s
`as_pbr`), median of interleaved runs. Load average at the end: {_load(data["pbr_time"].get("load_average"))}.

{chr(10).join(pt)}

### What textures cost: time

{run.caption(None, "min of interleaved runs")} Each scene textured, and with its textures replaced
by their average factors (the same geometry and material kind, `bench/texture_cost.py`); *trace*:
the renderer's trace stage; CPU: the process's CPU time for the frame. Load average at the end:
{_load(data.get("texture_load_average"))}.

{tex}

{verdict}

### What textures cost: memory

RGBA8 texels; a mip chain adds a third. The GPU array packs each texture into a square
power-of-two slot of a layer (docs/FORMATS.md, "Textures"): a texture that is not a power of two
a side pays its padding.

{mem}
"""

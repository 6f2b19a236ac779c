"""The path integrator's denoisers: Intel Open Image Denoise (``pyoidn``, whose wheel ships the
library) or the edge-avoiding à-trous filter (renderer/image/atrous.py, the one device mode runs in
WebGL2) on the frame's linear radiance, guided by the albedo and the normal of the first hit.

Both guides come from the frame's own trace: a path frame with ``denoise`` on is traced by the
variant with ``GUIDES`` (``shaders/lighting.glsl``), which also sums over its samples the first
hit's outward normal and its material's albedo as the path integrator's lobes see it —
``w_d · color + w_r + w_t``, the lobe weights scaled to sum at most 1 as the shader scales them
(the mirror and glass lobes are white, so a perfect specular surface has albedo 1, as OIDN asks);
a ray that meets nothing: the environment clamped to [0, 1], normal 0. Their means
(``RenderResult.guides``) are anti-aliased as the radiance is, which OIDN wants. A result without
them (traced with ``denoise`` off) is guided by the same albedo looked up on the CPU from its
first sample's primary hit (``primid``) and that hit's normal — aliased, measured worse than no
guides at all (``bench/denoise.py``), kept only so that any radiance can be denoised.

Denoising is applied to the mean a frame answers (an accumulation's included: never to what it
holds), on the request's thread, after the GL thread is done with the frame (docs/API.md,
"Denoising").

What a denoise holds beyond the frame's own arrays is :func:`denoise_nbytes`, which the service
counts in a frame's reservation (server/frames/pipeline.py). OIDN's scratch is the largest part
(576 bytes a pixel): its filter is released after every frame, so that no frame's scratch outlives
it (a kept filter holds the last frame's scratch, and its images, until the next call — 2.3 GiB
after one 2048² frame); its device is kept, and one frame is denoised at a time.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from typing import Any

import numpy as np

from ..geometry.scene import Scene
from ..integrators import Denoiser
from ..materials.pbr import PbrMaterial
from .atrous import atrous
from .result import RenderResult

# Bytes a pixel one denoise holds beyond the frame's own arrays (its colour and guides), measured on
# the 2-core development machine as the rise of VmHWM over one call, one process per size:
# - OIDN 2.5.1 (pyoidn, CPU device, quality high, hdr, albedo and normal): 588.0 B/px at 256², 512²,
#   1024² and 2048² alike — its scratch, 576, and the output image, 12
#   (``python -m bench.hostile admission_oidn_bytes``);
# - à-trous (renderer/image/atrous.py): 233 B/px at 1024², 235 at 512² (its guides, sums, weights and
#   taps' temporaries, float32), rounded up.
OIDN_BYTES_PER_PIXEL = 576 + 12
ATROUS_BYTES_PER_PIXEL = 240
BYTES_PER_PIXEL: dict[str, int] = {Denoiser.OIDN: OIDN_BYTES_PER_PIXEL, Denoiser.ATROUS: ATROUS_BYTES_PER_PIXEL}


def denoise_nbytes(denoiser: str, width: int, height: int) -> int:
    """At most the bytes a ``denoiser`` adds while it denoises a ``width`` × ``height`` frame and
    that its output holds after (``off``: 0)."""
    per_pixel = BYTES_PER_PIXEL.get(denoiser, 0)
    return int(width) * int(height) * per_pixel


def material_albedos(scene: Scene) -> np.ndarray:
    """float32 (M, 3): each material's albedo as the path integrator's lobes see it."""
    out = np.zeros((len(scene.materials), 3), np.float32)
    for i, m in enumerate(scene.materials):
        if isinstance(m, PbrMaterial):  # the guide of the glTF material: its base colour
            out[i] = m.base_color
            continue
        w = np.array([m.diffuse, m.reflective, m.transmissive], np.float64)
        w /= max(1.0, float(w.sum()))  # the shader's weights: scaled to sum 1 where they exceed it
        out[i] = w[0] * np.asarray(m.color) + w[1] + w[2]
    return out


def first_hit_albedo(scene: Scene, primid: np.ndarray) -> np.ndarray:
    """float32 H×W×3: the albedo of the primary hit ``primid`` (int32 H×W, −1 on a miss) names."""
    plane_materials = np.array([p.material for p in scene.planes], np.int32)
    material_of = np.concatenate(
        [np.asarray(scene.sphere_materials, np.int32), plane_materials, np.asarray(scene.triangle_materials, np.int32)]
    )
    albedos = material_albedos(scene)
    hit = primid >= 0
    out = np.empty((*primid.shape, 3), np.float32)
    out[...] = np.clip(np.asarray(scene.environment, np.float32), 0.0, 1.0)
    out[hit] = albedos[material_of[primid[hit]]]
    return out


def denoise_result(result: RenderResult, scene: Scene, denoiser: str) -> RenderResult:
    """``result`` with its radiance denoised by ``denoiser`` (``off``: ``result`` itself); the
    statistics say which and how long it took (``denoise``, ``denoise_ms``). ``scene``: the
    (posed) scene the frame was traced of."""
    if denoiser == Denoiser.OFF or result.display is None:
        return result
    if denoiser not in (Denoiser.OIDN, Denoiser.ATROUS):
        raise ValueError(f"unknown denoiser {denoiser!r}")
    t0 = time.perf_counter()
    color = np.ascontiguousarray(result.image, np.float32)
    if result.guides is not None:
        albedo, normal = (np.ascontiguousarray(g, np.float32) for g in result.guides)
    else:
        albedo = first_hit_albedo(scene, result.primid)
        normal = np.ascontiguousarray(result.normal, np.float32)
    if denoiser == Denoiser.ATROUS:
        image = atrous(color, albedo, normal, result.samples or 1)  # a path frame says its samples
    else:
        image = oidn(color, albedo, normal)
    np.maximum(image, 0.0, out=image)  # (its own array: no copy of the frame's size)
    stats = {**(result.stats or {}), "denoise": denoiser, "denoise_ms": (time.perf_counter() - t0) * 1e3}
    return dataclasses.replace(result, image=image, stats=stats)


_oidn_lock = threading.Lock()  # one denoise at a time: one scratch in the process
_oidn_device: Any = None  # kept (its threads and weights); filters are not


def oidn(color: np.ndarray, albedo: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """float32 H×W×3: OIDN's RT filter (quality high, HDR) of ``color`` guided by ``albedo`` and
    ``normal`` (float32 H×W×3, contiguous), through a filter made for this call and released after
    it, so that its scratch (OIDN_BYTES_PER_PIXEL) goes with it."""
    import pyoidn  # ships the library in its wheel; imported when a frame first asks for it

    global _oidn_device
    out = np.empty_like(color)
    with _oidn_lock:
        if _oidn_device is None:
            device = pyoidn.Device()
            device.commit()
            if (error := device.get_error()) is not None:
                device.release()
                raise RuntimeError(f"OIDN: no device: {error}")
            _oidn_device = device
        device = _oidn_device
        flt = pyoidn.Filter(device, pyoidn.OIDN_FILTER_TYPE_RT)
        try:
            for name, image in (("color", color), ("albedo", albedo), ("normal", normal), ("output", out)):
                flt.set_image(name, image, pyoidn.OIDN_FORMAT_FLOAT3)
            flt.set_bool("hdr", True)
            flt.set_quality(pyoidn.OIDN_QUALITY_HIGH)
            flt.commit()
            flt.execute()
            error = device.get_error()
        finally:
            flt.release()
    if error is not None:
        raise RuntimeError(f"OIDN: {error}")
    return out

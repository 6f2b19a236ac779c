"""The edge-avoiding à-trous wavelet filter (Dammertz et al. 2010, "Edge-Avoiding À-Trous
Wavelet Transform for fast Global Illumination Filtering"): the ``denoise=atrous`` setting.

This NumPy code is the reference of the GLSL copy that a browser runs in device mode
(``ATROUS_FS`` in client_web/js/device/device_gl.js; tests/browser/test_device_denoise.py holds
the two equal), and the server runs it on its own frames too. Both work in float32.

``ATROUS_ITERATIONS`` passes of the 5 × 5 B3-spline kernel (1, 4, 6, 4, 1)/16 with holes: pass i
reads taps ``2^i`` pixels apart (steps 1, 2, 4, 8, 16 cover 125 × 125 pixels in five passes of 25
taps). A tap q of pixel p weighs ``h(dx)·h(dy)·exp(−|c_p−c_q|²/σ_c,i² − |n_p−n_q|²/σ_n² −
|a_p−a_q|²/σ_a²)`` where c is the colour compressed as c/(1+c) (radiance is unbounded: the
compression keeps one σ_c meaningful at any exposure), n the first hit's normal and a its
albedo (the denoiser's guides, renderer/denoise.py; their means over the pixel's samples), and
σ_c,i = σ_c·√(16/s)·2^−i for a mean of s samples: the paper halves the colour's σ each pass
(coarser passes only smooth what is already alike), and the √(16/s) follows the mean's noise,
which shrinks as 1/√s, so that a converging image is filtered less and less (a fixed σ_c
blurred the lighting's gradients into a bias: the 64² Cornell box stayed at 29.2 dB from 32 to
1,024 samples; with it, 31.6 dB at 64 samples and 36.0 dB at 256, where the unfiltered mean has
28.6 and 34.2). Taps outside the image do not count; the output is Σ w·c_q / Σ w of the
uncompressed colour, so a flat region keeps its radiance exactly.
"""

from __future__ import annotations

import math

import numpy as np

ATROUS_ITERATIONS = 5
ATROUS_KERNEL = (1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0)
# The weights' widths, chosen on the 16-sample Cornell box (48 × 48, depth 8) against 1,024 samples of
# the same integrator: 25.0 dB noisy, 27.8 dB filtered (σ_c 0.25 … 2, σ_n 0.1 … 1, σ_a 0.05 … 1 tried).
ATROUS_SIGMA_COLOR = 0.6  # compressed colour c/(1+c), at the first pass (halved each pass) …
ATROUS_SIGMA_SAMPLES = 16  # … of a mean of this many samples (× √(this / samples) for another count)
ATROUS_SIGMA_NORMAL = 0.3  # the normal guide's difference (unit normals: 0 … 2)
ATROUS_SIGMA_ALBEDO = 0.3  # the albedo guide's difference


def atrous(color: np.ndarray, albedo: np.ndarray, normal: np.ndarray, samples: int) -> np.ndarray:
    """float32 H×W×3: ``color`` (linear radiance, H×W×3, the mean of ``samples`` samples per pixel)
    filtered with the guides ``albedo`` and ``normal`` (H×W×3 each, the means the GUIDES variant
    writes)."""
    c = np.asarray(color, np.float32)
    h, w = c.shape[:2]
    kernel = np.asarray(ATROUS_KERNEL, np.float32)
    sigma_c = color_sigma(samples)
    # The guides scaled by 1/σ once: a tap's guide term is then a squared distance of 6 channels.
    guides = np.concatenate(
        [np.asarray(normal, np.float32) / ATROUS_SIGMA_NORMAL, np.asarray(albedo, np.float32) / ATROUS_SIGMA_ALBEDO],
        axis=-1,
    )
    for i in range(ATROUS_ITERATIONS):
        step = 1 << i
        scaled = c / (np.float32(1.0) + np.maximum(c, np.float32(0.0))) / np.float32(sigma_c * 0.5**i)
        features = np.concatenate([scaled, guides], axis=-1)
        total = c * kernel[2] * kernel[2]  # the centre tap: weight h(0)², distance 0
        weights = np.full((h, w, 1), kernel[2] * kernel[2], np.float32)
        # A tap's weight is symmetric (w(p, q) = w(q, p), h(j)·h(k) = h(4−j)·h(4−k)): each pair of
        # pixels d apart is weighed once and added to both.
        for j, k in _HALF:
            dy, dx = (j - 2) * step, (k - 2) * step
            # The pixels whose tap (y + dy, x + dx) lies inside the image, and those taps.
            ys, yd = _span(h, dy)
            xs, xd = _span(w, dx)
            if ys.start >= ys.stop or xs.start >= xs.stop:
                continue
            d = features[yd, xd] - features[ys, xs]
            wt = kernel[j] * kernel[k] * np.exp(-np.einsum("...k,...k->...", d, d))[..., None]
            total[ys, xs] += wt * c[yd, xd]
            weights[ys, xs] += wt
            total[yd, xd] += wt * c[ys, xs]
            weights[yd, xd] += wt
        c = total / weights
    return c.astype(np.float32)


def color_sigma(samples: int) -> float:
    """σ_c of the first pass for a mean of ``samples`` samples per pixel."""
    return ATROUS_SIGMA_COLOR * math.sqrt(ATROUS_SIGMA_SAMPLES / max(1, int(samples)))


def parameters() -> dict[str, object]:
    """The filter's parameters as JSON (device-data's ``path.atrous``: the device's GLSL copy reads
    them, so that they are declared here alone)."""
    return {
        "iterations": ATROUS_ITERATIONS,
        "kernel": list(ATROUS_KERNEL),
        "sigma_color": ATROUS_SIGMA_COLOR,
        "sigma_samples": ATROUS_SIGMA_SAMPLES,
        "sigma_normal": ATROUS_SIGMA_NORMAL,
        "sigma_albedo": ATROUS_SIGMA_ALBEDO,
    }


# One tap of each symmetric pair of the 5 × 5 kernel (the 12 before the centre in row order).
_HALF = [(j, k) for j in range(5) for k in range(5) if (j, k) < (2, 2)]


def _span(size: int, d: int) -> tuple[slice, slice]:
    """The slice of pixels whose tap ``d`` away is inside ``range(size)``, and the taps' slice."""
    lo, hi = max(0, -d), min(size, size - d)
    return slice(lo, hi), slice(lo + d, hi + d)

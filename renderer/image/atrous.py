"""The edge-avoiding à-trous wavelet filter (Dammertz et al. 2010, "Edge-Avoiding À-Trous
Wavelet Transform for fast Global Illumination Filtering"), with the luminance edge-stopping of
SVGF (Schied et al. 2017, "Spatiotemporal Variance-Guided Filtering"): the ``denoise=atrous``
setting.

This NumPy code is the reference of the GLSL copy that a browser runs in device mode
(``ATROUS_PRE_FS`` and ``ATROUS_FS`` in client_web/js/device/device_gl.js;
tests/browser/test_device_denoise.py holds the two equal), and the server runs it on its own
frames too. Both work in float32.

1. **Demodulation.** The colour is divided by the first hit's albedo (the guide, at least
   ``ATROUS_ALBEDO_FLOOR``): what is filtered is the lighting, which is smooth where the albedo
   is not, and the albedo multiplies the filtered lighting back at the end, so that a texture
   or an edge between two colours keeps its sharpness whatever the filter does.
2. **Variance and fireflies** (one pass). Each pixel's luminance l, compressed as y/(1+y) so
   that one width means the same at any exposure, is compared with the pixels around it that its
   guides call alike (weight exp(−|g_p−g_q|²), the pixel itself left out). Its variance v is the
   least of the four 3 × 3 quadrants of its 5 × 5 neighbourhood that meet at the pixel (and that
   the image's border leaves more than two pixels): one of them lies on the pixel's side of an edge or a pattern that
   the guides do not show (a mirror's reflection, a shadow), so v measures the noise, not the
   detail. A pixel brighter than the
   neighbourhood's μ + ``ATROUS_FIREFLY_SIGMAS``·√v is scaled down to it (a path that found a
   light by luck: spread by the wavelet over 125 × 125 pixels, it makes a blotch).
3. ``ATROUS_ITERATIONS`` passes of the 5 × 5 B3-spline kernel (1, 4, 6, 4, 1)/16 with holes: pass i
   reads taps ``2^i`` pixels apart (steps 1, 2, 4, 8, 16 cover 125 × 125 pixels). A tap q of pixel
   p weighs ``h(dx)·h(dy)·exp(−|n_p−n_q|²/σ_n² − |a_p−a_q|²/σ_a² − |l_p−l_q| / (σ_l·√v_p))``
   (n the first hit's normal, a its albedo: the denoiser's guides, renderer/image/denoise.py, their
   means over the pixel's samples). The luminance term is relative to the pixel's own noise: a
   difference that noise explains is smoothed, a shadow's edge or a mirror's reflected detail,
   larger than the noise, is kept. A width set by the sample count alone cannot tell the two
   apart: at a few samples it is wide enough to smooth away whatever the normal and albedo do
   not show (a mirror's or a glass's whole image, contact shadows) and the coarse passes step
   across edges. Each pass carries the variance of its output, Σ w²·v_q / (Σ w)², so that the
   next pass's width follows the noise that is left. The variance a single image measures still
   counts some of its detail (a gradient) as noise: past ``ATROUS_NOISE_SAMPLES`` samples the
   noise of the mean goes on shrinking as 1/√s while the detail stays, so σ_l shrinks as
   √(ATROUS_NOISE_SAMPLES / s) and a converging image is left more and more alone (the Cornell
   box's and the table's 1,024-sample means, filtered, stay 52.2 and 47.2 dB from themselves;
   with the one width per sample count, 42.8 and 43.7). Taps outside the image do not count; the
   output is Σ w·d_q / Σ w, so a flat region keeps its radiance exactly.
"""

from __future__ import annotations

import math

import numpy as np

ATROUS_ITERATIONS = 5
ATROUS_KERNEL = (1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0)
# The widths, chosen on the Cornell box and the table at 96 × 208 (depth 8), 1, 4 and 16 samples,
# against 1,024 samples of the same integrator (``python -m bench.device_denoise --numpy`` prints the
# table; σ_l 3 … 10 and 4 or 8 noise samples tried).
ATROUS_SIGMA_NORMAL = 0.2  # the normal guide's difference (unit normals: 0 … 2)
ATROUS_SIGMA_ALBEDO = 0.2  # the albedo guide's difference
ATROUS_SIGMA_LUMINANCE = 8.0  # the compressed luminance's difference, in standard deviations of its noise …
ATROUS_NOISE_SAMPLES = 8  # … up to this many samples (× √(this / samples) for more)
ATROUS_QUADRANT_PIXELS = 3  # a quadrant of the noise estimate counts with this many pixels in the image
ATROUS_FIREFLY_SIGMAS = 3.0  # a pixel's luminance at most this many standard deviations over its neighbours'
ATROUS_ALBEDO_FLOOR = 0.02  # demodulation divides by the albedo, at least this (a black surface, a miss)
ATROUS_VARIANCE_FLOOR = 1e-8  # √ of it added to σ_l·√v: a noiseless flat region divides by no zero
LUMINANCE = (0.2126, 0.7152, 0.0722)  # Rec. 709, linear


def atrous(color: np.ndarray, albedo: np.ndarray, normal: np.ndarray, samples: int) -> np.ndarray:
    """float32 H×W×3: ``color`` (linear radiance, H×W×3, the mean of ``samples`` samples per pixel)
    filtered with the guides ``albedo`` and ``normal`` (H×W×3 each, the means the GUIDES variant writes)."""
    a = np.maximum(np.asarray(albedo, np.float32), np.float32(ATROUS_ALBEDO_FLOOR))
    d = np.asarray(color, np.float32) / a
    h, w = d.shape[:2]
    kernel = np.asarray(ATROUS_KERNEL, np.float32)
    # The guides scaled by 1/σ once: a tap's guide term is then a squared distance of 6 channels.
    guides = np.concatenate(
        [np.asarray(normal, np.float32) / ATROUS_SIGMA_NORMAL, np.asarray(albedo, np.float32) / ATROUS_SIGMA_ALBEDO],
        axis=-1,
    )
    d, variance = _moments(d, guides)
    inv_sigma = np.float32(1.0 / luminance_sigma(samples))
    for i in range(ATROUS_ITERATIONS):
        step = 1 << i
        lum = _compressed_luminance(d)
        scale = inv_sigma / (np.sqrt(variance) + np.float32(np.sqrt(ATROUS_VARIANCE_FLOOR)))
        total = np.zeros_like(d)
        weights = np.zeros((h, w), np.float32)
        var_sum = np.zeros((h, w), np.float32)
        for j in range(5):
            for k in range(5):
                ys, yd = _span(h, (j - 2) * step)
                xs, xd = _span(w, (k - 2) * step)
                if ys.start >= ys.stop or xs.start >= xs.stop:
                    continue
                g = guides[yd, xd] - guides[ys, xs]
                e = np.einsum("...k,...k->...", g, g) + np.abs(lum[yd, xd] - lum[ys, xs]) * scale[ys, xs]
                wt = kernel[j] * kernel[k] * np.exp(-e)
                total[ys, xs] += wt[..., None] * d[yd, xd]
                weights[ys, xs] += wt
                var_sum[ys, xs] += wt * wt * variance[yd, xd]
        d = total / weights[..., None]  # the centre tap weighs h(0)² > 0: never empty
        variance = var_sum / (weights * weights)
    return (d * a).astype(np.float32)


def luminance_sigma(samples: int) -> float:
    """σ_l for a mean of ``samples`` samples per pixel."""
    return ATROUS_SIGMA_LUMINANCE * min(1.0, math.sqrt(ATROUS_NOISE_SAMPLES / max(1, int(samples))))


def _compressed_luminance(d: np.ndarray) -> np.ndarray:
    """y/(1+y) of the luminance y of ``d`` (negative channels as 0): H×W float32 in [0, 1)."""
    y = np.maximum(d, np.float32(0.0)) @ np.asarray(LUMINANCE, np.float32)
    return y / (np.float32(1.0) + y)


def _moments(d: np.ndarray, guides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The first pass: each pixel's noise and its fireflies, from the alike pixels around it (weight
    exp(−|g_p−g_q|²), the pixel itself left out, luminances about its own so that the sums keep
    their digits). The variance is the least of the four 3 × 3 quadrants of its 5 × 5 neighbourhood
    that meet at the pixel: one of them lies on the pixel's side of an edge or a pattern the guides
    do not show, so that it measures noise, not detail; the firefly's bound, μ + k·√v, is of the
    whole neighbourhood. → (``d`` with each firefly scaled down to its bound, the variance)."""
    h, w = d.shape[:2]
    lum = _compressed_luminance(d)
    zero = np.zeros((h, w), np.float32)
    # per quadrant Σw, Σw·l, Σw·l² and its pixels inside the image
    quadrants = [[zero.copy(), zero.copy(), zero.copy(), zero.copy()] for _ in range(4)]
    every = [zero.copy(), zero.copy(), zero.copy()]
    for dy in range(-2, 3):
        for dx in range(-2, 3):
            ys, yd = _span(h, dy)
            xs, xd = _span(w, dx)
            if (dy == 0 and dx == 0) or ys.start >= ys.stop or xs.start >= xs.stop:
                continue
            g = guides[yd, xd] - guides[ys, xs]
            wt = np.exp(-np.einsum("...k,...k->...", g, g))
            lq = lum[yd, xd] - lum[ys, xs]
            terms = (wt, wt * lq, wt * lq * lq)
            for k, sums in enumerate(quadrants):
                if dy * (1 if k & 2 else -1) >= 0 and dx * (1 if k & 1 else -1) >= 0:
                    for total, term in zip(sums, terms, strict=False):
                        total[ys, xs] += term
                    sums[3][ys, xs] += np.float32(1.0)
            for total, term in zip(every, terms, strict=True):
                total[ys, xs] += term
    # A quadrant that the image's border cuts to fewer than ATROUS_QUADRANT_PIXELS pixels is no
    # candidate: two pixels' variance is often near 0 by chance, and the least of the four would
    # then stop all smoothing along the border; with no candidate, the whole neighbourhood's.
    variance = np.full((h, w), np.inf, np.float32)
    for s0, s1, s2, inside in quadrants:
        fits = inside >= np.float32(ATROUS_QUADRANT_PIXELS)
        variance = np.minimum(variance, np.where(fits, _variance(s0, s1, s2), np.float32(np.inf)))
    s0, s1, s2 = every
    variance = np.where(np.isinf(variance), _variance(s0, s1, s2), variance).astype(np.float32)
    offset = np.where(s0 > 0, s1 / np.maximum(s0, np.float32(1e-30)), np.float32(0.0))
    spread = np.float32(ATROUS_FIREFLY_SIGMAS) * np.sqrt(_variance(s0, s1, s2))
    top = np.minimum(lum + offset + spread, np.float32(0.999))
    # compressed t ↔ luminance t/(1−t): a firefly's colour scaled by (its allowed luminance / its own)
    bright = lum > top
    y = lum / (np.float32(1.0) - lum)
    allowed = top / (np.float32(1.0) - top)
    factor = np.where(bright, allowed / np.maximum(y, np.float32(1e-30)), np.float32(1.0)).astype(np.float32)
    return d * factor[..., None], variance


def _variance(s0: np.ndarray, s1: np.ndarray, s2: np.ndarray) -> np.ndarray:
    """Σw·x² / Σw − (Σw·x / Σw)², at least 0 (0 where no weight)."""
    n = np.maximum(s0, np.float32(1e-30))
    m = s1 / n
    return np.where(s0 > 0, np.maximum(s2 / n - m * m, np.float32(0.0)), np.float32(0.0)).astype(np.float32)


def parameters() -> dict[str, object]:
    """The filter's parameters as JSON (device-data's ``path.atrous``: the device's GLSL copy reads
    them, so that they are declared here alone)."""
    return {
        "iterations": ATROUS_ITERATIONS,
        "kernel": list(ATROUS_KERNEL),
        "sigma_normal": ATROUS_SIGMA_NORMAL,
        "sigma_albedo": ATROUS_SIGMA_ALBEDO,
        "sigma_luminance": ATROUS_SIGMA_LUMINANCE,
        "noise_samples": ATROUS_NOISE_SAMPLES,
        "firefly_sigmas": ATROUS_FIREFLY_SIGMAS,
        "quadrant_pixels": ATROUS_QUADRANT_PIXELS,
        "albedo_floor": ATROUS_ALBEDO_FLOOR,
        "variance_floor": ATROUS_VARIANCE_FLOOR,
        "luminance": list(LUMINANCE),
    }


def _span(size: int, d: int) -> tuple[slice, slice]:
    """The slice of pixels whose tap ``d`` away is inside ``range(size)``, and the taps' slice."""
    lo, hi = max(0, -d), min(size, size - d)
    return slice(lo, hi), slice(lo + d, hi + d)

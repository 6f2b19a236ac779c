"""Image comparisons and filters: PSNR, SSIM, largest difference, upscaling, box filter."""

from __future__ import annotations

import math

import numpy as np


def psnr(ref: np.ndarray, img: np.ndarray) -> float:
    """PSNR in dB of two float images in [0, 1] (∞ when identical), scikit-image's definition."""
    from skimage.metrics import peak_signal_noise_ratio

    a = np.clip(ref, 0.0, 1.0).astype(np.float64)
    b = np.clip(img, 0.0, 1.0).astype(np.float64)
    if np.array_equal(a, b):
        return math.inf
    return float(peak_signal_noise_ratio(a, b, data_range=1.0))


def ssim(ref: np.ndarray, img: np.ndarray) -> float:
    """Structural similarity (scikit-image), colour images in [0, 1]."""
    from skimage.metrics import structural_similarity

    a = np.clip(ref, 0.0, 1.0).astype(np.float64)
    b = np.clip(img, 0.0, 1.0).astype(np.float64)
    win = min(7, a.shape[0], a.shape[1])
    win -= (win + 1) % 2  # odd
    return float(structural_similarity(a, b, channel_axis=2, data_range=1.0, win_size=max(3, win)))


def max_abs(ref: np.ndarray, img: np.ndarray) -> float:
    return float(np.max(np.abs(np.clip(ref, 0, 1).astype(np.float64) - np.clip(img, 0, 1).astype(np.float64))))


def upscale(img: np.ndarray, width: int, height: int) -> np.ndarray:
    """Bilinear upscaling of a float H×W×3 image (Pillow, per channel, pixel centres aligned)."""
    from PIL import Image

    chans = [
        np.asarray(
            Image.fromarray(np.ascontiguousarray(img[..., c], dtype=np.float32), mode="F").resize(
                (width, height), Image.BILINEAR
            )
        )
        for c in range(img.shape[2])
    ]
    return np.stack(chans, axis=2)

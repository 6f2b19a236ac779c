"""The two render profiles the speed-against-accuracy experiment recommends.

``bench/experiments/pareto.py`` measures time to image and error (PSNR, SSIM,
max error) against a float64 depth-8, 4×4-supersampled reference for every
knob that trades one for the other, and names the fastest setting that keeps
quality (docs/RESULTS.md, "Speed against accuracy": scenarios 1–3, 256 spheres,
320 × 544, 5 runs). ``/api/info`` hands both to the client, which asks for
``INTERACTIVE`` frames while a finger moves (depth capped at the session's).
``STILL`` is the service's default for new sessions (``server.config``): the
frames a session shows at rest. Frames traced on the device (WebGL2) use the
session's depth but trace every ray at one sample per pixel.

``resolution_scale``: the frame is rendered at 1/scale of the requested
resolution and upscaled by the client.
"""

from __future__ import annotations

# Measured on 2026-11-23 (llvmpipe, 2 cores). interactive: 110.4 ms mean, worst PSNR 36.89 dB,
# SSIM 0.9750 (the old default, depth 5 without cut-off: 143.6 ms, 37.52 dB). still: 531.1 ms,
# worst PSNR 45.16 dB, SSIM 0.9957.
INTERACTIVE: dict = {"max_recursion_depth": 8, "samples_per_pixel": 1, "min_weight": 0.3, "resolution_scale": 1}
STILL: dict = {"max_recursion_depth": 8, "samples_per_pixel": 4, "min_weight": 0.03, "resolution_scale": 1}

PROFILES = {"interactive": INTERACTIVE, "still": STILL}

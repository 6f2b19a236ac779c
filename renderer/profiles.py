"""The two render profiles the speed-against-accuracy experiment recommends.

``bench/experiments/pareto.py`` measures time to image and error (PSNR, SSIM,
max error) against a float64 depth-8, 4×4-supersampled reference for every
knob that trades one for the other, and names the fastest setting that keeps
quality (docs/RESULTS.md, "Speed against accuracy"). The service uses them:
``STILL`` is every session's default frame, ``INTERACTIVE`` the frames a client
asks for while a finger moves (``/api/info`` hands both to the client).

``resolution_scale``: the frame is rendered at 1/scale of the requested
resolution and upscaled by the client.
"""

from __future__ import annotations

INTERACTIVE: dict = {"max_recursion_depth": 5, "samples_per_pixel": 1, "min_weight": 0.0, "resolution_scale": 2}
STILL: dict = {"max_recursion_depth": 5, "samples_per_pixel": 1, "min_weight": 0.0, "resolution_scale": 1}

PROFILES = {"interactive": INTERACTIVE, "still": STILL}

"""The two measured render profiles (renderer.frame.profiles): valid render settings, interactive
cheaper than still. (That ``/api/info`` hands them out and new sessions start at ``STILL`` is
tested in ``tests/server/api/routes/test_meta.py``.)"""

from __future__ import annotations

from renderer.config.settings import RenderSettings
from renderer.frame.profiles import INTERACTIVE, PROFILES, STILL


def test_each_profile_is_valid_render_settings():
    assert PROFILES == {"interactive": INTERACTIVE, "still": STILL}
    for profile in PROFILES.values():
        engine = {k: v for k, v in profile.items() if k != "resolution_scale"}  # the client's, not the engine's
        RenderSettings(width=64, height=64, **engine)


def test_interactive_frames_trace_less_than_still_ones():
    assert INTERACTIVE["samples_per_pixel"] <= STILL["samples_per_pixel"]
    assert INTERACTIVE["min_weight"] >= STILL["min_weight"]
    assert INTERACTIVE["max_recursion_depth"] <= STILL["max_recursion_depth"]

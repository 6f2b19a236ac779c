"""The service's settings (server/config.py)."""

from __future__ import annotations


def test_new_sessions_default_to_the_still_profile(tmp_path):
    """Without default_render, a session's settings are RenderSettings' plus the measured 'still'
    profile, and the default work cap admits it at the client's largest 'fit' frame."""
    from renderer.frame.profiles import STILL
    from server.config import ServerConfig

    config = ServerConfig(sqlite_path=tmp_path / "s.db")
    d = config.default_settings()
    for k in ("max_recursion_depth", "samples_per_pixel", "min_weight"):
        assert d[k] == STILL[k], k
    assert 1088 * 1088 * d["max_recursion_depth"] * d["samples_per_pixel"] <= config.max_work
    # default_render still overrides the profile.
    pinned = ServerConfig(sqlite_path=tmp_path / "t.db", default_render={"samples_per_pixel": 1})
    assert pinned.default_settings()["samples_per_pixel"] == 1

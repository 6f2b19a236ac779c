"""Progressive frames in the client: a supersampled full frame shows its
pixel-centre image first and then the refined one — from the server's multipart answer, and
in device mode from the device's own pixel-centre phase."""

from __future__ import annotations

from browser_support import FAILED_LOAD, FAST_QUERY


def parts_at_full(log: list[dict]) -> list[str]:
    return [e["part"] for e in log if e["level"] == "full"]


def test_a_supersampled_full_frame_arrives_as_preview_then_final(open_client):
    c = open_client(query=FAST_QUERY + "&samples_per_pixel=4")
    c.wait_idle(min_frames=2)
    log = c.hook("log")
    parts = parts_at_full(log)
    assert parts[:2] == ["preview", "final"], log
    first, final = (next(e for e in log if e["level"] == "full" and e["part"] == p) for p in ("preview", "final"))
    assert first["clientMs"] < final["clientMs"]  # the first image came before the refined one
    assert c.hook("lastFrame.part") == "final"  # the refined image stays on screen
    assert c.errors(allow=(FAILED_LOAD,)) == []


def test_one_sample_per_pixel_has_no_preview(open_client):
    c = open_client(query=FAST_QUERY + "&samples_per_pixel=1")
    c.wait_idle(min_frames=1)
    assert "preview" not in parts_at_full(c.hook("log"))


def test_device_mode_refines_the_same_way(open_client):
    c = open_client(query=FAST_QUERY + "&samples_per_pixel=4&renderer=device")
    c.wait_idle(min_frames=2, timeout=120_000)
    log = [e for e in c.hook("log") if e["renderer"] == "device"]
    assert [e["part"] for e in log if e["level"] == "full"][:2] == ["preview", "final"], log

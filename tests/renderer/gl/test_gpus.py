"""The GPUs EGL lists (renderer.gl.gpus). ``pocketray gpus --probe`` (a context made in a child
process on each) is tested with the command line, in ``tests/server/test_cli.py``."""

from __future__ import annotations

from renderer.gl.gpus import list_gpus


def test_every_gpu_has_its_index_in_egls_order_and_a_kind():
    gpus = list_gpus()
    assert gpus, "EGL lists at least the device the tests' contexts run on"
    assert [g["index"] for g in gpus] == list(range(len(gpus)))
    for g in gpus:
        assert g["kind"] in ("software", "nvidia", "gpu", "other") and isinstance(g["extensions"], list)
        assert (g["kind"] == "software") == ("EGL_MESA_device_software" in g["extensions"])

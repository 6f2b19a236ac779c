"""The registry of methods (renderer.config.methods): every method is registered and prepares
a scene; ``auto`` picks brute force below the measured crossover and the BIH from it."""

from __future__ import annotations

import pytest

from renderer.config.methods import AUTO_CROSSOVER_N, AUTO_METHOD, METHODS, mesh_methods, not_on_gpu, resolve_method
from renderer.config.settings import RenderSettings
from renderer.scenes.scenarios import scenario


def test_auto_method_uses_crossover():
    assert resolve_method("auto", AUTO_CROSSOVER_N - 1) == "bruteforce"
    assert resolve_method("auto", AUTO_CROSSOVER_N) == "bih"
    assert resolve_method("bih", 1) == "bih"


def test_methods_registered():
    assert {"bvh", "kdtree"} <= set(METHODS)
    RenderSettings(method="bvh")
    RenderSettings(method="kdtree")


def test_registered_like_the_other_methods():
    for name in ("rayengine", "hre"):
        assert name in METHODS
        prep = METHODS[name].prepare(scenario(1, 8), 8, 64)
        assert prep.stats["method"] == name
    assert RenderSettings(method="hre").method == "hre"


def test_bruteforce_refuses_more_primitives_than_one_shader_loop_runs():
    """llvmpipe ends a loop after 65,535 iterations without an error: brute force over more
    primitives would silently drop the last ones, so such a scene is refused naming the method."""
    from renderer.config.methods import check_primitives
    from renderer.geometry.scene import SceneError
    from renderer.limits import MAX_LOOP_PRIMITIVES
    from renderer.scenes.scenarios import scenario

    check_primitives("bruteforce", scenario(1, MAX_LOOP_PRIMITIVES))
    with pytest.raises(SceneError) as e:
        check_primitives("bruteforce", scenario(1, MAX_LOOP_PRIMITIVES + 1))
    assert e.value.field == "method" and "65,533" in str(e.value)
    check_primitives("bih", scenario(1, MAX_LOOP_PRIMITIVES + 1))  # a hierarchy has no such loop


def test_the_methods_that_trace_meshes_are_read_from_their_capabilities(monkeypatch):
    """The list a refusal names is the registry's: every method whose layout holds triangles, and
    auto while every method it picks does; a method without them drops out of it."""
    import dataclasses

    traced = [n for n, m in METHODS.items() if m.capabilities.meshes_on_gpu]
    assert mesh_methods() == [*traced, AUTO_METHOD] and "rayengine" not in traced and "bih" in traced
    assert not_on_gpu().endswith(", ".join(mesh_methods()))
    bf = METHODS["bruteforce"]
    monkeypatch.setattr(bf, "capabilities", dataclasses.replace(bf.capabilities, meshes_on_gpu=False))
    assert "bruteforce" not in mesh_methods() and AUTO_METHOD not in mesh_methods()  # auto picks it below the crossover

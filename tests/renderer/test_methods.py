"""The registry of methods (renderer.methods): every method is registered and prepares
a scene; ``auto`` picks brute force below the measured crossover and the BIH from it."""

from __future__ import annotations

from renderer.methods import AUTO_CROSSOVER_N, METHODS, resolve_method
from renderer.scenarios import scenario
from renderer.settings import RenderSettings


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

"""Methods ``rayengine`` and ``hre`` (renderer.accel.ray_engine) without a GPU: nothing to
build, spheres and planes only, and the tile of rays each culls by. Their passes are
tested on the GPU in ``tests/renderer/gl/test_ray_engine.py``."""

from __future__ import annotations

import pytest

from renderer.accel.ray_engine import SPHERES_AND_PLANES, HierarchicalRayEngine, RayEngine
from renderer.limits import STENCIL_BITS
from renderer.scenes.scenarios import scenario


@pytest.mark.parametrize("method", [RayEngine(), HierarchicalRayEngine()])
def test_prepare_builds_and_packs_nothing(method):
    s = scenario(2, 64)
    prep = method.prepare(s, 4, 64)
    assert prep.packed.textures == {} and prep.packed.uniforms == {}
    assert prep.stats == {"method": method.name, "primitives": s.n_primitives, "multi_pass": True}
    caps = method.capabilities
    assert caps.multi_pass and caps.tests_every_sphere and caps.primitives == SPHERES_AND_PLANES
    assert method.stencil_bits == STENCIL_BITS


def test_the_ray_engine_traces_every_ray_alone_and_hre_by_tiles():
    assert [RayEngine().tile(t) for t in (2, 16, 64)] == [1, 1, 1]
    assert [HierarchicalRayEngine().tile(t) for t in (2, 16, 64)] == [2, 16, 64]
    assert "tile_size" in HierarchicalRayEngine.capabilities.settings
    assert "cones" in HierarchicalRayEngine.capabilities.modes and "cones" not in RayEngine.capabilities.modes

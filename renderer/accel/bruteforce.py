"""Method ``bruteforce``: every ray tests every sphere (the thesis's "BF" series) — and
every triangle, once the GPU traces them (until then a scene with meshes is refused when its
frame is uploaded, :class:`~renderer.accel.base.NotOnGPU`).

No structure: ``shaders/method_bruteforce.glsl`` loops over the sphere records in id
order (``u_bf_spheres``, :func:`renderer.gpu_layout.sphere_records`: 16 bytes a sphere
when the radii are equal, else 32), a record array the host may put in a uniform block.
"""

from __future__ import annotations

import numpy as np

from .. import gpu_layout
from ..gpu_layout import Binding, wrap_rows
from ..limits import DEFAULT_TEXTURE_WIDTH
from ..scene import Scene
from ..tree_update import REBUILD, TreeUpdate
from .base import Capabilities, PreparedMethod, gpu_data, mesh_stats

SPHERES = Binding("u_bf_spheres", doc="spheres in id order (gpu_layout.sphere_records)", records=True)


class BruteForce:
    name = "bruteforce"
    capabilities = Capabilities(shader="method_bruteforce.glsl", tests_every_sphere=True)
    bindings = (SPHERES,)

    @staticmethod
    def glsl_defines() -> str:
        return ""

    def prepare(self, scene: Scene, max_prims: int, max_tree_depth: int,
                max_width: int = DEFAULT_TEXTURE_WIDTH, update: TreeUpdate = REBUILD) -> PreparedMethod:
        return PreparedMethod(
            gpu_data(scene, lambda: gpu_layout.PackedScene(
                {SPHERES.name: wrap_rows(gpu_layout.sphere_records(scene, np.arange(scene.n_spheres)), max_width)})),
            0.0, {"method": self.name, "primitives": scene.n_spheres + scene.n_triangles, **mesh_stats(scene)})

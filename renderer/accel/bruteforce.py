"""Method ``bruteforce``: every ray tests every sphere (the thesis's "BF" series) — and
every triangle, once the GPU traces them (until then a scene with meshes is refused when its
frame is uploaded, :class:`~renderer.accel.base.NotOnGPU`).

No structure: ``shaders/method_bruteforce.glsl`` loops over the sphere texture.
"""

from __future__ import annotations

from .. import gpu_layout
from ..limits import DEFAULT_TEXTURE_WIDTH
from ..scene import Scene
from ..tree_update import REBUILD, TreeUpdate
from .base import Capabilities, NoLayout, PreparedMethod, gpu_data, mesh_stats


class BruteForce(NoLayout):
    name = "bruteforce"
    capabilities = Capabilities(shader="method_bruteforce.glsl", tests_every_sphere=True)

    def prepare(self, scene: Scene, max_prims: int, max_tree_depth: int,
                max_width: int = DEFAULT_TEXTURE_WIDTH, update: TreeUpdate = REBUILD) -> PreparedMethod:
        return PreparedMethod(gpu_data(scene, lambda: gpu_layout.PackedScene({})), 0.0,
                              {"method": self.name, "primitives": scene.n_spheres + scene.n_triangles,
                               **mesh_stats(scene)})

"""Method ``bruteforce``: every ray tests every sphere (the thesis's "BF" series), every
triangle and every analytic shape.

No structure: ``shaders/method_bruteforce.glsl`` loops over the sphere records in id
order (``u_bf_spheres``, :func:`renderer.gpu.gpu_layout.sphere_records`: 16 bytes a sphere
when the radii are equal, else 32), a record array the host may put in a uniform block,
then — in a variant with the TRIANGLES data format — over the triangle records in id order
(``u_triangles``, :func:`renderer.gpu.gpu_layout.triangle_records`), and with SHAPES over the
analytic shapes' (``u_shapes``, :func:`renderer.gpu.gpu_layout.shape_records`).
"""

from __future__ import annotations

import numpy as np

from ..geometry.scene import Scene
from ..gpu import gpu_layout
from ..gpu.gpu_layout import Binding, wrap_rows
from ..limits import DEFAULT_TEXTURE_WIDTH, MAX_LOOP_PRIMITIVES
from ..scenes.tree_update import REBUILD, TreeUpdate
from .base import Capabilities, PreparedMethod, mesh_stats

SPHERES = Binding("u_bf_spheres", doc="spheres in id order (gpu_layout.sphere_records)", records=True)


class BruteForce:
    name = "bruteforce"
    label = "Brute force"
    capabilities = Capabilities(
        shader="method_bruteforce.glsl",
        tests_every_sphere=True,
        meshes_on_gpu=True,
        settings=("integrator",),
        max_primitives=MAX_LOOP_PRIMITIVES,
    )
    bindings = (SPHERES, *gpu_layout.TRIANGLE_BINDINGS, *gpu_layout.SHAPE_BINDINGS)

    @staticmethod
    def glsl_defines() -> str:
        return ""

    def prepare(
        self,
        scene: Scene,
        max_prims: int,
        max_tree_depth: int,
        max_width: int = DEFAULT_TEXTURE_WIDTH,
        update: TreeUpdate = REBUILD,
    ) -> PreparedMethod:
        def pack() -> gpu_layout.PackedScene:
            spheres = gpu_layout.PackedScene(
                {SPHERES.name: wrap_rows(gpu_layout.sphere_records(scene, np.arange(scene.n_spheres)), max_width)}
            )
            return gpu_layout.merged(
                spheres, gpu_layout.pack_triangles(scene, max_width), gpu_layout.pack_shapes(scene, max_width)
            )

        return PreparedMethod(
            pack(),
            0.0,
            {
                "method": self.name,
                "primitives": scene.n_tree_primitives,
                **mesh_stats(scene),
            },
        )

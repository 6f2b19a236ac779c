"""Methods ``rayengine`` (Carr et al. 2002) and ``hre`` (Szécsi's hierarchical ray engine, 2006).

Both draw the frame themselves in several GL passes: rays live in float textures and
every primitive is drawn over them (``hre``: culled per tile of rays by a cone), the
depth test keeping the nearest hit. There is no structure to build, so ``prepare``
returns no data; the passes are :mod:`renderer.gl.ray_engine` (described there), which
the GL renderer runs for every method whose capabilities say ``multi_pass``. The cone
construction they use has a float64 mirror in :mod:`renderer.accel.hre_cones`.
"""

from __future__ import annotations

from ..geometry.scene import Scene
from ..gpu import gpu_layout
from ..limits import DEFAULT_TEXTURE_WIDTH, STENCIL_BITS
from ..modes import MODES, SINGLE_PASS_MODES
from ..scenes.tree_update import REBUILD, TreeUpdate
from .base import Capabilities, NoLayout, PreparedMethod

SPHERES_AND_PLANES = ("spheres", "planes")


class RayEngine(NoLayout):
    """Carr et al.'s ray engine: every primitive drawn over every ray."""

    name = "rayengine"
    label = "Ray engine (Carr)"
    hierarchical = False
    # Its passes draw sphere and plane impostors only; triangles would need passes of their own.
    capabilities = Capabilities(
        multi_pass=True, modes=SINGLE_PASS_MODES, tests_every_sphere=True, primitives=SPHERES_AND_PLANES
    )
    stencil_bits = STENCIL_BITS  # bits used, one per generation (§5); fewer: fallback beyond them

    def prepare(
        self,
        scene: Scene,
        max_prims: int,
        max_tree_depth: int,
        max_width: int = DEFAULT_TEXTURE_WIDTH,
        update: TreeUpdate = REBUILD,
    ) -> PreparedMethod:
        """No structure to build: the ray engines need no tree (minimal data for the interface)."""
        return PreparedMethod(
            gpu_layout.PackedScene({}), 0.0, {"method": self.name, "primitives": scene.n_primitives, "multi_pass": True}
        )

    def tile(self, tile_size: int) -> int:
        """The side of a tile of rays: 1 (every ray on its own)."""
        return 1


class HierarchicalRayEngine(RayEngine):
    """Szécsi's hierarchical ray engine: tiles of rays, one cone each, culled in the vertex shader.
    Its ``cones`` mode shows the cones."""

    name = "hre"
    label = "Hierarchical ray engine (Szécsi)"
    hierarchical = True
    capabilities = Capabilities(
        multi_pass=True, modes=MODES, tests_every_sphere=True, settings=("tile_size",), primitives=SPHERES_AND_PLANES
    )

    def tile(self, tile_size: int) -> int:
        """The tile side, the ``tile_size`` setting (the settings bound it by ``limits``; the
        passes check it against the GPU's largest point)."""
        return int(tile_size)

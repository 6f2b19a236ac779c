"""What a scene can use: the basis of "model no more than a scene needs".

A shader variant compiled for a scene without reflective materials has no
reflection code, one without lights no shadow rays, and a scene where nothing
reflects or transmits needs no recursion beyond the primary ray. Each of these
is exact: the image is the one the generic variant renders.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import Scene


# The defines a specialised shader variant may carry, in the order they are emitted.
FEATURE_DEFINES = ("NO_REFLECTION", "NO_TRANSMISSION", "NO_LIGHTS")


@dataclass(frozen=True)
class SceneFeatures:
    reflection: bool
    transmission: bool
    lights: bool

    def defines(self) -> tuple[str, ...]:
        """Shader defines that remove what the scene cannot use."""
        out = []
        if not self.reflection:
            out.append("NO_REFLECTION")
        if not self.transmission:
            out.append("NO_TRANSMISSION")
        if not self.lights:
            out.append("NO_LIGHTS")
        return tuple(out)

    def recursion_depth(self, requested: int) -> int:
        """The deepest level a ray tree can reach in this scene (≤ requested)."""
        return requested if (self.reflection or self.transmission) else 1


GENERIC = SceneFeatures(reflection=True, transmission=True, lights=True)


def scene_features(scene: Scene) -> SceneFeatures:
    """Features of the materials that primitives actually use, and whether there are lights."""
    used = (set(np.unique(scene.sphere_materials).tolist()) | {p.material for p in scene.planes}
            | {m.material for m in scene.meshes})
    mats = [scene.materials[i] for i in used]
    return SceneFeatures(reflection=any(m.reflective > 0 for m in mats),
                         transmission=any(m.transmissive > 0 for m in mats),
                         lights=len(scene.lights) > 0)

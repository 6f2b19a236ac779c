"""How a method may carry its tree over from one frame of an animation to the next.

The thesis rebuilds its BIH for every request. Reiter (§3) asks whether updating the
previous frame's tree is cheaper when the scene moves; his answers are the update
schemes below, used by the methods that keep a tree between frames (``bvh``, and the
BVH half of ``twolevel``). Every other method rebuilds and ignores the update.

- ``rebuild``: a fresh tree every frame (the thesis's way);
- ``refit``: the previous frame's topology, node boxes recomputed bottom-up — fast, exact,
  but the tree degrades when the motion is incoherent;
- ``selective``: refit, then rebuild the subtrees whose SAH cost grew by more than
  ``threshold`` (0.30 = +30 %) since they were built (Reiter §3.1.3).

A tree is updated only from the previous frame *with the same key*: a key names one
animation (the server uses the session id and its scene revision), so two sessions
never refit each other's trees. When the sphere count changes (spheres appearing or
disappearing) an update falls back to a rebuild.
"""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass

import numpy as np

UPDATE_SCHEMES = ("rebuild", "refit", "selective")
DEFAULT_THRESHOLD = 0.30


@dataclass(frozen=True)
class TreeUpdate:
    """One frame's update request.

    scheme: one of ``UPDATE_SCHEMES``. threshold: selective rebuild's cost growth
    (fraction, ≥ 0). key: the animation this frame belongs to (None: one shared slot).
    moving: bool per tree primitive of the posed scene — its spheres, then its triangles
    (:mod:`renderer.accel.primitives`) — True where a motion moves it (the two-level method
    puts the others in its static kd-tree); None = nothing moves.
    """

    scheme: str = "rebuild"
    threshold: float = DEFAULT_THRESHOLD
    key: Hashable | None = None
    moving: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.scheme not in UPDATE_SCHEMES:
            raise ValueError(f"unknown update scheme {self.scheme!r}; one of {', '.join(UPDATE_SCHEMES)}")


REBUILD = TreeUpdate()

"""The Controller: gestures → a new camera (pure functions, thesis chapter III).

- pan: one finger dragged by (dx, dy) screen pixels moves the camera in its own
  x/y plane, camera and target together, so that what is at the target's
  distance follows the finger: a point drawn at pixel (x, y) is drawn at
  (x + dx, y + dy) afterwards (right/down positive, as screen coordinates).
- pinch: two fingers, ``scale`` = new finger distance / old. The camera moves
  along its view axis to distance ``d / scale`` from the target (spread,
  scale > 1: forward, the scene grows by ``scale``; pinch: back). It never
  reaches or passes the target: the distance stays ≥ ``min_distance``.
- reset: the home camera (the one the scene came with).

Everything in float64; the result is a validated :class:`renderer.scene.Camera`,
so a gesture that would leave the coordinate range raises ``SceneError``.
"""

from __future__ import annotations

import math

import numpy as np

from renderer.scene import Camera


def world_per_pixel(camera: Camera, viewport_height: float) -> float:
    """World units per screen pixel at the target's distance (pinhole, vertical fov)."""
    distance = float(np.linalg.norm(np.subtract(camera.target, camera.position)))
    return 2.0 * distance * math.tan(math.radians(camera.fov_y) / 2.0) / float(viewport_height)


def pan(camera: Camera, dx: float, dy: float, viewport_height: float) -> Camera:
    """Move camera and target by (−dx · right + dy · up) · world_per_pixel.

    dx, dy: pixels (right/down positive); viewport_height: pixels of the view's height.
    """
    right, up, _ = camera.basis()
    k = world_per_pixel(camera, viewport_height)
    delta = (-float(dx) * right + float(dy) * up) * k
    return Camera(position=tuple((np.array(camera.position) + delta).tolist()),
                  target=tuple((np.array(camera.target) + delta).tolist()),
                  up=camera.up, fov_y=camera.fov_y)


def pinch(camera: Camera, scale: float, min_distance: float = 1e-3) -> Camera:
    """Move the camera along the view axis to distance d / scale from the target.

    scale > 1 moves forward, < 1 back. Moving forward stops at ``min_distance``
    (world units); a camera already closer than that is not pushed back by it.
    """
    if not (scale > 0.0) or not math.isfinite(scale):
        raise ValueError(f"scale must be a finite number > 0, got {scale}")
    target = np.array(camera.target, dtype=np.float64)
    offset = np.array(camera.position, dtype=np.float64) - target
    distance = float(np.linalg.norm(offset))
    new_distance = distance / scale
    if scale > 1.0:
        new_distance = max(new_distance, min(distance, min_distance))
    position = target + offset * (new_distance / distance)
    return Camera(position=tuple(position.tolist()), target=camera.target, up=camera.up, fov_y=camera.fov_y)


def reset(home: Camera) -> Camera:
    """The home camera."""
    return home

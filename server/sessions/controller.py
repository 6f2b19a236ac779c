"""The Controller: gestures → a new camera (pure functions, thesis chapter III).

- pan: one finger dragged by (dx, dy) screen pixels moves the camera in its own
  x/y plane, camera and target together, so that what is at the target's
  distance follows the finger: a point drawn at pixel (x, y) is drawn at
  (x + dx, y + dy) afterwards (right/down positive, as screen coordinates).
- pinch: two fingers, ``scale`` = new finger distance / old. The camera moves
  along its view axis to distance ``d / scale`` from the target (spread,
  scale > 1: forward, the scene grows by ``scale``; pinch: back). It never
  reaches or passes the target: the distance stays ≥ ``min_distance``.
- orbit: the camera turns about its target, keeping the target and the distance:
  ``yaw`` degrees about the camera's ``up`` vector (a turntable: the horizon stays
  level), then ``pitch`` degrees about its ``right`` vector. Both are right-handed
  rotations of the camera's position about the target (yaw > 0 moves the camera
  towards its right, pitch > 0 moves it down). Pitch is clamped so that the view
  direction stays at least ``MIN_POLAR_DEG`` away from ``up`` and from ``−up``:
  the view never flips over the pole.
- reset: the home camera (the one the scene came with).

Everything in float64; the result is a validated :class:`renderer.geometry.scene.Camera`,
so a gesture that would leave the coordinate range raises ``SceneError``.
"""

from __future__ import annotations

import math

import numpy as np

from renderer.geometry.scene import Camera


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
    return Camera(
        position=tuple((np.array(camera.position) + delta).tolist()),
        target=tuple((np.array(camera.target) + delta).tolist()),
        up=camera.up,
        fov_y=camera.fov_y,
    )


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


# How close (degrees) orbiting may bring the view direction to the up vector or its opposite.
MIN_POLAR_DEG = 1.0


def _rotate(v: np.ndarray, axis: np.ndarray, degrees: float) -> np.ndarray:
    """``v`` rotated by ``degrees`` about the unit ``axis`` (right-handed; Rodrigues)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return v * c + np.cross(axis, v) * s + axis * float(axis @ v) * (1.0 - c)


def polar_angle(camera: Camera) -> float:
    """Degrees between ``up`` and the target→camera offset (90 = looking level, 0 = from above)."""
    offset = np.subtract(camera.position, camera.target).astype(np.float64)
    up = np.asarray(camera.up, dtype=np.float64)
    cos = float(offset @ up) / (float(np.linalg.norm(offset)) * float(np.linalg.norm(up)))
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def clamp_pitch(camera: Camera, pitch: float) -> float:
    """The part of ``pitch`` (degrees) that keeps the polar angle in [MIN, 180 − MIN]; a camera
    already outside that band (set directly) may move back in but not further out."""
    theta = polar_angle(camera)
    lo, hi = min(theta, MIN_POLAR_DEG), max(theta, 180.0 - MIN_POLAR_DEG)
    return max(lo, min(hi, theta + float(pitch))) - theta


def orbit(camera: Camera, yaw: float, pitch: float) -> Camera:
    """Turn the camera about its target: ``yaw`` degrees about ``up`` and ``pitch`` degrees
    (clamped by :func:`clamp_pitch`) about ``right``. Target, distance, up and fov stay."""
    if not (math.isfinite(yaw) and math.isfinite(pitch)):
        raise ValueError(f"yaw and pitch must be finite, got {yaw}, {pitch}")
    target = np.array(camera.target, dtype=np.float64)
    offset = np.array(camera.position, dtype=np.float64) - target
    up = np.array(camera.up, dtype=np.float64)
    up /= np.linalg.norm(up)
    pitch = clamp_pitch(camera, pitch)
    # Pitch first, about the right vector of the camera as it is: yaw about up leaves the
    # polar angle alone and turns right with it, so the two rotations commute.
    right, _, _ = camera.basis()
    offset = _rotate(offset, np.asarray(right, dtype=np.float64), pitch)
    offset = _rotate(offset, up, float(yaw))
    return Camera(position=tuple((target + offset).tolist()), target=camera.target, up=camera.up, fov_y=camera.fov_y)


def reset(home: Camera) -> Camera:
    """The home camera."""
    return home

"""Scenes of sessions: request bodies → validated ``Scene``, stored *sources*, a cache.

A session's scene is stored as a *source*, not re-serialised for every change:

- a thesis scenario is its recipe ``{"scenario", "n", "seed", "radius"}`` (a few
  bytes; ``renderer.scenarios.scenario`` is deterministic), and an animated Museum
  its recipe ``{"museum": {"n", "kind", "seed", "absent"}}``;
- an uploaded scene is its small parts (and motions) as JSON plus the sphere arrays,
  in one compressed ``.npz``.

An animated scene (one with motions) is an :class:`~renderer.animation.AnimatedScene`;
``SessionScene`` is either kind. The renderer poses it at the frame's ``time``.

The camera is not part of the source (it lives in the session state), so a
gesture never rewrites the scene. ``SceneCache`` keeps recently used scenes per
process, keyed by the session's scene revision token, so a frame does not
rebuild its scene from the source either.
"""

from __future__ import annotations

import io
import json
import threading
from collections import OrderedDict
from typing import Any, Iterator

import numpy as np

from renderer.animation import AnimatedScene, motion_from_json, motion_to_json, museum
from renderer.scenarios import scenario
from renderer.scene import Camera, Scene, SceneError

from .models import CameraModel, SceneModel

_RECIPE = b"R"
_ARRAYS = b"A"

SessionScene = Scene | AnimatedScene


def scene_from_model(model: SceneModel, where: str = "scene") -> SessionScene:
    """A validated Scene — an AnimatedScene when it has motions — from a request body
    (SceneError names the JSON field)."""
    small = model.model_dump(exclude={"spheres", "motions"})
    try:
        base = Scene.from_json(small)
        n = len(model.spheres)
        centers = np.array([s.center for s in model.spheres], dtype=np.float64).reshape(n, 3)
        radii = np.array([s.radius for s in model.spheres], dtype=np.float64).reshape(n)
        mats = np.array([s.material for s in model.spheres], dtype=np.int64).reshape(n)
        scene = Scene(base.camera, base.lights, base.materials, centers, radii, mats, base.planes)
        return with_motions(scene, [m.model_dump() for m in model.motions])
    except SceneError as e:
        raise SceneError(f"{where}.{e.field}" if where else e.field, e.message) from None


def with_motions(scene: Scene, motions: list[dict]) -> SessionScene:
    """``scene`` animated by the motions' JSON (SceneError ``motions[i].<field>``); no motions: ``scene``."""
    if not motions:
        return scene
    return AnimatedScene(scene, tuple(motion_from_json(m, f"motions[{i}]") for i, m in enumerate(motions)))


def museum_source(n: int, kind: str, seed: int, absent: float) -> bytes:
    return _RECIPE + json.dumps({"museum": {"n": n, "kind": kind, "seed": seed, "absent": absent}}).encode()


def camera_from_model(model: CameraModel, where: str = "camera") -> Camera:
    """A validated Camera (SceneError with ``camera.<field>``)."""
    return Camera.from_json(model.model_dump(), where)


def scenario_source(number: int, n: int, seed: int, radius: float) -> bytes:
    return _RECIPE + json.dumps({"scenario": number, "n": n, "seed": seed, "radius": radius}).encode()


def scene_source(scene: SessionScene) -> bytes:
    """Lights, materials, planes and motions as JSON, spheres as arrays (compressed npz)."""
    motions = [motion_to_json(m) for m in scene.motions] if isinstance(scene, AnimatedScene) else []
    if isinstance(scene, AnimatedScene):
        scene = scene.scene
    small = {"lights": [x.to_json() for x in scene.lights], "materials": [m.to_json() for m in scene.materials],
             "planes": [p.to_json() for p in scene.planes], "motions": motions}
    buf = io.BytesIO()
    np.savez_compressed(buf, meta=np.frombuffer(json.dumps(small).encode(), dtype=np.uint8),
                        centers=scene.sphere_centers, radii=scene.sphere_radii, materials=scene.sphere_materials)
    return _ARRAYS + buf.getvalue()


def load_source(source: bytes, camera: Camera) -> SessionScene:
    """The scene a source describes, seen through ``camera``."""
    kind, body = source[:1], source[1:]
    if kind == _RECIPE:
        r = json.loads(body)
        if "museum" in r:
            return museum(**r["museum"]).with_camera(camera)
        return scenario(r["scenario"], r["n"], r["seed"], r["radius"]).with_camera(camera)
    if kind == _ARRAYS:
        with np.load(io.BytesIO(body), allow_pickle=False) as z:
            small = json.loads(z["meta"].tobytes())
            motions = small.pop("motions", [])
            base = Scene.from_json({**small, "camera": camera.to_json()})
            scene = Scene(camera, base.lights, base.materials, z["centers"], z["radii"], z["materials"], base.planes)
            return with_motions(scene, motions)
    raise ValueError("unknown scene source")


def scene_json_chunks(scene: SessionScene, spheres_per_chunk: int = 20000) -> Iterator[bytes]:
    """The scene JSON (docs/FORMATS.md) of ``scene`` (exactly ``json.dumps(scene.to_json())``, compact) in
    pieces, so that a scene of 2^21 spheres is sent without building it in memory.
    An animated scene is its rest pose plus ``motions``."""
    def dumps(obj: Any) -> str:
        return json.dumps(obj, separators=(",", ":"), allow_nan=False)
    tail = ""
    if isinstance(scene, AnimatedScene):
        tail = ',"motions":' + dumps([motion_to_json(m) for m in scene.motions])
        scene = scene.scene
    head = scene.to_json() if scene.n_spheres == 0 else None
    if head is not None:
        yield (dumps(head)[:-1] + tail + "}").encode()
        return
    small = {"camera": scene.camera.to_json(), "lights": [x.to_json() for x in scene.lights],
             "materials": [m.to_json() for m in scene.materials]}
    yield (dumps(small)[:-1] + ',"spheres":[').encode()
    n = scene.n_spheres
    for start in range(0, n, spheres_per_chunk):
        stop = min(n, start + spheres_per_chunk)
        part = [{"center": c, "radius": r, "material": m} for c, r, m in
                zip(scene.sphere_centers[start:stop].tolist(), scene.sphere_radii[start:stop].tolist(),
                    scene.sphere_materials[start:stop].tolist())]
        text = dumps(part)[1:-1]
        yield ((text if start == 0 else "," + text)).encode()
    yield ('],"planes":' + dumps([p.to_json() for p in scene.planes]) + tail + "}").encode()


def scene_info(scene: SessionScene, recipe: dict[str, Any] | None = None) -> dict[str, Any]:
    rest = scene.scene if isinstance(scene, AnimatedScene) else scene
    info: dict[str, Any] = {"n_spheres": rest.n_spheres, "n_planes": len(rest.planes)}
    if isinstance(scene, AnimatedScene):
        info.update(animated=True, n_moving=int(scene.moving.sum()))
    if recipe:
        info.update(recipe)
    return info


class SceneCache:
    """Least-recently-used scenes of this process, keyed by (session id, scene revision).

    Bounded by the total number of spheres held (memory ≈ 36 bytes per sphere).
    """

    def __init__(self, max_spheres: int = 8 << 20):
        self.max_spheres = max_spheres
        self._items: OrderedDict[tuple[str, str], SessionScene] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple[str, str]) -> SessionScene | None:
        with self._lock:
            scene = self._items.get(key)
            if scene is not None:
                self._items.move_to_end(key)
            return scene

    def put(self, key: tuple[str, str], scene: SessionScene) -> None:
        with self._lock:
            self._items[key] = scene
            self._items.move_to_end(key)
            while len(self._items) > 1 and sum(s.n_spheres for s in self._items.values()) > self.max_spheres:
                self._items.popitem(last=False)

    def drop_session(self, session_id: str) -> None:
        with self._lock:
            for key in [k for k in self._items if k[0] == session_id]:
                del self._items[key]

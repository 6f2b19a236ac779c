"""``pocketray``: the one command (console script of the package; ``python -m server`` too).

::

    pocketray serve [--host H] [--port P] [--workers N] [--state-backend sqlite|redis] [--gpu I] …
    pocketray render SCENE.json -o OUT.png|.jpg|.npy|.exr [--width W --height H --method M --mode M
                     --spp S --depth D …]
    pocketray render MODEL.obj|.ply|.stl|.glb|.gltf|.zip -o OUT.png [--size S --smooth|--flat] [the same flags]
    pocketray scene --mesh MODEL [--mesh MODEL …] [--size S] [--as-is] [-o scene.json]
    pocketray scenario 1|2|3 --n N [--seed S] [--radius R] [--sky] -o scene.json
    pocketray scenario museum --n N [--kind mixed] [--absent A] [--seed S] -o scene.json
    pocketray scenario spheres|teapot|mixed|room|cornell|table [--sky] [--aspect W/H] -o scene.json
    pocketray gpus [--probe]
    pocketray stack [--processes N] [--port P]     (Redis + render processes + HAProxy, server/tools/stack.py)

``serve`` takes a flag for every field of :class:`server.config.ServerConfig` (``--queue-size``,
``--cors-origins``, ``--drain-s`` …): each is put in the environment as its ``POCKETRAY_*``
variable, so the flags are read and validated exactly as the variables are, by every worker.
uvicorn gets the app as the import string ``server.app:create_app`` (a factory), so that
``--workers N`` starts N processes, each with its own app and GL context; with more than one
the Prometheus metrics go through a shared directory (multiprocess mode).

``render`` takes the settings of the API's frame query (:class:`server.api.schemas.FrameQuery`,
validated by the same models and by ``RenderSettings``, with ``--spp`` for
``samples_per_pixel`` and ``--depth`` for ``max_recursion_depth``) and the scene JSON of
docs/FORMATS.md (:class:`server.api.schemas.SceneModel`). The output format follows the file's
extension. Errors are the API's 422 messages (``width: …``), exit status 2.

``render`` also takes a model file (any format :mod:`renderer.io.mesh_io` loads, told by its
suffix): :func:`renderer.io.mesh_io.model_scene` makes its scene — the model scaled so that its
longest side is ``--size`` (default 30) world units, centred on the y axis and standing on the
floor plane y = −20, seen by a camera that frames that box, under one light — the scene a
model uploaded with ``POST /api/sessions/{id}/meshes?size=…`` stands in. ``scene --mesh``
writes the scene JSON of one or more models (each as the file has it, with a ``transform``
that fits it: the same box, side by side along x), to edit and ``render``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from renderer.config.settings import SettingValues

EXTENSIONS = {".png": "png", ".jpg": "jpeg", ".jpeg": "jpeg", ".npy": "npy", ".exr": "exr"}
ENV_PREFIX = "POCKETRAY_"
# Short names of the render flags (the API's names work too).
RENDER_ALIASES = {"samples_per_pixel": ["--spp"], "max_recursion_depth": ["--depth"]}
APP_FACTORY = "server.app:create_app"


class UsageError(Exception):
    """A bad flag or input: printed, exit status 2."""


# ---- serve ------------------------------------------------------------------------------------
def _config_fields() -> dict[str, Any]:
    from ..config import ServerConfig

    return dict(ServerConfig.model_fields)


def _add_serve(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "serve",
        help="run the render service (uvicorn)",
        description="Run the render service. Every flag below but --workers is the "
        "POCKETRAY_<NAME> variable of the same name (docs/API.md).",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        help="uvicorn worker processes, each with its own GL context (default 1); with more "
        "than one use --state-backend redis, or they share one SQLite file",
    )
    for name, field in _config_fields().items():
        flag = "--" + name.replace("_", "-")
        default = field.get_default(call_default_factory=False)
        shown = "" if default is None or callable(default) or field.default_factory else f" (default {default})"
        p.add_argument(
            flag,
            dest=f"cfg_{name}",
            metavar=name.upper(),
            default=None,
            help=f"{field.description or name}{shown}".replace("%", "%%"),
        )
    # The GPU index's old flag, kept working for deployments that pass it (deprecated).
    p.add_argument("--gl-device", dest="cfg_gpu", default=None, help=argparse.SUPPRESS)


def start_line(host: str, port: int) -> str:
    """The one human line ``serve`` prints before the JSON logs: the address to open."""
    if host in ("0.0.0.0", "::", ""):  # every interface: this machine's own address is one of them
        return (
            f"pocketray: open http://127.0.0.1:{port}/ here, or http://<this machine's address>:{port}/ "
            "from a phone on the same network (API: /docs)"
        )
    shown = f"[{host}]" if ":" in host else host
    return f"pocketray: open http://{shown}:{port}/ (API: /docs)"


def serve(args: argparse.Namespace) -> int:
    import uvicorn

    from ..config import ServerConfig
    from ..http.observability import configure_logging, uvicorn_log_config
    from ..http.wire import GuardedH11Protocol, GuardedWebSocketProtocol

    for name in _config_fields():
        value = getattr(args, f"cfg_{name}")
        if value is not None:
            os.environ[ENV_PREFIX + name.upper()] = value
    try:
        config = ServerConfig()  # what every worker will read: fail here, once, with the message
    except Exception as e:
        raise UsageError(f"configuration: {e}") from None
    if args.workers < 1:
        raise UsageError("--workers: at least 1")
    configure_logging(config.log_level, config.log_format)
    print(start_line(config.host, config.port), file=sys.stderr, flush=True)
    multiproc_dir = None
    if args.workers > 1 and not os.environ.get("PROMETHEUS_MULTIPROC_DIR"):
        multiproc_dir = tempfile.mkdtemp(prefix="pocketray-metrics-")
        os.environ["PROMETHEUS_MULTIPROC_DIR"] = multiproc_dir
    if config.gpu is not None:
        os.environ["GLCONTEXT_DEVICE_INDEX"] = str(config.gpu)
    try:
        # GuardedH11Protocol: 408 for stalled requests, connections per client, write timeout, unsent
        # bytes per client; GuardedWebSocketProtocol: the same through the upgrade, idle and flooding
        # WebSockets (server/http/wire.py). The classes, not subclasses per config, so that --workers can
        # hand them to each worker process.
        uvicorn.run(
            APP_FACTORY,
            factory=True,
            host=config.host,
            port=config.port,
            workers=args.workers,
            http=GuardedH11Protocol,
            ws=GuardedWebSocketProtocol,
            log_level=config.log_level,
            log_config=uvicorn_log_config(config.log_level, config.log_format),
            access_log=False,
            timeout_graceful_shutdown=max(30, int(config.drain_s) + 30),
        )
    finally:
        if multiproc_dir:
            shutil.rmtree(multiproc_dir, ignore_errors=True)
    return 0


# ---- render ---------------------------------------------------------------------------------
def _add_render(sub: argparse._SubParsersAction) -> None:
    from ..api.schemas import RenderParams

    p = sub.add_parser(
        "render",
        help="render a scene JSON file or a model file to an image or array",
        description="Render SCENE (scene JSON, docs/FORMATS.md; - for stdin) or a model file "
        "(.obj .ply .stl .glb .gltf, side files read from its folder, or a .zip of its folder: fitted, on "
        "the floor, framed by the camera) with "
        "the API's settings. The output's extension picks the format: .png .jpg .npy .exr.",
    )
    p.add_argument("scene", help="scene JSON file (docs/FORMATS.md), - for standard input, or a model file")
    _add_model_flags(p)
    p.add_argument("-o", "--output", required=True, help="output file: .png, .jpg/.jpeg, .npy or .exr")
    for name, field in RenderParams.model_fields.items():
        if name == "format":
            continue
        flags = [*RENDER_ALIASES.get(name, []), "--" + name.replace("_", "-")]
        p.add_argument(
            *flags,
            dest=f"set_{name}",
            metavar=name.upper(),
            default=None,
            help=((field.description or name) + _RENDER_NOTES.get(name, "")).replace("%", "%%"),
        )
    p.add_argument("--quiet", action="store_true", help="print nothing on success")


def _render_notes() -> dict[str, str]:
    """What a render flag's help adds to the API's description: the command's defaults and the
    limit they meet."""
    from renderer.frame.profiles import STILL
    from renderer.limits import MAX_IMAGE_SIDE, SAMPLES_PER_PIXEL

    from ..config import ServerConfig

    d = ServerConfig().default_settings()
    w, h, spp = d["width"], d["height"], STILL["samples_per_pixel"]
    side = max(w, h)
    fits = [s for s in SAMPLES_PER_PIXEL if side * round(s**0.5) <= MAX_IMAGE_SIDE]
    return {
        "samples_per_pixel": f". Default {spp} (the 'still' profile), whitted and path alike. Whitted traces "
        f"√spp × the size, whose longest side must stay ≤ {MAX_IMAGE_SIDE} pixels: at the default "
        f"{w}×{h}, --spp {' or '.join(map(str, fits))} (16 needs a side ≤ {MAX_IMAGE_SIDE // 4}); path samples "
        "are paths, not sub-pixels: no such limit",
        "width": f". Default {w}",
        "height": f". Default {h}",
    }


_RENDER_NOTES = _render_notes()


def _add_model_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--size",
        type=float,
        default=30.0,
        help="models: longest side (scene: the row's width) in world units (default 30)",
    )
    shade = p.add_mutually_exclusive_group()
    shade.add_argument(
        "--smooth",
        dest="smooth",
        action="store_const",
        const=True,
        default=None,
        help="models: smooth shading (the file's normals, else area-weighted ones)",
    )
    shade.add_argument(
        "--flat",
        dest="smooth",
        action="store_const",
        const=False,
        help="models: flat shading (default: the file's normals if it has them)",
    )


def is_model(path: str) -> bool:
    """Whether ``path`` names a model file or a zip of a model's folder (by its suffix)."""
    from renderer.io.mesh_io import UPLOAD_FORMATS

    return Path(path).suffix.lower().lstrip(".") in UPLOAD_FORMATS


def _size(size: float) -> float:
    from renderer.scenes.scenarios import CUBE_HALF

    if not (0.0 < size <= 2 * CUBE_HALF):  # what the upload's size takes (MeshUploadQuery)
        raise UsageError(f"size: greater than 0 and at most {2 * CUBE_HALF:g}")
    return size


def model_file_scene(path: str, size: float = 30.0, smooth: bool | None = None) -> Any:
    """The scene ``render MODEL`` renders (:func:`renderer.io.mesh_io.model_scene`). UsageError
    naming ``model`` for a file that cannot be read or is not a model."""
    from renderer.geometry.scene import SceneError
    from renderer.io.mesh_io import model_scene

    if not Path(path).is_file():
        raise UsageError(f"model: cannot read {path}: no such file")
    try:
        return model_scene(path, size=_size(size), smooth=smooth)
    except SceneError as e:
        raise UsageError(f"model: {e.message}") from None


def _validation_message(e: Exception) -> str:
    from pydantic import ValidationError

    if isinstance(e, ValidationError):
        out = []
        for err in e.errors():
            loc = ".".join(str(x) for x in err.get("loc", ()))
            out.append(f"{loc or 'input'}: {err.get('msg')}")
        return "; ".join(out)
    return str(e)


def render_file(scene_text: str | None, output: Path, flags: dict[str, str], scene: Any = None) -> dict[str, Any]:
    """Render ``scene_text`` (scene JSON; or the ready ``scene``, a model's) with the settings
    ``flags`` (text, as in a query) into ``output``.

    Returns what was done (method, size, format, timings in ms). UsageError on bad input."""
    from pydantic import ValidationError

    from renderer.frame.plan import plan_method
    from renderer.geometry.scene import SceneError

    from ..api.schemas import FrameQuery, SceneModel
    from ..config import ServerConfig
    from ..frames.encode import encode
    from ..frames.pipeline import render_settings
    from ..sessions.scenes import scene_from_model

    fmt = EXTENSIONS.get(output.suffix.lower())
    if fmt is None:
        raise UsageError(f"output: unknown extension {output.suffix!r}; use one of {', '.join(EXTENSIONS)}")
    try:
        patch = FrameQuery.model_validate({**flags, "format": fmt}).given()
    except ValidationError as e:
        raise UsageError(_validation_message(e)) from None
    if scene is None:
        assert scene_text is not None, "the scene's text or the scene"
        try:
            model = SceneModel.model_validate_json(scene_text)
        except ValidationError as e:
            raise UsageError("scene." + _validation_message(e).replace("; ", "; scene.")) from None
        try:
            scene = scene_from_model(model)
        except SceneError as e:
            raise UsageError(f"scene.{e.field}: {e.message}") from None
    config = ServerConfig()
    settings: SettingValues = {**config.default_settings(), **patch}
    try:
        rs = render_settings(settings)
        plan_method(rs, scene.n_tree_primitives)  # auto resolved as the frame resolves it
    except (SceneError, TypeError) as e:
        raise UsageError(f"{getattr(e, 'field', 'settings')}: {getattr(e, 'message', e)}") from None

    from renderer.gl import GLRenderer
    from renderer.integrators import Denoiser

    t0 = time.perf_counter()
    renderer = GLRenderer()
    t_ctx = time.perf_counter()
    result = renderer.render(scene, rs.with_(update="rebuild"))
    if rs.denoise != Denoiser.OFF:  # the flag names it: png, jpeg, npy and exr alike
        from renderer.image.denoise import denoise_result

        result = denoise_result(result, scene, rs.denoise)
    body, encode_ms = encode(
        result, fmt, settings.get("quality", config.default_jpeg_quality), config.png_compress_level
    )
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_bytes(body)
    method = (result.stats or {}).get("method", rs.method)
    return {
        "output": str(output),
        "format": fmt,
        "bytes": len(body),
        "width": rs.width,
        "height": rs.height,
        "method": method,
        "mode": rs.mode,
        "context_ms": round((t_ctx - t0) * 1e3, 1),
        "timings_ms": {k: round(float(v), 2) for k, v in {**result.timings, "encode": encode_ms}.items()},
        "gl_renderer": dict(getattr(renderer, "info", {}) or {}).get("renderer"),
    }


def render(args: argparse.Namespace) -> int:
    flags = {k[4:]: v for k, v in vars(args).items() if k.startswith("set_") and v is not None}
    if args.scene != "-" and is_model(args.scene):
        done = render_file(None, Path(args.output), flags, scene=model_file_scene(args.scene, args.size, args.smooth))
    else:
        text = sys.stdin.read() if args.scene == "-" else _read(args.scene)
        done = render_file(text, Path(args.output), flags)
    if not args.quiet:
        t = done["timings_ms"]
        print(
            f"{done['output']}: {done['width']}×{done['height']} {done['mode']} {done['format']}, "
            f"{done['bytes']} bytes; method {done['method']}; build {t.get('build', 0):.1f} ms, "
            f"trace {t.get('trace', 0):.1f} ms, encode {t.get('encode', 0):.1f} ms ({done['gl_renderer']})",
            file=sys.stderr,
        )
    return 0


def _read(path: str) -> str:
    try:
        return Path(path).read_text()
    except OSError as e:
        raise UsageError(f"scene: cannot read {path}: {e.strerror}") from None


# ---- scenario -----------------------------------------------------------------------------------
def scenario_names() -> dict[str, list[Any]]:
    """The ``scenario`` command's choices, made from the demo scenes' registry
    (:data:`renderer.scenes.scenarios.DEMO_SCENES`): each name and the entries it writes (``2`` is
    scenario 2 and, with ``--sky``, ``sky:2``)."""
    from renderer.scenes.scenarios import DEMO_SCENES

    names: dict[str, list[Any]] = {}
    for d in DEMO_SCENES:
        r = d.recipe
        name = r["mesh_scene"]["kind"] if "mesh_scene" in r else "museum" if "museum" in r else str(r["scenario"])
        names.setdefault(name, []).append(d)
    return names


def _scenario_epilog() -> str:
    lines = ["demo scenes (the client's picker, GET /api/info's scenes):"]
    for name, entries in scenario_names().items():
        for d in entries:
            r = d.recipe
            flags = " --sky" if r.get("sky") or r.get("mesh_scene", {}).get("sky") else ""
            flags += f" --n {r['n']}" if "scenario" in r else ""
            flags += f" --n {r['museum']['n']}" if "museum" in r else ""
            line = f"  {name + flags:<16} {d.label}"
            if d.settings:
                line += "; render it with " + " ".join(f"--{k.replace('_', '-')} {v}" for k, v in d.settings.items())
            lines.append(line)
    return "\n".join(lines)


def _add_scenario(sub: argparse._SubParsersAction) -> None:
    from renderer.scenes.animation import MUSEUM_KINDS

    names = list(scenario_names())
    p = sub.add_parser(
        "scenario",
        help="write a demo scene as scene JSON: " + ", ".join(names),
        description="Write the scene JSON (docs/FORMATS.md) of a demo scene: the thesis's scenario 1, "
        "2 or 3, the animated museum (its motions included) or a scene of meshes or analytic shapes.",
        epilog=_scenario_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("which", choices=names, help="the demo scene: " + ", ".join(names))
    p.add_argument("--n", type=int, default=None, help="spheres (museum: the moving ones); not for mesh scenes")
    p.add_argument("--seed", type=int, default=0, help="placement seed (default 0)")
    p.add_argument("--radius", type=float, default=1.0, help="sphere radius of scenarios 1–3 (default 1)")
    p.add_argument("--kind", choices=list(MUSEUM_KINDS), default="mixed", help="museum motion (default mixed)")
    p.add_argument(
        "--absent", type=float, default=0.2, help="museum: share of incoherent spheres absent at a time (default 0.2)"
    )
    p.add_argument(
        "--sky",
        action="store_true",
        help="under the procedural daylight sky (environment 'sky'): light for integrator=path; not the museum",
    )
    p.add_argument(
        "--aspect",
        type=float,
        default=None,
        help="the camera framed for an image of this width / height (0.5625 for 360 × 640); "
        "default: the scene's own camera",
    )
    p.add_argument("-o", "--output", default="-", help="output file (default: standard output)")


def scenario_scene(
    which: str,
    n: int | None,
    seed: int = 0,
    radius: float = 1.0,
    kind: str = "mixed",
    absent: float = 0.2,
    sky: bool = False,
) -> Any:
    """The scene (or animated scene) the ``scenario`` command writes; validated as the API does."""
    from renderer.geometry.scene import SceneError
    from renderer.limits import MAX_SPHERES
    from renderer.scenes.animation import MUSEUM_ROOM_SPHERES, museum
    from renderer.scenes.scenarios import MESH_SCENES, mesh_scene, scenario

    if which in MESH_SCENES:
        return mesh_scene(which, sky=sky)
    if sky and which == "museum":
        raise UsageError("sky: for scenarios 1–3 and the mesh scenes, not the museum")
    if n is None:
        raise UsageError("n: required for scenarios 1–3 and the museum")
    if n < 0 or n + (MUSEUM_ROOM_SPHERES if which == "museum" else 0) > MAX_SPHERES:
        raise UsageError(f"n: 0 … {MAX_SPHERES} spheres")
    try:
        if which == "museum":
            return museum(n, kind, seed, absent)
        return scenario(int(which), n, seed, radius, sky)
    except SceneError as e:
        raise UsageError(f"{e.field}: {e.message}") from None


def write_scenario(args: argparse.Namespace) -> int:
    from ..sessions.scenes import scene_json_chunks

    scene = scenario_scene(args.which, args.n, args.seed, args.radius, args.kind, args.absent, args.sky)
    if args.aspect is not None:
        from renderer.limits import ASPECT_RANGE
        from renderer.scenes.scenarios import framed

        lo, hi = ASPECT_RANGE
        if not lo <= args.aspect <= hi:
            raise UsageError(f"aspect: width / height in {lo:g} … {hi:g}, got {args.aspect:g}")
        rest = getattr(scene, "scene", scene)  # an animated scene is framed at rest
        scene = scene.with_camera(framed(rest, args.aspect).camera)
    if args.output == "-":
        for chunk in scene_json_chunks(scene):
            sys.stdout.buffer.write(chunk)
        sys.stdout.buffer.write(b"\n")
        sys.stdout.flush()
        return 0
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("wb") as f:
        for chunk in scene_json_chunks(scene):
            f.write(chunk)
    print(f"{out}: scenario {args.which}" + (f", {args.n} spheres" if args.n is not None else ""), file=sys.stderr)
    return 0


# ---- scene --mesh ---------------------------------------------------------------------------
def _add_scene(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "scene",
        help="write a scene JSON of model files (to edit, and render)",
        description="Write the scene JSON (docs/FORMATS.md) of one or more model files (.obj .ply "
        ".stl .glb .gltf .zip): each mesh as the file has it with a transform that fits it, "
        "side by side along x on the floor, the camera and light of render MODEL.",
    )
    p.add_argument("--mesh", action="append", required=True, metavar="MODEL", help="a model file (repeat for more)")
    p.add_argument("--as-is", action="store_true", help="no transform: the files' coordinates are world units")
    _add_model_flags(p)
    p.add_argument("-o", "--output", default="-", help="output file (default: standard output)")


def models_scene(paths: list[str], size: float = 30.0, smooth: bool | None = None, as_is: bool = False) -> dict:
    """The scene JSON ``scene --mesh`` writes, validated as the API validates a scene."""
    from pydantic import ValidationError

    from renderer.geometry.scene import SceneError
    from renderer.io.mesh_io import models_scene_json

    from ..api.schemas import SceneModel
    from ..sessions.scenes import scene_from_model

    for path in paths:
        if not Path(path).is_file():
            raise UsageError(f"mesh: cannot read {path}: no such file")
    try:
        doc = models_scene_json(paths, size=_size(size), smooth=smooth, as_is=as_is)
    except SceneError as e:
        raise UsageError(f"mesh: {e.message}") from None
    try:
        scene_from_model(SceneModel.model_validate(doc))
    except (ValidationError, SceneError) as e:  # e.g. --as-is with coordinates beyond the limits
        msg = _validation_message(e) if isinstance(e, ValidationError) else f"{e.field}: {e.message}"
        raise UsageError(f"scene.{msg}") from None
    return doc


def write_models_scene(args: argparse.Namespace) -> int:
    doc = models_scene(args.mesh, args.size, args.smooth, args.as_is)
    text = json.dumps(doc, separators=(",", ":"), allow_nan=False)
    if args.output == "-":
        sys.stdout.write(text + "\n")
        sys.stdout.flush()
        return 0
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    n = sum(len(m["triangles"]) for m in doc["meshes"])
    print(f"{out}: {len(doc['meshes'])} meshes, {n} triangles", file=sys.stderr)
    return 0


# ---- gpus ---------------------------------------------------------------------------------------
def _add_gpus(sub: argparse._SubParsersAction) -> None:
    # ("devices" is its old name, kept working: "device" is the browser client's own tracer now.)
    p = sub.add_parser(
        "gpus", aliases=["devices"], help="list the GPUs as EGL lists them (serve --gpu picks one by index)"
    )
    p.add_argument("--probe", action="store_true", help="also create a context on each and print its renderer")
    p.add_argument("--json", action="store_true", help="print JSON")


def gpus(args: argparse.Namespace) -> int:
    from renderer.gl.gpus import list_gpus, probe

    found = list_gpus()
    if args.probe:
        for d in found:
            d.update(probe(d["index"]))
    if args.json:
        print(json.dumps(found, indent=2))
        return 0
    if not found:
        print("no GPUs listed by EGL (EGL_EXT_device_enumeration missing, or no libEGL)")
    for d in found:
        extra = f"  → {d['gl_renderer']}" if d.get("gl_renderer") else (f"  → {d['error']}" if d.get("error") else "")
        print(f"{d['index']}: {d.get('kind', '?'):8} {d.get('drm') or d.get('renderer') or ''}{extra}")
    return 0


# ---- main -------------------------------------------------------------------------------------
def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pocketray", description="pocketray: the render service, and renders from the command line"
    )
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_serve(sub)
    _add_render(sub)
    _add_scenario(sub)
    _add_scene(sub)
    _add_gpus(sub)
    _add_stack(sub)
    return p


def _add_stack(sub: argparse._SubParsersAction) -> None:
    sub.add_parser(
        "stack",
        add_help=False,
        help="Redis + render processes + HAProxy on loopback ports "
        "(server/tools/stack.py; needs redis-server and haproxy)",
    )


def stack(args: argparse.Namespace) -> int:
    from .stack import main as stack_main

    return stack_main(args.rest)


COMMANDS = {
    "serve": serve,
    "render": render,
    "scenario": write_scenario,
    "scene": write_models_scene,
    "gpus": gpus,
    "devices": gpus,
    "stack": stack,
}


def main(argv: Sequence[str] | None = None) -> int:
    args, rest = parser().parse_known_args(argv)
    if args.command != "stack" and rest:
        parser().parse_args(argv)  # the usual error for unknown arguments
    args.rest = rest
    try:
        return COMMANDS[args.command](args)
    except UsageError as e:
        print(f"pocketray {args.command}: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

"""The GPUs of this machine, as EGL lists them (``pocketray gpus``), and which one a context uses.

("GPU" is the project's word for them, whatever EGL calls them: "device" is the browser
client's own tracer.) glcontext's EGL backend (moderngl's headless contexts) takes the GPU by
its index in ``eglQueryDevicesEXT``'s list, from ``GLCONTEXT_DEVICE_INDEX`` (default 0);
``pocketray serve --gpu I`` / ``POCKETRAY_GPU`` set it. This module lists that same list through
libEGL (ctypes): each device's DRM node and kind (``EGL_MESA_device_software`` is Mesa's
llvmpipe, ``EGL_NV_device_cuda`` an NVIDIA GPU). :func:`probe` makes a context on one
of them, in a child process (a context belongs to its thread, and a failing driver must not
take this process down), and reports its ``GL_RENDERER``.
"""

from __future__ import annotations

import ctypes
import json
import os
import subprocess
import sys
from typing import Any

EGL_EXTENSIONS = 0x3055
EGL_VENDOR = 0x3053
EGL_DRM_DEVICE_FILE_EXT = 0x3233
EGL_DRM_RENDER_NODE_FILE_EXT = 0x3377
EGL_RENDERER_EXT = 0x335F
GPU_INDEX_ENV = "GLCONTEXT_DEVICE_INDEX"  # glcontext's name
MAX_GPUS = 64


def _libegl() -> Any | None:
    try:
        egl = ctypes.CDLL("libEGL.so.1")
    except OSError:
        return None
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    egl.eglQueryString.restype = ctypes.c_char_p
    egl.eglQueryString.argtypes = [ctypes.c_void_p, ctypes.c_int]
    return egl


def _proc(egl: Any, name: str, restype: Any, *argtypes: Any) -> Any | None:
    addr = egl.eglGetProcAddress(name.encode())
    return ctypes.CFUNCTYPE(restype, *argtypes)(addr) if addr else None


def list_gpus() -> list[dict[str, Any]]:
    """``[{"index", "kind", "extensions", "drm", "render_node", "vendor", "renderer"}]`` in
    ``eglQueryDevicesEXT`` order (what ``GLCONTEXT_DEVICE_INDEX`` counts); [] without EGL."""
    egl = _libegl()
    if egl is None:
        return []
    client = (egl.eglQueryString(None, EGL_EXTENSIONS) or b"").decode()
    if "EGL_EXT_device_enumeration" not in client and "EGL_EXT_device_base" not in client:
        return []
    query_devices = _proc(
        egl,
        "eglQueryDevicesEXT",
        ctypes.c_uint,
        ctypes.c_int,
        ctypes.POINTER(ctypes.c_void_p),
        ctypes.POINTER(ctypes.c_int),
    )
    query_string = _proc(egl, "eglQueryDeviceStringEXT", ctypes.c_char_p, ctypes.c_void_p, ctypes.c_int)
    if query_devices is None or query_string is None:
        return []
    devices = (ctypes.c_void_p * MAX_GPUS)()
    count = ctypes.c_int(0)
    if not query_devices(MAX_GPUS, devices, ctypes.byref(count)):
        return []

    def text(dev: Any, name: int) -> str | None:
        # Unsupported names set an EGL error and return NULL; ask only for what the device offers.
        value = query_string(dev, name)
        return value.decode(errors="replace") if value else None

    out = []
    for i in range(count.value):
        dev = devices[i]
        ext = text(dev, EGL_EXTENSIONS) or ""
        info: dict[str, Any] = {"index": i, "extensions": ext.split()}
        if "EGL_EXT_device_drm" in ext:
            info["drm"] = text(dev, EGL_DRM_DEVICE_FILE_EXT)
        if "EGL_EXT_device_drm_render_node" in ext:
            info["render_node"] = text(dev, EGL_DRM_RENDER_NODE_FILE_EXT)
        if "EGL_EXT_device_query_name" in ext:
            info["vendor"] = text(dev, EGL_VENDOR)
            info["renderer"] = text(dev, EGL_RENDERER_EXT)
        info["kind"] = (
            "software"
            if "EGL_MESA_device_software" in ext
            else "nvidia"
            if "EGL_NV_device_cuda" in ext
            else "gpu"
            if info.get("drm")
            else "other"
        )
        out.append(info)
    return out


_PROBE = """
import json, moderngl
try:
    ctx = moderngl.create_standalone_context(backend="egl")
    print(json.dumps({"gl_renderer": ctx.info["GL_RENDERER"], "gl_version": ctx.info["GL_VERSION"]}))
except Exception as e:
    print(json.dumps({"error": f"{type(e).__name__}: {e}"}))
"""


def probe(index: int, timeout_s: float = 60.0) -> dict[str, Any]:
    """``{"gl_renderer", "gl_version"}`` of a context on GPU ``index`` (or ``{"error"}``)."""
    env = {**os.environ, GPU_INDEX_ENV: str(index)}
    try:
        run = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return {"error": f"no context within {timeout_s:g} s"}
    lines = [line for line in run.stdout.splitlines() if line.startswith("{")]
    if not lines:
        return {"error": (run.stderr.strip().splitlines() or [f"exit {run.returncode}"])[-1]}
    return json.loads(lines[-1])

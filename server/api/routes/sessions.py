"""Sessions (the Model): create, read, delete; their scene, camera and render defaults."""

from __future__ import annotations

import json
from typing import Annotated

from fastapi import APIRouter, Body, Query, Request, Response
from fastapi.responses import StreamingResponse
from starlette.concurrency import run_in_threadpool

from renderer.geometry.scene import SceneError
from renderer.io.mesh_io import UPLOAD_FORMATS, fit_transform, model_geometry

from ...faults import Busy, InputError, Where
from ...sessions.model_worker import load_model, parse_client
from ...sessions.ratelimit import client_key
from ...sessions.scenes import scene_json_chunks
from ...sessions.store import SessionState
from ..body import JSONBodyRoute
from ..deps import ServiceDep, SessionCreateRate, SessionId
from ..errors import documented, located
from ..schemas import (
    CameraModel,
    CameraOut,
    EnvironmentOut,
    EnvironmentUploadQuery,
    FullSettings,
    MeshAdded,
    MeshModel,
    MeshUploadQuery,
    SceneInfo,
    SceneModel,
    SessionCreate,
    SessionOut,
    SettingsOut,
    SettingsPatch,
    VersionOut,
)

router = APIRouter(route_class=JSONBodyRoute)  # JSON bodies strict, large ones off the event loop

ERR_SESSION = documented(404, 503)
ERR_SESSION_BODY = documented(404, 413, 503)


def session_out(state: SessionState) -> SessionOut:
    """The API's view of a stored session."""
    return SessionOut(
        id=state.id,
        version=state.version,
        settings=FullSettings(**state.settings),
        scene_info=SceneInfo(**state.scene_info),
        camera=CameraModel(**state.camera),
    )


@router.post(
    "/sessions",
    status_code=201,
    response_model=SessionOut,
    responses=documented(413, 429, 503, 507),
    dependencies=[SessionCreateRate],
    summary="Create a session from a thesis scenario, an animated museum or a full scene",
)
def create_session(body: SessionCreate, service: ServiceDep) -> SessionOut:
    with located(Where.BODY):
        return session_out(service.create(body))


@router.get(
    "/sessions/{session_id}",
    response_model=SessionOut,
    responses=ERR_SESSION,
    summary="A session: version, render defaults, scene info, camera",
)
def read_session(session_id: SessionId, service: ServiceDep) -> SessionOut:
    return session_out(service.get(session_id))


@router.delete(
    "/sessions/{session_id}",
    status_code=204,
    response_class=Response,
    responses=ERR_SESSION,
    summary="Delete a session",
)
def delete_session(session_id: SessionId, service: ServiceDep) -> Response:
    service.delete(session_id)
    return Response(status_code=204)


@router.get(
    "/sessions/{session_id}/scene",
    response_model=SceneModel,
    responses=ERR_SESSION,
    summary="The session's scene (scene JSON of docs/FORMATS.md) with its current camera",
)
def read_scene(session_id: SessionId, service: ServiceDep) -> Response:
    # Streamed: a scene of 2^21 spheres is never one JSON string in memory.
    state = service.get(session_id)
    return StreamingResponse(scene_json_chunks(service.scene(state)), media_type="application/json")


@router.put(
    "/sessions/{session_id}/scene",
    response_model=VersionOut,
    responses=documented(404, 413, 503, 507),
    summary="Replace the scene (its camera becomes the current and the reset camera)",
)
def replace_scene(session_id: SessionId, scene: Annotated[SceneModel, Body()], service: ServiceDep) -> VersionOut:
    with located(Where.BODY):
        return VersionOut(version=service.replace_scene(session_id, scene).version)


@router.put(
    "/sessions/{session_id}/camera", response_model=CameraOut, responses=ERR_SESSION_BODY, summary="Set the camera"
)
def set_camera(session_id: SessionId, camera: Annotated[CameraModel, Body()], service: ServiceDep) -> CameraOut:
    with located(Where.BODY):
        state = service.set_camera(session_id, camera)
    return CameraOut(version=state.version, camera=CameraModel(**state.camera))


@router.patch(
    "/sessions/{session_id}/settings",
    response_model=SettingsOut,
    responses=ERR_SESSION_BODY,
    summary="Change render defaults (all of them or some)",
)
def patch_settings(session_id: SessionId, patch: Annotated[SettingsPatch, Body()], service: ServiceDep) -> SettingsOut:
    with located(Where.BODY):
        state = service.patch_settings(session_id, patch)
    return SettingsOut(**state.settings, version=state.version)


# A model file is the raw request body (bytes), read in memory: no multipart, nothing written to disk.
_MODEL_BODY = {
    "requestBody": {
        "required": True,
        "description": "the model file's bytes ("
        + ", ".join(UPLOAD_FORMATS)
        + "; zip: the model's folder, its side files beside it); at most POCKETRAY_MAX_BODY_BYTES (else 413)",
        "content": {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}},
    }
}


@router.post(
    "/sessions/{session_id}/meshes",
    status_code=201,
    response_model=MeshAdded,
    responses=documented(404, 409, 413, 503, 507),
    openapi_extra=_MODEL_BODY,
    summary="Add a model file (OBJ, PLY, STL, glTF/GLB, or a zip of its folder; the body) to the session's scene",
)
async def add_mesh(
    session_id: SessionId, request: Request, query: Annotated[MeshUploadQuery, Query()], service: ServiceDep
) -> MeshAdded:
    data = await request.body()
    parse_client.set(client_key(request.client.host if request.client else None))
    added = await run_in_threadpool(service.add_mesh, session_id, data, query)
    state = added.state
    return MeshAdded(
        version=state.version,
        scene_info=SceneInfo(**state.scene_info),
        mesh=added.index,
        first_id=added.first_id,
        placed=added.placed,
        camera=CameraModel(**state.camera),
        notice=added.notice,
        n_meshes=added.n_meshes,
        n_textures=added.n_textures,
    )


@router.put(
    "/sessions/{session_id}/environment",
    response_model=EnvironmentOut,
    responses=documented(404, 409, 413, 503, 507),
    openapi_extra={
        "requestBody": {
            "required": True,
            "description": "an equirectangular HDR image's bytes (.hdr Radiance RGBE, .exr OpenEXR; "
            "docs/FORMATS.md, 'Environment'); at most POCKETRAY_MAX_BODY_BYTES (else 413)",
            "content": {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}},
        }
    },
    summary="Light the session's scene by an HDR image (the body): its environment, importance sampled",
)
async def set_environment(
    session_id: SessionId, request: Request, query: Annotated[EnvironmentUploadQuery, Query()], service: ServiceDep
) -> EnvironmentOut:
    data = await request.body()
    parse_client.set(client_key(request.client.host if request.client else None))
    state, env = await run_in_threadpool(
        service.set_environment, session_id, data, query.format, query.scale, query.rotation_deg
    )
    return EnvironmentOut(version=state.version, image=env.ref, width=env.width, height=env.height)


@router.delete(
    "/sessions/{session_id}/environment",
    response_model=VersionOut,
    responses=documented(404, 409, 503, 507),
    summary="The session's environment back to a colour (black)",
)
def clear_environment(session_id: SessionId, service: ServiceDep) -> VersionOut:
    return VersionOut(version=service.clear_environment(session_id).version)


@router.post(
    "/meshes",
    response_model=MeshModel,
    responses=documented(413, 503),
    openapi_extra=_MODEL_BODY,
    summary="A model file (the body) as mesh JSON, to put in a scene (nothing is stored)",
)
async def convert_mesh(request: Request, query: Annotated[MeshUploadQuery, Query()], service: ServiceDep) -> Response:
    data = await request.body()
    parse_client.set(client_key(request.client.host if request.client else None))

    def convert() -> bytes:
        try:
            parsed = load_model(
                service.config, data, query.format, max_triangles=service.config.max_triangles, busy=Busy
            )
            # one mesh JSON: the model's parts joined (a mesh names one scene material)
            mesh = model_geometry(parsed).to_json(
                query.material or 0, fit_transform(parsed, query.size) if query.size else None, query.smooth
            )
        except SceneError as e:
            raise InputError(("query", "format") if e.field == "format" else ("body",), e.message) from None
        return json.dumps(mesh, separators=(",", ":"), allow_nan=False).encode()

    # JSON written directly: a mesh of a million triangles is not validated again on its way out
    return Response(await run_in_threadpool(convert), media_type="application/json")

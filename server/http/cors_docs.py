"""Web basics of the service: CORS, offline API docs, OpenAPI names.

- **CORS** through Starlette's ``CORSMiddleware``: origins from ``POCKETRAY_CORS_ORIGINS``
  (default none: the client is served by the service itself, same origin); a preflight
  (``OPTIONS`` with ``Origin`` and ``Access-Control-Request-Method``) is answered by it; the
  frame headers (``Server-Timing``, ``X-Stats``, …) are exposed to the caller's script.
- **Plain OPTIONS** (no preflight) and 405s: :mod:`server.http.allow`.
- **/docs and /redoc offline**: Swagger UI's and ReDoc's files come from the
  ``fastapi-offline`` package (its ``static/``), served at ``/docs-assets/``; their pages carry
  their own Content-Security-Policy (:func:`server.http.security.docs_policy`).
- **OpenAPI**: operation ids are the route functions' names (``create_session``,
  ``session_frame``), grouped by the tags of :data:`OPENAPI_TAGS`.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from fastapi import FastAPI
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html, get_swagger_ui_oauth2_redirect_html
from fastapi.responses import HTMLResponse
from fastapi.routing import APIRoute
from starlette.middleware.cors import CORSMiddleware
from starlette.staticfiles import StaticFiles

from ..contract.headers import EXPOSED
from .observability import REQUEST_ID_HEADER, SESSION_HEADER
from .security import CSP, docs_policy

DOCS_ASSETS = "/docs-assets"
CORS_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")
CORS_HEADERS = ("content-type", SESSION_HEADER, REQUEST_ID_HEADER)
CORS_MAX_AGE_S = 600

OPENAPI_TAGS = [
    {"name": "sessions", "description": "The Model: a session's scene, camera and render defaults"},
    {
        "name": "frames",
        "description": "The View and the Controller: gestures, frames, build statistics, stateless renders",
    },
    {"name": "device", "description": "On-device rendering: packed scene data and the tracer's GLSL"},
    {"name": "service", "description": "Liveness, readiness, capabilities, metrics"},
]


def operation_id(route: APIRoute) -> str:
    """The route function's name: ``create_session``, ``session_frame``, ``ready`` …"""
    return route.name


def docs_assets_dir() -> Path:
    """Swagger UI's and ReDoc's JavaScript and CSS, shipped by the fastapi-offline package."""
    return Path(str(files("fastapi_offline").joinpath("static")))


def with_docs_policy(page: HTMLResponse) -> HTMLResponse:
    """``page`` with the docs' Content-Security-Policy (its inline scripts allowed by their hashes)."""
    page.headers[CSP] = docs_policy(bytes(page.body))
    return page


def install_docs(app: FastAPI) -> None:
    """``/docs`` (Swagger UI) and ``/redoc`` from the service's own files (call before the ``/`` mount)."""
    title = app.title
    openapi_url = app.openapi_url or "/openapi.json"
    oauth_url = "/docs/oauth2-redirect"
    app.mount(DOCS_ASSETS, StaticFiles(directory=docs_assets_dir()), name="docs-assets")

    @app.get("/docs", include_in_schema=False)
    def swagger_ui() -> HTMLResponse:
        return with_docs_policy(
            get_swagger_ui_html(
                openapi_url=openapi_url,
                title=f"{title} — Swagger UI",
                swagger_js_url=f"{DOCS_ASSETS}/swagger-ui-bundle.js",
                swagger_css_url=f"{DOCS_ASSETS}/swagger-ui.css",
                swagger_favicon_url=f"{DOCS_ASSETS}/favicon.png",
                oauth2_redirect_url=oauth_url,
            )
        )

    @app.get(oauth_url, include_in_schema=False)
    def swagger_ui_redirect() -> HTMLResponse:
        return with_docs_policy(get_swagger_ui_oauth2_redirect_html())

    @app.get("/redoc", include_in_schema=False)
    def redoc() -> HTMLResponse:
        return with_docs_policy(
            get_redoc_html(
                openapi_url=openapi_url,
                title=f"{title} — ReDoc",
                redoc_js_url=f"{DOCS_ASSETS}/redoc.standalone.js",
                redoc_favicon_url=f"{DOCS_ASSETS}/favicon.png",
                with_google_fonts=False,
            )
        )


def install_cors(app: FastAPI, origins: list[str]) -> None:
    allow_all = "*" in origins
    app.add_middleware(
        CORSMiddleware,
        allow_origins=["*"] if allow_all else list(origins),
        allow_methods=list(CORS_METHODS),
        allow_headers=list(CORS_HEADERS),
        expose_headers=[*EXPOSED, "X-Request-ID"],
        max_age=CORS_MAX_AGE_S,
    )

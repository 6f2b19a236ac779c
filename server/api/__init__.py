"""The HTTP and WebSocket API: dependencies, the error table, the schemas and the routes by resource.

:data:`server.api.routes.api_router` holds every route under ``/api`` (and
:mod:`server.api.routes.metrics` the one outside it); :func:`server.app.create_app` includes both
and installs :func:`server.api.errors.install` (docs/API.md describes the API). This package's
``__init__`` imports nothing, as every package of the service: importing one of its modules never
runs the routes. The models the sessions read too are the contract's (:mod:`server.contract`).
"""

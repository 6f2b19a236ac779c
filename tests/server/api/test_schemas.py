"""The request and answer models (server/api/schemas.py) as the OpenAPI schema states them."""

from __future__ import annotations


def test_the_schema_of_samples_per_pixel_is_its_four_values(client):
    spec = client.get("/openapi.json").json()
    for path, method in (("/api/sessions/{session_id}/frame", "get"), ("/api/sessions/{session_id}/gesture", "post")):
        (param,) = [p for p in spec["paths"][path][method]["parameters"] if p["name"] == "samples_per_pixel"]
        assert [s.get("enum") for s in param["schema"]["anyOf"] if s.get("type") == "integer"] == [[1, 4, 9, 16]]

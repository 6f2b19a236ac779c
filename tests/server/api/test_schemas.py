"""The request and answer models (server/api/schemas.py) as the OpenAPI schema states them."""

from __future__ import annotations


def test_the_schema_of_samples_per_pixel_is_its_bounds_and_names_whitteds_four_values(client):
    # The path integrator takes any count 1 … 4096; Whitted's four values are checked by the settings
    # (tests/server/api/test_errors.py) and named in the description.
    spec = client.get("/openapi.json").json()
    for path, method in (("/api/sessions/{session_id}/frame", "get"), ("/api/sessions/{session_id}/gesture", "post")):
        (param,) = [p for p in spec["paths"][path][method]["parameters"] if p["name"] == "samples_per_pixel"]
        (integer,) = [s for s in param["schema"]["anyOf"] if s.get("type") == "integer"]
        assert (integer["minimum"], integer["maximum"]) == (1, 4096) and "enum" not in integer
        assert "1, 4, 9, 16" in integer["description"]

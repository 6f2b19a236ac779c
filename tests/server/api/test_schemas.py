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


def test_the_schema_describes_what_samples_per_pixel_and_the_depth_are_under_each_integrator(client):
    """The description is made from the declaration of each integrator's values (renderer/config/settings.py)."""
    spec = client.get("/openapi.json").json()
    patch = spec["components"]["schemas"]["SettingsPatch"]["properties"]
    spp = patch["samples_per_pixel"]["description"]
    assert "whitted: a k × k grid of sub-pixels" in spp and "one of 1, 4, 9, 16" in spp
    assert "path: paths per pixel, 1 … 4096" in spp
    depth = patch["max_recursion_depth"]["description"]
    assert "whitted: levels of the ray tree, 1 … 8" in depth and "path: segments of a path" in depth

"""What users get does not change by accident: shader texts and device data match the record.

The record (``record.json``) is
rewritten only by a change that alters shaders or packing on purpose, in the same commit
(``python -m tests.golden.record --write``), whose message says why.
"""

from __future__ import annotations

import json

import pytest

from tests.golden import record as R

RECORDED = json.loads(R.RECORD.read_text())


@pytest.mark.parametrize("part", ["tracer", "ray_engine", "device_data"])
def test_matches_the_record(part):
    now = getattr(
        R, {"tracer": "tracer_shaders", "ray_engine": "ray_engine_shaders", "device_data": "device_data"}[part]
    )()
    assert set(now) == set(RECORDED[part]), "variants added or removed: rewrite the record on purpose"
    changed = sorted(k for k in now if now[k] != RECORDED[part][k])
    assert not changed, f"{len(changed)} of {len(now)} differ from the record, e.g. {changed[:5]}"

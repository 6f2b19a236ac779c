"""Every hierarchy's node record (each declared beside its build, ``<method>_layout.NODE``):
docs/FORMATS.md's "GPU records" tables are made here."""

from __future__ import annotations

from ..gpu.record_layout import RecordLayout
from . import bih_layout, bvh_layout, kdtree_layout

NODE_RECORDS: tuple[RecordLayout, ...] = (bih_layout.NODE, bvh_layout.NODE, kdtree_layout.NODE)


def formats_markdown() -> str:
    """The block of docs/FORMATS.md between ``<!-- gpu-records`` and ``<!-- /gpu-records -->``."""
    return "\n".join(r.markdown() for r in NODE_RECORDS).strip()

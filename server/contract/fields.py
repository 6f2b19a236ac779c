"""The contract's building blocks: strict JSON bodies, integers as JSON Schema has them, optional
fields that keep their description, query parameters, and the contract's own bounds."""

from __future__ import annotations

from typing import Annotated, Any, Literal, get_args

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    model_validator,
)
from pydantic.fields import FieldInfo
from pydantic_core import PydanticKnownError

from renderer.io.mesh_io import UPLOAD_FORMATS
from renderer.limits import (
    MAX_MOTION_SEED,
)
from renderer.scenes.animation import MUSEUM_KINDS

MuseumKind = Literal[MUSEUM_KINDS]
ModelFormat = Literal[UPLOAD_FORMATS]


# The API's own bound: a 32-bit placement seed (the renderer takes any non-negative one).
MAX_SEED = 2**32 - 1
# The incoherent motion's seed as JSON carries it: integers beyond 2^53 are not exact in JavaScript nor
# in JSON Schema validators that compare as doubles (2^63 − 1 + 192 passed as ≤ 2^63 − 1).
MAX_JSON_MOTION_SEED = min(MAX_MOTION_SEED, 2**53)
# A 422 lists at most this many errors, then one entry counting the rest: a body of 150,000 bad
# spheres is answered in a few kB, not 72 MB.
MAX_LISTED_ERRORS = 20
# The spheres of a scene are validated this many at a time, keeping only the first
# MAX_LISTED_ERRORS errors (the others are counted): the memory of a refusal stays that of one
# chunk's errors, and the GIL is given up between chunks (the event loop keeps answering).
SPHERE_CHUNK = 2048


def optional(tp: Any) -> Any:
    """``tp | None`` (left out: keep the current value) with ``tp``'s description on the
    field itself, where OpenAPI looks for a query parameter's description."""
    info = next((m for m in get_args(tp)[1:] if isinstance(m, FieldInfo)), None)
    return Annotated[tp | None, Field(description=info.description if info else None)]


class Strict(BaseModel):
    """A JSON body's model: unknown fields are errors; NaN and ±inf are rejected everywhere; types are
    strict — a number is a JSON number (``"1"`` and ``true`` are not), an integer an integral JSON number
    (an int field refuses ``1.5`` and ``true``), a boolean ``true``/``false``."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)


def _integral(value: Any) -> Any:
    """An integer as JSON Schema has it (draft 6 on, what the OpenAPI schema says): any number without a
    fraction, so ``4.0`` is 4 — a strict int would refuse it — but ``true`` is none (in Python it equals 1,
    and an int Literal such as 1 | 4 | 9 | 16 would take it). Text is left to the field: a body's strict
    int refuses ``"4"``, a query's reads it."""
    if isinstance(value, bool):
        raise PydanticKnownError("int_type")
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


Integral = BeforeValidator(_integral)


# ---- query parameters ---------------------------------------------------------------
class QueryModel(BaseModel):
    """Query parameters: unknown ones are ignored (links may carry the client's own); no NaN or ±inf.
    ``null`` for an optional parameter — what the schema allows there, and what a generic client sends
    for it — is the parameter left out."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _null_is_left_out(cls, data: Any) -> Any:
        if isinstance(data, dict) and "null" in data.values():
            optional = {k for k, f in cls.model_fields.items() if f.default is None and not f.is_required()}
            return {k: v for k, v in data.items() if not (v == "null" and k in optional)}
        return data

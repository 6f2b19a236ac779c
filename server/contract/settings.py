"""The render settings as request and answer models, made from their declarations
(:data:`renderer.config.settings.SETTINGS`): the patch a body or a query names (:class:`RenderParams`,
:class:`SettingsPatch`) and a session's whole settings (:class:`FullSettings`)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, cast, get_args

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    create_model,
)

from renderer.config import settings as declared
from renderer.config.settings import SettingSpec, SettingValues

from .fields import Integral, optional


# ---- render settings ----------------------------------------------------------
# Every model of the render settings is made from their declarations (renderer.config.settings.SETTINGS):
# a setting's type, bounds or choices, default and description are said there once.
def setting_type(spec: SettingSpec) -> Any:
    """The field type of one setting: its bounds or choices, its doc as the description; integers as
    JSON Schema has them (:data:`Integral`)."""
    described = Field(description=spec.description())
    if spec.choices is not None:
        values = Literal[spec.choices]  # type: ignore[name-defined]  # a Literal of the declared choices, made at run time
        return Annotated[values, Integral, described] if spec.type == "integer" else Annotated[values, described]
    if spec.type == "boolean":
        return Annotated[bool, described]
    assert spec.bounds is not None, f"setting {spec.name}: a number has bounds"
    lo, hi = spec.bounds
    if spec.type == "integer":
        return Annotated[int, Field(ge=lo, le=hi, description=spec.description()), Integral]
    return Annotated[float, Field(ge=lo, le=hi, allow_inf_nan=False, description=spec.description())]


class RenderParamsBase(BaseModel):
    """What :func:`build_render_params` adds the settings' fields to."""

    model_config = ConfigDict(allow_inf_nan=False)
    setting_names: ClassVar[tuple[str, ...]] = ()

    def given(self) -> SettingValues:
        """The settings named, as a patch of a session's settings (each checked against its declaration)."""
        return cast(SettingValues, {k: v for k in self.setting_names if (v := getattr(self, k)) is not None})


def build_render_params(specs: Iterable[SettingSpec] | None = None) -> type[RenderParamsBase]:
    """Every setting of ``specs`` (default: renderer.config.settings.SETTINGS as it is now), optional: what a request
    names (body or query)."""
    specs = tuple(declared.SETTINGS if specs is None else specs)
    model = create_model(
        "RenderParams",
        __base__=RenderParamsBase,
        __module__=__name__,
        **{s.name: (optional(setting_type(s)), None) for s in specs},
    )  # type: ignore[call-overload]
    model.__doc__ = """Render settings a request names; the ones left out (or null) keep their value.

    Declared once for the body (:class:`SettingsPatch`) and the query of a frame
    (:class:`FrameQuery`)."""
    model.setting_names = tuple(s.name for s in specs)
    return model


def build_full_settings(specs: Iterable[SettingSpec] | None = None) -> type[BaseModel]:
    """Every setting of ``specs`` (default: renderer.config.settings.SETTINGS as it is now) as a session has it; those
    added after the first sessions were stored take their default when a stored session lacks them."""
    specs = tuple(declared.SETTINGS if specs is None else specs)
    return create_model(
        "FullSettings",
        __module__=__name__,
        __doc__=FULL_SETTINGS_DOC,  # type: ignore[call-overload]
        **{s.name: (s.python_type, ... if s.stored_since_first else s.default) for s in specs},
    )


FULL_SETTINGS_DOC = "All render settings of a session (the render-settings JSON of docs/FORMATS.md plus ``quality``)."
SETTING_TYPES: dict[str, Any] = {s.name: setting_type(s) for s in declared.SETTINGS}
MaxPrims, TreeDepth, RecursionDepth, Time, Method, Mode = (
    SETTING_TYPES[k] for k in ("max_prims", "max_tree_depth", "max_recursion_depth", "time", "method", "mode")
)
MethodName = get_args(Method)[0]
ModeName = get_args(Mode)[0]

if TYPE_CHECKING:
    RenderParams = RenderParamsBase
else:
    RenderParams = build_render_params()


class SettingsPatch(RenderParams):
    """Some render settings; the ones left out (or null) keep their value. A JSON body: strict
    types as :class:`Strict` (the query, :class:`FrameQuery`, reads the same fields from text)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)


if TYPE_CHECKING:
    FullSettings = BaseModel
else:
    FullSettings = build_full_settings()

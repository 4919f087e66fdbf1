"""The models featherstar ships, by kind and by name.

`build_model(kind, options)` is what scenes use (options are build options: they change the
equations' structure). `MODELS` names the default builds for `featherstar build`.
"""
from __future__ import annotations

from typing import Callable, Mapping

from .errors import ModelError
from .feather import feather_model
from .model import Model
from .robot import robot_model
from .servo import servo_model
from .stroke_source import constant_source_model, stroke_source_model

_BUILDERS: dict[str, tuple[Callable[..., Model], tuple[str, ...]]] = {
    "feather": (feather_model, ("morphology", "n_units", "root_support", "drag_points", "drag_split", "wake")),
    "servo": (servo_model, ()),
    "robot": (robot_model, ()),
    # signal sources: the SSP export's FMUs of a scene's stroke and constant blocks
    "stroke_source": (stroke_source_model, ()),
    "constant_source": (constant_source_model, ("outputs",)),
}

MODELS: dict[str, Callable[[], Model]] = {
    "feather-plain": lambda: feather_model("plain"),
    "feather-chordwise": lambda: feather_model("chordwise"),
    "feather-spanwise": lambda: feather_model("spanwise"),
    "servo": servo_model,
    "robot": robot_model,
}


def build_options(kind: str) -> tuple[str, ...]:
    """The build options of model `kind` (those that change its equations' structure)."""
    if kind not in _BUILDERS:
        raise ModelError(f"unknown model kind '{kind}'; known: {', '.join(_BUILDERS)}")
    return _BUILDERS[kind][1]


def build_model(kind: str, options: Mapping[str, object] | None = None) -> Model:
    """The model of `kind` ("feather", "servo", "robot", "stroke_source", "constant_source")
    with the given build options."""
    if kind not in _BUILDERS:
        raise ModelError(f"unknown model kind '{kind}'; known: {', '.join(_BUILDERS)}")
    builder, allowed = _BUILDERS[kind]
    options = dict(options or {})
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ModelError(
            f"model '{kind}' has no build option(s) {unknown}; its build options are: {', '.join(allowed) or 'none'}"
        )
    return builder(**options)

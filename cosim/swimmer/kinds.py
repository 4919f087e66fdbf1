"""The swimmer's block kinds, added to the master's registry (featherstar.cosim.scene.blocks):
`stroke`, the paper's 4-phase stroke controller (featherstar.cosim.swimmer.controller), memoryless.
featherstar.cosim imports this module, so every scene read through the package knows the kind."""
from __future__ import annotations

import dataclasses
from typing import Any, Mapping

from ...fmu_src.errors import ModelError
from ..errors import SceneError
from ..scene.block_kind import BlockKind, ResolvedBlock, where
from ..scene.blocks import register_kind
from ..scene.specs import BlockSpec, FrozenMap, parse_value
from .controller import COMMAND_KEYS, STROKE_KEYS, StrokeController, resolve_command, resolve_stroke

#: The model parameter a stroke gives every model block that leaves it unset.
STROKE_AMPLITUDE_PARAMETER = "stroke_amplitude_rad"


class StrokeKind(BlockKind):
    name = "stroke"

    def override(self, spec: BlockSpec, key: str, raw: Any) -> BlockSpec:
        if key not in STROKE_KEYS + COMMAND_KEYS:
            raise SceneError(f"{where(spec)} has no setting '{key}'; it has: {', '.join(STROKE_KEYS + COMMAND_KEYS)}")
        value = parse_value(raw)
        if isinstance(value, (str, bool)):
            raise SceneError(f"{where(spec)}: {key} = {raw!r} is not a number")
        return dataclasses.replace(spec, overrides=spec.overrides.set(key, float(value)))

    def override_batch(self, spec: BlockSpec, items: Mapping[str, Any]) -> BlockSpec:
        """Each batch applies to the stroke the earlier ones produced: the period rule ("period_s
        alone scales the four times") then holds per batch, whatever came before."""
        if spec.overrides:
            try:
                stroke = resolve_stroke(spec.settings, spec.overrides, where(spec))
            except (ModelError, TypeError, ValueError) as exc:
                raise SceneError(str(exc)) from None
            settings = {k: getattr(stroke, k) for k in ("t_up_s", "t_hold_up_s", "t_down_s", "t_hold_down_s",
                                                         "amplitude_deg")}
            settings.update({k: v for source in (spec.settings, spec.overrides) for k, v in source.items()
                             if k in COMMAND_KEYS})
            spec = dataclasses.replace(spec, settings=FrozenMap(settings), overrides=FrozenMap())
        return super().override_batch(spec, items)

    def resolve(self, spec: BlockSpec) -> ResolvedBlock:
        try:
            stroke = resolve_stroke(spec.settings, spec.overrides, where(spec))
            command = resolve_command(spec.settings, spec.overrides, where(spec))
        except (ModelError, TypeError, ValueError) as exc:
            raise SceneError(str(exc)) from None
        obj = StrokeController(spec.name, stroke, command)
        return ResolvedBlock(spec, {}, dict(obj.outputs), memoryless=True, iterable=True, continuous=True,
                             identity=("stroke", stroke, command), period_s=stroke.period_s, obj=obj, can_rollback=True,
                             gives_period=True,
                             ramps_s=((stroke.t_up_s, f"{spec.name}.t_up_s"), (stroke.t_down_s, f"{spec.name}.t_down_s")),
                             # the feather's oscillatory drag takes each point's Keulegan-Carpenter
                             # number from the stroke amplitude (docs/model.md)
                             shared_parameters={STROKE_AMPLITUDE_PARAMETER: stroke.amplitude_rad})


register_kind(StrokeKind())

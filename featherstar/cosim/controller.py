"""The stroke controller block: the paper's 4-phase root motion as a memoryless Python block.

Outputs the commanded root angle, rate and acceleration (the servo's setpoint, or the feather's
root motion directly in the kinematic scene). Ramps are minimum-jerk (10τ³ − 15τ⁴ + 6τ⁵, see
`featherstar.cosim.stroke`): angle, rate and acceleration are continuous, so the added-mass force, which is
proportional to the root acceleration, stays finite; a linear ramp would put infinite spikes
into the thrust.

How a scene gives the stroke (block table keys, and the same names for --set overrides):

* absolute times: t_up_s, t_hold_up_s, t_down_s, t_hold_down_s (defaults 0.25, 0.5, 0.25, 0.5)
* or the paper's optimizer variables at a fixed period: period_s with log10_up_down,
  log10_hold_up_down, log10_hold_move (base-10 logs of t_up/t_down, t_hold_up/t_hold_down,
  t_hold/t_move);
* amplitude_deg (peak to peak, centred on 0; default 60).

Override rule: overridden times replace the scene's; overridden log-ratios are applied at the
(possibly overridden) period; `period_s` alone scales all four times by P_new / P_old, which
keeps every log-ratio (the paper fixes the period and optimizes the ratios). Setting period_s
together with some but not all of the four times is refused (ambiguous), as is mixing times
and log-ratios.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping

from ..fmu_src.errors import ModelError

from .block import Port
from .stroke import Stroke, root_motion, root_motion_function, stroke_from_log_ratios

TIME_KEYS = ("t_up_s", "t_hold_up_s", "t_down_s", "t_hold_down_s")
RATIO_KEYS = ("log10_up_down", "log10_hold_up_down", "log10_hold_move")
STROKE_KEYS = (*TIME_KEYS, *RATIO_KEYS, "period_s", "amplitude_deg")

OUTPUTS = {
    "angle_rad": Port("angle_rad", "rad", "commanded root angle"),
    "rate_rad_s": Port("rate_rad_s", "rad/s", "commanded root rate"),
    "accel_rad_s2": Port("accel_rad_s2", "rad/s2", "commanded root acceleration"),
}


def _apply(stroke: Stroke, values: Mapping[str, float], where: str) -> Stroke:
    times = {k: float(values[k]) for k in TIME_KEYS if k in values}
    ratios = {k: float(values[k]) for k in RATIO_KEYS if k in values}
    if times and ratios:
        raise ModelError(f"{where}: give the stroke by times ({', '.join(times)}) or by log-ratios "
                         f"({', '.join(ratios)}), not both")
    if "amplitude_deg" in values:
        stroke = dataclasses.replace(stroke, amplitude_deg=float(values["amplitude_deg"]))
    if times:
        stroke = dataclasses.replace(stroke, **times)
    period = float(values["period_s"]) if "period_s" in values else None
    if ratios:
        current = dict(zip(RATIO_KEYS, stroke.log_ratios()))
        current.update(ratios)
        return stroke_from_log_ratios(period or stroke.period_s, *(current[k] for k in RATIO_KEYS),
                                      amplitude_deg=stroke.amplitude_deg)
    if period is not None:
        if not (math.isfinite(period) and period > 0):
            raise ModelError(f"{where}: period_s = {period!r} must be > 0")
        if times and len(times) < 4:
            raise ModelError(
                f"{where}: period_s was set with only {', '.join(times)}: set period_s alone (it scales "
                "all four times and keeps their ratios) or all four times")
        if len(times) == 4 and abs(stroke.period_s - period) > 1e-9 * period:
            raise ModelError(f"{where}: the four times sum to {stroke.period_s:g} s, not period_s = {period:g} s")
        scale = period / stroke.period_s
        stroke = dataclasses.replace(stroke, **{k: getattr(stroke, k) * scale for k in TIME_KEYS})
    return stroke


def resolve_stroke(settings: Mapping[str, float], overrides: Mapping[str, float], where: str) -> Stroke:
    """The stroke a scene's controller table plus the user's overrides describe (rule above)."""
    for source in (settings, overrides):
        for key in source:
            if key not in STROKE_KEYS:
                raise ModelError(f"{where}: unknown stroke setting '{key}' (known: {', '.join(STROKE_KEYS)})")
    stroke = _apply(Stroke(), settings, where)
    return _apply(stroke, overrides, where)


class StrokeController:
    """Memoryless block: root angle, rate and acceleration of the stroke at any instant."""

    can_iterate = True

    def __init__(self, name: str, stroke: Stroke) -> None:
        self.name = name
        self.stroke = stroke
        self.inputs: dict[str, Port] = {}
        self.outputs = dict(OUTPUTS)
        self._t = 0.0

    @property
    def period_s(self) -> float:
        return self.stroke.period_s

    def evaluate(self, t_s: float, inputs: Mapping[str, float]) -> dict[str, float]:
        a, r, acc = root_motion(self.stroke, t_s)
        return {"angle_rad": a, "rate_rad_s": r, "accel_rad_s2": acc}

    def outputs_at(self, t_s: float) -> tuple[float, float, float]:
        """Output values at t_s in the order of `outputs` (the master's fast path: no dicts)."""
        return root_motion(self.stroke, t_s)

    def time_function(self) -> tuple[Any, list[float]]:
        """The outputs as a CasADi function of (t_s, stroke parameters) and this stroke's
        parameters: the strong coupling's compiled right-hand side evaluates it in C."""
        s = self.stroke
        return root_motion_function(), [s.t_up_s, s.t_hold_up_s, s.t_down_s, s.t_hold_down_s, s.amplitude_rad]

    # Block protocol
    def start(self, t0_s: float) -> None:
        self._t = t0_s

    def set_inputs(self, values: Mapping[str, float]) -> None:
        pass

    def get_outputs(self) -> dict[str, float]:
        return self.evaluate(self._t, {})

    def do_step(self, t_s: float, h_s: float) -> None:
        self._t = t_s + h_s

    def close(self) -> None:
        pass

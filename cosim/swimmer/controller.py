"""The stroke controller block: the paper's 4-phase root motion as a memoryless Python block.

Outputs the commanded root angle, rate and acceleration (the servo's setpoint, or the feather's
root motion directly in the kinematic scene). Ramps are minimum-jerk (10τ³ − 15τ⁴ + 6τ⁵, see
`featherstar.cosim.swimmer.stroke`): angle, rate and acceleration are continuous, so the added-mass force, which is
proportional to the root acceleration, stays finite; a linear ramp would put infinite spikes
into the thrust.

How a scene gives the stroke (block table keys, and the same names for --set overrides):

* absolute times: t_up_s, t_hold_up_s, t_down_s, t_hold_down_s (defaults 0.25, 0.5, 0.25, 0.5)
* or the paper's optimizer variables at a fixed period: period_s with log10_up_down,
  log10_hold_up_down, log10_hold_move (base-10 logs of t_up/t_down, t_hold_up/t_hold_down,
  t_hold/t_move);
* amplitude_deg (peak to peak, centred on 0; default 60).

How the command reaches the servo (default: continuously, as the stroke itself):

* sample_period_s: the command a digital bench sends, updated every sample_period_s and held
  between updates (the bench loop's period, its master.step_s). As featherstar's real-time
  master (Gauss-Seidel) does, the command written at the start of a step is the stroke at that
  step's end. Rate and acceleration outputs are then zero (a held setpoint), so this is for a
  servo's setpoint, not a kinematic root; and for the strong coupling (a weak coupling's macro
  steps already sample the controller, so a bench run itself leaves it at 0).
* rate_limit_rad_s: each sample moves at most rate_limit_rad_s * sample_period_s from the last,
  starting from 0 rad, as featherstar's hardware servo block limits what it commands
  (featherstar.hil.blocks.ServoBlock, MG996R: 6.2 rad/s).

A simulation that is to predict a bench measurement runs the bench's command path: on the
plain feather, holding the command for 5 ms raises the mean thrust of a fast-downstroke stroke
by ~10 % and the rate limit lowers it by ~30 % (docs/bench-loop.md).

Override rule: overridden times replace the scene's; overridden log-ratios are applied at the
(possibly overridden) period; `period_s` alone scales all four times by P_new / P_old, which
keeps every log-ratio (the paper fixes the period and optimizes the ratios). Setting period_s
together with some but not all of the four times is refused (ambiguous), as is mixing times
and log-ratios.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

from ...fmu_src.errors import ModelError
from ..framework.block import Port, TimeSource
from ..scene.listing import SettableKey
from .stroke import Stroke, root_motion, root_motion_function, stroke_from_log_ratios

TIME_KEYS = ("t_up_s", "t_hold_up_s", "t_down_s", "t_hold_down_s")
RATIO_KEYS = ("log10_up_down", "log10_hold_up_down", "log10_hold_move")
STROKE_KEYS = (*TIME_KEYS, *RATIO_KEYS, "period_s", "amplitude_deg")
COMMAND_KEYS = ("sample_period_s", "rate_limit_rad_s")
#: A sample instant is taken within this fraction of the period (floating-point grids).
_SAMPLE_EPS = 1e-9

OUTPUTS = {
    "angle_rad": Port("angle_rad", "rad", "commanded root angle"),
    "rate_rad_s": Port("rate_rad_s", "rad/s", "commanded root rate"),
    "accel_rad_s2": Port("accel_rad_s2", "rad/s2", "commanded root acceleration"),
}


def _number(values: Mapping[str, float], key: str, where: str) -> float:
    """values[key] as a float, or a ModelError naming the key (a boolean or a text is no number)."""
    value = values[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ModelError(f"{where}: {key} = {value!r} is not a number")
    return float(value)


def _apply(stroke: Stroke, values: Mapping[str, float], where: str) -> Stroke:
    times = {k: _number(values, k, where) for k in TIME_KEYS if k in values}
    ratios = {k: _number(values, k, where) for k in RATIO_KEYS if k in values}
    if times and ratios:
        raise ModelError(f"{where}: give the stroke by times ({', '.join(times)}) or by log-ratios "
                         f"({', '.join(ratios)}), not both")
    if "amplitude_deg" in values:
        stroke = dataclasses.replace(stroke, amplitude_deg=_number(values, "amplitude_deg", where))
    if times:
        stroke = dataclasses.replace(stroke, **times)
    period = _number(values, "period_s", where) if "period_s" in values else None
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
            if key not in STROKE_KEYS + COMMAND_KEYS:
                raise ModelError(f"{where}: unknown stroke setting '{key}' (known: "
                                 f"{', '.join(STROKE_KEYS + COMMAND_KEYS)})")
    stroke_only = [{k: v for k, v in source.items() if k in STROKE_KEYS} for source in (settings, overrides)]
    stroke = _apply(Stroke(), stroke_only[0], where)
    return _apply(stroke, stroke_only[1], where)


@dataclass(frozen=True)
class Command:
    """How the stroke reaches the servo (module docstring): continuous when sample_period_s = 0."""

    sample_period_s: float = 0.0
    rate_limit_rad_s: float = 0.0

    def __post_init__(self) -> None:
        for key in COMMAND_KEYS:
            value = getattr(self, key)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ModelError(f"stroke '{key}' = {value!r} must be a number >= 0")
        if self.rate_limit_rad_s and not self.sample_period_s:
            raise ModelError("stroke 'rate_limit_rad_s' limits a sampled command: set sample_period_s too")


def resolve_command(settings: Mapping[str, float], overrides: Mapping[str, float], where: str) -> Command:
    """The command path a controller table plus the user's overrides describe."""
    values = {k: _number(source, k, where) for source in (settings, overrides) for k in source
              if k in COMMAND_KEYS}
    try:
        return Command(**values)
    except ModelError as exc:
        raise ModelError(f"{where}: {exc}") from None


class StrokeController(TimeSource):
    """Memoryless block: root angle, rate and acceleration of the stroke at any instant (or of
    its sampled command, `Command`: a function of time with jumps at the sample instants, which
    it reports as time events so the strong coupling's solver restarts there)."""

    def __init__(self, name: str, stroke: Stroke, command: Command = Command()) -> None:
        super().__init__()
        self.name = name
        self.stroke = stroke
        self.command = command
        self.outputs = dict(OUTPUTS)
        self._t0 = 0.0
        self._samples_rad: list[float] = []   # the sampled command, computed as far as asked

    @property
    def period_s(self) -> float:
        return self.stroke.period_s

    def settable_keys(self) -> list[SettableKey]:
        """The keys --set takes on a stroke block, with this stroke's values (the period rule:
        `period_s` alone scales the four times; the log ratios re-shape them at the same period)."""
        s, c = self.stroke, self.command
        up_down, hold_up_down, hold_move = s.log_ratios()
        return [
            SettableKey("t_up_s", s.t_up_s, "s", "(0, inf)", "rise (power stroke up)"),
            SettableKey("t_hold_up_s", s.t_hold_up_s, "s", "[0, inf)", "hold at the top"),
            SettableKey("t_down_s", s.t_down_s, "s", "(0, inf)", "fall"),
            SettableKey("t_hold_down_s", s.t_hold_down_s, "s", "[0, inf)", "hold at the bottom"),
            SettableKey("period_s", s.period_s, "s", "(0, inf)", "alone: scales the four times"),
            SettableKey("amplitude_deg", s.amplitude_deg, "deg", "(0, 180]",
                    f"peak to peak, centred on zero: {s.amplitude_deg:g} means +-{s.amplitude_deg / 2:g} deg"),
            SettableKey("log10_up_down", up_down, "", "", "log10 t_up/t_down at the same period"),
            SettableKey("log10_hold_up_down", hold_up_down, "", "", "log10 t_hold_up/t_hold_down"),
            SettableKey("log10_hold_move", hold_move, "", "", "log10 (holds)/(moves)"),
            SettableKey("sample_period_s", c.sample_period_s, "s", "[0, inf)",
                    "send the command as samples this far apart (0: continuous)"),
            SettableKey("rate_limit_rad_s", c.rate_limit_rad_s, "rad/s", "[0, inf)",
                    "limit the sampled command's rate (0: none)"),
        ]

    def evaluate(self, t_s: float, inputs: Mapping[str, float]) -> dict[str, float]:
        a, r, acc = self.outputs_at(t_s)
        return {"angle_rad": a, "rate_rad_s": r, "accel_rad_s2": acc}

    def outputs_at(self, t_s: float) -> tuple[float, float, float]:
        """Output values at t_s in the order of `outputs` (the master's fast path: no dicts)."""
        if not self.command.sample_period_s:
            return root_motion(self.stroke, t_s)
        return self._sample_rad(self._sample_index(t_s)), 0.0, 0.0

    def _sample_index(self, t_s: float) -> int:
        return max(math.floor((t_s - self._t0) / self.command.sample_period_s + _SAMPLE_EPS), 0)

    def _sample_rad(self, k: int) -> float:
        period, limit = self.command.sample_period_s, self.command.rate_limit_rad_s
        samples = self._samples_rad
        while len(samples) <= k:
            target = root_motion(self.stroke, self._t0 + (len(samples) + 1) * period)[0]
            if limit:
                last = samples[-1] if samples else 0.0
                target = min(max(target, last - limit * period), last + limit * period)
            samples.append(target)
        return samples[k]

    def next_sample_s(self, t_s: float) -> float | None:
        """The first instant after t_s at which the output jumps (None: it never jumps)."""
        if not self.command.sample_period_s:
            return None
        return self._t0 + (self._sample_index(t_s) + 1) * self.command.sample_period_s

    def time_function(self) -> tuple[Any, list[float]] | None:
        """The outputs as a CasADi function of (t_s, stroke parameters) and this stroke's
        parameters: the strong coupling's compiled right-hand side evaluates it in C. None for
        a sampled command (a Python op)."""
        if self.command.sample_period_s:
            return None
        s = self.stroke
        return root_motion_function(), [s.t_up_s, s.t_hold_up_s, s.t_down_s, s.t_hold_down_s, s.amplitude_rad]

    def fmu_stand_in(self) -> tuple[str, dict[str, Any], dict[str, float]] | None:
        """The FMU that stands in for this block in an SSP package (featherstar.cosim.ssp.export):
        (catalog model kind, build options, parameter values); None for a sampled command."""
        if self.command.sample_period_s:
            return None
        s = self.stroke
        return "stroke_source", {}, {"t_up_s": s.t_up_s, "t_hold_up_s": s.t_hold_up_s, "t_down_s": s.t_down_s,
                                     "t_hold_down_s": s.t_hold_down_s, "amplitude_rad": s.amplitude_rad}

    def start(self, t0_s: float) -> None:
        super().start(t0_s)
        self._t0, self._samples_rad = t0_s, []   # samples count from the run's start

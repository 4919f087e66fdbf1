"""The stroke controller as an FMU, for masters that have no stroke block (libcosim, Ecos, fmpy).

featherstar's stroke is a time function (featherstar.cosim.swimmer.stroke.root_motion_symbolic).
A fmu_src Model is an autonomous ODE, so the FMU carries its own clock: one state `clock_s` with
d(clock_s)/dt = 1 and the root motion evaluated at it. Its outputs are then exact at every
communication point of any master (the CS shell integrates 1 exactly), and as Model Exchange
the same FMU gives featherstar's strong coupling the same stroke as its own block.
Bench-local on purpose: the project's stroke-source FMU belongs in fmu_src, not here.
"""
from __future__ import annotations

from pathlib import Path

import casadi as ca
from featherstar.cosim.swimmer.stroke import Stroke, root_motion_symbolic
from featherstar.fmu_src.export import build_fmu
from featherstar.fmu_src.model import Model, Parameter, Variable


def stroke_source_model(stroke: Stroke) -> Model:
    """Clock state -> (angle_rad, rate_rad_s, accel_rad_s2) of `stroke`; stroke times are parameters."""
    names = (("t_up_s", stroke.t_up_s, "rising time"), ("t_hold_up_s", stroke.t_hold_up_s, "hold at the top"),
             ("t_down_s", stroke.t_down_s, "falling time"),
             ("t_hold_down_s", stroke.t_hold_down_s, "hold at the bottom"))
    parameters = tuple(Parameter(n, v, "s", 0.0, 100.0, d) for n, v, d in names) + (
        Parameter("amplitude_rad", stroke.amplitude_rad, "rad", 0.0, 3.2, "peak to peak", True),)
    p = ca.SX.sym("p", len(parameters))
    clock = ca.SX.sym("clock_s")
    angle, rate, accel = root_motion_symbolic(clock, p[0], p[1], p[2], p[3], p[4])
    return Model(
        name="stroke_source",
        description="featherstar's stroke as a time source (bench helper)",
        states=(Variable("clock_s", "s", "time since the start"),),
        inputs=(),
        parameters=parameters,
        outputs=(Variable("angle_rad", "rad", "root angle"), Variable("rate_rad_s", "rad/s", "root rate"),
                 Variable("accel_rad_s2", "rad/s2", "root acceleration")),
        x=clock, u=ca.SX.sym("u", 0), p=p, xdot=ca.SX(1.0), y=ca.vertcat(angle, rate, accel),
    )


def build_stroke_fmu(stroke: Stroke, out_dir: Path, fmi_version: int = 2) -> Path:
    """`<out_dir>/stroke_source.fmu` (FMI 2.0 by default: what every peer reads)."""
    return build_fmu(stroke_source_model(stroke), out_dir, fmi_version=fmi_version)

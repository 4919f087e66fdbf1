"""The shell refuses what the model code would silently compute with: start values are readable
before initialization, NaN or out-of-range parameters and non-finite inputs or states are refused
with fmi3Error and a log line, and no NaN output or derivative is ever returned with fmi3OK.
Exercised through fmpy's low-level FMI 3 API, as an independent importer would."""
from __future__ import annotations

import math
import re

import casadi as ca
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import fmi3Float64

from featherstar.fmu_src.export import build_fmu
from featherstar.fmu_src.model import Model, Parameter, Variable

DISCARD, ERROR = 2, 3


def sqrt_model() -> Model:
    """level' = -rate from 1: the output sqrt(level) turns NaN at t = 1/rate while the derivative
    stays finite (as the robot's outputs can); `gain` may only be 1 or 2 (a switch)."""
    x, u, p = ca.SX.sym("x", 1), ca.SX.sym("u", 1), ca.SX.sym("p", 2)
    return Model(
        name="toy_sqrt",
        description="Output that leaves its domain while the state is fine (strictness toy)",
        states=(Variable("level", "m", "Level", 1.0),),
        inputs=(Variable("offset", "m", "Added to the output", 0.0),),
        parameters=(Parameter("rate", 1.0, "m/s", 0.0, 10.0, "Drain rate", exclusive_minimum=True),
                    Parameter("gain", 1.0, "1", 1.0, 2.0, "Output gain", choices=(1.0, 2.0))),
        outputs=(Variable("root", "m", "gain * sqrt(level) + offset"),),
        x=x, u=u, p=p,
        xdot=-p[0] * ca.DM.ones(1),
        y=p[1] * ca.sqrt(x[0]) + u[0],
    )


@pytest.fixture(scope="module")
def sqrt_fmu(fmu_cache):
    return build_fmu(sqrt_model())


def refs(path) -> dict[str, int]:
    return {v.name: v.valueReference for v in read_model_description(path).modelVariables}


@pytest.mark.parametrize("kind", ["CS", "ME"])
def test_start_values_are_readable_before_initialization(oscillator_fmu, open_fmu, kind):
    vr = refs(oscillator_fmu)
    log: list[tuple[int, str]] = []
    fmu = open_fmu(oscillator_fmu, kind, log)
    assert fmu.getFloat64([vr["phi"], vr["omega"], vr["torque"], vr["k"], vr["inertia"]]) == [0.5, 0.0, 0.0, 4.0, 1.0]
    fmu.setFloat64([vr["k"], vr["phi"]], [9.0, 0.25])
    assert fmu.getFloat64([vr["k"], vr["phi"]]) == [9.0, 0.25]
    with pytest.raises(FMICallException):
        fmu.getFloat64([vr["net_torque"]])
    assert log[-1][0] == ERROR and "'net_torque'" in log[-1][1] and "calculated" in log[-1][1]
    fmu.enterInitializationMode(startTime=0.0)
    # net torque = torque - k phi - c omega with the values set before initialization
    assert fmu.getFloat64([vr["net_torque"]]) == [pytest.approx(-9.0 * 0.25)]


@pytest.mark.parametrize("name, value, why", [
    ("k", math.nan, "parameter 'k' = nan N.m/rad refused: outside its valid range [0, 1e+06] N.m/rad"),
    ("k", -1.0, "parameter 'k' = -1 N.m/rad refused: outside its valid range [0, 1e+06] N.m/rad"),
    ("inertia", 0.0, "parameter 'inertia' = 0 kg.m2 refused: outside its valid range (0, 1000] kg.m2"),
    ("c", math.inf, "parameter 'c' = inf N.m.s/rad refused"),
    ("torque", math.nan, "input 'torque' = nan refused: not finite"),
    ("torque", -math.inf, "input 'torque' = -inf refused: not finite"),
    ("phi", math.nan, "state 'phi' = nan refused: not finite"),
])
def test_invalid_values_are_refused_with_a_log_line(oscillator_fmu, open_fmu, name, value, why):
    vr = refs(oscillator_fmu)
    log: list[tuple[int, str]] = []
    slave = open_fmu(oscillator_fmu, "CS", log)
    before = slave.getFloat64([vr["k"], vr[name]])
    with pytest.raises(FMICallException):
        slave.setFloat64([vr["k"], vr[name]], [5.0, value])  # all or nothing: k stays too
    assert log[-1][0] == ERROR and why in log[-1][1], log
    assert slave.getFloat64([vr["k"], vr[name]]) == before
    if name != "phi":  # states are only settable before initialization
        slave.enterInitializationMode(startTime=0.0)
        slave.exitInitializationMode()
        with pytest.raises(FMICallException):
            slave.setFloat64([vr[name]], [value])
        assert why in log[-1][1]
        slave.doStep(0.0, 0.1)  # the instance carries on with its valid values
        assert all(math.isfinite(v) for v in slave.getFloat64(list(vr.values())))


def test_boundary_and_listed_values_are_accepted(sqrt_fmu, open_fmu):
    vr = refs(sqrt_fmu)
    log: list[tuple[int, str]] = []
    slave = open_fmu(sqrt_fmu, "CS", log)
    slave.setFloat64([vr["rate"], vr["gain"]], [10.0, 2.0])
    slave.setFloat64([vr["rate"]], [1e-300])  # only 0 itself is excluded
    with pytest.raises(FMICallException):
        slave.setFloat64([vr["gain"]], [1.5])
    assert "parameter 'gain' = 1.5 refused: it must be one of the 2 values" in log[-1][1]
    assert slave.getFloat64([vr["gain"]]) == [2.0]


def test_cosimulation_step_with_a_nan_output_fails(sqrt_fmu, open_fmu):
    vr = refs(sqrt_fmu)
    log: list[tuple[int, str]] = []
    slave = open_fmu(sqrt_fmu, "CS", log)
    slave.setFloat64([vr["rate"]], [2.0])  # empty at t = 0.5
    slave.enterInitializationMode(startTime=0.0)
    slave.exitInitializationMode()
    slave.doStep(0.0, 0.4)
    assert slave.getFloat64([vr["root"]]) == [pytest.approx(math.sqrt(0.2))]
    with pytest.raises(FMICallException) as failure:
        slave.doStep(0.4, 0.2)
    assert failure.value.status == ERROR
    assert log[-1][0] == ERROR
    assert re.fullmatch(r"doStep failed at t=0.6 : output 'root' is not finite \(-?nan\)", log[-1][1])
    with pytest.raises(FMICallException) as read:  # nor is the NaN handed out afterwards
        slave.getFloat64([vr["root"]])
    assert read.value.status == DISCARD and re.search(r"'root' is not finite \(-?nan\) at t=0.6$", log[-1][1])
    assert slave.getFloat64([vr["level"]]) == [pytest.approx(-0.2)]


def test_model_exchange_never_returns_nan_with_ok(sqrt_fmu, drain_fmu, open_fmu):
    log: list[tuple[int, str]] = []
    model = open_fmu(drain_fmu, "ME", log)
    model.enterInitializationMode(startTime=0.0)
    model.exitInitializationMode()
    model.enterContinuousTimeMode()
    model.setContinuousStates((fmi3Float64 * 1)(0.25), 1)
    derivatives = (fmi3Float64 * 1)()
    model.getContinuousStateDerivatives(derivatives, 1)
    assert list(derivatives) == [pytest.approx(-1.0)]
    with pytest.raises(FMICallException):
        model.setContinuousStates((fmi3Float64 * 1)(math.nan), 1)
    assert log[-1] == (ERROR, "fmi3SetContinuousStates: state 'level' = nan refused: not finite")
    model.setContinuousStates((fmi3Float64 * 1)(-0.25), 1)  # sqrt of a negative level
    with pytest.raises(FMICallException) as failure:
        model.getContinuousStateDerivatives(derivatives, 1)
    assert failure.value.status == DISCARD
    assert log[-1][0] == DISCARD and log[-1][1].startswith(
        "fmi3GetContinuousStateDerivatives: der(level) is not finite (")

    vr = refs(sqrt_fmu)
    me = open_fmu(sqrt_fmu, "ME", log)
    me.enterInitializationMode(startTime=0.0)
    me.exitInitializationMode()
    me.enterContinuousTimeMode()
    me.setContinuousStates((fmi3Float64 * 1)(-1.0), 1)
    with pytest.raises(FMICallException) as failure:
        me.getFloat64([vr["root"]])
    assert failure.value.status == DISCARD and "'root' is not finite" in log[-1][1]


def test_robot_parameters_that_break_the_four_bar_are_refused_before_the_first_step(fmu_cache, open_fmu):
    """Each robot parameter is in range, but a 0.5 m crank cannot close the four-bar: the root
    angle is NaN. The FMU says so when initialization ends instead of stepping on with NaN."""
    from featherstar.fmu_src.robot import robot_model

    path = build_fmu(robot_model())
    vr = refs(path)
    log: list[tuple[int, str]] = []
    slave = open_fmu(path, "CS", log)
    slave.setFloat64([vr["crank_m"]], [0.5])
    slave.enterInitializationMode(startTime=0.0)
    with pytest.raises(FMICallException):
        slave.exitInitializationMode()
    assert log[-1][0] == ERROR and re.match(
        r"fmi3ExitInitializationMode: output '\w+' is not finite \(-?nan\) at t=0 with the values set", log[-1][1])
    slave.setFloat64([vr["crank_m"]], [0.025])  # still in Initialization: the importer can fix it
    slave.exitInitializationMode()
    slave.doStep(0.0, 0.01)
    assert all(math.isfinite(v) for v in slave.getFloat64([vr["root_angle_rad"], vr["body_position_m"]]))

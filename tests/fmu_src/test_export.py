"""FMU export: validation, ME and CS simulation, the shell's state machine and robustness,
FMU state rollback, the build cache and the `featherstar build` command. Toy models only."""
from __future__ import annotations

import argparse
import ctypes
import math
import sys
import threading
import time
import types
import zipfile
from pathlib import Path

import casadi as ca
import fmpy
import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave, fmi3Boolean, fmi3Float64, fmi3ValueReference
from fmpy.validation import validate_fmu

from featherstar.fmu_src import cli, export
from featherstar.fmu_src.errors import BuildError
from featherstar.fmu_src.export import build_fmu

TIME_VR = 4294967295
# When the toy drain (h' = -(sqrt(h) + 0.5), h(0) = 1) empties: integral of dh / (sqrt(h) + 0.5).
DRAIN_EMPTY_TIME = 2.0 - math.log(3.0)


def variable_refs(path: Path) -> dict[str, int]:
    return {v.name: v.valueReference for v in read_model_description(path).modelVariables}


def start_cs(slave, tolerance: float | None = None, start_values: dict[int, float] | None = None) -> None:
    for vr, value in (start_values or {}).items():
        slave.setFloat64([vr], [value])
    slave.enterInitializationMode(tolerance=tolerance, startTime=0.0)
    slave.exitInitializationMode()


def cvodes_reference(model, parameters: dict[str, float], inputs: np.ndarray, step: float,
                     x0: list[float] | None = None) -> np.ndarray:
    """States and outputs after each step of a zero-order-hold input, integrated by CVODES."""
    step_map = ca.integrator("F", "cvodes", {"x": model.x, "p": ca.vertcat(model.u, model.p), "ode": model.xdot},
                             0.0, step, {"reltol": 1e-12, "abstol": 1e-14})
    output = ca.Function("g", [model.x, model.u, model.p], [model.y])
    p = model.parameter_vector(parameters)
    x = ca.DM(x0 if x0 is not None else model.initial_state())
    rows = []
    for u in inputs:
        x = step_map(x0=x, p=ca.vertcat(u, p))["xf"]
        rows.append(np.concatenate([x.full().ravel(), output(x, u, p).full().ravel()]))
    return np.array(rows)


def test_fmu_validates_and_describes_units_ranges_and_cosimulation(oscillator_fmu, drain_fmu):
    for path in (oscillator_fmu, drain_fmu):
        assert validate_fmu(str(path)) == []
        names = zipfile.ZipFile(path).namelist()
        identifier = read_model_description(path).coSimulation.modelIdentifier
        assert {"modelDescription.xml", f"binaries/x86_64-linux/{identifier}.so",
                f"sources/{identifier}_wrap.c", "sources/fmi3_shell.c"} <= set(names)
    description = read_model_description(oscillator_fmu)
    variables = {v.name: v for v in description.modelVariables}
    assert description.coSimulation.canHandleVariableCommunicationStepSize
    assert description.coSimulation.canGetAndSetFMUstate and description.modelExchange.canGetAndSetFMUstate
    assert {u.name for u in description.unitDefinitions} == {v.unit for v in variables.values()}
    assert variables["omega"].unit == "rad/s" and variables["der(omega)"].unit == "rad/s2"
    assert variables["k"].min == "0.0" and variables["k"].max == "1000000.0"
    assert variables["torque"].description == "Applied torque"
    assert all(v.unit and v.description for v in variables.values())


@pytest.mark.parametrize("fmi_type", ["ModelExchange", "CoSimulation"])
def test_simulate_fmu_runs_both_interfaces(oscillator_fmu, make_oscillator, fmi_type):
    # A repeated time stamp is a step in fmpy's input signals.
    inputs = np.array([(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (4.0, 1.0)], dtype=[("time", float), ("torque", float)])
    result = fmpy.simulate_fmu(oscillator_fmu, fmi_type=fmi_type, stop_time=4.0, output_interval=0.01,
                               start_values={"k": 9.0}, input=inputs, relative_tolerance=1e-8,
                               output=["phi", "omega", "net_torque"])
    # ME results carry an extra row at the input event; states are continuous there.
    time_grid, first = np.unique(result["time"], return_index=True)
    held = np.where(time_grid[:-1] >= 2.0 - 1e-9, 1.0, 0.0)
    reference = cvodes_reference(make_oscillator(), {"k": 9.0}, held, 0.01)
    error = np.max(np.abs(result["phi"][first][1:] - reference[:, 0]))
    # fmpy's ME loop holds inputs per output interval and never stops CVode there: ~1e-4 floor.
    assert error < (1e-4 if fmi_type == "ModelExchange" else 1e-6)


def test_cosimulation_matches_cvodes(oscillator_fmu, make_oscillator, open_fmu):
    vr = variable_refs(oscillator_fmu)
    slave = open_fmu(oscillator_fmu, "CS")
    start_cs(slave, tolerance=1e-10, start_values={vr["k"]: 9.0, vr["c"]: 0.5})
    step, inputs = 0.05, np.sin(np.arange(100) * 0.05 * 3.0)
    rows = []
    for n, u in enumerate(inputs):
        slave.setFloat64([vr["torque"]], [u])
        slave.doStep(n * step, step)
        rows.append(slave.getFloat64([vr["phi"], vr["omega"], vr["net_torque"], vr["angle"]]))
    reference = cvodes_reference(make_oscillator(), {"k": 9.0, "c": 0.5}, inputs, step)
    assert np.max(np.abs(np.array(rows) - reference)) <= 1e-6
    assert slave.getFloat64([TIME_VR]) == [pytest.approx(100 * step, abs=1e-12)]


def test_time_and_every_variable_readable_in_each_allowed_state(oscillator_fmu, open_fmu):
    vrs = list(variable_refs(oscillator_fmu).values())
    assert TIME_VR in vrs

    def read_all(fmu, expected_time):
        assert fmu.getFloat64([TIME_VR]) == [expected_time]
        one_by_one = [fmu.getFloat64([vr])[0] for vr in vrs]
        assert fmu.getFloat64(vrs) == one_by_one
        assert all(math.isfinite(v) for v in one_by_one)

    model = open_fmu(oscillator_fmu, "ME")
    model.enterInitializationMode(startTime=1.5)
    read_all(model, 1.5)
    model.exitInitializationMode()
    read_all(model, 1.5)  # EventMode
    model.updateDiscreteStates()
    model.enterContinuousTimeMode()
    model.setTime(2.0)
    read_all(model, 2.0)
    model.terminate()
    read_all(model, 2.0)

    slave = open_fmu(oscillator_fmu, "CS")
    slave.enterInitializationMode(startTime=0.0)
    read_all(slave, 0.0)
    slave.exitInitializationMode()
    read_all(slave, 0.0)  # StepMode
    slave.doStep(0.0, 0.25)
    read_all(slave, 0.25)
    slave.terminate()
    read_all(slave, 0.25)


def test_out_of_sequence_and_invalid_calls_fail_cleanly(oscillator_fmu, open_fmu):
    vr = variable_refs(oscillator_fmu)
    log: list[tuple[int, str]] = []
    slave = open_fmu(oscillator_fmu, "CS", log)
    with pytest.raises(FMICallException):
        slave.doStep(0.0, 0.1)
    assert log[-1] == (3, "fmi3DoStep: not allowed in state Instantiated")
    with pytest.raises(FMICallException):  # calculated: no value before initialization
        slave.getFloat64([vr["net_torque"]])
    start_cs(slave)
    bad_calls = {
        "getContinuousStates": lambda: slave.fmi3GetContinuousStates(slave.component, (fmi3Float64 * 2)(), 2),
        "set state": lambda: slave.setFloat64([vr["phi"]], [1.0]),
        "set output": lambda: slave.setFloat64([vr["net_torque"]], [1.0]),
        "unknown vr": lambda: slave.getFloat64([999]),
        "vr 0": lambda: slave.getFloat64([0]),
        "set time": lambda: slave.setFloat64([TIME_VR], [3.0]),
        "nValues": lambda: slave.getFloat64([vr["phi"]], nValues=2),
        "NULL values": lambda: slave.fmi3GetFloat64(slave.component, (fmi3ValueReference * 1)(vr["phi"]), 1, None, 1),
        "NULL instance": lambda: slave.fmi3GetFloat64(None, (fmi3ValueReference * 1)(vr["phi"]), 1, (fmi3Float64 * 1)(), 1),
        "wrong time": lambda: slave.doStep(5.0, 0.1),
        "negative step": lambda: slave.doStep(0.0, -0.1),
        "enterContinuousTimeMode": lambda: slave.fmi3EnterContinuousTimeMode(slave.component),
        "enterInitializationMode": lambda: slave.enterInitializationMode(),
        "Int32": lambda: slave.getInt32([vr["phi"]]),
        "serialize": lambda: slave.serializeFMUState(slave.getFMUState()),
    }
    for name, call in bad_calls.items():
        with pytest.raises(FMICallException):
            call()
            pytest.fail(f"{name} did not fail")
    assert any("not available in Co-Simulation" in m for _, m in log)
    assert any("unknown value reference 999" in m for _, m in log)
    # The instance survives all of it.
    slave.doStep(0.0, 0.1)
    assert math.isfinite(slave.getFloat64([vr["phi"]])[0])

    model = open_fmu(oscillator_fmu, "ME", log)
    with pytest.raises(FMICallException):
        model.setTime(1.0)
    model.enterInitializationMode()
    model.exitInitializationMode()
    with pytest.raises(FMICallException):
        model.setContinuousStates((fmi3Float64 * 2)(0.0, 0.0), 2)
    with pytest.raises(FMICallException):
        model.fmi3DoStep(model.component, 0.0, 0.1, True, None, None, None, None)
    assert "fmi3SetContinuousStates: not allowed in state EventMode" in [m for _, m in log]
    model.enterContinuousTimeMode()
    model.setContinuousStates((fmi3Float64 * 2)(0.1, 0.0), 2)
    assert model.getFloat64([vr["phi"]]) == [0.1]


def test_wrong_instantiation_token_is_refused(oscillator_fmu, tmp_path):
    description = read_model_description(oscillator_fmu)
    slave = FMU3Slave(guid="not-this-model", unzipDirectory=fmpy.extract(oscillator_fmu, tmp_path),
                      modelIdentifier=description.coSimulation.modelIdentifier)
    with pytest.raises(Exception, match="Failed to instantiate"):
        slave.instantiate(logMessage=lambda *args: None)
    slave.freeLibrary()


def test_fmu_state_rolls_back_a_cosimulation_exactly(oscillator_fmu, open_fmu):
    vr = variable_refs(oscillator_fmu)
    slave = open_fmu(oscillator_fmu, "CS")
    start_cs(slave, tolerance=1e-6)
    watched = [TIME_VR, vr["phi"], vr["omega"], vr["net_torque"]]

    def steps(t0, n, u):
        rows = []
        for i in range(n):
            slave.setFloat64([vr["torque"]], [u * i])
            slave.doStep(t0 + i * 0.01, 0.01)
            rows.append(slave.getFloat64(watched))
        return rows

    steps(0.0, 10, 0.3)
    saved = slave.getFMUState()
    first = steps(0.1, 20, 1.0)
    slave.setFMUState(saved)
    assert slave.getFloat64([TIME_VR]) == [pytest.approx(0.1, abs=1e-15)]
    assert steps(0.1, 20, 1.0) == first
    slave.setFMUState(saved)
    assert steps(0.1, 20, -1.0) != first
    slave.freeFMUState(saved)


def test_stiff_model_is_stable_in_cosimulation(oscillator_fmu, make_oscillator, open_fmu):
    vr = variable_refs(oscillator_fmu)
    stiff = {"k": 1.0, "c": 1e4}  # eigenvalues ~ -1e4 and -1e-4
    slave = open_fmu(oscillator_fmu, "CS")
    start_cs(slave, tolerance=1e-8, start_values={vr["k"]: 1.0, vr["c"]: 1e4, vr["omega"]: 2.0})
    slave.setFloat64([vr["torque"]], [1.0])
    rows = []
    for n in range(10):
        slave.doStep(n * 0.2, 0.2)
        rows.append(slave.getFloat64([vr["phi"], vr["omega"], vr["net_torque"], vr["angle"]]))
    reference = cvodes_reference(make_oscillator(), stiff, np.ones(10), 0.2, x0=[0.5, 2.0])
    # omega(0) = 2 decays within ~1e-4 s, then phi creeps at torque / c. The net torque is a
    # difference of O(1) terms with omega weighted by c = 1e4: it carries 1e4 x omega's error.
    error = np.abs(np.array(rows) - reference)
    assert np.max(error[:, [0, 1, 3]]) < 1e-9 and np.max(error[:, 2]) < 1e-6


def test_non_finite_derivative_fails_dostep(drain_fmu, open_fmu):
    vr = variable_refs(drain_fmu)
    log: list[tuple[int, str]] = []
    slave = open_fmu(drain_fmu, "CS", log)
    start_cs(slave)
    slave.doStep(0.0, 0.5)
    flags = [fmi3Boolean() for _ in range(3)]
    last = fmi3Float64()
    with pytest.raises(FMICallException):
        slave.fmi3DoStep(slave.component, 0.5, 1.0, True, *map(ctypes.byref, flags), ctypes.byref(last))
    assert last.value == pytest.approx(DRAIN_EMPTY_TIME, abs=1e-3)
    assert log[-1][1].startswith(f"doStep failed at t={last.value:.10g} : ")
    level = slave.getFloat64([vr["level"], TIME_VR])
    assert 0 <= level[0] < 1e-3 and level[1] == last.value
    with pytest.raises(FMICallException):
        slave.doStep(last.value, 0.1)
    slave.reset()
    start_cs(slave)
    slave.doStep(0.0, 0.5)


def test_rebuild_hits_cache_and_concurrent_builds_agree(make_oscillator, tmp_path, monkeypatch):
    monkeypatch.setenv("FEATHERSTAR_CACHE", str(tmp_path / "cache"))
    model = make_oscillator("toy_cached")
    start = time.perf_counter()
    cold = build_fmu(model)
    cold_s = time.perf_counter() - start
    start = time.perf_counter()
    warm = build_fmu(model, tmp_path / "out")
    warm_s = time.perf_counter() - start
    assert warm == tmp_path / "out" / "toy_cached.fmu"
    assert warm.read_bytes() == cold.read_bytes()
    assert cold_s >= 10 * warm_s, (cold_s, warm_s)

    # Two builders of a new model: one compiles, the other waits and takes its result.
    monkeypatch.setenv("FEATHERSTAR_CACHE", str(tmp_path / "cache2"))
    results: list[Path] = []
    threads = [threading.Thread(target=lambda: results.append(build_fmu(model))) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(results) == 2 and results[0] == results[1] and validate_fmu(str(results[0])) == []
    assert [p.name for p in results[0].parent.iterdir() if p.name.endswith(".part")] == []


def test_compiler_failure_raises_build_error_and_keeps_cache(oscillator_fmu, make_oscillator, monkeypatch):
    before = oscillator_fmu.read_bytes()
    monkeypatch.setattr(export, "_WRAP_HOOKS", "\n#error deliberately broken hooks\n")
    with pytest.raises(BuildError, match="deliberately broken hooks"):
        build_fmu(make_oscillator(), force=True)
    assert oscillator_fmu.read_bytes() == before


def test_cli_build_and_unknown_model(oscillator_fmu, make_oscillator, tmp_path, monkeypatch, capsys):
    catalog = types.ModuleType("featherstar.fmu_src.catalog")
    catalog.MODELS = {"toy-oscillator": make_oscillator}
    monkeypatch.setitem(sys.modules, "featherstar.fmu_src.catalog", catalog)
    parser = argparse.ArgumentParser(prog="featherstar")
    cli.register(parser.add_subparsers())

    args = parser.parse_args(["build", "--out", str(tmp_path)])
    assert args.func(args) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "toy_oscillator.fmu")
    assert (tmp_path / "toy_oscillator.fmu").read_bytes() == oscillator_fmu.read_bytes()

    args = parser.parse_args(["build", "toy-oscillator", "feather-nope"])
    with pytest.raises(SystemExit):
        args.func(args)
    assert "unknown model(s) feather-nope; known models: toy-oscillator" in capsys.readouterr().err

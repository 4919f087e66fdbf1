"""FMI 2.0 export: the same shell behind an FMI 2.0 adapter. Validates in fmpy, exports only
fmi2 functions, gives bit-identical results to the FMI 3.0 FMU of the same model in both
interfaces, keeps the shell's checks (with their log lines through the FMI 2.0 logger)."""
from __future__ import annotations

import argparse
import ctypes
import math
import sys
import types
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.validation import validate_fmu

from featherstar.fmu_src import cli
from featherstar.fmu_src.errors import BuildError
from featherstar.fmu_src.export import build_fmu


@pytest.fixture(scope="module")
def oscillator_fmu2(fmu_cache, make_oscillator) -> Path:
    return build_fmu(make_oscillator(), fmi_version=2)


def test_fmi2_fmu_validates_and_exports_only_fmi2_functions(oscillator_fmu2, tmp_path):
    assert validate_fmu(str(oscillator_fmu2)) == []
    description = read_model_description(oscillator_fmu2)
    assert description.fmiVersion == "2.0"
    assert description.modelExchange.modelIdentifier == description.coSimulation.modelIdentifier == "toy_oscillator"
    assert description.coSimulation.canGetAndSetFMUstate and description.modelExchange.canGetAndSetFMUstate
    names = set(zipfile.ZipFile(oscillator_fmu2).namelist())
    assert "binaries/linux64/toy_oscillator.so" in names and "sources/fmi2_adapter.c" in names
    assert not any(n.startswith("extra/") or n.endswith("buildDescription.xml") for n in names)
    variables = {v.name: v for v in description.modelVariables}
    assert "time" not in variables
    assert variables["der(omega)"].derivative is variables["omega"]
    assert variables["k"].unit == "N.m/rad" and variables["k"].max == "1000000.0"
    library = ctypes.CDLL(str(Path(fmpy.extract(oscillator_fmu2, tmp_path)) / "binaries/linux64/toy_oscillator.so"))
    assert hasattr(library, "fmi2DoStep") and hasattr(library, "fmi2GetDerivatives")
    assert not hasattr(library, "fmi3DoStep") and not hasattr(library, "casadi_fmi3GetFloat64")


@pytest.mark.parametrize("fmi_type", ["ModelExchange", "CoSimulation"])
def test_fmi2_results_equal_fmi3_results(oscillator_fmu, oscillator_fmu2, fmi_type):
    inputs = np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 2.0), (3.0, 2.0)], dtype=[("time", float), ("torque", float)])
    results = [fmpy.simulate_fmu(str(path), fmi_type=fmi_type, stop_time=3.0, output_interval=0.01,
                                 start_values={"k": 9.0, "c": 0.5}, input=inputs, relative_tolerance=1e-8,
                                 output=["phi", "omega", "net_torque"])
               for path in (oscillator_fmu, oscillator_fmu2)]
    for name in ("time", "phi", "omega", "net_torque"):
        assert np.array_equal(results[0][name], results[1][name]), name


def test_fmi2_shell_checks_log_through_the_fmi2_logger(oscillator_fmu2, tmp_path):
    description = read_model_description(oscillator_fmu2)
    vr = {v.name: v.valueReference for v in description.modelVariables}
    log: list[tuple[int, str]] = []

    @fmi2CallbackLoggerTYPE
    def logger(environment, instance, status, category, message):  # noqa: ANN001 (ctypes callback)
        log.append((status, message.decode()))

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = logger
    slave = FMU2Slave(guid=description.guid, unzipDirectory=fmpy.extract(oscillator_fmu2, tmp_path),
                      modelIdentifier="toy_oscillator", instanceName="strict2")
    slave.instantiate(callbacks=callbacks)
    try:
        assert slave.getReal([vr["phi"], vr["k"]]) == [0.5, 4.0]  # start values before initialization
        with pytest.raises(FMICallException):
            slave.setReal([vr["k"]], [math.nan])
        assert log[-1] == (3, "fmi3SetFloat64: parameter 'k' = nan N.m/rad refused: outside its valid range "
                              "[0, 1e+06] N.m/rad")
        with pytest.raises(FMICallException):
            slave.setReal([vr["torque"]], [math.inf])
        assert log[-1] == (3, "fmi3SetFloat64: input 'torque' = inf refused: not finite")
        slave.setupExperiment(tolerance=1e-8, startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        with pytest.raises(FMICallException):
            slave.doStep(0.5, 0.1)  # not the FMU's time
        assert "differs from the FMU time" in log[-1][1]
        with pytest.raises(FMICallException):
            slave.getInteger([vr["phi"]])
        assert log[-1][1] == "fmi2GetInteger: the model has no variables of this type"
        slave.doStep(0.0, 0.1)
        state = slave.getFMUstate()
        slave.doStep(0.1, 0.1)
        after = slave.getReal([vr["phi"], vr["omega"]])
        slave.setFMUstate(state)
        slave.doStep(0.1, 0.1)
        assert slave.getReal([vr["phi"], vr["omega"]]) == after
        slave.freeFMUstate(state)
        slave.terminate()
    finally:
        slave.freeInstance()


def test_unknown_fmi_version_is_refused(make_oscillator):
    with pytest.raises(BuildError, match="FMI version 1 cannot be built"):
        build_fmu(make_oscillator(), fmi_version=1)


def test_cli_build_fmi2(oscillator_fmu2, make_oscillator, tmp_path, monkeypatch, capsys):
    catalog = types.ModuleType("featherstar.fmu_src.catalog")
    catalog.MODELS = {"toy-oscillator": make_oscillator}
    monkeypatch.setitem(sys.modules, "featherstar.fmu_src.catalog", catalog)
    parser = argparse.ArgumentParser(prog="featherstar")
    cli.register(parser.add_subparsers())
    args = parser.parse_args(["build", "--fmi", "2", "--out", str(tmp_path)])
    assert args.func(args) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "toy_oscillator.fmu")
    assert (tmp_path / "toy_oscillator.fmu").read_bytes() == oscillator_fmu2.read_bytes()
    with pytest.raises(SystemExit):
        parser.parse_args(["build", "--fmi", "1"])

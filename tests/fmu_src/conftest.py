"""Toy models and FMU fixtures for the export tests; reusable by any test under tests/fmu_src.

FMUs are built once per session into a private build cache, so no test writes to the user's
~/.cache and no test pays for a compile another one already did.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Iterator

import casadi as ca
import fmpy
import pytest
from fmpy import read_model_description
from fmpy.fmi3 import FMU3Model, FMU3Slave

from featherstar.fmu_src.export import build_fmu
from featherstar.fmu_src.model import Model, Parameter, Variable

def oscillator_model(name: str = "toy_oscillator") -> Model:
    """J phi'' = torque - k phi - c phi'. With c = 1e4, k = J = 1 one eigenvalue is ~ -1e4."""
    x, u, p = ca.SX.sym("x", 2), ca.SX.sym("u", 1), ca.SX.sym("p", 3)
    phi, omega, torque, k, c, inertia = x[0], x[1], u[0], p[0], p[1], p[2]
    return Model(
        name=name,
        description="Damped torsional oscillator (export test toy)",
        states=(Variable("phi", "rad", "Angle", 0.5), Variable("omega", "rad/s", "Angular rate", 0.0)),
        inputs=(Variable("torque", "N.m", "Applied torque", 0.0),),
        parameters=(
            Parameter("k", 4.0, "N.m/rad", 0.0, 1e6, "Spring stiffness"),
            Parameter("c", 0.3, "N.m.s/rad", 0.0, 1e5, "Viscous damping"),
            Parameter("inertia", 1.0, "kg.m2", 0.0, 1e3, "Moment of inertia", exclusive_minimum=True),
        ),
        # The net torque depends on the input directly: an output with direct feedthrough.
        outputs=(Variable("net_torque", "N.m", "Torque accelerating the rotor"),
                 Variable("angle", "rad", "Angle, as an output")),
        x=x, u=u, p=p,
        xdot=ca.vertcat(omega, (torque - k * phi - c * omega) / inertia),
        y=ca.vertcat(torque - k * phi - c * omega, phi),
    )


def drain_model() -> Model:
    """h' = -(sqrt(h) + 0.5) from h = 1: empties at DRAIN_EMPTY_TIME, then sqrt gives NaN."""
    x, u, p = ca.SX.sym("x", 1), ca.SX.sym("u", 0), ca.SX.sym("p", 0)
    return Model(
        name="toy_drain",
        description="Tank that drains below empty (NaN test toy; no inputs, no parameters)",
        states=(Variable("level", "m", "Water level", 1.0),),
        inputs=(), parameters=(),
        outputs=(Variable("level_out", "m", "Water level, as an output"),),
        x=x, u=u, p=p,
        xdot=-(ca.sqrt(x[0]) + 0.5),
        y=x[0],
    )


@pytest.fixture(scope="session")
def make_oscillator() -> Callable[..., Model]:
    """oscillator_model(name="toy_oscillator"): the toy factory, for tests that need the Model."""
    return oscillator_model


@pytest.fixture(scope="session")
def fmu_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A private FEATHERSTAR_CACHE for the session."""
    cache = tmp_path_factory.mktemp("fmu-cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("FEATHERSTAR_CACHE", str(cache))
        yield cache


@pytest.fixture(scope="session")
def oscillator_fmu(fmu_cache: Path) -> Path:
    return build_fmu(oscillator_model())


@pytest.fixture(scope="session")
def drain_fmu(fmu_cache: Path) -> Path:
    return build_fmu(drain_model())


@pytest.fixture
def open_fmu(tmp_path: Path) -> Iterator[Callable[..., FMU3Slave | FMU3Model]]:
    """open_fmu(path, "CS" | "ME", log=None) -> an instantiated fmpy FMU3Slave / FMU3Model.

    Log messages are appended to `log` as (status, message). Instances are freed at teardown.
    """
    opened: list[FMU3Slave | FMU3Model] = []

    def open_(path: Path, kind: str, log: list[tuple[int, str]] | None = None) -> FMU3Slave | FMU3Model:
        description = read_model_description(path)
        unzipped = fmpy.extract(path, tmp_path / f"{path.stem}-{len(opened)}")
        interface = description.coSimulation if kind == "CS" else description.modelExchange
        cls = FMU3Slave if kind == "CS" else FMU3Model
        fmu = cls(guid=description.guid, unzipDirectory=unzipped,
                  modelIdentifier=interface.modelIdentifier, instanceName=f"{path.stem}{len(opened)}")

        def record(env, status, category, message):  # noqa: ANN001 (ctypes callback)
            if log is not None:
                log.append((status, message.decode()))

        fmu.instantiate(logMessage=record)
        opened.append(fmu)
        return fmu

    yield open_
    for fmu in opened:
        fmu.freeInstance()

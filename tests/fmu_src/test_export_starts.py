"""Start values in modelDescription.xml are the model's doubles, bit for bit (CasADi rounds them
to 6 significant digits; an importer that applies the declared starts, as every SSP tool does,
would otherwise run another model). Checked on every shipped FMU, FMI 3.0 and FMI 2.0, against
the Model and against the values the binary itself holds before initialization."""
from __future__ import annotations

import math
import struct
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import casadi as ca
import pytest

from featherstar.fmu_src.catalog import MODELS, build_model
from featherstar.fmu_src.export import build_fmu
from featherstar.fmu_src.fmi2_description import fmi2_model_description
from featherstar.fmu_src.model import Model, Parameter, Variable

# Doubles that 6 (or 15) significant digits do not carry, and the edges of the format.
AWKWARD = (math.pi / 3, 1 / 3, 0.1 + 0.2, 5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
           -0.0, 123456789.12345679, 1e-7 * 3)


def _model_starts(model: Model) -> dict[str, float]:
    values = {v.name: v.start for v in (*model.states, *model.inputs)}
    values.update({p.name: p.default for p in model.parameters})
    return values


def _declared_starts(xml_text: str) -> dict[str, str]:
    root = ET.fromstring(xml_text)
    fmi3 = {v.get("name"): v.get("start") for v in root.iter("Float64")}
    fmi2 = {v.get("name"): v.find("Real").get("start") for v in root.iter("ScalarVariable")}
    return {name: start for name, start in {**fmi3, **fmi2}.items() if start is not None}


def _bits(value: float) -> bytes:
    return struct.pack("<d", value)


def _assert_exact(model: Model, xml_text: str) -> None:
    declared = _declared_starts(xml_text)
    expected = _model_starts(model)
    assert set(expected) <= set(declared), sorted(set(expected) - set(declared))
    wrong = {name: (declared[name], repr(value)) for name, value in expected.items()
             if _bits(float(declared[name])) != _bits(float(value))}
    assert not wrong, wrong


def _xml(fmu: Path) -> str:
    with zipfile.ZipFile(fmu) as archive:
        return archive.read("modelDescription.xml").decode()


def _awkward_model() -> Model:
    n = len(AWKWARD)
    x, u, p = ca.SX.sym("x", 1), ca.SX.sym("u", 1), ca.SX.sym("p", n)
    return Model(
        name="toy_awkward_starts",
        description="Start values no short decimal carries (export test toy)",
        states=(Variable("x", "1", "state", AWKWARD[0]),),
        inputs=(Variable("u", "1", "input", AWKWARD[1]),),
        parameters=tuple(Parameter(f"p{i}", value, "1", -sys.float_info.max, sys.float_info.max, f"awkward {i}")
                         for i, value in enumerate(AWKWARD)),
        outputs=(Variable("y", "1", "output"),),
        x=x, u=u, p=p, xdot=-x[0] + u[0], y=x[0] + ca.sum1(p) * 0,
    )


SOURCES = {"stroke_source": lambda: build_model("stroke_source"),   # the SSP export's stand-ins
           "constant_source": lambda: build_model("constant_source", {"outputs": {"flow_speed_m_s": "m/s"}})}


@pytest.mark.parametrize("name", [*MODELS, *SOURCES])
def test_shipped_fmu_declares_the_models_exact_starts(name):
    model = {**MODELS, **SOURCES}[name]()
    xml3 = _xml(build_fmu(model))
    _assert_exact(model, xml3)
    # The FMI 2.0 description is made from the FMI 3.0 one (fmu_src/export.py does exactly this);
    # the feathers' FMI 2.0 builds take minutes and are covered by the built ones below.
    _assert_exact(model, fmi2_model_description(xml3))


@pytest.mark.parametrize("name", ["servo", "robot", "feather-plain"])
def test_built_fmi2_fmu_declares_the_models_exact_starts(fmu_cache, name):
    """In the session's cache, where test_fmus_fmi2.py builds the same FMUs."""
    model = MODELS[name]()
    _assert_exact(model, _xml(build_fmu(model, fmi_version=2)))


def test_awkward_starts_survive_export_and_equal_the_binarys(fmu_cache, open_fmu):
    model = _awkward_model()
    fmu = build_fmu(model)
    xml3 = _xml(fmu)
    _assert_exact(model, xml3)
    _assert_exact(model, _xml(build_fmu(model, fmi_version=2)))
    # What the binary holds in Instantiated (before any set) is what the XML says.
    root = ET.fromstring(xml3)
    declared = {v.get("name"): (int(v.get("valueReference")), v.get("start")) for v in root.iter("Float64")}
    names = list(_model_starts(model))
    instance = open_fmu(fmu, "CS")
    held = instance.getFloat64([declared[n][0] for n in names])
    assert [_bits(v) for v in held] == [_bits(float(declared[n][1])) for n in names]

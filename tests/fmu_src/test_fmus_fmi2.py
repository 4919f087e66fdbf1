"""The shipped models as FMI 2.0 FMUs (`featherstar build --fmi 2`): standard-clean in fmpy and,
in both interfaces, the same numbers as their FMI 3.0 FMUs. The two flapped feathers take minutes
to compile and share every line of the shell with the plain one: they are left to
`featherstar build --fmi 2` + `fmpy validate` by hand (docs/ssp.md)."""
from __future__ import annotations

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from featherstar.fmu_src.catalog import MODELS
from featherstar.fmu_src.export import build_fmu
from test_fmus import INPUTS


@pytest.mark.parametrize("name", ["servo", "robot", "feather-plain"])
def test_fmi2_fmu_validates_and_equals_fmi3(fmu_cache, name):
    model = MODELS[name]()
    fmi2, fmi3 = build_fmu(model, fmi_version=2), build_fmu(model)
    assert validate_fmu(str(fmi2)) == []
    start = {v.name: value for v, value in zip(model.inputs, INPUTS[name])}
    outputs = [v.name for v in (*model.states, *model.outputs)]
    for fmi_type in ("ModelExchange", "CoSimulation"):
        runs = [fmpy.simulate_fmu(str(path), fmi_type=fmi_type, stop_time=0.2, output_interval=0.01,
                                  start_values=start, output=outputs, relative_tolerance=1e-8)
                for path in (fmi3, fmi2)]
        for variable in ("time", *outputs):
            assert np.array_equal(runs[0][variable], runs[1][variable]), (fmi_type, variable)
        assert np.all(np.isfinite(runs[1][outputs[-1]]))

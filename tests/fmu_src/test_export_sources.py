"""The signal sources the SSP export puts in for a scene's stroke controller and constants
(fmu_src/stroke_source.py): standard-clean FMUs whose outputs are featherstar's stroke and
constants, in Co-Simulation (what Ecos and libcosim use) and Model Exchange."""
from __future__ import annotations

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from featherstar.cosim.swimmer.stroke import Stroke, root_motion
from featherstar.fmu_src.catalog import build_model
from featherstar.fmu_src.errors import ModelError
from featherstar.fmu_src.export import build_fmu

STROKE = Stroke(t_up_s=0.2, t_hold_up_s=0.35, t_down_s=0.3, t_hold_down_s=0.15, amplitude_deg=50.0)


@pytest.mark.parametrize("fmi_version", [3, 2])
@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_the_stroke_source_fmu_is_the_stroke(fmi_version, fmi_type):
    fmu = build_fmu(build_model("stroke_source"), fmi_version=fmi_version)
    assert validate_fmu(str(fmu)) == []
    start = {"t_up_s": STROKE.t_up_s, "t_hold_up_s": STROKE.t_hold_up_s, "t_down_s": STROKE.t_down_s,
             "t_hold_down_s": STROKE.t_hold_down_s, "amplitude_rad": STROKE.amplitude_rad}
    result = fmpy.simulate_fmu(str(fmu), fmi_type=fmi_type, stop_time=2.5, output_interval=0.01, start_values=start,
                               output=["angle_rad", "rate_rad_s", "accel_rad_s2"])
    expected = np.array([root_motion(STROKE, t) for t in result["time"]])
    for j, name in enumerate(("angle_rad", "rate_rad_s", "accel_rad_s2")):
        scale = np.max(np.abs(expected[:, j]))
        assert np.max(np.abs(result[name] - expected[:, j])) <= 1e-9 * scale, name


def test_the_constant_source_fmu_outputs_its_parameters():
    fmu = build_fmu(build_model("constant_source", {"outputs": {"flow_speed_m_s": "m/s", "u": "1"}}))
    assert validate_fmu(str(fmu)) == []
    description = fmpy.read_model_description(str(fmu))
    units = {v.name: v.unit for v in description.modelVariables}
    assert units["flow_speed_m_s"] == units["flow_speed_m_s_value"] == "m/s"
    result = fmpy.simulate_fmu(str(fmu), stop_time=0.5, output_interval=0.1,
                               start_values={"flow_speed_m_s_value": 0.125, "u_value": -3.5e-7})
    assert np.all(result["flow_speed_m_s"] == 0.125) and np.all(result["u"] == -3.5e-7)
    with pytest.raises(ModelError, match="at least one output"):
        build_model("constant_source", {"outputs": {}})

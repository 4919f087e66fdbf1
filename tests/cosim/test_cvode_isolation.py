"""The master's CVODE binding must not change fmpy's: both load the same SUNDIALS libraries."""
import featherstar.cosim.coupling._cvode  # noqa: F401  (importing it is the hazard under test)
import fmpy


def test_fmpy_model_exchange_still_works_after_loading_the_master(tmp_path):
    from featherstar.fmu_src.catalog import MODELS
    from featherstar.fmu_src.export import build_fmu

    path = build_fmu(MODELS["servo"](), tmp_path)
    result = fmpy.simulate_fmu(str(path), fmi_type="ModelExchange", stop_time=0.1,
                               start_values={"setpoint_rad": 0.2})
    assert result["time"][-1] == 0.1
    assert 0.0 < result["angle_rad"][-1] <= 0.2

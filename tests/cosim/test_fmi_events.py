"""Time events, discrete inputs and the FMU's own log lines, with hand-written FMI 2.0 and 3.0
FMUs (tests/cosim/c_fmus.py: `events` counts time events t = k * period into an Int32 and
integrates x' = level with `level` a discrete input; `vdp` is a Model-Exchange-only Van der Pol
oscillator)."""
from __future__ import annotations

import numpy as np
import pytest
from featherstar.cosim.errors import StepError
from featherstar.cosim.scene.data import scene_from_dict
from featherstar.cosim.swimmer.report import summary_table
from featherstar.cosim.swimmer.run import run_scene
from scipy.integrate import solve_ivp

PERIOD = 0.25


def _scene(fmu, coupling, interface=None, step_s=0.03, **blocks):
    block = {"kind": "fmu", "fmu": str(fmu)}
    if interface:
        block["interface"] = interface
    return scene_from_dict({
        "name": "events",
        "connections": ["clock.counter -> integ.level"],
        "master": {"coupling": coupling, "t_end_s": 1.1, "step_s": step_s, "output_interval_s": 0.01,
                   "rtol": 1e-9, "atol": 1e-11},
        "blocks": {"clock": dict(block), "integ": dict(block),
                   "rec": {"kind": "recorder", "signals": ["clock.counter", "clock.odd", "integ.x", "integ.counter"]},
                   **blocks},
    })


def _integral_of_counter(t: np.ndarray) -> np.ndarray:
    """x(t) = integral of floor(s / period) ds: the counter driven into x' = level."""
    k = np.floor(t / PERIOD + 1e-9)
    return PERIOD * k * (k - 1) / 2 + k * (t - k * PERIOD)


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("coupling,interface", [("strong", None), ("gauss-seidel", "me"), ("jacobi", "me")])
def test_time_events_at_the_exact_times_and_a_discrete_input_set_at_them(c_fmu, version, coupling, interface):
    """The Int32 counter steps exactly at k * period (the value recorded at an event time is the
    one after it); the counter drives the other FMU's discrete Float64 input (Int32 -> Float64),
    which takes it in event mode at the same instant, so its integral is exact."""
    result = run_scene(_scene(c_fmu("events", version), coupling, interface))
    t = result.time
    if coupling != "strong":  # weak: the events are communication points, whatever step_s is
        for k in (1, 2, 3, 4):
            assert np.min(np.abs(t - k * PERIOD)) < 1e-12
    expected = np.floor(t / PERIOD + 1e-9)
    assert np.array_equal(result["clock.counter"], expected.astype(np.int32))
    assert result["clock.counter"].dtype == np.int32 and result["clock.odd"].dtype == np.bool_
    assert np.array_equal(result["clock.odd"], expected % 2 == 1)
    assert np.max(np.abs(result["integ.x"] - _integral_of_counter(t))) < 1e-9
    assert result["integ.counter"][-1] == 4


@pytest.mark.parametrize("version", [2, 3])
def test_co_simulation_fmus_handle_their_events_inside_the_step(c_fmu, version):
    """As co-simulation FMUs the events happen inside doStep (the FMU stops at them); at every
    communication point the values are exact."""
    result = run_scene(_scene(c_fmu("events", version), "jacobi", "cs", step_s=0.05))
    t = result.time
    assert np.array_equal(result["clock.counter"], np.floor(t / PERIOD + 1e-9).astype(np.int32))
    assert np.max(np.abs(result["integ.x"] - _integral_of_counter(t))) < 1e-9


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("coupling", ["strong", "jacobi"])
def test_the_fmus_own_log_line_is_in_the_error(c_fmu, version, coupling):
    scene = _scene(c_fmu("events", version), coupling).with_overrides({"clock.period": -1.0})
    with pytest.raises(StepError) as err:
        run_scene(scene)
    text = str(err.value)
    assert "block 'clock'" in text and "ExitInitializationMode" in text
    assert "the FMU logged: parameter period must be > 0 s (got -1)" in text


@pytest.mark.parametrize("version", [2, 3])
def test_a_model_exchange_fmu_under_gauss_seidel_is_as_accurate_as_under_strong_coupling(c_fmu, version):
    """An ME-only FMU stepped by the weak master is integrated by CVODE with its error control
    intact from one macro step to the next: at the same rtol its error is within 10x of strong
    coupling's (it was 19-161x before CVODE kept its history across macro steps;
    bench/me_weak_accuracy.py)."""
    fmu = c_fmu("vdp", version)
    t_end = 10.0
    ref = solve_ivp(lambda t, x: [x[1], (1 - x[0] ** 2) * x[1] - x[0]], (0, t_end), [2.0, 0.0],
                    rtol=1e-13, atol=1e-13, dense_output=True)
    errors = {}
    for coupling in ("strong", "gauss-seidel"):
        scene = scene_from_dict({
            "name": "vdp", "connections": [],
            "master": {"coupling": coupling, "t_end_s": t_end, "step_s": 0.01, "output_interval_s": 0.01,
                       "rtol": 1e-6, "atol": 1e-8},
            "blocks": {"v": {"kind": "fmu", "fmu": str(fmu)}, "rec": {"kind": "recorder", "signals": ["v.x0", "v.x1"]}},
        })
        result = run_scene(scene)
        errors[coupling] = max(np.max(np.abs(result["v.x0"] - ref.sol(result.time)[0])),
                               np.max(np.abs(result["v.x1"] - ref.sol(result.time)[1])))
    assert errors["strong"] < 1e-3
    assert errors["gauss-seidel"] < 10 * errors["strong"]


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("coupling,interface,step_s", [
    ("strong", None, 0.03), ("jacobi", "me", 0.03), ("gauss-seidel", "me", 0.03),
    ("jacobi", "cs", 0.05), ("gauss-seidel", "cs", 0.05), ("mixed", "me", 0.03), ("mixed", "cs", 0.05)])
@pytest.mark.parametrize("max_count", [1, 2, 4])
def test_an_fmu_asking_to_terminate_ends_the_run_normally_at_that_time(c_fmu, version, coupling, interface,
                                                                       step_s, max_count):
    """terminateSimulation is the model's way to say it is done (ME: in the event update; CS: FMI
    3.0 doStep's out-argument, FMI 2.0 fmi2Discard + fmi2Terminated): the run ends at
    t = max_count * period without an error, the data are kept up to and including that time, the
    summary names who ended it and when."""
    t_stop = max_count * PERIOD
    scene = _scene(c_fmu("events", version), coupling, interface, step_s=step_s).with_overrides(
        {"clock.max_count": max_count})
    result = run_scene(scene)
    assert result.complete and "error" not in result.summary
    assert result.summary["terminated_by"] == "clock"
    assert result.summary["terminated_at_s"] == pytest.approx(t_stop, abs=1e-12)
    assert "terminated_note" not in result.summary
    t = result.time
    assert t[-1] == pytest.approx(t_stop, abs=1e-12) and np.all(np.diff(t) > 0)
    assert result["clock.counter"][-1] == max_count   # the values after the terminating event
    assert np.array_equal(result["clock.counter"], np.floor(t / PERIOD + 1e-9).astype(np.int32))
    # GS holds the counter after the step's event; mixed records a stepped block's output held
    # between communication points (here every block steps: the 10 ms grid inside 50 ms steps)
    if not (coupling in ("gauss-seidel", "mixed") and interface == "cs"):
        assert np.max(np.abs(result["integ.x"] - _integral_of_counter(t))) < 1e-9
    assert f"ended by                       clock (asked to terminate) at t={t_stop:g} s of 1.1 s" in \
        summary_table(result.summary)


@pytest.mark.parametrize("version", [2, 3])
def test_a_co_simulation_fmu_that_stops_inside_a_macro_step_ends_the_run_at_its_end_and_says_so(c_fmu, version):
    """doStep from 0.48 s to 0.51 s stops at the event at 0.5 s: the other blocks are at 0.51 s,
    so the run ends at that communication point, and the summary says where the FMU stopped."""
    scene = _scene(c_fmu("events", version), "jacobi", "cs", step_s=0.03).with_overrides({"clock.max_count": 2})
    result = run_scene(scene)
    assert result.complete
    assert result.summary["terminated_at_s"] == pytest.approx(0.51, abs=1e-12)
    assert result.time[-1] == pytest.approx(0.51, abs=1e-12) and result["clock.counter"][-1] == 2
    assert "clock stopped at t=0.5 s inside the last macro step" in result.summary["terminated_note"]


def test_the_adaptive_macro_step_does_not_take_a_discrete_jump_for_a_hold_error(c_fmu):
    """The counter jumps by 1 at each event; the adaptive weak master's error estimate covers
    only inputs driven by continuous real signals, so the jumps cost no rejected steps."""
    scene = _scene(c_fmu("events", 3), "jacobi", "cs", step_s=0.05).with_overrides(
        {"master.adaptive": True, "master.macro_rtol": 1e-3})
    result = run_scene(scene)
    assert result.summary["stats"]["rejected_steps"] == 0
    assert np.max(np.abs(result["integ.x"] - _integral_of_counter(result.time))) < 0.06


@pytest.mark.parametrize("version", [2, 3])
def test_a_discrete_input_driven_by_a_continuous_signal_is_sampled_on_the_recording_grid(c_fmu, version):
    """Strong coupling: the stroke angle drives the discrete input `level`; it is taken (in event
    mode) at every recording time, held in between, so x is the left Riemann sum of the samples."""
    scene = scene_from_dict({
        "name": "sampled", "connections": ["controller.angle_rad -> to_level.u", "to_level.y -> integ.level"],
        "master": {"coupling": "strong", "t_end_s": 1.0, "output_interval_s": 0.01, "rtol": 1e-10, "atol": 1e-12},
        "blocks": {"controller": {"kind": "stroke"}, "integ": {"kind": "fmu", "fmu": str(c_fmu("events", version))},
                   "to_level": {"kind": "gain", "gain": 1.0, "unit_in": "rad", "unit_out": ""},
                   "rec": {"kind": "recorder", "signals": ["controller.angle_rad", "integ.x"]}},
    })
    result = run_scene(scene)
    angle, x = result["controller.angle_rad"], result["integ.x"]
    riemann = np.concatenate([[0.0], np.cumsum(angle[:-1] * np.diff(result.time))])
    assert np.max(np.abs(angle)) > 0.5
    assert np.max(np.abs(x - riemann)) < 1e-9


def _ball_height(t: np.ndarray, g: float = 9.81, e: float = 0.7, h0: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Height and bounce count of the bouncing ball, analytic (flights between impacts)."""
    impacts, speeds = [np.sqrt(2 * h0 / g)], [e * np.sqrt(2 * g * h0)]
    while len(impacts) < 8:
        impacts.append(impacts[-1] + 2 * speeds[-1] / g)
        speeds.append(e * speeds[-1])
    impacts = np.array(impacts)
    k = np.searchsorted(impacts, t, side="right")
    start = np.where(k == 0, 0.0, impacts[np.maximum(k - 1, 0)])
    u = np.where(k == 0, 0.0, np.array(speeds)[np.maximum(k - 1, 0)])
    tau = t - start
    h = np.where(k == 0, h0 - g * t ** 2 / 2, u * tau - g * tau ** 2 / 2)
    return h, k


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("coupling", ["strong", "gauss-seidel"])
def test_state_events_are_located_exactly(c_fmu, version, coupling):
    """Bouncing ball (ME only, one event indicator): CVODE's root finding places every bounce,
    in strong coupling and inside a weak coupling's macro step alike; the height matches the
    analytic flights and the Int32 bounce count steps at the analytic impact times."""
    scene = scene_from_dict({
        "name": "ball", "connections": [],
        "master": {"coupling": coupling, "t_end_s": 2.0, "output_interval_s": 0.001, "step_s": 0.01,
                   "rtol": 1e-10, "atol": 1e-12},
        "blocks": {"ball": {"kind": "fmu", "fmu": str(c_fmu("ball", version))},
                   "rec": {"kind": "recorder", "signals": ["ball.h", "ball.bounces"]}},
    })
    result = run_scene(scene)
    h, count = _ball_height(result.time)
    assert np.max(np.abs(result["ball.h"] - h)) < 1e-6
    near_impact = np.abs(result.time[:, None] - np.array([0.4515, 1.0834, 1.5260])[None, :]).min(axis=1) < 1e-3
    assert np.array_equal(result["ball.bounces"][~near_impact], count[~near_impact])


@pytest.mark.parametrize("coupling", ["strong", "jacobi"])
def test_outputs_recorded_at_an_event_are_consistent_with_the_discrete_inputs_taken_there(c_fmu, coupling):
    """The counter drives a discrete Int32 input of a Model Exchange FMU that passes it through
    (+ 10): what is recorded at t0 and at each event already includes the input taken there in
    event mode, under weak coupling as under strong."""
    types = c_fmu("types", 3)
    scene = scene_from_dict({
        "name": "chain", "connections": ["clock.counter -> pass.Int32_input"],
        "master": {"coupling": coupling, "t_end_s": 0.6, "step_s": 0.05, "output_interval_s": 0.05},
        "blocks": {"clock": {"kind": "fmu", "fmu": str(c_fmu("events", 3)), "interface": "me"},
                   "pass": {"kind": "fmu", "fmu": str(types), "interface": "me",
                            "parameters": {"Int32_parameter": 10}},
                   "rec": {"kind": "recorder", "signals": ["clock.counter", "pass.Int32_output"]}},
    })
    result = run_scene(scene)
    assert np.array_equal(result["pass.Int32_output"], result["clock.counter"] + 10)
    assert result["clock.counter"][-1] == 2

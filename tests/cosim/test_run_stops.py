"""Every way a run can stop from inside the master becomes a StepError with the partial data:
an interrupt (Ctrl-C or a signal handler's RunInterrupted) and an internal error."""
from __future__ import annotations

import pytest
from featherstar.cosim.coupling.simulator import Simulator
from featherstar.cosim.errors import RunInterrupted, StepError
from featherstar.cosim.scene.data import scene_from_dict
from featherstar.cosim.swimmer.run import run_scene

SCENE = scene_from_dict({
    "name": "stops",
    "connections": [],
    "master": {"coupling": "jacobi", "t_end_s": 0.2, "step_s": 0.01},
    "blocks": {"controller": {"kind": "stroke"},
               "rec": {"kind": "recorder", "signals": ["controller.angle_rad"]}},
})


@pytest.mark.parametrize("raised, message, interrupted", [
    (KeyboardInterrupt(), "interrupted by SIGINT", "SIGINT"),
    (RunInterrupted("SIGTERM"), "interrupted by SIGTERM", "SIGTERM"),
    (ZeroDivisionError("float division by zero"), "internal error: ZeroDivisionError", None),
])
def test_a_stop_inside_the_master_keeps_the_partial_result(monkeypatch, raised, message,
                                                          interrupted):
    real_advance_to = Simulator.advance_to

    def failing(sim, t_s):
        real_advance_to(sim, t_s / 2)   # half the run is recorded, then the stop comes
        raise raised

    monkeypatch.setattr(Simulator, "advance_to", failing)
    with pytest.raises(StepError) as info:
        run_scene(SCENE)
    error = info.value
    assert error.block == "master" and message in str(error)
    assert error.interrupted == interrupted
    partial = error.partial
    assert partial is not None and not partial.complete
    assert partial.time[-1] == pytest.approx(0.1) and len(partial.time) == 11
    assert partial.summary["failed_block"] == "master"

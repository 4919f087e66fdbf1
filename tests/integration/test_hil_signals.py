"""The command's stop signals (featherstar.terminal), in-process: with hardware a signal is
recorded, never raised, and the exit status is the signal's; without, it raises at once."""
from __future__ import annotations

import os
import signal

import pytest

from featherstar.cosim.coupling.pacing import RealTimePacer
from featherstar.cosim.coupling.context import Context
from featherstar.cosim.errors import RunInterrupted
from featherstar.terminal import exit_status, stop_signals


def test_a_deferred_signal_is_kept_and_honoured_only_at_the_next_step(capsys):
    with stop_signals(deferred=True) as stop:
        os.kill(os.getpid(), signal.SIGTERM)     # e.g. inside the safe stop: nothing raises
        os.kill(os.getpid(), signal.SIGINT)      # a repeat is only reported
        assert stop.pending == "SIGTERM" and stop.repeats == 1
        with pytest.raises(RunInterrupted) as caught:
            RealTimePacer(Context.__new__(Context))(0.0, 0.004)   # the pacer honours it
        assert caught.value.signal_name == "SIGTERM"
        assert exit_status(2, stop) == 143
    assert "SIGINT received, still stopping safely" in capsys.readouterr().err


def test_without_hardware_the_first_signal_raises_at_once():
    with pytest.raises(RunInterrupted):
        with stop_signals(deferred=False) as stop:
            os.kill(os.getpid(), signal.SIGTERM)
    assert exit_status(0, stop) == 143


def test_no_signal_leaves_the_status_alone():
    with stop_signals(deferred=True) as stop:
        pass
    assert exit_status(2, stop) == 2 and exit_status(0, stop) == 0

"""Fixtures every test folder shares: whether this machine can keep time for a real-time test
right now. (Fixtures only: test modules import helpers from their own folder's conftest.)"""
from __future__ import annotations

import time

import pytest

SLEEP_S = 0.005
MAX_OVERSHOOT_P90_S = 0.05     # a wake-up later than this, one time in ten: no timing test


@pytest.fixture
def keeps_time() -> float:
    """Skip unless a sleeping process wakes up in time (p90 overshoot of 40 sleeps of 5 ms);
    returns the measured p90 overshoot in seconds."""
    overshoot = []
    for _ in range(40):
        t0 = time.perf_counter()
        time.sleep(SLEEP_S)
        overshoot.append(time.perf_counter() - t0 - SLEEP_S)
    p90 = sorted(overshoot)[int(0.9 * len(overshoot))]
    if p90 > MAX_OVERSHOOT_P90_S:
        pytest.skip(f"the machine cannot keep time now: 5 ms sleeps overshoot by "
                    f"{p90 * 1e3:.0f} ms (p90; limit {MAX_OVERSHOOT_P90_S * 1e3:.0f} ms)")
    return p90

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


#: Words in a run's validity reasons that say the PC or the device's plant lost real time.
TIMING_WORDS = ("late", "deadline", "behind real time", "lag")


@pytest.fixture
def skip_if_time_was_lost():
    """A real-time test's second gate: `keeps_time` is measured before the run, load that comes
    during it shows in the run's own summary. Called with a summary (a run's, or a bench study's
    records' reasons), it skips with the measured reasons when periods were excluded, or runs
    discarded, because time was lost; a gap or reconnect is not timing and is left to the test."""
    def check(summary: dict | None = None, reasons: list[str] | None = None) -> None:
        found = list(reasons or [])
        if summary is not None:
            for period in (summary.get("validity") or {}).get("invalid_periods", []):
                found += period.get("reasons", [])
            if summary.get("lags"):
                found.append(f"{summary['lags']} report(s) of the device's plant behind real time")
        lost = [r for r in found if any(word in r for word in TIMING_WORDS)]
        if lost:
            pytest.skip(f"the machine lost real time during the run: {'; '.join(sorted(set(lost)))}")
    return check

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
    during it shows in the run's own summary. Called with a summary (a run's) or with reasons (a
    bench study's discarded runs), it skips with the measured reasons when the run broke the
    master's own timing limits (featherstar.cosim.swimmer.validity: a step later than MAX_LATE_S,
    more than MAX_MISS_FRACTION of the steps late), had periods excluded for time, or its device's
    plant fell behind real time. A gap or a reconnect is not timing and is left to the test."""
    from featherstar.cosim.swimmer.validity import MAX_LATE_S, MAX_MISS_FRACTION

    def check(summary: dict | None = None, reasons: list[str] | None = None) -> None:
        found = list(reasons or [])
        if summary is not None:
            steps = max(int((summary.get("stats") or {}).get("macro_steps", 0) or 0), 1)
            if summary.get("worst_lateness_s", 0.0) > MAX_LATE_S:
                found.append(f"a step started {summary['worst_lateness_s']:.3f} s late (limit {MAX_LATE_S} s)")
            if summary.get("deadline_misses", 0) > MAX_MISS_FRACTION * steps:
                found.append(f"{summary['deadline_misses']} of {steps} steps missed their deadline")
            for period in (summary.get("validity") or {}).get("invalid_periods", []):
                found += period.get("reasons", [])
            if summary.get("lags"):
                found.append(f"{summary['lags']} report(s) of the device's plant behind real time")
        lost = [r for r in found if any(word in r for word in TIMING_WORDS)]
        if lost:
            pytest.skip(f"the machine lost real time during the run: {'; '.join(sorted(set(lost)))}")
    return check

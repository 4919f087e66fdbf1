"""The [session] registers on a device clock: restarts and frozen firmware, deterministically."""
from __future__ import annotations

import random

import pytest
from hypothesis import given, strategies as st

from featherstar.hil.errors import Fault
from featherstar.hil.lifecycle import BootSession, CommandWatchdog
from featherstar.hil.link import FaultSignal
from featherstar.hil.registers import SessionField
from featherstar.hil.session import FROZEN_S, SessionWatch

FIELD = SessionField(address=3, uptime_address=4)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def _regs(session: BootSession) -> dict[int, int]:
    boot_id, uptime = session.words()
    return {3: boot_id, 4: uptime[0], 5: uptime[1]}


@given(st.lists(st.tuples(st.floats(0.001, 0.4), st.booleans()), min_size=1, max_size=40),
       st.integers(0, 2**32 - 1))
def test_every_reboot_and_only_a_reboot_is_reported(steps, seed):
    clock = Clock()
    device = BootSession(random.Random(seed), clock)
    watch = SessionWatch(FIELD)
    assert watch.check(_regs(device), clock.t) is None
    for dt_s, reboot in steps:
        clock.t += dt_s
        if reboot:
            device.boot()
        assert (watch.check(_regs(device), clock.t) is not None) == reboot


def test_a_frozen_uptime_is_a_stale_fault_once_it_lasts():
    clock = Clock()
    device = BootSession(random.Random(1), clock)
    watch = SessionWatch(FIELD)
    frozen = _regs(device)
    watch.check(frozen, clock.t)
    watch.check(frozen, clock.t + 0.9 * FROZEN_S)      # within the limit: fine
    with pytest.raises(FaultSignal) as caught:
        watch.check(frozen, clock.t + 1.1 * FROZEN_S)
    assert caught.value.fault is Fault.STALE and "uptime frozen" in caught.value.detail


def test_the_watchdog_trips_once_per_silence_and_only_when_armed():
    clock = Clock()
    dog = CommandWatchdog(clock)
    clock.t += 10.0
    assert not dog.expired()                    # never armed: a client that did not ask
    dog.arm(200)
    dog.feed()
    clock.t += 0.19
    assert not dog.expired()
    clock.t += 0.02
    assert dog.expired() and not dog.expired()  # once
    dog.resume()
    dog.feed()
    clock.t += 0.3
    assert dog.expired() and dog.trips == 2

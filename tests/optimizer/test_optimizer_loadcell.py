import math

import numpy as np
import pytest

from featherstar.optimizer.errors import OptimizerError
from featherstar.optimizer.loadcell import DEFAULT_NOISE_SD_N, LoadCell, measure


def _square_wave(period_s=1.5, positive_N=0.03, negative_N=-0.01, duration_s=15.0, rate_hz=1000.0):
    t = np.arange(0.0, duration_s + 1e-9, 1.0 / rate_hz)
    thrust = np.where(np.mod(t, period_s) < period_s / 2, negative_N, positive_N)
    return t, thrust


def test_default_noise_is_two_ten_thousandths_of_a_3_kg_full_scale():
    assert DEFAULT_NOISE_SD_N == pytest.approx(2e-4 * 3 * 9.80665)


def test_no_negative_thrust_gives_an_infinite_ratio():
    t, thrust = _square_wave(negative_N=0.0)
    (m,) = measure(t, thrust, 1.5, LoadCell(noise_sd_N=0.0), np.random.default_rng(0))
    assert m.thrust_ratio == math.inf


def test_noise_free_reading_keeps_impulse_and_ratio():
    t, thrust = _square_wave()
    (m,) = measure(t, thrust, 1.5, LoadCell(noise_sd_N=0.0), np.random.default_rng(0))
    # only the samples that straddle a sign change mix positive and negative thrust
    assert m.thrust_ratio == pytest.approx(3.0, rel=0.01)
    assert m.mean_thrust_N == pytest.approx(0.01, rel=1e-6)


def test_noise_is_seeded_and_zero_is_allowed():
    t, thrust = _square_wave()
    cell = LoadCell()
    a = measure(t, thrust, 1.5, cell, np.random.default_rng(5))
    b = measure(t, thrust, 1.5, cell, np.random.default_rng(5))
    c = measure(t, thrust, 1.5, cell, np.random.default_rng(6))
    assert a == b and a != c
    assert abs(a[0].thrust_ratio - 3.0) < 0.3


def test_windows_are_consecutive_whole_periods_after_settling():
    t, thrust = _square_wave(duration_s=1.5 * (3 + 4 * 2) + 0.05)
    windows = measure(t, thrust, 1.5, LoadCell(noise_sd_N=0.0), np.random.default_rng(0), periods=2, windows=4)
    assert len(windows) == 4
    assert all(w.thrust_ratio == pytest.approx(3.0, rel=0.01) for w in windows)


def test_short_run_and_diverged_run_are_errors():
    t, thrust = _square_wave(duration_s=5.0)
    with pytest.raises(OptimizerError, match="need 12.000 s"):
        measure(t, thrust, 1.5, LoadCell(), np.random.default_rng(0))
    thrust[10] = math.nan
    with pytest.raises(OptimizerError, match="diverged"):
        LoadCell().read(t, thrust, np.random.default_rng(0))
    with pytest.raises(OptimizerError, match=">= 0"):
        LoadCell(noise_sd_N=-1.0)

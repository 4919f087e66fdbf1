import warnings

import numpy as np
import pytest
from scipy.stats import norm
from skopt.space import Real, Space
from skopt.utils import cook_estimator
from threadpoolctl import threadpool_limits

from featherstar.optimizer.acquisition import (
    expected_improvement, expected_improvement_plus, incumbent, noise_sd, with_more_variance_between_observations,
)


def _fit(X, y):
    gp = cook_estimator("GP", Space([Real(0.0, 1.0)] * X.shape[1]), random_state=0)
    with warnings.catch_warnings(), threadpool_limits(1, "blas"):
        warnings.simplefilter("ignore")
        return gp.fit(X, y)


def test_expected_improvement_closed_form():
    ei = expected_improvement(np.array([1.0, 0.5, 2.0]), np.array([0.2, 0.0, 0.0]), best_mean=1.0)
    assert ei[0] == pytest.approx(0.2 * norm.pdf(0.0))
    assert ei[1] == pytest.approx(0.5) and ei[2] == 0.0


def test_incumbent_is_the_best_posterior_mean_not_the_luckiest_sample():
    rng = np.random.default_rng(0)
    X = np.concatenate([0.2 + 0.01 * rng.random((6, 1)), 0.8 + 0.01 * rng.random((6, 1))])
    y = np.array([1.0, 1.02, 0.98, 1.01, 0.99, 0.5, 0.8, 0.81, 0.79, 0.8, 0.82, 0.78])
    gp = _fit(X, y)
    index, mean = incumbent(gp, X)
    assert int(np.argmin(y)) == 5  # the lucky outlier near 0.2
    assert index >= 6 and mean == pytest.approx(0.8, abs=0.05)
    assert noise_sd(gp) > 0.05  # the outlier is explained as noise


def _overexploited():
    """Dense, noise-dominated data: the GP is sure of its (flat) mean everywhere."""
    rng = np.random.default_rng(1)
    X = rng.random((60, 1))
    return X, 0.01 * X[:, 0] + 0.3 * rng.standard_normal(60)


def test_kernel_modification_raises_uncertainty_between_observations():
    X, y = _overexploited()
    gp = _fit(X, y)
    grid = np.linspace(0, 1, 201)[:, None]
    _, before = gp.predict(grid, return_std=True)
    _, after = with_more_variance_between_observations(gp, X, y, 8.0).predict(grid, return_std=True)
    assert after.max() > 2 * before.max()


def test_overexploitation_triggers_bounded_kernel_modifications():
    X, y = _overexploited()
    gp = _fit(X, y)
    candidates = np.linspace(0, 1, 401)[:, None]
    plain = expected_improvement_plus(gp, X, y, candidates, exploration_ratio=0.0)
    assert plain.retries == 0
    plus = expected_improvement_plus(gp, X, y, candidates, exploration_ratio=0.6)
    assert plain.sigma_f < 0.6 * plain.noise_sd  # plain EI over-exploits here
    assert 1 <= plus.retries <= 5
    assert plus.overexploiting == (plus.sigma_f < 0.6 * plus.noise_sd)
    capped = expected_improvement_plus(gp, X, y, candidates, exploration_ratio=1e9, max_retries=2)
    assert capped.retries == 2 and capped.overexploiting

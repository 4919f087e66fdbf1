"""Expected-improvement-plus, the acquisition of MATLAB's bayesopt that the paper used, on skopt's GP.

Pure functions of a fitted `skopt.learning.GaussianProcessRegressor` (in skopt's minimizing
convention) and candidate points in its transformed space. As MathWorks documents it:

1. incumbent = the evaluated point with the best *posterior mean* (not the luckiest noisy sample);
2. x = argmax EI over the candidates;
3. if σF(x), the posterior sd of the noise-free objective at x, is below
   exploration_ratio · σ (σ: the noise sd the GP estimated), the model is over-exploiting: raise the
   variance between observations and recompute argmax EI, a bounded number of times, accepting the
   last x if all retries over-exploit.

MathWorks describes step 3 as multiplying the kernel parameters by a growing factor (after Bull,
2011) so that the variance between observations rises, and does not publish the exact update. We
divide the ARD length scales and multiply the signal variance by 2, 4, 8, ... (the GP then expects
the objective to vary faster and more, so the space between observations is less certain), noise
level kept, at most `max_retries` times.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import norm
from sklearn.base import clone
from skopt.learning import GaussianProcessRegressor
from skopt.learning.gaussian_process.kernels import WhiteKernel

DEFAULT_EXPLORATION_RATIO = 0.6
DEFAULT_MAX_RETRIES = 5


@dataclass(frozen=True)
class Proposal:
    """The chosen candidate and why: `retries` kernel modifications were needed; `overexploiting`
    is still True if even the last retry's choice had σF < ratio·σ."""

    index: int
    expected_improvement: float
    sigma_f: float
    noise_sd: float
    retries: int
    overexploiting: bool


def noise_sd(gp: GaussianProcessRegressor) -> float:
    """The observation-noise sd the fitted GP estimated, in objective units."""
    return float(np.sqrt(gp.noise_) * gp.y_train_std_) if gp.noise_ is not None else 0.0


def incumbent(gp: GaussianProcessRegressor, X_evaluated: np.ndarray) -> tuple[int, float]:
    """(index, posterior mean) of the evaluated point with the lowest posterior mean."""
    mean = gp.predict(np.atleast_2d(X_evaluated))
    best = int(np.argmin(mean))
    return best, float(mean[best])


def expected_improvement(mean: np.ndarray, sigma_f: np.ndarray, best_mean: float) -> np.ndarray:
    """EI below best_mean for a minimized objective; zero where the model is certain."""
    improvement = best_mean - mean
    with np.errstate(divide="ignore", invalid="ignore"):
        z = improvement / sigma_f
        ei = improvement * norm.cdf(z) + sigma_f * norm.pdf(z)
    return np.where(sigma_f > 0, ei, np.maximum(improvement, 0.0))


def with_more_variance_between_observations(
    gp: GaussianProcessRegressor, X: np.ndarray, y: np.ndarray, factor: float
) -> GaussianProcessRegressor:
    """A copy of the fitted GP with length scales divided and the signal variance multiplied by
    factor, refitted on (X, y) without re-optimizing hyperparameters (noise level kept).

    Both are needed: shorter length scales alone only let σF rise towards the prior sd, which a
    noise-dominated fit estimates below ratio·σ, so no retry could ever stop over-exploiting."""
    kernel = clone(gp.kernel_)
    params = kernel.get_params()
    kernel.set_params(
        **{key: value / factor for key, value in params.items()
           if key.endswith("length_scale") and not key.endswith("bounds")},
        **{key: value * factor for key, value in params.items()
           if key.endswith("constant_value") and not key.endswith("bounds")},
        **{key: WhiteKernel(noise_level=gp.noise_ or 0.0, noise_level_bounds="fixed")
           for key, value in params.items() if isinstance(value, WhiteKernel)},
    )
    model = GaussianProcessRegressor(kernel=kernel, optimizer=None, normalize_y=True, noise="gaussian")
    return model.fit(X, y)


def expected_improvement_plus(
    gp: GaussianProcessRegressor,
    X_evaluated: np.ndarray,
    y_evaluated: np.ndarray,
    candidates: np.ndarray,
    exploration_ratio: float = DEFAULT_EXPLORATION_RATIO,
    max_retries: int = DEFAULT_MAX_RETRIES,
) -> Proposal:
    """Pick a candidate (rows in the GP's transformed space) by MATLAB's EI-plus rule."""
    sigma = noise_sd(gp)
    model, retry = gp, 0
    while True:
        _, best_mean = incumbent(model, X_evaluated)
        mean, sigma_f = model.predict(candidates, return_std=True)
        ei = expected_improvement(mean, sigma_f, best_mean)
        index = int(np.argmax(ei))
        overexploiting = bool(sigma_f[index] < exploration_ratio * sigma)
        if not overexploiting or retry == max_retries:
            return Proposal(index, float(ei[index]), float(sigma_f[index]), sigma, retry, overexploiting)
        retry += 1
        model = with_more_variance_between_observations(gp, X_evaluated, y_evaluated, 2.0**retry)

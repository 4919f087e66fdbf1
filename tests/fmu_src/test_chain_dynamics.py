"""The O(N) recursive solve (featherstar.fmu_src.chain) against the dense formulation it replaced
(tests/fmu_src/dense_feather_reference.py: Jacobians, full mass matrix, LDLᵀ): the same equations, so the
same derivatives and outputs at any state, flaps and hinges in contact with their stops included."""
import numpy as np
import pytest
from dense_feather_reference import dense_feather_function

from featherstar.fmu_src.feather import feather_model

SAMPLES = 40
TOLERANCE = 1e-10  # relative to the largest magnitude of each quantity over the samples


def smooth_profile(rng: np.random.Generator, n: int, total: float) -> np.ndarray:
    """`total` spread over a run of n joints along a random smooth bending shape that vanishes
    at both ends of the run, where a free end or a hinge carries (almost) no moment. A random
    angle per joint instead would load the stiff joints of N = 40 with torques that give
    accelerations of 1e8 rad/s², whose cancellation, not the formulation, then sets the
    difference of the two solves."""
    span = (np.arange(n) + 0.5) / n
    shape = np.sin(np.pi * span) * (1.0 + rng.uniform(-1, 1) * np.cos(np.pi * span))
    return total * shape / np.sum(np.abs(shape))


def bending_runs(model, fold: list[int]) -> list[list[int]]:
    """The bending joints in runs of consecutive joints, split at the hinges."""
    runs: list[list[int]] = [[]]
    for k in range(model.x.numel() // 2):
        if k in fold:
            runs.append([])
        elif not model.states[k].name.startswith("flap_"):
            runs[-1].append(k)
    return [run for run in runs if run]


def random_states(model, rng: np.random.Generator) -> np.ndarray:
    """Bending angles and rates along smooth profiles (up to ±2 rad and ~±20 rad/s over the
    feather), fold angles within 0.05 rad of either stop (pressing on it by up to 6 times its
    smoothing depth, or just clear of it) or anywhere between, fold rates up to ~10 rad/s."""
    values = model.default_parameters()
    n = model.x.numel() // 2
    fold = [k for k, state in enumerate(model.states[:n]) if state.name.startswith("flap_") or "hinge" in state.description]
    states = np.zeros((2 * n, SAMPLES))
    for run in bending_runs(model, fold):
        for sample in range(SAMPLES):
            states[run, sample] = smooth_profile(rng, len(run), rng.uniform(-2, 2))
            states[[n + k for k in run], sample] = smooth_profile(rng, len(run), rng.normal(0, 10))
    if fold:
        limit = values["fold_limit_rad"]
        sign = 1.0 if model.options["morphology"] == "chordwise" else -1.0  # the spanwise hinge folds to q < 0
        near_flat = rng.uniform(-0.05, 0.05, (len(fold), SAMPLES))
        near_limit = limit + rng.uniform(-0.05, 0.05, (len(fold), SAMPLES))
        anywhere = rng.uniform(0.0, limit, (len(fold), SAMPLES))
        states[fold] = sign * np.choose(rng.integers(0, 3, (len(fold), SAMPLES)), [near_flat, near_limit, anywhere])
        states[[n + k for k in fold]] = rng.normal(0, 5, (len(fold), SAMPLES))
    return states


CASES = [(morphology, root_support, n_units, None) for n_units in (5, 10, 20, 40)
         for morphology, root_support in (("plain", None), ("chordwise", None), ("spanwise", None), ("spanwise", False))]
# The drag quadrature without the split (Gauss points over each whole strip).
CASES += [("chordwise", None, 5, (3, False)), ("spanwise", False, 6, (4, False))]


@pytest.mark.parametrize("morphology,root_support,n_units,drag_rule", CASES)
def test_recursive_solve_equals_the_dense_mass_matrix_solve(morphology, root_support, n_units, drag_rule):
    options = {} if root_support is None else {"root_support": root_support}
    if drag_rule is not None:
        options["drag_points"], options["drag_split"] = drag_rule
    model = feather_model(morphology, n_units, **options)
    rng = np.random.default_rng(n_units)
    states = random_states(model, rng)
    inputs = np.vstack([rng.uniform(-1.2, 1.2, SAMPLES), rng.normal(0, 5, SAMPLES), rng.normal(0, 100, SAMPLES),
                        rng.uniform(-0.1, 0.2, SAMPLES)])
    parameters = model.parameter_vector()
    recursive = [np.array(v) for v in model.function().map(SAMPLES)(states, inputs, parameters)]
    n = model.x.numel() // 2
    accels = recursive[0][n:]
    dense = [np.array(v) for v in dense_feather_function(model).map(SAMPLES)(states, inputs, parameters, accels)]
    np.testing.assert_array_equal(recursive[0][:n], dense[0][:n])

    # The recursive accelerations satisfy the dense equations M(Q) Q̈ = f to rounding.
    masses, forces = dense[2].reshape(n, n, SAMPLES, order="F"), dense[3]
    residual = np.abs(np.einsum("ijs,js->is", masses, accels) - forces)
    size = np.einsum("ijs,js->is", np.abs(masses), np.abs(accels)) + np.abs(forces)
    assert np.max(residual / size.max(axis=0)) <= 1e-14

    # The two solves agree to 1e-10 of the largest acceleration, or, where M is so ill-conditioned
    # that rounding alone allows more (N >= 20: stiff joints next to light links), to the
    # forward-error bound of a backward-stable solve, 10·eps·cond(M).
    condition = np.array([np.linalg.cond(masses[:, :, s]) for s in range(SAMPLES)])
    tolerance = np.maximum(TOLERANCE, 10 * np.finfo(float).eps * condition)
    accel_scale = np.max(np.abs(dense[0][n:]), axis=0)
    assert np.all(np.max(np.abs(accels - dense[0][n:]), axis=0) <= tolerance * accel_scale)

    # Every output equals the dense formulation's at the same accelerations to 1e-10 of its scale
    # (the root torque's: of the terms that cancel in it, up to 1e8 times the torque when a stiff
    # joint next to the unsupported spanwise hinge accelerates a light link).
    for k, output in enumerate(model.outputs):
        scale = np.max(np.abs(dense[4][k]))
        if output.name == "root_torque_Nm":
            scale = np.max(dense[5])
        assert np.all(np.abs(recursive[1][k] - dense[4][k]) <= TOLERANCE * scale), output.name
    if morphology != "plain":
        values = model.default_parameters()
        folds = [k for k, s in enumerate(model.states[:n]) if s.name.startswith("flap_") or "hinge" in s.description]
        fold = states[folds] if morphology == "chordwise" else -states[folds]  # the fold angle, both kinds
        assert (fold < 0).any() and (fold > values["fold_limit_rad"]).any(), "no sample presses on both stops"

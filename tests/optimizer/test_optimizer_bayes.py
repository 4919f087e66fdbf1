import math

import numpy as np
import pytest

from featherstar.optimizer.bayes import StrokeOptimizer, optimize
from featherstar.optimizer.errors import OptimizerError
from featherstar.optimizer.space import stroke_overrides, stroke_space, symmetric_stroke

from optimizer_testing import FEATHER, PLAN, SHORT_ITERATIONS, SPACE, Interrupting, logged_evaluations


def _true_extremes():
    X = SPACE.sample(np.random.default_rng(0), 20000)
    tr = np.array([FEATHER.true_thrust_ratio(SPACE.overrides(SPACE.point(x))) for x in X])
    return tr.min(), tr.max()


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    path = tmp_path_factory.mktemp("full") / "evaluations.jsonl"
    return optimize(FEATHER, SPACE, path, iterations=30, plan=PLAN), path


def test_best_posterior_mean_is_near_the_true_optimum(uninterrupted):
    run, _ = uninterrupted
    true_min, true_max = _true_extremes()
    best = run.best
    assert best.point in [r["params"] for r in run.evaluations]
    true_at_best = FEATHER.true_thrust_ratio(SPACE.overrides(best.point))
    assert true_at_best >= 0.95 * true_max
    assert true_at_best >= 1.2 * FEATHER.true_thrust_ratio(stroke_overrides(symmetric_stroke(1.5)))
    # the estimate is of the noise-free objective, not the luckiest sample
    assert best.sd < 0.2 and abs(best.value - true_at_best) < 0.3


def test_minimizing_finds_the_worst_stroke(tmp_path):
    run = optimize(FEATHER, SPACE, tmp_path / "log.jsonl", iterations=20, maximize=False, plan=PLAN)
    true_min, _ = _true_extremes()
    assert FEATHER.true_thrust_ratio(SPACE.overrides(run.best.point)) <= true_min + 0.15




def test_resume_continues_exactly_where_it_stopped(short_run, tmp_path):
    path = tmp_path / "evaluations.jsonl"
    optimize(FEATHER, SPACE, path, iterations=7, plan=PLAN)
    optimize(FEATHER, SPACE, path, iterations=SHORT_ITERATIONS, plan=PLAN, resume=True)
    assert logged_evaluations(path) == logged_evaluations(short_run)


def test_ctrl_c_loses_nothing(short_run, tmp_path):
    path = tmp_path / "evaluations.jsonl"
    with pytest.raises(KeyboardInterrupt):
        optimize(Interrupting(at=9), SPACE, path, iterations=SHORT_ITERATIONS, plan=PLAN)
    assert [r["index"] for r in logged_evaluations(path)] == list(range(8))
    optimize(FEATHER, SPACE, path, iterations=SHORT_ITERATIONS, plan=PLAN, resume=True)
    assert logged_evaluations(path) == logged_evaluations(short_run)


def test_a_record_cut_by_a_hard_kill_is_dropped(tmp_path):
    path = tmp_path / "evaluations.jsonl"
    optimize(FEATHER, SPACE, path, iterations=6, plan=PLAN)
    with open(path, "a") as handle:
        handle.write('{"kind": "evaluation", "index": 6, "par')
    with pytest.warns(UserWarning, match="incomplete last record"):
        run = optimize(FEATHER, SPACE, path, iterations=8, plan=PLAN, resume=True)
    assert [r["index"] for r in run.evaluations] == list(range(8))
    assert [r["index"] for r in logged_evaluations(path)] == list(range(8))


def test_an_existing_log_is_never_overwritten_or_mixed(tmp_path):
    path = tmp_path / "evaluations.jsonl"
    optimize(FEATHER, SPACE, path, iterations=4, plan=PLAN)
    with pytest.raises(OptimizerError, match="already holds a run.*--resume"):
        optimize(FEATHER, SPACE, path, iterations=4, plan=PLAN)
    with pytest.raises(OptimizerError, match="different setup.*maximize"):
        optimize(FEATHER, SPACE, path, iterations=6, plan=PLAN, maximize=False, resume=True)
    with pytest.raises(OptimizerError, match="different setup.*period_s"):
        optimize(FEATHER, stroke_space(3.0), path, iterations=6, plan=PLAN, resume=True)


def test_ask_tell_rejects_bad_input():
    optimizer = StrokeOptimizer(SPACE, seed=1)
    point = optimizer.ask()
    assert SPACE.is_feasible(point)
    with pytest.raises(OptimizerError, match="not finite"):
        optimizer.tell(point, math.inf)
    with pytest.raises(OptimizerError, match="outside"):
        optimizer.tell({**point, "log10_up_down": 5.0}, 1.0)
    with pytest.raises(OptimizerError, match="unknown"):
        optimizer.tell({**point, "t_up": 0.1}, 1.0)
    with pytest.raises(OptimizerError, match="n_initial_points"):
        optimize(FEATHER, SPACE, "unused.jsonl", iterations=2)


def test_a_stroke_the_simulation_refuses_stops_the_study_naming_it(tmp_path):
    """A StepError inside an evaluation (e.g. the master's energy guard) ends the study with the
    evaluation and its point named; the evaluations before it stay in the log."""
    from featherstar.cosim.errors import StepError

    calls = []

    def refusing(overrides, duration_s):
        calls.append(overrides)
        if len(calls) == 4:
            raise StepError("feather", 1.5, "mechanical energy gained 0.3 J, more than 2x the 0.1 J its ports put in")
        return FEATHER(overrides, duration_s)

    path = tmp_path / "log.jsonl"
    with pytest.raises(OptimizerError, match=r"evaluation 3 at \{.*could not be simulated: block 'feather'") as info:
        optimize(refusing, SPACE, path, iterations=SHORT_ITERATIONS, plan=PLAN)
    assert str(path) in str(info.value)
    assert len(logged_evaluations(path)) == 3

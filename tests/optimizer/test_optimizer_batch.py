"""Batches of the Bayesian optimizer (constant liar): deterministic, consistent with sequential
asks, and resumable mid-batch to exactly the uninterrupted run."""
import pytest
from optimizer_testing import FEATHER, PLAN, SPACE, Interrupting, logged_evaluations

from featherstar.optimizer.bayes import StrokeOptimizer, optimize
from featherstar.optimizer.errors import OptimizerError
from featherstar.optimizer.executor import InlineExecutor, ProcessExecutor

BATCH_ITERATIONS = 10


def _told(n):
    """An optimizer told the first n points of a sequential run (past its random initial design)."""
    optimizer = StrokeOptimizer(SPACE, seed=PLAN.seed)
    for _ in range(n):
        point = optimizer.ask()
        optimizer.tell(point, FEATHER.true_thrust_ratio(SPACE.overrides(point)))
    return optimizer


def test_a_batch_is_deterministic_spread_and_leaves_no_lies_behind():
    optimizer = _told(6)
    batch = optimizer.ask_batch(3)
    assert optimizer.n_told == 6  # the lies went to a copy
    assert _told(6).ask_batch(3) == batch  # same seed, history and size: same batch
    assert _told(6).ask_batch(2) == batch[:2]  # the first j points of a batch of k are the batch of j
    assert _told(6).ask() == batch[0]  # and the first is the sequential ask
    assert len({tuple(sorted(p.items())) for p in batch}) == 3
    assert len(optimizer.last_proposals) == 3 and all(p is not None for p in optimizer.last_proposals)


def test_the_initial_design_is_the_sequential_one():
    assert StrokeOptimizer(SPACE, seed=PLAN.seed).ask_batch(4) == [p for p in _initial_points(4)]
    with pytest.raises(OptimizerError, match="batch size 0 must be >= 1"):
        StrokeOptimizer(SPACE).ask_batch(0)


def _initial_points(n):
    optimizer = StrokeOptimizer(SPACE, seed=PLAN.seed)
    points = []
    for _ in range(n):
        points.append(optimizer.ask())
        optimizer.tell(points[-1], 1.0)
    return points


@pytest.fixture(scope="module")
def batched_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("batched") / "evaluations.jsonl"
    optimize(FEATHER, SPACE, path, iterations=BATCH_ITERATIONS, plan=PLAN, batch_size=3)
    return path


def test_resume_mid_batch_reproduces_the_uninterrupted_run(batched_run, tmp_path):
    path = tmp_path / "evaluations.jsonl"
    with pytest.raises(KeyboardInterrupt):  # batches 0-2, 3-5, 6-8: stopped inside the third
        optimize(Interrupting(at=8), SPACE, path, iterations=BATCH_ITERATIONS, plan=PLAN, batch_size=3)
    assert [r["index"] for r in logged_evaluations(path)] == list(range(7))
    optimize(FEATHER, SPACE, path, iterations=BATCH_ITERATIONS, plan=PLAN, batch_size=3, resume=True)
    assert logged_evaluations(path) == logged_evaluations(batched_run)
    with pytest.raises(OptimizerError, match="batch_size: log has 3, now 2"):
        optimize(FEATHER, SPACE, path, iterations=12, plan=PLAN, batch_size=2, resume=True)


def test_batches_on_local_processes_equal_batches_in_this_process(batched_run, tmp_path):
    path = tmp_path / "evaluations.jsonl"
    with ProcessExecutor(2) as executor:
        run = optimize(FEATHER, SPACE, path, iterations=BATCH_ITERATIONS, plan=PLAN, batch_size=3, executor=executor)
    assert logged_evaluations(path) == logged_evaluations(batched_run)
    # one estimate per batch, at its last index
    assert [i for i, e in enumerate(run.estimates) if e is not None] == [5, 8, 9]
    assert InlineExecutor().describe() == "this process"

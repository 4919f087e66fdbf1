import pytest
from optimizer_testing import FEATHER, PLAN, SHORT_ITERATIONS, SPACE

from featherstar.optimizer.bayes import optimize


@pytest.fixture(scope="session")
def short_run(tmp_path_factory):
    """The log of an uninterrupted run: what every interrupted and resumed run must reproduce."""
    path = tmp_path_factory.mktemp("short") / "evaluations.jsonl"
    optimize(FEATHER, SPACE, path, iterations=SHORT_ITERATIONS, plan=PLAN)
    return path

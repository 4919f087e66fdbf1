"""The paper's results through the real FMU master (issue: optimizer, "Done when").

Slow (each study is 30 simulated experiments plus 2 × 10 validation sets: minutes), hence the
`stress` mark. Skipped only while the master's `run_scene` does not exist; the numbers are printed
so a disagreement with the paper is reported, not hidden. CVODE Adams: the fastest accurate method
for the flapped feathers (physics notes §9).
"""
import math

import pytest

from featherstar.optimizer.evaluation import MeasurementPlan
from featherstar.optimizer.executor import ProcessExecutor
from featherstar.optimizer.objective import SceneObjective, master_available
from featherstar.optimizer.paper.family import validated_stroke_task
from featherstar.optimizer.paper.plan import FULL, MEMBERS, Member
from featherstar.optimizer.paper.robustness import DEFAULT
from featherstar.optimizer.space import stroke_space
from featherstar.optimizer.study import BEST_VALIDATION_INDEX, run_study

pytestmark = [
    pytest.mark.stress,
    pytest.mark.skipif(not master_available(), reason="featherstar.cosim.run_scene (the FMU master) is not available yet"),
]

SCENE = "testbed"  # the single-feather test bed: servo + feather + load cell
CHORDWISE = {"feather.morphology": "chordwise", "feather.width_ratio": 7.5, "master.method": "adams"}
PLAIN = {"feather.morphology": "plain", "master.method": "adams"}


def _study(tmp_path, overrides, objective, iterations=30):
    summary = run_study(
        SceneObjective(SCENE, overrides), stroke_space(1.5), tmp_path / objective,
        maximize=objective == "max", iterations=iterations, plan=MeasurementPlan(seed=0),
        context={"scene": SCENE, "overrides": overrides},
    )
    print(f"{overrides} {objective}: TR {summary['thrust_ratio']:.3f} ± {summary['thrust_ratio_sd']:.3f}, "
          f"baseline {summary['baseline_thrust_ratio']:.3f} ± {summary['baseline_thrust_ratio_sd']:.3f}, "
          f"best {summary['best_params']}")
    return summary


@pytest.fixture(scope="module")
def studies(tmp_path_factory):
    """The three 30-iteration studies of this module, each in its own process (two at once: they
    are independent and each takes most of a minute on one core), by the executor the paper
    report uses. Each study is the one a serial run would give: seed 0, its own directory."""
    root = tmp_path_factory.mktemp("studies")
    plans = {"chordwise-max": (CHORDWISE, "max"), "chordwise-min": (CHORDWISE, "min"), "plain-max": (PLAIN, "max")}
    with ProcessExecutor(workers=2) as executor:
        futures = {name: executor.submit(_study, root / name, overrides, objective)
                   for name, (overrides, objective) in plans.items()}
        return {name: future.result() for name, future in futures.items()}


def test_chordwise_best_beats_the_symmetric_baseline(studies):
    best = studies["chordwise-max"]
    assert best["thrust_ratio"] > best["baseline_thrust_ratio"]


def test_chordwise_worst_is_below_the_baseline(studies):
    worst = studies["chordwise-min"]
    assert worst["thrust_ratio"] < worst["baseline_thrust_ratio"]


@pytest.fixture(scope="module")
def plain_best(studies):
    """The plain feather's 30-iteration study under the default model."""
    return studies["plain-max"]


@pytest.mark.xfail(
    strict=True,
    reason="the model disagrees with the paper: through the testbed scene (Adams, seed 0) the optimizer "
    "lifts the plain feather to TR 1.38 ± 0.01 (baseline 0.99) with a slower upstroke than downstroke "
    "(t_up/t_down 1.45) and a long hold after the upstroke. Quasi-steady drag, which grows as v^2, rewards a "
    "slow recovery stroke (a rigid plate's drag-only TR is exactly t_up/t_down); the paper's plain feather "
    "does not show it. The default model (wake = 'none') has no wake: the water a fast stroke sets moving meets "
    "the next stroke. With the feather's wake option (laws fitted to oscillatory and steady plate data) the "
    "slow-return stroke's TR falls from 1.30 to 0.98-1.02 (bench/wake_feathers.py), the law undecided by those "
    "data (docs/model.md, 'Wake memory' and 'What the model does not reproduce'). Across the model family "
    "(featherstar paper's claims table, re-optimized under each member, full budgets: docs/paper-report) the plain "
    "optimum's TR is 1.03-1.11 under the wake laws, 1.05 with the steady drag law and 1.13-1.43 under the added-mass range: "
    "the claim is undecided by the model, a bench decides it (docs/model.md, 'Which claims the model family decides')",
)
def test_plain_feather_gains_no_asymmetry_from_the_optimizer(plain_best):
    assert plain_best["thrust_ratio"] <= 1.15


def test_plain_feather_optimum_has_its_range_across_the_model_family(plain_best):
    """The default model's optimized plain-feather stroke validated under every member of the model
    family that changes the plain feather (the wake laws, added mass, drag law): the range is
    computed from every member (none dropped), it contains the default's own validated TR, which
    the family's measurement reproduces number for number, and the wake laws pull it down (the
    quasi-steady timing gain is what a wake removes, docs/model.md)."""
    best = plain_best
    res = FULL   # the measurement of _study: MeasurementPlan(seed=0), 10 sets of 5 periods
    stroke = {k: v for k, v in best["best_overrides"].items() if k.startswith("controller.")}
    plain = [m for m in MEMBERS if m.applies("plain")]
    values = {m.name: validated_stroke_task("plain", None, 1.5, stroke, Member(m.name, (("master.method", "adams"),
                                                                                        *m.overrides), m.what),
                                            res, BEST_VALIDATION_INDEX)["thrust_ratio"] for m in plain}
    values[DEFAULT] = validated_stroke_task("plain", None, 1.5, stroke, Member(DEFAULT, (("master.method", "adams"),), ""),
                                            res, BEST_VALIDATION_INDEX)["thrust_ratio"]
    lo_end, hi_end = min(values, key=values.get), max(values, key=values.get)
    print(f"plain optimum, TR across the model family: {values[lo_end]:.3f} ({lo_end}) - {values[hi_end]:.3f} "
          f"({hi_end}); " + ", ".join(f"{n} {v:.3f}" for n, v in values.items()))
    assert len(values) == len(plain) + 1 and all(math.isfinite(v) for v in values.values())
    assert values[DEFAULT] == best["thrust_ratio"]
    assert values[lo_end] <= best["thrust_ratio"] <= values[hi_end]
    assert max(values[f"wake-{law}"] for law in ("relative", "self", "plate")) < best["thrust_ratio"]

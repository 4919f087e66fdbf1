"""The paper's results through the real FMU master (issue: optimizer, "Done when").

Slow (each study is 30 simulated experiments plus 2 × 10 validation sets: minutes), hence the
`stress` mark. Skipped only while the master's `run_scene` does not exist; the numbers are printed
so a disagreement with the paper is reported, not hidden. CVODE Adams: the fastest accurate method
for the flapped feathers (physics notes §9).
"""
import pytest

from featherstar.optimizer.evaluation import MeasurementPlan
from featherstar.optimizer.objective import SceneObjective, master_available
from featherstar.optimizer.space import stroke_space
from featherstar.optimizer.study import run_study

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


def test_chordwise_best_beats_the_symmetric_baseline(tmp_path):
    best = _study(tmp_path, CHORDWISE, "max")
    assert best["thrust_ratio"] > best["baseline_thrust_ratio"]


def test_chordwise_worst_is_below_the_baseline(tmp_path):
    worst = _study(tmp_path, CHORDWISE, "min")
    assert worst["thrust_ratio"] < worst["baseline_thrust_ratio"]


@pytest.mark.xfail(
    strict=True,
    reason="the model disagrees with the paper: through the testbed scene (Adams, seed 0) the optimizer "
    "lifts the plain feather to TR 1.38 ± 0.01 (baseline 0.99) with a slower upstroke than downstroke "
    "(t_up/t_down 1.45) and a long hold after the upstroke. Quasi-steady drag, which grows as v^2, rewards a "
    "slow recovery stroke (a rigid plate's drag-only TR is exactly t_up/t_down); the paper's plain feather "
    "does not show it. The default model (wake = 'none') has no wake: the water a fast stroke sets moving meets "
    "the next stroke. With the feather's wake option (laws fitted to oscillatory and steady plate data) the "
    "slow-return stroke's TR falls from 1.30 to 0.98-1.02 (bench/wake_feathers.py), the law undecided by those "
    "data (docs/model.md, 'Wake memory' and 'What the model does not reproduce')",
)
def test_plain_feather_gains_no_asymmetry_from_the_optimizer(tmp_path):
    best = _study(tmp_path, PLAIN, "max")
    assert best["thrust_ratio"] <= 1.15

"""The paper's experiments as data: its feathers, periods and controllers, how hard each figure
is rerun (`Resolution`: QUICK, FULL) and which studies, Fig. 7 cases and sweep geometries that
gives. `featherstar.optimizer.paper.paper` runs them; `paper_figures` and `paper_report` draw and report them."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..sweep import PAPER_CONTROLLERS, Controller, Geometry, paper_geometries

PERIOD_S = 1.5                      # the paper's period for Figs. 5, 6, 8, 9
FAMILY_RATIOS = {"chordwise": (5.5, 7.5, 9.5), "spanwise": (1.5, 2.0, 2.5)}  # the paper's subsets (Fig. 3)
DEFAULT_RATIO = {"chordwise": 7.5, "spanwise": 2.0}
MORPHOLOGIES = ("plain", "chordwise", "spanwise")
LABELS = {"plain": "plain", "chordwise": "chordwise WR 7.5", "spanwise": "spanwise LR 2"}
CONTROLLERS = ("best", "baseline", "worst")
ROBOT_SAMPLE_S = 0.02               # robot traces kept for Fig. 9


@dataclass(frozen=True)
class Member:
    """One model of the feather's model family: the default model with `overrides`; `morphologies`:
    the feathers it changes (a hinge stiffness does not exist on the plain feather)."""

    name: str
    overrides: tuple[tuple[str, str | float], ...]
    what: str
    morphologies: tuple[str, ...] = ("plain", "chordwise", "spanwise")

    def applies(self, family: str) -> bool:
        return family in self.morphologies


_FLAPPED = ("chordwise", "spanwise")
# One at a time from the default: the three wake laws (build option `wake`, docs/model.md "Wake
# memory") and the ends of the coefficients' documented ranges (docs/model.md, "Coefficients").
MEMBERS = (
    Member("wake-relative", (("feather.wake", "relative"),), "wake memory, the plate leaves its wake (u|s|)"),
    Member("wake-self", (("feather.wake", "self"),), "wake memory, the wake convects itself away (u|u|)"),
    Member("wake-plate", (("feather.wake", "plate"),), "wake memory, the wake is left at the plate's speed (u|v_n|)"),
    Member("hinge-1e-3", (("feather.hinge_stiffness_Nm_rad_m", 1e-3),), "tape hinge 1e-3 N·m/rad/m (range's low end)",
           _FLAPPED),
    Member("hinge-1e-1", (("feather.hinge_stiffness_Nm_rad_m", 1e-1),), "tape hinge 1e-1 N·m/rad/m (range's high end)",
           _FLAPPED),
    Member("added-mass-0.7", (("feather.added_mass_scale", 0.7),), "added mass × 0.7 (range's low end)"),
    Member("added-mass-2", (("feather.added_mass_scale", 2.0),), "added mass × 2 (range's high end, C_m at KC 5)"),
    Member("steady-drag", (("feather.oscillatory_drag", 0.0),), "drag law: steady plate C_d 1.2 instead of C_d(KC)"),
)
MEMBER_BY_NAME = {m.name: m for m in MEMBERS}
# The studies whose optimum the claims read under each member (re-validated or re-optimized).
FAMILY_STUDIES = ("plain-max", "chordwise-max", "chordwise-min", "spanwise-max", "spanwise-min")


@dataclass(frozen=True)
class Resolution:
    """How hard each figure's experiments are run (periods are stroke periods)."""

    name: str
    sweep_geometries: int | None     # per family, the paper's chosen ratios first; None = the paper's grid
    sweep_controllers: tuple[Controller, ...]
    sweep_settle_periods: int
    sweep_periods: int
    settle_periods: int              # test-bed runs: settling before any measurement
    periods: int                     # measured periods per optimizer evaluation
    iterations: int                  # optimizer budget, Figs. 6 and 8 (best and worst)
    initial_points: int
    fig7_iterations: int
    fig7_width_ratios: tuple[float, ...]
    fig7_length_ratios: tuple[float, ...]
    fig7_periods_s: tuple[float, ...]
    validation_repeats: int          # Figs. 5 and 8: sets of `validation_periods` periods
    validation_periods: int
    robot_periods: int               # robot run length; speed measured after robot_settle_periods
    robot_settle_periods: int
    family: tuple[str, ...] = ()     # model-family members (MEMBERS' names) every claim is also run under
    reoptimize: tuple[str, ...] = () # studies re-optimized under each member (the others: their stroke re-validated)
    workers: int | None = None       # local processes; None = all cores
    seed: int = 0

    def __post_init__(self) -> None:
        for key, names, known in (("family", self.family, MEMBER_BY_NAME), ("reoptimize", self.reoptimize, FAMILY_STUDIES)):
            unknown = [n for n in names if n not in known]
            if unknown:
                raise ValueError(f"Resolution {key} = {unknown!r}: unknown; known: {', '.join(known)}")

    def describe(self) -> dict:
        out = dataclasses.asdict(self)
        out["sweep_controllers"] = [f"{c.t_up_s}/{c.t_down_s}/{c.t_hold_s}" for c in self.sweep_controllers]
        if self.sweep_geometries is None:
            out["sweep_geometries"] = "the paper's grid (22 widths, 13 lengths)"
        if self.workers is None:
            out["workers"] = "all cores"
        return out


FULL = Resolution(
    "full", sweep_geometries=None, sweep_controllers=PAPER_CONTROLLERS, sweep_settle_periods=2, sweep_periods=3,
    settle_periods=3, periods=5, iterations=30, initial_points=4, fig7_iterations=30,
    fig7_width_ratios=FAMILY_RATIOS["chordwise"], fig7_length_ratios=FAMILY_RATIOS["spanwise"],
    fig7_periods_s=(1.5, 3.0), validation_repeats=10, validation_periods=5, robot_periods=12,
    robot_settle_periods=6, family=tuple(m.name for m in MEMBERS), reoptimize=("plain-max",),
)
# The two sweep controllers are those that gave the highest TR for WR 7.5 and LR 2 on the paper's
# 12-controller grid (a probe on the kinematic scene): the quick Fig. 3 maxima stay close to the full ones.
QUICK = dataclasses.replace(
    FULL, name="quick", sweep_geometries=4,
    sweep_controllers=(Controller(0.5, 1.0, 0.0), Controller(0.1, 0.5, 0.5)), sweep_settle_periods=1,
    sweep_periods=2, settle_periods=1, periods=2, iterations=8, fig7_iterations=6,
    fig7_width_ratios=(7.5,), fig7_length_ratios=(2.0,), validation_repeats=3, validation_periods=2,
    robot_periods=8, robot_settle_periods=4,
    # One wake law (the best fit to the plate data, docs/model.md): a wake build costs the chordwise
    # feather ~10× the quasi-steady run time, and the three laws differ by a few percent.
    family=tuple(m.name for m in MEMBERS if m.name not in ("wake-self", "wake-plate")),
)


def feather_overrides(family: str, ratio: float | None = None) -> dict[str, str | float]:
    """Test-bed overrides for the paper's feathers (all 115 × 75 mm unfolded, the scene default)."""
    if family == "plain":
        return {"feather.morphology": "plain"}
    key = "feather.width_ratio" if family == "chordwise" else "feather.length_ratio"
    return {"feather.morphology": family, key: DEFAULT_RATIO[family] if ratio is None else ratio}


@dataclass(frozen=True)
class StudySpec:
    """One stroke optimization on the test bed; `validate`: also validate optimum and baseline (Fig. 8)."""

    key: str
    family: str
    ratio: float | None
    period_s: float
    maximize: bool
    iterations: int
    validate: bool


def study_specs(res: Resolution) -> dict[str, StudySpec]:
    specs = {}
    for family in MORPHOLOGIES:
        for maximize in (True, False):
            key = f"{family}-{'max' if maximize else 'min'}"
            specs[key] = StudySpec(key, family, DEFAULT_RATIO.get(family), PERIOD_S, maximize, res.iterations, True)
    for family in ("chordwise", "spanwise"):
        for ratio, period in fig7_cases(res, family):
            key = fig7_key(family, ratio, period)
            specs.setdefault(key, StudySpec(key, family, ratio, period, True, res.fig7_iterations, False))
    return specs


def fig7_cases(res: Resolution, family: str) -> list[tuple[float, float]]:
    ratios = res.fig7_width_ratios if family == "chordwise" else res.fig7_length_ratios
    return [(ratio, period) for period in res.fig7_periods_s for ratio in ratios]


def fig7_key(family: str, ratio: float, period_s: float) -> str:
    """The Fig. 6/8 best-controller study doubles as Fig. 7's entry for its own ratio at 1.5 s."""
    if ratio == DEFAULT_RATIO[family] and period_s == PERIOD_S:
        return f"{family}-max"
    return f"{family}-{ratio:g}-{period_s:g}s"


def sweep_geometries(family: str, count: int | None) -> list[Geometry]:
    """`count` geometries of the paper's grid: nearest to the chosen ratios first (the middle one
    first), then spread out (farthest from those taken); the reference geometry is always added."""
    *grid, reference = paper_geometries(family)
    if count is None or count >= len(grid):
        return grid + [reference]
    chosen = FAMILY_RATIOS[family]
    taken: list[Geometry] = []
    for target in (chosen[1], chosen[0], chosen[2]):
        nearest = min((g for g in grid if g not in taken), key=lambda g: abs(g.ratio - target))
        taken.append(nearest)
    taken = taken[:count]
    while len(taken) < count:
        taken.append(max((g for g in grid if g not in taken), key=lambda g: min(abs(g.ratio - t.ratio) for t in taken)))
    return sorted(taken, key=lambda g: g.ratio) + [reference]

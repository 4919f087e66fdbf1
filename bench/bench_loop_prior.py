"""Does the simulation help a bench study when it is structurally wrong? No prior, seeded prior, discrepancy prior.

    python bench/bench_loop_prior.py [--quick] [--seeds 5] [--iterations 10] [--out docs/results]
    python bench/bench_loop_prior.py --repeatability [REST_S:SETTLE ...]   # the bench's repeatability only

1. The simulation: a simulated study of the plain feather (testbed scene, default coefficients,
   quasi-steady drag: wake `none`, strong coupling), `--sim-iterations` evaluations. It is the
   prior of both prior arms, and the discrepancy arm's simulation at each bench stroke.
2. The bench: the emulator's FMU plant (servo and feather FMUs, plain feather) with a wake law
   (`feather.wake = plate`) and hidden coefficients (added mass ×1.5, the plate law's drag
   coefficient 8.0 instead of its fitted 6.65, joint damping 0.003 N·m·s/rad where the model has
   none): a bench whose physics differ from the simulation's in model form and coefficients. Device-timed (`&clock=device` on both URLs), so
   the machine's load does not discard runs.
3. The bench's repeatability, once, before the studies: the simulation's best stroke measured
   after two other strokes, twice each (`repeatability`). Its sd is the discrepancy arm's noise
   floor (`noise_floor_sd`): a property of the bench, not fitted per study.
4. For each seed, three bench studies of `iterations` evaluations: no prior (random initial
   design), `--prior-use seed` (the simulated study's best strokes as initial design, then a GP
   on the bench's data), `--prior-use discrepancy` (the same initial design, then the surrogate
   ρ · simulation + GP discrepancy). The two prior arms share their first 4 strokes; they differ
   in what their models ask after them.
5. Iterations to reach 95 % of the bench optimum: the first evaluation whose measured TR is at
   least 95 % of the best TR measured by any study of this bench (all arms, all seeds; the bench
   optimum is not known otherwise); a study that never gets there counts as budget + 1 (listed as
   `null`). Targets (issue 26): discrepancy mean ≤ half the no-prior mean, and on no seed more than
   one iteration worse than no prior.

Each run rests the feather REST["s"] (12 s; `--rest-s`; counted from the previous run's end, so the studies'
compute time between runs is part of it: `--rest-curve` measures why: a tare taken while the
feather still rings offsets the run, and with 3 s the same stroke after the same stroke
measured TR 0.97-1.11 depending on the second of the ring the tare fell in; the discrepancy arm,
which computes about a second longer between runs, measured the seeded design's strokes 0.05
lower than the seeded arm did), then runs SETTLE_PERIODS (6) periods of the new stroke
before its MEASURED_PERIODS (2). Why settling and not rest (`--repeatability`,
docs/results/bench_loop_repeatability.json): the plate wake remembers the previous stroke, and
at rest it hardly decays (its decay law scales with the plate's speed). With 1 settling period
one stroke measured TR 1.14 and 1.13 after one stroke, 1.08 and 1.06 after another (sd 0.034
over five runs), unchanged with 10 s of rest instead of 3 (sd 0.032); per period from the
stroke's start, the two predecessors' curves differ by 0.08 in the first period and by ~0.015
from the seventh; with 6 settling periods the sd is 0.011 (the studies' stroke). The joint
damping is there because without it the undamped feather rings between runs: the same stroke
measured TR 1.07, 0.82, 0.33 in a row with 1 s of rest (the tare taken in the ringing). Writes
bench_loop_prior.json and bench_loop_prior.png (best TR so far per study, one panel per arm).
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from featherstar.cosim.plotstyle import save_figure  # noqa: E402
import numpy as np  # noqa: E402
from featherstar.hil.emulator import spawn_emulator  # noqa: E402
from featherstar.optimizer.bayes import optimize  # noqa: E402
from featherstar.optimizer.bench.discrepancy import SimulationModel  # noqa: E402
from featherstar.optimizer.bench.objective import BenchObjective  # noqa: E402
from featherstar.optimizer.bench.run import BenchFault  # noqa: E402
from featherstar.optimizer.bench.sim_prior import SimPrior, study_morphology  # noqa: E402
from featherstar.optimizer.bench.study import run_bench_study  # noqa: E402
from featherstar.optimizer.evaluation import ITERATION_STREAM, MeasurementPlan, evaluate, validate  # noqa: E402
from featherstar.optimizer.loadcell import LoadCell  # noqa: E402
from featherstar.optimizer.objective import SceneObjective  # noqa: E402
from featherstar.optimizer.space import stroke_space  # noqa: E402

PERIOD_S = 1.0
FEATHER = {"feather.morphology": "plain"}
# joint damping: the model's plain feather rings for minutes after a stroke (docs/bench-loop.md,
# "Record from rest"); a real one settles. 0.003 N·m·s/rad per joint makes a 3 s rest enough.
HIDDEN = {"feather.wake": "plate", "feather.added_mass_scale": 1.5, "feather.wake_drag_coeff": 8.0,
          "feather.joint_damping_Nms_rad": 0.003}
TARGET = 0.95
#: The rest before each run, counted from the previous run's end (BenchObjective): the shortest
#: from which the tare is within TARE_TOLERANCE_N of rest whatever stroke came before
#: (`--rest-curve`, docs/results/bench_loop_rest.json). The tare offsets the whole run, and a
#: stroke's TR moves by ~0.02 per mN of it; 0.5 mN keeps that within the bench's repeatability.
REST = {"s": 12.0}   # --rest-s sets it
TARE_TOLERANCE_N = 0.0005
#: Periods run under each stroke before its measured ones (periodic steady state): see
#: docs/bench-loop.md, "A prior that learns the simulation's bias" (the plate wake remembers the
#: previous stroke; rest does not erase it, the new stroke does).
SETTLE_PERIODS = 6
MEASURED_PERIODS = 2
ARMS = {"no_prior": None, "seeded_prior": "seed", "discrepancy_prior": "discrepancy"}
MAX_PAUSES, PAUSE_S = 10, 10.0
#: `--repeatability`'s repeated stroke (a fast downstroke; the studies repeat the simulation's best).
REPEATABILITY_STROKE = {"log10_up_down": 0.2, "log10_hold_up_down": 0.3, "log10_hold_move": -0.8}
#: The strokes the repeatability measurement puts before the repeated one: a slow downstroke with
#: short holds, and a symmetric stroke with long holds (unlike each other and the optimum).
REPEATABILITY_OTHERS = [{"log10_up_down": -0.25, "log10_hold_up_down": -0.9, "log10_hold_move": -0.4},
                        {"log10_up_down": 0.0, "log10_hold_up_down": 0.0, "log10_hold_move": -1.2}]


def simulated_prior(directory: Path, iterations: int) -> SimPrior:
    space = stroke_space(PERIOD_S)
    plan = MeasurementPlan(load_cell=LoadCell(), settle_periods=SETTLE_PERIODS, periods=MEASURED_PERIODS, seed=100)
    optimize(SceneObjective("testbed", FEATHER), space, directory / "evaluations.jsonl", iterations=iterations,
             plan=plan, context={"scene": "testbed", "overrides": FEATHER})
    return SimPrior.load(directory, feather=study_morphology("testbed", FEATHER), space=space, maximize=True)


def bench_study(emulator, out: Path, seed: int, iterations: int, prior: SimPrior, use: str | None,
                noise_floor_sd: float | None = None) -> dict:
    bench = bench_objective(emulator, REST["s"], SETTLE_PERIODS)
    plan = MeasurementPlan(load_cell=LoadCell(noise_sd_N=0.0, sample_rate_hz=250.0), settle_periods=SETTLE_PERIODS,
                           periods=MEASURED_PERIODS, seed=seed)
    started = time.perf_counter()
    pauses = 0
    while True:
        try:
            summary = run_bench_study(bench, stroke_space(PERIOD_S), out, plan=plan, iterations=iterations,
                                      prior=prior if use else None, prior_use=use or "seed", max_attempts=4,
                                      noise_floor_sd=noise_floor_sd if use == "discrepancy" else None,
                                      validation_repeats=1, validation_periods=2, resume=pauses > 0)
            break
        except BenchFault as fault:   # wait, then resume the study as a user would
            pauses += 1
            if pauses > MAX_PAUSES:
                raise
            print(f"  paused ({str(fault)[:120]}...); resuming in {PAUSE_S:g} s", flush=True)
            time.sleep(PAUSE_S)
    records = [json.loads(line) for line in (out / "evaluations.jsonl").read_text().splitlines()[1:]]
    observed = [r["thrust_ratio"] for r in records if r["kind"] == "evaluation"]
    simulated = [r["thrust_ratio"] for r in records if r["kind"] == "simulation"]
    return {"seed": seed, "arm": use or "none", "observed_thrust_ratio": observed,
            "simulated_thrust_ratio": simulated or None,
            "validated_best_thrust_ratio": summary["thrust_ratio"],
            "estimated_best_thrust_ratio": summary["estimated_thrust_ratio"],
            "baseline_thrust_ratio": summary["baseline_thrust_ratio"], "below_baseline": summary["below_baseline"],
            "model": (summary["prior"] or {}).get("model"), "discarded_runs": summary["discarded_runs"],
            "pauses": pauses, "wall_s": time.perf_counter() - started}


def bench_objective(emulator, rest_s: float, settle_periods: int) -> BenchObjective:
    options = "&timeout_s=0.3&reconnect_s=3&clock=device"
    return BenchObjective("testbed", {"servo": emulator.servo_url + options + "&safe_timeout_s=2",
                                      "loadcell": emulator.loadcell_url + options}, FEATHER,
                          settle_periods=settle_periods, rest_s=rest_s)


def repeatability(emulator, stroke: dict, others: list[dict], rest_s: float, settle_periods: int,
                  repeats: int = 2) -> dict:
    """The same stroke measured after different strokes: `stroke`, then (other, stroke) for each of
    `others`, `repeats` times. The first measurement follows whatever the bench did before (a fresh
    emulator: rest); each later one follows a different stroke. Their sd is what a study's single
    run of a stroke can be trusted to (the bench's repeatability), with len - 1 degrees of freedom."""
    space = stroke_space(PERIOD_S)
    bench = bench_objective(emulator, rest_s, settle_periods)
    plan = MeasurementPlan(load_cell=LoadCell(noise_sd_N=0.0, sample_rate_hz=250.0), settle_periods=settle_periods,
                           periods=MEASURED_PERIODS, seed=0)
    sequence = [("stroke", stroke)] + [x for _ in range(repeats) for i, other in enumerate(others)
                                       for x in ((f"other {i}", other), ("stroke", stroke))]
    measured = []
    started = time.perf_counter()
    for k, (name, point) in enumerate(sequence):
        for attempt in range(4):
            try:
                result = evaluate(bench, space.overrides(point), space.period_s, plan, ITERATION_STREAM, (k,))
                break
            except Exception as exc:   # a discarded run (deadline misses): measure again
                print(f"  repeatability run {k} {name}: {str(exc)[:100]}; again", flush=True)
        else:
            raise RuntimeError("the bench does not keep time")
        measured.append({"run": name, "after": sequence[k - 1][0] if k else "rest (fresh emulator)",
                         "thrust_ratio": result.thrust_ratio})
        print(f"  rest {rest_s:g} s, {settle_periods} settling: {name} after {measured[-1]['after']}: "
              f"TR {result.thrust_ratio:.4f}", flush=True)
    same = np.array([m["thrust_ratio"] for m in measured if m["run"] == "stroke"])
    return {"rest_s": rest_s, "settle_periods": settle_periods, "measured_periods": MEASURED_PERIODS, "runs": measured,
            "stroke": stroke, "others": others, "same_stroke_thrust_ratio": same.tolist(),
            "same_stroke_sd_thrust_ratio": float(np.std(same, ddof=1)),
            "same_stroke_sd_after_first_thrust_ratio": float(np.std(same[1:], ddof=1)),
            "wall_s": time.perf_counter() - started}


def settling_curve(emulator, stroke: dict, others: list[dict], rest_s: float, periods: int = 12,
                   repeats: int = 2) -> list[dict]:
    """TR of each period of `stroke` from its start (no settling), after each of `others`,
    `repeats` times: how many periods the bench needs before a stroke's TR no longer depends on
    the stroke before it (its periodic steady state)."""
    space = stroke_space(PERIOD_S)
    bench = bench_objective(emulator, rest_s, 0)
    plan = MeasurementPlan(load_cell=LoadCell(noise_sd_N=0.0, sample_rate_hz=250.0), settle_periods=0,
                           periods=MEASURED_PERIODS, seed=0)
    curves = []
    for rep in range(repeats):
        for i, other in enumerate(others):
            evaluate(bench, space.overrides(other), space.period_s, plan, ITERATION_STREAM, (0,))
            v = validate(bench, space.overrides(stroke), space.period_s, plan, (1,), repeats=periods, periods=1)
            curves.append({"after": f"other {i}", "repeat": rep,
                           "thrust_ratio_per_period": [m.thrust_ratio for m in v.repeats]})
            print(f"  after other {i}: " + " ".join(f"{m.thrust_ratio:.3f}" for m in v.repeats), flush=True)
    return curves


def measure_repeatability(out: Path, configs: list[tuple[float, int]]) -> None:
    """--repeatability: the same stroke after different strokes at each (rest_s, settle_periods),
    and the per-period settling curve, each on a fresh emulator; writes bench_loop_repeatability.json."""
    logging.getLogger("hil").setLevel(logging.ERROR)
    result = {"stroke": REPEATABILITY_STROKE, "others": REPEATABILITY_OTHERS, "configs": [], "settling_curve": None}
    for config in [*configs, None]:   # None: the settling curve
        emulator = spawn_emulator(plant="fmu", morphology=FEATHER["feather.morphology"], noise_N=0.005, seed=7,
                                  plant_parameters=HIDDEN,
                                  start_timeout_s=300.0)
        try:
            if config is None:
                result["settling_curve"] = settling_curve(emulator, REPEATABILITY_STROKE, REPEATABILITY_OTHERS, REST["s"])
            else:
                result["configs"].append(repeatability(emulator, REPEATABILITY_STROKE, REPEATABILITY_OTHERS, *config))
        finally:
            emulator.stop()
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_loop_repeatability.json").write_text(json.dumps(result, indent=2) + "\n")


def rest_curve(rests_s: tuple[float, ...] = (3, 4, 5, 6, 7, 8, 10, 12, 15, 20)) -> dict:
    """The tare's error and its TR against the rest before a run (the bench's plant offline,
    stepped as the client drives it, no noise): `REPEATABILITY_STROKE` measured as the studies
    measure it (SETTLE_PERIODS + MEASURED_PERIODS) after each of `REPEATABILITY_OTHERS`, the
    load cell tared at the rest's end. The tare is the force at that moment: a feather that still
    rings there offsets the whole run. The rest the studies use is the shortest from which the
    tare stays within TARE_TOLERANCE_N after every predecessor (`chosen_rest_s`)."""
    from featherstar.cosim.scenes import load_scene
    from featherstar.cosim.swimmer.controller import resolve_stroke
    from featherstar.cosim.swimmer.stroke import root_motion
    from featherstar.hil.blocks import MG996R_RATE_RAD_S
    from featherstar.hil.fmu_plant import FmuPlant

    space, step_s = stroke_space(PERIOD_S), 0.005
    amplitude = load_scene("testbed").to_dict()["blocks"]["controller"]["amplitude_deg"]
    options = {k.split(".", 1)[1]: v for k, v in HIDDEN.items() if k == "feather.wake"}
    parameters = {k.split(".", 1)[1]: v for k, v in HIDDEN.items() if k != "feather.wake"}

    def run(plant, point: dict, periods: int, tare_N: float) -> np.ndarray:
        stroke = resolve_stroke({"amplitude_deg": amplitude}, {"period_s": PERIOD_S, **{
            k.split(".", 1)[1]: v for k, v in space.overrides(point).items() if k.startswith("controller.")}}, "stroke")
        command, force = plant.angle_rad, []
        for k in range(round(periods * PERIOD_S / step_s)):
            limit = MG996R_RATE_RAD_S * step_s
            command = min(max(root_motion(stroke, (k + 1) * step_s)[0], command - limit), command + limit)
            plant.set_setpoint_rad(command)
            impulse = plant.impulse_Ns
            plant.advance(step_s)
            force.append((plant.impulse_Ns - impulse) / step_s - tare_N)
        return np.array(force)

    def thrust_ratio(force: np.ndarray) -> float:
        measured = force[-round(MEASURED_PERIODS * PERIOD_S / step_s):]
        return float(measured[measured > 0].sum() / -measured[measured < 0].sum())

    rows = []
    for i, other in enumerate(REPEATABILITY_OTHERS):
        for rest_s in rests_s:
            plant = FmuPlant(FEATHER["feather.morphology"], feather_parameters=parameters, feather_options=options)
            try:
                run(plant, other, SETTLE_PERIODS + MEASURED_PERIODS, 0.0)
                for _ in range(round(rest_s / step_s)):
                    plant.set_setpoint_rad(0.0)
                    plant.advance(step_s)
                impulse = plant.impulse_Ns
                plant.advance(0.02)   # the emulator's tare: its converter's mean force over 20 ms
                tare_N = (plant.impulse_Ns - impulse) / 0.02
                rows.append({"after": f"other {i}", "rest_s": rest_s, "tare_N": tare_N,
                             "thrust_ratio": thrust_ratio(run(plant, REPEATABILITY_STROKE,
                                                              SETTLE_PERIODS + MEASURED_PERIODS, tare_N))})
            finally:
                plant.close()
            print(f"  after other {i}, rest {rest_s:g} s: tare {rows[-1]['tare_N'] * 1e3:+.2f} mN, "
                  f"TR {rows[-1]['thrust_ratio']:.4f}", flush=True)
    ok = [r for r in rests_s if all(abs(x["tare_N"]) <= TARE_TOLERANCE_N for x in rows if x["rest_s"] >= r)]
    return {"stroke": REPEATABILITY_STROKE, "others": REPEATABILITY_OTHERS, "rows": rows,
            "tare_tolerance_N": TARE_TOLERANCE_N, "chosen_rest_s": min(ok) if ok else None}


def stem(name: str, morphology: str | None = None) -> str:
    """An output's file stem: the plain feather's keeps the bare name, another feather's adds it."""
    morphology = morphology or FEATHER["feather.morphology"]
    return name if morphology == "plain" else f"{name}_{morphology}"


def iterations_to(observed: list[float], threshold: float) -> int | None:
    return next((i + 1 for i, tr in enumerate(observed) if tr >= threshold), None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 seeds, 4 iterations, 10 simulated (a smoke test)")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--iterations", type=int, default=10)
    parser.add_argument("--sim-iterations", type=int, default=20, help="the simulated study's evaluations")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent.parent / "docs" / "results")
    parser.add_argument("--morphology", choices=("plain", "spanwise", "chordwise"), default="plain",
                        help="the feather of the simulation and of the bench (default plain; others write "
                             "..._MORPHOLOGY.json)")
    parser.add_argument("--rest-s", type=float, default=REST["s"],
                        help=f"rest before each run, from the previous run's end (default {REST['s']:g}: the plain "
                             "feather's --rest-curve choice; measure another feather's)")
    parser.add_argument("--rest-curve", action="store_true",
                        help="no bench: the tare's error and its TR against the rest before a run (the plant "
                             "offline); writes OUT/bench_loop_rest.json")
    parser.add_argument("--reanalyse", action="store_true",
                        help="no bench: redo the analysis and the plot of OUT/bench_loop_prior.json's studies")
    parser.add_argument("--repeatability", nargs="*", metavar="REST_S:SETTLE", default=None,
                        help="no studies: measure the bench's repeatability at each rest/settling setting "
                             "(default 3:1 3:3 10:1 3:6) and the per-period settling curve")
    args = parser.parse_args()
    FEATHER["feather.morphology"], REST["s"] = args.morphology, args.rest_s
    if args.repeatability is not None:
        configs = [(float(a.split(":")[0]), int(a.split(":")[1])) for a in args.repeatability or
                   ["3:1", "3:3", "10:1", "3:6"]]
        measure_repeatability(args.out, configs)
        return
    if args.rest_curve:
        curve = rest_curve()
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / f"{stem('bench_loop_rest')}.json").write_text(json.dumps(curve, indent=2) + "\n")
        print(f"chosen rest: {curve['chosen_rest_s']} s (REST_S = {REST['s']:g} s)")
        return
    if args.reanalyse:
        write(json.loads((args.out / f"{stem('bench_loop_prior')}.json").read_text()), args.out)
        return
    seeds, iterations, sim_iterations = (2, 4, 10) if args.quick else (args.seeds, args.iterations,
                                                                        args.sim_iterations)
    logging.getLogger("hil").setLevel(logging.ERROR)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        prior = simulated_prior(tmp / "sim", sim_iterations)
        space = stroke_space(PERIOD_S)
        # How well the simulation's GP predicts simulations it was not fitted on (the discrepancy
        # arm reads the simulation through it at the acquisition's candidates).
        holdout = SimulationModel(space, prior.points, prior.values).holdout_error()
        print(f"prior: {len(prior.points)} simulated evaluations, best TR {max(prior.values):.3f}; its GP predicts "
              f"held-out simulations within {holdout['rms_error']:.3f} rms", flush=True)
        emulator = spawn_emulator(plant="fmu", morphology=FEATHER["feather.morphology"], noise_N=0.005, seed=7,
                                  plant_parameters=HIDDEN,
                                  start_timeout_s=300.0)
        studies = []
        try:
            # The bench's repeatability, before any study, at the studies' settings: the prior's
            # best stroke (every prior arm's first) after two other strokes, twice each. Its sd is
            # the discrepancy arm's noise floor (a property of the bench, measured once, not per study).
            best = prior.initial_points(space, 1, maximize=True)[0]
            repeat = repeatability(emulator, best, REPEATABILITY_OTHERS, REST["s"], SETTLE_PERIODS)
            noise_floor_sd = repeat["same_stroke_sd_thrust_ratio"]
            print(f"repeatability: {repeat['same_stroke_thrust_ratio']} -> sd {noise_floor_sd:.4f} TR "
                  f"(the discrepancy arm's noise floor)", flush=True)
            for seed in range(seeds):
                for name, use in ARMS.items():
                    study = bench_study(emulator, tmp / f"bench-{seed}-{name}", seed, iterations, prior, use,
                                        noise_floor_sd)
                    study["arm"] = name
                    studies.append(study)
                    print(f"seed {seed} {name}: TR {' '.join(f'{x:.3f}' for x in study['observed_thrust_ratio'])}; "
                          f"validated {study['validated_best_thrust_ratio']:.3f} (baseline "
                          f"{study['baseline_thrust_ratio']:.3f}) ({study['discarded_runs']} discarded, "
                          f"{study['wall_s']:.0f} s)", flush=True)
        finally:
            emulator.stop()
    result = {
        "question": f"bench iterations to reach {TARGET:.0%} of the best measured TR: no prior, seeded prior, "
                    "discrepancy prior, on a bench whose physics differ from the simulation's",
        "simulated_prior_best_thrust_ratio": max(prior.values), "simulation_gp_holdout": holdout,
        "bench_repeatability": repeat, "noise_floor_sd": noise_floor_sd,
        "studies": studies,
        "setup": {"feather": FEATHER, "simulation": "testbed scene, default coefficients, wake none (quasi-steady)",
                  "hidden_plant": HIDDEN, "emulator": "FMU plant (servo + plain feather), noise 5 mN, device-timed",
                  "rest_s": REST["s"], "period_s": PERIOD_S, "settle_periods": SETTLE_PERIODS,
                  "measured_periods": MEASURED_PERIODS,
                  "iterations": iterations, "sim_iterations": sim_iterations, "seeds": seeds, "quick": args.quick},
        "wall_s": time.perf_counter() - started,
        "machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "load_average": os.getloadavg()},
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{stem('bench_loop_prior')}.json").write_text(json.dumps(result, indent=2) + "\n")   # kept if analysis fails
    write(result, args.out)


def analyse(result: dict) -> dict:
    """The arms' iterations to target, the issue's two targets, the bench's repeatability and
    the simulation's agreement with the bench, from the studies (so --reanalyse can redo them)."""
    studies, iterations = result["studies"], result["setup"]["iterations"]
    best = max(max(s["observed_thrust_ratio"]) for s in studies)
    for s in studies:
        s["iterations_to_target"] = iterations_to(s["observed_thrust_ratio"], TARGET * best)
    counted = {name: [iterations + 1 if s["iterations_to_target"] is None else s["iterations_to_target"]
                      for s in studies if s["arm"] == name] for name in ARMS}
    arms = {name: {"iterations_to_target": [s["iterations_to_target"] for s in studies if s["arm"] == name],
                   "mean_iterations": float(np.mean(counted[name])),
                   "reached": sum(s["iterations_to_target"] is not None for s in studies if s["arm"] == name),
                   "studies": len(counted[name]),
                   "validated_best_thrust_ratio": [s["validated_best_thrust_ratio"] for s in studies
                                                   if s["arm"] == name],
                   "below_baseline": sum(s["below_baseline"] for s in studies if s["arm"] == name)}
            for name in ARMS}
    # The same target on the gain over the symmetric stroke (added after the tare fix showed a flat
    # bench: best ~1.03 against a baseline ~0.98, so 95 % of the best TR lies below the baseline and
    # nearly every stroke "reaches" it): the first evaluation with TR >= baseline + 95 % of
    # (best - baseline), the baseline the mean of the studies' validated symmetric strokes.
    baseline = float(np.mean([s["baseline_thrust_ratio"] for s in studies]))
    gain_target = baseline + TARGET * (best - baseline)
    for name in ARMS:
        reached = [iterations_to(s["observed_thrust_ratio"], gain_target) for s in studies if s["arm"] == name]
        arms[name]["iterations_to_gain_target"] = reached
        arms[name]["mean_iterations_to_gain_target"] = float(np.mean([iterations + 1 if r is None else r
                                                                      for r in reached]))
    # What each prior arm's model adds after the shared initial design: the best TR its own asks
    # measured against the best of the design it was given, per seed.
    n_initial = min(4, iterations)
    for name in ("seeded_prior", "discrepancy_prior"):
        runs = [s["observed_thrust_ratio"] for s in studies if s["arm"] == name]
        design, asked = [max(r[:n_initial]) for r in runs], [max(r[n_initial:], default=float("nan")) for r in runs]
        arms[name]["after_initial_design"] = {
            "best_of_design": design, "best_of_model_asks": asked,
            "model_beat_design": sum(a > d for a, d in zip(asked, design)),
            "mean_of_model_asks": [float(np.mean(r[n_initial:])) if r[n_initial:] else None for r in runs]}
    worse = [d - n for d, n in zip(counted["discrepancy_prior"], counted["no_prior"])]
    targets = {"discrepancy_mean_at_most_half_of_no_prior":
               arms["discrepancy_prior"]["mean_iterations"] <= 0.5 * arms["no_prior"]["mean_iterations"],
               "discrepancy_never_more_than_one_worse_than_no_prior": max(worse) <= 1,
               "discrepancy_minus_no_prior_per_seed": worse}
    gain_counted = {name: [iterations + 1 if r is None else r for r in arms[name]["iterations_to_gain_target"]]
                    for name in ARMS}
    gain_worse = [d - n for d, n in zip(gain_counted["discrepancy_prior"], gain_counted["no_prior"])]
    targets["on_the_gain"] = {
        "discrepancy_mean_at_most_half_of_no_prior":
            arms["discrepancy_prior"]["mean_iterations_to_gain_target"] <= 0.5 * arms["no_prior"]["mean_iterations_to_gain_target"],
        "discrepancy_never_more_than_one_worse_than_no_prior": max(gain_worse) <= 1,
        "discrepancy_minus_no_prior_per_seed": gain_worse}
    # The same strokes measured once per seed and prior arm: the prior arms' initial design does
    # not depend on the seed, so its spread is the bench's repeatability between studies.
    n_initial = min(4, iterations)
    same = [[s["observed_thrust_ratio"][i] for s in studies if s["arm"] != "no_prior"] for i in range(n_initial)]
    same = [x for x in same if len(x) > 1]
    baselines = [s["baseline_thrust_ratio"] for s in studies]
    pairs = [(sim, bench) for s in studies if s["arm"] == "discrepancy_prior"
             for sim, bench in zip(s["simulated_thrust_ratio"] or [], s["observed_thrust_ratio"])]
    sim, bench = np.array(pairs).T if pairs else (np.array([]), np.array([]))
    return {**result, "best_measured_thrust_ratio": best, "target_thrust_ratio": TARGET * best, "arms": arms,
            "baseline_thrust_ratio": baseline, "gain_target_thrust_ratio": gain_target,
            "targets": targets,
            "repeatability": {
                "same_stroke_sd_thrust_ratio": [float(np.std(x, ddof=1)) for x in same],
                "pooled_sd_thrust_ratio": float(np.sqrt(np.mean([np.var(x, ddof=1) for x in same]))) if same else None,
                "baseline_validations": {"mean": float(np.mean(baselines)), "sd": float(np.std(baselines, ddof=1))}},
            "simulation_vs_bench": {
                "strokes": len(pairs), "mean_bench_minus_sim": float(np.mean(bench - sim)) if pairs else None,
                "correlation": float(np.corrcoef(sim, bench)[0, 1]) if len(pairs) > 2 else None,
                "rho_fitted": [(s["model"] or {}).get("rho") for s in studies if s["arm"] == "discrepancy_prior"]}}


def write(result: dict, out: Path) -> None:
    result = analyse(result)
    arms, targets = result["arms"], result["targets"]
    out.mkdir(parents=True, exist_ok=True)
    written = stem("bench_loop_prior", result["setup"]["feather"]["feather.morphology"])
    (out / f"{written}.json").write_text(json.dumps(result, indent=2) + "\n")
    _figure(result["studies"], result["target_thrust_ratio"], result["gain_target_thrust_ratio"],
            result["baseline_thrust_ratio"], out / f"{written}.png")
    for name, arm in arms.items():
        print(f"{name}: iterations to {TARGET:.0%} of best TR {arm['iterations_to_target']} "
              f"(mean {arm['mean_iterations']:.1f}, {arm['reached']}/{arm['studies']} reached; "
              f"{arm['below_baseline']} validated below the baseline)")
        print(f"  on the gain (TR >= {result['gain_target_thrust_ratio']:.3f}): {arm['iterations_to_gain_target']} "
              f"(mean {arm['mean_iterations_to_gain_target']:.1f})")
        if "after_initial_design" in arm:
            after = arm["after_initial_design"]
            print(f"  after the initial design its model's asks beat the design's best on "
                  f"{after['model_beat_design']}/{arm['studies']} seeds (mean TR of its asks "
                  f"{np.nanmean([m for m in after['mean_of_model_asks'] if m is not None]):.3f})")
    print(f"targets: {json.dumps(targets)}")
    print(f"repeatability: {json.dumps(result['repeatability'])}")
    print(f"simulation vs bench: {json.dumps(result['simulation_vs_bench'])}")
    print(f"wrote {out / written}.json and {written}.png ({result['wall_s']:.0f} s of bench)")


def _figure(studies: list[dict], target: float, gain_target: float, baseline: float, path: Path) -> None:
    fig, axes = plt.subplots(1, len(ARMS), figsize=(10, 3.4), sharey=True)
    for ax, name in zip(axes, ARMS):
        for s in (s for s in studies if s["arm"] == name):
            best_so_far = np.maximum.accumulate(s["observed_thrust_ratio"])
            ax.plot(np.arange(1, len(best_so_far) + 1), best_so_far, "-o", ms=3, alpha=0.8, label=f"seed {s['seed']}")
        ax.axhline(target, color="k", ls=":", lw=1, label="95 % of the best measured TR")
        ax.axhline(gain_target, color="k", ls="--", lw=1, label="95 % of the best gain over the baseline")
        ax.axhline(baseline, color="0.5", ls="-", lw=0.8, label="symmetric baseline (validated, mean)")
        ax.set_title(name.replace("_", " "), fontsize=9)
        ax.set_xlabel("bench iteration")
    axes[0].set_ylabel("best measured TR so far")
    axes[-1].legend(fontsize=6)
    fig.suptitle("bench study on the emulator (plate wake, hidden coefficients) with a quasi-steady simulation",
                 fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()

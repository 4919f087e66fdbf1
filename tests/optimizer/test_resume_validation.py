"""Damaged logs on resume: every mutation either resumes to the run never damaged, or is refused
with one line naming the log. Lines duplicated, dropped, edited, garbage bytes, a cut last line."""
import json
import tempfile
import warnings
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from optimizer_testing import FEATHER, PLAN, SPACE

from featherstar.optimizer.bayes import optimize
from featherstar.optimizer.bench.study import bench_entries
from featherstar.optimizer.errors import OptimizerError
from featherstar.optimizer.executor import InlineExecutor
from featherstar.optimizer.log import ExperimentLog, LogRepairWarning
from featherstar.optimizer.resume import check_log
from featherstar.optimizer.sweep import Controller, run_sweep

CONTROLLERS = [Controller(0.5, 1.0, 0.5)]
STUDY_ITERATIONS = 6
SETTINGS = settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _sweep(log: Path | None, *, resume: bool = False):
    return run_sweep(FEATHER, ["spanwise"], controllers=CONTROLLERS, executor=InlineExecutor(), log_path=log,
                     resume=resume, progress=False)


def _rows(result) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "sim_wall_s"} for r in result.runs]


def _evaluations(path: Path) -> list[dict]:
    records = [json.loads(line) for line in path.read_text().splitlines()[1:]]
    return [{k: v for k, v in r.items() if k not in ("sim_wall_s", "digest")} for r in records
            if r["kind"] == "evaluation"]


@pytest.fixture(scope="module")
def sweep_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("sweep") / "runs.jsonl"
    _sweep(path)
    return path.read_bytes()


@pytest.fixture(scope="module")
def study_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("study") / "evaluations.jsonl"
    optimize(FEATHER, SPACE, path, iterations=STUDY_ITERATIONS, plan=PLAN)
    return path.read_bytes(), _evaluations(path)


def _edit(line: bytes, choice: int) -> bytes:
    """Change one value of a record, keeping valid JSON (a number nudged, a string or bool changed)."""
    record = json.loads(line)
    keys = sorted(k for k in record if k not in ("kind", "digest"))
    key = keys[choice % len(keys)]
    value = record[key]
    if isinstance(value, bool):
        record[key] = not value
    elif isinstance(value, (int, float)):
        record[key] = value + 1
    elif isinstance(value, dict) and value:
        inner = sorted(value)[0]
        record[key] = {**value, inner: (value[inner] + 0.01) if isinstance(value[inner], (int, float)) else "x"}
    else:
        record[key] = f"{value}x"
    return json.dumps(record, sort_keys=True).encode()


MUTATIONS = st.one_of(
    st.tuples(st.just("duplicate"), st.integers(1, 10_000), st.integers(0, 10_000)),
    st.tuples(st.just("drop"), st.integers(1, 10_000)),
    st.tuples(st.just("edit"), st.integers(1, 10_000), st.integers(0, 10_000)),
    st.tuples(st.just("garbage"), st.integers(0, 10**6), st.binary(min_size=1, max_size=8)),
    st.tuples(st.just("cut"), st.integers(1, 400)),
)


def _mutate(data: bytes, mutation: tuple) -> bytes:
    lines = data.split(b"\n")[:-1]
    kind = mutation[0]
    if kind == "duplicate":
        _, i, j = mutation
        line = lines[1 + i % (len(lines) - 1)]
        lines.insert(1 + j % len(lines), line)
    elif kind == "drop":
        del lines[1 + mutation[1] % (len(lines) - 1)]
    elif kind == "edit":
        i = 1 + mutation[1] % (len(lines) - 1)
        lines[i] = _edit(lines[i], mutation[2])
    elif kind == "garbage":
        at = mutation[1] % len(data)
        return data[:at] + mutation[2] + data[at:]
    elif kind == "cut":
        return data[: len(data) - 1 - mutation[1] % len(lines[-1])]   # the last line loses its end
    return b"\n".join(lines) + b"\n"


def _resume(fn, path: Path, mutation: tuple, *, must_proceed: tuple[str, ...]):
    """Run fn(); None if refused, which must be one line naming the log, never for `must_proceed`."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LogRepairWarning)
            return fn()
    except OptimizerError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc), str(exc)
        assert mutation[0] not in must_proceed, f"{mutation[0]} must resume, not be refused: {exc}"
        return None


@SETTINGS
@given(mutation=MUTATIONS)
def test_a_damaged_sweep_log_resumes_to_the_undamaged_sweep_or_is_refused(sweep_log, mutation):
    fresh = _rows(_sweep(None))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "runs.jsonl"
        path.write_bytes(_mutate(sweep_log, mutation))
        # A sweep's runs are independent: a lost line (dropped, or cut by a kill) is simply run again.
        resumed = _resume(lambda: _sweep(path, resume=True), path, mutation, must_proceed=("drop", "cut"))
        if resumed is None:
            return
        assert mutation[0] not in ("duplicate", "edit"), "a duplicated or edited record was accepted"
        assert _rows(resumed) == fresh
        assert _sweep(path, resume=True).resumed_runs == len(fresh)   # the log is whole again


@SETTINGS
@given(mutation=MUTATIONS)
def test_a_damaged_study_log_resumes_to_the_undamaged_study_or_is_refused(study_log, mutation):
    data, fresh = study_log
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "evaluations.jsonl"
        path.write_bytes(_mutate(data, mutation))
        run = _resume(lambda: optimize(FEATHER, SPACE, path, iterations=STUDY_ITERATIONS, plan=PLAN, resume=True),
                      path, mutation, must_proceed=("cut",))
        if run is None:
            return
        assert mutation[0] not in ("duplicate", "edit"), "a duplicated or edited record was accepted"
        assert _evaluations(path) == fresh


def test_a_dropped_sweep_line_is_run_again(sweep_log, tmp_path):
    path = tmp_path / "runs.jsonl"
    path.write_bytes(_mutate(sweep_log, ("drop", 3)))
    assert _sweep(path, resume=True).resumed_runs == len(CONTROLLERS) * 14 - 1


def test_a_phantom_run_beyond_the_grid_is_refused(sweep_log, tmp_path):
    from featherstar.optimizer.log import digest

    lines = sweep_log.split(b"\n")[:-1]
    phantom = json.loads(lines[-1])
    phantom["index"] = 999
    phantom["digest"] = digest(phantom)   # a well-formed record, from another grid
    path = tmp_path / "runs.jsonl"
    path.write_bytes(sweep_log + json.dumps(phantom).encode() + b"\n")
    with pytest.raises(OptimizerError, match="run index 999 is not one this run plans"):
        _sweep(path, resume=True)


def test_a_run_moved_to_another_index_is_refused(sweep_log, tmp_path):
    from featherstar.optimizer.log import digest

    lines = sweep_log.split(b"\n")[:-1]
    moved = json.loads(lines[2])
    del lines[3]
    moved["index"] += 1   # run 2's record in the place of run 3, whose line is gone
    moved["digest"] = digest(moved)
    path = tmp_path / "runs.jsonl"
    path.write_bytes(b"\n".join(lines) + b"\n" + json.dumps(moved).encode() + b"\n")
    with pytest.raises(OptimizerError, match="where the plan has"):
        _sweep(path, resume=True)


def test_a_bench_log_with_two_validations_of_one_controller_is_refused(tmp_path):
    validation = {"kind": "validation", "controller": "best", "thrust_ratio": 2.0, "thrust_ratio_sd": 0.1,
                  "mean_thrust_N": 0.02, "mean_thrust_sd_N": 0.001}
    log = ExperimentLog(tmp_path / "evaluations.jsonl", [validation, dict(validation)], [2, 3])
    with pytest.raises(OptimizerError, match="line 3 repeats the validation controller 'best' of line 2"):
        check_log(log, bench_entries(SPACE, 4))
    log = ExperimentLog(tmp_path / "evaluations.jsonl", [{**validation, "controller": "median"}], [2])
    with pytest.raises(OptimizerError, match="not one this run plans"):
        check_log(log, bench_entries(SPACE, 4))


def test_sweep_resume_from_the_command_line_refuses_a_duplicated_run_and_warns_of_a_cut_one(tmp_path, capsys):
    from featherstar.app import main

    out = tmp_path / "sweep"
    argv = ["sweep", "synthetic:plain", "--family", "spanwise", "--workers", "1", "--no-progress", "--out", str(out)]
    assert main(argv) == 0
    log = out / "runs.jsonl"
    good = log.read_bytes()
    lines = good.splitlines(keepends=True)
    log.write_bytes(good + lines[5])
    capsys.readouterr()
    assert main([*argv, "--resume"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "repeats the run index" in err and str(log) in err

    log.write_bytes(b"".join(lines[:-1]) + lines[-1][:-7])   # the last record cut by a kill
    assert main([*argv, "--resume"]) == 0
    warnings_printed = [ln for ln in capsys.readouterr().err.splitlines() if "warning" in ln]
    assert len(warnings_printed) == 1 and "dropping an incomplete last record" in warnings_printed[0]
    assert json.loads((out / "summary.json").read_text())["resumed_runs"] == 14 * 12 - 1


def test_a_format_1_log_without_digests_still_resumes(sweep_log, tmp_path):
    lines = [json.loads(line) for line in sweep_log.splitlines()]
    lines[0]["format"] = 1
    old = [lines[0]] + [{k: v for k, v in r.items() if k != "digest"} for r in lines[1:-3]]
    path = tmp_path / "runs.jsonl"
    path.write_text("".join(json.dumps(r, sort_keys=True) + "\n" for r in old))
    resumed = _sweep(path, resume=True)
    assert resumed.resumed_runs == len(old) - 1 and _rows(resumed) == _rows(_sweep(None))
    assert all("digest" not in json.loads(line) for line in path.read_text().splitlines())   # one format per log

"""Locating the bench/ scripts of a checkout and running them as processes, two at a time."""
from __future__ import annotations

import re
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from ..fmu_src.errors import FeatherstarError


class BenchError(FeatherstarError):
    """The benchmark folder is missing, or the dashboard could not run."""


def find_bench_dir(start: Path | str | None = None) -> Path:
    """The `bench/` folder of the repository checkout containing `start` (default: the cwd)."""
    here = Path(start if start is not None else Path.cwd()).resolve()
    for folder in (here, *here.parents):
        bench = folder / "bench"
        if bench.is_dir() and (folder / "pyproject.toml").is_file() and bench_scripts(bench):
            return bench
    raise BenchError(
        f"no bench/ folder with benchmark scripts in {here} or any folder above it: the benchmarks "
        "live in a featherstar repository checkout, not in the installed package; run `featherstar "
        "bench` from inside a checkout (git clone ... && cd featherstar)")


def bench_scripts(bench: Path) -> list[Path]:
    """Every benchmark script: bench/*.py except this dashboard's own wrapper and private modules."""
    return sorted(p for p in bench.glob("*.py") if p.name != "dashboard.py" and not p.name.startswith("_"))


@dataclass(frozen=True)
class Plan:
    """How the dashboard runs one script. `quick_args` replace a bare --quick in quick mode;
    None: the script runs in full mode only (too long for --quick's 5 minutes)."""

    quick_args: tuple[str, ...] | None = ("--quick",)
    full_args: tuple[str, ...] = ()
    alone: bool = False  # timing-sensitive: nothing else runs meanwhile
    expected_s: float = 60.0  # for scheduling the longest first


# Reduced invocations keep `featherstar bench --quick` within 5 minutes on the 2-core machine.
PLANS: dict[str, Plan] = {
    "cosim_work_precision.py": Plan(("--quick", "--scenes", "testbed"), expected_s=150),
    "fmu_models.py": Plan(("--quick", "--models", "feather-plain,feather-chordwise,servo"), expected_s=60),
    "optimizer_timing.py": Plan(("--quick", "--synthetic"), expected_s=20),
    "hil_loop_rate.py": Plan(("--quick",), alone=True, expected_s=30),
    "stability_map.py": Plan(("--quick",), expected_s=90),
    "feather_speed.py": Plan(("--quick",), expected_s=150),
    "optimizer_speed.py": Plan(("--seeds", "1", "--iterations", "8"), expected_s=60),
    "me_weak_accuracy.py": Plan((), expected_s=30),
    "mixed_coupling.py": Plan(("--quick",), expected_s=25),
    "same_numbers.py": Plan((), expected_s=20),
    # a CPU-share measurement of the idle emulator: nothing else may run meanwhile
    "bench_emulator_idle.py": Plan(("--seconds", "10"), full_args=(), alone=True, expected_s=20),
    # minutes each even when reduced, or real time on the emulator: full runs only
    "flap_mechanisms.py": Plan(None, expected_s=240),
    "drag_convergence.py": Plan(None, expected_s=240),
    "wake_feathers.py": Plan(None, expected_s=200),
    # they start busy processes themselves and measure real time: alone
    "bench_timed_load.py": Plan(None, alone=True, expected_s=300),
    "bench_timed_optimize.py": Plan(None, alone=True, expected_s=1500),
    "wake_memory.py": Plan(None, expected_s=600),   # its own --quick takes ~7 min
    "bench_loop_prior.py": Plan(None, expected_s=300),
    "bench_calibration.py": Plan(None, expected_s=300),
    "model_form_design.py": Plan(None, expected_s=900),   # 9 fits per design, 5 designs
}


def plan_of(script: Path) -> Plan:
    """How `script` is run: its entry in PLANS, else `--quick` in quick mode when the script has
    that option and full mode only when it has not (a plan never passes an option the script
    lacks; tests/stress/test_bench_command.py checks the entries)."""
    if script.name in PLANS:
        return PLANS[script.name]
    return Plan() if defines_option(script, "--quick") else Plan(None)


def defines_option(script: Path, option: str) -> bool:
    """Whether the script's source names `option` as a string (how argparse options are declared;
    read, not run: a script is not started to find out)."""
    source = script.read_text(encoding="utf-8", errors="replace")
    return re.search(rf"""['"]{re.escape(option)}['"]""", source) is not None


def full_run_only(bench: Path | None) -> list[str]:
    """The checkout's scripts that `--quick` leaves out."""
    return [s.name for s in (bench_scripts(bench) if bench is not None else []) if plan_of(s).quick_args is None]
MEASURE_EXPECTED_S = 90.0


@dataclass
class Task:
    name: str
    argv: list[str]
    log: Path
    alone: bool = False
    expected_s: float = 60.0
    started: float = 0.0
    wall_s: float = 0.0
    returncode: int | None = None
    timed_out: bool = False
    outputs: list[str] = field(default_factory=list)


def scripts_without_out(bench: Path) -> list[str]:
    """Benchmark scripts with no --out option: the dashboard would have them write elsewhere
    (into the checkout's committed docs/results), so it refuses to start while there are any."""
    return [s.name for s in bench_scripts(bench) if not defines_option(s, "--out")]


def make_tasks(bench: Path | None, out: Path, quick: bool, measure: bool = True) -> list[Task]:
    """The checkout's bench scripts (none without a checkout) and the dashboard's own measurements."""
    tasks = []
    logs = out / "logs"
    scheduled = [s for s in (bench_scripts(bench) if bench is not None else [])
                 if not (quick and plan_of(s).quick_args is None)]
    # every script, not only those this mode runs: the other mode would write outside --out
    missing = scripts_without_out(bench) if bench is not None else []
    if missing:
        raise BenchError(f"{', '.join(missing)}: no --out option; every benchmark script must write where "
                         "the dashboard says (nothing outside --out)")
    for script in scheduled:
        plan = plan_of(script)
        args = list(plan.quick_args if quick else plan.full_args)
        args += ["--out", str(out)]
        tasks.append(Task(script.stem, [sys.executable, str(script), *args], logs / f"{script.stem}.log",
                          plan.alone, plan.expected_s))
    if measure:
        argv = [sys.executable, "-m", __package__, "--measure", str(out)] + (["--quick"] if quick else [])
        tasks.append(Task("dashboard_measurements", argv, logs / "dashboard_measurements.log",
                          expected_s=MEASURE_EXPECTED_S))
    return tasks


def _new_files(folder: Path, since: float, suffixes: tuple[str, ...] = (".json", ".png")) -> list[Path]:
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.suffix in suffixes and p.stat().st_mtime >= since - 1e-3)


def run_tasks(tasks: list[Task], out: Path, *, jobs: int, timeout_s: float | None, env: dict[str, str],
              cwd: Path, log: Callable[[str], None]) -> None:
    """Run the tasks, `jobs` at a time (alone-tasks by themselves), longest expected first."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "logs").mkdir(exist_ok=True)
    alone = [t for t in tasks if t.alone]
    rest = sorted((t for t in tasks if not t.alone), key=lambda t: -t.expected_s)
    for batch, width in ([(alone, 1)] if alone else []) + [(rest, max(1, jobs))]:
        pending = list(batch)
        running: list[tuple[Task, subprocess.Popen, Any]] = []
        while pending or running:
            while pending and len(running) < width:
                task = pending.pop(0)
                task.started = time.time()
                fh = open(task.log, "w")
                log(f"start {task.name}: {' '.join(Path(a).name if i < 2 else a for i, a in enumerate(task.argv))}")
                proc = subprocess.Popen(task.argv, stdout=fh, stderr=subprocess.STDOUT, cwd=cwd, env=env)
                running.append((task, proc, fh))
            time.sleep(0.2)
            for entry in list(running):
                task, proc, fh = entry
                elapsed = time.time() - task.started
                if proc.poll() is None and timeout_s and elapsed > timeout_s:
                    proc.kill()
                    proc.wait()
                    task.timed_out = True
                if proc.poll() is not None:
                    fh.close()
                    task.returncode = proc.returncode
                    task.wall_s = time.time() - task.started
                    running.remove(entry)
                    _collect(task, out)
                    state = "timed out" if task.timed_out else ("ok" if task.returncode == 0 else f"FAILED (rc {task.returncode})")
                    log(f"done  {task.name}: {state} in {task.wall_s:.0f} s")


def _collect(task: Task, out: Path) -> None:
    """The files this task wrote: new since it started and named after it (`<name>.json`,
    `<name>_*.json`, `<name>.png`...; benches running at the same time write other names)."""
    files = [f for f in _new_files(out, task.started) if f.stem == task.name or f.stem.startswith(task.name + "_")]
    task.outputs = sorted(f.name for f in files)

"""`featherstar bench`: run every benchmark, then write dashboard.json and dashboard.md."""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any, Callable, Sequence

from ..fmu_src.errors import FeatherstarError
from .report import derive, load_json, plot_all, write_markdown
from .runner import BenchError, find_bench_dir, full_run_only, make_tasks, run_tasks
from .timing import measure


def run_dashboard(quick: bool = False, out: Path | None = None, *, jobs: int = 2, timeout_s: float | None = None,
                  start: Path | None = None, log: Callable[[str], None] | None = None,
                  measure: bool = True) -> dict[str, Any]:
    """Run every benchmark and write dashboard.json and dashboard.md; returns the report.
    measure=False skips the dashboard's own measurements (tests of the plumbing)."""
    t0 = time.perf_counter()
    log = log or (lambda msg: print(f"{time.perf_counter() - t0:6.0f}s {msg}", flush=True))
    env = dict(os.environ)
    try:
        bench: Path | None = find_bench_dir(start)
    except BenchError as exc:   # an installed package: the dashboard's own measurements still run
        bench = None
        log(f"{exc}; running the dashboard's own measurements only")
    if bench is not None:
        root = bench.parent
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")]))
    else:
        root = Path.cwd()
    out = Path(out) if out is not None else (bench / "results" if bench is not None else Path("bench-results"))
    out = out if out.is_absolute() else Path.cwd() / out
    out.mkdir(parents=True, exist_ok=True)
    env.setdefault("MPLBACKEND", "Agg")
    tasks = make_tasks(bench, out, quick, measure)
    started = time.strftime("%Y-%m-%d %H:%M:%S")
    machine = {"cpus": os.cpu_count(), "load_avg_1min_at_start": os.getloadavg()[0],
               "python": platform.python_version(), "platform": platform.platform()}
    run_tasks(tasks, out, jobs=jobs, timeout_s=timeout_s, env=env, cwd=root, log=log)
    machine["load_avg_1min_at_end"] = os.getloadavg()[0]
    data: dict[str, Any] = {}
    benches: dict[str, Any] = {}
    for task in tasks:
        benches[task.name] = {"argv": [Path(task.argv[0]).name, *task.argv[1:]], "returncode": task.returncode,
                              "timed_out": task.timed_out, "wall_s": task.wall_s, "outputs": task.outputs,
                              "log": str(task.log.relative_to(out))}
        for name in task.outputs:
            if name.endswith(".json"):
                loaded = load_json(out, name)
                if loaded is not None:
                    data[Path(name).stem] = loaded
    if quick and bench is not None and "optimizer_timing" not in data:  # the last real optimizer measurement, labelled as such
        last = load_json(bench / "results", "optimizer_timing.json")
        if last is not None:
            data["optimizer_timing"] = last
    report = {"quick": quick, "started": started, "machine": machine,
              "bench_dir": str(bench) if bench is not None else None, "benches": benches,
              "full_run_only": full_run_only(bench) if quick else [],
              "total_s": time.perf_counter() - t0}
    report["summary"] = derive(data, quick)
    data["summary"] = report["summary"]
    report["figures"] = plot_all(data, out)
    report["results"] = data
    report["total_s"] = time.perf_counter() - t0
    (out / "dashboard.json").write_text(json.dumps(report, indent=2, default=float) + "\n")
    md = write_markdown(report, out)
    log(f"wrote {out / 'dashboard.json'} and {md} ({report['total_s']:.0f} s)")
    failed = [n for n, b in benches.items() if b["returncode"] != 0]
    if failed:
        log(f"{len(failed)} benchmark(s) failed or timed out: {', '.join(failed)} (logs in {out / 'logs'})")
    return report


def _cmd_bench(args: argparse.Namespace) -> int:
    report = run_dashboard(args.quick, args.out, jobs=args.jobs, timeout_s=args.timeout)
    return 0 if all(b["returncode"] == 0 for b in report["benches"].values()) else 1


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="reduced benchmarks (the last measured wall time is in README.md and dashboard.json)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: bench/results in a checkout, ./bench-results elsewhere)")
    parser.add_argument("--jobs", type=int, default=2, help="benchmarks run at once (default 2; HIL always alone)")
    parser.add_argument("--timeout", type=float, default=None, help="stop a benchmark after this many seconds")


def register(subparsers: Any) -> None:
    """Adds `featherstar bench` to the featherstar command line."""
    parser = subparsers.add_parser(
        "bench", help="run every benchmark in bench/ and write one JSON and a markdown report",
        description="Run every benchmark script of the repository checkout's bench/ folder (found from the "
                    "current directory; outside a checkout only the dashboard's own measurements run), collect "
                    "their JSON, add the dashboard's own side-by-side measurements and write dashboard.json and "
                    "dashboard.md with plots.")
    add_arguments(parser)
    parser.set_defaults(func=_cmd_bench)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="featherstar bench", description=__doc__.splitlines()[0])
    add_arguments(parser)
    parser.add_argument("--measure", type=Path, metavar="OUT", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    try:
        if args.measure is not None:
            measure(args.measure, args.quick)
            return 0
        return _cmd_bench(args)
    except FeatherstarError as exc:
        print(f"featherstar bench: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

"""`featherstar bench [--quick] [--out DIR]`: every benchmark in bench/, one JSON, one report.

The benchmarks are scripts in a repository checkout's `bench/` folder (they are not installed with
the package): `find_bench_dir` looks for it from the current directory upwards. Outside a
checkout (an installed package) only the dashboard's own measurements run, into ./bench-results.
Each script runs as its own process (`--quick` passed through, `--out DIR` always: a script
without --out is refused, so nothing writes outside DIR), two at
a time on a 2-core machine, except the timing-sensitive HIL loop-rate bench, which runs alone.
Their JSON is collected as is. What they do not measure, the dashboard measures itself, in one
more process (`python -m featherstar.dashboard --measure`), side by side in that process:

* the same ODE four ways: the co-simulation master (strong: ME FMU + CVODE; Jacobi: CS FMU at 1 ms),
  the monolithic CasADi model (`featherstar.dashboard.monolithic.run_monolithic`: CVODES on CasADi's expression graph) and
  what a user would write instead: scipy `solve_ivp` (RK45, the default) calling the same CasADi
  equations from Python. Every timing is reported as a ratio to the monolithic model and to scipy;
* cost growth with N (plain feather) and with the simulated duration;
* a work-precision set for the kinematic scene with the plain feather (periodic, so errors are
  pointwise) against a compiled monolithic reference at rtol 1e-10;
* the cost of one RHS call of the CasADi equations from Python (numpy in, DM out; and CasADi's
  preallocated-buffer call), to set the FMU call overhead measured by bench/fmu_models.py against;
* in --quick mode, one real optimizer evaluation (the optimizer bench then only times the
  optimizer's own overhead on its analytic stand-in): the 30-iteration and sweep wall times
  are estimated from the two, and labelled as estimates.

Then `<out>/dashboard.json` (everything) and `<out>/dashboard.md` (the short report, with
dashboard_*.png figures and the benches' own figures) are written.
"""
from .cli import main, register, run_dashboard
from .runner import BenchError, find_bench_dir

__all__ = ["BenchError", "find_bench_dir", "run_dashboard", "register", "main"]

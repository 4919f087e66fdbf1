"""`featherstar bench`: finds bench/ from the current directory or says clearly that it cannot,
runs every script there and writes one JSON and one markdown report (plumbing only: the real
benchmarks take minutes, `featherstar bench --quick` is timed by hand and in docs/stability.md)."""
from __future__ import annotations

import json
import textwrap

import pytest
from featherstar.dashboard import BenchError, find_bench_dir, run_dashboard

from featherstar.app import main


#: The argument handling every benchmark script has (the dashboard passes --out, always).
ARGS = "import argparse; p = argparse.ArgumentParser(); p.add_argument('--quick', action='store_true'); " \
       "p.add_argument(\"--out\"); p.parse_args()\n"


def test_bench_is_a_featherstar_command(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["bench", "--help"])
    assert exit_.value.code == 0
    assert "--quick" in capsys.readouterr().out


def test_outside_a_checkout_it_says_where_it_looked_and_runs_its_own_measurements(tmp_path, monkeypatch):
    """An installed package has no bench/: the dashboard says so and still writes its report."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(BenchError, match="no bench/ folder"):
        find_bench_dir()
    said: list[str] = []
    report = run_dashboard(quick=True, measure=False, log=said.append)
    assert any("no bench/ folder" in line and str(tmp_path) in line for line in said)
    assert report["bench_dir"] is None and report["benches"] == {}
    assert (tmp_path / "bench-results" / "dashboard.json").is_file()


def test_runs_every_script_and_writes_one_report(tmp_path, monkeypatch):
    checkout = tmp_path / "checkout"
    bench = checkout / "bench"
    bench.mkdir(parents=True)
    (checkout / "pyproject.toml").write_text("[project]\nname = 'x'\n")
    script = textwrap.dedent("""
        import argparse, json, pathlib
        p = argparse.ArgumentParser()
        p.add_argument("--quick", action="store_true")
        p.add_argument("--out", type=pathlib.Path)
        a = p.parse_args()
        (a.out / "{name}.json").write_text(json.dumps({{"quick": a.quick, "value": 42}}))
    """)
    for name in ("alpha", "beta"):
        (bench / f"{name}.py").write_text(script.format(name=name))
    (bench / "broken.py").write_text(ARGS + "raise SystemExit(3)\n")
    (bench / "dashboard.py").write_text("raise SystemExit('the dashboard must not run itself')\n")
    monkeypatch.chdir(bench)  # found from inside bench/ too
    report = run_dashboard(quick=True, out=tmp_path / "out", measure=False, log=lambda msg: None)
    assert set(report["benches"]) == {"alpha", "beta", "broken"}
    assert report["benches"]["alpha"]["outputs"] == ["alpha.json"]
    assert report["benches"]["broken"]["returncode"] == 3
    saved = json.loads((tmp_path / "out" / "dashboard.json").read_text())
    assert saved["results"]["beta"] == {"quick": True, "value": 42}
    md = (tmp_path / "out" / "dashboard.md").read_text()
    assert "| alpha | ok |" in md and "| broken | FAILED (rc 3" in md


def test_quick_leaves_out_full_run_only_scripts_and_says_so(tmp_path, monkeypatch):
    from featherstar.dashboard import runner

    checkout = tmp_path / "checkout"
    bench = checkout / "bench"
    bench.mkdir(parents=True)
    (checkout / "pyproject.toml").write_text("[project]\nname = 'x'\n")
    full_only = "raise SystemExit('a full-run-only script must not run in --quick')\n"
    # slow.py has no --quick (so, without a plan, it runs in full mode only); planned.py's plan says so
    (bench / "slow.py").write_text("import argparse; p = argparse.ArgumentParser(); p.add_argument(\"--out\"); "
                                   "p.parse_args()\n" + full_only)
    (bench / "planned.py").write_text(ARGS + full_only)
    (bench / "fast.py").write_text(ARGS)
    monkeypatch.setitem(runner.PLANS, "planned.py", runner.Plan(None))
    monkeypatch.chdir(checkout)
    report = run_dashboard(quick=True, out=tmp_path / "out", measure=False, log=lambda msg: None)
    assert set(report["benches"]) == {"fast"}
    assert report["full_run_only"] == ["planned.py", "slow.py"]
    md = (tmp_path / "out" / "dashboard.md").read_text()
    assert "| slow | not run: full runs only (`python bench/slow.py`)" in md


def test_a_script_without_out_is_refused_before_anything_runs(tmp_path, monkeypatch):
    """Nothing writes outside --out: a script that would write into the checkout stops the dashboard."""
    checkout = tmp_path / "checkout"
    bench = checkout / "bench"
    bench.mkdir(parents=True)
    (checkout / "pyproject.toml").write_text("[project]\nname = 'x'\n")
    (bench / "good.py").write_text(ARGS + "open('ran', 'w')\n")
    (bench / "writes_home.py").write_text("open('ran', 'w')\n")
    monkeypatch.chdir(checkout)
    with pytest.raises(BenchError, match="writes_home.py: no --out option"):
        run_dashboard(quick=True, out=tmp_path / "out", measure=False, log=lambda msg: None)
    assert not (checkout / "ran").exists() and not (bench / "ran").exists()


def test_every_benchmark_of_this_checkout_takes_out():
    from pathlib import Path

    from featherstar.dashboard.runner import scripts_without_out

    assert scripts_without_out(Path(__file__).resolve().parents[2] / "bench") == []


def test_every_plan_passes_only_options_its_script_has():
    """`featherstar bench` passes each script its plan's arguments and `--out DIR`: an option the
    script does not define fails it in a second (six scripts once did, with --quick)."""
    import re
    from pathlib import Path

    from featherstar.dashboard.runner import bench_scripts, defines_option, plan_of

    for script in bench_scripts(Path(__file__).resolve().parents[2] / "bench"):
        plan, source = plan_of(script), script.read_text(encoding="utf-8")
        for args in (plan.quick_args or (), plan.full_args, ("--out",)):
            for option in (a for a in args if a.startswith("--")):
                assert defines_option(script, option), f"{script.name}: its plan passes {option}, which it does not define"
        # --out names a directory: the script writes its own file names in it (never `--out FILE`)
        assert not re.search(r"args\.out\.(write_text|write_bytes|with_suffix|open)\(", source), \
            f"{script.name}: --out is used as a file; the dashboard passes a directory"

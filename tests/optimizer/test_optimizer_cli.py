import argparse
import json

import pytest

from featherstar.optimizer.cli import main as _main, register


def main(argv):
    """The command's exit status, argparse's refusals (SystemExit from parse_args) included."""
    try:
        return _main(argv)
    except SystemExit as exc:
        return exc.code


def test_register_adds_the_subcommands():
    parser = argparse.ArgumentParser()
    register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["optimize", "some_scene", "--objective", "min", "--iterations", "5", "--noise-N", "0",
                              "--seed", "3", "--set", "feather.width_ratio=7.5", "--set", "feather.morphology=plain"])
    assert args.func.__name__ == "_optimize_command"
    assert args.overrides == [("feather.width_ratio", 7.5), ("feather.morphology", "plain")]
    assert parser.parse_args(["sweep", "s", "--scheduler", "tcp://h:8786"]).scheduler == "tcp://h:8786"


def test_optimize_writes_log_summary_and_figures(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["optimize", "synthetic:chordwise", "--iterations", "6", "--out", str(out), "--seed", "2"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for key in ("best_params", "thrust_ratio", "thrust_ratio_sd", "baseline_thrust_ratio", "estimated_thrust_ratio"):
        assert key in summary
    assert len(summary["validation"]["best"]["repeats"]) == 10
    assert sum('"evaluation"' in line for line in (out / "evaluations.jsonl").read_text().splitlines()) == 6
    assert (out / "fig6_progress.png").stat().st_size > 0 and (out / "fig8_validation.png").stat().st_size > 0
    # a second, worst-controller run drawn together with the first in Fig. 8
    worst = tmp_path / "worst"
    assert main(["optimize", "synthetic:chordwise", "--objective", "min", "--iterations", "5", "--out", str(worst),
                 "--compare", str(out)]) == 0
    assert "baseline TR" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["--period", "0.4"], "shorter than the servo allows"),
    (["--bounds", "log10_up_down=0.2,-0.2"], "inverted"),
    (["--bounds", "log10_hold_mov=-1,0"], "unknown variable 'log10_hold_mov'"),
    (["--iterations", "2"], "wants a whole number >= 4"),
])
def test_bad_input_is_a_clear_error(tmp_path, capsys, argv, message):
    assert main(["optimize", "synthetic:plain", "--out", str(tmp_path), *argv]) == 2
    assert message in capsys.readouterr().err


def test_sweep_command(tmp_path, capsys):
    out = tmp_path / "sweep"
    assert main(["sweep", "synthetic:plain", "--family", "spanwise", "--out", str(out), "--no-progress"]) == 0
    for name in ("runs.csv", "table.csv", "fig3_sweep.png", "summary.json"):
        assert (out / name).exists()
    assert json.loads((out / "summary.json").read_text())["runs"] == 14 * 12
    assert "spanwise" in capsys.readouterr().out


def test_ctrl_c_points_to_resume(tmp_path, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("featherstar.optimizer.cli.run_study", interrupted)
    assert main(["optimize", "synthetic:plain", "--out", str(tmp_path)]) == 130
    assert "--resume" in capsys.readouterr().err


@pytest.mark.parametrize("command", [
    ["sweep", "synthetic:plain"], ["optimize", "synthetic:plain"], ["codesign", "synthetic:plain"], ["paper", "--quick"],
])
@pytest.mark.parametrize("address, reason", [
    ("tcp://127.0.0.1:1", "refused"), ("nonsense://x:1", "unknown address scheme"), ("host-without-port", "port"),
])
def test_a_bad_scheduler_address_is_one_line_naming_it(tmp_path, capsys, command, address, reason):
    assert main([*command, "--scheduler", address, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert f"cannot connect to the Dask scheduler at '{address}'" in err and reason in err
    assert not (tmp_path / "out").exists()


def test_sweep_resume_and_batched_optimize_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["sweep", "synthetic:plain", "--family", "spanwise", "--workers", "1", "--out", str(out), "--no-progress"]
    assert main(argv) == 0
    assert main(argv) == 2 and "--resume" in capsys.readouterr().err
    assert main([*argv, "--resume"]) == 0
    assert json.loads((out / "summary.json").read_text())["resumed_runs"] == 14 * 12
    opt = tmp_path / "opt"
    assert main(["optimize", "synthetic:plain", "--iterations", "6", "--batch-size", "2", "--out", str(opt)]) == 0
    assert json.loads((opt / "evaluations.jsonl").read_text().splitlines()[0])["batch_size"] == 2
    assert main(["optimize", "synthetic:plain", "--batch-size", "0", "--out", str(tmp_path / "x")]) == 2

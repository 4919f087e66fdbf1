"""Every bad option value of the optimizer commands: exit status 2, one line, at once, nothing written."""
import time

import pytest

from featherstar.app import main


def _run(argv):
    try:
        return main(argv)
    except SystemExit as exc:   # argparse's refusals exit from inside parse_args
        return exc.code


BAD = [
    (["sweep", "synthetic:plain", "--settle-periods", "-1"], "--settle-periods"),
    (["sweep", "synthetic:plain", "--periods", "0"], "--periods"),
    (["sweep", "synthetic:plain", "--seed", "-1"], "--seed"),
    (["sweep", "synthetic:plain", "--workers", "0"], "--workers"),
    (["sweep", "synthetic:plain", "--amplitude-deg", "nan"], "--amplitude-deg"),
    (["sweep", "synthetic:plain", "--noise-N", "-0.1"], "--noise-N"),
    (["sweep", "robot"], "feather.thrust_N"),                       # the scene lacks what the sweep measures
    (["sweep", "testbed", "--set", "feather.bogus=1"], "bogus"),      # refused by the first run's plan
    (["sweep", "synthetic:leafy"], "leafy"),
    (["optimize", "synthetic:plain", "--iterations", "0"], "--iterations"),
    (["optimize", "synthetic:plain", "--iterations", "3"], "initial points"),
    (["optimize", "synthetic:plain", "--seed", "-5"], "--seed"),
    (["optimize", "synthetic:plain", "--rest-s", "inf"], "--rest-s"),
    (["optimize", "synthetic:plain", "--period", "0"], "--period"),
    (["optimize", "synthetic:plain", "--servo-rate", "inf"], "--servo-rate"),
    (["optimize", "synthetic:plain", "--batch-size", "0"], "--batch-size"),
    (["optimize", "synthetic:plain", "--max-attempts", "0"], "--max-attempts"),
    (["optimize", "synthetic:plain", "--validation-repeats", "0"], "--validation-repeats"),
    (["optimize", "robot"], "feather.thrust_N"),
    (["optimize", "synthetic:plain", "--bounds", "log10_up_down=0.01,0.02", "--bounds",
      "log10_hold_up_down=0.01,0.02", "--bounds", "log10_hold_move=-3,-2.9"], "log10_hold_move"),   # no stroke there
    (["codesign", "synthetic:plain", "--budget", "0"], "--budget"),
    (["codesign", "synthetic:plain", "--period", "-1"], "--period"),
    (["calibrate", "run.csv", "--window-s", "inf"], "--window-s"),
    (["paper", "--quick", "--workers", "0"], "--workers"),
]
UNWRITABLE = [["optimize", "synthetic:plain"], ["sweep", "synthetic:plain"], ["codesign", "synthetic:plain"],
              ["calibrate", "run.csv"], ["paper", "--quick"]]


def _refused(argv, capsys, mention):
    started = time.perf_counter()
    code = _run(argv)
    elapsed_s = time.perf_counter() - started
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert mention in err
    assert elapsed_s < 1.0, f"refused after {elapsed_s:.1f} s"


@pytest.mark.parametrize("argv, mention", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_a_bad_value_is_refused_at_once_with_one_line(tmp_path, capsys, argv, mention):
    out = tmp_path / "out"
    _refused([*argv, "--out", str(out)], capsys, mention)
    assert not out.exists() or not any(out.iterdir()), "a refused command wrote something"


@pytest.mark.parametrize("argv", UNWRITABLE, ids=[a[0] for a in UNWRITABLE])
def test_an_unwritable_out_is_refused_at_once(tmp_path, capsys, argv):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    _refused([*argv, "--out", str(blocker / "out")], capsys, "--out")
    _refused([*argv, "--out", str(blocker)], capsys, "not a directory")

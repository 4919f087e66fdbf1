"""Every bad option value of the optimizer commands: exit status 2, one line, at once, nothing written."""
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

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


COMMANDS = {"optimize": ["synthetic:plain"], "sweep": ["synthetic:plain"], "codesign": ["synthetic:plain"],
            "calibrate": ["run.csv"], "paper": []}


def _numeric_options():
    """(command, option, its type) for every option of the optimizer commands, found in the parser."""
    from featherstar.app import build_parser

    parser = build_parser(only="optimize")
    commands = next(a for a in parser._actions if a.dest == "command").choices
    found = []
    for name in COMMANDS:
        for action in commands[name]._actions:
            if action.option_strings and action.type is not None:
                found.append((name, action.option_strings[0], action.type))
    return found


def test_no_optimizer_option_parses_a_bare_int_or_float():
    bare = [(c, o) for c, o, t in _numeric_options() if t in (int, float)]
    assert not bare, f"options without a range check: {bare}"


def _bad_values(kind):
    if hasattr(kind, "least"):
        return st.one_of(st.integers(max_value=kind.least - 1).map(str), st.sampled_from(["1.5", "x", "", "1e3"]))
    if hasattr(kind, "above"):
        low = kind.above if kind.above is not None else kind.at_least
        bad = st.sampled_from(["nan", "inf", "-inf", "x", ""])
        if low is None:
            return bad
        below = st.floats(max_value=low, allow_nan=False, allow_infinity=False)
        if kind.above is None:
            below = below.filter(lambda v: v < low)
        return st.one_of(bad, below.map(repr))
    return st.nothing()


NUMERIC = [(c, o, t) for c, o, t in _numeric_options() if hasattr(t, "least") or hasattr(t, "above")]


# tmp_path and capsys are shared by the examples on purpose: each refusal writes nothing and is read at once.
@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
@pytest.mark.parametrize("command, option, kind", NUMERIC, ids=[f"{c} {o}" for c, o, _ in NUMERIC])
def test_every_out_of_range_value_of_every_numeric_option_is_one_line(tmp_path, capsys, command, option, kind, data):
    value = data.draw(_bad_values(kind))
    _refused([command, *COMMANDS[command], f"{option}={value}", "--out", str(tmp_path / "out")], capsys, option)

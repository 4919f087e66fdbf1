"""The featherstar command's registry: a subcommand whose module fails to import stays listed."""
from __future__ import annotations

import re
import sys

import pytest

from featherstar.app import SUBCOMMANDS, build_parser, main


def test_every_registered_subcommand_is_listed(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    for entry in SUBCOMMANDS:
        for name in entry.names:
            assert name in out
    assert "UNAVAILABLE" not in out


def test_a_module_that_fails_to_import_is_listed_with_its_error(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "featherstar.optimizer.cli", None)   # `import optimizer.cli` now fails
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    entries = re.sub(r"\n {10,}", " ", out)   # a long name's help continues on the next lines
    lines = [ln for ln in entries.splitlines()
             if ln.strip().startswith(("optimize", "calibrate", "sweep", "codesign", "paper"))]
    assert len(lines) == 5 and all("UNAVAILABLE" in ln for ln in lines), out
    assert "cannot load featherstar.optimizer.cli" in out and "ModuleNotFoundError" in out
    # the others still work
    assert "run " in out and "emulate" in out and out.count("UNAVAILABLE") == 5
    assert main(["optimize", "testbed", "--iterations", "3"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("featherstar optimize: unavailable: cannot load featherstar.optimizer.cli: ModuleNotFoundError")


def test_a_register_that_raises_is_reported_the_same_way(tmp_path, monkeypatch):
    (tmp_path / "broken_commands.py").write_text("def register(sub):\n    raise RuntimeError('no luck')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    from featherstar.app import Subcommands

    parser = build_parser([Subcommands("broken_commands", ("frobnicate",))])
    assert "UNAVAILABLE (cannot load broken_commands: RuntimeError: no luck)" in parser.format_help()

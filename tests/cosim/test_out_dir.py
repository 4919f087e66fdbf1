"""The --out probe's refusals say why in words that fit the case (one check for every command)."""
import errno
import sys
import tempfile

import pytest

from featherstar.cosim.out_dir import out_dir_problem


@pytest.mark.parametrize("code, words", [
    (errno.EACCES, "does not let this user create files"),
    (errno.EPERM, "does not let this user create files"),
    (errno.EROFS, "read-only file system"),
    (errno.ENOSPC, "full disk"),
    (errno.ENOENT, "refuses new directories"),
    (errno.EIO, "refuses a new directory"),
])
def test_a_refused_probe_names_the_directory_and_the_reason(tmp_path, monkeypatch, code, words):
    def refuse(*args, **kwargs):
        raise OSError(code, "as the kernel says it")

    monkeypatch.setattr(tempfile, "mkdtemp", refuse)
    problem = out_dir_problem(tmp_path / "new" / "out")
    assert problem is not None and str(tmp_path) in problem and words in problem


def test_a_writable_place_and_a_file_in_the_way():
    assert out_dir_problem(tempfile.gettempdir()) is None
    assert out_dir_problem(__file__) == "is a file, not a directory"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc is Linux's")
def test_proc_is_not_said_to_be_missing():
    problem = out_dir_problem("/proc/featherstar-out")
    assert problem is not None and "No such file or directory" not in problem and "/proc" in problem

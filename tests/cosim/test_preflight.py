"""Bad input refused before any work, each with exit 2 and one line naming the culprit: the
metric window, the run length against memory, corrupt FMU archives (and a corrupt cache entry
rebuilt), and an optimizer override that would be silently ignored."""
from __future__ import annotations

import zipfile
from pathlib import Path

import pytest
from featherstar.cosim.fmi.archive import cached_fmu, fmu_archive_problem

from featherstar.app import main

LAG_XML = Path(__file__).parent / "fmi2_lag" / "modelDescription.xml"


def _refused(capsys, argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("featherstar: error:"), err
    return err[0]


@pytest.mark.parametrize("value, expected", [
    ("-1", "metrics.settle_periods = -1.0 must be a finite number >= 0"),
    ("nan", "metrics.settle_periods = nan must be a finite number >= 0"),
    ("50", "metrics.settle_periods = 50 leaves no whole period to measure in a run of 6 periods"),
    ("6", "metrics.settle_periods = 6 leaves no whole period"),
])
def test_a_metric_window_without_a_whole_period_is_refused(capsys, value, expected):
    line = _refused(capsys, ["run", "testbed", "--quiet", "--set", f"metrics.settle_periods={value}"])
    assert expected in line


def test_a_run_too_long_for_memory_is_refused_with_its_estimate(capsys):
    line = _refused(capsys, ["run", "testbed", "--quiet", "--set", "master.periods=1e9"])
    assert "master.periods = 1e+09" in line and "TiB" in line and "memory is available" in line


def test_optimize_refuses_a_run_length_override_it_would_ignore(capsys, tmp_path):
    line = _refused(capsys, ["optimize", "testbed", "--set", "master.periods=3",
                             "--iterations", "4", "--out", str(tmp_path)])
    assert "--set master.periods: refused" in line


def _fmu(path: Path, corrupt: bool) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.write(LAG_XML, "modelDescription.xml")
        z.writestr("binaries/linux64/lag.so", bytes(range(256)) * 64)
    if corrupt:   # damage the compressed binary, as a truncated download or a bad disk does
        data = bytearray(path.read_bytes())
        at = data.index(b"binaries/linux64/lag.so") + len("binaries/linux64/lag.so") + 20
        data[at] ^= 0xFF
        path.write_bytes(bytes(data))
    return path


def test_a_corrupt_fmu_file_is_refused_before_it_is_loaded(tmp_path, capsys):
    fmu = _fmu(tmp_path / "lag.fmu", corrupt=True)
    assert "binaries/linux64/lag.so" in fmu_archive_problem(fmu)
    assert fmu_archive_problem(_fmu(tmp_path / "ok.fmu", corrupt=False)) is None
    scene = tmp_path / "corrupt.toml"
    scene.write_text(f"""name = "corrupt"
connections = ["controller.angle_rad -> lag.u"]
[master]
coupling = "jacobi"
t_end_s = 0.1
[blocks.controller]
kind = "stroke"
[blocks.lag]
kind = "fmu"
fmu = "{fmu}"
[blocks.rec]
kind = "recorder"
signals = ["lag.x"]
""")
    line = _refused(capsys, ["run", str(scene), "--quiet"])
    assert "block 'lag'" in line and str(fmu) in line and "CRC" in line


def test_a_corrupt_cache_entry_is_rebuilt_once(tmp_path, caplog):
    cached = _fmu(tmp_path / "model.fmu", corrupt=True)
    calls = []

    def build(model, force=False):
        calls.append(force)
        if force:
            _fmu(cached, corrupt=False)
        return cached

    assert cached_fmu("model", build, "block 'feather'") == cached
    assert calls == [False, True] and fmu_archive_problem(cached) is None
    assert "corrupt" in caplog.text and "rebuilding" in caplog.text

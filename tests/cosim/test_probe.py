"""A foreign binary cannot take the master down: FMUs whose library segfaults, aborts, exits or
hangs in instantiate or in initialization, and truncated libraries inside well-formed zips, in a
TOML scene, in an SSP package and on the command line. Every case is one line naming the FMU, the
FMI call and the signal; the process survives; no verdict is cached for a binary that crashed; a
healthy binary is probed once."""
from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from crash_fmus import build_crash, truncated
from featherstar.cosim.errors import FeatherstarError, StepError
from featherstar.cosim.fmi import probe
from featherstar.cosim.scene.data import scene_from_dict
from featherstar.cosim.ssp.read import SSD_NAME
from featherstar.cosim.swimmer.run import run_scene

from featherstar.app import main

SIGNAL = {"segv": "SIGSEGV", "abort": "SIGABRT", "exit": "exit status 3"}
CALL = {("instantiate", 2): "fmi2Instantiate", ("instantiate", 3): "fmi3InstantiateModelExchange",
        ("initialization", 2): "fmi2ExitInitializationMode", ("initialization", 3): "fmi3ExitInitializationMode"}


@pytest.fixture(scope="module")
def crash_folder(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.skip("gcc is needed to build the crashing test FMUs")
    return tmp_path_factory.mktemp("crash_fmus")


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch):
    """Verdicts and unpacked packages in a fresh cache: what a case leaves there is seen."""
    monkeypatch.setenv("FEATHERSTAR_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(probe, "_seen", {})
    return tmp_path / "cache"


def _scene(fmu: Path):
    return scene_from_dict({
        "name": "foreign", "connections": [],
        "master": {"coupling": "strong", "t_end_s": 0.1, "output_interval_s": 0.01},
        "blocks": {"vdp": {"kind": "fmu", "fmu": str(fmu)}, "rec": {"kind": "recorder", "signals": ["vdp.x0"]}},
    })


def _one_line(exc: BaseException) -> str:
    text = str(exc)
    assert "\n" not in text, text
    return text


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("at", ["instantiate", "initialization"])
@pytest.mark.parametrize("how", ["segv", "abort", "exit"])
def test_a_crashing_binary_is_one_line_and_the_master_survives(crash_folder, own_cache, version, at, how):
    fmu = build_crash(at, how, version, crash_folder)
    with pytest.raises(StepError) as failed:
        run_scene(_scene(fmu))
    line = _one_line(failed.value)
    assert f"FMU '{fmu}'" in line and SIGNAL[how] in line and CALL[at, version] in line, line
    assert failed.value.block == "vdp" and failed.value.function == "probe"
    assert not (own_cache / "probed").exists() or not any((own_cache / "probed").iterdir())


def test_a_hanging_binary_is_killed_after_the_timeout(crash_folder, tmp_path):
    fmu = build_crash("instantiate", "hang", 2, crash_folder)
    with zipfile.ZipFile(fmu) as z:
        z.extractall(tmp_path / "unzipped")
    from fmpy import read_model_description

    md = read_model_description(str(fmu))
    problem = probe.probe_fmu(fmu, tmp_path / "unzipped", md.guid, "crash", md.fmiVersion, "me", timeout_s=1.0)
    assert problem == "did not return from fmi2Instantiate within 1 s (killed)"


def test_a_healthy_binary_is_probed_once_per_hash(crash_folder, own_cache, monkeypatch):
    fmu = build_crash("nowhere", "segv", 3, crash_folder)
    children = []
    real = probe._run_child
    monkeypatch.setattr(probe, "_run_child", lambda *a, **k: children.append(a) or real(*a, **k))
    first = run_scene(_scene(fmu))
    assert len(children) == 1 and len(list((own_cache / "probed").iterdir())) == 1
    monkeypatch.setattr(probe, "_seen", {})   # another process: the verdict on disk counts
    again = run_scene(_scene(fmu))
    assert len(children) == 1
    assert (first["vdp.x0"] == again["vdp.x0"]).all()
    copy = shutil.copy(fmu, own_cache / "copy.fmu")   # the same bytes elsewhere: the same verdict
    run_scene(_scene(Path(copy)))
    assert len(children) == 1


@pytest.mark.parametrize("fraction", [0.2, 0.5, 0.8, 0.95])
def test_a_truncated_library_in_a_well_formed_zip_never_takes_the_process(crash_folder, tmp_path, fraction):
    """Cut short, a library fails to load (SIGBUS in the child, or dlopen refuses it) or, when
    only sections the loader does not map are lost, runs: never a dead master."""
    fmu = truncated(build_crash("nowhere", "segv", 2, crash_folder), fraction, tmp_path / "cut.fmu", 2)
    try:
        result = run_scene(_scene(fmu))
    except FeatherstarError as exc:
        line = _one_line(exc)
        assert "cut.fmu" in line or "block 'vdp'" in line, line
    else:
        assert result.time[-1] == pytest.approx(0.1)


def test_a_crashing_fmu_in_an_ssp_package_on_the_command_line(crash_folder, tmp_path, capsys):
    fmu = build_crash("instantiate", "segv", 3, crash_folder)
    package = tmp_path / "crash.ssp"
    with zipfile.ZipFile(package, "w") as z:
        z.write(fmu, "resources/vdp.fmu")
        z.writestr(SSD_NAME, SSD)
    assert main(["run", str(package), "-q", "--no-figure", "--set", "master.coupling=strong"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "SIGSEGV in fmi3InstantiateModelExchange" in err[0] and "vdp.fmu" in err[0], err


def test_the_command_exits_2_in_a_fresh_process(crash_folder, tmp_path):
    """The real thing: a `featherstar run` process, not pytest's, survives to say so."""
    fmu = build_crash("initialization", "abort", 2, crash_folder)
    scene = tmp_path / "crash.toml"
    scene.write_text(f'name = "crash"\nconnections = []\n[master]\ncoupling = "strong"\nt_end_s = 0.1\n'
                     f'[blocks.vdp]\nkind = "fmu"\nfmu = "{fmu}"\n[blocks.rec]\nkind = "recorder"\nsignals = ["vdp.x0"]\n')
    done = subprocess.run([sys.executable, "-m", "featherstar", "run", str(scene), "-q", "--no-figure"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "SIGABRT in fmi2ExitInitializationMode" in lines[0], lines


SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="crash"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription">
  <ssd:System name="root">
    <ssd:Connectors><ssd:Connector name="x0" kind="output"/></ssd:Connectors>
    <ssd:Elements>
      <ssd:Component name="vdp" source="resources/vdp.fmu"/>
    </ssd:Elements>
    <ssd:Connections><ssd:Connection startElement="vdp" startConnector="x0" endConnector="x0"/></ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="0.1"/>
</ssd:SystemStructureDescription>
"""


def test_a_probe_that_cannot_run_refuses_rather_than_trusts(crash_folder, monkeypatch):
    fmu = build_crash("nowhere", "segv", 2, crash_folder)
    monkeypatch.setattr(sys, "executable", "/bin/false")
    with pytest.raises(StepError, match="could not be probed"):
        run_scene(_scene(fmu))

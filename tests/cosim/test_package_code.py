"""A package is data: an SSP package whose featherstar annotation names Python code anywhere (a
block factory, a model function, a parameter, a setting, an override, a key) is refused with one
line naming the package, the place and the reference, before anything is imported, and leaves
nothing in the cache; featherstar's own block classes stay allowed; `allow_code` / --allow-code
lets a trusted package through. The packages are generated: hypothesis puts references into every
slot of a real exported package's annotation."""
from __future__ import annotations

import importlib
import json
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path
from typing import Any

import pytest
from conftest import OSCILLATOR, make_scene
from featherstar.cosim.errors import SceneError
from featherstar.cosim.scene.python_blocks import CODE_REFERENCE, featherstar_block_class
from featherstar.cosim.scenes import load_scene
from featherstar.cosim.ssp.export import export_ssp
from featherstar.cosim.ssp.read import NS, SSD_NAME
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_ssp import MIXED, OVERRIDES

from featherstar.app import main

SCENE_TAG = f"{{{NS['fs']}}}Scene"
FOREIGN = ["os:system", "subprocess:run", "builtins:eval", "toy_blocks:Poison", "toys:gain",
           "featherstar.__main__:main", "featherstar.app:main", "featherstar.cosim.ssp.export:export_ssp",
           "featherstar.cosim.scene.python_blocks:import_code", "featherstar.hil.blocks:Servo.__init__"]
OWN = ["featherstar.hil.blocks:Servo", "featherstar.hil.blocks:LoadCell", "featherstar.cosim.scene.blocks:Gain",
       "featherstar.optimizer.calibration.playback:RecordedRoot"]


@pytest.fixture(scope="module")
def package(tmp_path_factory) -> Path:
    return export_ssp(make_scene(OSCILLATOR, **MIXED), tmp_path_factory.mktemp("ssp") / "mixed.ssp", OVERRIDES)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """A fresh cache for the reads (the package's FMUs were built in the usual one)."""
    folder = tmp_path_factory.mktemp("cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("FEATHERSTAR_CACHE", str(folder))
        yield folder


def annotation(package: Path) -> dict[str, Any]:
    root = ET.fromstring(zipfile.ZipFile(package).read(SSD_NAME))
    return json.loads(root.find(f".//{SCENE_TAG}").text)


def with_annotation(package: Path, scene: dict[str, Any], out: Path) -> Path:
    for prefix, uri in NS.items():
        ET.register_namespace(prefix, uri)
    root = ET.fromstring(zipfile.ZipFile(package).read(SSD_NAME))
    root.find(f".//{SCENE_TAG}").text = json.dumps(scene)
    with zipfile.ZipFile(package) as original, zipfile.ZipFile(out, "w") as archive:
        for member in original.namelist():
            if member != SSD_NAME:
                archive.writestr(member, original.read(member))
        archive.writestr(SSD_NAME, ET.tostring(root, encoding="unicode"))
    return out


def slots(value: Any, path: tuple = ()) -> list[tuple]:
    """Every place a value sits in the annotation (and a new key of every object)."""
    out = [path] if path else []
    if isinstance(value, dict):
        out.append((*path, "+key"))
        for key, item in value.items():
            out.extend(slots(item, (*path, key)))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            out.extend(slots(item, (*path, index)))
    return out


def put(scene: dict[str, Any], path: tuple, ref: str, as_key: bool) -> dict[str, Any]:
    scene = json.loads(json.dumps(scene))
    *parents, last = path
    holder = scene
    for part in parents:
        holder = holder[part]
    if last == "+key":
        holder[ref if as_key else "extra_setting"] = "x" if as_key else ref
    elif as_key and isinstance(holder, dict):
        holder[ref] = holder.pop(last)
    else:
        holder[last] = ref
    return scene


references = st.one_of(st.sampled_from(FOREIGN), st.from_regex(CODE_REFERENCE, fullmatch=True))


@st.composite
def mutations(draw, base: dict[str, Any]) -> tuple[dict[str, Any], str, str, bool]:
    """(annotation with one reference put somewhere, the reference, the block it went into or '',
    whether it is only the text of a description)."""
    ref = draw(references)
    choice = draw(st.sampled_from(["slot", "python block", "model block"]))
    if choice == "python block":
        scene = json.loads(json.dumps(base))
        scene["blocks"]["intruder"] = {"kind": "python", "factory": ref, "parameters": {"t_bad": 0.5}}
        return scene, ref, "intruder", False
    if choice == "model block":
        scene = json.loads(json.dumps(base))
        scene["blocks"]["intruder"] = {"kind": "fmu", "model": ref, "options": {}}
        return scene, ref, "intruder", False
    path = draw(st.sampled_from(slots(base)))
    as_key = draw(st.booleans())
    block = path[1] if len(path) > 2 and path[0] == "blocks" and path[1] != "+key" else ""
    return put(base, path, ref, as_key), ref, block, path[-1] == "description" and not as_key


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_package_naming_code_anywhere_is_refused_before_any_import(package, cache, tmp_path, monkeypatch, data):
    scene, ref, block, text_only = data.draw(mutations(annotation(package)))
    if ref.strip() != ref or featherstar_block_class(ref):
        return   # not a reference as written, or one of featherstar's own blocks (the next test)
    bad = with_annotation(package, scene, tmp_path / "bad.ssp")
    if text_only:   # a description is shown, never imported
        load_scene(bad)
        return
    imported = []
    real = importlib.import_module
    monkeypatch.setattr(importlib, "import_module", lambda name, *a: imported.append(name) or real(name, *a))
    before = sorted((cache / "ssp").iterdir()) if (cache / "ssp").exists() else []
    with pytest.raises(SceneError) as refused:
        load_scene(bad)
    line = str(refused.value)
    assert "\n" not in line and f"SSP package '{bad}'" in line and f"'{ref}'" in line, line
    assert "--allow-code" in line
    if block:
        assert f"block '{block}'" in line, line
    assert all(name.startswith("featherstar.") for name in imported), imported
    assert sorted((cache / "ssp").iterdir()) == before   # nothing of a refused package is kept
    try:   # trusted: the reference is no longer the refusal (a kind may still refuse its value;
        load_scene(bad, allow_code=True)   # some kinds raise ValueError on a mistyped setting)
    except Exception as exc:
        assert "Python code" not in str(exc)


@pytest.mark.parametrize("ref", OWN)
def test_featherstars_own_block_classes_stay_allowed(package, cache, tmp_path, ref):
    scene = annotation(package)
    scene["blocks"]["device"] = {"kind": "python", "factory": ref, "parameters": {}}
    assert featherstar_block_class(ref)
    load_scene(with_annotation(package, scene, tmp_path / "own.ssp"))


@pytest.mark.parametrize("ref", FOREIGN)
def test_a_reference_that_is_not_a_featherstar_block_class_is_foreign(ref):
    assert not featherstar_block_class(ref)


def test_the_command_refuses_a_package_with_code_and_runs_it_with_allow_code(package, cache, tmp_path, capsys):
    scene = annotation(package)
    scene["blocks"]["scale"] = {"kind": "python", "factory": "toy_blocks:Integrator", "parameters": {"y0": 1.0}}
    bad = with_annotation(package, scene, tmp_path / "code.ssp")
    assert main(["run", str(bad), "-q", "--no-figure"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("featherstar: error:"), err
    assert f"SSP package '{bad}'" in err[0] and "block 'scale' factory names 'toy_blocks:Integrator'" in err[0], err
    out = tmp_path / "run"
    assert main(["run", str(bad), "-q", "--no-figure", "--allow-code", "--out", str(out),
                 "--set", "master.coupling=jacobi", "master.step_s=0.01"]) == 0
    assert "scale.y" in (out / "results.csv").read_text().splitlines()[0]

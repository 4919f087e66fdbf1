"""`featherstar scenes SCENE`: every key --set takes, listed from where it is interpreted; the
listing and --set agree both ways on every shipped scene."""
from __future__ import annotations

import math

import pytest

from featherstar.app import main
from featherstar.cosim.errors import SceneError
from featherstar.cosim.scene.graph import plan
from featherstar.cosim.scene.listing import scene_keys
from featherstar.cosim.scenes import list_scenes, load_scene

SCENES = [name for name, _ in list_scenes()]


def _settings(name: str, overrides=None):
    return scene_keys(plan(load_scene(name).with_overrides(overrides or {})))


@pytest.mark.parametrize("name", SCENES)
def test_every_listed_key_is_taken_by_set_at_its_listed_value(name):
    """Setting each listed key to the value listed plans the same scene (the list names real keys)."""
    settings = _settings(name)
    assert len({s.key for s in settings}) == len(settings)
    for s in settings:
        if s.value == "" or s.kind == "build option":
            continue
        value = repr(s.value) if isinstance(s.value, float) else str(s.value)
        plan(load_scene(name).with_overrides({s.key: value}))


@pytest.mark.parametrize("name", SCENES)
def test_every_model_parameter_and_option_is_listed(name):
    p = plan(load_scene(name))
    listed = {s.key for s in scene_keys(p)}
    for block, rb in p.blocks.items():
        if rb.model is not None:
            expected = {f"{block}.{q.name}" for q in rb.model.parameters} | {f"{block}.{o}" for o in rb.model.options}
            assert expected <= listed, sorted(expected - listed)


def test_a_listed_range_is_the_range_set_enforces():
    """A value just past a listed upper bound is refused (the range is the model's own check)."""
    checked = 0
    for s in _settings("testbed"):
        if not s.range.endswith("]") or s.kind != "parameter" or s.key.startswith(("master.", "metrics.")):
            continue
        upper = float(s.range.rstrip("]").split(",")[1])
        if not math.isfinite(upper):
            continue
        with pytest.raises(SceneError, match=s.key.split(".")[1]):
            plan(load_scene("testbed").with_overrides({s.key: repr(upper * 1.5 + 1)}))
        checked += 1
    assert checked > 10


def test_a_build_option_changes_which_parameters_are_listed():
    chordwise = {s.key for s in _settings("testbed")}
    spanwise = {s.key for s in _settings("testbed", {"feather.morphology": "spanwise"})}
    assert "feather.width_ratio" in chordwise - spanwise
    assert "feather.length_ratio" in spanwise - chordwise


def test_the_command_prints_keys_units_ranges_and_the_amplitude_meaning(capsys):
    assert main(["scenes", "testbed"]) == 0
    text = capsys.readouterr().out
    assert "master.rtol" in text and "feather.youngs_modulus_Pa" in text and "Pa" in text
    assert "controller.amplitude_deg" in text and "means +-30 deg" in text
    assert main(["scenes"]) == 0 and "testbed" in capsys.readouterr().out

from __future__ import annotations

import copy
from typing import Any

import pytest
from featherstar.cosim.scene.data import scene_from_dict

OSCILLATOR = {
    "name": "oscillator",
    "description": "two masses split across two blocks (force/displacement coupling)",
    "connections": [
        "a.position_m -> b.other_position_m",
        "a.velocity_m_s -> b.other_velocity_m_s",
        "b.force_N -> a.force_N",
    ],
    "master": {"coupling": "strong", "t_end_s": 4.0, "output_interval_s": 0.01, "rtol": 1e-10, "atol": 1e-12},
    "blocks": {
        "a": {"kind": "fmu", "model": "toys:oscillator_a"},
        "b": {"kind": "fmu", "model": "toys:oscillator_b"},
        "rec": {"kind": "recorder", "signals": ["a.position_m", "b.position_m", "b.force_N"]},
    },
}


def make_scene(base: dict[str, Any], **changes: Any):
    data = copy.deepcopy(base)
    for key, value in changes.items():
        if isinstance(value, dict) and isinstance(data.get(key), dict):
            data[key].update(value)
        else:
            data[key] = value
    return scene_from_dict(data)


@pytest.fixture
def oscillator():
    return make_scene(OSCILLATOR)


@pytest.fixture(scope="session")
def c_fmu(tmp_path_factory):
    """build("types", 3) -> path of a hand-written test FMU (tests/cosim/c_fmus.py), compiled once
    per session."""
    import shutil

    if shutil.which("gcc") is None:
        pytest.skip("gcc is needed to build the hand-written test FMUs")
    from c_fmus import build

    folder = tmp_path_factory.mktemp("c_fmus")
    return lambda name, version: build(name, version, folder)

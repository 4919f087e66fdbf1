"""The scene edge (issue 23): a scene file or a --set value either gives a scene the plan
accepts, or one SceneError naming the key; never another exception. Generated cases mutate the
shipped scenes' TOML (types replaced, values out of range, tables replaced by scalars, unknown
keys, non-UTF-8 bytes)."""
from __future__ import annotations

import json
import tomllib
from typing import Any

import pytest
from featherstar.cosim.errors import SceneError
from featherstar.cosim.scene.sections import MasterSpec, MetricsSpec
from featherstar.cosim.scene.settings import declared, listing
from featherstar.cosim.scenes import load_scene, shipped_scenes
from featherstar.cosim.swimmer.run import prepare
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from featherstar.terminal import one_line
from tomlgen import to_toml

SHIPPED = {name: tomllib.loads(path.read_text()) for name, path in sorted(shipped_scenes().items())}


def test_the_writer_round_trips_the_shipped_scenes():
    for data in SHIPPED.values():
        assert tomllib.loads(to_toml(data)) == data


# --- mutations ---------------------------------------------------------------------------------

def _paths(data: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key path of the scene (tables and leaves), and the index paths of arrays."""
    out = []
    if isinstance(data, dict):
        for k, v in data.items():
            out.append(prefix + (k,))
            out += _paths(v, prefix + (k,))
    elif isinstance(data, list):
        for i, v in enumerate(data[:3]):
            out.append(prefix + (i,))
            out += _paths(v, prefix + (i,))
    return out


toml_scalars = st.one_of(
    st.integers(-10**12, 10**12), st.floats(allow_nan=True, allow_infinity=True), st.booleans(),
    st.text(max_size=12), st.sampled_from(["strong", "jacobi", "stroke", "fmu", "feather.thrust_N", "x.y",
                                           "", "1e-9", "true", "1e400"]),
    st.sampled_from([0, -1, 1e-9, 1e-20, 1.0, 1e9, 3, 0.5]),
    st.dates(), st.times(),
)
toml_values = st.one_of(toml_scalars, st.lists(toml_scalars, max_size=3),
                        st.dictionaries(st.text(min_size=1, max_size=6), toml_scalars, max_size=2))


def _get(data: Any, path: tuple) -> Any:
    for p in path:
        data = data[p]
    return data


@st.composite
def mutated_scene(draw: Any) -> tuple[str, dict[str, Any], tuple, str]:
    name = draw(st.sampled_from(sorted(SHIPPED)))
    data = json.loads(json.dumps(SHIPPED[name]))
    path = draw(st.sampled_from(_paths(data)))
    parent, last = _get(data, path[:-1]), path[-1]
    how = draw(st.sampled_from(["replace", "replace", "replace", "delete", "unknown key"]))
    if how == "replace":
        parent[last] = draw(toml_values)
    elif how == "delete":
        del parent[last]
    else:
        target = _get(data, path) if isinstance(_get(data, path), dict) else parent
        if not isinstance(target, dict):
            return name, data, path, "none"
        last = draw(st.sampled_from(["rtoll", "tend_s", "periodes", "thrustt", "kindd", "zzz"]))
        target[last] = draw(toml_scalars)
        path = path + (last,) if target is not parent else path[:-1] + (last,)
    return name, data, path, how


def _plan_or_refusal(scene_source: Any, overrides: dict[str, str] | None = None) -> SceneError | None:
    """None when the scene passes every check before work; else the SceneError. Any other
    exception fails the test."""
    try:
        prepare(scene_source, overrides, strict_window=True)
    except SceneError as exc:
        return exc
    return None


#: Refusals of what a valid value implies elsewhere (a stroke so slow the run would not fit in
#: memory, a grid too coarse for it, an empty connection list): they name what to change instead.
CONSEQUENCES = ("memory is available", "leaves no whole period", "needs at least", "samples of master.",
                "is not connected (dangling)")


def _assert_one_line_naming(exc: SceneError, *names: str) -> None:
    line = one_line(exc)
    assert "\n" not in line and line
    assert any(str(n) in line for n in names), (names, line)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_scene())
def test_a_mutated_scene_file_loads_or_is_refused_naming_the_key(tmp_path_factory, case):
    name, data, path, how = case
    folder = tmp_path_factory.mktemp("scene")
    file = folder / f"{name}.toml"
    file.write_text(to_toml(data), encoding="utf-8")
    exc = _plan_or_refusal(str(file))
    if exc is None or how == "delete":   # a deleted key may fall back to its default, or leave
        return                           # a dangling input named by its port
    # a refusal names the file (once) and the key, the table or the block it concerns
    assert str(file) in one_line(exc)
    names = [str(p) for p in path if isinstance(p, str)]
    if path[0] == "connections":
        names.append("connection")
    _assert_one_line_naming(exc, *names, *CONSEQUENCES)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(sorted(SHIPPED)), st.binary(min_size=1, max_size=4).filter(lambda b: not _utf8(b)),
       st.floats(0, 1))
def test_a_scene_file_that_is_not_utf8_is_one_line(tmp_path_factory, name, junk, where):
    text = shipped_scenes()[name].read_bytes()
    at = int(where * len(text))
    file = tmp_path_factory.mktemp("scene") / f"{name}.toml"
    file.write_bytes(text[:at] + junk + text[at:])
    with pytest.raises(SceneError, match=r"not UTF-8 text \(byte 0x[0-9a-f]{2} at offset \d+\)") as info:
        load_scene(str(file))
    assert str(file) in str(info.value) and "\n" not in str(info.value)


def _utf8(b: bytes) -> bool:
    try:
        b.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


@pytest.mark.parametrize("text, key", [
    ("master = 3", "master"), ('blocks.feather = "x"', "feather"), ("connections = {}", "connections"),
    ('aliases = "x"', "aliases"), ("metrics = [1]", "metrics"), ("blocks = 3", "blocks"),
    ('name = 3', "name"),
])
def test_tables_replaced_by_scalars_are_refused(tmp_path, text, key):
    data = SHIPPED["testbed"]
    top, _, rest = text.partition(" = ")
    mutated = json.loads(json.dumps(data))
    value = tomllib.loads(f"v = {rest}")["v"]
    if "." in top:
        mutated["blocks"][top.split(".")[1]] = value
    else:
        mutated[top] = value
    file = tmp_path / "scene.toml"
    file.write_text(to_toml(mutated))
    exc = _plan_or_refusal(str(file))
    assert exc is not None
    _assert_one_line_naming(exc, key)


# --- --set values ------------------------------------------------------------------------------

SET_KEYS = ([f"master.{n}" for n, *_ in declared(MasterSpec)] + [f"metrics.{n}" for n, *_ in declared(MetricsSpec)]
            + ["controller.t_up_s", "controller.period_s", "controller.amplitude_deg", "feather.width_ratio",
               "feather.morphology", "feather.n_units", "tank.flow_speed_m_s", "loadcell.signals",
               "feather.options", "feather.parameters", "controller.sample_period_s", "nosuch.key"])
set_values = st.one_of(st.sampled_from(["x", "", "nan", "inf", "-1", "0", "1e-9", "1e9", "true", "3", "0.5",
                                        "[1]", "{a=1}", "1,2", "strong", "plain", "feather.thrust_N"]),
                       st.text(max_size=8), st.floats(allow_nan=True).map(repr))


@settings(max_examples=150, deadline=None)
@given(st.sampled_from(SET_KEYS), set_values)
def test_a_set_value_is_taken_or_refused_naming_the_key(key, value):
    exc = _plan_or_refusal("testbed", {key: value})
    if exc is not None:
        block, _, param = key.partition(".")
        _assert_one_line_naming(exc, key, param, *(() if block in ("master", "metrics") else (block,)),
                                *CONSEQUENCES)


def test_declared_schema_covers_every_key_and_lists_it():
    for cls, section in ((MasterSpec, "master"), (MetricsSpec, "metrics")):
        rows = listing(cls, section)
        names = [n for n, *_ in declared(cls)]
        assert len(rows) == len(names) and all(f"{section}.{n}" in r for n, r in zip(names, rows))
        for name, kind, default, spec in declared(cls):
            assert spec.meaning, name
            assert kind in (bool, int, float, str)
            assert not (kind in (int, float) and spec.lo is None and spec.hi is None), name


@pytest.mark.parametrize("override, expected", [
    ({"master.atol": "1"}, "master.atol = 1.0 must be a finite number in [1e-14, 0.0001]"),
    ({"master.rtol": "1e-15"}, "master.rtol = 1e-15 must be a finite number in [1e-12, 0.01]"),
    ({"metrics.period_s": "1e-9"}, "metrics.period_s = 1e-09 must be a finite number 0 (the scene's stroke period)"),
    ({"master.coupling": "jacobbi"}, "did you mean 'jacobi'?"),
    ({"master.rtoll": "1e-6"}, "master has no setting 'rtoll'; did you mean 'rtol'?"),
    ({"master.loop_max_iter": "2.5"}, "master.loop_max_iter = '2.5' is not a valid int"),
    ({"master.coupling": "3"}, "master.coupling = '3' is not one of strong"),
    ({"metrics.thrust": "thrust"}, "metrics.thrust = 'thrust' must name a recorded signal as 'block.port'"),
    ({"loadcell.signals": "3"}, "loadcell.signals"),
    ({"feather.options": "3"}, "feather.options = 3 must be a table"),
    ({"feathr.width_ratio": "5"}, "no block named 'feathr'; did you mean 'feather'?"),
])
def test_out_of_range_and_misspelt_settings_say_what_is_expected(override, expected):
    exc = _plan_or_refusal("testbed", override)
    assert exc is not None and expected in one_line(exc)

"""Register maps and plant-parameter files as hostile data (hypothesis): whatever the bytes,
loading either gives a valid object or a one-line HILConfigError / HILError naming the file,
never another exception; and `featherstar emulate` refuses them with exit 2."""
from __future__ import annotations

import json
import math
import tomllib
from importlib import resources
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from featherstar.app import main
from featherstar.hil.emulator import Emulator
from featherstar.hil.errors import HILConfigError, HILError
from featherstar.hil.plant import flat_plate_plant, read_plant_parameters
from featherstar.hil.registers import LoadCellMap, available_maps, load_map
from tomlgen import to_toml

SHIPPED = {name: (resources.files("featherstar.hil") / "maps" / f"{name}.toml").read_text("utf-8")
           for name in available_maps()}
SETTINGS = settings(max_examples=150, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])

scalars = st.one_of(st.integers(-2**40, 2**40), st.floats(allow_nan=True, allow_infinity=True),
                    st.booleans(), st.text(max_size=8), st.sampled_from(
                        ["float32", "int32", "CDAB", "deg", "kg", "holding", "input", "servo",
                         "loadcell", 0, 1, 65535, 65536, -1]))
values = st.one_of(scalars, st.lists(scalars, max_size=3))


@st.composite
def mutated_maps(draw) -> str:
    doc = tomllib.loads(SHIPPED[draw(st.sampled_from(sorted(SHIPPED)))])
    for _ in range(draw(st.integers(1, 3))):
        table = draw(st.sampled_from(sorted(doc)))
        keys = sorted(doc[table])
        action = draw(st.sampled_from(["set", "delete", "add", "drop-table"]))
        if action == "set" and keys:
            doc[table][draw(st.sampled_from(keys))] = draw(values)
        elif action == "delete" and keys:
            del doc[table][draw(st.sampled_from(keys))]
        elif action == "add":
            doc[table][draw(st.sampled_from(["adress", "bit", "scale", "lag_bit", "x"]))] = draw(values)
        elif action == "drop-table" and len(doc) > 1:
            del doc[table]
    return to_toml(doc)


def _loads_or_refuses(path: Path) -> None:
    try:
        parsed = load_map(path)
    except HILConfigError as exc:
        message = str(exc)
        assert "\n" not in message and str(path) in message
        return
    # A map that loads must be servable: the emulator lays out its registers from it.
    other = load_map("servo-default" if isinstance(parsed, LoadCellMap) else "loadcell-float32-abcd")
    lc, sv = (parsed, other) if isinstance(parsed, LoadCellMap) else (other, parsed)
    Emulator(lc, sv).units()


@SETTINGS
@given(text=mutated_maps())
def test_a_mutated_register_map_loads_or_is_refused_in_one_line(tmp_path, text):
    path = tmp_path / "map.toml"
    path.write_text(text, encoding="utf-8")
    _loads_or_refuses(path)


@SETTINGS
@given(name=st.sampled_from(sorted(SHIPPED)), at=st.integers(0, 10_000),
       junk=st.binary(min_size=1, max_size=8))
def test_a_register_map_with_arbitrary_bytes_loads_or_is_refused(tmp_path, name, at, junk):
    data = SHIPPED[name].encode()
    at %= len(data)
    path = tmp_path / "map.toml"
    path.write_bytes(data[:at] + junk + data[at:])
    _loads_or_refuses(path)


def test_a_map_that_is_not_utf8_is_named_as_such(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(SHIPPED["servo-default"].replace("deg", "\u00b0").encode("latin-1", "replace"))
    with pytest.raises(HILConfigError, match="not UTF-8"):
        load_map(path)


json_values = st.recursive(st.one_of(st.none(), st.booleans(), st.floats(), st.integers(),
                                     st.text(max_size=6)),
                           lambda inner: st.lists(inner, max_size=3)
                           | st.dictionaries(st.text(max_size=6), inner, max_size=3), max_leaves=8)


@SETTINGS
@given(doc=json_values, raw=st.none() | st.binary(max_size=40))
def test_a_plant_parameter_file_gives_finite_numbers_or_a_refusal(tmp_path, doc, raw):
    path = tmp_path / "plant.json"
    if raw is None:
        path.write_text(json.dumps(doc), encoding="utf-8")
    else:
        path.write_bytes(raw)
    try:
        parameters = read_plant_parameters(path)
        plant = flat_plate_plant(parameters)
    except HILError as exc:
        assert "\n" not in str(exc)
        return
    assert all(isinstance(v, float) and math.isfinite(v) for v in parameters.values())
    assert all(getattr(plant, k) == v for k, v in parameters.items())


@pytest.mark.parametrize("content", [b'{"c_n": true}', b'{"c_n": 1e999}', b'\xff\xfe{"c_n": 1}',
                                     b'[' * 100_000, b'{"c_nn": 1.2}'])
def test_emulate_refuses_a_bad_plant_parameter_file_with_exit_2(tmp_path, capsys, content):
    path = tmp_path / "plant.json"
    path.write_bytes(content)
    assert main(["emulate", "--plant", "flat-plate", "--port", "0",
                 "--plant-parameters", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("featherstar: error:")


@pytest.mark.parametrize("argv, expected", [
    (["--noise-N", "inf"], "--noise-N inf"),
    (["--noise-N", "nan"], "--noise-N nan"),
    (["--servo-map", "{map}"], "not UTF-8"),
])
def test_emulate_refuses_bad_options_with_exit_2(tmp_path, capsys, argv, expected):
    bad = tmp_path / "bad.toml"
    bad.write_bytes(b"[device]\nkind = \"servo\"\ndescription = \"\xb0\"\n")
    argv = [a.format(map=bad) for a in argv]
    assert main(["emulate", "--plant", "flat-plate", "--port", "0", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expected in err[0]


@pytest.mark.parametrize("feather, servo, named", [({"drag_coef": 1.5}, {}, "drag_coef"),
                                                   ({"length_ratio": 2.0}, {}, "length_ratio"),
                                                   ({}, {"kp_typo": 1.0}, "kp_typo")])
def test_a_hidden_fmu_coefficient_the_plant_would_ignore_is_refused(feather, servo, named):
    from featherstar.hil.fmu_plant import FmuPlant

    with pytest.raises(HILError, match=f"not applied.*'{named}'"):
        FmuPlant("chordwise", feather_parameters=feather, servo_parameters=servo)

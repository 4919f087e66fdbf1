"""Every FMI scalar type in a scene (hand-written FMUs, tests/cosim/c_fmus.py), FMI 2.0 and 3.0:
like-typed ports connect, safe conversions pass, unsafe ones are refused by name, values are
recorded in their own type, parameters of every type are set, and ports nobody connects never
block a scene. FMI 3.0 arrays connect whole or by element."""
from __future__ import annotations

import numpy as np
import pytest
from featherstar.cosim.errors import SceneError, StepError
from featherstar.cosim.fmi.fmi_types import conversion_problem
from featherstar.cosim.scene.data import scene_from_dict
from featherstar.cosim.scene.graph import plan
from featherstar.cosim.swimmer.run import run_scene

TYPES = {2: ["Float64", "Int32", "Boolean", "String", "Enumeration"],
         3: ["Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64",
             "Boolean", "String", "Binary", "Enumeration"]}
#: parameters of the first FMU (the second keeps its start values, see c_fmus.PARAM_START)
SET = {"Float32": 1.5, "Float64": -2.75, "Int8": -100, "UInt8": 200, "Int16": -30000, "UInt16": 60000,
       "Int32": -2_000_000_000, "UInt32": 4_000_000_000, "Int64": -(2 ** 53) + 3, "UInt64": 2 ** 53 - 7,
       "Boolean": True, "String": "hello, ", "Binary": "c0ffee", "Enumeration": 3}
START = {"Float32": 0.5, "Float64": 0.25, "Boolean": False, "String": "p:", "Binary": b"\x00"}


def _expected(t: str):
    a = SET[t]
    b = START.get(t, 1)
    if t == "Boolean":
        return a ^ b
    if t == "String":
        return b + a            # output = parameter + input
    if t == "Binary":
        return b + bytes.fromhex(a) + b"\x00"  # b's parameter + (a's parameter + a's input)
    if t == "Enumeration":
        return max(max(1, a), b)  # the larger of input (start 1) and parameter, twice
    return a + b


def _scene(fmu, types, coupling="jacobi", **extra):
    return scene_from_dict({
        "name": "types",
        "connections": [f"a.{t}_output -> b.{t}_input" for t in types],
        "master": {"coupling": coupling, "t_end_s": 0.02, "step_s": 0.01, "output_interval_s": 0.01},
        "blocks": {
            "a": {"kind": "fmu", "fmu": str(fmu), "parameters": {f"{t}_parameter": SET[t] for t in types}},
            "b": {"kind": "fmu", "fmu": str(fmu)},
            "rec": {"kind": "recorder", "signals": [f"b.{t}_output" for t in types]},
        },
        **extra,
    })


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("coupling", ["jacobi", "strong"])
def test_every_scalar_type_in_and_out(c_fmu, version, coupling):
    fmu = c_fmu("types", version)
    types = TYPES[version]
    result = run_scene(_scene(fmu, types, coupling))
    for t in types:
        values = result[f"b.{t}_output"]
        expected = _expected(t)
        assert len(values) == 3
        for v in values:
            if t == "Float32":
                assert v == pytest.approx(expected, rel=1e-7)
            else:
                assert v == expected, (t, v, expected)
        if t in ("String", "Binary"):
            assert values.dtype == object
        elif t == "Boolean":
            assert values.dtype == np.bool_
        elif t.startswith(("Int", "UInt")):
            assert values.dtype == np.dtype(t.lower())
        elif t == "Enumeration":  # FMI 2.0: Integer; FMI 3.0: Int64
            assert values.dtype == (np.int32 if version == 2 else np.int64)


def test_safe_conversions_connect_and_unsafe_ones_are_refused_by_name(c_fmu):
    fmu = c_fmu("types", 3)
    good = _scene(fmu, [], connections=["a.Int32_output -> b.Float64_input", "a.UInt8_output -> b.Int16_input",
                                        "a.Boolean_output -> b.Int8_input", "a.Float32_output -> b.Float64_vector_input[0]"],
                  blocks={"a": {"kind": "fmu", "fmu": str(fmu), "parameters": {"Int32_parameter": 7, "UInt8_parameter": 250,
                                                                                "Boolean_parameter": True}},
                          "b": {"kind": "fmu", "fmu": str(fmu)},
                          "rec": {"kind": "recorder", "signals": ["b.Float64_output", "b.Int16_output", "b.Int8_output",
                                                                  "b.Float64_vector_output"]}})
    result = run_scene(good)
    assert result["b.Float64_output"][-1] == 7 + 0.25          # Int32 7 -> Float64, + b's 0.25
    assert result["b.Int16_output"][-1] == 250 + 1             # UInt8 250 -> Int16, + 1
    assert result["b.Int8_output"][-1] == 1 + 1                # Boolean (False xor True) -> Int8, + 1
    assert result["b.Float64_vector_output[0]"][-1] == 2 * 0.5  # Float32 0.5 -> an array element
    bad = _scene(fmu, [], connections=["a.Float64_output -> b.Int32_input", "a.Int64_output -> b.Float64_input",
                                       "a.Int16_output -> b.UInt16_input", "a.Float64_output -> b.Float32_input",
                                       "a.String_output -> b.Binary_input", "a.Int8_output -> b.Boolean_input"])
    with pytest.raises(SceneError) as err:
        plan(bad)
    text = str(err.value)
    for conn in ["a.Float64_output -> b.Int32_input", "a.Int64_output -> b.Float64_input",
                 "a.Int16_output -> b.UInt16_input", "a.Float64_output -> b.Float32_input",
                 "a.String_output -> b.Binary_input", "a.Int8_output -> b.Boolean_input"]:
        assert f"type mismatch on '{conn}'" in text


def test_conversion_rules():
    assert conversion_problem("Int32", "Float64") is None
    assert conversion_problem("UInt32", "Int64") is None
    assert conversion_problem("Int16", "Float32") is None
    assert "round" in conversion_problem("Int32", "Float32")
    assert "round" in conversion_problem("UInt64", "Float64")
    assert "wrap" in conversion_problem("Int8", "UInt64")
    assert "truncate" in conversion_problem("Float32", "Int64")


def test_an_integer_beyond_the_exact_float64_range_stops_the_run_by_name(c_fmu):
    fmu = c_fmu("types", 3)
    scene = _scene(fmu, ["UInt64"]).with_overrides({"a.UInt64_parameter": 2 ** 60})
    with pytest.raises(StepError, match=r"block 'a'.*output UInt64_output: UInt64 value 1152921504606846976 is beyond 2\*\*53"):
        run_scene(scene)


def test_parameters_are_checked_against_their_type(c_fmu):
    fmu = c_fmu("types", 3)
    for key, value, words in [("Int8_parameter", 300, "outside Int8"), ("Int32_parameter", 1.5, "not an integer"),
                              ("Boolean_parameter", 2, "not a Boolean"), ("Float64_parameter", "x", "not a number"),
                              ("Binary_parameter", "zz", "not hexadecimal")]:
        with pytest.raises(SceneError, match=words):
            plan(_scene(fmu, []).with_overrides({f"a.{key}": value}))


def test_ports_nobody_connects_never_block_a_scene(c_fmu):
    """Only one Float64 port of an FMU full of other types is used; its unconnected inputs keep
    their start values and its unused outputs are never read."""
    fmu = c_fmu("types", 3)
    scene = scene_from_dict({
        "name": "one-port", "connections": [],
        "master": {"coupling": "strong", "t_end_s": 0.01, "output_interval_s": 0.01},
        "blocks": {"a": {"kind": "fmu", "fmu": str(fmu)}, "rec": {"kind": "recorder", "signals": ["a.Float64_output"]}},
    })
    p = plan(scene)
    assert any("held at the FMU's start values" in n for n in p.notes)
    assert list(p.blocks["a"].fmu_info.outputs) == ["Float64_output"]
    assert run_scene(scene)["a.Float64_output"][-1] == 0.25


@pytest.mark.parametrize("coupling", ["strong", "gauss-seidel"])
def test_arrays_connect_whole_and_by_element(c_fmu, coupling):
    fmu = c_fmu("types", 3)
    scene = scene_from_dict({
        "name": "arrays",
        "connections": ["a.Float64_vector_output -> b.Float64_vector_input",
                        "b.Float64_vector_output[2] -> c.Float64_input",
                        "src.value -> a.Float64_vector_input[1]"],
        "master": {"coupling": coupling, "t_end_s": 0.02, "step_s": 0.01, "output_interval_s": 0.01},
        "blocks": {
            "src": {"kind": "constant", "outputs": {"value": {"value": 3.0, "unit": ""}}},
            "a": {"kind": "fmu", "fmu": str(fmu)}, "b": {"kind": "fmu", "fmu": str(fmu)},
            "c": {"kind": "fmu", "fmu": str(fmu)},
            "rec": {"kind": "recorder", "signals": ["b.Float64_vector_output", "c.Float64_output"]},
        },
    })
    result = run_scene(scene)
    # a: [0, 3, 0] -> [0, 6, 0]; b: -> [0, 12, 0]; c = b[2] + 0.25
    assert [result[f"b.Float64_vector_output[{i}]"][-1] for i in range(3)] == [0.0, 12.0, 0.0]
    assert result["c.Float64_output"][-1] == 0.25
    bad = scene_from_dict({**scene.to_dict(), "connections": ["a.Float64_vector_output -> b.Float64_input"]})
    with pytest.raises(SceneError, match="is an array of 3 but b.Float64_input is a scalar"):
        plan(bad)


def test_results_csv_writes_every_type_in_full(c_fmu, tmp_path):
    import csv

    from featherstar.cosim.swimmer.report import write_outputs

    fmu = c_fmu("types", 3)
    types = ["UInt64", "Int64", "Boolean", "String", "Binary", "Float64"]
    result = run_scene(_scene(fmu, types))
    paths = write_outputs(result, tmp_path, figure=False)
    rows = list(csv.reader(paths["results"].open()))
    header, last = rows[0], rows[-1]
    row = dict(zip([h.split(" [")[0] for h in header], last))
    assert int(row["b.UInt64_output"]) == 2 ** 53 - 7 + 1       # all 16 digits, not %.10g
    assert int(row["b.Int64_output"]) == -(2 ** 53) + 3 + 1
    assert row["b.Boolean_output"] == "1" and row["b.String_output"] == "p:hello, "
    assert row["b.Binary_output"] == "00c0ffee00" and float(row["b.Float64_output"]) == -2.75 + 0.25


def test_the_interface_key_is_checked(c_fmu):
    vdp = c_fmu("vdp", 3)
    base = {"name": "iface", "connections": [], "master": {"coupling": "jacobi", "t_end_s": 0.1, "step_s": 0.01},
            "blocks": {"v": {"kind": "fmu", "fmu": str(vdp)}, "rec": {"kind": "recorder", "signals": ["v.x0"]}}}
    for value, words in [("cs", "has no Co-Simulation interface"), ("both", "use \"me\"")]:
        data = {**base, "blocks": {**base["blocks"], "v": {"kind": "fmu", "fmu": str(vdp), "interface": value}}}
        with pytest.raises(SceneError, match=words):
            plan(scene_from_dict(data))
    events = c_fmu("events", 2)
    strong_cs = {**base, "master": {"coupling": "strong", "t_end_s": 0.1},
                 "blocks": {"v": {"kind": "fmu", "fmu": str(events), "interface": "cs"},
                            "rec": {"kind": "recorder", "signals": ["v.x"]}}}
    with pytest.raises(SceneError, match="co-simulation-only FMU"):
        plan(scene_from_dict(strong_cs))

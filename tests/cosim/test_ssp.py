"""SSP 1.0 packages: a scene exported and run back gives identical results (the testbed too, on
FMI 3.0 and on FMI 2.0 FMUs); a hand-written package with system-level .ssv bindings and system
outputs runs; what featherstar cannot map is refused naming the element."""
from __future__ import annotations

import html
import json
import re
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from conftest import OSCILLATOR, make_scene
from featherstar.cosim.errors import SceneError
from featherstar.cosim.scene.graph import plan
from featherstar.cosim.scenes import load_scene
from featherstar.fmu_src.errors import ModelError
from featherstar.cosim.ssp.export import export_ssp
from featherstar.cosim.ssp.read import NS, SSD_NAME
from featherstar.cosim.swimmer.run import run_scene
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from featherstar.app import main

# The oscillator pair plus an FMU driven by a featherstar constant (through a system input
# connector) and driving a featherstar gain (through a system output connector).
MIXED = dict(
    connections=[*OSCILLATOR["connections"], "source.u -> g.u", "g.y -> scale.u"],
    blocks={
        "g": {"kind": "fmu", "model": "toys:gain", "parameters": {"gain": 2.0}},
        "source": {"kind": "constant", "outputs": {"u": {"value": 1.0, "unit": "1"}}},
        "scale": {"kind": "gain", "gain": -1.0},
        "rec": {"kind": "recorder", "signals": ["a.position_m", "b.force_N", "g.y", "scale.y"]},
    },
    master={"t_end_s": 2.0},
)
OVERRIDES = {"b.coupling_stiffness_N_m": 50, "source.u": 3.0, "g.offset": -0.5}


@pytest.fixture(scope="module")
def mixed_ssp(tmp_path_factory) -> Path:
    return export_ssp(make_scene(OSCILLATOR, **MIXED), tmp_path_factory.mktemp("ssp") / "mixed.ssp", OVERRIDES,
                      system_outputs=True)


def assert_identical(a, b) -> None:
    assert np.array_equal(a.time, b.time)
    assert set(a.signals) == set(b.signals)
    for name in a.signals:
        assert np.array_equal(a[name], b[name]), name


def assert_same_scene(back, original) -> None:
    """The scene read back from a package is the one exported: its featherstar blocks (stand-ins
    are the blocks again, not their FMUs), connections and settings; FMU blocks are FMU files."""
    a, b = back.to_dict(), original.to_dict()
    assert sorted(a["connections"]) == sorted(b["connections"])
    for key in ("master", "metrics", "aliases", "units"):
        assert a.get(key) == b.get(key), key
    assert set(a["blocks"]) == set(b["blocks"])
    for name, table in b["blocks"].items():
        if table["kind"] != "fmu":
            assert a["blocks"][name] == table, name


def test_exported_package_is_standard_ssp_and_runs_back_identically(mixed_ssp):
    archive = zipfile.ZipFile(mixed_ssp)
    assert sorted(archive.namelist()) == [SSD_NAME, *(f"resources/{n}.fmu" for n in ("a", "b", "g", "source"))]
    ssd = archive.read(SSD_NAME).decode()
    assert f'xmlns:ssd="{NS["ssd"]}"' in ssd and 'type="application/x-fmu-sharedlibrary"' in ssd
    # the constant that drives an FMU input is an FMU of its own, set by the override
    assert '<ssd:Connection startElement="source" startConnector="u" endElement="g" endConnector="u" />' in ssd
    assert re.search(r'<ssv:Parameter name="u_value">\s*<ssv:Real value="3.0" />', ssd)
    assert '<ssd:Connection startElement="g" startConnector="y" endConnector="scale.u" />' in ssd  # -> a gain
    # recorded signals of components are system outputs
    assert '<ssd:Connection startElement="a" startConnector="position_m" endConnector="a.position_m" />' in ssd
    assert '<ssd:DefaultExperiment startTime="0.0" stopTime="2.0" />' in ssd
    assert re.search(r'<ssv:Parameter name="coupling_stiffness_N_m">\s*<ssv:Real value="50.0" />', ssd)
    assert_same_scene(load_scene(mixed_ssp), make_scene(OSCILLATOR, **MIXED).with_overrides(OVERRIDES))
    for name in ("a", "b", "g", "source"):
        archive.extract(f"resources/{name}.fmu", mixed_ssp.parent)
        assert validate_fmu(str(mixed_ssp.parent / "resources" / f"{name}.fmu")) == []

    direct = run_scene(make_scene(OSCILLATOR, **MIXED), OVERRIDES)
    back = run_scene(mixed_ssp)
    assert_identical(direct, back)
    assert back["scale.y"][-1] == -(2.0 * 3.0 - 0.5)
    # Overrides apply to a package as to a scene.
    assert run_scene(mixed_ssp, {"source.u": 1.0})["g.y"][-1] == 2.0 * 1.0 - 0.5


def test_testbed_round_trip_on_fmi3_and_fmi2(tmp_path):
    short = {"feather.morphology": "plain", "master.periods": 1, "metrics.settle_periods": 0}
    direct = run_scene("testbed", short)
    for fmi_version, system_outputs in ((3, False), (2, False), (3, True)):
        package = export_ssp(load_scene("testbed"), tmp_path / f"testbed-fmi{fmi_version}-{system_outputs}.ssp", short,
                             fmi_version=fmi_version, system_outputs=system_outputs)
        scene = load_scene(package)
        versions = {read_model_description(scene.block(b).settings["fmu"]).fmiVersion for b in ("servo", "feather")}
        assert versions == {f"{fmi_version}.0"}
        # FMUs only for other tools: the stroke and the still water are components too; the run
        # length, given in periods, is periods x period there and stays `periods` here
        ssd = zipfile.ZipFile(package).read(SSD_NAME).decode()
        assert '<ssd:DefaultExperiment startTime="0.0" stopTime="1.5" />' in ssd
        assert 'endElement=' in ssd and "startConnector=\"controller.angle_rad\"" not in ssd
        # the recorded signals as system outputs, the stroke's too (its own connector, not a connection)
        assert ('<ssd:Connection startElement="controller" startConnector="angle_rad" '
                'endConnector="controller.angle_rad" />' in ssd) == system_outputs
        assert all(f'<ssd:Component name="{n}"' in ssd for n in ("controller", "tank", "servo", "feather"))
        assert scene.master.periods == 1 and scene.master.t_end_s == 0.0
        # connector units, defined by their SI base units
        assert ssd.count('<ssc:Real unit="N.m" />') == 2   # the feather's torque and the servo's load
        assert re.search(r'<ssc:Unit name="N.m">\s*<ssc:BaseUnit kg="1" m="2" s="-2" />', ssd)
        assert_same_scene(scene, load_scene("testbed").with_overrides(short))
        back = run_scene(package)
        if fmi_version == 3:
            assert_identical(direct, back)
        else:  # the same shell behind the FMI 2.0 adapter: the same numbers
            assert np.array_equal(direct.time, back.time)
            for name in direct.signals:
                assert np.max(np.abs(direct[name] - back[name])) <= 1e-10, name
        assert back.summary["thrust_ratio"] == direct.summary["thrust_ratio"]


def test_a_waived_connection_is_exported_without_units_and_reads_back_waived(tmp_path):
    """The waiver says the numbers agree although the units differ: its two connectors carry no
    unit, else an SSP tool would convert; the waiver itself travels in the annotation."""
    blocks = {**MIXED["blocks"], "source": {"kind": "constant", "outputs": {"u": {"value": 1.0, "unit": "m"}}}}
    scene = make_scene(OSCILLATOR, **dict(MIXED, blocks=blocks, units={"waive": ["source.u -> g.u"]}))
    package = export_ssp(scene, tmp_path / "waived.ssp", OVERRIDES)
    root = ET.fromstring(zipfile.ZipFile(package).read(SSD_NAME))
    declared = {(c.get("name"), k.get("name")): k[0].get("unit")
                for c in root.iterfind(".//ssd:Component", NS) for k in c.iterfind("ssd:Connectors/ssd:Connector", NS)}
    assert declared[("source", "u")] is None and declared[("g", "u")] is None
    assert declared[("a", "position_m")] == "m" and declared[("b", "force_N")] == "N"
    back = load_scene(package)
    assert [str(c) for c in back.unit_waivers] == ["source.u -> g.u"]
    assert_identical(run_scene(package), run_scene(scene, OVERRIDES))


FOREIGN_SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="foreign"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssd:System name="root">
    <ssd:Connectors>
      <ssd:Connector name="force_out" kind="output"><ssc:Real/></ssd:Connector>
    </ssd:Connectors>
    <ssd:ParameterBindings>
      <ssd:ParameterBinding type="application/x-ssp-parameter-set" source="resources/params.ssv"/>
    </ssd:ParameterBindings>
    <ssd:Elements>
      <ssd:Component name="a" source="resources/a.fmu" implementation="ModelExchange"/>
      <ssd:Component name="b" type="application/x-fmu-sharedlibrary" source="./resources/b.fmu"/>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="a" startConnector="position_m" endElement="b" endConnector="other_position_m"/>
      <ssd:Connection startElement="a" startConnector="velocity_m_s" endElement="b" endConnector="other_velocity_m_s"/>
      <ssd:Connection startElement="b" startConnector="force_N" endElement="a" endConnector="force_N">
        <ssd:ConnectionGeometry pointsX="1" pointsY="2"/>
      </ssd:Connection>
      <ssd:Connection startElement="b" startConnector="force_N" endConnector="force_out"/>
    </ssd:Connections>
    <ssd:Annotations>
      <ssc:Annotation type="org.openmodelica"><x/></ssc:Annotation>
    </ssd:Annotations>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="2.5"/>
</ssd:SystemStructureDescription>
"""
FOREIGN_SSV = """<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet version="1.0" name="p" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssv:Parameters>
    <ssv:Parameter name="b.coupling_stiffness_N_m"><ssv:Real value="50"/></ssv:Parameter>
    <ssv:Parameter name="a.mass_kg"><ssv:Integer value="2"/></ssv:Parameter>
  </ssv:Parameters>
</ssv:ParameterSet>
"""


def write_package(path: Path, ssd: str, source: Path, extra: dict[str, str] | None = None) -> Path:
    """A package with `ssd` as its SystemStructure.ssd and the FMUs of the package `source`."""
    with zipfile.ZipFile(source) as original, zipfile.ZipFile(path, "w") as archive:
        for member in original.namelist():
            if member.endswith(".fmu"):
                archive.writestr(member, original.read(member))
        archive.writestr(SSD_NAME, ssd)
        for name, text in (extra or {}).items():
            archive.writestr(name, text)
    return path


def test_foreign_package_with_ssv_file_and_system_output_runs(mixed_ssp, tmp_path):
    package = write_package(tmp_path / "foreign.ssp", FOREIGN_SSD, mixed_ssp, {"resources/params.ssv": FOREIGN_SSV})
    # A package without featherstar's annotation runs on the default master settings.
    master = {key: OSCILLATOR["master"][key] for key in ("rtol", "atol", "output_interval_s")}
    result = run_scene(package, {f"master.{key}": value for key, value in master.items()})
    assert result.time[-1] == pytest.approx(2.5)
    assert list(result.signals) == ["b.force_N"]  # the system output, recorded
    reference = run_scene(make_scene(OSCILLATOR, master={"t_end_s": 2.5}),
                          {"b.coupling_stiffness_N_m": 50, "a.mass_kg": 2})
    assert np.array_equal(result.time, reference.time)
    assert np.array_equal(result["b.force_N"], reference["b.force_N"])


def test_a_foreign_package_without_system_outputs_records_every_components_outputs(mixed_ssp, tmp_path):
    """Nothing requested (no system output, recorder, metrics or --record): every output of every
    component is recorded, and the run says so, rather than pruning the whole system away."""
    ssd = FOREIGN_SSD.replace('<ssd:Connection startElement="b" startConnector="force_N" endConnector="force_out"/>', "")
    ssd = ssd.replace('<ssd:Connector name="force_out" kind="output"><ssc:Real/></ssd:Connector>', "")
    package = write_package(tmp_path / "silent.ssp", ssd, mixed_ssp, {"resources/params.ssv": FOREIGN_SSV})
    master = {f"master.{key}": OSCILLATOR["master"][key] for key in ("rtol", "atol", "output_interval_s")}
    result = run_scene(package, master)
    scene = load_scene(package)
    outputs = [f"{block}.{port}" for block in ("a", "b")
               for port in read_model_description(scene.block(block).settings["fmu"]).modelVariables
               for port in ([port.name] if port.causality == "output" else [])]
    assert sorted(result.signals) == sorted(outputs) and "b.force_N" in outputs
    assert sorted(result.info["instantiated"]) == ["a", "b"] and not result.info["pruned"]
    assert any(note.startswith(f"no signals requested (no recorder, metrics or --record): recording every output "
                               f"of every block ({len(outputs)} signals)") for note in result.info["notes"])
    reference = run_scene(make_scene(OSCILLATOR, master={"t_end_s": 2.5}), {"b.coupling_stiffness_N_m": 50, "a.mass_kg": 2})
    assert np.array_equal(result["b.force_N"], reference["b.force_N"])
    # --record still records only what it names
    assert list(run_scene(package, master, outputs=["a.position_m"]).signals) == ["a.position_m"]


def _with_connector_units(mixed_ssp: Path, path: Path, units: dict[tuple[str, str], str], transform: str = "") -> Path:
    """The package with units on component connectors {(component, connector): unit} and, with
    `transform`, that child on the connection a.position_m -> b.other_position_m."""
    root = ET.fromstring(zipfile.ZipFile(mixed_ssp).read(SSD_NAME))
    for component in root.iterfind(".//ssd:Component", NS):
        for connector in component.iterfind("ssd:Connectors/ssd:Connector", NS):
            unit = units.get((component.get("name"), connector.get("name")))
            if unit:
                connector[0].set("unit", unit)
    for connection in root.iterfind(".//ssd:Connection", NS):
        if transform and (connection.get("startElement"), connection.get("endConnector")) == ("a", "other_position_m"):
            connection.append(ET.fromstring(transform))
    return write_package(path, ET.tostring(root, encoding="unicode"), mixed_ssp)


def test_a_linear_transformation_between_components_is_a_gain_block(mixed_ssp, tmp_path):
    """y = factor x + offset on a.position_m -> b.other_position_m runs as a featherstar gain
    between them: the same numbers as the scene with that gain written by hand."""
    transform = f'<ssc:LinearTransformation xmlns:ssc="{NS["ssc"]}" factor="0.5" offset="0.01"/>'
    package = _with_connector_units(mixed_ssp, tmp_path / "linear.ssp", {}, transform)
    scene = load_scene(package)
    assert scene.block("transform_0").settings.to_plain() == {"gain": 0.5, "offset": 0.01, "unit_in": "", "unit_out": ""}
    by_hand = dict(MIXED, connections=[c for c in MIXED["connections"] if c != "a.position_m -> b.other_position_m"]
                   + ["a.position_m -> transform_0.u", "transform_0.y -> b.other_position_m"],
                   blocks={**MIXED["blocks"], "transform_0": {"kind": "gain", "gain": 0.5, "offset": 0.01,
                                                             "unit_in": "", "unit_out": ""}})
    back = run_scene(package)
    assert_identical(back, run_scene(make_scene(OSCILLATOR, **by_hand), OVERRIDES))
    assert any("units not checked" in note and "transform_0.y -> b.other_position_m" in note
               for note in back.info["notes"])


def test_a_gain_between_components_is_exported_as_a_linear_transformation(tmp_path):
    """Other tools see a.position_m -> b.other_position_m with y = 0.5 x + 0.01 (no system
    connector, so the package stays FMUs only); featherstar reads back its gain block."""
    by_hand = dict(MIXED, connections=[c for c in MIXED["connections"] if c != "a.position_m -> b.other_position_m"]
                   + ["a.position_m -> half.u", "half.y -> b.other_position_m"],
                   blocks={**MIXED["blocks"], "half": {"kind": "gain", "gain": 0.5, "offset": 0.01,
                                                       "unit_in": "m", "unit_out": "m"}})
    scene = make_scene(OSCILLATOR, **by_hand)
    package = export_ssp(scene, tmp_path / "gain.ssp", OVERRIDES)
    ssd = zipfile.ZipFile(package).read(SSD_NAME).decode()
    assert re.search(r'<ssd:Connection startElement="a" startConnector="position_m" endElement="b" '
                     r'endConnector="other_position_m">\s*<ssc:LinearTransformation factor="0.5" offset="0.01" />', ssd)
    assert "half.u" not in ssd.split("<ssd:Annotations>")[0]
    back = load_scene(package)
    assert_same_scene(back, scene.with_overrides(OVERRIDES))
    assert_identical(run_scene(package), run_scene(scene, OVERRIDES))


def test_connectors_with_different_units_are_refused_and_equal_ones_accepted(mixed_ssp, tmp_path):
    same = _with_connector_units(mixed_ssp, tmp_path / "same.ssp", {("a", "position_m"): "m", ("b", "other_position_m"): "m"})
    load_scene(same)
    differ = _with_connector_units(mixed_ssp, tmp_path / "differ.ssp",
                                   {("a", "position_m"): "m", ("b", "other_position_m"): "mm"})
    with pytest.raises(SceneError, match=r"ssd:Connection a.position_m -> b.other_position_m: its connectors' "
                                         r"units differ \('m' -> 'mm'\); SSP tools convert"):
        load_scene(differ)


def mutated(mixed_ssp: Path, tmp_path: Path, old: str, new: str, count: int = 1) -> Path:
    ssd = zipfile.ZipFile(mixed_ssp).read(SSD_NAME).decode()
    assert old in ssd, old
    return write_package(tmp_path / "bad.ssp", ssd.replace(old, new, count), mixed_ssp)


@pytest.mark.parametrize("old, new, message", [
    ('<ssd:Connection startElement="a" startConnector="position_m" endElement="b" endConnector="other_position_m" />',
     '<ssd:Connection startElement="a" startConnector="position_m" endElement="b" endConnector="other_position_m">'
     '<ssc:BooleanMappingTransformation/></ssd:Connection>',
     "ssc:BooleanMappingTransformation on the ssd:Connection a.position_m -> b.other_position_m: featherstar maps "
     "only ssc:LinearTransformation"),
    ('<ssd:Connection startElement="g" startConnector="y" endConnector="scale.u" />',
     '<ssd:Connection startElement="g" startConnector="y" endConnector="scale.u"><ssc:LinearTransformation/>'
     '</ssd:Connection>',
     "ssc:LinearTransformation on the ssd:Connection g.y -> scale.u: featherstar maps only "
     "ssc:LinearTransformation (transformations between components only)"),
    ('<ssd:Connection startElement="a" startConnector="position_m" endElement="b" endConnector="other_position_m" />',
     '<ssd:Connection startElement="a" startConnector="position_m" endElement="b" endConnector="other_position_m">'
     '<ssc:LinearTransformation factor="inf"/></ssd:Connection>',
     "ssc:LinearTransformation on the ssd:Connection a.position_m -> b.other_position_m: factor = inf"),
    ('endElement="b" endConnector="other_velocity_m_s"', 'endElement="nobody" endConnector="other_velocity_m_s"',
     "ssd:Connection a.velocity_m_s -> nobody.other_velocity_m_s names element 'nobody', which is not a component"),
    ('endElement="b" endConnector="other_velocity_m_s"', 'endElement="b"',
     "ssd:Connection a.velocity_m_s -> b needs a startConnector and an endConnector"),
    ("<ssd:Elements>", '<ssd:Elements><ssd:System name="inner"/>',
     "ssd:System 'inner': featherstar maps a flat system of FMU components only"),
    ('type="application/x-fmu-sharedlibrary" source="resources/g.fmu"',
     'type="application/x-ssp-package" source="resources/g.fmu"',
     "ssd:Component 'g' has type 'application/x-ssp-package'"),
    ('source="resources/g.fmu"', 'source="resources/missing.fmu"',
     "ssd:Component 'g' source 'resources/missing.fmu' is not in the package"),
    ('<ssv:Real value="50.0" />', '<ssv:Boolean value="true" />',
     "ssv:Parameter 'coupling_stiffness_N_m' in the ssd:ParameterBinding of ssd:Component 'b' is ssv:Boolean"),
    ('<ssv:Real value="50.0" />', '<ssv:Real value="fifty" />',
     "ssv:Parameter 'coupling_stiffness_N_m' in the ssd:ParameterBinding of ssd:Component 'b' value = 'fifty' is not a number"),
    ('<ssd:ParameterValues>', '<ssd:ParameterMapping/><ssd:ParameterValues>',
     "ssd:ParameterMapping in the ssd:ParameterBinding of ssd:Component 'a'"),
    ('<fs:Scene format="json">{', '<fs:Scene format="json">{{',
     "ssc:Annotation 'org.featherstar.scene': fs:Scene is not valid JSON"),
    ('endConnector="scale.u"', 'endConnector="elsewhere.u"',
     "ssd:Connection g.y -> elsewhere.u: the system has no output connector 'elsewhere.u'"),
    ('<ssd:DefaultExperiment startTime="0.0"', '<ssd:DefaultExperiment startTime="1.0"',
     "ssd:DefaultExperiment startTime = 1.0: featherstar runs start at t = 0"),
    ('"stand_ins": [\n  "source"\n ]', '"stand_ins": [\n  "nobody"\n ]',
     "stand-in 'nobody' is no ssd:Component of the system"),
    ('"stand_ins": [\n  "source"\n ]', '"stand_ins": 5',
     "ssc:Annotation 'org.featherstar.scene': 'stand_ins' must be a JSON array, not 5"),
    ('"blocks": {', '"blocks": {"x": 3, ',
     "ssc:Annotation 'org.featherstar.scene': block 'x' must be a JSON object"),
    ('"connections": [', '"connections": 7, "unused": [',
     "ssc:Annotation 'org.featherstar.scene': 'connections' must be a JSON array, not 7"),
    ('"kind": "gain"', '"kind": "python", "factory": "os:system"',
     "block 'scale' factory names 'os:system': Python code, which a package may not run"),
    ('"transformed": []', '"transformed": [1]',
     "ssc:Annotation 'org.featherstar.scene': 'transformed' must be a list of strings, not [1]"),
    ("<ssd:Elements>", "<ssd:SignalDictionaries/><ssd:Elements>",
     "ssd:SignalDictionaries in ssd:System 'oscillator': featherstar cannot map it"),
])
def test_malformed_package_is_refused_naming_the_element(mixed_ssp, tmp_path, old, new, message):
    with pytest.raises(SceneError) as refused:
        load_scene(mutated(mixed_ssp, tmp_path, old, new))
    assert message in str(refused.value)


JSON = st.recursive(st.none() | st.booleans() | st.integers(-3, 3) | st.floats(allow_nan=False) | st.text(max_size=4),
                    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner, max_size=3),
                    max_leaves=6)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=st.sampled_from(["blocks", "connections", "overrides", "aliases", "master", "metrics", "stand_ins",
                            "transformed", "units", "description"]), value=JSON)
def test_any_annotation_content_is_refused_or_read_never_a_crash(mixed_ssp, tmp_path_factory, key, value):
    """The annotation is data from elsewhere: whatever JSON stands under any of its keys, reading
    and planning the package give a plan or a SceneError (ModelError for a model's values)."""
    ssd = zipfile.ZipFile(mixed_ssp).read(SSD_NAME).decode()
    start = ssd.index('<fs:Scene format="json">') + len('<fs:Scene format="json">')
    end = ssd.index("</fs:Scene>")
    annotation = json.loads(html.unescape(ssd[start:end]))
    annotation[key] = value
    text = html.escape(json.dumps(annotation), quote=False)
    folder = tmp_path_factory.mktemp("fuzz")
    package = write_package(folder / "fuzz.ssp", ssd[:start] + text + ssd[end:], mixed_ssp)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("FEATHERSTAR_CACHE", str(folder / "cache"))   # unpacked here, not in the user's cache
        try:
            plan(load_scene(package))
        except (SceneError, ModelError):
            pass


def test_broken_archives_are_refused(mixed_ssp, tmp_path):
    (tmp_path / "text.ssp").write_text("not a zip")
    with pytest.raises(SceneError, match="not a zip archive"):
        load_scene(tmp_path / "text.ssp")
    with zipfile.ZipFile(tmp_path / "empty.ssp", "w") as archive:
        archive.writestr("resources/a.fmu", b"")
    with pytest.raises(SceneError, match="no SystemStructure.ssd at the top of the package"):
        load_scene(tmp_path / "empty.ssp")
    with zipfile.ZipFile(tmp_path / "escape.ssp", "w") as archive:
        archive.writestr("../evil.txt", "x")
    with pytest.raises(SceneError, match="archive member '../evil.txt' points outside the package"):
        load_scene(tmp_path / "escape.ssp")
    package = write_package(tmp_path / "notxml.ssp", "<ssd:System", mixed_ssp)
    with pytest.raises(SceneError, match="SystemStructure.ssd is not well-formed XML"):
        load_scene(package)
    with pytest.raises(SceneError, match="FMU 'b.fmu' has no tunable/fixed parameter 'nonsense'"):
        run_scene(mixed_ssp, {"b.nonsense": 1.0})


def test_cli_export_and_run(mixed_ssp, tmp_path, capsys):
    scene_file = tmp_path / "mixed.toml"
    scene_file.write_text(SCENE_TOML)
    package = tmp_path / "out" / "mixed.ssp"
    assert main(["export-ssp", str(scene_file), "--out", str(package), "--set", "source.u=3"]) == 0
    assert capsys.readouterr().out.strip() == str(package)
    assert main(["run", str(package), "-q", "--no-figure", "--out", str(tmp_path / "run")]) == 0
    assert (tmp_path / "run" / "results.csv").is_file()
    capsys.readouterr()
    with_outputs = tmp_path / "out" / "outputs.ssp"
    assert main(["export-ssp", str(scene_file), "--out", str(with_outputs), "--system-outputs"]) == 0
    assert '<ssd:Connector name="g.y" kind="output">' in zipfile.ZipFile(with_outputs).read(SSD_NAME).decode()
    assert '<ssd:Connector name="g.y" kind="output">' not in zipfile.ZipFile(package).read(SSD_NAME).decode()
    capsys.readouterr()
    assert main(["run", str(tmp_path / "nothing.ssp"), "-q"]) == 2
    assert f"SSP package '{tmp_path / 'nothing.ssp'}': no such file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["export-ssp", str(scene_file), "--out", str(tmp_path / "x.zip")])


SCENE_TOML = """
name = "mixed"
connections = ["source.u -> g.u", "g.y -> scale.u"]
[master]
t_end_s = 0.5
[blocks.g]
kind = "fmu"
model = "toys:gain"
[blocks.source]
kind = "constant"
outputs = { u = { value = 1.0, unit = "1" } }
[blocks.scale]
kind = "gain"
gain = -1.0
[blocks.rec]
kind = "recorder"
signals = ["scale.y", "g.y"]
"""


@pytest.mark.parametrize("coupling", ["strong", "jacobi", "gauss-seidel"])
def test_fmi2_fmus_give_the_fmi3_results_under_every_coupling(tmp_path, coupling):
    """Model Exchange (strong) and Co-Simulation (weak couplings) through the FMI 2.0 adapter."""
    settings = {"master.coupling": coupling, "master.step_s": 0.01}
    direct = run_scene(make_scene(OSCILLATOR), settings)
    package = export_ssp(make_scene(OSCILLATOR), tmp_path / "osc2.ssp", fmi_version=2)
    assert {read_model_description(load_scene(package).block(b).settings["fmu"]).fmiVersion
            for b in ("a", "b")} == {"2.0"}
    back = run_scene(package, settings)
    assert np.array_equal(direct.time, back.time)
    for name in direct.signals:
        assert np.max(np.abs(direct[name] - back[name])) <= 1e-10, name

"""Hand-written test FMUs (tests/cosim/fmu_c), FMI 2.0 and 3.0 from one spec each.

A spec lists the variables once; from it this module writes modelDescription.xml (FMI 2.0 or
3.0) and the C variable table `vars.h` (struct fields, start values, value references) that the
model file and the shells (fmi2_shell.c, fmi3_shell.c) compile against, so XML and binary cannot
disagree. `build(name, version, folder)` compiles with gcc against fmpy's FMI headers and zips.

Models
  types   every scalar type the FMI version has, in and out: T_output = T_input + T_parameter
          (Boolean: xor; String and Binary: the parameter followed by the input; Enumeration:
          the larger of the two); FMI 3.0 adds
          an array port Float64_vector_output[3] = 2 * Float64_vector_input[3]
  events  counter (Int32) += 1 at the time events t = k * period; x' = level with `level` a
          discrete Float64 input (settable only in initialization or event mode, as the standard
          says; the FMU logs why when set elsewhere); odd (Boolean) = counter is odd;
          period <= 0 is refused at initialization with a log line; with max_count > 0 it asks
          to terminate when the counter reaches it (Model Exchange: terminateSimulation of the event
          update; Co-Simulation: doStep stops at that event, FMI 3.0 with terminateSimulation and
          lastSuccessfulTime, FMI 2.0 with fmi2Discard + fmi2Terminated)
  vdp     Van der Pol oscillator, Model Exchange only: x0' = x1, x1' = mu (1 - x0^2) x1 - x0
  ball    bouncing ball, Model Exchange only: h' = v, v' = -g; a state event at h = 0 falling
          (event indicator z = h) sets v := -e v and counts bounces (Int32)
"""
from __future__ import annotations

import hashlib
import subprocess
import zipfile
from dataclasses import dataclass
from pathlib import Path

import fmpy

SOURCE = Path(__file__).parent / "fmu_c"
INCLUDE = Path(fmpy.__file__).parent / "c-code"

C_TYPE = {"Float64": "double", "Float32": "float", "Int8": "int8_t", "UInt8": "uint8_t", "Int16": "int16_t",
          "UInt16": "uint16_t", "Int32": "int32_t", "UInt32": "uint32_t", "Int64": "int64_t", "UInt64": "uint64_t",
          "Boolean": "int", "String": "StrVal", "Binary": "BinVal"}
V_TYPE = {"Float64": "F64", "Float32": "F32", "Int8": "I8", "UInt8": "U8", "Int16": "I16", "UInt16": "U16",
          "Int32": "I32", "UInt32": "U32", "Int64": "I64", "UInt64": "U64", "Boolean": "BOOL", "String": "STR",
          "Binary": "BIN"}
FMI2_TYPE = {"Float64": "Real", "Int32": "Integer", "Boolean": "Boolean", "String": "String", "Enumeration": "Enumeration"}
#: the test FMUs' one enumeration type: declared in TypeDefinitions, Int32 in FMI 2.0, Int64 in 3.0
MODE_ITEMS = (("off", 1), ("on", 2), ("auto", 3))
CAUS = {"fixed": "PAR_FIXED", "tunable": "PAR_TUNABLE", "input": "INPUT", "output": "OUTPUT", "local": "LOCAL"}


@dataclass
class Var:
    name: str
    type: str
    causality: str  # parameter | input | output | local
    variability: str  # fixed | tunable | discrete | continuous
    start: object = None
    size: int = 1  # > 1: an FMI 3.0 array
    depends: tuple[str, ...] = ()
    unit: str = ""
    derivative_of: str = ""
    indicator: bool = False  # an event indicator (FMI 3.0 lists it in <ModelStructure>)

    @property
    def field(self) -> str:
        return self.name.replace("(", "_").replace(")", "_")


SCALARS3 = ["Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64",
            "Boolean", "String", "Binary"]
PARAM_START = {"Float32": 0.5, "Float64": 0.25, "Boolean": False, "String": "p:", "Binary": "00"}
INPUT_START = {"String": "", "Binary": "00", "Enumeration": 1}


def _types_spec(version: int) -> list[Var]:
    names = (SCALARS3 if version == 3 else ["Float64", "Int32", "Boolean", "String"]) + ["Enumeration"]
    out = []
    for t in names:
        cont = "continuous" if t.startswith("Float") else "discrete"
        out.append(Var(f"{t}_parameter", t, "parameter", "tunable", PARAM_START.get(t, 1)))
        out.append(Var(f"{t}_input", t, "input", cont, INPUT_START.get(t, 0)))
        out.append(Var(f"{t}_output", t, "output", cont, depends=(f"{t}_input",)))
    if version == 3:
        out.append(Var("Float64_vector_input", "Float64", "input", "continuous", 0.0, size=3))
        out.append(Var("Float64_vector_output", "Float64", "output", "continuous", size=3,
                       depends=("Float64_vector_input",)))
    return out


def _events_spec(version: int) -> list[Var]:
    return [
        Var("period", "Float64", "parameter", "fixed", 0.25, unit="s"),
        Var("max_count", "Int32", "parameter", "fixed", 0),
        Var("level", "Float64", "input", "discrete", 0.0),
        Var("counter", "Int32", "output", "discrete", 0),
        Var("odd", "Boolean", "output", "discrete", False),
        Var("x", "Float64", "output", "continuous", 0.0),
        Var("der(x)", "Float64", "local", "continuous", derivative_of="x"),
    ]


def _vdp_spec(version: int) -> list[Var]:
    return [
        Var("mu", "Float64", "parameter", "fixed", 1.0),
        Var("x0", "Float64", "output", "continuous", 2.0),
        Var("der(x0)", "Float64", "local", "continuous", derivative_of="x0"),
        Var("x1", "Float64", "output", "continuous", 0.0),
        Var("der(x1)", "Float64", "local", "continuous", derivative_of="x1"),
    ]


def _ball_spec(version: int) -> list[Var]:
    return [
        Var("g", "Float64", "parameter", "fixed", 9.81, unit="m/s2"),
        Var("e", "Float64", "parameter", "fixed", 0.7),
        Var("h", "Float64", "output", "continuous", 1.0, unit="m"),
        Var("der(h)", "Float64", "local", "continuous", derivative_of="h", unit="m/s"),
        Var("v", "Float64", "output", "continuous", 0.0, unit="m/s"),
        Var("der(v)", "Float64", "local", "continuous", derivative_of="v", unit="m/s2"),
        Var("bounces", "Int32", "output", "discrete", 0),
        Var("z", "Float64", "local", "continuous", indicator=True),
    ]


MODELS = {"types": (_types_spec, True, True), "events": (_events_spec, True, True), "vdp": (_vdp_spec, True, False),
          "ball": (_ball_spec, True, False)}


def _c_start(v: Var) -> str:
    if v.type == "String":
        return f'strcpy(m->{v.field}, "{v.start or ""}");'
    if v.type == "Binary":
        data = bytes.fromhex(str(v.start or ""))
        return (f"m->{v.field}.n = {len(data)}; " +
                " ".join(f"m->{v.field}.d[{i}] = {b};" for i, b in enumerate(data)))
    value = int(v.start) if v.type == "Boolean" else (v.start or 0)
    if v.size > 1:
        return f"for (int i = 0; i < {v.size}; i++) m->{v.field}[i] = {value};"
    return f"m->{v.field} = {value};"


def _c_types(version: int) -> tuple[dict[str, str], dict[str, str]]:
    enum = ("int64_t", "I64") if version == 3 else ("int32_t", "I32")
    return {**C_TYPE, "Enumeration": enum[0]}, {**V_TYPE, "Enumeration": enum[1]}


def vars_header(spec: list[Var], version: int) -> str:
    c_type, v_type = _c_types(version)
    fields = "\n".join(f"  {c_type[v.type]} {v.field}{f'[{v.size}]' if v.size > 1 else ''};" for v in spec)
    rows = []
    for vr, v in enumerate(spec):
        caus = CAUS[v.variability] if v.causality == "parameter" else CAUS[v.causality]
        rows.append(f'  {{{vr}, "{v.name}", {v_type[v.type]}, {caus}, {int(v.variability == "discrete")}, {v.size}, '
                    f"offsetof(Model, {v.field})}},")
    starts = "\n".join(f"  {_c_start(v)}" for v in spec if v.start is not None)
    return (f"typedef struct {{\n{fields}\n}} Model;\n"
            f"static const VarDef VARS[] = {{\n" + "\n".join(rows) + "\n};\n"
            f"static void m_start(Model* m) {{\n  memset(m, 0, sizeof *m);\n{starts}\n}}\n")


def _xml_start(v: Var) -> str:
    if v.start is None:
        return ""
    if v.type == "Boolean":
        return "true" if v.start else "false"
    return str(v.start)


def model_description(name: str, spec: list[Var], version: int, me: bool, cs: bool) -> str:
    guid = "{" + hashlib.md5(f"{name}{version}".encode()).hexdigest() + "}"
    index = {v.name: i for i, v in enumerate(spec)}
    units = sorted({v.unit for v in spec if v.unit})
    unit_xml = ("  <UnitDefinitions>\n" + "".join(f'    <Unit name="{u}"/>\n' for u in units) + "  </UnitDefinitions>\n"
                if units else "")
    caps = 'canGetAndSetFMUState="true"' if version == 3 else 'canGetAndSetFMUstate="true"'
    ifaces = ""
    if me:
        ifaces += f'  <ModelExchange modelIdentifier="{name}" {caps}/>\n'
    if cs:
        ifaces += f'  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="true" {caps}/>\n'
    lines = []
    states = [v for v in spec if v.derivative_of]
    for vr, v in enumerate(spec):
        variability = v.variability
        attrs = f'name="{v.name}" valueReference="{vr}" causality="{v.causality}" variability="{variability}"'
        initial = ""
        if v.causality == "output" or v.causality == "local":
            initial = ' initial="exact"' if v.start is not None else (' initial="calculated"' if v.causality == "output" else "")
        unit = f' unit="{v.unit}"' if v.unit else ""
        if v.type == "Enumeration":
            unit = ' declaredType="Mode"'
        start = _xml_start(v)
        deriv = f' derivative="{index[v.derivative_of] + (1 if version == 2 else 0)}"' if v.derivative_of else ""
        if version == 3:
            body = ""
            start_attr = f' start="{start}"' if v.start is not None else ""
            if v.type in ("String", "Binary") and v.start is not None:
                start_attr, body = "", f'<Start value="{start}"/>'
            if v.size > 1:
                start_attr = f' start="{" ".join([start] * v.size)}"' if v.start is not None else ""
                body += f'<Dimension start="{v.size}"/>'
            tag = f"<{v.type} {attrs}{initial}{start_attr}{unit}{deriv}"
            lines.append(f"    {tag}>{body}</{v.type}>" if body else f"    {tag}/>")
        else:
            start_attr = f' start="{start}"' if v.start is not None else ""
            lines.append(f"    <ScalarVariable {attrs}{initial}><{FMI2_TYPE[v.type]}{start_attr}{unit}{deriv}/></ScalarVariable>")
    outputs = [v for v in spec if v.causality == "output"]
    if version == 3:
        struct = "".join(f'    <Output valueReference="{index[v.name]}" dependencies="{" ".join(str(index[d]) for d in v.depends)}"/>\n'
                         if v.depends else f'    <Output valueReference="{index[v.name]}" dependencies=""/>\n' for v in outputs)
        struct += "".join(f'    <ContinuousStateDerivative valueReference="{index[v.name]}"/>\n' for v in states)
        struct += "".join(f'    <InitialUnknown valueReference="{index[v.name]}"/>\n'
                          for v in spec if (v.causality == "output" and v.start is None) or v.derivative_of)
        struct += "".join(f'    <EventIndicator valueReference="{index[v.name]}"/>\n' for v in spec if v.indicator)
        lines.insert(0, f'    <Float64 name="time" valueReference="{len(spec)}" causality="independent" variability="continuous"/>')
        head = (f'<fmiModelDescription fmiVersion="3.0" modelName="{name}" instantiationToken="{guid}" '
                f'generationTool="featherstar tests">\n')
    else:
        struct = "    <Outputs>\n" + "".join(
            f'      <Unknown index="{index[v.name] + 1}" dependencies="{" ".join(str(index[d] + 1) for d in v.depends)}"/>\n'
            for v in outputs) + "    </Outputs>\n"
        if states:
            struct += "    <Derivatives>\n" + "".join(f'      <Unknown index="{index[v.name] + 1}"/>\n' for v in states) + "    </Derivatives>\n"
        calc = [v for v in spec if (v.causality == "output" and v.start is None) or v.derivative_of]
        if calc:
            struct += "    <InitialUnknowns>\n" + "".join(f'      <Unknown index="{index[v.name] + 1}"/>\n' for v in calc) + "    </InitialUnknowns>\n"
        head = (f'<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{guid}" generationTool="featherstar tests" '
                f'numberOfEventIndicators="{sum(v.indicator for v in spec)}">\n')
    if any(v.type == "Enumeration" for v in spec):
        items = "".join(f'      <Item name="{n}" value="{k}"/>\n' for n, k in MODE_ITEMS)
        unit_xml += ("  <TypeDefinitions>\n    <EnumerationType name=\"Mode\">\n" + items + "    </EnumerationType>\n"
                     "  </TypeDefinitions>\n" if version == 3 else
                     "  <TypeDefinitions>\n    <SimpleType name=\"Mode\">\n      <Enumeration>\n" +
                     items.replace("      <Item", "        <Item") + "      </Enumeration>\n    </SimpleType>\n"
                     "  </TypeDefinitions>\n")
    return ('<?xml version="1.0" encoding="UTF-8"?>\n' + head + ifaces + unit_xml + "  <ModelVariables>\n" +
            "\n".join(lines) + "\n  </ModelVariables>\n  <ModelStructure>\n" + struct + "  </ModelStructure>\n"
            "</fmiModelDescription>\n")


def build(name: str, version: int, folder: Path) -> Path:
    """Compile test model `name` as an FMI `version` FMU into folder (once per content hash)."""
    spec_fn, me, cs = MODELS[name]
    spec = spec_fn(version)
    xml = model_description(name, spec, version, me, cs)
    header = vars_header(spec, version)
    sources = [SOURCE / "shell.h", SOURCE / f"fmi{version}_shell.c", SOURCE / f"{name}.c"]
    digest = hashlib.sha1((xml + header + "".join(p.read_text() for p in sources)).encode()).hexdigest()[:12]
    fmu = folder / f"{name}{version}-{digest}.fmu"
    if fmu.exists():
        return fmu
    work = folder / f"{name}{version}-{digest}"
    work.mkdir(parents=True, exist_ok=True)
    (work / "vars.h").write_text(header)
    so = work / f"{name}.so"
    defines = [] if cs else ["-DNO_CS"]
    subprocess.run(["gcc", "-O1", "-shared", "-fPIC", "-w",
                    f"-I{INCLUDE}", f"-I{SOURCE}", f"-I{work}", f'-DMODEL_SOURCE="{name}.c"', f"-DFMI_MAJOR={version}", *defines,
                    str(SOURCE / f"fmi{version}_shell.c"), "-o", str(so), "-lm"], check=True)
    tmp = fmu.with_suffix(".tmp")
    with zipfile.ZipFile(tmp, "w") as z:
        z.writestr("modelDescription.xml", xml)
        z.write(so, f"binaries/{'x86_64-linux' if version == 3 else 'linux64'}/{name}.so")
    tmp.rename(fmu)
    return fmu

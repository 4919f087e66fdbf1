"""Model → FMI 3.0 FMU (Model Exchange and Co-Simulation) for x86_64-linux.

CasADi's `DaeBuilder.export_fmu` writes Model Exchange sources whose entry points trust the
caller completely and whose Co-Simulation functions are stubs. The FMU built here keeps
CasADi's generated model code but links it behind a hand-written shell (`fmu_src/c/`) that
checks the FMI state machine and every argument, answers `time`, adds FMU state snapshots and
implements Co-Simulation with an embedded Dormand–Prince integrator. modelDescription.xml is
patched to declare what the shell adds plus units, descriptions and parameter ranges.

Builds are cached by the model's fingerprint and a hash of this pipeline (shell sources, this
module, CasADi version): rebuilding an unchanged model is a file copy.
"""
from __future__ import annotations

import fcntl
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import casadi as ca
import fmpy

from .build_progress import cold_build
from .errors import BuildError
from .model import Model
from .shell_tables import variable_tables
from .si_units import base_unit

SHELL_DIR = Path(__file__).parent / "c"
SHELL_HEADER = "fmi3_shell.h"
SHELL_SOURCES = (
    "fmi3_shell.c", "fmi3_variables.c", "fmi3_model_exchange.c", "fmi3_cosim.c", "fmi3_state.c",
    "fmi3_unsupported.c",
)
# An FMI 2.0 FMU is the same shell behind this adapter; the shell's fmi3 functions stay hidden.
FMI2_ADAPTER = "fmi2_adapter.c"
FMI2_PLATFORM = "linux64"  # FMI 2.0's name for the binaries' folder
FMI_VERSIONS = (2, 3)
PLATFORM = "x86_64-linux"
FMI_HEADERS = Path(fmpy.__file__).parent / "c-code"
# Hidden visibility leaves only the shell's fmi3* functions exported: CasADi's globals
# (`start`, `evaluate`, the model functions) would otherwise be visible to the whole process.
CFLAGS = ("-O2", "-fPIC", "-fvisibility=hidden", "-DCASADI_SYMBOL_EXPORT=")

#: Above this much C, the model function itself is compiled at -O1 (see _prepare_model_source).
HUGE_MODEL_BYTES = 600_000

# Defined in the wrap source (with the instantiation token the shell checks importers against)
# rather than on the command line, so that sources/ stays buildable from buildDescription.xml
# alone: CasADi's fmi3* functions become casadi_fmi3*, the shell's are the real ones.
_WRAP_PREFIX = "#define FMI3_FUNCTION_PREFIX casadi_\n"
_WRAP_HOOKS = """
/* Appended by featherstar (fmu_src/export.py): the shell's window into this file. Variables
 * are scalars, so a value reference indexes m->v directly, as in evaluate() above. */
#include "fmi3_shell.h"
static int fs_rhs(void* memory, double t, const double* x, double* xdot) {
  casadi_fmi_memory* m = (casadi_fmi_memory*)memory;
  size_t i;
  m->t = t;
  for (i = 0; i < N_X; ++i) m->v[x_vr[i]] = x[i];
  if (evaluate(m)) return 1;
  m->up_to_date = 1;
  for (i = 0; i < N_X; ++i) xdot[i] = m->xdot[i];
  return 0;
}
static void fs_get_states(const void* memory, double* x) {
  const casadi_fmi_memory* m = (const casadi_fmi_memory*)memory;
  size_t i;
  for (i = 0; i < N_X; ++i) x[i] = m->v[x_vr[i]];
}
static void fs_set_states(void* memory, double t, const double* x) {
  casadi_fmi_memory* m = (casadi_fmi_memory*)memory;
  size_t i;
  m->t = t;
  if (x) for (i = 0; i < N_X; ++i) m->v[x_vr[i]] = x[i];
  m->up_to_date = 0;
}
static const double* fs_values(const void* memory) { return ((const casadi_fmi_memory*)memory)->v; }
static int fs_evaluate(void* memory) {
  casadi_fmi_memory* m = (casadi_fmi_memory*)memory;
  if (evaluate(m)) return 1;
  m->up_to_date = 1;
  return 0;
}
const fs_model* fs_model_info(void) {
  static const fs_model info = {FS_INSTANTIATION_TOKEN, sizeof(casadi_fmi_memory),
                                N_VAR, N_X, N_U, N_P, N_ZERO,
                                var_offset, x_vr, u_vr, p_vr, N_Y, y_vr, fs_limit_by_vr, fs_var_name,
                                fs_rhs, fs_get_states, fs_set_states, fs_values, fs_evaluate};
  return &info;
}
"""

def cache_dir() -> Path:
    """Where built FMUs are kept: $FEATHERSTAR_CACHE, else ~/.cache/featherstar/fmus."""
    root = os.environ.get("FEATHERSTAR_CACHE")
    return Path(root) if root else Path.home() / ".cache" / "featherstar" / "fmus"


def build_fmu(model: Model, out_dir: Path | None = None, *, force: bool = False, fmi_version: int = 3) -> Path:
    """Build `<out_dir>/<model.name>.fmu` (or return the cached FMU when out_dir is None), an
    FMI 3.0 FMU or (fmi_version=2) an FMI 2.0 one; both hold Model Exchange and Co-Simulation.

    An unchanged model is not rebuilt unless `force`. Files appear atomically, so concurrent
    builders and readers of the same FMU never see a partial file. Raises BuildError.
    """
    if fmi_version not in FMI_VERSIONS:
        raise BuildError(f"FMI version {fmi_version!r} cannot be built; choose one of {FMI_VERSIONS}")
    # Read once: the key and the build must see the same shell, even if it is edited meanwhile.
    names = (SHELL_HEADER, *SHELL_SOURCES, *((FMI2_ADAPTER,) if fmi_version == 2 else ()))
    shell = {name: (SHELL_DIR / name).read_bytes() for name in names}
    cached = cache_dir() / _cache_key(model, shell, fmi_version) / f"{model.name}.fmu"
    cached.parent.mkdir(parents=True, exist_ok=True)
    # The lock only saves duplicate work between processes; atomic renames keep files whole.
    with open(cached.parent / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if force or not cached.exists():
            with cold_build(model.name), tempfile.TemporaryDirectory(prefix="featherstar-fmu-") as tmp:
                _atomic_copy(_build(model, shell, Path(tmp), fmi_version), cached)
    if out_dir is None:
        return cached
    target = Path(out_dir) / f"{model.name}.fmu"
    target.parent.mkdir(parents=True, exist_ok=True)
    if not (target.exists() and _same_bytes(target, cached)):
        _atomic_copy(cached, target)
    return target


def _cache_key(model: Model, shell: dict[str, bytes], fmi_version: int) -> str:
    digest = hashlib.sha256(f"{ca.__version__} {PLATFORM} {CFLAGS} FMI{fmi_version}".encode())
    for name, source in sorted(shell.items()):
        digest.update(name.encode() + source)
    for module in ("export.py", "shell_tables.py", "si_units.py", *(("fmi2_description.py",) if fmi_version == 2 else ())):
        digest.update((Path(__file__).parent / module).read_bytes())
    # The fingerprint covers equations and variable metadata but not the model's own text.
    digest.update(f"{model.name}\0{model.description}".encode())
    version = "" if fmi_version == 3 else f"fmi{fmi_version}-"
    return f"{model.name}-{version}{model.fingerprint()}-{digest.hexdigest()[:12]}"


def _same_bytes(a: Path, b: Path) -> bool:
    return a.stat().st_size == b.stat().st_size and a.read_bytes() == b.read_bytes()


def _atomic_copy(source: Path, target: Path) -> None:
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".part")
    try:
        with os.fdopen(fd, "wb") as out, open(source, "rb") as src:
            shutil.copyfileobj(src, out)
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _build(model: Model, shell: dict[str, bytes], work: Path, fmi_version: int) -> Path:
    # CasADi only accepts C identifiers as function names, so the model name is one.
    identifier = model.name
    files = _export_sources(model, identifier, work)
    xml_path = work / "modelDescription.xml"
    xml_path.write_text(_patch_model_description(xml_path.read_text(), model, identifier))
    wrap = work / f"{identifier}_wrap.c"
    token = ET.parse(xml_path).getroot().get("instantiationToken", "")
    prefix = _WRAP_PREFIX + f'#define FS_INSTANTIATION_TOKEN "{token}"\n'
    tables = variable_tables(model, ET.parse(xml_path).getroot())
    wrap.write_text(prefix + wrap.read_text() + tables + _WRAP_HOOKS)
    model_flags = _prepare_model_source(work / f"{identifier}.c", identifier)
    for name, source in shell.items():
        (work / name).write_bytes(source)
        files[name] = f"sources/{name}"
    if fmi_version == 2:
        from .fmi2_description import fmi2_model_description

        xml_path.write_text(fmi2_model_description(xml_path.read_text()))
        # buildDescription.xml and extra/ are FMI 3.0 features.
        files = {local: archived for local, archived in files.items()
                 if not archived.startswith("extra/") and archived != "sources/buildDescription.xml"}
    else:
        _add_shell_to_build_description(work / "buildDescription.xml")
    library = _compile(work, identifier, model_flags, [name for name in shell if name.endswith(".c")], fmi_version)
    platform = PLATFORM if fmi_version == 3 else FMI2_PLATFORM
    files[library.name] = f"binaries/{platform}/{library.name}"
    fmu = work / f"{model.name}.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        for local, archived in sorted(files.items(), key=lambda item: item[1]):
            archive.write(work / local, os.path.normpath(archived))
    return fmu


def _export_sources(model: Model, identifier: str, work: Path) -> dict[str, str]:
    """Run CasADi's export in a child process: it writes into the current directory, and
    changing the cwd of this (possibly multi-threaded) process is not safe."""
    spec = {
        "identifier": identifier,
        "function": model.function().serialize(),
        "states": [[v.name, v.start] for v in model.states],
        "inputs": [[v.name, v.start] for v in model.inputs],
        "parameters": [[p.name, p.default] for p in model.parameters],
        "outputs": [v.name for v in model.outputs],
    }
    # the child imports this module by its full name, from wherever this process found it
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [*sys.path, os.environ.get("PYTHONPATH")])))
    result = subprocess.run(
        [sys.executable, "-c", f"from {__name__} import _export_worker; _export_worker()"],
        input=json.dumps(spec), capture_output=True, text=True, cwd=work, env=env,
    )
    if result.returncode != 0:
        raise BuildError(f"CasADi FMU export of '{model.name}' failed:\n{result.stderr[-3000:]}")
    return json.loads(result.stdout)


def _export_worker() -> None:
    """Child side of _export_sources: spec on stdin, {local file: archive path} on stdout."""
    spec = json.load(sys.stdin)
    ode = ca.Function.deserialize(spec["function"])
    dae = ca.DaeBuilder(spec["identifier"])
    x = [dae.add(n, "local", "continuous", {"start": s, "initial": "exact"}) for n, s in spec["states"]]
    u = [dae.add(n, "input", {"start": s}) for n, s in spec["inputs"]]
    p = [dae.add(n, "parameter", "tunable", {"start": s}) for n, s in spec["parameters"]]
    y = [dae.add(n, "output") for n in spec["outputs"]]

    def column(symbols: list[ca.MX]) -> ca.MX:
        return ca.vertcat(*symbols) if symbols else ca.MX(0, 1)

    xdot, y_value = ode(column(x), column(u), column(p))
    for i, state in enumerate(x):
        dae.eq(dae.der(state), xdot[i])
    for i, output in enumerate(y):
        dae.eq(output, y_value[i])
    json.dump(dae.export_fmu({"no_warning": True}), sys.stdout)


def _compile(work: Path, identifier: str, model_flags: tuple[str, ...], shell_sources: list[str],
             fmi_version: int) -> Path:
    """Compile each translation unit in parallel, then link; BuildError with gcc's stderr."""
    sources = [f"{identifier}.c", f"{identifier}_wrap.c", *shell_sources]
    include = [f"-I{FMI_HEADERS}", f"-I{work}"]
    # An empty FMI3_Export leaves the fmi3 functions hidden behind the FMI 2.0 adapter.
    version_flags = ("-DFMI3_Export=",) if fmi_version == 2 else ()
    jobs: list[tuple[str, subprocess.Popen[str]]] = []
    try:
        for src in sources:
            flags = (*CFLAGS, *version_flags, *(model_flags if src == sources[0] else ()))
            command = ["gcc", *flags, *include, "-c", src, "-o", f"{src}.o"]
            jobs.append((src, subprocess.Popen(command, cwd=work, stderr=subprocess.PIPE, text=True)))
        stderrs = [job.communicate()[1] for _, job in jobs]
        failures = [(src, stderr) for (src, job), stderr in zip(jobs, stderrs) if job.returncode]
        library = work / f"{identifier}.so"
        if not failures:
            objects = [f"{src}.o" for src in sources]
            link = subprocess.run(["gcc", "-shared", "-o", library.name, *objects, "-lm"],
                                  cwd=work, stderr=subprocess.PIPE, text=True)
            failures = [("link", link.stderr)] if link.returncode else []
    except OSError as error:
        raise BuildError(f"cannot run gcc: {error}") from error
    finally:
        # A big model compiles for minutes: an interrupted build must not leave gcc running.
        for _, job in jobs:
            if job.poll() is None:
                job.kill()
                job.wait()
    if failures:
        src, stderr = failures[0]
        tail = "\n".join(stderr.strip().splitlines()[-30:])
        raise BuildError(f"gcc failed on {src} for FMU '{identifier}':\n{tail}")
    return library


def _prepare_model_source(source: Path, identifier: str) -> tuple[str, ...]:
    """Tune how CasADi's generated model code is optimized; returns extra gcc flags for it.

    gcc's register allocation is superlinear in function size and CasADi writes each function
    as one straight-line body. The forward and adjoint derivative code is ~6x the size of the
    model function and at -O2 takes many minutes for a 20-state feather, yet it only serves
    fmi3GetDirectionalDerivative / fmi3GetAdjointDerivative: it is compiled without
    optimization. The model function, which the integrators call, keeps -O2 unless it is huge:
    for the 0.8 MB of the chordwise feather at N = 40 (O(N) chain solve) -O2 took 32 s, -O1 with
    priority colouring 8 s, and evaluation is ~1.2x slower (bench/feather_speed.py). CasADi writes the derivatives after the model function,
    headed by a `/* fwd1_<id>:(...` comment; without it, everything is the model function.
    """
    text = source.read_text()
    model_part = text.find(f"/* fwd1_{identifier}:(")
    if model_part >= 0:
        source.write_text(text[:model_part] + '#pragma GCC optimize ("O0")\n' + text[model_part:])
    else:
        model_part = len(text)
    return ("-O1", "-fira-algorithm=priority") if model_part > HUGE_MODEL_BYTES else ()


def _add_shell_to_build_description(path: Path) -> None:
    tree = ET.parse(path)
    file_set = tree.find("./BuildConfiguration/SourceFileSet")
    if file_set is None:
        raise BuildError("CasADi's buildDescription.xml has no SourceFileSet")
    for name in (*SHELL_SOURCES, SHELL_HEADER):
        ET.SubElement(file_set, "SourceFile", name=name)
    ET.indent(tree, space="    ")
    tree.write(path, encoding="UTF-8", xml_declaration=True)


def _patch_model_description(text: str, model: Model, identifier: str) -> str:
    root = ET.fromstring(text)
    root.set("modelName", model.name)
    root.set("description", model.description)
    # CasADi's helper variables (`__assign__der(x)__`) are not valid structured names.
    root.set("variableNamingConvention", "flat")
    me = root.find("ModelExchange")
    if me is None:
        raise BuildError("CasADi's modelDescription.xml has no ModelExchange element")
    me.set("canGetAndSetFMUState", "true")
    cs = ET.Element("CoSimulation", {
        "modelIdentifier": identifier,
        "canHandleVariableCommunicationStepSize": "true",
        "canGetAndSetFMUState": "true",
        "canSerializeFMUState": "false",
    })
    for flag in ("providesDirectionalDerivatives", "providesAdjointDerivatives"):
        if me.get(flag):
            cs.set(flag, me.get(flag))
    position = list(root).index(me) + 1
    root.insert(position, cs)

    units, descriptions = _variable_metadata(model, root)
    unit_defs = ET.Element("UnitDefinitions")
    for unit in sorted(set(units.values())):
        element = ET.SubElement(unit_defs, "Unit", name=unit)
        base = base_unit(unit)
        if base is not None:
            ET.SubElement(element, "BaseUnit", {k: str(v) for k, v in base.items()})
    log_categories = ET.Element("LogCategories")
    ET.SubElement(log_categories, "Category", name="logStatusError",
                  description="Calls out of sequence, bad arguments (NaN, out-of-range parameters), failed steps")
    ET.SubElement(log_categories, "Category", name="logStatusDiscard",
                  description="A result is not finite: retry with a shorter step or other inputs")
    root.insert(position + 1, unit_defs)
    root.insert(position + 2, log_categories)

    ranges = {p.name: p for p in model.parameters}
    starts = _start_values(model)
    for variable in root.iter("Float64"):
        name = variable.get("name")
        variable.set("unit", units[name])
        variable.set("description", descriptions[name])
        if name in starts:
            # CasADi writes starts with 6 significant digits; the binary holds the exact double.
            # An importer that sets the declared start (every SSP tool does) must not move it.
            variable.set("start", starts[name])
        if name in ranges:
            variable.set("min", repr(ranges[name].minimum))
            variable.set("max", repr(ranges[name].maximum))
    ET.indent(root, space="    ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode")


def _start_values(model: Model) -> dict[str, str]:
    """The start of every state, input and parameter, as the shortest text that parses back to
    the same double (`repr`)."""
    values = {v.name: v.start for v in (*model.states, *model.inputs)}
    values.update({p.name: p.default for p in model.parameters})
    return {name: repr(float(value)) for name, value in values.items()}


def _variable_metadata(model: Model, root: ET.Element) -> tuple[dict[str, str], dict[str, str]]:
    """Unit and description of every declared variable, CasADi's derived ones included."""
    units = {"time": "s"}
    descriptions = {"time": "Simulation time"}
    for v in (*model.states, *model.inputs, *model.parameters, *model.outputs):
        units[v.name], descriptions[v.name] = v.unit, v.description
    variables = list(root.iter("Float64"))
    by_vr = {v.get("valueReference"): v.get("name") for v in variables}
    for v in variables:
        name = v.get("name")
        if v.get("derivative"):
            state = by_vr[v.get("derivative")]
            units[name], descriptions[name] = _per_second(units[state]), f"Time derivative of {state}"
    for v in variables:
        name = v.get("name")
        assigned = re.fullmatch(r"__assign__(.+)__", name)
        if assigned and assigned[1] in units:
            units[name] = units[assigned[1]]
            descriptions[name] = f"Internal: value CasADi assigns to {assigned[1]}"
    unknown = [v.get("name") for v in variables if v.get("name") not in units]
    if unknown:
        raise BuildError(f"CasADi declared variables the model does not know: {unknown}")
    return units, descriptions


def _per_second(unit: str) -> str:
    """The unit of a time derivative, in the models' unit syntax ("rad/s" -> "rad/s2")."""
    if unit == "1":
        return "1/s"
    numerator, slash, denominator = unit.partition("/")
    if not slash:
        return f"{unit}/s"
    factors = denominator.strip("()").split(".")
    for i, factor in enumerate(factors):
        seconds = re.fullmatch(r"s(\d*)", factor)
        if seconds:
            factors[i] = f"s{int(seconds[1] or 1) + 1}"
            break
    else:
        factors.append("s")
    joined = ".".join(factors)
    return f"{numerator}/{joined}" if len(factors) == 1 else f"{numerator}/({joined})"

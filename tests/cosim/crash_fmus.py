"""FMUs whose binary takes its process down (tests/cosim/fmu_c/crash.c), compiled with gcc like
the other hand-written test FMUs (tests/cosim/c_fmus.py): `build_crash(at, how, version, folder)`
with at = "instantiate" | "initialization" | "nowhere" and how = "segv" | "abort" | "exit" | "hang";
`truncated(fmu, fraction, out)`: the same FMU with its shared library cut short, zipped anew (so
every CRC holds: the zip is well formed, the binary is not)."""
from __future__ import annotations

import hashlib
import subprocess
import zipfile
from pathlib import Path

from c_fmus import INCLUDE, SOURCE, model_description, vars_header, _vdp_spec

AT = {"nowhere": 0, "instantiate": 1, "initialization": 2}
HOW = {"segv": 1, "abort": 2, "exit": 3, "hang": 4}


def build_crash(at: str, how: str, version: int, folder: Path) -> Path:
    spec = _vdp_spec(version)
    name = "crash"
    xml = model_description(name, spec, version, True, True)
    header = vars_header(spec, version)
    shell = SOURCE / f"fmi{version}_shell.c"
    digest = hashlib.sha1((xml + header + shell.read_text() + (SOURCE / "crash.c").read_text() + at + how)
                          .encode()).hexdigest()[:12]
    fmu = folder / f"crash-{at}-{how}-{version}-{digest}.fmu"
    if fmu.exists():
        return fmu
    work = folder / fmu.stem
    work.mkdir(parents=True, exist_ok=True)
    (work / "vars.h").write_text(header)
    so = work / f"{name}.so"
    subprocess.run(["gcc", "-O1", "-shared", "-fPIC", "-w", f"-I{INCLUDE}", f"-I{SOURCE}", f"-I{work}",
                    '-DMODEL_SOURCE="crash.c"', f"-DFMI_MAJOR={version}", f"-DCRASH_AT={AT[at]}",
                    f"-DCRASH_HOW={HOW[how]}", str(shell), "-o", str(so), "-lm"], check=True)
    _zip(fmu, xml, so.read_bytes(), version)
    return fmu


def _library(version: int) -> str:
    return f"binaries/{'x86_64-linux' if version == 3 else 'linux64'}/crash.so"


def _zip(fmu: Path, xml: str, library: bytes, version: int) -> None:
    tmp = fmu.with_suffix(".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", xml)
        z.writestr(_library(version), library)
    tmp.rename(fmu)


def truncated(fmu: Path, fraction: float, out: Path, version: int) -> Path:
    with zipfile.ZipFile(fmu) as z:
        xml = z.read("modelDescription.xml").decode()
        library = z.read(_library(version))
    _zip(out, xml, library[: int(len(library) * fraction)], version)
    return out

"""The hand-written FMI 2.0 first-order lag (tests/cosim/fmi2_lag: x' = (k u - x) / tau, ME and
CS in one FMU), compiled with gcc and zipped: `build_lag_fmu(folder)`."""
from __future__ import annotations

import subprocess
import zipfile
from pathlib import Path

import fmpy

SOURCE = Path(__file__).parent / "fmi2_lag"


def build_lag_fmu(folder: Path) -> Path:
    binaries = folder / "binaries" / "linux64"
    binaries.mkdir(parents=True, exist_ok=True)
    include = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(["gcc", "-O2", "-shared", "-fPIC", f"-I{include}", str(SOURCE / "lag.c"),
                    "-o", str(binaries / "lag.so"), "-lm"], check=True)
    fmu = folder / "lag.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.write(SOURCE / "modelDescription.xml", "modelDescription.xml")
        z.write(binaries / "lag.so", "binaries/linux64/lag.so")
    return fmu

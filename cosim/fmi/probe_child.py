"""The probe's child process (featherstar.cosim.fmi.probe): load an unpacked FMU's binary and take
one instance through its life — instantiate, initialize, terminate, free — announcing each FMI call
on stdout before making it, so that the parent can name the call a crash happened in.

Run as `python probe_child.py UNZIP_DIR GUID MODEL_IDENTIFIER FMI_VERSION MODE`. A status error
is not a crash: the master makes the same calls again and reports them with the FMU's own words;
the probe reports only that it got through.
"""
from __future__ import annotations

import sys

MARK = "featherstar-probe:"
#: The child's first line: it started and could import fmpy (an error before it is the probe's own).
READY = "ready"


def _say(step: str) -> None:
    sys.stdout.write(f"{MARK}{step}\n")
    sys.stdout.flush()


def _quiet(*_args: object) -> None:
    """The FMU's log lines: not the probe's business (the master keeps them)."""


def main(argv: list[str]) -> int:
    unzip_dir, guid, identifier, version, mode = argv
    fmi3 = version.startswith("3.")
    kw = dict(guid=guid, unzipDirectory=unzip_dir, modelIdentifier=identifier, instanceName="probe")
    pre = "fmi3" if fmi3 else "fmi2"
    # fmpy itself, before READY: a failure here is the probe's, not the FMU's
    from fmpy import calloc, free
    from fmpy.fmi2 import (
        FMU2Model,
        FMU2Slave,
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
    )
    from fmpy.fmi3 import FMU3Model, FMU3Slave

    _say(READY)
    _say("load")
    if fmi3:
        fmu = (FMU3Slave if mode == "cs" else FMU3Model)(**kw)
        instantiate = f"fmi3Instantiate{'CoSimulation' if mode == 'cs' else 'ModelExchange'}"
        _say(instantiate)
        fmu.instantiate(logMessage=_quiet)
    else:
        fmu = (FMU2Slave if mode == "cs" else FMU2Model)(**kw)
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(lambda *args: None)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        _say("fmi2Instantiate")
        fmu.instantiate(callbacks=callbacks)
    try:
        if fmi3:
            _say("fmi3EnterInitializationMode")
            fmu.enterInitializationMode(startTime=0.0)
        else:
            _say("fmi2SetupExperiment")
            fmu.setupExperiment(startTime=0.0)
            _say("fmi2EnterInitializationMode")
            fmu.enterInitializationMode()
        _say(f"{pre}ExitInitializationMode")
        fmu.exitInitializationMode()
        _say(f"{pre}Terminate")
        fmu.terminate()
    except Exception:   # a status error: the master will report it in the FMU's words
        pass
    _say(f"{pre}FreeInstance")
    fmu.freeInstance()
    _say("done")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except Exception as exc:   # a refusal in Python (no such symbol, instantiate returned NULL)
        _say(f"error {type(exc).__name__}: {exc}".replace("\n", " "))
        sys.exit(3)

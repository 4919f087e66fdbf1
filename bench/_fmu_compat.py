"""Does every catalog FMU, FMI 3.0 and FMI 2.0, run in every peer, with the same numbers?

Each FMU alone, one input started at 0.2 and held (a feather's root angle, the servo's setpoint,
a force on the robot's body: each moves its model), one output recorded every 1 ms for 0.1 s
(thrust, servo angle, body speed): in libcosim, in Ecos and in fmpy's
simulate_fmu (Co-Simulation). With constant inputs the masters' conventions for when inputs are
set cannot differ, so the records can be compared bit for bit with fmpy's. A master that refuses
an FMU is a result ("failed" with its error), not an omission; each run is its own process,
because a master may crash on an FMU it cannot read (libcosim 0.11 dies of SIGSEGV on FMI 3.0),
and that crash is reported as such.
"""
from __future__ import annotations

import json
import signal as signals
import subprocess
import sys
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
from _peer_masters import RUNNERS, FmuSystem, available
from featherstar.fmu_src.catalog import MODELS
from featherstar.fmu_src.export import build_fmu

STEP_S, STOP_S, EXCITATION = 1e-3, 0.1, 0.2
PEERS = ("libcosim", "ecos")
TIMEOUT_S = 120.0


def run_isolated(master: str, path: Path, angle_input: str, signal: str) -> np.ndarray:
    """`signal` from `master` running the FMU alone, in a child process; RuntimeError names a
    crash (the signal), a timeout or the child's error."""
    argv = [sys.executable, __file__, master, str(path), angle_input, signal]
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise RuntimeError(f"{master} did not finish within {TIMEOUT_S:g} s") from None
    if done.returncode < 0:
        raise RuntimeError(f"{master} crashed ({signals.Signals(-done.returncode).name}) running {path.name}")
    lines = done.stdout.strip().splitlines()
    if done.returncode != 0 or not lines:
        tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"{master} failed (exit {done.returncode}): {tail}")
    return np.array(json.loads(lines[-1]), dtype=float)   # JSON floats round-trip exactly


#: model -> (input started at EXCITATION, output recorded); feathers: root angle -> thrust
EXCITED = {"servo": ("setpoint_rad", "angle_rad"), "robot": ("thrust_left_N", "body_speed_m_s")}
FEATHER = ("root_angle_rad", "thrust_N")


def compat_matrix(folder: Path, models: Sequence[str] = tuple(MODELS),
                  log: Callable[[str], None] = print) -> dict[str, Any]:
    """model -> "fmi3"/"fmi2" -> master -> {status, bit_identical_to_fmpy, max_abs_diff_to_fmpy} or the reason."""
    reasons = available()
    out: dict[str, Any] = {}
    for name in models:
        model = MODELS[name]()
        for version in (3, 2):
            path = build_fmu(model, folder / f"fmi{version}" / name, fmi_version=version)
            excited, recorded = EXCITED.get(name, FEATHER)
            angle, signal = f"{name}.{excited}", f"{name}.{recorded}"
            entry: dict[str, Any] = {"signal": signal, "start_values": {angle: EXCITATION}}
            try:
                baseline = run_isolated("fmpy", path, angle, signal)
                entry["fmpy"] = {"status": "ok", "moves": bool(np.ptp(baseline) > 0)}
            except Exception as exc:  # a master that refuses an FMU is a result
                baseline = None
                entry["fmpy"] = {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"}
            for peer in PEERS:
                if reasons[peer]:
                    entry[peer] = {"status": "skipped", "reason": reasons[peer]}
                    continue
                try:
                    values = run_isolated(peer, path, angle, signal)
                except Exception as exc:
                    entry[peer] = {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"}
                    continue
                entry[peer] = {"status": "ok"}
                if baseline is not None:
                    entry[peer].update(bit_identical_to_fmpy=bool(np.array_equal(values, baseline)),
                                       max_abs_diff_to_fmpy=float(np.max(np.abs(values - baseline))))
            out.setdefault(name, {})[f"fmi{version}"] = entry
            log(f"  {name} FMI {version}: " + ", ".join(
                f"{m} {e['status']}" + (" (bit-identical)" if e.get("bit_identical_to_fmpy") else "")
                for m, e in entry.items() if isinstance(e, dict) and "status" in e))
    return out


def _child(master: str, path: str, angle_input: str, signal: str) -> None:
    name = angle_input.split(".", 1)[0]
    system = FmuSystem({name: Path(path)}, (), {angle_input: EXCITATION}, STEP_S, STOP_S)
    extra = (lambda grid: {},) if master == "fmpy" else ()
    print(json.dumps(RUNNERS[master](system, signal, *extra).tolist()), flush=True)


if __name__ == "__main__":
    _child(*sys.argv[1:5])

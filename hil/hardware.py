"""Swap simulated blocks of a scene for hardware blocks, by configuration only.

`--hardware servo=URL` replaces the scene's `servo` block with `featherstar.hil.blocks.Servo` (same ports;
the real servo feels the real load, so its simulated load-torque input is dropped).
`--hardware loadcell=URL` adds `featherstar.hil.blocks.LoadCell` as block `loadcell_hw` and makes it the
thrust the metrics read; simulated signals of the feather are no longer recorded, so the
simulated feather is pruned unless something else needs it. Either way the master switches to
Gauss–Seidel coupling paced on the wall clock (`master.realtime`).

URL query options beyond the device's own (unit, serial settings) configure the block:
timeout_s (per request), reconnect_s (how long a lost device is retried), start_timeout_s,
start_retry_s (patient start) and, for the servo, safe_timeout_s (how long the safe position
is retried on stop), e.g. `modbus-tcp://127.0.0.1:5020?unit=1&timeout_s=0.1&reconnect_s=3`.

A real load cell with a simulated servo reads a feather that nothing physical moves: that is
refused unless `allow_unactuated=True`, and then the summary carries a warning.
"""
from __future__ import annotations

import math
from typing import Any, Mapping
from urllib.parse import parse_qsl, urlencode, urlsplit

from ..cosim.errors import SceneError
from ..cosim.scene.data import Scene, scene_from_dict
from .blocks import MG996R_RATE_RAD_S, LoadCell, Servo

SLOTS = ("servo", "loadcell")
LOADCELL_BLOCK = "loadcell_hw"
BLOCK_OPTIONS = {"servo": ("timeout_s", "reconnect_s", "start_timeout_s", "start_retry_s",
                           "safe_timeout_s"),
                 "loadcell": ("timeout_s", "reconnect_s", "start_timeout_s", "start_retry_s")}
def _factory(cls: type) -> str:
    """The scene's `factory` reference of a block class ("package.module:Class")."""
    return f"{cls.__module__}:{cls.__qualname__}"


UNACTUATED_WARNING = ("the load cell is real but the servo is simulated: nothing the run "
                      "commands moves the feather it measures")


CLOCKS = ("pc", "device")


def split_url(slot: str, url: str) -> tuple[str, dict[str, Any]]:
    """The device URL without the block options, and the block options (seconds, > 0; and
    `clock`, pc or device)."""
    parts = urlsplit(url)
    device: list[tuple[str, str]] = []
    options: dict[str, Any] = {}
    for key, value in parse_qsl(parts.query, keep_blank_values=True):
        if key == "clock":
            if value not in CLOCKS or "clock" in options:
                raise SceneError(f"--hardware {slot}: clock={value!r}; valid values: "
                                 f"{', '.join(CLOCKS)} (once)")
            options["clock"] = value
            continue
        if key not in BLOCK_OPTIONS[slot]:
            device.append((key, value))
            continue
        try:
            seconds = float(value)
        except ValueError:
            seconds = math.nan
        if not (math.isfinite(seconds) and seconds > 0):
            raise SceneError(f"--hardware {slot}: {key}={value!r} must be a positive number of "
                             "seconds")
        if key in options:
            raise SceneError(f"--hardware {slot}: {key} given twice")
        options[key] = seconds
    # Not urlunsplit: it drops the '//' of an empty host, turning modbus-rtu:///dev/ttyUSB0 into
    # modbus-rtu:/dev/ttyUSB0, which no longer parses.
    query = urlencode(device)
    return f"{parts.scheme}://{parts.netloc}{parts.path}" + (f"?{query}" if query else ""), options


def parse_hardware(items: list[str] | None) -> dict[str, str]:
    """['servo=modbus-tcp://...', ...] -> {'servo': url}; clear errors for anything else."""
    out: dict[str, str] = {}
    for item in items or ():
        slot, eq, url = item.partition("=")
        slot, url = slot.strip(), url.strip()
        if not eq or slot not in SLOTS or not url:
            raise SceneError(f"--hardware '{item}' must read SLOT=URL with SLOT one of {', '.join(SLOTS)} "
                             "(e.g. loadcell=modbus-tcp://127.0.0.1:5020?unit=1)")
        if slot in out:
            raise SceneError(f"--hardware {slot} given twice")
        out[slot] = url
    return out


def check_hardware_overrides(scene: Scene, overrides: Mapping[str, Any] | None) -> None:
    """Refuse overrides that would unpace a hardware scene: the devices run on the wall clock
    whatever the master does, so an unpaced master plays a 9 s stroke on them in 2 s."""
    if not scene.with_overrides(overrides or {}).master.realtime:
        raise SceneError("--set master.realtime=false with --hardware: the devices run on the "
                         "wall clock, so an unpaced run would play the stroke faster than its "
                         "period; hardware runs are always paced in real time")


def bench_command(step_s: float) -> dict[str, float]:
    """Stroke-controller settings that make a simulation command its servo as a bench run at
    `step_s` does (featherstar.cosim.swimmer.controller, "How the command reaches the servo"): the stroke
    sampled once per loop step and held, each sample rate-limited as the hardware servo block
    limits its commands. A simulation that is to predict a bench measurement needs them."""
    return {"sample_period_s": float(step_s), "rate_limit_rad_s": MG996R_RATE_RAD_S}


def with_hardware(scene: Scene, hardware: Mapping[str, str], *, step_s: float = 4e-3,
                  allow_unactuated: bool = False) -> Scene:
    """The scene with hardware blocks in the named slots, run in real time at `step_s` (250 Hz)."""
    if not hardware:
        return scene
    if "loadcell" in hardware and "servo" not in hardware and not allow_unactuated:
        raise SceneError("--hardware loadcell without --hardware servo: the load cell would "
                         "measure a feather that no command moves (the servo is simulated); "
                         "add --hardware servo=URL, or --allow-unactuated-loadcell to measure "
                         "anyway with a warning")
    split = {slot: split_url(slot, url) for slot, url in hardware.items()}
    clocks = {options.pop("clock", "pc") for _, options in split.values()}
    if len(clocks) > 1 or (clocks == {"device"} and set(split) != set(SLOTS)):
        raise SceneError("--hardware ...&clock=device: both the servo and the load cell must "
                         "say it (a device-timed run plays and samples on the devices' clocks)")
    timed = {"clock": "device"} if clocks == {"device"} else {}
    data = scene.to_dict()
    blocks = data["blocks"]
    if "servo" in hardware:
        if blocks.get("servo", {}).get("kind") != "fmu":
            raise SceneError(f"scene '{scene.name}' has no simulated 'servo' block to replace")
        url, options = split["servo"]
        blocks["servo"] = {"kind": "python", "factory": _factory(Servo),
                           "parameters": {"url": url, **options, **timed}}
        data["connections"] = [c for c in data["connections"]
                               if not c.replace(" ", "").endswith("->servo.load_torque_Nm")]
    if "loadcell" in hardware:
        url, options = split["loadcell"]
        parameters: dict[str, Any] = {"url": url, **options, **timed}
        if "servo" not in hardware:
            parameters["warning"] = UNACTUATED_WARNING
        blocks[LOADCELL_BLOCK] = {"kind": "python", "factory": _factory(LoadCell),
                                  "parameters": parameters}
        data["metrics"]["thrust"] = f"{LOADCELL_BLOCK}.thrust_N"
        for block in blocks.values():
            if block.get("kind") == "recorder":
                kept = [s for s in block.get("signals", []) if not s.startswith("feather")]
                # the reading and when the PC took it (the step grid is when it was due)
                block["signals"] = [*kept, f"{LOADCELL_BLOCK}.thrust_N",
                                    f"{LOADCELL_BLOCK}.t_read_s"]
    data["master"].update(coupling="gauss-seidel", realtime=True, step_s=step_s, adaptive=False)
    return scene_from_dict(data, name=scene.name)

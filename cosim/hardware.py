"""Swap simulated blocks of a scene for hardware blocks, by configuration only.

`--hardware servo=URL` replaces the scene's `servo` block with `hil.blocks.Servo` (same ports;
the real servo feels the real load, so its simulated load-torque input is dropped).
`--hardware loadcell=URL` adds `hil.blocks.LoadCell` as block `loadcell_hw` and makes it the
thrust the metrics read; simulated signals of the feather are no longer recorded, so the
simulated feather is pruned unless something else needs it. Either way the master switches to
Gauss–Seidel coupling paced on the wall clock (`master.realtime`).
"""
from __future__ import annotations

from typing import Mapping

from .errors import SceneError
from .scene import Scene, scene_from_dict

SLOTS = ("servo", "loadcell")
LOADCELL_BLOCK = "loadcell_hw"


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


def with_hardware(scene: Scene, hardware: Mapping[str, str], *, step_s: float = 4e-3) -> Scene:
    """The scene with hardware blocks in the named slots, run in real time at `step_s` (250 Hz)."""
    if not hardware:
        return scene
    data = scene.to_dict()
    blocks = data["blocks"]
    if "servo" in hardware:
        if blocks.get("servo", {}).get("kind") != "fmu":
            raise SceneError(f"scene '{scene.name}' has no simulated 'servo' block to replace")
        blocks["servo"] = {"kind": "python", "factory": "hil.blocks:Servo",
                           "parameters": {"url": hardware["servo"]}}
        data["connections"] = [c for c in data["connections"]
                               if not c.replace(" ", "").endswith("->servo.load_torque_Nm")]
    if "loadcell" in hardware:
        blocks[LOADCELL_BLOCK] = {"kind": "python", "factory": "hil.blocks:LoadCell",
                                  "parameters": {"url": hardware["loadcell"]}}
        data["metrics"]["thrust"] = f"{LOADCELL_BLOCK}.thrust_N"
        for block in blocks.values():
            if block.get("kind") == "recorder":
                kept = [s for s in block.get("signals", []) if not s.startswith("feather")]
                block["signals"] = [*kept, f"{LOADCELL_BLOCK}.thrust_N"]
    data["master"].update(coupling="gauss-seidel", realtime=True, step_s=step_s, adaptive=False)
    return scene_from_dict(data, name=scene.name)

"""featherstar's co-simulation master: scenes as data, strong and weak coupling over FMUs.

    from featherstar.cosim import load_scene, run_scene
    result = run_scene("testbed", {"feather.morphology": "spanwise", "master.coupling": "jacobi"})
    result.summary["thrust_ratio"], result["feather.thrust_N"], result.time

See cosim/README.md for the scene format and how the master works.
"""
from __future__ import annotations

import importlib
from typing import Any

from .swimmer import kinds  # noqa: F401  (the `stroke` block kind joins the registry)

_EXPORTS = {
    "Block": "framework.block", "MemorylessBlock": "framework.block", "Port": "framework.block",
    "RollbackBlock": "framework.block",
    "FeatherstarError": "errors", "SceneError": "errors", "StepError": "errors",
    "Plan": "scene.plan", "plan": "scene.graph",
    "RunResult": "swimmer.run", "run_scene": "swimmer.run", "Simulator": "coupling.simulator",
    "MasterSpec": "scene.data", "MetricsSpec": "scene.data", "Scene": "scene.data", "scene_from_dict": "scene.data",
    "list_scenes": "scenes", "load_scene": "scenes",
}


def __getattr__(name: str) -> Any:
    # lazy: `import cosim.block` (hil, optimizer) must not pull in CasADi, fmpy and SUNDIALS
    if name in _EXPORTS:
        return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module '{__name__}' has no attribute '{name}'")


__all__ = [
    "Block",
    "FeatherstarError",
    "MasterSpec",
    "MemorylessBlock",
    "MetricsSpec",
    "Plan",
    "Port",
    "RollbackBlock",
    "RunResult",
    "Scene",
    "SceneError",
    "Simulator",
    "StepError",
    "list_scenes",
    "load_scene",
    "plan",
    "run_scene",
    "scene_from_dict",
]

"""Errors of the co-simulation master (see the tree in `featherstar.fmu_src.errors`).

SceneError  (FeatherstarError)   a scene is malformed; raised before any FMU is loaded: unknown
                                 block or model, unknown port, dangling or doubly driven input,
                                 unit mismatch, an algebraic loop that cannot be iterated, a bad
                                 override. Collects every problem it finds (``problems``).
StepError   (FeatherstarError)   a run failed: NaN/inf, solver failure, an FMU call returning an
                                 error, an algebraic loop that did not converge. Names the block,
                                 the simulation time and the likely cause; ``partial`` holds what
                                 was computed so far (a RunResult) when the master got that far.
"""
from __future__ import annotations

from typing import Any, Sequence

from ..fmu_src.errors import FeatherstarError

__all__ = ["FeatherstarError", "RunInterrupted", "SceneError", "StepError"]


class RunInterrupted(KeyboardInterrupt):
    """Raised by a signal handler (SIGTERM, SIGHUP) to stop a run the way Ctrl-C does: a
    KeyboardInterrupt, so no `except Exception` on the way swallows it."""

    def __init__(self, signal_name: str) -> None:
        super().__init__(signal_name)
        self.signal_name = signal_name


class SceneError(FeatherstarError):
    """A scene is malformed. ``problems`` lists every problem found, one line each."""

    def __init__(self, problems: str | Sequence[str], scene: str = "") -> None:
        self.problems = [problems] if isinstance(problems, str) else list(problems)
        self.scene = scene
        where = f"scene '{scene}': " if scene else ""
        if len(self.problems) == 1:
            super().__init__(f"{where}{self.problems[0]}")
        else:
            body = "\n".join(f"  - {p}" for p in self.problems)
            super().__init__(f"{where}{len(self.problems)} problems:\n{body}")


class StepError(FeatherstarError):
    """A simulation step failed. Names where (block, function), when (t_s) and why (cause)."""

    def __init__(
        self,
        block: str,
        t_s: float,
        message: str,
        *,
        function: str = "",
        cause: str = "",
        recoverable: bool = False,
    ) -> None:
        self.block = block
        self.t_s = t_s
        self.function = function
        self.cause = cause
        self.message = message
        self.partial: Any = None  # a RunResult with what was computed up to the failure
        self.interrupted: str | None = None  # the signal's name when stopped from outside
        # FMI Discard inside a right-hand side: the integrator may retry with a smaller step
        self.recoverable = recoverable
        text = f"block '{block}' at t={t_s:.6g} s"
        if function:
            text += f" in {function}"
        text += f": {message}"
        if cause:
            text += f" (likely cause: {cause})"
        super().__init__(text)

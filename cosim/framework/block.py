"""The Block protocol: what every scene block offers the master (Drake's System, in small).

A block has named input and output ports with units. Its runtime state lives in the object the
master creates for one run (blocks are built per run from scene data, never shared between runs).
Time is in seconds; port values are floats in the port's unit.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Protocol, runtime_checkable


@dataclass(frozen=True)
class Port:
    """A named scalar port. For outputs, `depends_on` names the inputs it reads at the same
    instant (direct feedthrough); the master uses it to order evaluation and find algebraic loops.
    `type` is an FMI 3.0 type name (featherstar.cosim.fmi.fmi_types; Python blocks are Float64); a `discrete`
    port changes only at events (an FMU's discrete input can be set only in event mode)."""

    name: str
    unit: str
    description: str = ""
    depends_on: tuple[str, ...] = ()
    type: str = "Float64"
    discrete: bool = False


@runtime_checkable
class Block(Protocol):
    name: str
    inputs: Mapping[str, Port]
    outputs: Mapping[str, Port]

    def start(self, t0_s: float) -> None:
        """Prepare for a run starting at t0_s (instantiate, initialise, connect hardware)."""

    def set_inputs(self, values: Mapping[str, float]) -> None:
        """Set input port values; they hold until set again."""

    def get_outputs(self) -> dict[str, float]:
        """Output port values at the block's current time and inputs."""

    def do_step(self, t_s: float, h_s: float) -> None:
        """Advance from t_s to t_s + h_s with the inputs held."""

    def close(self) -> None:
        """Release resources; for hardware, command the safe state first. Must not raise."""


# --- optional capabilities (added for the master; a plain Block needs none of them) -----------

@runtime_checkable
class MemorylessBlock(Block, Protocol):
    """A block without state: its outputs are a function of time and of its current inputs
    (the stroke generator, a gain). The strong master evaluates it inside the ODE right-hand
    side at every instant the solver asks for, so its signals are exact between communication
    points; the weak master evaluates it at every communication point. `do_step` may do nothing.
    Such a block may sit inside an algebraic loop (the master re-evaluates it for trial inputs).
    """

    def evaluate(self, t_s: float, inputs: Mapping[str, float]) -> Mapping[str, float]:
        """Output values at time t_s for the given input values (no side effects)."""


class TimeSource:
    """Base of a memoryless block without inputs, whose outputs are a function of time only (a
    stroke, a recorded root motion): subclasses set `name` and `outputs` and implement
    `evaluate`; the Block protocol's stepping is here, once."""

    can_iterate = True
    name: str
    outputs: Mapping[str, Port]

    def __init__(self) -> None:
        self.inputs: dict[str, Port] = {}
        self._t = 0.0

    def evaluate(self, t_s: float, inputs: Mapping[str, float]) -> Mapping[str, float]:
        raise NotImplementedError

    def start(self, t0_s: float) -> None:
        self._t = t0_s

    def set_inputs(self, values: Mapping[str, float]) -> None:
        if values:
            raise ValueError(f"{self.name} has no inputs (got {', '.join(values)})")

    def get_outputs(self) -> dict[str, float]:
        return dict(self.evaluate(self._t, {}))

    def do_step(self, t_s: float, h_s: float) -> None:
        self._t = t_s + h_s

    def close(self) -> None:
        pass


@runtime_checkable
class RollbackBlock(Block, Protocol):
    """A block whose state can be saved and restored: needed by the adaptive weak master, which
    rejects a macro step whose error estimate is too large and repeats it with a smaller one."""

    def get_state(self) -> object:
        """An opaque snapshot of the block's state."""

    def set_state(self, state: object) -> None:
        """Return to a snapshot taken by get_state."""


@dataclass(frozen=True)
class Passivity:
    """A passive block declares it: water and damping can only take energy out of it, so its
    mechanical energy (output `energy_output`, J) may not grow by more than the work its power
    ports put in. Each power port is an (effort output, flow input) pair whose product is the
    power into the block: (torque N·m, rate rad/s) or (force N, velocity m/s). The passive-energy
    guard (featherstar.cosim.scene.guards) judges every block that declares this."""

    energy_output: str
    power_ports: tuple[tuple[str, str], ...]


#: featherstar's models report their energy here and pair `<x>_torque_Nm` outputs with
#: `<x>_rate_rad_s` inputs (the actuator's torque and the rate it imposes).
ENERGY_OUTPUT = "mechanical_energy_J"
TORQUE_SUFFIX, RATE_SUFFIX = "_torque_Nm", "_rate_rad_s"


def passivity_by_convention(inputs: Mapping[str, Port], outputs: Mapping[str, Port]) -> Passivity | None:
    """The Passivity of a model that follows featherstar's port names (the one place they are read):
    an energy output and at least one torque/rate pair."""
    if ENERGY_OUTPUT not in outputs:
        return None
    pairs = tuple((out, out[: -len(TORQUE_SUFFIX)] + RATE_SUFFIX) for out in outputs
                  if out.endswith(TORQUE_SUFFIX) and out[: -len(TORQUE_SUFFIX)] + RATE_SUFFIX in inputs)
    return Passivity(ENERGY_OUTPUT, pairs) if pairs else None


def can_iterate(block: object) -> bool:
    """True if the master may set trial inputs and read outputs again at the same instant (needed
    to solve an algebraic loop through the block). Memoryless blocks can; other blocks say so with
    a `can_iterate = True` attribute (hardware cannot: reading a sensor twice is not a function)."""
    explicit = getattr(block, "can_iterate", None)
    if explicit is not None:
        return bool(explicit)
    return isinstance(block, MemorylessBlock)

"""The step-wise Simulator: everything that runs a scene drives one (Drake's Simulator, in small).

    sim = Simulator(plan(load_scene("testbed")))
    sim.initialize()                 # start every block, consistent values at t = 0, first record
    sim.advance_to(1.5)              # strong or weak coupling, as the scene's master says
    sim.read("feather.thrust_N")     # any port's current value
    sim.write("tank.flow_speed_m_s", 0.1)   # a source's output (a constant block), from outside
    state = sim.save_state(); ...; sim.restore_state(state)   # where every block can roll back
    sim.recorded()                   # (time, {"block.port": values}) of the requested signals
    sim.close()                      # every started block closed (hardware: safe position first)

The pieces, each its own artefact: the Plan (featherstar.cosim.scene.graph: resolved blocks and wiring, never
changed) → runtime units built from it (`build_units`) → the System (featherstar.cosim.coupling.system: units and
their wiring) → the Context (featherstar.cosim.coupling.context: time, statistics, deadline misses) and the Recording
→ the coupling strategy, `StrongCoupling` (featherstar.cosim.coupling.strong: one ODE by CVODE) or `WeakCoupling`
(featherstar.cosim.coupling.weak: Jacobi or Gauss–Seidel macro steps), which the Simulator hands what it needs. A
real-time scene is paced on the wall clock by featherstar.cosim.coupling.pacing before every macro step.
`featherstar.cosim.swimmer.run.run_scene` is the one-call driver: initialize, advance_to(end), result.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..errors import SceneError, StepError
from ..fmi.archive import cached_fmu
from ..fmi.fmi_types import typed_signal
from ..framework.units import ModelUnit, PyUnit, Unit
from ..scene.data import PortRef
from ..scene.guards import passive_energy_guards
from ..scene.plan import Plan
from .context import Context, Recording
from .pacing import RealTimePacer
from .mixed import MixedCoupling
from .strong import StrongCoupling
from .system import System
from .weak import WeakCoupling


def build_units(plan: Plan) -> dict[str, Unit]:
    """A runtime unit for every instantiated block that computes something (recorders do not)."""
    from ...fmu_src.build_progress import next_block, number_builds

    master = plan.scene.master
    units: dict[str, Unit] = {}
    number_builds(sum(1 for n in plan.instantiate if plan.blocks[n].model is not None and not plan.blocks[n].records_only
                      and master.backend != "casadi"))
    for name in plan.instantiate:
        rb = plan.blocks[name]
        if rb.records_only:
            continue
        if rb.obj is not None:
            units[name] = PyUnit(rb.obj)
        elif rb.model is not None and master.backend == "casadi":
            units[name] = ModelUnit(name, rb.model, rb.parameters)
        elif rb.model is not None:
            from ..fmi.fmu_block import FmuUnit, model_fmu_info

            try:
                from ...fmu_src.export import build_fmu
            except ImportError as exc:
                raise SceneError(f"block '{name}': FMU export is not available ({exc}); "
                                 "set master.backend = casadi to run models in-process") from None
            next_block()
            path = cached_fmu(rb.model, build_fmu, f"block '{name}'")
            info = model_fmu_info(rb.model, Path(path), name)
            units[name] = FmuUnit(name, info, rb.parameters, _fmu_mode(master.coupling, info, name))
        elif rb.fmu_info is not None:
            from ..fmi.fmu_block import FmuUnit

            units[name] = FmuUnit(name, rb.fmu_info, rb.parameters, _fmu_mode(master.coupling, rb.fmu_info, name))
        else:  # pragma: no cover
            raise SceneError(f"block '{name}' ({rb.spec.kind}) cannot be instantiated")
    return units


def _fmu_mode(coupling: str, info: Any, name: str) -> str:
    if coupling == "mixed":   # the ODE takes every FMU it can
        return "me" if info.has_me else "cs"
    if coupling == "strong":
        if not info.has_me:
            raise SceneError(f"block '{name}': the FMU has no Model Exchange interface, needed by "
                             "master.coupling = strong; use jacobi or gauss-seidel")
        return "me"
    return "cs" if info.has_cs else "me"


class Simulator:
    """Steps one run of a plan. Not reusable: make a new one per run (blocks are built per run).

    record: keep the requested signals at every recorded point (a plant stepped for hours passes
    False; the guards still judge every point). progress: called with the simulation time now
    and then (a progress bar).
    """

    def __init__(self, plan: Plan, *, record: bool = True,
                 progress: Callable[[float], None] | None = None) -> None:
        t_build = time.perf_counter()
        self.plan = plan
        self.master = plan.scene.master
        self.t_end_s = plan.t_end_s
        self.units = build_units(plan)
        self.system = System(plan, self.units)
        self.context = Context()
        refs, requested = [], []
        for ref in plan.requested:
            block, k = self.system.output_node(ref)
            refs.append((self.units[block].outbuf, k))
            requested.append(plan.canonical(ref))
        # judged from one stroke period in (a tenth of the run without a stroke): see PassiveEnergyGuard
        guards = passive_energy_guards(self.units, {n: plan.blocks[n].passivity for n in self.units},
                                       self.master.passive_energy_factor, plan.period_s or 0.1 * plan.t_end_s)
        self.recording = Recording(requested, refs, guards, keep_rows=record, progress=progress)
        self.coupling: StrongCoupling | MixedCoupling | WeakCoupling
        pace = RealTimePacer(self.context) if self.master.realtime else None
        if self.master.coupling == "strong":
            self.coupling = StrongCoupling(self.system, self.context, self.recording)
        elif self.master.coupling == "mixed":
            self.coupling = MixedCoupling(self.system, self.context, self.recording, pace)
        else:
            self.coupling = WeakCoupling(self.system, self.context, self.recording, pace)
        self.started: list[Unit] = []
        self.initialized = False
        self.closed = False
        self.context.stats["build_s"] = time.perf_counter() - t_build

    # --- lifecycle ------------------------------------------------------------------------
    def initialize(self, t0_s: float = 0.0) -> None:
        """Start every block (FMUs instantiated, hardware connected), make inputs and outputs
        consistent at t0_s and record the first point. Close() the simulator on any exit path."""
        if self.initialized:
            raise StepError("master", self.context.t, "initialize() called twice", cause="a Simulator runs once")
        self.initialized = True
        for u in self.units.values():
            self.context.t = t0_s
            self.started.append(u)
            u.start(t0_s, self.t_end_s, self.master.rtol)
        self.coupling.initialize(t0_s, self.t_end_s)

    def advance_to(self, t_s: float) -> float:
        """Advance to t_s (at most the plan's end); returns the time reached (earlier only if a
        block asked to terminate: see `ended`). Raises StepError naming block and time on a failure."""
        if not self.initialized or self.closed:
            raise StepError("master", self.context.t, "advance_to() before initialize() or after close()",
                            cause="call initialize() first; a closed simulator cannot continue")
        if t_s > self.t_end_s * (1 + 1e-12) + 1e-12:
            raise StepError("master", self.context.t, f"advance_to({t_s:g} s) is past the run's end "
                            f"({self.t_end_s:g} s)", cause="set master.t_end_s or periods longer")
        t = self.coupling.advance_to(min(t_s, self.t_end_s))
        self.context.t = t
        return t

    @property
    def t(self) -> float:
        return self.context.t

    @property
    def ended(self) -> tuple[str, float] | None:
        """(the block(s) that asked to terminate, the time the run ended), when a block ended the
        run before its end (FMI terminateSimulation: the model is done; not an error)."""
        return self.coupling.ended if self.initialized else None

    def close(self) -> None:
        """Close every started block (in start order; a hardware servo commands its safe
        position), then free the solvers. Safe to call more than once."""
        if self.closed:
            return
        self.closed = True
        for u in self.started:
            u.close()
        self.coupling.close()

    def __enter__(self) -> "Simulator":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- ports ----------------------------------------------------------------------------
    def _port(self, ref: str) -> tuple[Unit, str, int]:
        port = PortRef.parse(ref)
        c = self.plan.canonical(port)
        u = self.units.get(c.block)
        if u is None:
            raise SceneError(f"read/write '{ref}': block '{port.block}' is not instantiated in this run; "
                             f"instantiated: {', '.join(self.units)}")
        if c.port in u.output_names:
            return u, "out", u.output_names.index(c.port)
        if c.port in u.input_names:
            return u, "in", u.input_names.index(c.port)
        raise SceneError(f"block '{c.block}' has no port '{c.port}'; outputs: {', '.join(u.output_names)}; "
                         f"inputs: {', '.join(u.input_names)}")

    def read(self, ref: str) -> float:
        """The current value of port "block.port" (an output is evaluated now if its block can be
        asked again; a hardware block's is its last reading)."""
        u, kind, i = self._port(ref)
        if kind == "in":
            return float(u.inbuf[i])
        if self.initialized and not self.closed and u.can_iterate:
            u.output_getter([i])()
        return float(u.outbuf[i])

    def write(self, ref: str, value: float) -> None:
        """Set an output of a source block from outside (a constant block's value: the command
        a plant receives, the flow speed); it holds until written again. The coupling treats it
        as a jump at the current time."""
        u, kind, i = self._port(ref)
        block = getattr(u, "block", None)
        if kind != "out" or not hasattr(block, "set_output"):
            raise SceneError(f"'{ref}' cannot be written: only outputs of source blocks (kind = \"constant\") can")
        block.set_output(u.output_names[i], float(value))
        u.output_getter([i])()
        if self.initialized and not self.closed:
            self.coupling.input_changed(self.context.t)

    def recorded(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """(time, {"block.port": values}) of the requested signals recorded so far (whole samples),
        each in its port's own type (featherstar.cosim.fmi.fmi_types.typed_signal)."""
        rec = self.recording
        n = min(len(rec.rows), len(rec.times))
        data = np.asarray(rec.rows[:n], dtype=float).reshape(n, len(self.plan.requested))
        return (np.asarray(rec.times[:n], dtype=float),
                {str(ref): typed_signal(self.plan.blocks[ref.block].outputs[ref.port].type, data[:, j].copy())
                 for j, ref in enumerate(self.plan.requested)})

    # --- state ----------------------------------------------------------------------------
    def save_state(self) -> Any:
        """A snapshot to return to with restore_state (free it with free_state). Needs every block
        to roll back (FMUs with canGetAndSetFMUstate, models, memoryless and RollbackBlock blocks)."""
        stuck = [u.name for u in self.units.values() if not u.can_rollback]
        if stuck:
            raise SceneError(f"cannot save the simulation state: block(s) {', '.join(stuck)} cannot save and "
                             "restore their state")
        return self.context.t, self.coupling.get_state()

    def restore_state(self, state: Any) -> None:
        """Back to a snapshot; the points recorded after it are dropped."""
        t, inner = state
        self.coupling.set_state(inner)
        self.context.t = t
        self.recording.truncate_after(t)

    def free_state(self, state: Any) -> None:
        self.coupling.free_state(state[1])

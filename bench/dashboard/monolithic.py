"""The monolithic reference: a whole scene composed symbolically into one CasADi ODE.

Every block becomes CasADi expressions — the stroke controller via `root_motion_symbolic(t, ...)`,
model blocks via their Model's equations with fresh state symbols, constants and gains as
expressions — and each input is replaced by the expression of the output that drives it
(repeated substitution in dependency order). The result is one explicit ODE x' = f(t, x),
integrated by CasADi's CVODES at a tight tolerance on the scene's output grid, and the requested
signals are evaluated on that grid. Deduplication is switched off here on purpose: the robot's
two feathers are both integrated, which makes this an independent check of the master's dedup.

Only scenes made of CasADi-expressible blocks can be composed (no external FMU files, no
stateful Python blocks) and without algebraic loops; anything else is a SceneError.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Any, Mapping, Sequence

import casadi as ca
import numpy as np

from ..cosim.coupling.native import casadi_library
from ..cosim.errors import SceneError, StepError
from ..cosim.scene.data import PortRef, Scene
from ..cosim.scene.graph import plan as make_plan
from ..cosim.scenes import load_scene


def compose(scene: Scene, outputs: Sequence[str] | None = None) -> dict[str, Any]:
    """The scene as one ODE: dict(t, x, x0, xdot, signals: {name: expr}, plan, state_blocks)."""
    scene = dataclasses.replace(scene, master=dataclasses.replace(scene.master, dedup=False))
    plan = make_plan(scene, outputs)
    t = ca.SX.sym("t")
    states, x0, xdots, state_blocks = [], [], [], []
    out_expr: dict[PortRef, ca.SX] = {}
    in_sym: dict[PortRef, ca.SX] = {}
    for name in plan.instantiate:
        rb = plan.blocks[name]
        kind = rb.spec.kind
        u_syms = {port: ca.SX.sym(f"{name}.{port}") for port in rb.inputs}
        for port, s in u_syms.items():
            in_sym[PortRef(name, port)] = s
        if kind == "stroke":
            st = rb.obj.stroke
            a, r, acc = _stroke_expr(t, st)
            out_expr.update({PortRef(name, "angle_rad"): a, PortRef(name, "rate_rad_s"): r,
                             PortRef(name, "accel_rad_s2"): acc})
        elif kind == "constant":
            for port, v in rb.obj.values.items():
                out_expr[PortRef(name, port)] = ca.SX(v)
        elif kind == "gain":
            out_expr[PortRef(name, "y")] = rb.obj.gain * u_syms["u"] + rb.obj.offset
        elif rb.model is not None:
            model = rb.model
            x = ca.SX.sym(f"{name}.x", model.x.numel())
            u = ca.vertcat(*[u_syms[v.name] for v in model.inputs]) if model.inputs else ca.SX(0, 1)
            p = ca.DM(model.parameter_vector(rb.parameters))
            xdot, y = model.function()(x, u, p)
            states.append(x)
            x0.extend(model.initial_state())
            xdots.append(xdot)
            state_blocks.append((name, model.x.numel()))
            for k, v in enumerate(model.outputs):
                out_expr[PortRef(name, v.name)] = y[k]
        else:
            raise SceneError(f"block '{name}' ({kind}) cannot be composed into the monolithic CasADi "
                             "reference: only stroke, constant, gain and model blocks can", scene.name)
    if plan.loops:
        raise SceneError(f"the monolithic reference cannot compose the algebraic loop {plan.loops[0].describe()}",
                         scene.name)
    # substitute inputs by their drivers until no input symbol remains
    u_all = ca.vertcat(*in_sym.values()) if in_sym else ca.SX(0, 1)
    drivers = ca.vertcat(*[out_expr[plan.source_of[ref]] for ref in in_sym]) if in_sym else ca.SX(0, 1)
    for _ in range(len(in_sym) + 1):
        if not in_sym or not ca.depends_on(drivers, u_all):
            break
        drivers = ca.substitute(drivers, u_all, drivers)
    else:
        raise SceneError("the monolithic reference could not resolve the connections (a loop?)", scene.name)
    xdot = ca.vertcat(*xdots) if xdots else ca.SX(0, 1)
    if in_sym:
        xdot = ca.substitute(xdot, u_all, drivers)
    signals = {}
    for ref in plan.requested:
        e = out_expr[ref]
        signals[str(ref)] = ca.substitute(e, u_all, drivers) if in_sym else e
    x = ca.vertcat(*states) if states else ca.SX(0, 1)
    return dict(t=t, x=x, x0=np.array(x0, dtype=float), xdot=xdot, signals=signals, plan=plan,
                state_blocks=state_blocks)


def _stroke_expr(t: ca.SX, stroke: Any) -> tuple[ca.SX, ca.SX, ca.SX]:
    from ..cosim.swimmer.stroke import root_motion_symbolic

    return root_motion_symbolic(t, stroke.t_up_s, stroke.t_hold_up_s, stroke.t_down_s, stroke.t_hold_down_s,
                                stroke.amplitude_rad)


def run_monolithic(
    scene: str | Scene,
    overrides: Mapping[str, Any] | None = None,
    *,
    outputs: Sequence[str] | None = None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_num_steps: int = 10_000_000,
    method: str = "bdf",
    compiled: bool = False,
) -> Any:
    """Integrate the composed scene with CVODES; returns a RunResult like run_scene's.

    compiled: generate C for the right-hand side and the output function, compile it (gcc -O1,
    cached by the functions' hash; the first build of a flapped feather takes ~40 s) and
    integrate through `casadi.external`. With method="adams" CVODES then uses functional
    iteration (no Jacobian); otherwise finite-difference Jacobians. The default (False) is plain
    CasADi: CVODES on the expression graph, evaluated by CasADi's virtual machine."""
    from ..cosim.swimmer.metrics import scene_metrics
    from ..cosim.swimmer.run import RunResult

    wall0 = time.perf_counter()
    sc = load_scene(scene).with_overrides(overrides)
    c = compose(sc, outputs)
    plan = c["plan"]
    m = sc.master
    t_end = plan.t_end_s
    n = int(np.floor(t_end / m.output_interval_s + 1e-9))
    grid = m.output_interval_s * np.arange(n + 1)
    if grid[-1] < t_end - 1e-12:
        grid = np.append(grid, t_end)
    t, x = c["t"], c["x"]
    opts = {"reltol": rtol, "abstol": atol, "max_num_steps": max_num_steps,
            "linear_multistep_method": method, "newton_scheme": "direct"}
    names = list(c["signals"])
    fout = ca.Function("signals", [x, t], [ca.vertcat(*c["signals"].values())])
    compile_s = 0.0
    if compiled and x.numel():
        t_c = time.perf_counter()
        fode, fout = _compiled(ca.Function("ode", [x, t], [c["xdot"]]), fout)
        compile_s = time.perf_counter() - t_c
        X, T = ca.MX.sym("x", x.numel()), ca.MX.sym("t")
        dae = {"x": X, "t": T, "ode": fode(X, T)}
        if method == "adams":  # no Jacobian needed: functional iteration
            opts["nonlinear_solver_iteration"] = "functional"
    else:
        dae = {"x": x, "t": t, "ode": c["xdot"]}
    t_int = time.perf_counter()
    try:
        if x.numel():
            F = ca.integrator("monolithic", "cvodes", dae, 0.0, grid[1:], opts)
            xs = np.hstack([c["x0"][:, None], np.array(F(x0=c["x0"])["xf"])])
        else:
            xs = np.zeros((0, len(grid)))
    except RuntimeError as exc:
        raise StepError("monolithic", float("nan"), f"CVODES failed: {exc}", function="cvodes") from None
    integrate_s = time.perf_counter() - t_int
    ys = np.array(fout.map(len(grid))(xs, grid.reshape(1, -1)))
    signals = {nm: ys[k].copy() for k, nm in enumerate(names)}
    units = {str(ref): plan.blocks[ref.block].outputs[ref.port].unit for ref in plan.requested}
    summary: dict[str, Any] = {"scene": sc.name, "coupling": "monolithic", "rtol": rtol, "atol": atol,
                               "t_end_s": t_end, "period_s": plan.period_s,
                               "method": method, "compiled": compiled,
                               "stats": {"integrate_s": integrate_s, "compile_s": compile_s,
                                         "states": int(x.numel())}}
    summary.update(scene_metrics(sc.metrics, plan.period_s, grid, signals))
    summary["wall_time_s"] = time.perf_counter() - wall0 - compile_s  # compilation is cached: reported apart
    return RunResult(sc, grid, signals, units, summary, {"instantiated": list(plan.instantiate)})


def _compiled(fode: ca.Function, fout: ca.Function) -> tuple[ca.Function, ca.Function]:
    """C code for the ODE and output functions, compiled once and cached by their hash."""
    lib = casadi_library([fode, fout], flags=("-O1",))
    opts = {"enable_fd": True}
    return ca.external(fode.name(), str(lib), opts), ca.external(fout.name(), str(lib), opts)

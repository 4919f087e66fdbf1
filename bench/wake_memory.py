"""Would a wake stop the plain feather from gaining thrust by stroke timing? A mechanism study.

featherstar's fluid model is quasi-steady: each point's drag follows its own velocity now, with
the oscillatory-flow coefficient C_d(KC) of Luhar & Nepf (2016). For a rigid plate that makes the
drag-only TR exactly t_up/t_down, so the optimizer lifts the plain feather to TR 1.38 where the
paper measures TR ≲ 1 (docs/model.md). The candidate mechanism is wake memory: the water a fast
stroke sets moving is still moving when the plate stops and when it returns.

This study adds one wake state per strip (the normal velocity u of the water the strip drags
along) to a rigid plate pivoting at its root, with the energy-consistent reactive force
−m_a r (θ̈ n − θ̇² e) of featherstar's model:

    drag on the strip   D = −½ ρ C_0 A s|s|,   s = v_n − u        (velocity relative to the wake)
    wake                w u̇ = B s|s| − decay(u, s, v_n) / γ

with three decay laws: the plate leaves its wake ("relative": u|s|), the wake convects itself
away ("self": u|u|), the wake is left behind at the plate's speed ("plate": u|v_n|).
The constants (C_0, B, γ) of each law are fitted jointly to the sinusoidal plate data (the
Fourier-averaged drag coefficient of a strip oscillating at KC must follow Luhar & Nepf's
max(10 KC^(−1/3), 1.95) for KC 2–400) and to the steady plate's drag (C_0 s² once the wake has
settled must be STEADY_PLATE_DRAG_COEFF), one more point of the same least squares. Nothing is
fitted to the paper. These are the constants of the feather model's `wake` option
(featherstar.fmu_src.fluid.WAKE_CONSTANTS; tests/fmu_src/test_wake_physics.py checks they are this
JSON's); the laws are written here again in numpy, independently of the model, which a test
compares with. Then every law predicts the rigid plate's TR under the paper's symmetric stroke and
its best TR over the servo-feasible strokes (a grid), next to the quasi-steady model.

Writes <out>/wake_memory.json and <out>/wake_memory.png (default docs/results).

    python bench/wake_memory.py [--out DIR] [--quick]      (~10 min alone on 2 cores, 22 min under load; --quick ~5 min)
"""
from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import minimize

ROOT = Path(__file__).resolve().parents[1]

from featherstar.cosim.swimmer.stroke import Stroke, root_motion  # noqa: E402
from featherstar.fmu_src.fluid import dnv_added_mass_coeff, oscillatory_drag_coeff, stroke_keulegan_carpenter  # noqa: E402

WATER_DENSITY_KG_M3 = 1000.0
WIDTH_M, LENGTH_M = 0.075, 0.115  # the paper's feather
STRIPS = 16
#: A flat plate broadside to a steady stream (Hoerner, Fluid-Dynamic Drag, 1965, ch. 3: 1.17 for a
#: square plate, 1.2 at aspect ratio 1.5, the feather's l/w): the wake laws' other fit point.
STEADY_PLATE_DRAG_COEFF = 1.2
MIN_RAMP_S, MIN_PHASE_S = 0.32, 0.02  # servo limits of optimizer/space.py at 60°, 1.5 s

DecayLaw = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
DECAY_LAWS: dict[str, DecayLaw] = {
    "relative": lambda u, s, v: u * np.abs(s),
    "self": lambda u, s, v: u * np.abs(u),
    "plate": lambda u, s, v: u * np.abs(v),
}


@dataclass(frozen=True)
class WakeModel:
    """A decay law and its constants; velocities in m/s, `B` and `gamma_widths` dimensionless."""

    law: str
    drag_coeff_0: float
    forcing_B: float
    gamma_widths: float

    def rate(self, u: np.ndarray, s: np.ndarray, v: np.ndarray, width_m: float) -> np.ndarray:
        """du/dt (m/s²) of the wake velocity u given relative velocity s and plate velocity v."""
        return (self.forcing_B * s * np.abs(s) - DECAY_LAWS[self.law](u, s, v) / self.gamma_widths) / width_m


def luhar_nepf(kc: np.ndarray) -> np.ndarray:
    return np.array([float(oscillatory_drag_coeff(float(k))) for k in np.atleast_1d(kc)])


def sinusoidal_drag_coeff(model: WakeModel, kc: float, periods: int = 10) -> float:
    """Fourier-averaged drag coefficient of a strip oscillating at KC = 2πa/w (velocity scale 1,
    width 1): C_d = ∫F v dt / (½ T 4/(3π)), the Morison coefficient that dissipates the same work."""
    period = kc  # v = cos(2π t / KC) in units of w and U_max
    omega = 2 * math.pi / period

    def rhs(t: float, u: np.ndarray) -> np.ndarray:
        v = math.cos(omega * t)
        return model.rate(u, v - u, np.array(v), 1.0)

    t = np.linspace((periods - 1) * period, periods * period, 1001)
    sol = solve_ivp(rhs, (0, periods * period), [0.0], t_eval=t, rtol=1e-7, atol=1e-9, method="LSODA")
    if not sol.success:
        raise RuntimeError(f"wake law '{model.law}' at KC {kc}: {sol.message}")
    v = np.cos(omega * t)
    s = v - sol.y[0]
    work = np.trapezoid(0.5 * model.drag_coeff_0 * s * np.abs(s) * v, t)
    return float(work / (0.5 * period * 4 / (3 * math.pi)))


def steady_drag_coeff(model: WakeModel) -> float:
    """Drag coefficient of a strip moving at constant speed once its wake has settled: C_0 s²
    (speed 1, width 1), the wake integrated from rest over 2000 widths of travel."""
    sol = solve_ivp(lambda t, u: model.rate(u, 1.0 - u, np.array(1.0), 1.0), (0.0, 2000.0), [0.0],
                    rtol=1e-9, atol=1e-12, method="LSODA")
    if not sol.success:
        raise RuntimeError(f"wake law '{model.law}', steady plate: {sol.message}")
    return float(model.drag_coeff_0 * (1.0 - sol.y[0, -1]) ** 2)


def fit_wake_model(law: str, kcs: np.ndarray, steady: bool = True) -> tuple[WakeModel, float]:
    """Least squares in log C_d against Luhar & Nepf over `kcs` and, with `steady`, the steady
    plate's STEADY_PLATE_DRAG_COEFF as one more point; returns the model and rms log error."""
    target = np.log(luhar_nepf(kcs))

    def error(log_params: np.ndarray) -> float:
        model = WakeModel(law, *np.exp(log_params))
        fitted = np.array([sinusoidal_drag_coeff(model, k) for k in kcs])
        residual = np.sum((np.log(fitted) - target) ** 2)
        if steady:
            residual += (math.log(steady_drag_coeff(model)) - math.log(STEADY_PLATE_DRAG_COEFF)) ** 2
        return float(residual)

    starts = [(1.0, 0.0, 0.0), (2.0, -1.0, 1.0), (1.0, 1.0, -1.0), (2.0, 0.0, 2.0)]
    best = min((minimize(error, np.array(x0), method="Nelder-Mead",
                         options={"maxiter": 300, "xatol": 1e-3, "fatol": 1e-5}) for x0 in starts),
               key=lambda r: r.fun)
    return WakeModel(law, *map(float, np.exp(best.x))), math.sqrt(best.fun / (len(kcs) + steady))


class RigidPlate:
    """The paper's plate pivoting at its root, in strips; thrust along ŷ (downstroke positive)."""

    def __init__(self, strips: int = STRIPS) -> None:
        edges = np.linspace(0.0, LENGTH_M, strips + 1)
        self.radius_m = 0.5 * (edges[1:] + edges[:-1])
        self.area_m2 = WIDTH_M * np.diff(edges)
        coeff = float(dnv_added_mass_coeff(LENGTH_M / WIDTH_M))
        self.added_mass_kg = coeff * WATER_DENSITY_KG_M3 * math.pi * WIDTH_M**2 / 4 * np.diff(edges)

    def reactive_thrust_N(self, theta: np.ndarray, rate: np.ndarray, accel: np.ndarray) -> np.ndarray:
        return -np.sum(self.added_mass_kg * self.radius_m) * (accel * np.cos(theta) - rate**2 * np.sin(theta))

    def drag_thrust_N(self, theta: np.ndarray, relative_velocity: np.ndarray, drag_coeff: np.ndarray | float) -> np.ndarray:
        normal_force = -0.5 * WATER_DENSITY_KG_M3 * drag_coeff * self.area_m2 * relative_velocity * np.abs(relative_velocity)
        return normal_force.sum(axis=1) * np.cos(theta)

    def thrust_N(self, stroke: Stroke, model: WakeModel | None, periods: int = 6,
                 samples: int = 6001) -> tuple[np.ndarray, np.ndarray]:
        """Thrust over the last of `periods` periods; `model` None is featherstar's quasi-steady law."""
        period = stroke.period_s
        t = np.linspace((periods - 1) * period, periods * period, samples)
        theta, rate, accel = np.array([root_motion(stroke, x) for x in t]).T
        velocity = np.outer(rate, self.radius_m)
        if model is None:
            kc = stroke_keulegan_carpenter(self.radius_m, stroke.amplitude_rad, WIDTH_M)
            drag = self.drag_thrust_N(theta, velocity, luhar_nepf(kc))
        else:
            def rhs(time_s: float, u: np.ndarray) -> np.ndarray:
                v = root_motion(stroke, time_s)[1] * self.radius_m
                return model.rate(u, v - u, v, WIDTH_M)

            sol = solve_ivp(rhs, (0, periods * period), np.zeros_like(self.radius_m), t_eval=t, rtol=1e-7,
                            atol=1e-10, method="LSODA", max_step=period / 400)
            if not sol.success:
                raise RuntimeError(f"rigid plate, wake law '{model.law}', stroke {stroke}: {sol.message}")
            drag = self.drag_thrust_N(theta, velocity - sol.y.T, model.drag_coeff_0)
        return t, drag + self.reactive_thrust_N(theta, rate, accel)


def thrust_ratio(thrust: np.ndarray) -> float:
    return float(thrust[thrust > 0].sum() / -thrust[thrust < 0].sum())


def feasible_strokes(period_s: float, quick: bool) -> list[Stroke]:
    """A grid over the servo-feasible 4-phase strokes of one period (ramps ≥ 0.32 s, holds ≥ 0.02 s)."""
    downs = [0.32, 0.55] if quick else [0.32, 0.4, 0.55]
    ups = [0.32, 0.7, 1.1] if quick else [0.32, 0.45, 0.6, 0.75, 0.9, 1.1]
    strokes = []
    for t_down in downs:
        for t_up in ups:
            hold = period_s - t_up - t_down
            if hold < 2 * MIN_PHASE_S:
                continue
            for fraction in ([MIN_PHASE_S / hold, 0.5, 1 - MIN_PHASE_S / hold] if quick else
                             [MIN_PHASE_S / hold, 0.25, 0.5, 0.75, 1 - MIN_PHASE_S / hold]):
                strokes.append(Stroke(t_up, hold * fraction, t_down, hold * (1 - fraction)))
    return strokes


def run(out: Path, quick: bool) -> dict:
    started = time.perf_counter()
    kcs = np.geomspace(2, 100, 5 if quick else 9).tolist() + [400.0]
    plate = RigidPlate()
    symmetric = Stroke(0.25, 0.5, 0.25, 0.5)
    strokes = feasible_strokes(symmetric.period_s, quick)
    models: dict[str, WakeModel | None] = {"quasi-steady": None}
    result: dict = {"kc_fit_points": kcs, "laws": {}}
    for law in DECAY_LAWS:
        model, rms = fit_wake_model(law, np.array(kcs))
        models[law] = model
        result["laws"][law] = {"drag_coeff_0": model.drag_coeff_0, "forcing_B": model.forcing_B,
                               "gamma_widths": model.gamma_widths, "fit_rms_log": rms,
                               "steady_drag_coeff": steady_drag_coeff(model),
                               "fitted_drag_coeff": [sinusoidal_drag_coeff(model, k) for k in kcs]}
        print(f"{law}: C_0 {model.drag_coeff_0:.2f}, B {model.forcing_B:.3f}, γ {model.gamma_widths:.2f} w, "
              f"rms log error {rms:.3f}", flush=True)
    result["rigid_plate"] = {}
    for name, model in models.items():
        _, symmetric_thrust = plate.thrust_N(symmetric, model)
        ratios = [thrust_ratio(plate.thrust_N(s, model)[1]) for s in strokes]
        best = int(np.argmax(ratios))
        result["rigid_plate"][name] = {
            "symmetric_thrust_ratio": thrust_ratio(symmetric_thrust),
            "best_thrust_ratio": ratios[best],
            "best_stroke_s": [strokes[best].t_up_s, strokes[best].t_hold_up_s, strokes[best].t_down_s,
                              strokes[best].t_hold_down_s],
            "thrust_ratio_by_stroke": ratios,
        }
        print(f"{name}: symmetric TR {thrust_ratio(symmetric_thrust):.3f}, best TR {ratios[best]:.3f} "
              f"(up/hold/down/hold {np.round(result['rigid_plate'][name]['best_stroke_s'], 2).tolist()} s)", flush=True)
    result["strokes_s"] = [[s.t_up_s, s.t_hold_up_s, s.t_down_s, s.t_hold_down_s] for s in strokes]
    result["seconds"] = time.perf_counter() - started
    out.mkdir(parents=True, exist_ok=True)
    (out / "wake_memory.json").write_text(json.dumps(result, indent=1))
    plot(result, models, plate, out / "wake_memory.png")
    return result


def plot(result: dict, models: dict[str, WakeModel | None], plate: RigidPlate, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from featherstar.cosim.plotstyle import save_figure

    fig, (fit_ax, tr_ax, time_ax) = plt.subplots(1, 3, figsize=(15, 4.2))
    kc_line = np.geomspace(2, 400, 100)
    fit_ax.semilogx(kc_line, luhar_nepf(kc_line), "k-", label="Luhar & Nepf 2016 fit")
    for law, fit in result["laws"].items():
        fit_ax.semilogx(result["kc_fit_points"], fit["fitted_drag_coeff"], "o--", label=f"wake, {law} decay")
    fit_ax.set(xlabel="KC", ylabel="Fourier-averaged drag coefficient $C_d$", title="Sinusoidal oscillation: what the wake laws are fitted to")
    fit_ax.legend(fontsize=8)
    names = list(result["rigid_plate"])
    x = np.arange(len(names))
    tr_ax.bar(x - 0.2, [result["rigid_plate"][n]["symmetric_thrust_ratio"] for n in names], 0.4, label="symmetric stroke")
    tr_ax.bar(x + 0.2, [result["rigid_plate"][n]["best_thrust_ratio"] for n in names], 0.4, label="best feasible stroke")
    tr_ax.axhline(1.15, color="r", lw=0.8, ls=":", label="paper's plain feather: TR ≲ 1 (band 1.15)")
    tr_ax.set_xticks(x, names, rotation=15)
    tr_ax.set(xlabel="drag model", ylabel="TR of a rigid plate", title="Rigid plate (drag + reactive)")
    tr_ax.legend(fontsize=8)
    best_stroke = Stroke(*result["rigid_plate"]["quasi-steady"]["best_stroke_s"])
    for name, model in models.items():
        t, thrust = plate.thrust_N(best_stroke, model)
        time_ax.plot(t - t[0], thrust * 1e3, label=name)
    time_ax.set(xlabel="time in period (s)", ylabel="thrust (mN)",
                title="Thrust under the quasi-steady model's best stroke")
    time_ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results", help="where the JSON and plot go")
    parser.add_argument("--quick", action="store_true", help="fewer fit points and strokes (~5 min)")
    args = parser.parse_args(argv)
    run(args.out, args.quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The strong coupling's compiled right-hand side (featherstar.cosim.coupling.compiled_rhs): the same
numbers as the Python path, FMI statuses answered as the standard says (Discard: retry with a
smaller step; Error: stop naming the block, the function and the time)."""
from __future__ import annotations

import ctypes
import math
import shutil
import subprocess
from ctypes import c_double

import numpy as np
import pytest
from conftest import OSCILLATOR, make_scene
from featherstar.cosim.coupling.context import Context
from featherstar.cosim.coupling.ode_group import OdeGroup
from featherstar.cosim.errors import StepError
from featherstar.cosim.framework.units import NativeCalls, Unit
from featherstar.cosim.swimmer.run import run_scene
from featherstar.cosim.swimmer.stroke import Stroke, root_motion, root_motion_function

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="the compiled right-hand side needs gcc")


def _same_runs(a, b) -> None:
    assert np.array_equal(a.time, b.time)
    for name in a.signals:
        assert np.array_equal(a[name], b[name]), name


@pytest.mark.parametrize("changes", [
    {},   # two ME FMUs, outputs copied into inputs in C
    # a memoryless Python block in the loop between the FMUs: a Python step called back from C
    {"connections": ["a.position_m -> b.other_position_m", "a.velocity_m_s -> b.other_velocity_m_s",
                     "b.force_N -> gain.u", "gain.y -> a.force_N"],
     "blocks": {"gain": {"kind": "gain", "gain": 0.5, "unit_in": "N", "unit_out": "N"}}},
], ids=["fmus", "python-block-between"])
def test_compiled_and_python_right_hand_sides_give_the_same_run(changes):
    scene = make_scene(OSCILLATOR, **changes)
    compiled = run_scene(scene)
    python = run_scene(scene, {"master.compiled_rhs": "false"})
    assert compiled.summary["stats"]["rhs"] == "compiled"
    assert python.summary["stats"]["rhs"].startswith("python")
    assert compiled.summary["stats"]["rhs_evals"] == python.summary["stats"]["rhs_evals"]
    _same_runs(compiled, python)


def test_stroke_time_function_matches_the_python_stroke():
    """The stroke controller runs in C as its CasADi function: the same motion as root_motion."""
    stroke = Stroke(t_up_s=0.2, t_hold_up_s=0.45, t_down_s=0.35, t_hold_down_s=0.5, amplitude_deg=50.0)
    fn = root_motion_function()
    p = [stroke.t_up_s, stroke.t_hold_up_s, stroke.t_down_s, stroke.t_hold_down_s, stroke.amplitude_rad]
    for t in np.linspace(0.0, 4.5, 997):
        expected = root_motion(stroke, float(t))
        got = [float(v) for v in fn(t, p)]
        assert got == pytest.approx(expected, rel=1e-12, abs=1e-12)


# --- FMI statuses, on a unit whose C entry points a test library provides ----------------------

DECAY_C = r"""
/* x' = -x with fmi3-shaped entry points; GetContinuousStateDerivatives answers `bad_status` on
   call number `bad_call` (counted from 1) and OK otherwise. */
#include <stddef.h>
typedef struct { double t, x; int calls, bad_call, bad_status; } decay;
int set_time(void* inst, double t) { ((decay*)inst)->t = t; return 0; }
int set_states(void* inst, const double* x, size_t n) { ((decay*)inst)->x = x[0]; return 0; }
int get_derivatives(void* inst, double* dx, size_t n) {
  decay* d = (decay*)inst;
  d->calls++;
  if (d->calls == d->bad_call) return d->bad_status;
  dx[0] = -d->x;
  return 0;
}
"""


class _Decay(ctypes.Structure):
    _fields_ = [("t", c_double), ("x", c_double), ("calls", ctypes.c_int), ("bad_call", ctypes.c_int),
                ("bad_status", ctypes.c_int)]


@pytest.fixture(scope="module")
def decay_library(tmp_path_factory):
    folder = tmp_path_factory.mktemp("decay")
    (folder / "decay.c").write_text(DECAY_C)
    subprocess.run(["gcc", "-O1", "-shared", "-fPIC", str(folder / "decay.c"), "-o", str(folder / "decay.so")],
                   check=True)
    return ctypes.CDLL(str(folder / "decay.so"))


class DecayUnit(Unit):
    """A continuous unit with C entry points only (what an ME FMU offers the compiled path)."""

    continuous = True
    n_states = 1

    def __init__(self, library: ctypes.CDLL, bad_call: int, bad_status: int) -> None:
        super().__init__("decay", [], [])
        self.library = library
        self.memory = _Decay(0.0, 1.0, 0, bad_call, bad_status)

    def get_states(self, address: int) -> None:
        ctypes.memmove(address, ctypes.addressof(self.memory) + _Decay.x.offset, 8)

    def native_calls(self) -> NativeCalls:
        def address(name: str) -> int:
            return ctypes.cast(getattr(self.library, name), ctypes.c_void_p).value
        return NativeCalls(instance=ctypes.addressof(self.memory), fmi3=True, set_time=address("set_time"),
                           set_states=address("set_states"), get_derivatives=address("get_derivatives"),
                           set_float64=0, get_float64=0, value_refs_in=(), value_refs_out=(),
                           inputs=frozenset(), outputs=frozenset())


def _integrate(unit: DecayUnit, t_end: float = 1.0) -> tuple[OdeGroup, Context]:
    context = Context()
    group = OdeGroup(None, context, [unit], [], 0.0, method="adams", rtol=1e-8, atol=1e-10)
    assert context.stats["rhs"] == "compiled"
    group.cv.advance(t_end)
    return group, context


def test_discard_from_the_derivatives_makes_the_solver_retry(decay_library):
    """FMI: a Discard from GetContinuousStateDerivatives asks for a smaller step, not the end."""
    unit = DecayUnit(decay_library, bad_call=40, bad_status=2)
    group, _ = _integrate(unit)
    assert unit.memory.calls > 40   # the discarded call happened, and integration went on
    assert group.cv.y[0] == pytest.approx(math.exp(-1.0), rel=1e-6)


def test_error_from_the_derivatives_stops_naming_block_function_and_time(decay_library):
    unit = DecayUnit(decay_library, bad_call=40, bad_status=3)
    with pytest.raises(StepError) as err:
        _integrate(unit)
    exc = err.value
    assert exc.block == "decay"
    assert "GetContinuousStateDerivatives" in str(exc)
    assert 0.0 < exc.t_s < 1.0
    assert unit.memory.calls == 40   # nothing was called after the failing op


def test_without_gcc_the_python_path_runs_and_says_why(monkeypatch):
    import featherstar.cosim.coupling.compiled_rhs as compiled_rhs
    from featherstar.cosim.coupling.native import NativeBuildError

    def no_gcc(*args, **kwargs):
        raise NativeBuildError("cannot run gcc: [Errno 2] No such file or directory: 'gcc'")

    monkeypatch.setattr(compiled_rhs, "shared_library", no_gcc)
    monkeypatch.setattr(compiled_rhs, "casadi_library", no_gcc)
    scene = make_scene(OSCILLATOR)
    fallback = run_scene(scene)
    assert fallback.summary["stats"]["rhs"] == "python (cannot run gcc: [Errno 2] No such file or directory: 'gcc')"
    monkeypatch.undo()
    _same_runs(fallback, run_scene(scene))


class PythonDecayUnit(DecayUnit):
    """The same unit through the Python path: its calls raise the error an FMU unit raises."""

    def status_error(self, function: str, t: float, status: int) -> StepError:
        return StepError(self.name, t, f"{function} returned status {status}", function=function,
                         recoverable=status == 2)

    def set_time(self, t: float) -> None:
        self.library.set_time(ctypes.byref(self.memory), c_double(t))

    def set_states(self, address: int) -> None:
        self.library.set_states(ctypes.byref(self.memory), ctypes.c_void_p(address), ctypes.c_size_t(1))

    def get_derivatives(self, address: int) -> None:
        status = self.library.get_derivatives(ctypes.byref(self.memory), ctypes.c_void_p(address),
                                              ctypes.c_size_t(1))
        if status > 1:
            raise self.status_error("GetContinuousStateDerivatives", self.t, status)


@pytest.mark.parametrize("status, survives", [(2, True), (3, False)], ids=["discard", "error"])
def test_the_python_path_answers_statuses_the_same_way(decay_library, status, survives):
    unit = PythonDecayUnit(decay_library, bad_call=40, bad_status=status)
    context = Context()
    group = OdeGroup(None, context, [unit], [], 0.0, method="adams", rtol=1e-8, atol=1e-10, compiled=False)
    assert context.stats["rhs"].startswith("python")
    if survives:
        group.cv.advance(1.0)
        assert unit.memory.calls > 40 and group.cv.y[0] == pytest.approx(math.exp(-1.0), rel=1e-6)
    else:
        with pytest.raises(StepError, match="GetContinuousStateDerivatives"):
            group.cv.advance(1.0)
        assert unit.memory.calls == 40

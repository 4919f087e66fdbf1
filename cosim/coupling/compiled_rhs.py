"""The strong coupling's right-hand side compiled into a program of C calls (compiled_rhs.c).

Python's share of a right-hand-side evaluation (a dozen ctypes calls and closures, ~15-20 µs)
used to cost several times the feather model itself. Here the schedule is translated once per
run into ops that CVODE's C callback executes directly:

- Model Exchange FMUs: SetTime, SetContinuousStates, Set/GetFloat64 (fmi2Set/GetReal) of their
  scalar float64 ports, GetContinuousStateDerivatives, on their raw entry points;
- connections: a copy from the driving output's buffer into the input's buffer (the same
  buffers the Python path uses, so both paths see the same values);
- memoryless blocks without inputs that give their outputs as a CasADi function of time
  (the stroke controller): that function's generated C;
- everything else (Python blocks, algebraic loops, ports of other types): the step's own Python
  function, called back from C.

A unit with continuous states but no C entry points (the in-process CasADi backend) keeps the
whole group on the Python right-hand side, as does a machine without gcc (`reason` says why).
A failure is reported as the Python path reports it: the block, the FMI function, the time.
"""
from __future__ import annotations

import ctypes
from ctypes import CFUNCTYPE, POINTER, Structure, c_double, c_int, c_longlong, c_size_t, c_uint, c_void_p
from importlib import resources
from typing import Any, Callable, Sequence

from ..errors import StepError
from ..framework.units import NativeCalls, Unit
from .context import Context
from .native import NativeBuildError, casadi_library, shared_library
from .schedule import Step, non_finite_origin

SET_TIME, SET_STATES, GET_DERIVATIVES, COPY, SET_FLOAT64, GET_FLOAT64, SET_REAL, GET_REAL, CASADI, PYTHON = range(1, 11)
_SET_OF = {True: SET_FLOAT64, False: SET_REAL}
_GET_OF = {True: GET_FLOAT64, False: GET_REAL}
_PYTHON_OP = CFUNCTYPE(c_int, c_double)


class _Op(Structure):
    _fields_ = [("kind", c_int), ("fn", c_void_p), ("instance", c_void_p), ("vr", c_void_p), ("n", c_size_t),
                ("values", c_void_p), ("offset", c_size_t), ("src", c_void_p), ("dst", c_void_p),
                ("arg", c_void_p), ("res", c_void_p), ("iw", c_void_p), ("w", c_void_p), ("t_cell", c_void_p)]


class _Program(Structure):
    _fields_ = [("ops", POINTER(_Op)), ("n_ops", c_int), ("array", c_void_p), ("failed_op", c_int),
                ("failed_status", c_int), ("failed_t", c_double), ("calls", c_longlong)]


def _interpreter() -> ctypes.CDLL:
    source = resources.files(__package__).joinpath("compiled_rhs.c").read_text()
    return ctypes.CDLL(str(shared_library("featherstar_compiled_rhs", source)))


class CompiledRhs:
    """The program for one ODE group. `address` is the CVRhsFn, `user_data` its program;
    `failure()` turns the last failing op into the exception the Python path would raise."""

    def __init__(self, ops: list[_Op], explain: list[Callable[[int, float], BaseException]],
                 keep: list[Any], array_fn: int) -> None:
        lib = _interpreter()
        self._lib = lib
        self._ops = (_Op * max(len(ops), 1))(*ops)
        self._program = _Program(ctypes.cast(self._ops, POINTER(_Op)), len(ops), array_fn, -1, 0, 0.0, 0)
        self._explain = explain
        self._keep = keep  # every buffer and callback the ops point into
        self.address = ctypes.cast(lib.fs_rhs, c_void_p).value
        self.user_data = ctypes.addressof(self._program)
        self._point = lib.fs_point
        self._point.restype = c_int
        self._point.argtypes = [c_void_p, c_double, c_void_p]

    def point(self, t: float, y_address: int) -> None:
        """Run the program at (t, y) without derivatives (every input set, every output the
        program reads evaluated); raises what the failing op raises."""
        if self._point(self.user_data, t, y_address):
            raise self.failure() or StepError("master", t, "the compiled program failed")

    @property
    def calls(self) -> int:
        return self._program.calls

    def failure(self) -> BaseException | None:
        """The exception for the last op that failed (None if none did since the last call)."""
        p = self._program
        if p.failed_op < 0:
            return None
        exc = self._explain[p.failed_op](p.failed_status, p.failed_t)
        p.failed_op = -1
        return exc


class _Builder:
    def __init__(self, context: Context) -> None:
        self.context = context
        self.ops: list[_Op] = []
        self.explain: list[Callable[[int, float], BaseException]] = []
        self.keep: list[Any] = []
        self.evaluated: set[str] = set()   # time-function units whose op is already in the program

    def add(self, explain: Callable[[int, float], BaseException], **fields: Any) -> None:
        self.ops.append(_Op(**fields))
        self.explain.append(explain)

    def array(self, ctype: Any, values: Sequence[Any]) -> int:
        arr = (ctype * max(len(values), 1))(*values)
        self.keep.append(arr)
        return ctypes.addressof(arr)

    def copy(self, src: int, dst: int) -> None:
        """*dst = *src (one float64), which cannot fail."""
        self.add(_copies_cannot_fail, kind=COPY, src=src, dst=dst)

    def fmi(self, unit: Unit, function: str) -> Callable[[int, float], BaseException]:
        def explain(status: int, t: float) -> BaseException:
            return unit.status_error(function, t, status)
        return explain

    def python(self, run: Callable[[], None], name: str) -> None:
        """A step that stays in Python, called back from C; its exception is kept for failure()."""
        caught: list[BaseException] = []
        context = self.context

        def call(t: float) -> int:
            try:
                context.t = t
                run()
                return 0
            except BaseException as exc:  # never let an exception cross the C boundary
                caught[:] = [exc]
                return 3

        callback = _PYTHON_OP(call)
        self.keep.append(callback)

        def explain(status: int, t: float) -> BaseException:
            return caught[0] if caught else StepError(name, t, "the Python step failed")
        self.add(explain, kind=PYTHON, fn=ctypes.cast(callback, c_void_p).value)


def compile_rhs(context: Context, timed: Sequence[Unit], stateful: Sequence[tuple[Unit, int]],
                steps: Sequence[Step], array_fn: int) -> CompiledRhs | str:
    """The group's right-hand side as a C program, or the reason it stays in Python."""
    natives: dict[str, NativeCalls | None] = {}

    def native(u: Unit) -> NativeCalls | None:
        if u.name not in natives:
            natives[u.name] = u.native_calls()
        return natives[u.name]

    missing = [u.name for u, _ in stateful if native(u) is None]
    if missing:
        return f"{', '.join(missing)} has no C entry points (not a Model Exchange FMU)"
    b = _Builder(context)
    time_functions: dict[str, tuple[Any, list[float]]] = {}
    for u in timed:
        calls = native(u)
        if calls is not None:
            b.add(b.fmi(u, "SetTime"), kind=SET_TIME, fn=calls.set_time, instance=calls.instance)
            continue
        offer = u.time_function()
        if offer is not None:
            time_functions[u.name] = offer   # evaluated where the schedule reads its outputs
        elif not u.static:   # constants never read the time
            b.python(lambda u=u: u.set_time(b.context.t), u.name)
    for u, off in stateful:
        calls = native(u)
        b.add(b.fmi(u, "SetContinuousStates"), kind=SET_STATES, fn=calls.set_states, instance=calls.instance,
              offset=off, n=u.n_states)
    try:
        for step in steps:
            _translate(b, step, native, time_functions)
    except NativeBuildError as exc:
        return str(exc)
    for u, off in stateful:
        calls = native(u)
        b.add(b.fmi(u, "GetContinuousStateDerivatives" if calls.fmi3 else "GetDerivatives"),
              kind=GET_DERIVATIVES, fn=calls.get_derivatives, instance=calls.instance, offset=off, n=u.n_states)
    try:
        return CompiledRhs(b.ops, b.explain, b.keep, array_fn)
    except NativeBuildError as exc:
        return str(exc)


def _translate(b: _Builder, step: Step, native: Callable[[Unit], NativeCalls | None],
               time_functions: dict[str, tuple[Any, list[float]]]) -> None:
    u = step.unit
    calls = native(u) if u is not None else None
    idx = list(step.indices)
    if step.kind == "set" and calls is not None and all(i in calls.inputs for i in idx):
        sources = step.sources
        for i, src, k in sources:
            b.copy(ctypes.addressof(src.outbuf) + 8 * k, ctypes.addressof(u.inbuf) + 8 * i)
        values, pairs = _packed(b, u.inbuf, idx)
        for buffer_address, packed_address in pairs:   # before the call: gather into the packed array
            b.copy(buffer_address, packed_address)
        fmi = b.fmi(u, "SetFloat64 (inputs)" if calls.fmi3 else "SetReal (inputs)")

        def explain(status: int, t: float, fmi: Callable = fmi) -> BaseException:
            return non_finite_origin(u, sources, t) or fmi(status, t)
        b.add(explain, kind=_SET_OF[calls.fmi3], fn=calls.set_float64, instance=calls.instance,
              vr=b.array(c_uint, [calls.value_refs_in[i] for i in idx]), n=len(idx), values=values)
        return
    if step.kind == "get" and calls is not None and all(i in calls.outputs for i in idx):
        values, pairs = _packed(b, u.outbuf, idx)
        b.add(b.fmi(u, "GetFloat64 (outputs)" if calls.fmi3 else "GetReal (outputs)"), kind=_GET_OF[calls.fmi3],
              fn=calls.get_float64, instance=calls.instance,
              vr=b.array(c_uint, [calls.value_refs_out[i] for i in idx]), n=len(idx), values=values)
        for buffer_address, packed_address in pairs:   # after the call: scatter into the buffer
            b.copy(packed_address, buffer_address)
        return
    if step.kind == "get" and u is not None and u.name in time_functions:
        if u.name not in b.evaluated:   # one evaluation gives every output: later reads find them in outbuf
            _casadi_op(b, u, *time_functions[u.name])
            b.evaluated.add(u.name)
        return
    b.python(step.run, u.name if u is not None else "algebraic loop")


def _packed(b: _Builder, buf: ctypes.Array, idx: list[int]) -> tuple[int, list[tuple[int, int]]]:
    """Address of buf[idx] as one contiguous array, and the (buffer, packed) address pairs to copy
    between them: in place when idx is a run (no copies), else a temporary array."""
    if idx == list(range(idx[0], idx[0] + len(idx))):
        return ctypes.addressof(buf) + 8 * idx[0], []
    temp = b.array(c_double, [0.0] * len(idx))
    return temp, [(ctypes.addressof(buf) + 8 * i, temp + 8 * j) for j, i in enumerate(idx)]


def _casadi_op(b: _Builder, u: Unit, fn: Any, parameters: list[float]) -> None:
    lib = ctypes.CDLL(str(casadi_library([fn])))
    b.keep.append(lib)
    if fn.n_out() != len(u.output_names) or any(fn.size1_out(k) * fn.size2_out(k) != 1 for k in range(fn.n_out())):
        raise NativeBuildError(f"{u.name}: its time function must give one scalar per output")
    t_cell = b.array(c_double, [0.0])
    p = b.array(c_double, parameters)
    arg = b.array(c_void_p, [t_cell, p] + [None] * (fn.sz_arg() - 2))
    res = b.array(c_void_p, [ctypes.addressof(u.outbuf) + 8 * k for k in range(fn.n_out())]
                  + [None] * (fn.sz_res() - fn.n_out()))
    iw = b.array(c_longlong, [0] * fn.sz_iw())
    w = b.array(c_double, [0.0] * fn.sz_w())

    def explain(status: int, t: float) -> BaseException:
        return StepError(u.name, t, f"its compiled time function {fn.name()} failed", function=fn.name())
    b.add(explain, kind=CASADI, fn=ctypes.cast(getattr(lib, fn.name()), c_void_p).value, arg=arg, res=res, iw=iw,
          w=w, t_cell=t_cell)


def _copies_cannot_fail(status: int, t: float) -> BaseException:
    return StepError("master", t, f"a buffer copy reported status {status}")

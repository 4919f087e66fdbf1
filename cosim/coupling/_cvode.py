"""A thin ctypes binding to SUNDIALS CVODE 7 (the copy bundled with fmpy), for the strong master.

Only what the master needs: BDF (stiff) or Adams, scalar tolerances, dense direct linear solver
with CVODE's internal difference-quotient Jacobian, root finding, stop time, dense output
(`CVodeGetDky`) and statistics. The right-hand side is a Python callable that receives raw
addresses of the state and derivative arrays (no numpy wrapping in the hot loop).
"""
from __future__ import annotations

import ctypes
from ctypes import CFUNCTYPE, POINTER, byref, c_char_p, c_double, c_int, c_int64, c_long, c_void_p
from typing import Callable, Protocol

from fmpy.sundials import libraries as _libs


def _own_handle(lib: ctypes.CDLL) -> ctypes.CDLL:
    """A handle of our own on fmpy's SUNDIALS library: ctypes caches function objects per handle,
    so declaring restype/argtypes on fmpy's handle would change fmpy's own CVode solver (it
    expects pointer results where we declare c_void_p) and break `simulate_fmu` for ME FMUs."""
    return ctypes.CDLL(lib._name)


_core = _own_handle(_libs.sundials_core)
_nvec = _own_handle(_libs.sundials_nvecserial)
_mat = _own_handle(_libs.sundials_sunmatrixdense)
_ls = _own_handle(_libs.sundials_sunlinsoldense)
_cv = _own_handle(_libs.sundials_cvode)

CV_ADAMS, CV_BDF = 1, 2
CV_NORMAL, CV_ONE_STEP = 1, 2
CV_SUCCESS, CV_TSTOP_RETURN, CV_ROOT_RETURN = 0, 1, 2

_RHS = CFUNCTYPE(c_int, c_double, c_void_p, c_void_p, c_void_p)
_ROOT = CFUNCTYPE(c_int, c_double, c_void_p, c_void_p, c_void_p)
_ERR = CFUNCTYPE(None, c_int, c_char_p, c_char_p, c_char_p, c_int, c_void_p, c_void_p)


def _fn(lib, name, restype, *argtypes):
    f = getattr(lib, name)
    f.restype = restype
    f.argtypes = list(argtypes)
    return f


SUNContext_Create = _fn(_core, "SUNContext_Create", c_int, c_int, c_void_p)
SUNContext_Free = _fn(_core, "SUNContext_Free", c_int, POINTER(c_void_p))
SUNContext_PushErrHandler = _fn(_core, "SUNContext_PushErrHandler", c_int, c_void_p, _ERR, c_void_p)
SUNContext_ClearErrHandlers = _fn(_core, "SUNContext_ClearErrHandlers", c_int, c_void_p)
N_VNew_Serial = _fn(_nvec, "N_VNew_Serial", c_void_p, c_int64, c_void_p)
N_VDestroy = _fn(_nvec, "N_VDestroy_Serial", None, c_void_p)
N_VGetArrayPointer = _fn(_nvec, "N_VGetArrayPointer_Serial", c_void_p, c_void_p)
SUNDenseMatrix = _fn(_mat, "SUNDenseMatrix", c_void_p, c_int64, c_int64, c_void_p)
SUNMatDestroy = _fn(_mat, "SUNMatDestroy_Dense", None, c_void_p)
SUNLinSol_Dense = _fn(_ls, "SUNLinSol_Dense", c_void_p, c_void_p, c_void_p, c_void_p)
SUNLinSolFree = _fn(_ls, "SUNLinSolFree_Dense", c_int, c_void_p)
CVodeCreate = _fn(_cv, "CVodeCreate", c_void_p, c_int, c_void_p)
CVodeInit = _fn(_cv, "CVodeInit", c_int, c_void_p, _RHS, c_double, c_void_p)
CVodeReInit = _fn(_cv, "CVodeReInit", c_int, c_void_p, c_double, c_void_p)
CVodeSStolerances = _fn(_cv, "CVodeSStolerances", c_int, c_void_p, c_double, c_double)
CVodeSVtolerances = _fn(_cv, "CVodeSVtolerances", c_int, c_void_p, c_double, c_void_p)
CVodeSetLinearSolver = _fn(_cv, "CVodeSetLinearSolver", c_int, c_void_p, c_void_p, c_void_p)
CVodeSetMaxStep = _fn(_cv, "CVodeSetMaxStep", c_int, c_void_p, c_double)
CVodeSetInitStep = _fn(_cv, "CVodeSetInitStep", c_int, c_void_p, c_double)
CVodeSetMinStep = _fn(_cv, "CVodeSetMinStep", c_int, c_void_p, c_double)
CVodeSetMaxHnilWarns = _fn(_cv, "CVodeSetMaxHnilWarns", c_int, c_void_p, c_int)
CVodeSetMaxNumSteps = _fn(_cv, "CVodeSetMaxNumSteps", c_int, c_void_p, c_long)
CVodeSetStopTime = _fn(_cv, "CVodeSetStopTime", c_int, c_void_p, c_double)
CVodeClearStopTime = _fn(_cv, "CVodeClearStopTime", c_int, c_void_p)
CVodeRootInit = _fn(_cv, "CVodeRootInit", c_int, c_void_p, c_int, _ROOT)
CVodeSetNoInactiveRootWarn = _fn(_cv, "CVodeSetNoInactiveRootWarn", c_int, c_void_p)
CVodeGetRootInfo = _fn(_cv, "CVodeGetRootInfo", c_int, c_void_p, c_void_p)
CVode = _fn(_cv, "CVode", c_int, c_void_p, c_double, c_void_p, POINTER(c_double), c_int)
CVodeGetDky = _fn(_cv, "CVodeGetDky", c_int, c_void_p, c_double, c_int, c_void_p)
CVodeGetNumSteps = _fn(_cv, "CVodeGetNumSteps", c_int, c_void_p, POINTER(c_long))
CVodeGetNumRhsEvals = _fn(_cv, "CVodeGetNumRhsEvals", c_int, c_void_p, POINTER(c_long))
CVodeGetNumLinRhsEvals = _fn(_cv, "CVodeGetNumLinRhsEvals", c_int, c_void_p, POINTER(c_long))
CVodeGetCurrentTime = _fn(_cv, "CVodeGetCurrentTime", c_int, c_void_p, POINTER(c_double))
CVodeFree = _fn(_cv, "CVodeFree", None, POINTER(c_void_p))
SUNNonlinSol_FixedPoint = _fn(_cv, "SUNNonlinSol_FixedPoint", c_void_p, c_void_p, c_int, c_void_p)
SUNNonlinSolFree_FixedPoint = _fn(_cv, "SUNNonlinSolFree_FixedPoint", c_int, c_void_p)
CVodeSetNonlinearSolver = _fn(_cv, "CVodeSetNonlinearSolver", c_int, c_void_p, c_void_p)
CVodeSetUserData = _fn(_cv, "CVodeSetUserData", c_int, c_void_p, c_void_p)

#: Address of N_VGetArrayPointer_Serial, for right-hand sides written in C.
N_VGET_ARRAY_POINTER_ADDRESS = ctypes.cast(N_VGetArrayPointer, c_void_p).value

RETURN_CODES = {
    -1: "too much work (mxstep internal steps before reaching the output time)",
    -2: "too much accuracy requested",
    -3: "error test failed repeatedly or with |h| = hmin (the solution is probably blowing up or "
        "has a discontinuity the solver cannot step over)",
    -4: "corrector convergence failed repeatedly (stiff or discontinuous right-hand side)",
    -6: "linear solver setup failed (singular Jacobian?)",
    -8: "the right-hand side failed unrecoverably",
    -9: "the right-hand side failed at the first call",
    -10: "the right-hand side failed repeatedly",
    -11: "the right-hand side failed and could not recover",
    -12: "the root function failed",
    -22: "illegal input",
    -27: "output time too close to the start time",
}


RHS_FAILURES = (-8, -9, -10, -11)


class CVodeError(RuntimeError):
    def __init__(self, flag: int, t: float, detail: str = ""):
        self.flag = flag
        self.t = t
        msg = RETURN_CODES.get(flag, f"CVODE flag {flag}")
        super().__init__(f"{msg}{': ' + detail if detail else ''}")


class NativeRhs(Protocol):
    """A right-hand side written in C: `address` of a CVRhsFn, its `user_data`, and `failure()`,
    the exception behind its last failure (None if none)."""

    address: int
    user_data: int

    def failure(self) -> BaseException | None: ...


class CVodeIntegrator:
    """CVODE on y' = f(t, y) with f(t, y_address, ydot_address) -> int (0 ok, >0 recoverable,
    <0 fatal), or a NativeRhs. Root function g(t, y_address, gout_address) optional."""

    def __init__(
        self,
        n: int,
        rhs: Callable[[float, int, int], int] | NativeRhs,
        t0: float,
        y0,
        *,
        method: str = "bdf",
        nonlinear: str = "newton",
        rtol: float = 1e-6,
        atol: float = 1e-8,
        max_step: float = 0.0,
        max_num_steps: int = 100000,
        min_step: float = 1e-13,
        n_roots: int = 0,
        roots: Callable[[float, int, int], int] | None = None,
    ):
        self.n = n
        self._native = None if callable(rhs) else rhs
        self._rhs_py = rhs
        self.last_error = ""
        self._ctx = c_void_p()
        if SUNContext_Create(0, byref(self._ctx)) != 0:
            raise RuntimeError("SUNContext_Create failed")
        self._err_cb = _ERR(self._on_error)
        SUNContext_ClearErrHandlers(self._ctx)
        SUNContext_PushErrHandler(self._ctx, self._err_cb, None)
        self._y = N_VNew_Serial(n, self._ctx)
        self._dky = N_VNew_Serial(n, self._ctx)
        self.y_address = N_VGetArrayPointer(self._y)
        self.y = (c_double * n).from_address(self.y_address)
        self._dky_address = N_VGetArrayPointer(self._dky)
        self.dky = (c_double * n).from_address(self._dky_address)
        for i, v in enumerate(y0):
            self.y[i] = v
        lmm = {"bdf": CV_BDF, "adams": CV_ADAMS}[method]
        self._mem = CVodeCreate(lmm, self._ctx)
        if self._native is not None:
            self._rhs_cb = _RHS(self._native.address)
            self._check(CVodeInit(self._mem, self._rhs_cb, t0, self._y), t0)
            self._check(CVodeSetUserData(self._mem, self._native.user_data), t0)
        else:
            self._rhs_cb = _RHS(self._rhs)
            self._check(CVodeInit(self._mem, self._rhs_cb, t0, self._y), t0)
        self._check(CVodeSStolerances(self._mem, rtol, atol), t0)
        self._NLS = None
        if nonlinear == "fixedpoint":  # functional iteration: no Jacobian (non-stiff problems)
            self._A = self._LS = None
            self._NLS = SUNNonlinSol_FixedPoint(self._y, 0, self._ctx)
            self._check(CVodeSetNonlinearSolver(self._mem, self._NLS), t0)
        else:
            self._A = SUNDenseMatrix(n, n, self._ctx)
            self._LS = SUNLinSol_Dense(self._y, self._A, self._ctx)
            self._check(CVodeSetLinearSolver(self._mem, self._LS, self._A), t0)
        if max_step > 0:
            CVodeSetMaxStep(self._mem, max_step)
        CVodeSetMaxNumSteps(self._mem, max_num_steps)
        # A NaN right-hand side makes CVODE shrink h towards 0 for mxstep steps; a floor far
        # below any physical time scale makes it fail fast instead (and silences t + h = t).
        CVodeSetMinStep(self._mem, min_step)
        CVodeSetMaxHnilWarns(self._mem, -1)
        self._roots_cb = None
        self.n_roots = n_roots
        if n_roots:
            self._roots_py = roots
            self._roots_cb = _ROOT(self._roots)
            self._check(CVodeRootInit(self._mem, n_roots, self._roots_cb), t0)
            CVodeSetNoInactiveRootWarn(self._mem)
        self._tret = c_double(t0)
        self.t = t0

    # callbacks -------------------------------------------------------------------------------
    def _rhs(self, t, y, ydot, _user):
        try:
            return self._rhs_py(t, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot))
        except BaseException as exc:  # never let an exception cross the C boundary
            self.callback_exception = exc
            # an FMI Discard: CVODE retries with a smaller step (the exception is kept in case it
            # gives up, and is reported then)
            return 1 if getattr(exc, "recoverable", False) else -1

    def _roots(self, t, y, gout, _user):
        try:
            return self._roots_py(t, N_VGetArrayPointer(y), gout)
        except BaseException as exc:
            self.callback_exception = exc
            return -1

    def _on_error(self, line, func, file, msg, code, user, ctx):
        self.last_error = f"{(func or b'').decode()}: {(msg or b'').decode()}"

    callback_exception: BaseException | None = None

    # stepping --------------------------------------------------------------------------------
    def _check(self, flag: int, t: float) -> int:
        exc = self.callback_exception
        self.callback_exception = None   # after a success only a recovered Discard can be left here
        if flag < 0:
            if exc is None and self._native is not None and flag in RHS_FAILURES:
                exc = self._native.failure()
            if exc is not None:
                raise exc
            raise CVodeError(flag, t, self.last_error)
        return flag

    def set_stop_time(self, t_stop: float) -> None:
        CVodeSetStopTime(self._mem, t_stop)

    def advance(self, t_out: float, *, one_step: bool = False) -> int:
        """Integrate towards t_out; returns the CVODE flag (0 reached, 1 stop time, 2 root)."""
        flag = CVode(self._mem, t_out, self._y, byref(self._tret), CV_ONE_STEP if one_step else CV_NORMAL)
        self.t = self._tret.value
        return self._check(flag, self.t)

    def interpolate(self, t: float) -> ctypes.Array:
        """Dense output: the state at t within the last step (into self.dky)."""
        self._check(CVodeGetDky(self._mem, t, 0, self._dky), t)
        return self.dky

    def reinit(self, t0: float, y0=None) -> None:
        if y0 is not None:
            for i, v in enumerate(y0):
                self.y[i] = v
        self._check(CVodeReInit(self._mem, t0, self._y), t0)
        self.t = t0

    def root_info(self) -> list[int]:
        info = (c_int * self.n_roots)()
        CVodeGetRootInfo(self._mem, info)
        return list(info)

    def stats(self) -> dict[str, int]:
        steps, rhs, lrhs = c_long(), c_long(), c_long()
        CVodeGetNumSteps(self._mem, byref(steps))
        CVodeGetNumRhsEvals(self._mem, byref(rhs))
        CVodeGetNumLinRhsEvals(self._mem, byref(lrhs))
        return {"steps": steps.value, "rhs_evals": rhs.value + lrhs.value}

    def free(self) -> None:
        if getattr(self, "_mem", None):
            CVodeFree(byref(c_void_p(self._mem)))
            self._mem = None
            if self._LS is not None:
                SUNLinSolFree(self._LS)
                SUNMatDestroy(self._A)
            if self._NLS is not None:
                SUNNonlinSolFree_FixedPoint(self._NLS)
            N_VDestroy(self._y)
            N_VDestroy(self._dky)
            SUNContext_Free(byref(self._ctx))

    def __del__(self):
        try:
            self.free()
        except Exception:
            pass

"""SUNDIALS called from compiled code: CVODE (BDF and Adams) with numba ``cfunc`` callbacks.

The system SUNDIALS (Debian's libsundials 6, which ``make`` installs) is called through ctypes.
Its right-hand side, Jacobian and root functions are numba ``cfunc`` s: they read the problem
from a parameter array (``user_data``) and the data of SUNDIALS' vectors and dense matrix
through their structs' layout (checked against SUNDIALS' own accessors when the library is
loaded), so no Python runs per step. Python calls ``CVode`` once per root return, save point and
loading segment, as the segment driver of :mod:`integrators.core.segments` asks: what a C user of
SUNDIALS does, with the same events and restarts as every other backend.

* Events: CVODE's root finding on the four root functions of :mod:`integrators.core.events`,
  with their counting directions (``CVodeSetRootDirection``); the crossings and their signs from
  ``CVodeGetRootInfo``. An exact zero of a root function is counted as positive (C h − D η
  cancels to exactly 0.0 at two times 1e−12 apart near a flat maximum of w, and CVODE then stops
  with "Root found at and very near t").
* Stepping: ``CVode(t_out, CV_NORMAL)`` with the stop time at the segment's end: CVODE returns
  at t_out (interpolated: the steps do not land on save points) or earlier at a root, and keeps
  a root beyond t_out for the next call.
* Counters: SUNDIALS' own getters (``CVodeGetNumSteps``, ``…NumRhsEvals`` + ``…NumLinRhsEvals``,
  ``…NumErrTestFails`` as rejected, ``…NumJacEvals``), read before each re-initialisation and
  summed. ``max_steps`` is exact: each call may take at most the steps left (``mxstep``).
* Failures: a retcode with SUNDIALS' flag name and the last message of its error handler (a
  cfunc that keeps it; SUNDIALS prints nothing).

Reference: Hindmarsh et al. (2005), SUNDIALS: Suite of nonlinear and differential/algebraic
equation solvers, ACM TOMS 31, 363–396; Gardner et al. (2022), ACM TOMS, doi:10.1145/3539801.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import math
from dataclasses import dataclass
from functools import cache
from types import SimpleNamespace
from typing import ClassVar

import numpy as np
from numba import carray, cfunc, farray, types

from integrators.core.events import DIRECTIONS, compiled_roots
from integrators.core.registry import AdaptiveAlgorithm, register
from integrators.core.segments import Advance, directional_roots
from integrators.core.solution import ReturnCode, Stats
from problems.formulations import ode_jacobian, ode_rhs

__all__ = ["SundialsCVODEBDF", "SundialsCVODEAdams"]

# cvode.h
_CV_ADAMS, _CV_BDF, _CV_NORMAL = 1, 2, 1
_SUCCESS, _TSTOP, _ROOT, _WARNING = 0, 1, 2, 99
_TOO_MUCH_WORK = -1
_UNDERFLOW = {-3, -4}          # CV_ERR_FAILURE, CV_CONV_FAILURE: h has collapsed
_NON_FINITE = {-8, -9, -10, -12}   # RHSFUNC_FAIL, FIRST_RHSFUNC_ERR, REPTD_RHSFUNC_ERR, RTFUNC_FAIL
_TINY = 1e-300
#: steps per CVode call at most (SUNDIALS' default mxstep); between calls the budgets are checked
_MXSTEP = 500
#: internal steps that do not advance CVODE's time (t + h == t: SUNDIALS only warns and goes
#: on, and the state it moves may even cross roots, all at one t) before the run stops
_STALLED_STEPS = 10
#: the parameter array handed to the callbacks as user_data
(_LAW, _BETA, _C, _D, _E, _LN_10ES, _LN_ES, _LN_E) = range(8)
_N_P = 8
#: the error handler's buffer: the last code (int32 in the first 4 bytes), then the message
_EH_SIZE = 1024

# --- the callbacks: numba cfuncs ---------------------------------------------------------------
_F8P = types.CPointer(types.float64)
# an N_Vector or a SUNMatrix: a pointer to a struct whose first field, ``content``, points to a
# struct whose third 8-byte field is the double* of the data (N_VectorContent_Serial: length,
# own_data, data; SUNMatrixContent_Dense: M, N, data). So v[0][2] is the data.
_OBJ = types.CPointer(types.CPointer(_F8P))
_I4 = types.int32


@cfunc(_I4(types.float64, _OBJ, _OBJ, _F8P), cache=True, error_model="numpy")
def _rhs(t, y, ydot, user_data):
    q = carray(user_data, _N_P)
    out = carray(ydot[0][2], 3)
    ode_rhs(int(q[_LAW]), q[_BETA], q[_C], q[_D], q[_E], carray(y[0][2], 3), out)
    # a non-finite rate (e^u of an overshooting trial) is a recoverable failure: CVODE retries
    # with a smaller step
    return 0 if math.isfinite(out[0] + out[1] + out[2]) else 1


@cfunc(_I4(types.float64, _OBJ, _OBJ, _OBJ, _F8P, _OBJ, _OBJ, _OBJ), cache=True,
       error_model="numpy")
def _jac(t, y, fy, jmat, user_data, tmp1, tmp2, tmp3):
    q = carray(user_data, _N_P)
    jac = farray(jmat[0][2], (3, 3))            # column-major: J(i, j) = data[i + 3 j]
    ode_jacobian(int(q[_LAW]), q[_BETA], q[_C], q[_D], q[_E], carray(y[0][2], 3), jac)
    return 0


@cfunc(_I4(types.float64, _OBJ, _F8P, _F8P), cache=True, error_model="numpy")
def _roots(t, y, gout, user_data):
    q = carray(user_data, _N_P)
    g = carray(gout, 4)
    compiled_roots(q[_BETA], q[_C], q[_D], q[_LN_10ES], q[_LN_ES], q[_LN_E], carray(y[0][2], 3),
                   g)
    for k in range(4):
        if g[k] == 0.0:
            g[k] = _TINY
    return 0


_U8P = types.CPointer(types.uint8)


@cfunc(types.void(_I4, _U8P, _U8P, _U8P, _U8P), cache=True)
def _on_error(code, module, function, msg, buf):
    """Keep the last message (not the per-call step limit's) in ``buf``: code, then text."""
    if code == _TOO_MUCH_WORK:
        return
    codes = carray(buf, 4)
    c = code if code >= 0 else code + 4294967296      # two's complement into 4 bytes
    for i in range(4):
        codes[i] = (c >> (8 * i)) & 255
    text = carray(buf, _EH_SIZE)
    n = 4
    i = 0
    while n < _EH_SIZE - 1 and msg[i] != 0:
        text[n] = msg[i]
        n += 1
        i += 1
    text[n] = 0


# --- the library -------------------------------------------------------------------------------
_P, _PR, _R, _L = ctypes.c_void_p, ctypes.c_uint64, ctypes.c_double, ctypes.c_long
_I = ctypes.c_int
#: name → (restype, argtypes) of what is called, as in SUNDIALS 6's headers
_SIGNATURES = {
    "SUNContext_Create": (_I, (_P, _P)), "SUNContext_Free": (_I, (_P,)),
    "N_VMake_Serial": (_PR, (ctypes.c_int64, _P, _P)), "N_VDestroy": (None, (_P,)),
    "N_VGetArrayPointer": (_PR, (_P,)),
    "SUNDenseMatrix": (_PR, (ctypes.c_int64, ctypes.c_int64, _P)),
    "SUNDenseMatrix_Data": (_PR, (_P,)), "SUNMatDestroy": (None, (_P,)),
    "SUNLinSol_Dense": (_PR, (_P, _P, _P)), "SUNLinSolFree": (_I, (_P,)),
    "CVodeCreate": (_PR, (_I, _P)), "CVodeInit": (_I, (_P, _P, _R, _P)),
    "CVodeReInit": (_I, (_P, _R, _P)), "CVodeSStolerances": (_I, (_P, _R, _R)),
    "CVodeSetUserData": (_I, (_P, _P)), "CVodeSetMaxNumSteps": (_I, (_P, _L)),
    "CVodeSetStopTime": (_I, (_P, _R)), "CVodeSetErrHandlerFn": (_I, (_P, _P, _P)),
    "CVodeRootInit": (_I, (_P, _I, _P)), "CVodeSetRootDirection": (_I, (_P, _P)),
    "CVodeSetNoInactiveRootWarn": (_I, (_P,)), "CVodeSetLinearSolver": (_I, (_P, _P, _P)),
    "CVodeSetJacFn": (_I, (_P, _P)), "CVode": (_I, (_P, _R, _P, _P, _I)),
    "CVodeGetRootInfo": (_I, (_P, _P)), "CVodeGetCurrentTime": (_I, (_P, _P)),
    "CVodeGetNumSteps": (_I, (_P, _P)), "CVodeGetNumRhsEvals": (_I, (_P, _P)),
    "CVodeGetNumLinRhsEvals": (_I, (_P, _P)), "CVodeGetNumErrTestFails": (_I, (_P, _P)),
    "CVodeGetNumJacEvals": (_I, (_P, _P)), "CVodeGetReturnFlagName": (_P, (_L,)),
    "CVodeFree": (None, (_P,)), "SUNDIALSGetVersion": (_I, (_P, _I)),
}


@cache
def _library() -> SimpleNamespace:
    """CVODE's shared library (it carries its own copy of the vector, matrix and linear-solver
    modules), its functions declared, and the struct layout the callbacks rely on checked."""
    path = ctypes.util.find_library("sundials_cvode")
    if path is None:
        raise ImportError("SUNDIALS' CVODE library (libsundials_cvode) was not found: "
                          "apt-get install libsundials-dev")
    lib = ctypes.CDLL(path)
    fns = {}
    for name, (restype, argtypes) in _SIGNATURES.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, list(argtypes)
        fns[name] = fn
    ns = SimpleNamespace(**fns, path=path, free=ctypes.CDLL(None).free)
    ns.free.argtypes, ns.free.restype = [_P], None
    buf = ctypes.create_string_buffer(32)
    ns.version = buf.value.decode() if ns.SUNDIALSGetVersion(buf, len(buf)) == 0 else "?"
    if not ns.version.startswith("6."):
        raise ImportError(f"SUNDIALS {ns.version} at {path}: this backend reads the structs of "
                          "SUNDIALS 6")
    _check_layout(ns)
    return ns


def _data_field(obj: int) -> int:
    """What the callbacks read as an object's data: content (first field), then its third
    8-byte field."""
    content = ctypes.cast(obj, ctypes.POINTER(ctypes.c_uint64))[0]
    return ctypes.cast(content, ctypes.POINTER(ctypes.c_uint64))[2]


def _check_layout(ns) -> None:
    ctx = ctypes.c_uint64(0)
    if ns.SUNContext_Create(None, ctypes.byref(ctx)) != 0:
        raise ImportError("SUNContext_Create failed")
    a = np.zeros(3)
    v = ns.N_VMake_Serial(3, a.ctypes.data, ctx.value)
    m = ns.SUNDenseMatrix(3, 3, ctx.value)
    try:
        ok = (_data_field(v) == ns.N_VGetArrayPointer(v) == a.ctypes.data
              and _data_field(m) == ns.SUNDenseMatrix_Data(m))
    finally:
        ns.SUNMatDestroy(m)
        ns.N_VDestroy(v)
        ns.SUNContext_Free(ctypes.byref(ctx))
    if not ok:
        raise ImportError(f"SUNDIALS {ns.version}: its vector or matrix struct is not laid out as "
                          "this backend's callbacks read it")


_library()        # at import: without the library the registry leaves these names out, saying why


def _flag_name(ns, flag: int) -> str:
    p = ns.CVodeGetReturnFlagName(flag)
    if not p:
        return str(flag)
    name = ctypes.string_at(p).decode()
    ns.free(p)                           # the name is malloc'ed
    return name


# --- the backend -------------------------------------------------------------------------------
@dataclass(frozen=True)
class _SundialsC(AdaptiveAlgorithm):
    """Options of the compiled SUNDIALS backends: those of :class:`AdaptiveAlgorithm`."""

    library: ClassVar[str] = "SUNDIALS (C, numba cfunc callbacks)"
    rhs_tiers: ClassVar[tuple[str, ...]] = ("numba",)
    rhs_tiers_reason: ClassVar[str] = (
        "SUNDIALS is called from C here: its callbacks are compiled numba cfuncs")
    lmm: ClassVar[int] = _CV_BDF

    @classmethod
    def library_version(cls) -> str:
        return f"SUNDIALS {_library().version} (ctypes, numba cfunc callbacks)"

    def make_stepper(self, nd, budget):
        return _CvodeC(self, nd, budget)


class _CvodeC:
    """The segment protocol over one CVODE memory, re-initialised at each segment."""

    def __init__(self, algorithm: _SundialsC, nd, budget=None):
        self.algorithm = algorithm
        self.nd = nd
        self.budget = budget
        self.stats = Stats()
        self._ns = _library()
        self._p = np.empty(_N_P)
        self._y = np.empty(3)                # CVODE's y vector wraps this array's memory
        self._eh = np.zeros(_EH_SIZE, np.uint8)
        self._dirs = np.array(DIRECTIONS, dtype=np.intc)
        self._rootinfo = np.zeros(4, dtype=np.intc)
        self._tret, self._count = ctypes.c_double(0.0), ctypes.c_long(0)
        self._ctx = self._mem = self._vec = self._mat = self._ls = None
        self._live = False
        self._p[:] = (nd.law_code, nd.beta, nd.c, nd.d, nd.e_slow, math.log(10.0 * nd.e_slow),
                      math.log(nd.e_slow), math.log(nd.e_slow))

    # --- set-up ---------------------------------------------------------------------------------
    def _check(self, what: str, flag: int) -> None:
        if flag != 0:
            raise RuntimeError(f"{what} returned {_flag_name(self._ns, flag)} ({flag}): "
                               f"{self._message() or 'no message'}")

    def _create(self, tau0: float) -> None:
        ns, a = self._ns, self.algorithm
        ctx = ctypes.c_uint64(0)
        self._check("SUNContext_Create", ns.SUNContext_Create(None, ctypes.byref(ctx)))
        self._ctx = ctx.value
        self._vec = ns.N_VMake_Serial(3, self._y.ctypes.data, self._ctx)
        self._mem = ns.CVodeCreate(a.lmm, self._ctx)
        self._mat = ns.SUNDenseMatrix(3, 3, self._ctx)
        self._ls = ns.SUNLinSol_Dense(self._vec, self._mat, self._ctx)
        if not (self._vec and self._mem and self._mat and self._ls):
            raise RuntimeError("SUNDIALS could not allocate its solver")
        mem = self._mem
        self._check("CVodeSetErrHandlerFn",
                    ns.CVodeSetErrHandlerFn(mem, _on_error.address, self._eh.ctypes.data))
        self._check("CVodeInit", ns.CVodeInit(mem, _rhs.address, tau0, self._vec))
        self._check("CVodeSStolerances", ns.CVodeSStolerances(mem, a.rtol, a.atol))
        self._check("CVodeSetUserData", ns.CVodeSetUserData(mem, self._p.ctypes.data))
        self._check("CVodeSetLinearSolver", ns.CVodeSetLinearSolver(mem, self._ls, self._mat))
        self._check("CVodeSetJacFn", ns.CVodeSetJacFn(mem, _jac.address))
        self._check("CVodeRootInit", ns.CVodeRootInit(mem, 4, _roots.address))
        self._check("CVodeSetRootDirection",
                    ns.CVodeSetRootDirection(mem, self._dirs.ctypes.data))
        self._check("CVodeSetNoInactiveRootWarn", ns.CVodeSetNoInactiveRootWarn(mem))

    # --- the protocol ---------------------------------------------------------------------------
    def start(self, tau0, z0, e, t_bound):
        self._close_segment()
        self._e = e
        self._p[_E], self._p[_LN_E] = e, math.log(e)
        self._t, self._z = float(tau0), np.array(z0, dtype=float)
        self._y[:] = self._z
        self._eh[:] = 0
        self._moved_t, self._moved_steps = self._t, 0     # CVODE's time last seen to advance
        self._failure = None
        try:
            if self._mem is None:
                self._create(self._t)
            else:
                self._check("CVodeReInit", self._ns.CVodeReInit(self._mem, self._t, self._vec))
            self._check("CVodeSetStopTime",
                        self._ns.CVodeSetStopTime(self._mem, float(t_bound)))
            self._live = True
        except RuntimeError as exc:
            self._failure = str(exc)

    def advance(self, t_out):
        if self._failure is not None:
            return Advance(self._t, self._z, retcode=ReturnCode.FAILURE, message=self._failure)
        ns, a, mem = self._ns, self.algorithm, self._mem
        while True:
            left = a.max_steps - self.stats.steps - self._get("CVodeGetNumSteps")
            if left <= 0:
                return Advance(self._t, self._z, retcode=ReturnCode.MAX_STEPS,
                               message=f"step budget of {a.max_steps} used up at "
                                       f"t = {self._t * self.nd.time_scale:.9g} s")
            ns.CVodeSetMaxNumSteps(mem, min(_MXSTEP, left))
            flag = ns.CVode(mem, t_out, self._vec, ctypes.byref(self._tret), _CV_NORMAL)
            t, z = self._tret.value, self._y.copy()
            if flag < 0 and flag != _TOO_MUCH_WORK:
                return self._failed(flag)
            stalled = self._stalled()
            if stalled:
                return Advance(self._t, self._z, retcode=ReturnCode.STEP_UNDERFLOW,
                               message=f"step size underflow: {stalled} steps did not advance "
                                       f"t = {self._moved_t * self.nd.time_scale:.9g} s "
                                       f"(t + h == t; {self._message() or 'no message'})")
            if flag == _TOO_MUCH_WORK:
                if self.budget is not None and self.budget.exceeded():
                    return Advance(self._t, self._z, retcode=ReturnCode.WALL_TIME,
                                   message=f"wall-time budget of {self.budget.wall_s} s used up "
                                           f"at t = {t * self.nd.time_scale:.6g} s")
                if np.all(np.isfinite(z)):
                    self._t, self._z = t, z
                continue
            self._t, self._z = t, z
            if flag != _ROOT:             # t_out or the stop time reached
                return Advance(t, z)
            self._check_root_info()
            found = [k for k in range(4) if self._rootinfo[k] != 0]
            counted = directional_roots(self.nd, self._e, z, found,
                                        [int(self._rootinfo[k]) for k in found])
            if counted:
                return Advance(t, z, roots=counted)

    def finish(self):
        self._close_segment()
        ns = self._ns
        if self._mem is not None:
            ns.CVodeFree(ctypes.byref(ctypes.c_void_p(self._mem)))
        if self._ls:
            ns.SUNLinSolFree(self._ls)
        if self._mat:
            ns.SUNMatDestroy(self._mat)
        if self._vec:
            ns.N_VDestroy(self._vec)
        if self._ctx is not None:
            ns.SUNContext_Free(ctypes.byref(ctypes.c_uint64(self._ctx)))
        self._ctx = self._mem = self._vec = self._mat = self._ls = None

    def __del__(self):
        if getattr(self, "_ctx", None) is not None:
            self.finish()

    # --- internals ------------------------------------------------------------------------------
    def _get(self, getter: str) -> int:
        getattr(self._ns, getter)(self._mem, ctypes.byref(self._count))
        return self._count.value

    def _stalled(self) -> int:
        """The steps taken since CVODE's time last advanced, if that is too many; else 0."""
        steps = self._get("CVodeGetNumSteps")
        self._ns.CVodeGetCurrentTime(self._mem, ctypes.byref(self._tret))
        if self._tret.value > self._moved_t:
            self._moved_t, self._moved_steps = self._tret.value, steps
            return 0
        return steps - self._moved_steps if steps - self._moved_steps >= _STALLED_STEPS else 0

    def _check_root_info(self) -> None:
        self._ns.CVodeGetRootInfo(self._mem, self._rootinfo.ctypes.data)

    def _close_segment(self) -> None:
        """Fold the segment's counters in (CVodeReInit zeroes SUNDIALS' own)."""
        if self._live:
            s = self.stats
            s.steps += self._get("CVodeGetNumSteps")
            s.nfev += self._get("CVodeGetNumRhsEvals") + self._get("CVodeGetNumLinRhsEvals")
            s.rejected += self._get("CVodeGetNumErrTestFails")
            s.njev += self._get("CVodeGetNumJacEvals")
        self._live = False

    def _message(self) -> str:
        raw = bytes(self._eh[4:])
        return raw[:raw.index(0)].decode(errors="replace") if 0 in raw else ""

    def _failed(self, flag: int) -> Advance:
        if flag in _UNDERFLOW:
            code = ReturnCode.STEP_UNDERFLOW
        elif flag in _NON_FINITE:
            code = ReturnCode.NON_FINITE
        else:
            code = ReturnCode.FAILURE
        message = (f"{_flag_name(self._ns, flag)} (flag {flag}): "
                   f"{self._message() or 'no message'}")
        return Advance(self._t, self._z, retcode=code, message=message)


@register
@dataclass(frozen=True)
class SundialsCVODEBDF(_SundialsC):
    """SUNDIALS CVODE, variable-order variable-step BDF (orders 1–5), called from compiled code.

    Adaptive. Newton iteration with the dense analytic Jacobian (``ode_jacobian``); CVODE's root
    finding for the events. Right-hand side, Jacobian and root functions are numba cfuncs: no
    Python per step. Needs ``rtol`` and ``atol``. Reference: Hindmarsh et al. (2005), ACM TOMS
    31, 363–396.
    """

    name: ClassVar[str] = "sundials-CVODE-BDF"
    family: ClassVar[str] = "BDF"
    order: ClassVar[int] = 5
    lmm: ClassVar[int] = _CV_BDF


@register
@dataclass(frozen=True)
class SundialsCVODEAdams(_SundialsC):
    """SUNDIALS CVODE, variable-order variable-step Adams–Moulton (orders 1–12), called from
    compiled code, with Newton iteration on the analytic Jacobian (as ``odes-CVODE-Adams``: the
    fixed-point iteration does not converge in the stiff stick phase). Needs ``rtol`` and
    ``atol``. Reference: Hindmarsh et al. (2005), ACM TOMS 31, 363–396.
    """

    name: ClassVar[str] = "sundials-CVODE-Adams"
    family: ClassVar[str] = "Adams-Moulton"
    order: ClassVar[int] = 12
    stiff: ClassVar[bool] = False
    lmm: ClassVar[int] = _CV_ADAMS

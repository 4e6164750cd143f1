"""SUNDIALS called from compiled code: CVODE (BDF, Adams), IDA and ARKODE (ARKStep's IMEX
additive Runge–Kutta, ERKStep's explicit Runge–Kutta) with numba ``cfunc`` callbacks.

The system SUNDIALS (Debian's libsundials 6, which ``make`` installs) is called through ctypes.
Its right-hand side, Jacobian and root functions are numba ``cfunc`` s: they read the problem
from a parameter array (``user_data``) and the data of SUNDIALS' vectors and dense matrix
through their structs' layout (checked against SUNDIALS' own accessors when the library is
loaded), so no Python runs per step. Python calls ``CVode`` once per root return, save point and
loading segment, as the segment driver of :mod:`integrators.core.segments` asks: what a C user of
SUNDIALS does, with the same events and restarts as every other backend. CVODE integrates the
ODE form z = (h, u, s), IDA the index-1 DAE form y = (h, u, s, η) with u algebraic
(``IDASetId``) and consistent (y0, y'0) from ``dae_initial`` at every (re)start. ARKStep splits
the ODE form: the spring's h' = E − w explicit, the friction's relaxation (u', s') implicit.

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
from problems.formulations import (N_Q, Q_E, dae_differential, dae_initial, dae_jacobian,
                                   dae_residual, form_vector, ode_jacobian, ode_rhs)
from problems.loading import ln_load_rate

__all__ = ["SundialsCVODEBDF", "SundialsCVODEAdams", "SundialsIDA", "SundialsARKodeIMEX",
           "SundialsARKodeERK"]

# cvode.h
_CV_ADAMS, _CV_BDF, _CV_NORMAL = 1, 2, 1
_SUCCESS, _TSTOP, _ROOT, _WARNING = 0, 1, 2, 99
_TOO_MUCH_WORK = -1
_UNDERFLOW = {-3, -4}          # error-test or convergence failures: h has collapsed
#: a failing right-hand side, residual or root function (the same codes in CVODE and IDA)
_NON_FINITE = {-8, -9, -10, -12}
_TINY = 1e-300
#: ARKStep's error-test failures per step (SUNDIALS' default: 7; see _ArkStep._init)
_ARK_MAX_ERR_TEST_FAILS = 20
#: steps per CVode call at most (SUNDIALS' default mxstep); between calls the budgets are checked
_MXSTEP = 500
#: internal steps that do not advance CVODE's time (t + h == t: SUNDIALS only warns and goes
#: on, and the state it moves may even cross roots, all at one t) before the run stops
_STALLED_STEPS = 10
#: the parameter array handed to the callbacks as user_data
#: the problem vector q of problems.formulations, then the root functions' levels
(_LN_10ES, _LN_ES, _LN_E) = range(N_Q, N_Q + 3)
_E = Q_E
_N_P = N_Q + 3
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
    ode_rhs(q, carray(y[0][2], 3), out)
    # a non-finite rate (e^u of an overshooting trial) is a recoverable failure: CVODE retries
    # with a smaller step
    return 0 if math.isfinite(out[0] + out[1] + out[2]) else 1


@cfunc(_I4(types.float64, _OBJ, _OBJ, _OBJ, _F8P, _OBJ, _OBJ, _OBJ), cache=True,
       error_model="numpy")
def _jac(t, y, fy, jmat, user_data, tmp1, tmp2, tmp3):
    q = carray(user_data, _N_P)
    jac = farray(jmat[0][2], (3, 3))            # column-major: J(i, j) = data[i + 3 j]
    ode_jacobian(q, carray(y[0][2], 3), jac)
    return 0


@cfunc(_I4(types.float64, _OBJ, _F8P, _F8P), cache=True, error_model="numpy")
def _roots(t, y, gout, user_data):
    q = carray(user_data, _N_P)
    g = carray(gout, 4)
    compiled_roots(q, q[_LN_10ES], q[_LN_ES], q[_LN_E], carray(y[0][2], 3),
                   g)
    for k in range(4):
        if g[k] == 0.0:
            g[k] = _TINY
    return 0


@cfunc(_I4(types.float64, _OBJ, _OBJ, _F8P), cache=True, error_model="numpy")
def _rhs_explicit(t, y, ydot, user_data):
    """ARKStep's explicit part: the load-point spring, h' = E − w (non-stiff: the oscillator)."""
    q = carray(user_data, _N_P)
    z, out = carray(y[0][2], 3), carray(ydot[0][2], 3)
    out[0], out[1], out[2] = q[_E] - math.exp(z[1]), 0.0, 0.0
    return 0 if math.isfinite(out[0]) else 1


@cfunc(_I4(types.float64, _OBJ, _OBJ, _F8P), cache=True, error_model="numpy")
def _rhs_implicit(t, y, ydot, user_data):
    """ARKStep's implicit part: the friction's relaxation, u' and s' (stiff where w is small:
    the eigenvalue −D/w)."""
    q = carray(user_data, _N_P)
    out = carray(ydot[0][2], 3)
    ode_rhs(q, carray(y[0][2], 3), out)
    out[0] = 0.0
    return 0 if math.isfinite(out[1] + out[2]) else 1


@cfunc(_I4(types.float64, _OBJ, _OBJ, _OBJ, _F8P, _OBJ, _OBJ, _OBJ), cache=True,
       error_model="numpy")
def _jac_implicit(t, y, fy, jmat, user_data, tmp1, tmp2, tmp3):
    """∂(implicit part)/∂z: the ODE form's Jacobian without its first row."""
    q = carray(user_data, _N_P)
    jac = farray(jmat[0][2], (3, 3))
    ode_jacobian(q, carray(y[0][2], 3), jac)
    jac[0, 0], jac[0, 1], jac[0, 2] = 0.0, 0.0, 0.0
    return 0


@cfunc(_I4(types.float64, _OBJ, _OBJ, _OBJ, _F8P), cache=True, error_model="numpy")
def _res(t, yy, yp, rr, user_data):
    q = carray(user_data, _N_P)
    out = carray(rr[0][2], 4)
    dae_residual(q, carray(yy[0][2], 4),
                 carray(yp[0][2], 4), out)
    return 0 if math.isfinite(out[0] + out[1] + out[2] + out[3]) else 1


@cfunc(_I4(types.float64, types.float64, _OBJ, _OBJ, _OBJ, _OBJ, _F8P, _OBJ, _OBJ, _OBJ),
       cache=True, error_model="numpy")
def _res_jac(t, cj, yy, yp, rr, jmat, user_data, tmp1, tmp2, tmp3):
    q = carray(user_data, _N_P)
    jac = farray(jmat[0][2], (4, 4))
    dae_jacobian(q, carray(yy[0][2], 4), cj, jac)
    return 0


@cfunc(_I4(types.float64, _OBJ, _OBJ, _F8P, _F8P), cache=True, error_model="numpy")
def _res_roots(t, yy, yp, gout, user_data):
    q = carray(user_data, _N_P)
    g = carray(gout, 4)
    compiled_roots(q, q[_LN_10ES], q[_LN_ES], q[_LN_E],
                   carray(yy[0][2], 3), g)
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


# --- the libraries -----------------------------------------------------------------------------
_P, _PR, _R, _L = ctypes.c_void_p, ctypes.c_uint64, ctypes.c_double, ctypes.c_long
_I = ctypes.c_int
#: name → (restype, argtypes), as in SUNDIALS 6's headers: what each solver's library gives (each
#: carries its own copy of the vector, matrix and linear-solver modules), then the solver's own
#: functions under their generic names (CVODE's prefix "CVode", IDA's "IDA")
_COMMON = {
    "SUNContext_Create": (_I, (_P, _P)), "SUNContext_Free": (_I, (_P,)),
    "N_VMake_Serial": (_PR, (ctypes.c_int64, _P, _P)), "N_VDestroy": (None, (_P,)),
    "N_VGetArrayPointer": (_PR, (_P,)),
    "SUNDenseMatrix": (_PR, (ctypes.c_int64, ctypes.c_int64, _P)),
    "SUNDenseMatrix_Data": (_PR, (_P,)), "SUNMatDestroy": (None, (_P,)),
    "SUNLinSol_Dense": (_PR, (_P, _P, _P)), "SUNLinSolFree": (_I, (_P,)),
    "SUNDIALSGetVersion": (_I, (_P, _I)),
}
_GENERIC = {
    "SStolerances": (_I, (_P, _R, _R)), "SetUserData": (_I, (_P, _P)),
    "SetMaxNumSteps": (_I, (_P, _L)), "SetStopTime": (_I, (_P, _R)),
    "SetErrHandlerFn": (_I, (_P, _P, _P)), "RootInit": (_I, (_P, _I, _P)),
    "SetRootDirection": (_I, (_P, _P)), "SetNoInactiveRootWarn": (_I, (_P,)),
    "GetRootInfo": (_I, (_P, _P)), "GetCurrentTime": (_I, (_P, _P)),
    "GetNumSteps": (_I, (_P, _P)), "GetNumErrTestFails": (_I, (_P, _P)),
    "GetReturnFlagName": (_P, (_L,)), "Free": (None, (_P,)),
}
#: the generic functions of the solvers with a linear solver (not ERKStep)
_IMPLICIT = {
    "SetLinearSolver": (_I, (_P, _P, _P)), "SetJacFn": (_I, (_P, _P)),
    "GetNumJacEvals": (_I, (_P, _P)),
}
#: solver → (library, prefix of the generic names, has a linear solver, its own functions)
_SOLVERS = {
    "cvode": ("sundials_cvode", "CVode", True, {
        "Create": ("CVodeCreate", _PR, (_I, _P)), "Init": ("CVodeInit", _I, (_P, _P, _R, _P)),
        "ReInit": ("CVodeReInit", _I, (_P, _R, _P)), "Solve": ("CVode", _I, (_P, _R, _P, _P, _I)),
        "GetNumFEvals": ("CVodeGetNumRhsEvals", _I, (_P, _P)),
        "GetNumLinFEvals": ("CVodeGetNumLinRhsEvals", _I, (_P, _P))}),
    "ida": ("sundials_ida", "IDA", True, {
        "Create": ("IDACreate", _PR, (_P,)), "Init": ("IDAInit", _I, (_P, _P, _R, _P, _P)),
        "ReInit": ("IDAReInit", _I, (_P, _R, _P, _P)),
        "Solve": ("IDASolve", _I, (_P, _R, _P, _P, _P, _I)),
        "GetNumFEvals": ("IDAGetNumResEvals", _I, (_P, _P)),
        "GetNumLinFEvals": ("IDAGetNumLinResEvals", _I, (_P, _P)),
        "SetId": ("IDASetId", _I, (_P, _P))}),
    # ARKODE: ARKStep (additive Runge–Kutta, here IMEX) and ERKStep (explicit), one library;
    # ARKStep counts the explicit and the implicit part's evaluations apart (GetNumFEvals2)
    "arkstep": ("sundials_arkode", "ARKStep", True, {
        "Create": ("ARKStepCreate", _PR, (_P, _P, _R, _P, _P)),
        "ReInit": ("ARKStepReInit", _I, (_P, _P, _P, _R, _P)),
        "Solve": ("ARKStepEvolve", _I, (_P, _R, _P, _P, _I)),
        "GetNumFEvals2": ("ARKStepGetNumRhsEvals", _I, (_P, _P, _P)),
        "SetMaxErrTestFails": ("ARKStepSetMaxErrTestFails", _I, (_P, _I)),
        "GetNumLinFEvals": ("ARKStepGetNumLinRhsEvals", _I, (_P, _P))}),
    "erkstep": ("sundials_arkode", "ERKStep", False, {
        "Create": ("ERKStepCreate", _PR, (_P, _R, _P, _P)),
        "ReInit": ("ERKStepReInit", _I, (_P, _P, _R, _P)),
        "Solve": ("ERKStepEvolve", _I, (_P, _R, _P, _P, _I)),
        "GetNumFEvals": ("ERKStepGetNumRhsEvals", _I, (_P, _P))}),
}


@cache
def _library(solver: str) -> SimpleNamespace:
    """A solver's shared library ("cvode" or "ida"), its functions declared under generic names,
    and the struct layout the callbacks rely on checked."""
    soname, prefix, implicit, own = _SOLVERS[solver]
    path = ctypes.util.find_library(soname)
    if path is None:
        raise ImportError(f"SUNDIALS' lib{soname} was not found: apt-get install libsundials-dev")
    lib = ctypes.CDLL(path)

    def declared(symbol, restype, argtypes):
        fn = getattr(lib, symbol)
        fn.restype, fn.argtypes = restype, list(argtypes)
        return fn

    fns = {name: declared(name, *sig) for name, sig in _COMMON.items()}
    generic = _GENERIC | (_IMPLICIT if implicit else {})
    fns |= {name: declared(prefix + name, *sig) for name, sig in generic.items()
            if name not in own}
    fns |= {name: declared(symbol, restype, argtypes)
            for name, (symbol, restype, argtypes) in own.items()}
    ns = SimpleNamespace(**fns, path=path, implicit=implicit, free=ctypes.CDLL(None).free)
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


for _solver in _SOLVERS:    # at import: without them the registry leaves these names out, saying why
    _library(_solver)


def _flag_name(ns, flag: int) -> str:
    p = ns.GetReturnFlagName(flag)
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
    package: ClassVar[str] = "sundials-c"
    kind: ClassVar[str] = "multistep"
    code: ClassVar[str] = "sundials"
    compiled: ClassVar[bool] = True
    rhs_tiers: ClassVar[tuple[str, ...]] = ("numba",)
    rhs_tiers_reason: ClassVar[str] = (
        "SUNDIALS is called from C here: its callbacks are compiled numba cfuncs")
    lmm: ClassVar[int] = _CV_BDF
    _stepper: ClassVar[type]

    @classmethod
    def library_version(cls) -> str:
        return f"SUNDIALS {_library('cvode').version} (ctypes, numba cfunc callbacks)"

    def make_stepper(self, nd, budget):
        return self._stepper(self, nd, budget)


class _Stepper:
    """The segment protocol over one SUNDIALS solver memory, re-initialised at each segment;
    subclasses say which solver and how it is set up and called."""

    solver: ClassVar[str]
    n: ClassVar[int]                     # the length of the solver's state vector
    callbacks: ClassVar[tuple]           # cfuncs: (…, Jacobian, roots); the Jacobian if implicit

    def __init__(self, algorithm: _SundialsC, nd, budget=None):
        self.algorithm = algorithm
        self.nd = nd
        self.budget = budget
        self.stats = Stats()
        self._ns = _library(self.solver)
        self._p = np.empty(_N_P)
        self._y = np.empty(self.n)          # SUNDIALS' y vector wraps this array's memory
        self._eh = np.zeros(_EH_SIZE, np.uint8)
        self._dirs = np.array(DIRECTIONS, dtype=np.intc)
        self._rootinfo = np.zeros(4, dtype=np.intc)
        self._tret, self._count = ctypes.c_double(0.0), ctypes.c_long(0)
        self._ctx = self._mem = self._vec = self._mat = self._ls = None
        self._live = False
        self._p[:N_Q] = form_vector(nd, nd.e_slow)
        self._p[N_Q:] = (math.log(10.0 * nd.e_slow), math.log(nd.e_slow),
                         ln_load_rate(nd.e_slow))

    # --- set-up ---------------------------------------------------------------------------------
    def _check(self, what: str, flag: int) -> None:
        if flag != 0:
            raise RuntimeError(f"{what} returned {_flag_name(self._ns, flag)} ({flag}): "
                               f"{self._message() or 'no message'}")

    def _vector(self, array: np.ndarray) -> int:
        v = self._ns.N_VMake_Serial(len(array), array.ctypes.data, self._ctx)
        if not v:
            raise RuntimeError("SUNDIALS could not allocate a vector")
        self._owned.append(v)
        return v

    def _create(self, tau0: float) -> None:
        ns, a = self._ns, self.algorithm
        ctx = ctypes.c_uint64(0)
        self._check("SUNContext_Create", ns.SUNContext_Create(None, ctypes.byref(ctx)))
        self._ctx, self._owned = ctx.value, []
        self._vec = self._vector(self._y)
        self._mem = self._new_memory(tau0)
        if not self._mem:
            raise RuntimeError("SUNDIALS could not allocate its solver")
        mem, roots = self._mem, self.callbacks[-1]
        self._check("SetErrHandlerFn",
                    ns.SetErrHandlerFn(mem, _on_error.address, self._eh.ctypes.data))
        self._init(tau0)
        self._check("SStolerances", ns.SStolerances(mem, a.rtol, a.atol))
        self._check("SetUserData", ns.SetUserData(mem, self._p.ctypes.data))
        if ns.implicit:
            self._mat = ns.SUNDenseMatrix(self.n, self.n, self._ctx)
            self._ls = ns.SUNLinSol_Dense(self._vec, self._mat, self._ctx)
            if not (self._mat and self._ls):
                raise RuntimeError("SUNDIALS could not allocate its linear solver")
            self._check("SetLinearSolver", ns.SetLinearSolver(mem, self._ls, self._mat))
            self._check("SetJacFn", ns.SetJacFn(mem, self.callbacks[-2].address))
        self._check("RootInit", ns.RootInit(mem, 4, roots.address))
        self._check("SetRootDirection", ns.SetRootDirection(mem, self._dirs.ctypes.data))
        self._check("SetNoInactiveRootWarn", ns.SetNoInactiveRootWarn(mem))

    # --- the protocol ---------------------------------------------------------------------------
    def start(self, tau0, z0, e, t_bound):
        self._close_segment()
        self._e = e
        self._p[_E], self._p[_LN_E] = e, ln_load_rate(e)
        self._t, self._z = float(tau0), np.array(z0, dtype=float)
        self._set_state(self._z)
        self._eh[:] = 0
        self._moved_t, self._moved_steps = self._t, 0     # CVODE's time last seen to advance
        self._failure = None
        try:
            if self._mem is None:
                self._create(self._t)
            else:
                self._reinit(self._t)
            self._check("SetStopTime", self._ns.SetStopTime(self._mem, float(t_bound)))
            self._live = True
        except RuntimeError as exc:
            self._failure = str(exc)

    def advance(self, t_out):
        if self._failure is not None:
            return Advance(self._t, self._z, retcode=ReturnCode.FAILURE, message=self._failure)
        ns, a, mem = self._ns, self.algorithm, self._mem
        while True:
            left = a.max_steps - self.stats.steps - self._get(ns.GetNumSteps)
            if left <= 0:
                return Advance(self._t, self._z, retcode=ReturnCode.MAX_STEPS,
                               message=f"step budget of {a.max_steps} used up at "
                                       f"t = {self._t * self.nd.time_scale:.9g} s")
            ns.SetMaxNumSteps(mem, min(_MXSTEP, left))
            flag = self._solve(t_out)
            t, z = self._tret.value, self._y[:3].copy()
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
            ns.GetRootInfo(mem, self._rootinfo.ctypes.data)
            found = [k for k in range(4) if self._rootinfo[k] != 0]
            counted = directional_roots(self.nd, self._e, z, found,
                                        [int(self._rootinfo[k]) for k in found])
            if counted:
                return Advance(t, z, roots=counted)

    def finish(self):
        self._close_segment()
        ns = self._ns
        if self._mem:
            ns.Free(ctypes.byref(ctypes.c_void_p(self._mem)))
        if self._ls:
            ns.SUNLinSolFree(self._ls)
        if self._mat:
            ns.SUNMatDestroy(self._mat)
        for v in getattr(self, "_owned", ()):
            ns.N_VDestroy(v)
        if self._ctx is not None:
            ns.SUNContext_Free(ctypes.byref(ctypes.c_uint64(self._ctx)))
        self._ctx = self._mem = self._vec = self._mat = self._ls = None
        self._owned = []

    def __del__(self):
        if getattr(self, "_ctx", None) is not None:
            self.finish()

    # --- internals ------------------------------------------------------------------------------
    def _get(self, getter) -> int:
        getter(self._mem, ctypes.byref(self._count))
        return self._count.value

    def _stalled(self) -> int:
        """The steps taken since the solver's time last advanced, if that is too many; else 0."""
        steps = self._get(self._ns.GetNumSteps)
        self._ns.GetCurrentTime(self._mem, ctypes.byref(self._tret))
        if self._tret.value > self._moved_t:
            self._moved_t, self._moved_steps = self._tret.value, steps
            return 0
        return steps - self._moved_steps if steps - self._moved_steps >= _STALLED_STEPS else 0

    def _close_segment(self) -> None:
        """Fold the segment's counters in (a re-initialisation zeroes SUNDIALS' own)."""
        if self._live:
            ns = self._ns
            self.stats += Stats(nfev=self._nfev(),
                                njev=self._get(ns.GetNumJacEvals) if ns.implicit else 0,
                                steps=self._get(ns.GetNumSteps),
                                rejected=self._get(ns.GetNumErrTestFails))
        self._live = False

    def _nfev(self) -> int:
        """Right-hand-side (or residual) evaluations of the segment, the linear solver's too."""
        ns = self._ns
        return self._get(ns.GetNumFEvals) + (self._get(ns.GetNumLinFEvals) if ns.implicit else 0)

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


class _Cvode(_Stepper):
    solver, n, callbacks = "cvode", 3, (_rhs, _jac, _roots)

    def _new_memory(self, tau0) -> int:
        return self._ns.Create(self.algorithm.lmm, self._ctx)

    def _set_state(self, z) -> None:
        self._y[:] = z

    def _init(self, tau0) -> None:
        self._check("CVodeInit", self._ns.Init(self._mem, _rhs.address, tau0, self._vec))

    def _reinit(self, tau0) -> None:
        self._check("CVodeReInit", self._ns.ReInit(self._mem, tau0, self._vec))

    def _solve(self, t_out) -> int:
        return self._ns.Solve(self._mem, t_out, self._vec, ctypes.byref(self._tret), _CV_NORMAL)


class _Ida(_Stepper):
    solver, n, callbacks = "ida", 4, (_res, _res_jac, _res_roots)

    def __init__(self, algorithm, nd, budget=None):
        super().__init__(algorithm, nd, budget)
        self._yp = np.empty(4)               # IDA's y' vector wraps this array's memory
        self._id = dae_differential(nd)

    def _new_memory(self, tau0) -> int:
        self._ypvec, self._idvec = self._vector(self._yp), self._vector(self._id)
        return self._ns.Create(self._ctx)

    def _set_state(self, z) -> None:
        self._y[:], self._yp[:] = dae_initial(self.nd, self._e, z)

    def _init(self, tau0) -> None:
        self._check("IDAInit", self._ns.Init(self._mem, _res.address, tau0, self._vec,
                                             self._ypvec))
        self._check("IDASetId", self._ns.SetId(self._mem, self._idvec))

    def _reinit(self, tau0) -> None:
        self._check("IDAReInit", self._ns.ReInit(self._mem, tau0, self._vec, self._ypvec))

    def _solve(self, t_out) -> int:
        return self._ns.Solve(self._mem, t_out, ctypes.byref(self._tret), self._vec, self._ypvec,
                              _CV_NORMAL)


class _ArkStep(_Stepper):
    """ARKStep with the explicit part h' = E − w and the implicit rest (IMEX: ARKODE's default
    ARK4(3)6L pair), Newton on the implicit part's analytic Jacobian."""

    solver, n, callbacks = "arkstep", 3, (_jac_implicit, _roots)

    def _new_memory(self, tau0) -> int:
        return self._ns.Create(_rhs_explicit.address, _rhs_implicit.address, tau0, self._vec,
                               self._ctx)

    def _set_state(self, z) -> None:
        self._y[:] = z

    def _init(self, tau0) -> None:
        # ARKStepCreate initialised it. With SUNDIALS' default of 7 error-test failures per
        # step the pair fails at the first slip event (flag −3); 20 lets it through
        self._check("ARKStepSetMaxErrTestFails",
                    self._ns.SetMaxErrTestFails(self._mem, _ARK_MAX_ERR_TEST_FAILS))

    def _reinit(self, tau0) -> None:
        self._check("ARKStepReInit", self._ns.ReInit(self._mem, _rhs_explicit.address,
                                                     _rhs_implicit.address, tau0, self._vec))

    def _solve(self, t_out) -> int:
        return self._ns.Solve(self._mem, t_out, self._vec, ctypes.byref(self._tret), _CV_NORMAL)

    def _nfev(self) -> int:
        nfe, nfi = ctypes.c_long(0), ctypes.c_long(0)
        self._ns.GetNumFEvals2(self._mem, ctypes.byref(nfe), ctypes.byref(nfi))
        return nfe.value + nfi.value + self._get(self._ns.GetNumLinFEvals)


class _ErkStep(_ArkStep):
    """ERKStep on the whole right-hand side (ARKODE's default explicit pair, order 4)."""

    solver, n, callbacks = "erkstep", 3, (_roots,)

    def _init(self, tau0) -> None:
        pass                                 # ERKStepCreate initialised it

    def _new_memory(self, tau0) -> int:
        return self._ns.Create(_rhs.address, tau0, self._vec, self._ctx)

    def _reinit(self, tau0) -> None:
        self._check("ERKStepReInit", self._ns.ReInit(self._mem, _rhs.address, tau0, self._vec))

    def _nfev(self) -> int:
        return self._get(self._ns.GetNumFEvals)


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
    _stepper: ClassVar[type] = _Cvode


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
    _stepper: ClassVar[type] = _Cvode


@register
@dataclass(frozen=True)
class SundialsIDA(_SundialsC):
    """SUNDIALS IDA, variable-order variable-step BDF (orders 1–5) on the index-1 DAE form,
    called from compiled code.

    Adaptive. y = (h, u, s, η) with u algebraic (``IDASetId``), Newton iteration on the analytic
    iteration matrix (``dae_jacobian``), consistent initial values from ``dae_initial`` at every
    restart; root functions on y[:3]; residual, Jacobian and root functions are numba cfuncs.
    Needs ``rtol`` and ``atol``. Reference: Hindmarsh et al. (2005), ACM TOMS 31, 363–396.
    """

    name: ClassVar[str] = "sundials-IDA"
    dae: ClassVar[bool] = True
    family: ClassVar[str] = "BDF (DAE)"
    order: ClassVar[int] = 5
    _stepper: ClassVar[type] = _Ida


@register
@dataclass(frozen=True)
class SundialsARKodeIMEX(_SundialsC):
    """SUNDIALS ARKODE's ARKStep, an additive Runge–Kutta method (IMEX: ARK4(3)6L, Kennedy &
    Carpenter 2003), called from compiled code: the spring's h' = E − w explicit, the friction's
    relaxation u', s' implicit (Newton on its analytic Jacobian). Adaptive; ARKODE's root finding
    for the events. Up to 20 error-test failures per step (SUNDIALS' default, 7, stops it at the
    first slip event). Needs ``rtol`` and ``atol``. Reference: Reynolds et al. (2023), ARKODE,
    ACM TOMS 49, doi:10.1145/3594632; Kennedy & Carpenter (2003), Appl. Numer. Math. 44, 139–181.
    """

    name: ClassVar[str] = "sundials-ARKODE-IMEX"
    kind: ClassVar[str] = "implicit"
    family: ClassVar[str] = "additive Runge–Kutta (IMEX)"
    order: ClassVar[int] = 4
    _stepper: ClassVar[type] = _ArkStep


@register
@dataclass(frozen=True)
class SundialsARKodeERK(_SundialsC):
    """SUNDIALS ARKODE's ERKStep, explicit Runge–Kutta (ARKODE's default order-4 pair, Zonneveld
    4(3)), called from compiled code. Adaptive; ARKODE's root finding for the events. Explicit:
    on this stiff problem its steps are bounded by stability, as CashKarp45's. Needs ``rtol`` and
    ``atol``. Reference: Reynolds et al. (2023), ACM TOMS 49, doi:10.1145/3594632.
    """

    name: ClassVar[str] = "sundials-ARKODE-ERK"
    kind: ClassVar[str] = "explicit"
    family: ClassVar[str] = "explicit Runge–Kutta"
    order: ClassVar[int] = 4
    stiff: ClassVar[bool] = False
    _stepper: ClassVar[type] = _ErkStep

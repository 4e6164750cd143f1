"""Event semantics shared by every adaptive backend (SPEC §4), on the ODE form z = (h, u, s).

Root functions located by the backend's own root finding:

* ``START``: u − ln(10·E_slow), crossing upward: an event starts;
* ``END``:   u − ln(E_slow), crossing downward: it ends (under two-speed loading the integration
  stops here and restarts with the fast loading speed);
* ``H_EXTREMUM``: u − ln E (h' = E − w = 0): the spring force is extremal — its maximum before
  an event and its minimum during one;
* ``PEAK``: a function with the sign of u' (C h − D η with mass and no damping), crossing
  downward: the peak slip rate (:func:`problems.formulations.peak_function`).

:class:`EventRecorder` turns the located roots, fed in time order, into the rows of
``EVENT_COLUMNS`` (nondimensional until :meth:`EventRecorder.table` converts them).

The spring force's extremes (``fs_max_before``, ``fs_min``) are read at located states only,
never at save points, so that a save grid cannot change them: h is piecewise smooth with
h' = E − w, so its extremes over a stretch lie at the stretch's ends or where h' = 0 or E
jumps. ``fs_max_before`` is the largest h over [previous END, START] (the start of the run for
the first event): at the previous END, at the H_EXTREMUM roots between, at the ends of loading
segments (E changes there) and at START itself, which is where it lies when the loading is
still faster than the slider as the event starts (two-speed loading: an event that starts
within the fast loading, w crossing 10 E_slow < E_fast with h still rising; the maximum of h
inside the event, at w = E_fast, is not "before"). ``fs_min`` is the smallest h over
[START, END], read at the same kinds of points. The own engine (:mod:`integrators.own.engine`)
also observes every accepted step's end (one comparison a step), which catches an extremum
whose two crossings of h' = 0 fall within one step; the segment driver sees no step ends.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from problems.formulations import form_vector, ode_rhs, peak_function, state_rate_partials
from problems.loading import ln_load_rate

__all__ = ["START", "END", "H_EXTREMUM", "PEAK", "DIRECTIONS", "AT_ROOT", "sign_change",
           "carry_signs",
           "compiled_roots", "root_functions", "RootFunctions", "root_derivatives", "EventRecorder", "events_table",
           "new_recorder", "observe", "record", "REC_SIZE"]

START, END, H_EXTREMUM, PEAK = range(4)
#: direction of a crossing that counts: +1 upward, −1 downward, 0 both
DIRECTIONS = (1, -1, 0, -1)
#: |g| of a root function marked "just crossed, now on this side" after a located root
AT_ROOT = 1e-300


@njit(cache=True, nogil=True, inline="always")
def sign_change(a: float, b: float) -> int:
    """+1 if a root function goes from a to b across zero upwards, −1 downwards, else 0.

    Reaching exactly zero counts (zero is the far side), except from a value marked at a root
    (|a| ≤ ``AT_ROOT``, the sign after a crossing just reported): from there only a strict sign
    change counts. Without that exception a function that sits at exactly zero (velocity-
    strengthening sliding settles at w = E to the bit, where u − ln E is 0.0) crosses back and
    forth at one instant for ever: marked −AT_ROOT → 0 is "up", marked +AT_ROOT → 0 is "down".
    """
    if a < 0.0 and (b > 0.0 or (b == 0.0 and a < -AT_ROOT)):
        return 1
    if a > 0.0 and (b < 0.0 or (b == 0.0 and a > AT_ROOT)):
        return -1
    return 0


@njit(cache=True, nogil=True, inline="always")
def carry_signs(old, new) -> None:
    """Before ``new`` replaces ``old`` as the root functions at the cursor: an exact zero in
    ``new`` becomes ±``AT_ROOT`` with the sign of ``old``. A function that lands on zero without
    crossing (from a marked value, see :func:`sign_change`) keeps the side it came from; a plain
    0.0 would never cross again (``sign_change(0, b)`` is 0)."""
    for k in range(new.shape[0]):
        if new[k] == 0.0 and old[k] != 0.0:
            new[k] = AT_ROOT if old[k] > 0.0 else -AT_ROOT


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def compiled_roots(q, ln_start, ln_end, ln_e, z, g):
    """:func:`root_functions` in numba, into ``g`` (the same operations, so the same values to
    the bit): q the problem vector (:mod:`problems.formulations`), ``ln_start`` = ln(10 E_slow),
    ``ln_end`` = ln E_slow, ``ln_e`` = ln E (:func:`problems.loading.ln_load_rate`)."""
    g[0], g[1], g[2] = z[1] - ln_start, z[1] - ln_end, z[1] - ln_e
    g[3] = peak_function(q, z)


class RootFunctions:
    """The four root functions under loading E = ``e``, their constants computed once:
    ``RootFunctions(nd, e)(z)`` is :func:`root_functions` ``(nd, e, z)``."""

    def __init__(self, nd, e: float):
        self.q = form_vector(nd, e)
        self.levels = (math.log(10.0 * nd.e_slow), math.log(nd.e_slow), ln_load_rate(e))

    def __call__(self, z) -> np.ndarray:
        g = np.empty(4)
        compiled_roots(self.q, *self.levels, np.asarray(z, dtype=float), g)
        return g


def root_functions(nd, e: float, z: np.ndarray) -> np.ndarray:
    """Values of the four root functions at state z under loading E = ``e``."""
    return RootFunctions(nd, e)(z)


def root_derivatives(nd, e: float, z: np.ndarray) -> np.ndarray:
    """d/dτ of the four root functions at z: the crossing direction where one is zero."""
    q = form_vector(nd, e)
    z = np.asarray(z, dtype=float)
    f = np.empty(3)
    ode_rhs(q, z, f)
    h, u, s = z
    w = math.exp(u)
    du, ds = f[1], f[2]
    if nd.quasi_static:
        dsu, dss = state_rate_partials(q, u, s, w)
        dpeak = -nd.c * w * du - nd.beta * (dsu * du + dss * ds)
    else:
        dpeak = nd.c * f[0] - nd.d * (du + nd.beta * ds) - nd.g * w * du
    return np.array([du, du, du, dpeak])


#: the recorder's state (one float array): in an event, the largest h since the last event, the
#: current event's start τ, slip at its start, smallest h, peak w and its τ, events recorded, h(0)
(IN_EVENT, H_MAX, EV_START, EV_SLIP, H_MIN, W_PEAK, TAU_PEAK, N_EVENTS, H0) = range(9)
REC_SIZE = 9


def new_recorder(h0: float) -> np.ndarray:
    """A recorder's state at the start of a run, h(0) = ``h0``."""
    rec = np.full(REC_SIZE, math.nan)
    rec[IN_EVENT], rec[N_EVENTS], rec[H_MAX], rec[H0] = 0.0, 0.0, h0, h0
    return rec


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def observe(rec, h):
    """A located state the run passed through (a root, a segment end, an own engine's step
    end; never a save point, which would make the extrema depend on the save grid): the
    extrema of h."""
    if rec[IN_EVENT] != 0.0:
        if h < rec[H_MIN]:
            rec[H_MIN] = h
    elif h > rec[H_MAX]:
        rec[H_MAX] = h


@njit(cache=True, nogil=True, error_model="numpy")
def record(rec, ev, kind, tau, h, u, load):
    """A located root of ``kind`` at τ with state (h, u) and load-point displacement ``load``
    (Lc); a completed event becomes row rec[N_EVENTS] of ``ev`` (room for it is the caller's
    business), nondimensional. True when an event has just ended."""
    slip = load - (h - rec[H0])
    if kind == START and rec[IN_EVENT] == 0.0:
        # the stretch before the event ends here: h at START counts towards its maximum (h
        # still rises at START when the loading is faster than 10 E_slow, module docstring)
        if h > rec[H_MAX]:
            rec[H_MAX] = h
        rec[IN_EVENT] = 1.0
        rec[EV_START], rec[EV_SLIP] = tau, slip
        rec[H_MIN], rec[W_PEAK], rec[TAU_PEAK] = h, math.exp(u), tau
    elif kind == PEAK and rec[IN_EVENT] != 0.0:
        if math.exp(u) > rec[W_PEAK]:
            rec[W_PEAK], rec[TAU_PEAK] = math.exp(u), tau
    elif kind == H_EXTREMUM:
        observe(rec, h)
    elif kind == END and rec[IN_EVENT] != 0.0:
        if h < rec[H_MIN]:
            rec[H_MIN] = h
        n = int(rec[N_EVENTS])
        ev[n, 0], ev[n, 1], ev[n, 2], ev[n, 3] = rec[EV_START], tau, rec[H_MAX], rec[H_MIN]
        ev[n, 4], ev[n, 5], ev[n, 6], ev[n, 7] = rec[W_PEAK], rec[TAU_PEAK], rec[EV_SLIP], slip
        rec[N_EVENTS] = n + 1
        rec[IN_EVENT] = 0.0
        rec[H_MAX] = h
        return True
    return False


class EventRecorder:
    """The events table from located roots and observed states, for the Python segment driver
    (:mod:`integrators.core.segments`): the compiled recorder the own engine runs, so that every
    backend records events the same way."""

    def __init__(self, h0: float):
        self.rec = new_recorder(h0)
        self.ev = np.empty((64, 8))

    def observe(self, h: float) -> None:
        observe(self.rec, float(h))

    def root(self, kind: int, tau: float, z: np.ndarray, load: float) -> bool:
        """Process a located root of ``kind`` at τ with state z and load-point displacement
        ``load`` (in Lc). Returns True when an event has just ended."""
        if self.rec[N_EVENTS] >= len(self.ev):
            self.ev = np.concatenate([self.ev, np.empty_like(self.ev)])
        return record(self.rec, self.ev, int(kind), float(tau), float(z[0]), float(z[1]),
                      float(load))

    def table(self, problem, nd) -> np.ndarray:
        """The rows in SI units, columns of ``EVENT_COLUMNS``."""
        return events_table(self.ev[:int(self.rec[N_EVENTS])], problem, nd)


def events_table(rows: np.ndarray, problem, nd) -> np.ndarray:
    """Nondimensional event rows (τ, h, w, slip in Lc) in SI units, columns of ``EVENT_COLUMNS``."""
    ts, lc, fh, f0 = nd.time_scale, problem.law.lc, nd.force_h, problem.f0
    scale = np.array([ts, ts, fh, fh, problem.law.v0, ts, lc, lc])
    return rows * scale + np.array([0.0, 0.0, f0, f0, 0.0, 0.0, 0.0, 0.0])

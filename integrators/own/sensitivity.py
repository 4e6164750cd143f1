"""Forward sensitivities through the compiled engine: ∂z/∂θ along each step, root and restart
of a Rodas5P or RadauIIA5 solve, for any set of the problem's parameters
(:mod:`problems.directions`).

Each accepted step is differentiated on the step's own h: Rodas5P's stages, reusing its
factorisation (:func:`integrators.own.rodas5p_stages.stage_sensitivities`: internal
differentiation, the exact derivative of the computed solution with its steps held);
RadauIIA5's collocation equations, solved exactly for the derivative
(:mod:`integrators.own.radau5_sensitivity`). The engine tells :func:`sense` of
every step, save, root and restart (:func:`integrators.own.engine.run`), and it follows:

* at a located root, g(z(τ_r)) = 0 moves by dτ_r = −(∂g/∂z·S + ∂g/∂θ)/(∂g/∂z·f): the event
  time's sensitivity; a value read at the root moves by S + f dτ_r (at an extremum of h or of
  u, f's component is 0 there);
* the recorder's choices (the largest h before an event, the smallest within it, the peak w)
  are mirrored, so that each row of the events table gets its derivative; an extreme h the
  recorder takes at a step end stands for the extremum near it (the envelope:
  :func:`_extremum_shift`);
* at a restart where the loading rate jumps at a moving time τ* (the overshoot starts at an
  event's end, ends τ_fast later; a switch fixed in seconds moves with Lc/v0),
  S⁺ = S⁻ + (f⁻ − f⁺) dτ*;
* an arrest (the engine's limit step through a deep lock) has no derivative: S becomes NaN
  from there, the step control goes on with the state alone, and
  ``Sensitivity.message`` says where.

Only with mass (the quasi-static form's force balance is refused by :mod:`problems.directions`).
Everything here is nondimensional (z, τ); :func:`physical` converts to SI units.

The right-hand side's derivatives (z = (h, u, s), w = e^u, R = s' of the law, N = C h − D η):
f = (E − w, N/w − G, R); ∂f/∂z has rows (0, −w, 0), (C/w, −D/w − N/w, −Dβ/w), (0, R_u, R_s);
∂f/∂θ = (dE, (dC h − dD η − D dβ s)/w − dG, R_γ dγ − γ dE) (the laws here take E only in the
Nagata term −γ E).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from integrators.own import engine
from integrators.own.engine import (HACC, SENSE_ARREST, SENSE_LOAD, SENSE_RESTART, SENSE_ROOT,
                                    SENSE_SAVE, SENSE_SAVE_HANDED, SENSE_SEGMENT_END,
                                    SENSE_STEP, SENSE_STEP_END, TAU, TAU_OLD, ZROW)
from integrators.core.events import END, H_EXTREMUM, PEAK, START
from integrators.own import radau5_sensitivity as radau
from integrators.own.rodas5p_stages import (chain, dense_sensitivities, sensitivity_workspace,
                                            stage_sensitivities, stages)
from problems.formulations import (N_Q, Q_BETA, Q_C, Q_D, Q_E, Q_G, Q_LAWP,
                                   state_rate_partials, state_rate_second_partials)
from problems.loading import H_E_FAST, H_TAU_FAST

__all__ = ["sense", "radau_sense", "sense_with", "radau_error", "arrays", "make_arrays",
           "grow_events", "DIR", "V", "SI", "rodas5p_kernel", "rodas_directions",
           "direction_matrix", "si_columns", "physical"]

#: columns of the directions array: dq (E: the slow rate's), then these
DIR = dict(E_FAST=N_Q, TAU_FAST=N_Q + 1, LN_TS=N_Q + 2, Z0=N_Q + 3, SCALE=N_Q + 6)
_D_EFAST, _D_TAUFAST, _D_LNTS, _D_Z0, _D_SCALE = N_Q, N_Q + 1, N_Q + 2, N_Q + 3, N_Q + 6
N_DIR = N_Q + 7
#: per-direction scalars: the derivatives of the segment's start τ0, the load there, the
#: overshoot's end, the τ handed on, the segment's end; of the recorder's largest h, event
#: start, slip at the start, smallest h, peak w and its τ; the loading rate before a restart
V = dict(TAU0=0, LOAD0=1, FAST_UNTIL=2, LAST_T=3, BOUND=4, H_MAX=5, START=6, SLIP=7, H_MIN=8,
         W_PEAK=9, T_PEAK=10, E_OLD=11)
(_V_TAU0, _V_LOAD0, _V_FAST_UNTIL, _V_LAST_T, _V_BOUND, _V_HMAX, _V_START, _V_SLIP, _V_HMIN,
 _V_WPEAK, _V_TPEAK, _V_EOLD) = range(12)
N_V = 12
_ZO, _F, _ZR, _Z, _ZC = ZROW["ZO"], ZROW["F"], ZROW["ZR"], ZROW["Z"], ZROW["ZC"]
_P_E, _P_TAU_END = engine.P["E"], engine.P["TAU_END"]
_P_RTOL, _P_ATOL = engine.P["RTOL"], engine.P["ATOL"]
_LN_ES, _P_TWO_SPEED = engine.P["LN_E_SLOW"], engine.P["TWO_SPEED"]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _partials(p, dq, z, jac, fth, s):
    """∂f/∂z into jac[s], ∂f/∂θ along the directions ``dq`` into fth[s] (module docstring)."""
    h, u, sv = z[0], z[1], z[2]
    w = math.exp(u)
    beta, c, d = p[Q_BETA], p[Q_C], p[Q_D]
    inv = 1.0 / w
    r_u, r_s = state_rate_partials(p, u, sv, w)
    r_g = state_rate_second_partials(p, u, sv, w)[3]
    j = jac[s]                          # ode_jacobian's form with mass, sharing w and 1/w
    j[0, 0], j[0, 1], j[0, 2] = 0.0, -w, 0.0
    j[1, 0], j[1, 1] = c * inv, -d * inv - (c * h - d * (u + beta * sv)) * inv
    j[1, 2] = -d * beta * inv
    j[2, 0], j[2, 1], j[2, 2] = 0.0, r_u, r_s
    for n in range(dq.shape[0]):
        de = dq[n, Q_E]
        fth[s, 0, n] = de
        fth[s, 1, n] = ((dq[n, Q_C] * h - dq[n, Q_D] * (u + beta * sv) - d * dq[n, Q_BETA] * sv)
                        * inv - dq[n, Q_G])
        fth[s, 2, n] = r_g * dq[n, Q_LAWP] - p[Q_LAWP] * de


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _second(p, dq, z, hyy, hyt):
    """∂²f/∂z∂z into hyy, ∂²f/∂z∂θ along ``dq`` into hyt (:func:`_partials`'s f): the
    entries that are not zero; the others are left as they are, zero in the workspaces that
    hold them (made so, and written by this alone)."""
    h, u, sv = z[0], z[1], z[2]
    w = math.exp(u)
    beta, c, d = p[Q_BETA], p[Q_C], p[Q_D]
    r_uu, r_us, r_ss, r_g, r_ug = state_rate_second_partials(p, u, sv, w)
    inv = 1.0 / w
    n1 = (c * h - d * (u + beta * sv)) * inv
    hyy[0, 1, 1] = -w
    hyy[1, 0, 1] = hyy[1, 1, 0] = -c * inv
    hyy[1, 1, 1] = 2.0 * d * inv + n1
    hyy[1, 1, 2] = hyy[1, 2, 1] = d * beta * inv
    hyy[2, 1, 1], hyy[2, 1, 2], hyy[2, 2, 1], hyy[2, 2, 2] = r_uu, r_us, r_us, r_ss
    for n in range(dq.shape[0]):
        dn = (dq[n, Q_C] * h - dq[n, Q_D] * (u + beta * sv) - d * dq[n, Q_BETA] * sv) * inv
        hyt[1, 0, n] = dq[n, Q_C] * inv
        hyt[1, 1, n] = -dq[n, Q_D] * inv - dn
        hyt[1, 2, n] = -(dq[n, Q_D] * beta + d * dq[n, Q_BETA]) * inv
        hyt[2, 1, n] = r_ug * dq[n, Q_LAWP]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _change(hyy, hyt, n, s0, s1, s2):
    """dJ = ∂J/∂z·S + ∂J/∂θ along direction n, the entries :func:`_second` can make nonzero:
    (0, 1), (1, 0), (1, 1), (1, 2), (2, 1), (2, 2) (:func:`rodas_directions`)."""
    return (hyy[0, 1, 1] * s1, hyt[1, 0, n] + hyy[1, 0, 1] * s1,
            hyt[1, 1, n] + hyy[1, 1, 0] * s0 + hyy[1, 1, 1] * s1 + hyy[1, 1, 2] * s2,
            hyt[1, 2, n] + hyy[1, 2, 1] * s1,
            hyt[2, 1, n] + hyy[2, 1, 1] * s1 + hyy[2, 1, 2] * s2,
            hyy[2, 2, 1] * s1 + hyy[2, 2, 2] * s2)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _products(jst, s, d, u0, u1, u2, k0, k1, k2):
    """J(u_s)·u + dJ·K_s with :func:`_partials`' J, rows (0, −w, 0), (·, ·, ·), (0, R_u, R_s),
    and :func:`_change`'s dJ: the zeros skipped."""
    return (d[0] * k1 + jst[s, 0, 1] * u1,
            d[1] * k0 + d[2] * k1 + d[3] * k2
            + jst[s, 1, 0] * u0 + jst[s, 1, 1] * u1 + jst[s, 1, 2] * u2,
            d[4] * k1 + d[5] * k2 + jst[s, 2, 1] * u1 + jst[s, 2, 2] * u2)


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def rodas_directions(hg, mi, K, jst, fst, hyy, hyt, dk, S):
    """Rodas5P's stage chain of each direction
    (:func:`integrators.own.rodas5p_stages.chain`) for this module's f, the Jacobian's zeros
    skipped (:func:`_change`, :func:`_products`)."""
    chain(_change, _products, hg, mi, K, jst, fst, hyy, hyt, dk, S)


def arrays(directions: np.ndarray, n_grid: int, n_events: int, error_control: bool = False,
           workspace=sensitivity_workspace):
    """The arrays ``sa`` of :func:`sense` for the (n, N_DIR) ``directions``
    (:func:`make_arrays`, run by numpy: the compiled maker's boxing costs microseconds)."""
    return make_arrays.py_func(workspace.py_func, np.ascontiguousarray(directions, dtype=float),
                               n_grid, n_events, float(error_control))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def make_arrays(workspace, directions, n_grid, n_events, error_control):
    """The arrays ``sa`` of :func:`sense` for the (n, N_DIR) ``directions``: the method's
    workspace (its maker ``workspace(n)``: Rodas5P's :func:`sensitivity_workspace`, say), the
    directions, the current dq, S, S at the step's start, the dense output's dD, S at a root,
    S handed on, the scalars :data:`V` (the recorder's largest h is h(0) until a larger is
    seen), the events' derivatives (n_events, 8, n), S at the save points (n_grid, n, 3; the
    first, τ = 0, saved before the kernel runs: ∂z0), a scratch (3, 3: f, a state, and flags:
    DD stale, the sensitivities in the error test (``error_control`` 1.0), an arrest taken),
    and S at a trial step's end. Inlined where it is called: a maker passed to a compiled
    function that is not would be a function pointer, which numba does not cache."""
    n = directions.shape[0]
    sc = directions[:, _D_Z0:_D_Z0 + 3].copy()
    v = np.zeros((n, N_V))
    v[:, _V_HMAX] = sc[:, 0]
    ss = np.full((n_grid, n, 3), np.nan)
    ss[0] = sc
    tmp = np.zeros((3, 3))
    tmp[2, 1] = error_control
    return (workspace(n), directions.copy(), directions[:, :N_Q].copy(), sc.copy(),
            np.zeros((n, 3)), np.zeros((3, n, 3)), np.zeros((n, 3)), sc, v,
            np.full((n_events, 8, n), np.nan), ss, tmp, np.zeros((n, 3)))


def grow_events(sa):
    """``sa`` with the events' derivatives doubled in length, as the engine's events table."""
    return sa[:9] + (np.concatenate([sa[9], np.full_like(sa[9], np.nan)]),) + sa[10:]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _dense(S, SO, DD, x, n, i):
    """Component i of direction n's S on the last step's dense output at the fraction x."""
    y = 1.0 - x
    return y * SO[n, i] + x * (S[n, i] + y * (DD[0, n, i] + x * (DD[1, n, i]
                                                                + x * DD[2, n, i])))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _kept(rec, h):
    """The recorder's :func:`~integrators.core.events.observe`, mirrored: the slot of V
    whose extreme h becomes at a step end (−1: none)."""
    if rec[0] != 0.0:
        return _V_HMIN if h < rec[4] else -1
    return _V_HMAX if h > rec[1] else -1


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _extremum_shift(st, Z):
    """How far a step end the recorder keeps as an extreme h lies from the extremum it
    stands for (one a rounding beyond the located extremum, or the extremum itself). Its
    value moves by S_h at the extremum (f_h = 0: the envelope); S_h at the step end is off by
    dS_h/dτ times the distance, first order. One Newton step on f_h = E − w gives the
    distance δτ = f_h/(w f_u), returned with w; δτ = 0 where the stationary point is not
    within the last step. The derivative carried there is S_h + (dE − w S_u) δτ."""
    w = math.exp(Z[_Z, 1])
    den = w * Z[_F, 1]
    if den != 0.0:
        delta = Z[_F, 0] / den
        if abs(delta) <= st[TAU] - st[TAU_OLD]:
            return w, delta
    return w, 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def _root(st, p, Z, G, sa):
    """At a root the engine has just located (before the recorder sees it): S there, the root
    time's derivative, and the recorder's quantities' derivatives (module docstring)."""
    sw, DIRS, DQ, S, SO, DD, SR, SC, V, EVS, SS, tmp, SN = sa
    rec = st[engine.REC:engine.REC + 9]
    t_old, t_new, t_r = st[TAU_OLD], st[TAU], st[engine.T_RET]
    x = (t_r - t_old) / (t_new - t_old) if t_new > t_old else 1.0
    z = Z[_ZR]
    f = tmp[0]
    engine.f_of(p, z, f)
    w = math.exp(z[1])
    beta, c, d, g = p[Q_BETA], p[Q_C], p[Q_D], p[Q_G]
    kind = 0
    while kind < 3 and G[1, kind] == 0.0:
        kind += 1
    e_slow = math.exp(p[_LN_ES])
    for n in range(S.shape[0]):
        for i in range(3):
            SR[n, i] = _dense(S, SO, DD, x, n, i)
        if kind == PEAK:
            gz0, gz1, gz2 = c, -d - g * w, -d * beta
            gth = (DQ[n, Q_C] * z[0] - DQ[n, Q_D] * (z[1] + beta * z[2])
                   - d * DQ[n, Q_BETA] * z[2] - DQ[n, Q_G] * w)
        else:
            gz0, gz1, gz2 = 0.0, 1.0, 0.0
            gth = -(DQ[n, Q_E] / p[_P_E] if kind == H_EXTREMUM else DIRS[n, Q_E] / e_slow)
        dt = -(gz0 * SR[n, 0] + gz1 * SR[n, 1] + gz2 * SR[n, 2] + gth) / (
            gz0 * f[0] + gz1 * f[1] + gz2 * f[2])
        dh, du = SR[n, 0] + f[0] * dt, SR[n, 1] + f[1] * dt
        load = (V[n, _V_LOAD0] + DQ[n, Q_E] * (t_r - st[engine.TAU0])
                + p[_P_E] * (dt - V[n, _V_TAU0]))
        slip = load - dh + DIRS[n, _D_Z0]
        in_event = rec[0] != 0.0
        h_max, h_min, w_peak = rec[1], rec[4], rec[5]
        for k in range(4):
            if G[1, k] == 0.0:
                continue
            if k == START and not in_event:
                if z[0] > h_max:
                    V[n, _V_HMAX] = dh
                in_event = True
                V[n, _V_START], V[n, _V_SLIP] = dt, slip
                V[n, _V_HMIN], V[n, _V_WPEAK], V[n, _V_TPEAK] = dh, w * du, dt
                h_min, w_peak = z[0], w
            elif k == PEAK and in_event:
                if w > w_peak:
                    V[n, _V_WPEAK], V[n, _V_TPEAK] = w * du, dt
                    w_peak = w
            elif k == H_EXTREMUM:
                if in_event and z[0] < h_min:
                    V[n, _V_HMIN] = dh
                    h_min = z[0]
                elif not in_event and z[0] > h_max:
                    V[n, _V_HMAX] = dh
                    h_max = z[0]
            elif k == END and in_event:
                if z[0] < h_min:
                    V[n, _V_HMIN] = dh
                row = int(rec[7])
                EVS[row, 0, n], EVS[row, 1, n] = V[n, _V_START], dt
                EVS[row, 2, n], EVS[row, 3, n] = V[n, _V_HMAX], V[n, _V_HMIN]
                EVS[row, 4, n], EVS[row, 5, n] = V[n, _V_WPEAK], V[n, _V_TPEAK]
                EVS[row, 6, n], EVS[row, 7, n] = V[n, _V_SLIP], slip
                in_event = False
                V[n, _V_HMAX] = dh
                h_max = z[0]
                if p[_P_TWO_SPEED] != 0.0:
                    V[n, _V_FAST_UNTIL] = dt + DIRS[n, _D_TAUFAST]
        if in_event:                    # the observe after the roots
            if z[0] < h_min:
                V[n, _V_HMIN] = dh
        elif z[0] > h_max:
            V[n, _V_HMAX] = dh
        V[n, _V_LAST_T] = dt
        for i in range(3):
            SC[n, i] = SR[n, i]


@njit(cache=True, nogil=True, error_model="numpy")
def _restart(tau, st, p, Z, sa):
    """After the engine's restart at τ: the loading rate's direction for the new segment, the
    jump of S where the rate changed at a moving time, the segment end's derivative."""
    sw, DIRS, DQ, S, SO, DD, SR, SC, V, EVS, SS, tmp, SN = sa
    hist = p[engine.N_P:]
    tiny = 1e-12 * p[_P_TAU_END]
    e_new = p[_P_E]
    fast = hist[H_TAU_FAST] > 0.0 and st[engine.FAST_UNTIL] - tau > tiny
    e_slow = math.exp(p[_LN_ES])
    for n in range(S.shape[0]):
        e_old = V[n, _V_EOLD]
        for j in range(N_Q):
            DQ[n, j] = DIRS[n, j]
        DQ[n, Q_E] = DIRS[n, _D_EFAST] if fast else DIRS[n, Q_E] * (e_new / e_slow)
        jump = (e_old - e_new) * V[n, _V_LAST_T]
        S[n, 0] = SC[n, 0] + jump
        S[n, 1] = SC[n, 1]
        S[n, 2] = SC[n, 2] - p[Q_LAWP] * jump
        for i in range(3):
            SO[n, i] = S[n, i]
        bound = st[engine.T_BOUND]
        V[n, _V_BOUND] = (V[n, _V_FAST_UNTIL] if fast and bound == st[engine.FAST_UNTIL]
                          else -bound * DIRS[n, _D_LNTS])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _rodas_step(p, dq, hs, ws, sw, z0, S):
    # the engine's SENSE_STEP comes straight after the accepted attempt, the last one, whose
    # stages made the stage Jacobians (_stage_partials): nothing runs an attempt between
    stage_sensitivities(_partials, _second, rodas_directions, p, dq, hs, ws, sw, z0, S, True)
    return True                         # (M is regular: the attempt solved with it)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _radau_step(p, dq, hs, ws, sw, z0, S):
    return radau.step_sensitivities(_partials, p, dq, hs, ws[5], ws[10], sw, z0, S)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def sense(op, arg, st, p, Z, G, ws, grid, sa):
    """The engine's ``sense`` (:func:`integrators.own.engine.run`) for Rodas5P's forward
    sensitivities in the arrays ``sa`` (:func:`arrays`)."""
    sense_with(_rodas_step, dense_sensitivities, op, arg, st, p, Z, G, ws, grid, sa)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def radau_sense(op, arg, st, p, Z, G, ws, grid, sa):
    """:func:`sense` for RadauIIA5 (:mod:`integrators.own.radau5_sensitivity`; its kernel's
    ``ws`` is RadauIIA5's workspace and then ``sa``)."""
    sense_with(_radau_step, radau.dense_sensitivities, op, arg, st, p, Z, G, ws, grid, sa)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def sense_with(step, dense, op, arg, st, p, Z, G, ws, grid, sa):
    """The engine's ``sense`` for a method whose accepted step's sensitivities
    ``step(p, dq, h, ws, sw, z0, S)`` makes (in place; False where its linear system is
    singular: then, as after an arrest, no derivative from there, flag 2) and whose dense
    output's dD ``dense(sw, dD)`` makes from them."""
    sw, DIRS, DQ, S, SO, DD, SR, SC, V, EVS, SS, tmp, SN = sa
    n_s = S.shape[0]
    if op == SENSE_STEP:
        arrested = tmp[2, 2] != 0.0     # S stays NaN (the attempts no longer make SN)
        for n in range(n_s):
            for i in range(3):
                SO[n, i] = S[n, i]
                if tmp[2, 1] != 0.0 and not arrested:   # the attempt differentiated its step
                    S[n, i] = SN[n, i]
        if tmp[2, 1] == 0.0 and not arrested:
            if not step(p, DQ, st[HACC], ws, sw, Z[_ZO], S):
                for n in range(n_s):
                    for i in range(3):
                        S[n, i] = np.nan
                tmp[2, 2] = 2.0         # a singular step: S NaN from here (physical says so)
        tmp[2, 0] = 1.0                 # DD is the last step's no more
    elif op == SENSE_ARREST:
        for n in range(n_s):
            for i in range(3):
                S[n, i] = SO[n, i] = np.nan
                for r in range(3):
                    DD[r, n, i] = 0.0
        tmp[2, 0] = 0.0
        tmp[2, 2] = 1.0                 # no derivative from here on: the solve goes on alone
    elif op == SENSE_SAVE or op == SENSE_SAVE_HANDED:
        # a save time is fixed in seconds: it moves in τ by −τ d ln(Lc/v0)
        if tmp[2, 0] != 0.0 and int(arg) < int(st[engine.NEXT_SAVE]):
            dense(sw, DD)
            tmp[2, 0] = 0.0
        t0, t1 = st[TAU_OLD], st[TAU]
        zt, f = tmp[1], tmp[0]
        for k in range(int(arg), int(st[engine.NEXT_SAVE])):
            x = (grid[k] - t0) / (t1 - t0) if t1 > t0 else 1.0
            if op == SENSE_SAVE_HANDED:
                for i in range(3):
                    zt[i] = Z[_ZC, i]
            else:
                engine._dense(Z, x, zt)
            engine.f_of(p, zt, f)
            for n in range(n_s):
                dt = -grid[k] * DIRS[n, _D_LNTS]
                for i in range(3):
                    if op == SENSE_SAVE_HANDED:
                        sk = SC[n, i]
                    else:
                        sk = S[n, i] if grid[k] == t1 else _dense(S, SO, DD, x, n, i)
                    SS[k, n, i] = sk + f[i] * dt
    elif op == SENSE_ROOT:
        if tmp[2, 0] != 0.0:
            dense(sw, DD)
            tmp[2, 0] = 0.0
        _root(st, p, Z, G, sa)
    elif op == SENSE_STEP_END or op == SENSE_SEGMENT_END:
        slot = _kept(st[engine.REC:engine.REC + 9], Z[_Z, 0])
        at_bound = op == SENSE_SEGMENT_END or arg >= st[engine.T_BOUND]
        if slot >= 0:
            w, delta = (1.0, 0.0) if at_bound else _extremum_shift(st, Z)
            for n in range(n_s):
                if at_bound:            # the segment's end moves: h there by S + f dτ_bound
                    V[n, slot] = S[n, 0] + Z[_F, 0] * V[n, _V_BOUND]
                else:
                    V[n, slot] = S[n, 0] + (DQ[n, Q_E] - w * S[n, 1]) * delta
        for n in range(n_s):
            V[n, _V_LAST_T] = V[n, _V_BOUND] if op == SENSE_SEGMENT_END else 0.0
            for i in range(3):
                SC[n, i] = S[n, i]
    elif op == SENSE_LOAD:
        for n in range(n_s):
            V[n, _V_LOAD0] += (DQ[n, Q_E] * (arg - st[engine.TAU0])
                               + p[_P_E] * (V[n, _V_LAST_T] - V[n, _V_TAU0]))
            V[n, _V_TAU0] = V[n, _V_LAST_T]
            V[n, _V_EOLD] = p[_P_E]
    elif op == SENSE_RESTART:
        _restart(arg, st, p, Z, sa)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt(p, hs, ws, z0, f0, z1, f1, D):
    """Rodas5P's attempt; with the sensitivities in the error test, also their step (into SN)
    and its error, dK_7 of each direction scaled by its parameter's size, |θ| ∂z/∂θ
    (CVODES' scaling), against the state's atol + rtol·|θ S|: the larger error decides."""
    sa = ws[6]
    err = stages(engine.f_of, _stage_partials, p, p[_P_RTOL], p[_P_ATOL], hs, ws, z0, f0, z1, D)
    tmp, SN = sa[11], sa[12]
    if tmp[2, 1] == 0.0 or not err <= 1.0 or tmp[2, 2] != 0.0:
        return err                      # (after an arrest S is NaN: the state's test alone)
    S, DIRS, sw = sa[3], sa[1], sa[0]
    for n in range(S.shape[0]):
        for i in range(3):
            SN[n, i] = S[n, i]
    stage_sensitivities(_partials, _second, rodas_directions, p, sa[2], hs, ws, sw, z0, SN,
                        True)
    return _error_test(p, S, SN, DIRS, sw[4], 7, err)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _stage_partials(p, s, u, ws):
    """:func:`stages`' ``after`` for the sensitive kernel: stage s's ∂f/∂z and ∂f/∂θ at its
    argument u (:func:`_partials`, beside f there: the two share exp(u)), for every attempt,
    so that the accepted one's are at hand (``ws[6]``: ``sa``); none after an arrest."""
    sa = ws[6]
    if sa[11][2, 2] == 0.0:
        _partials(p, sa[2], u, sa[0][0], sa[0][1], s)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def radau_error(p, hs, ws, z0, f0, err):
    """RadauIIA5's attempt (error ``err``) continued: with the sensitivities in the error
    test, their step (into SN) and its error estimate's derivative, tested as Rodas5P's
    (:func:`_attempt`); ``ws`` RadauIIA5's workspace and then ``sa``."""
    sa = ws[13]
    tmp, SN = sa[11], sa[12]
    if tmp[2, 1] == 0.0 or not err <= 1.0 or tmp[2, 2] != 0.0:
        return err
    S, DIRS, sw = sa[3], sa[1], sa[0]
    for n in range(S.shape[0]):
        for i in range(3):
            SN[n, i] = S[n, i]
    _radau_step(p, sa[2], hs, ws, sw, z0, SN)
    radau.error_sensitivities(_partials, _second, p, sa[2], hs, ws[1], ws[2], f0, ws[5],
                              ws[8], ws[10], sw, z0, S)
    return _error_test(p, S, SN, DIRS, sw[4], radau.ERROR_ROW, err)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _error_test(p, S, SN, DIRS, dk, row, err):
    """The larger of ``err`` and the sensitivities' scaled error: dk[n, row] (the error
    estimate's derivative) by its parameter's size, |θ| ∂z/∂θ (CVODES' scaling), against the
    state's atol + rtol·|θ S| over the step's ends."""
    rtol, atol = p[_P_RTOL], p[_P_ATOL]
    for n in range(S.shape[0]):
        scale = DIRS[n, _D_SCALE]
        for i in range(3):
            r = abs(scale * dk[n, row, i]) / (atol + rtol * scale * max(abs(S[n, i]),
                                                                       abs(SN[n, i])))
            if not r <= err:
                err = r
    return err if np.isfinite(err) else np.inf


@njit(**engine.NO_NRT)
def rodas5p_kernel(ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max, sa):
    """Rodas5P's kernel (:mod:`integrators.own.rodas5p`) with :func:`sense` following it."""
    wsx = (ws[0], ws[1], ws[2], ws[3], ws[4], ws[5], sa)
    return engine.run(engine.prepare_jacobian, _attempt, engine.rodas_reject,
                      engine.rodas_accept, wsx, sc, st, p, Z, G, dirs, grid, saved, ev, n_max,
                      sense, sa)


def direction_matrix(directions) -> np.ndarray:
    """The (n, N_DIR) array of :func:`sense` from
    :class:`problems.directions.Direction` objects."""
    out = np.zeros((len(directions), N_DIR))
    for n, d in enumerate(directions):
        out[n, :N_Q] = d.dq
        out[n, _D_EFAST], out[n, _D_TAUFAST], out[n, _D_LNTS] = d.de_fast, d.dtau_fast, d.dln_ts
        out[n, _D_Z0:_D_Z0 + 3] = d.dz0
        out[n, _D_SCALE] = d.scale
    return out


#: the columns of :func:`si_columns`
SI = dict(LN_TS=0, FORCE_H=1, FN=2, LC=3)


def si_columns(directions) -> np.ndarray:
    """What turns each direction's nondimensional derivatives into SI ones, (n, 4): the
    derivatives of ln(seconds per unit τ), of the newtons per unit h, of Fn (N) and of Lc
    (1 along Lc, else 0) (:data:`SI`)."""
    return np.array([[d.dln_ts, d.d_force_h, d.d_fn, 1.0 if d.name == "lc" else 0.0]
                     for d in directions], dtype=float).reshape(len(directions), 4)


def physical(problem, directions, saved: np.ndarray, sa, rows: np.ndarray):
    """The run's sensitivities in SI units (:class:`integrators.core.solution.Sensitivity`):
    ``saved`` the ODE states at the save points, ``rows`` the nondimensional events
    (:func:`integrators.core.events.events_table`'s input), ``sa`` :func:`sense`'s arrays."""
    from integrators.core.solution import Sensitivity
    from problems.formulations import LOG_STATE_LAWS
    nd = problem.nondimensional()
    evs, ss = sa[9][:len(rows)], sa[10][:len(saved)]
    ts, lc, fh, fn = nd.time_scale, problem.law.lc, nd.force_h, problem.normal_force
    n = len(directions)
    events, y = np.empty((len(rows), 8, n)), np.empty((len(saved), 3, n))
    scale = np.array([ts, ts, fh, fh, problem.law.v0, ts, lc, lc])
    h, u, s = saved[:, 0], saved[:, 1], saved[:, 2]
    v = problem.law.v0 * np.exp(u)
    log_state = nd.law_code in LOG_STATE_LAWS
    for j, (d, (dln_ts, d_force_h, d_fn, d_lc)) in enumerate(zip(directions,
                                                               si_columns(directions))):
        dscale = np.array([ts * dln_ts, ts * dln_ts, d_force_h, d_force_h, 0.0,
                           ts * dln_ts, d_lc, d_lc])
        dshift = np.array([0.0, 0.0, 1.0, 1.0, 0, 0, 0, 0]) * problem.mu0 * d_fn
        events[:, :, j] = evs[:, :, j] * scale + rows * dscale + dshift
        dh, du, ds = ss[:, j, 0], ss[:, j, 1], ss[:, j, 2]
        y[:, 0, j] = v * du
        y[:, 1, j] = fh * dh + h * d.d_force_h + problem.mu0 * d.d_fn
        if log_state:
            y[:, 2, j] = np.exp(s) * lc / problem.law.v0 * (ds + d_lc / lc)
        else:
            b = problem.law.b
            y[:, 2, j] = b * fn * ds + s * (d.d_b * fn + b * d.d_fn)
    message = {0.0: "", 1.0: "an arrest (the engine's limit step through a deep lock) has no "
                             "derivative: the sensitivities after the first are NaN",
               2.0: "a step's sensitivity system was singular: the sensitivities after it are "
                    "NaN (with sensitivity_error=True such a step is rejected instead)"
               }[float(sa[11][2, 2])]
    return Sensitivity(names=tuple(d.name for d in directions), y=y, events=events,
                       message=message)

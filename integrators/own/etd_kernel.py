"""Compiled loop of the paper's exponential time differencing (ETD) schemes (Appendices 1–2).

Everything here is a numba ``@njit`` function on plain floats and arrays, nondimensional
(SPEC §2): x = (h, η, Ψ), w = v/v0 from the friction-law constraint, τ = v0 t/Lc.

The loop is resumable: its whole state lives in the float array ``st`` (layout ``S_*`` below),
so the Python side can run it in chunks, empty the output buffers when they fill, report
progress and enforce budgets, without the output growing with the run length.

The step is Eq. 53's, bounded further by the loading: a step may change the spring force by at
most ``o[O_LOAD_MAX]`` times A = a·Fn, i.e. s·(C/D)·|E − w| ≤ load_max (C/D = k Lc/A). Eq. 53
bounds the slip of a step, not the load the spring takes on while the slider sticks (w ≪ E):
there only Δτmax bounds the step, and a large one let a single frozen-coefficient step load the
spring by many A, through the whole nucleation of an event, which the step never saw (its
targets frozen at the start; ETD1 did not even see it at the step's end). At the paper's
settings the bound never binds on the paper's problems (their load per step is at most 0.04 A).

Event detection (SPEC §4) happens inside the loop: an event starts when w crosses 10·E_slow
upwards and ends when w ≤ E_slow; both crossing times are located by linear interpolation of
ln w within the step (second-order accurate). Under two-speed loading the step that crosses the
event end is redone to end at the located time, so that the loading switches at a step boundary
and the scheme keeps its order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from problems.formulations import (N_Q, Q_BETA, Q_C, Q_D, Q_E, Q_G, Q_LAW, etd_targets,
                                   ln_slip_rate)
from problems.loading import H_TAU_FAST, load_segment

# --- layout of the loop state ``st`` -------------------------------------------------------
S_TAU, S_H, S_ETA, S_PSI = 0, 1, 2, 3
S_LOAD = 4            # load-point displacement / Lc since the start
S_FAST_UNTIL = 5      # τ until which the fast loading speed applies
S_IN_EVENT = 6
S_HMAX = 7            # max h since the end of the last event (spring force before the event)
S_HMIN = 8            # min h during the current event
S_WPEAK = 9
S_TAU_START = 10
S_SLIP_START = 11
S_NEXT_SAVE = 12
S_STEPS = 13
S_EVALS = 14
S_REDONE = 15         # steps redone to land on an event end
S_NSAVED = 16
S_NEVENTS = 17
S_TAU_PEAK = 18
S_RULE = 19           # the step-rule ratio of the step that left the rule (STEP_RULE), else 0
S_RULE_MAX = 20       # the largest step-rule ratio of the run (diagnostic)
S_LOAD_BOUND = 21     # steps shortened by the loading bound (diagnostic)
S_SIZE = 22

# --- layout of the parameters ``p`` --------------------------------------------------------
#: the problem vector q of :mod:`problems.formulations` (its E set per step), the end of the run,
#: the event thresholds, the two-speed flag; from P_SIZE on the load-point history
P_TAU_END, P_W_START, P_W_END, P_TWO_SPEED = N_Q, N_Q + 1, N_Q + 2, N_Q + 3
P_SIZE = N_Q + 4

# --- layout of the options ``o`` -----------------------------------------------------------
O_DTAU_MAX, O_DTAU_CNST, O_W_MAX, O_N_ITER, O_SAVE_DTAU, O_RULE_MAX, O_LOAD_MAX = range(7)
O_SIZE = 7

# --- event record columns ------------------------------------------------------------------
E_TAU_START, E_TAU_END, E_HMAX, E_HMIN, E_WPEAK, E_SLIP_START, E_SLIP_END, E_TAU_PEAK = range(8)
E_SIZE = 8

# --- return codes of :func:`etd_advance` ---------------------------------------------------
DONE, BUFFER_FULL, CHUNK_END, NONFINITE, STEP_RULE, STALLED = 0, 1, 2, -1, -2, -3


@njit(cache=True, nogil=True, error_model="numpy")
def log_slip_rate(law, beta, eta, psi):
    """ln w from the friction-law constraint (Eq. 32 slip law, Eq. 62 aging law)."""
    return ln_slip_rate(law, beta, eta, psi)


@njit(cache=True, nogil=True, error_model="numpy")
def coefficients(q, h, eta, psi):
    """Frozen coefficients at (h, η, Ψ) under the problem vector q: w, ηss, D/w (rate of η),
    Ψss, the rate of Ψ.

    Eqs. 36–40 (slip law) and 63–65 (aging law): :func:`problems.formulations.etd_targets`;
    radiation damping moves ηss by −G w/D (η' = (C h − D η)/w − G + β s').
    """
    lnw = ln_slip_rate(int(q[Q_LAW]), q[Q_BETA], eta, psi)
    w = math.exp(lnw)
    d = q[Q_D]
    eta_ss, psi_ss, psi_rate = etd_targets(q, h, lnw, w, psi)
    if q[Q_G] != 0.0:
        eta_ss -= q[Q_G] * w / d
    return w, eta_ss, d / w, psi_ss, psi_rate


@njit(cache=True, nogil=True, error_model="numpy")
def _relax(y0, y_ss, rate, s):
    # exact solution of y' = −rate (y − y_ss) over s; −expm1 keeps accuracy when rate·s is tiny
    return y0 - (y0 - y_ss) * (-math.expm1(-rate * s))


@njit(cache=True, nogil=True, error_model="numpy")
def etd_step(q, h0, eta0, psi0, s, n_iter):
    """One ETD step of length s under the problem vector q (loading rate E = q[Q_E]): first
    order for ``n_iter`` = 0 (Eqs. 33–41), the paper's second-order scheme for 1 (Eqs. 42–52),
    further re-evaluations for more.

    Returns the end state and the largest slip rate w at which coefficients were evaluated (the
    start, the starred state, each iterate): the step-rule check of :func:`etd_advance`."""
    e = q[Q_E]
    w0, ess0, re0, pss0, rp0 = coefficients(q, h0, eta0, psi0)
    w_seen = w0
    h1 = h0 + (e - w0) * s
    eta1 = _relax(eta0, ess0, re0, s)
    psi1 = _relax(psi0, pss0, rp0, s)
    if n_iter > 0:
        half = 0.5 * s
        h_half = h0 + (e - w0) * half
        eta_half = _relax(eta0, ess0, re0, half)
        psi_half = _relax(psi0, pss0, rp0, half)
        for _ in range(n_iter):
            w1, ess1, re1, pss1, rp1 = coefficients(q, h1, eta1, psi1)
            if w1 > w_seen:
                w_seen = w1
            h1 = h_half + (e - w1) * half
            eta1 = _relax(eta_half, ess1, re1, half)
            psi1 = _relax(psi_half, pss1, rp1, half)
    return h1, eta1, psi1, w_seen


@njit(cache=True, nogil=True, error_model="numpy")
def _crossing(lnw0, lnw1, ln_threshold):
    """Fraction of the step at which ln w crosses the threshold (linear interpolation)."""
    if lnw1 == lnw0:
        return 1.0
    f = (ln_threshold - lnw0) / (lnw1 - lnw0)
    return min(1.0, max(0.0, f))


@njit(cache=True, nogil=True, error_model="numpy")
def etd_advance(st, p, o, save_buf, ev_buf, max_steps):
    """Advance the ETD loop from state ``st`` for at most ``max_steps`` steps.

    Writes saved points (τ, h, η, Ψ) to ``save_buf`` and completed events to ``ev_buf`` starting
    at the counts in ``st``. Returns DONE at τ_end, BUFFER_FULL when an output buffer is full,
    CHUNK_END after ``max_steps`` steps, NONFINITE if a step produced a non-finite value,
    STALLED if a step is too short to advance τ in floating point, and STEP_RULE if a step
    slipped more than ``o[O_RULE_MAX]`` times what Eq. 53 allows at the fastest state it
    evaluated (the ratio is in ``st[S_RULE]``); ``st`` then still holds the state before that
    step. Each step is Eq. 53's, shortened to change the spring force by at most
    ``o[O_LOAD_MAX]`` A (module docstring; counted in ``st[S_LOAD_BOUND]``)."""
    law = int(p[Q_LAW])
    beta = p[Q_BETA]
    tau_end = p[P_TAU_END]
    hist = p[P_SIZE:]
    tau_fast = hist[H_TAU_FAST]
    ln_w_start, ln_w_end = math.log(p[P_W_START]), math.log(p[P_W_END])
    two_speed = p[P_TWO_SPEED] > 0.5
    dtau_max, dtau_cnst, w_max = o[O_DTAU_MAX], o[O_DTAU_CNST], o[O_W_MAX]
    slip_bound = dtau_cnst * w_max          # Eq. 53: the slip per step, in Lc, at most
    rule_max = o[O_RULE_MAX]
    load_max = o[O_LOAD_MAX]
    stiffness = p[Q_C] / p[Q_D]             # C/D = k Lc/A: spring force per Lc, in A
    n_iter = int(o[O_N_ITER])
    save_dtau = o[O_SAVE_DTAU]
    evals_per_step = 1 + n_iter
    tiny = 1e-12 * tau_end

    tau, h, eta, psi = st[S_TAU], st[S_H], st[S_ETA], st[S_PSI]
    n_save, n_ev = int(st[S_NSAVED]), int(st[S_NEVENTS])
    for _ in range(max_steps):
        if tau >= tau_end - tiny:
            break
        if n_save >= save_buf.shape[0] or n_ev >= ev_buf.shape[0]:
            _store(st, tau, h, eta, psi, n_save, n_ev)
            return BUFFER_FULL
        lnw = log_slip_rate(law, beta, eta, psi)
        w = math.exp(lnw)
        e, bound = load_segment(hist, tau, st[S_FAST_UNTIL], tau_end, tiny)
        p[Q_E] = e
        s = min(dtau_max, dtau_cnst * w_max / w)          # Eq. 53
        load_rate = stiffness * abs(e - w)                # spring force change per τ, in A
        if s * load_rate > load_max:
            s = load_max / load_rate
            st[S_LOAD_BOUND] += 1
        s = min(s, bound - tau)                           # land on a switch of the loading
        if not tau + s > tau:
            _store(st, tau, h, eta, psi, n_save, n_ev)
            return STALLED
        h1, eta1, psi1, w_seen = etd_step(p, h, eta, psi, s, n_iter)
        st[S_STEPS] += 1
        st[S_EVALS] += evals_per_step
        lnw1 = log_slip_rate(law, beta, eta1, psi1)
        if not (math.isfinite(h1) and math.isfinite(eta1) and math.isfinite(psi1)
                and math.isfinite(lnw1)):
            _store(st, tau, h, eta, psi, n_save, n_ev)
            return NONFINITE
        w1 = math.exp(lnw1)
        # the step rule at the fastest state the step saw: a step that slips far more than the
        # rule allows has run over dynamics it cannot resolve (an event it can step over)
        rule = s * max(w_seen, w1) / slip_bound
        if rule > st[S_RULE_MAX]:
            st[S_RULE_MAX] = rule
        if rule > rule_max:
            st[S_RULE] = rule
            _store(st, tau, h, eta, psi, n_save, n_ev)
            return STEP_RULE
        if st[S_IN_EVENT] < 0.5:
            if lnw1 > ln_w_start:
                f = _crossing(lnw, lnw1, ln_w_start)
                # the force at the start counts towards the largest before the event: under
                # two-speed loading the spring is still loading there (as the recorder's START)
                h_start = h + f * (h1 - h)
                if h_start > st[S_HMAX]:
                    st[S_HMAX] = h_start
                st[S_IN_EVENT] = 1.0
                st[S_TAU_START] = tau + f * s
                st[S_SLIP_START] = st[S_LOAD] + f * e * s - (h + f * (h1 - h))
                st[S_HMIN] = h1
                st[S_WPEAK] = w1
                st[S_TAU_PEAK] = tau + s
            elif h1 > st[S_HMAX]:
                st[S_HMAX] = h1
        elif lnw1 <= ln_w_end:
            f = _crossing(lnw, lnw1, ln_w_end)
            if two_speed and f < 1.0:
                # land on the event end so that the loading switches at a step boundary
                s = f * s
                h1, eta1, psi1, w_seen = etd_step(p, h, eta, psi, s, n_iter)
                st[S_STEPS] += 1
                st[S_EVALS] += evals_per_step
                st[S_REDONE] += 1
                f = 1.0
            tau_end_ev = tau + f * s
            h_end = h + f * (h1 - h)
            ev_buf[n_ev, E_TAU_START] = st[S_TAU_START]
            ev_buf[n_ev, E_TAU_END] = tau_end_ev
            ev_buf[n_ev, E_HMAX] = st[S_HMAX]
            ev_buf[n_ev, E_HMIN] = min(st[S_HMIN], h_end)
            ev_buf[n_ev, E_WPEAK] = st[S_WPEAK]
            ev_buf[n_ev, E_SLIP_START] = st[S_SLIP_START]
            ev_buf[n_ev, E_SLIP_END] = st[S_LOAD] + f * e * s - h_end
            ev_buf[n_ev, E_TAU_PEAK] = st[S_TAU_PEAK]
            n_ev += 1
            st[S_IN_EVENT] = 0.0
            st[S_HMAX] = h1
            if two_speed:
                st[S_FAST_UNTIL] = tau_end_ev + tau_fast
        else:
            if h1 < st[S_HMIN]:
                st[S_HMIN] = h1
            if w1 > st[S_WPEAK]:
                st[S_WPEAK] = w1
                st[S_TAU_PEAK] = tau + s
        st[S_LOAD] += e * s
        tau += s
        h, eta, psi = h1, eta1, psi1
        if tau >= st[S_NEXT_SAVE]:
            save_buf[n_save, 0] = tau
            save_buf[n_save, 1] = h
            save_buf[n_save, 2] = eta
            save_buf[n_save, 3] = psi
            n_save += 1
            while st[S_NEXT_SAVE] <= tau:
                st[S_NEXT_SAVE] += save_dtau
    _store(st, tau, h, eta, psi, n_save, n_ev)
    if tau >= tau_end - tiny:
        return DONE
    return CHUNK_END


@njit(cache=True, nogil=True, error_model="numpy")
def _store(st, tau, h, eta, psi, n_save, n_ev):
    st[S_TAU] = tau
    st[S_H] = h
    st[S_ETA] = eta
    st[S_PSI] = psi
    st[S_NSAVED] = n_save
    st[S_NEVENTS] = n_ev


def initial_loop_state(x0: np.ndarray, save_dtau: float) -> np.ndarray:
    """The loop state at τ = 0 for initial (h, η, Ψ)."""
    st = np.zeros(S_SIZE)
    st[S_H], st[S_ETA], st[S_PSI] = x0
    st[S_FAST_UNTIL] = -np.inf
    st[S_HMAX] = x0[0]
    st[S_NEXT_SAVE] = save_dtau
    return st

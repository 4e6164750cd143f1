"""A stick–slip recording made outside the project's model code: the paper's W2 spring-slider
(slip law, two-speed loading; Urata et al. 2017, Eqs. 4–7 and Tables 2–4, SPEC §1, §4, §5)
integrated by scipy's ``solve_ivp(method="Radau")`` from near steady sliding, so that it starts
with a transient (the start-up) before it settles on its limit cycle; sampled at ``rate`` with
white sensor noise of ``noise`` × each channel's per-event scale (as
``benchmarks/lab/synthetic.py`` adds it; that module's model is not used).

The truth is the run's own, per event: the start and end times of the model's rule (v crosses
10·vLs up, vLs down), Δμ from the spring force at the extremes (Fs is largest where v crosses
vLs upward during the stick and smallest at the event's end, where dFs/dt = k(vLs − v) changes
sign), the slip from start to end — all from the integrator's event location and dense output.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

#: the paper's W2 (problems/presets.py, SPEC §5): m kg, k N/m, Fn N, a, b, Lc m, v0 m/s
M, K, FN, A_LAW, B_LAW, LC, V0 = 1100.0, 1.48e8, 997500.0, 0.008, 0.0094, 3e-7, 1e-5
#: the loading: vLs, vLf (m/s), df (s); μ0 = F0/Fn
VLS, VLF, DF, MU0 = 7.5e-5, 1.9717e-3, 0.042, 0.6
A, B = A_LAW * FN, B_LAW * FN


def _rhs(t, y, vl):
    f, x, th = y                          # Fs − F0 (N), ln v, θ (N)
    v = math.exp(x)
    return [K * (vl - v), (f - A * (x - math.log(V0)) - th) / (M * v),
            -v / LC * (th + B * (x - math.log(V0)))]


def _jac(t, y, vl):
    f, x, th = y
    v = math.exp(x)
    r = f - A * (x - math.log(V0)) - th
    return [[0.0, -K * v, 0.0], [1 / (M * v), (-A - r) / (M * v), -1 / (M * v)],
            [0.0, -v / LC * (th + B * (x - math.log(V0)) + B), -v / LC]]


def _crossing(level, direction, terminal):
    def g(t, y, vl):
        return y[1] - math.log(level)
    g.terminal, g.direction = terminal, direction
    return g


def _phases(t, t_end):
    """(name, vL, events, stop) of one cycle: stick until the start, slip until the end, then
    vLf for df."""
    return (("stick", VLS, [_crossing(10 * VLS, 1, True), _crossing(VLS, 1, False)], t_end),
            ("slip", VLS, [_crossing(VLS, -1, True)], t_end),
            ("fast", VLF, None, None))


def run(t_end: float, start: float = 1.1, rtol: float = 1e-6):
    """The run from steady sliding at vLs/``start``: its pieces (t0, t1, vL, dense output) and
    the per-event truth (t_start, t_end, f_max, f_min)."""
    v = VLS / start
    th = -B * math.log(v / V0)
    y = [A * math.log(v / V0) + th, math.log(v), th]
    t, pieces, rows = 0.0, [], []
    while t < t_end:
        row = {}
        for name, vl, events, stop in _phases(t, t_end):
            stop = stop if stop is not None else min(t + DF, t_end)
            sol = solve_ivp(_rhs, (t, stop), y, method="Radau", rtol=rtol,
                            atol=[1e-4, 1e-10, 1e-4], jac=_jac, dense_output=True,
                            events=events, args=(vl,))
            pieces.append((t, sol.t[-1], vl, sol.sol))
            if name == "stick" and sol.t_events[0].size:
                row["t_start"] = sol.t_events[0][0]
                row["f_max"] = max((e[0] for e in sol.y_events[1]), default=math.nan)
            elif name == "slip" and sol.t_events[0].size:
                row["t_end"], row["f_min"] = sol.t_events[0][0], sol.y_events[0][0][0]
            t, y = sol.t[-1], sol.y[:, -1]
            if t >= t_end:
                break
        if "t_end" in row:
            rows.append(row)
    return pieces, pd.DataFrame(rows)


def _evaluate(pieces, tt):
    """The state (3 × n) and the load point's travel l (m) at the times ``tt``."""
    state, travel, so_far = np.empty((3, len(tt))), np.zeros(len(tt)), 0.0
    for t0, t1, vl, dense in pieces:
        inside = (tt >= t0) & (tt <= t1)
        if inside.any():
            state[:, inside] = dense(tt[inside])
            travel[inside] = so_far + vl * (tt[inside] - t0)
        so_far += vl * (t1 - t0)
    return state, travel


def recording(t_end: float = 45.0, rate: float = 5000.0, noise: float = 0.01, seed: int = 7,
              start: float = 1.1):
    """(the recording's table: time s, shear_force N, acceleration m/s², slip m, table m;
    the per-event truth: t_start, recurrence_s, friction_drop, slip_m)."""
    pieces, ev = run(t_end, start)
    f0 = pieces[0][3](0.0)[0]
    tt = np.arange(0.0, pieces[-1][1], 1.0 / rate)
    (f, x, th), l = _evaluate(pieces, tt)
    slip = l - (f - f0) / K
    accel = (f - A * (x - math.log(V0)) - th) / M          # (Fs − Ft)/m, Eq. 4
    ends = ev.t_end.to_numpy()
    (fs_, _, _), l_s = _evaluate(pieces, ev.t_start.to_numpy())
    (fe_, _, _), l_e = _evaluate(pieces, ends)
    truth = pd.DataFrame({"t_start": ev.t_start, "recurrence_s": ev.t_start.diff(),
                          "friction_drop": (ev.f_max - ev.f_min) / FN,
                          "slip_m": (l_e - (fe_ - f0) / K) - (l_s - (fs_ - f0) / K)})
    clean = {"shear_force": f + MU0 * FN, "acceleration": accel, "slip": slip, "table": l}
    settled = truth.iloc[-3:]
    scale = {"shear_force": settled.friction_drop.mean() * FN,
             "acceleration": float(np.abs(accel).max()), "slip": settled.slip_m.mean(),
             "table": VLS * settled.recurrence_s.mean()}
    rng = np.random.default_rng(seed)
    table = pd.DataFrame({"time": tt, **{c: y + noise * scale[c] * rng.standard_normal(len(y))
                                          for c, y in clean.items()}})
    return table, truth.reset_index(drop=True)

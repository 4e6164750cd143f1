"""Probe cases: the own adaptive integrators where friction, spring or mass are extreme.

A ladder of problems (b up to 0.1, a down to 1e−4, Lc small and large, stiff and soft springs,
heavy and light sliders), each run by every own adaptive method of the registry (the compiled
engine's: :class:`integrators.own.compiled.CompiledAlgorithm`) at rtol = atol = 1e−8 and by a
peer, SUNDIALS' CVODE-BDF at 1e−10. A case passes (``ok``) if the method succeeds and agrees with
the peer, or (``retcode``) if it fails with a failure retcode where the peer fails too; a
Success that disagrees, or a failure where the peer succeeds, is ``wrong``.

Agreement (:func:`check_against_peer`): every event the peer completed (its ``t_start``,
``t_end``, ``t_peak``, ``v_peak``, ``fs_max_before``, ``fs_min``) within ``AGREE[method] ×
rtol`` relative; where both reach the end, the spring force and state there too. Where the peer
stops at the plunge of a deep lock (every step-size control does, integrators.own.engine's
"arrest") its last state still pins the end: the slider then stays stopped (v ~ 1e−30 m/s), so
the spring force grows by k times the load point's displacement and θ stays (slip law) or grows
by the elapsed time (aging law: θ' = 1 − vθ/Lc) — :func:`lock_end`.
"""

from __future__ import annotations

import dataclasses

from probe.harness import Case, Observed, Wrong, cli, cli_outcome, one_json  # noqa: F401

__all__ = ["cases", "ladder", "check_against_peer", "before_plunge", "lock_end", "AGREE",
           "PEER", "PEER_RTOL", "RTOL"]

#: the tolerances of a case's method, and the peer with its tighter ones: CVODE-BDF's own error
#: at rtol = 1e−8 is ~250 rtol in an event's start (2.4e−6 on W2/slip b = 0.05 against itself at
#: 1e−12), at 1e−10 ~2e−8
RTOL = 1e-8
PEER, PEER_RTOL = "sundials-CVODE-BDF", 1e-10
#: allowed relative difference from the peer, in units of rtol: the methods' global error over
#: an event and a lock at rtol = 1e−8, measured against CVODE-BDF at 1e−10 (Rodas5P ≤ 9.7,
#: Exprb43 ≤ 7.3, Exprb32 ≤ 13, Rosenbrock23 ≤ 470: order 2, its error per step controlled;
#: RadauIIA5 between 3 and 10: it fails at 3, passes at 10), with a margin of 2–3
#: (tests/test_deep_lock.py)
AGREE = {"Rodas5P": 30.0, "RadauIIA5": 30.0, "Exprb43": 30.0, "Exprb32": 50.0,
         "Rosenbrock23": 1500.0, "CashKarp45": 30.0}
_EVENT_COLUMNS = ("t_start", "t_end", "t_peak", "v_peak", "fs_max_before", "fs_min")
#: a window's short run: the first event, its lock and the switch back to slow loading
_T_END = 0.06


def _window(name, law, t_end=_T_END, **changes):
    from problems import preset
    p = preset(name, law=law, t_end=t_end)
    law_changes = {k: v for k, v in changes.items() if k in ("a", "b", "lc")}
    slider_changes = {k: v for k, v in changes.items() if k not in law_changes}
    if law_changes:
        p = p.with_law(**law_changes)
    if slider_changes:
        p = dataclasses.replace(p, **{k: getattr(p, k) * v for k, v in slider_changes.items()})
    return p


def ladder():
    """(label, problem factory, deep lock expected, representable) for each rung: b up to 0.1
    and a down to 1e−4 (deep locks; at a = 1e−4 the lock's slip rate, ~e^−800 v0, is below
    the floating-point range, where every method must fail), Lc 0.01 and 10 µm, springs and
    masses ×10 and ×1/10 or ×100 and ×1/100."""
    return [
        ("W2/slip b=0.05", lambda: _window("W2", "slip", b=0.05), True, True),
        ("W2/aging b=0.05", lambda: _window("W2", "aging", b=0.05), True, True),
        ("W1/slip b=0.1", lambda: _window("W1", "slip", b=0.1), True, True),
        ("W4/aging b=0.1", lambda: _window("W4", "aging", b=0.1), True, True),
        ("W3/slip a=0.001", lambda: _window("W3", "slip", a=0.001), True, True),
        ("W2/aging a=0.0005", lambda: _window("W2", "aging", a=0.0005), True, True),
        ("W1/slip a=0.0001", lambda: _window("W1", "slip", a=0.0001), True, False),
        ("W2/slip Lc=0.01 um", lambda: _window("W2", "slip", lc=1e-8), False, True),
        ("W2/aging Lc=10 um", lambda: _window("W2", "aging", lc=1e-5), False, True),
        ("W2/slip k x10", lambda: _window("W2", "slip", stiffness=10.0), False, True),
        ("W2/slip k /10", lambda: _window("W2", "slip", stiffness=0.1), False, True),
        ("W2/slip m x100", lambda: _window("W2", "slip", mass=100.0), False, True),
        ("W2/slip m /100", lambda: _window("W2", "slip", mass=0.01), False, True),
        ("W2/slip m /100 b=0.05", lambda: _window("W2", "slip", mass=0.01, b=0.05), True, True),
    ]


def before_plunge(problem, peer):
    """The peer's run to just before the plunge where it stopped (``peer`` failed after its
    last event ended): the latest end time, found by bisection to 1e−12 s, at which the same
    solver still succeeds. (A failed run hands back the state of its last restart, the event's
    end, not of the plunge: between the two the slider still decelerates and θ still moves.)"""
    from integrators import solve
    lo, hi = peer.events.t_end.iloc[-1], problem.t_end
    best = None
    while hi - lo > 1e-12:
        mid = 0.5 * (lo + hi)
        run = solve(dataclasses.replace(problem, t_end=mid), peer.algorithm, max_points=2)
        if run.success:
            lo, best = mid, run
        else:
            hi = mid
    if best is None:
        raise Wrong(f"the peer fails at once after its event's end ({peer.message})")
    return best


def lock_end(problem, peer):
    """Spring force (N) and θ at ``problem.t_end`` if the slider stays stopped from the end of
    ``peer`` (a successful run up to just before the plunge, :func:`before_plunge`): Fs grows
    by k × the load point's displacement (two-speed loading: vLf until df after the event's
    end, vLs after), θ stays (slip law) or grows by the elapsed time (aging law)."""
    t_f, fs_f, th_f = peer.t[-1], peer.fs[-1], peer.theta[-1]
    load = problem.loading
    switch = peer.events.t_end.iloc[-1] + load.df
    t = problem.t_end
    shift = load.vlf * max(0.0, min(t, switch) - t_f) + load.vls * max(0.0, t - max(switch, t_f))
    theta = th_f + (t - t_f) if problem.law.name == "aging" else th_f
    return fs_f + problem.stiffness * shift, theta


def _close(what, got, want, tol):
    if not abs(got - want) <= tol * abs(want):
        raise Wrong(f"{what}: {got:.10g} against the peer's {want:.10g} (relative "
                    f"{abs(got - want) / abs(want):.2g} > {tol:.2g})")


def check_against_peer(sol, peer, problem, factor: float) -> str:
    """Raise :class:`Wrong` unless the successful ``sol`` agrees with ``peer`` within
    ``factor`` × rtol (module docstring); what was compared, else."""
    tol = factor * sol.algorithm.rtol
    n = len(peer.events) if peer.success else int(peer.events.t_end.notna().sum())
    if peer.success and len(sol.events) != n:
        raise Wrong(f"{len(sol.events)} events, the peer {n}")
    if len(sol.events) < n:
        raise Wrong(f"{len(sol.events)} events before the peer stopped after {n}")
    for i in range(n):
        for col in _EVENT_COLUMNS:
            _close(f"event {i} {col}", sol.events[col].iloc[i], peer.events[col].iloc[i], tol)
    if peer.success:
        want, how = (peer.fs[-1], peer.theta[-1]), "the peer's end"
    elif n and sol.meta.get("arrests", 0) >= 1 and peer.t[-1] >= peer.events.t_end.iloc[n - 1]:
        want, how = lock_end(problem, before_plunge(problem, peer)), "the lock after the peer"
    else:
        raise Wrong(f"Success where the peer stopped ({peer.retcode.value} at t = "
                    f"{peer.t[-1]:.6g} s) without a lock that explains it")
    _close("Fs at the end", sol.fs[-1], want[0], tol)
    _close("theta at the end", sol.theta[-1], want[1], tol)
    return f"{n} events and the end ({how}) within {factor:g} rtol"


def _case(method: str, label: str, make, lock: bool, representable: bool) -> Case:
    def run(tmp):
        from integrators import make_algorithm, solve
        problem = make()
        peer = solve(problem, make_algorithm(PEER, rtol=PEER_RTOL, atol=PEER_RTOL),
                     max_points=2, wall_budget=60)
        sol = solve(problem, make_algorithm(method, rtol=RTOL, atol=RTOL), max_points=2,
                    wall_budget=60)
        if sol.success:
            return Observed("ok", check_against_peer(sol, peer, problem, AGREE[method]))
        if sol.reached_end or not sol.message:
            raise Wrong(f"a failure ({sol.retcode.value}) that reached the end or says nothing")
        if peer.success:
            raise Wrong(f"{sol.retcode.value} ({sol.message}) where {PEER} succeeds")
        return Observed("retcode", f"{sol.retcode.value}: {sol.message}; {PEER}: "
                                   f"{peer.retcode.value}")
    explicit = method == "CashKarp45"
    expect = "ok" if representable and not (lock and explicit) else "retcode"
    return Case("integrators", f"{method} on {label}", run, expect, timeout=300.0)


def _methods():
    from integrators import REGISTRY
    return REGISTRY.select("own", "adaptive")       # the compiled engine's methods


def cases() -> list[Case]:
    return [_case(method, label, make, lock, representable)
            for method in _methods() for label, make, lock, representable in ladder()]

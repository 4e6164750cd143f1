"""diffrax (P. Kidger's JAX solvers) as the external peer of the project's gradients: the
derivatives of every event's ΔT and Δμ by JAX's automatic differentiation through diffrax's
own solve and event handling, written as a diffrax user writes it and independent of the
project's model code.

* The slider in SI, in the variables a user picks for a stiff rate-and-state problem:
  y = (Fs/Fn − μ0, ln(v/v0), ψ) with ψ = θ/Fn (slip law, θ in N) or ln(v0 θ/Lc) (aging law),
  from SPEC §1; the start is the presets' rule (steady sliding's state at vL/1.1, the spring
  force equal to friction), so that its dependence on (b, Lc) is differentiated too.
* ``diffrax.Kvaerno5`` (an ESDIRK of order 5, diffrax's stiff default) with a
  ``PIDController`` at rtol = atol; each event is a terminating ``diffrax.Event`` on ln v
  whose time ``optimistix.Newton`` locates on the dense output at the same tolerances: the
  start (v up through 10 vL), the end (v down through vL: the smallest Fs within the event)
  and the largest Fs before the next (v up through vL). Two-speed loading adds a segment at
  the fast speed for ``df`` after each end.
* The derivatives by ``jax.jacfwd`` with ``diffrax.ForwardMode`` (forward mode: two
  parameters, many outputs); an event time's derivative comes from optimistix's implicit
  differentiation of the root (diffrax's issue #451 reported it zero in older releases). The
  derivatives are not in the step control (as the project's ``sensitivity_error=False``), and
  the root's tolerances act on the event time in seconds. JAX runs in float64
  (``jax_enable_x64``, set process-wide on first use).
* Under two-speed loading an event's largest Fs before it is where v rises through vL, or at
  the fast loading's end if v is above vL there; an event that starts before v has risen
  through vL after the fast loading (one starting within it, say) is a failure, not a row.

Differentiated, diffrax's stiff solve trips equinox's check that a linear solve gets finite
input, in a trial whose result is discarded (W4/slip at every tolerance tried, in forward and
reverse mode; the solve alone passes); the rows it keeps are finite and agree with the
project's. So the peer sets ``EQX_ON_ERROR=nan``, which equinox's documentation offers, unless
the environment sets it (read once, when equinox is first imported): a failed check gives NaN
instead of an exception, and a NaN in a kept row is the peer's failure.

Only a slider with mass under the slip and aging laws without radiation damping, constant or
two-speed loading and the presets' start rule (the gradients study's cases); anything else is
refused before any work. JAX and diffrax are an extra
(``pip install .[diffrax]``); this module imports them on first use.
"""

from __future__ import annotations

import importlib.util
import os
import time
from functools import lru_cache
from typing import NamedTuple

import numpy as np

__all__ = ["available", "event_gradients", "PeerGradients", "PARAMETERS"]

#: the parameters the peer differentiates, by the project's names
PARAMETERS = ("b", "lc")


class PeerGradients(NamedTuple):
    """The peer's answer: ``grads`` (events − 1) × 2 × 2 — dΔT/dp, dΔμ/dp (s and 1 per
    unit of b and of Lc in m) of every event but the first, as
    :func:`benchmarks.physics.metrics.metric_gradients` orders them; the wall time of the
    compiled call with the gradients and of the solve alone (s), the time of the first call of
    each (s: with the compile where that law, loading kind and number of events was not
    compiled before), and the steps the call took; ``grads`` all NaN, the times
    NaN, steps −1 and ``message`` saying why where the solve failed (out of steps, a NaN,
    an exception)."""
    grads: np.ndarray
    wall_s: float
    solve_s: float
    first_s: float
    steps: int
    message: str


def available() -> bool:
    """Whether JAX and diffrax are installed here (found, not imported: see the module
    docstring on ``EQX_ON_ERROR``)."""
    return all(importlib.util.find_spec(name) is not None
               for name in ("jax", "diffrax", "optimistix"))


def _constants(problem) -> tuple[str, bool, np.ndarray]:
    """The law's kind, two-speed or not, and the numbers the compiled call takes."""
    law = type(problem.law).__name__
    if law not in ("SlipLaw", "AgingLaw") or problem.radiation_damping:
        raise ValueError(f"the diffrax peer takes the slip and aging laws without damping, "
                         f"not {problem.name!r} ({law}, damping "
                         f"{problem.radiation_damping} N s/m)")
    hist = problem.loading.history
    if hist.holds or len(hist.velocities) != 1 or hist.v_slow != hist.velocities[0]:
        raise ValueError(f"the diffrax peer takes constant or two-speed loading, not "
                         f"{problem.name!r}'s history")
    if not problem.mass > 0 or not hasattr(problem.initial, "slowdown"):
        raise ValueError(f"the diffrax peer takes a slider with mass and the presets' start "
                         f"rule (BalancedStart), not {problem.name!r} (mass {problem.mass} kg, "
                         f"start {type(problem.initial).__name__})")
    two = bool(hist.two_speed)
    c = [problem.mass, problem.stiffness, problem.normal_force, problem.law.a, problem.law.v0,
         hist.velocities[0], hist.v_fast, hist.fast_duration, problem.t_end,
         problem.initial.slowdown]
    return ("slip" if law == "SlipLaw" else "aging"), two, np.array(c, dtype=float)


def _segments(law: str, max_steps: int):
    """diffrax's solve of the slider from one located crossing to the next (``segment``)."""
    import diffrax as dfx
    import jax.numpy as jnp
    import optimistix as optx

    def rhs(t, y, args):
        (b, lc), c, vl = args
        m, k, fn, a, v0 = c[0], c[1], c[2], c[3], c[4]
        mus, x, psi = y
        v = v0 * jnp.exp(x)
        mut = a * x + (psi if law == "slip" else b * psi)
        dpsi = (-(v / lc) * (psi + b * x) if law == "slip"
                else (v0 / lc) * jnp.exp(-psi) - v / lc)
        return jnp.stack([k * (vl - v) / fn, fn * (mus - mut) / (m * v), dpsi])

    term = dfx.ODETerm(rhs)

    def segment(t0, t1, y0, args, tol, level=None, up=None, guard=None):
        """From t0 to the crossing of ln(v/v0) = ``level`` (upward if ``up``), or to t1 with
        no level. Its steps, or −1e12 if it failed, so that the run's sum says so: out of
        steps, a failed root (with EQX_ON_ERROR=nan these return), no crossing before t1, or
        an upward crossing of ``guard`` first (an event started before the level it waited
        for)."""
        conds = () if level is None else (lambda t, y, args, **kw: y[1] - level,) + (
            () if guard is None else (lambda t, y, args, **kw: y[1] - guard,))
        event = None if level is None else dfx.Event(
            conds, direction=(up, True)[:len(conds)], root_finder=optx.Newton(rtol=tol, atol=tol))
        sol = dfx.diffeqsolve(term, dfx.Kvaerno5(), t0, t1, 1e-6, y0, args=args,
                              stepsize_controller=dfx.PIDController(rtol=tol, atol=tol),
                              event=event, max_steps=max_steps, saveat=dfx.SaveAt(t1=True),
                              adjoint=dfx.ForwardMode())
        ok = sol.result == (dfx.RESULTS.successful if level is None
                            else dfx.RESULTS.event_occurred)
        if guard is not None:
            ok = ok & ~sol.event_mask[1]
        return sol.ts[-1], sol.ys[-1], jnp.where(ok, sol.stats["num_steps"], -1e12)
    return segment


@lru_cache(maxsize=None)
def _compiled(law: str, two_speed: bool, n_events: int, max_steps: int):
    """The jitted calls (θ = (b, Lc), the constants, rtol) → the rows (ΔT, Δμ) of events
    2..``n_events``, and → their Jacobian, the rows and the steps; compiled once per law,
    loading kind and number of events."""
    os.environ.setdefault("EQX_ON_ERROR", "nan")    # read when equinox is first imported
    import jax
    import jax.numpy as jnp
    jax.config.update("jax_enable_x64", True)
    segment = _segments(law, max_steps)

    def rows(theta, c, tol):
        b, lc = theta[0], theta[1]
        v0, vls, vlf, df, t_end = c[4], c[5], c[6], c[7], c[8]
        ln_e, ln_10e = jnp.log(vls / v0), jnp.log(10.0 * vls / v0)
        slow, fast = ((b, lc), c, vls), ((b, lc), c, vlf)
        xs = jnp.log(vls / c[9] / v0)
        psi = -b * xs if law == "slip" else -xs
        y = jnp.stack([c[3] * ln_e + (psi if law == "slip" else b * psi), ln_e, psi])
        horizon = t_end + 1.0
        t, y, n0 = segment(0.0, horizon, y, slow, tol, ln_10e, True)     # the first start

        def end(t, y, overshoot=True):
            """To the event's end (v down through vL: its smallest Fs) and, under two-speed
            loading, through the fast loading after it: Fs at both."""
            t, y, n1 = segment(t, horizon, y, slow, tol, ln_e, False)
            mu_min = y[0]
            if two_speed and overshoot:
                t, y, n2 = segment(t, t + df, y, fast, tol)
                n1 = n1 + n2
            return t, y, n1, mu_min, y[0]

        def cycle(carry, _):            # from an event's start to the next's
            t, y = carry
            t, y, n1, mu_min, mu_end = end(t, y)
            # the next's largest Fs: where v rises through vL (h' = 0), or at the fast
            # loading's end if v was above vL there (h falling); failed if the event starts
            # with no such crossing before it
            t, y, n2 = segment(t, horizon, y, slow, tol, ln_e, True, ln_10e)
            mu_max = jnp.maximum(y[0], mu_end)
            t, y, n3 = segment(t, horizon, y, slow, tol, ln_10e, True)  # its start
            return (t, y), jnp.stack([t, mu_max, mu_min, n1 + n2 + n3])

        (t_last, y_last), out = jax.lax.scan(cycle, (t, y), None, length=n_events - 1)
        n4, mu_last = end(t_last, y_last, overshoot=False)[2:4]
        mins = jnp.concatenate([out[1:, 2], jnp.stack([mu_last])])      # each event's min
        starts = jnp.concatenate([jnp.stack([t]), out[:, 0]])
        values = jnp.stack([jnp.diff(starts), out[:, 1] - mins], axis=1)
        return values, (values, n0 + n4 + out[:, 3].sum())

    def solve(theta, c, tol):
        return rows(theta, c, tol)[0]

    def gradients(theta, c, tol):
        return jax.jacfwd(lambda th: rows(th, c, tol), has_aux=True)(theta)
    return jax.jit(solve), jax.jit(gradients)


def event_gradients(problem, rtol: float, n_events: int, repeats: int = 3,
                    max_steps: int = 1_000_000) -> PeerGradients:
    """The peer's derivatives of ΔT and Δμ with respect to (b, Lc) for events 2..``n_events``
    of ``problem`` (module docstring) at rtol = atol = ``rtol``, each segment between events
    allowed ``max_steps``; the wall times are the minimum of ``repeats`` compiled calls.
    ValueError for a problem the peer does not take, ImportError where JAX or diffrax is
    missing."""
    law, two, c = _constants(problem)
    if n_events < 2:
        raise ValueError(f"n_events must be at least 2, not {n_events}")
    import jax.numpy as jnp
    solve, gradients = _compiled(law, two, int(n_events), int(max_steps))
    theta = jnp.array([problem.law.b, problem.law.lc])
    start = time.perf_counter()
    try:
        solve(theta, c, rtol).block_until_ready()
        jac, (values, steps) = gradients(theta, c, rtol)
        jac, values, steps = np.asarray(jac), np.asarray(values), float(steps)
        message = ("a segment failed (out of steps, no root, or an event out of order)"
                   if steps < 0 else "" if np.isfinite(jac).all() and np.isfinite(values).all()
                   else "a NaN")
    except (RuntimeError, ValueError) as exc:   # equinox's checks, where they raise (XLA's)
        message = str(exc).strip().splitlines()[-1][:200]
    first_s = time.perf_counter() - start
    if message:                     # failed: no gradient, no time
        nan = np.full((n_events - 1, 2, 2), np.nan)
        return PeerGradients(nan, np.nan, np.nan, first_s, -1, message)
    walls = {solve: [], gradients: []}
    for _ in range(repeats):
        for call in walls:
            start = time.perf_counter()
            out = call(theta, c, rtol)
            (out[0] if isinstance(out, tuple) else out).block_until_ready()
            walls[call].append(time.perf_counter() - start)
    return PeerGradients(jac, min(walls[gradients]), min(walls[solve]), first_s, int(steps),
                         "")

"""The limit cycle of a run from its events, in compiled code: one implementation for one run
(:func:`benchmarks.physics.metrics.limit_cycle`) and for a batch of runs inside the ensemble kernel
(:mod:`integrators.own.batch`), so that both classify a run the same way to the bit.

:func:`find_cycle` looks for the shortest period p (in events) whose four metrics repeat event
to event within ``rtol`` over the last ``min_repeats``·p events, tests that the fault locks
between events, and otherwise says why there is no cycle (:data:`OUTCOMES`).
:func:`classify` turns that outcome and the end state into a class of
:data:`CLASSIFICATIONS`. The rules, and the messages a reader sees, are
:mod:`benchmarks.physics.metrics`'. :func:`settled` is the engine's test, at each event's end,
of whether a run may stop there (``integrators.solve(..., settle=rtol)``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from problems.formulations import SLIP_LAW
from problems.loading import EVENT_START_FACTOR

__all__ = ["CLASSIFICATIONS", "CYCLES", "OUTCOMES", "PERIODIC", "OSCILLATING", "NO_EVENTS",
           "STOPPED", "TOO_FEW", "NOT_REPEATING", "F", "N_F", "find_cycle", "classify", "settled",
           "end_offsets", "settle_time", "on_oscillation", "LOCKED_SLIP_RATE", "STEADY_LOG_TOLERANCE",
           "SETTLE_EFOLDS", "DECAY_MARGIN_EFOLDS", "BAND_LOG_V", "BAND_OFFSET"]

CLASSIFICATIONS = ("stick-slip", "multiple recurrence", "oscillation about vL", "stable sliding",
                   "not converged", "too short to classify", "failed")
CYCLES = ("stick-slip", "multiple recurrence")
(_STICK_SLIP, _MULTIPLE, _OSCILLATION, _STABLE, _NOT_CONVERGED, _TOO_SHORT,
 FAILED) = range(len(CLASSIFICATIONS))
#: what :func:`find_cycle` found: a repeating cycle that locks; one that never locks; or no
#: repeating cycle because there are no events, they stopped long before the end, there are too
#: few to compare, or their metrics do not repeat
OUTCOMES = ("periodic", "oscillating", "no events", "stopped", "too few", "not repeating")
PERIODIC, OSCILLATING, NO_EVENTS, STOPPED, TOO_FEW, NOT_REPEATING = range(len(OUTCOMES))
#: stick–slip needs the mean slip rate between events at most this multiple of vLs
#: (:data:`benchmarks.physics.metrics.LOCKED_SLIP_RATE` says how it was chosen)
LOCKED_SLIP_RATE = 0.3
#: a run ended in steady sliding when its three offsets are all below this
#: (:data:`benchmarks.physics.metrics.STEADY_LOG_TOLERANCE`)
STEADY_LOG_TOLERANCE = 0.05
#: linear growth by this many e-folds (e^40 ≈ 2·10^17, more than 1/ε of double precision) turns
#: any perturbation of steady sliding, down to round-off, into one past the event threshold
#: (|ln v/vLs| > ln 10): a run that stays without events this long after its last event, with
#: steady sliding linearly unstable, has had its growth stopped by the nonlinearity — a small
#: limit cycle about vL (:func:`classify`)
SETTLE_EFOLDS = 40.0
#: an end state is on a small oscillation about vL, not in an event nor locked, while
#: |ln v/vLs| is below this — v between vLs/10 (the trajectory's locking level) and the event
#: start 10 vLs — and the state's and the spring's offsets below :data:`BAND_OFFSET` (A)
BAND_LOG_V = math.log(EVENT_START_FACTOR)
#: measured on the small limit cycles of the paper example, W2 and W4 under both laws at
#: k = kcr (1 − 1e−3 … 1e−2), up to where events begin: state and spring offsets at most 2.4 A;
#: a fault locked and healed for a recurrence interval is far off (W2 at its fits: ~8 A and
#: ~6 A), and so is one just weakened by an event
BAND_OFFSET = 3.0
#: a decaying oscillation is promised to be within :data:`STEADY_LOG_TOLERANCE` of steady
#: sliding after ln(offset/tolerance) e-folds of the linear decay plus this margin: the end
#: offsets are one phase of the oscillation, whose amplitude can be a few times larger
DECAY_MARGIN_EFOLDS = 2.0
#: the entries of :func:`find_cycle`'s output: the outcome, the period p, the index of the first
#: event from which the metrics repeat, the four metrics' means over the last period, the
#: locking ratio (mean inter-event slip rate / vLs), the quiet time at the end (s), and the
#: period's recurrence intervals (up to 4, NaN-padded)
F = dict(OUTCOME=0, PERIOD=1, FIRST=2, RECURRENCE=3, DROP=4, SLIP=5, PEAK_V=6, RATIO=7, GAP=8,
         VALUES=9)
_OUTCOME, _PERIOD, _FIRST, _RECURRENCE, _DROP, _SLIP, _PEAK_V, _RATIO, _GAP, _VALUES = range(10)
N_F = 13
MAX_PERIOD = 4


@njit(cache=True, nogil=True, error_model="numpy")
def _repeats_at(x, p, i, rtol):
    """Do all metrics of row p + i of ``x`` match those of row i within ``rtol``?"""
    for j in range(x.shape[1]):
        a, b = x[p + i, j], x[i, j]
        if not abs(a - b) <= rtol * max(abs(a), abs(b)):
            return False
    return True


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _event_change(ev, i, j):
    """The largest relative difference between the four metrics of events i and j (≥ 1) of the
    engine's nondimensional table ``ev`` (0 where both are equal; :func:`_repeats_at`'s
    measure). ΔT, Δμ, slip and peak v are each a constant multiple of τ_start − the previous
    one, h_max − h_min, the slip in Lc and the peak w, so their relative differences are these."""
    worst = 0.0
    for m in range(4):
        if m == 0:
            a, b = ev[i, 0] - ev[i - 1, 0], ev[j, 0] - ev[j - 1, 0]
        elif m == 1:
            a, b = ev[i, 2] - ev[i, 3], ev[j, 2] - ev[j, 3]
        elif m == 2:
            a, b = ev[i, 7] - ev[i, 6], ev[j, 7] - ev[j, 6]
        else:
            a, b = ev[i, 4], ev[j, 4]
        d = abs(a - b)
        r = 0.0 if d == 0.0 else d / max(abs(a), abs(b))
        if not r <= worst:          # a NaN wins
            worst = r
    return worst


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _period_change(ev, k, last, p):
    """:func:`_event_change` at its largest over the p events ending at ``k`` against those
    ending at ``last``."""
    worst = 0.0
    for j in range(p):
        r = _event_change(ev, k - j, last - j)
        if not r <= worst:
            worst = r
    return worst


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _back(ev, last, p, fraction):
    """The latest event k ≤ last − p in the phase of ``last`` (k ≡ last mod p) that starts at
    or before ``fraction`` of the start of event ``last``, by bisection; −1 if none with k ≥ p
    (a whole period before it)."""
    target = fraction * ev[last, 0]
    lo, hi = 0, last - p
    if ev[0, 0] > target:
        return -1
    while lo < hi:                  # the largest index ≤ last − p starting by the target
        mid = (lo + hi + 1) // 2
        if ev[mid, 0] <= target:
            lo = mid
        else:
            hi = mid - 1
    k = last - p * ((last - lo + p - 1) // p)
    return k if k >= p else -1


@njit(cache=True, nogil=True, error_model="numpy")
def settled(ev, n, rtol, max_period, min_repeats):
    """Has the run whose events are the first ``n`` rows of ``ev`` (the engine's table, τ)
    settled on its cycle, so that it may stop at the end of event n − 1?

    For the shortest period p ≤ ``max_period`` whose last ``min_repeats``·p events each
    repeat the event p before them within ``rtol`` (:func:`find_cycle`'s test), two more tests
    on all four metrics, against the latest period in the same phase that ends by t/2 and the
    one that ends by t/4 (t: the last event's start): the change d₂ from the t/2 period to the
    last is within ``rtol``, and it is either below ``rtol``/10 or at most half the change d₁
    from the t/4 period to the t/2 one. A transient that decays like e^(−λt) is then about
    d₂·q/(1 − q) from its cycle, q = e^(−λt/2), and d₂ ≤ d₁/2 means q ≤ 0.14: within d₂/6. The
    first test alone passes a drift of 1e−5 a period with 1e−3 left to go; the t/2 test alone
    passes a slow one early (q near 1). No test of a finite record rules out every slower
    transient: below ``rtol``/10 the record is read as settled."""
    last = n - 1
    for p in range(1, max_period + 1):
        need = min_repeats * p
        if last - p - need + 1 < 1:
            return False
        ok = True
        for i in range(last - p - need + 1, last - p + 1):
            if not _event_change(ev, i, i + p) <= rtol:
                ok = False
                break
        if not ok:
            continue
        half = _back(ev, last, p, 0.5)
        quarter = _back(ev, last, p, 0.25) if half >= 0 else -1
        if quarter < 0:
            return False
        d2 = _period_change(ev, half, last, p)
        d1 = _period_change(ev, quarter, half, p)
        return d2 <= rtol and (d2 <= 0.1 * rtol or d2 <= 0.5 * d1)
    return False


@njit(cache=True, nogil=True, error_model="numpy")
def find_cycle(t_start, t_stop, slip_start, slip_end, x, t_end, rtol, max_period, min_repeats,
               v_slow, out):
    """The limit cycle of the events (module docstring) into ``out`` (:data:`F`, NaN where an
    entry does not apply). ``x``: the events' metrics (n × 4: ΔT with NaN first, Δμ, slip, peak
    v), ``t_start``/``t_stop``: their start and end times (s), ``slip_start``/``slip_end``: the
    slip there (m); ``v_slow``: vLs (m/s), NaN to skip the locking test."""
    for k in range(N_F):
        out[k] = np.nan
    n = x.shape[0]
    gap = t_end - t_stop[n - 1] if n > 0 else t_end
    out[_GAP] = gap
    # events that stopped long before the end are no limit cycle, however regular they were:
    # quiet for more than 3 of the longest of the last max_period recurrence intervals (the
    # last alone would call a period-2 cycle of 0.06 s and 0.45 s stopped whenever the end
    # fell in its long gap)
    longest = -np.inf
    for i in range(max(1, n - max_period), n):
        if x[i, 0] > longest:
            longest = x[i, 0]
    stopped = n > 1 and np.isfinite(longest) and gap > 3.0 * longest
    if not stopped and n > 1:
        xs = x[1:]                    # event 0 has no recurrence interval
        m = xs.shape[0]
        for p in range(1, max_period + 1):
            need = min_repeats * p
            if m < need + p:
                break
            ok = True                 # the last `need` comparisons p apart all repeat
            for i in range(m - p - need, m - p):
                if not _repeats_at(xs, p, i, rtol):
                    ok = False
                    break
            if not ok:
                continue
            out[_PERIOD] = p
            if v_slow == v_slow:      # the mean slip rate between events: does the fault lock?
                ratio = -np.inf
                for i in range(n - p, n):
                    rate = (slip_start[i] - slip_end[i - 1]) / (t_start[i] - t_stop[i - 1])
                    if rate > ratio or rate != rate:
                        ratio = rate
                    if ratio != ratio:
                        break
                ratio = ratio / v_slow
                out[_RATIO] = ratio
                if not ratio <= LOCKED_SLIP_RATE:
                    out[_OUTCOME] = OSCILLATING
                    out[_RECURRENCE] = _tail_mean(xs, p, 0)
                    return
            trailing = 0              # comparisons that repeat, counted from the end
            for i in range(m - p - 1, -1, -1):
                if not _repeats_at(xs, p, i, rtol):
                    break
                trailing += 1
            out[_FIRST] = (m - p) - trailing if trailing < m - p else 0
            for j in range(4):
                out[_RECURRENCE + j] = _tail_mean(xs, p, j)
            for i in range(p):
                out[_VALUES + i] = xs[m - p + i, 0]
            out[_OUTCOME] = PERIODIC
            return
    out[_OUTCOME] = (NO_EVENTS if n == 0 else STOPPED if stopped
                         else TOO_FEW if n - 1 < 2 * min_repeats else NOT_REPEATING)


@njit(cache=True, nogil=True, error_model="numpy")
def _tail_mean(xs, p, j):
    """The mean of column j over the last p rows, summed in order (as numpy does for p < 8)."""
    m, acc = xs.shape[0], 0.0
    for i in range(m - p, m):
        acc += xs[i, j]
    return acc / p


@njit(cache=True, nogil=True, error_model="numpy")
def settle_time(growth_rate, offset, quiet):
    """How much longer (s) than this run a run must last before the linear stability of steady
    sliding decides it, for a run without a cycle that ended ``offset`` (the largest of the
    three end offsets, in A) from steady sliding, ``quiet`` s after its last event (or its
    start). Steady sliding linearly stable (``growth_rate`` σ < 0, 1/s): the time for the
    oscillation to decay within :data:`STEADY_LOG_TOLERANCE` (0 once it is). Unstable (σ > 0):
    the time to :data:`SETTLE_EFOLDS` e-folds of growth since the last event (0 once they have
    passed). Neutral (σ = 0): inf. NaN when σ or ``quiet`` is unknown."""
    if growth_rate < 0.0:
        if offset < STEADY_LOG_TOLERANCE:
            return 0.0
        return (math.log(offset / STEADY_LOG_TOLERANCE) + DECAY_MARGIN_EFOLDS) / -growth_rate
    if growth_rate > 0.0:
        return max(0.0, SETTLE_EFOLDS / growth_rate - quiet)
    if growth_rate == 0.0:
        return np.inf
    return np.nan


@njit(cache=True, nogil=True, error_model="numpy")
def on_oscillation(log_v, state_offset, force_offset):
    """Is an end state on a small oscillation about vL — neither in an event nor locked —
    where the linear stability of steady sliding applies (:data:`BAND_LOG_V`,
    :data:`BAND_OFFSET`)?"""
    return abs(log_v) < BAND_LOG_V and max(state_offset, force_offset) < BAND_OFFSET


@njit(cache=True, nogil=True, error_model="numpy")
def classify(outcome, period, growth_rate, log_v, state_offset, force_offset, quiet=np.nan,
             headroom=np.nan):
    """The index in :data:`CLASSIFICATIONS` of a run that reached its end.

    A periodic cycle by its period, a non-locking one as an oscillation. Without a cycle:
    stable sliding if the run ended near steady sliding (all three offsets below
    :data:`STEADY_LOG_TOLERANCE`) and steady sliding is linearly stable (``growth_rate`` σ < 0,
    1/s; NaN when unknown); not converged with enough events that do not repeat. Otherwise
    the linear stability decides from how long the run has been quiet (``quiet``: the seconds
    since its last event, or its length) and how much longer a run of this problem can be
    (``headroom``, s: the longest run the problem allows, τ = ``TAU_END_MAX``, less this
    run's length), through :func:`settle_time`:

    * unstable steady sliding, :data:`SETTLE_EFOLDS` e-folds of growth without an event (no
      event at all, or events that stopped): the growth has saturated below the event
      threshold, a small limit cycle — an oscillation about vL;
    * the time to settle longer than any run can be (neutral stability, k = kcr to within the
      precision of σ): at every length one can run, a steady oscillation about vL;
    * else too short to classify (a rerun ``settle_time`` longer is).

    Both oscillations need the end on one: |ln v/vLs| below :data:`BAND_LOG_V`, the other two
    offsets below :data:`BAND_OFFSET` (not in an event, not locked): the linear analysis says
    nothing of a fault in an event or locked between events.

    ``quiet`` and ``headroom`` NaN (not known): too short to classify, the rule without them.
    """
    if outcome == PERIODIC:
        return _STICK_SLIP if period == 1 else _MULTIPLE
    if outcome == OSCILLATING:
        return _OSCILLATION
    offset = max(abs(log_v), max(state_offset, force_offset))
    if growth_rate < 0.0 and offset < STEADY_LOG_TOLERANCE:
        return _STABLE
    if outcome == NOT_REPEATING:
        return _NOT_CONVERGED
    if headroom == headroom and on_oscillation(log_v, state_offset, force_offset):
        wait = settle_time(growth_rate, offset, quiet)
        if (wait == 0.0 and growth_rate > 0.0) or wait > headroom:
            return _OSCILLATION
    return _TOO_SHORT


@njit(cache=True, nogil=True, error_model="numpy")
def end_offsets(law_code, a, b, lc, v0, fn, f0, v_ref, v, fs, theta, damping):
    """How far the end state (v, Fs, θ) is from steady sliding at ``v_ref`` (the load point's
    speed at the end of the run): ln(v/v_ref), and the state's friction term and the spring
    force off their steady values (Fs = Ft,ss + ηr v_ref, ``damping`` = ηr) in units of
    A = a·Fn (the friction laws' formulas, :mod:`problems.friction`: the slip law's state is
    its friction term; the aging and Nagata laws' is B ln(v0 θ/Lc))."""
    amp = a * fn
    ft_ss = f0 + (a - b) * fn * math.log(v_ref / v0) + damping * v_ref
    if law_code == SLIP_LAW:     # θ is the state term itself, θss = −B ln(v_ref/v0)
        state, state_ss = theta, -b * fn * math.log(v_ref / v0)
    else:                        # B ln(v0 θ/Lc), θss = Lc/v_ref
        state = b * fn * math.log(v0 * theta / lc)
        state_ss = b * fn * math.log(v0 * (lc / v_ref) / lc)
    return math.log(v / v_ref), abs(state - state_ss) / amp, abs(fs - ft_ss) / amp

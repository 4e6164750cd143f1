"""The apparatus constants an event catalogue does not state, estimated from it where it can:
the stiffness k and the load-point speed vL of a one-degree-of-freedom spring-slider, each
with its standard error and what it assumed; and the problem file (``apparatus.toml``) that
``rsfbench observe --catalogue`` writes from them.

**Stiffness.** In a spring-slider the spring's force falls by k × slip during an event, so each
event measures k/Fn = Δμ/slip (1/m; Δμ the friction drop). The estimate is the **median** of
the per-event ratios over every event with a slip (the start-up and the outliers too: each
event's drop and slip measure the same spring); its spread is the robust σ (1.4826 × the
median absolute deviation) and its standard error √(π/2)·σ/√n, the median's under Gaussian
scatter. The median rather than a regression of the drops on the slips through the origin:
least squares weights each event by its slip squared, so that a few large events (the NIED
catalogue's start-up slips three times as far as the others) carry the fit. The regression is
given beside it as a check (``stiffness_regression``). k = Fn × k/Fn (N/m) with the normal
force, and per unit area σn × k/Fn = k/area (Pa/m).

**Load-point speed.** Between events the spring is loaded: the friction rises from the level
after event i to the level before event i+1 in onset[i+1] − onset[i]. With the load point at
a constant speed vL and the fault locked the rate is k·vL/Fn, so vL = rate/(k/Fn), whatever
the normal force. The rate is the whole record's, Σ(μ_before[i+1] − μ_after[i]) /
Σ(onset[i+1] − onset[i]) — the spring's loading over the time it took, the balance a
periodic cycle keeps (ΔT = Δμ·Fn/(k·vL) for a locked stick) — with a ratio estimator's
standard error, combined with the stiffness's. The median of the per-interval rates is given
beside it (``vl_median_interval``): the two differ when the stress regained is not in
proportion to the interval, as on the NIED catalogue, where it is about the same after 1 s as
after 10 s. Without the levels before and after (a catalogue of drops), the stress regained
is the next event's drop (the level after the events assumed not to drift). What it assumes:

* a fault that creeps between events (slip the catalogue does not count) loads the spring
  more slowly than k·vL: the estimate is then low;
* a level "after" read a time d after the onset (``after_delay``; 170 ms on the NIED
  catalogue) makes the rate low by d/ΔT (the stress rises over ΔT − d, divided by ΔT) and the
  drop low by the reloading over d less the event's duration, so k is low by up to the same
  fraction; in vL = rate/(k/Fn) the two cancel but for the event's duration over ΔT. Both
  bounds are reported (``after_bias``), not corrected for.

**Mass.** A catalogue of times, stresses and slips holds no inertia: the moving mass cannot be
estimated from it. The problem file takes the one given, else the paper's (Table 4, 1.1 × 10³
kg), marked as assumed. Nor does it hold the friction law's direct effect a: the file takes the
one given, else the paper's a = 0.008 (Indian metagabbro), marked as assumed.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from problems._validate import check_positive
from problems.presets import A as PAPER_A, MASS as PAPER_MASS

__all__ = ["Estimate", "CatalogueConstants", "estimate_constants", "catalogue_apparatus_toml",
           "PAPER_A", "PAPER_MASS", "MIN_EVENTS_CONSTANTS", "T_END_CYCLES", "box_lc"]

#: the fewest events with a slip for a stiffness, and the fewest intervals for a loading rate
MIN_EVENTS_CONSTANTS = 3
#: √(π/2): the median's standard error over the mean's, under Gaussian scatter
_MEDIAN_SE = math.sqrt(math.pi / 2.0)
#: the problem file's simulated time in mean recurrence intervals. A spring near its critical
#: stiffness, as a catalogue's fit is, settles slowly from the presets' start: on the NIED
#: catalogue's apparatus 10 intervals (40 s) left 29 of 49 points of the prior box "not
#: converged", 25 (100 s) left 1, whose ΔT then agreed with 200 s runs to 6e−5
T_END_CYCLES = 25.0


@dataclass(frozen=True)
class Estimate:
    """One constant: its value, standard error and unit, how it was obtained (``measured``
    from the catalogue, ``given``, ``assumed``) and what that assumed."""

    value: float
    se: float
    unit: str
    how: str
    assumption: str


@dataclass(frozen=True)
class CatalogueConstants:
    """The apparatus constants of a catalogue (module docstring).

    Parameters
    ----------
    stiffness_per_fn : Estimate
        k/Fn (1/m): the median of the events' drop/slip.
    stiffness : Estimate or None
        k (N/m); None without the normal force.
    stiffness_per_area : Estimate or None
        k/area (Pa/m); None without the normal force or the area.
    vl : Estimate
        The load-point speed (m/s).
    loading_rate : Estimate
        The friction regained between events per second (1/s).
    stiffness_regression : float
        k/Fn (1/m) from a regression of the drops on the slips through the origin: a check.
    vl_median_interval : float
        vL (m/s) from the median of the intervals' loading rates: a check.
    friction_before : float
        The median friction before the events (NaN without the levels).
    n_events, n_intervals : int
        The events with a slip, and the intervals between events, used.
    after_bias : dict or None
        The bounds of the bias of a level "after" read late (``after_delay`` given).
    notes : tuple of str
        What the estimates assumed, in words.
    """

    stiffness_per_fn: Estimate
    stiffness: Estimate | None
    stiffness_per_area: Estimate | None
    vl: Estimate
    loading_rate: Estimate
    stiffness_regression: float
    vl_median_interval: float
    friction_before: float
    n_events: int
    n_intervals: int
    after_bias: dict | None
    notes: tuple = field(default_factory=tuple)

    def as_dict(self) -> dict:
        """The estimates as plain data (for observations.json and ``--json``).

        Returns
        -------
        dict
            Each field; an :class:`Estimate` as a dict of its fields.
        """
        return {k: (asdict(v) if isinstance(v, Estimate) else v) for k, v in
                self.__dict__.items() if k != "notes"} | {"notes": list(self.notes),
                                                          "mass": MASS_NOT_ESTIMABLE}


#: what a catalogue says of the mass
MASS_NOT_ESTIMABLE = ("not estimable from a catalogue: times, stresses and slips hold no "
                      "inertia")


def estimate_constants(events: pd.DataFrame, normal_force: float | None = None,
                        area: float | None = None,
                        after_delay: float | None = None) -> CatalogueConstants:
    """The stiffness and the load-point speed a catalogue's events imply (module docstring).

    Parameters
    ----------
    events : pandas.DataFrame
        The per-event table of :func:`benchmarks.lab.catalogue.read_catalogue` (or
        ``events.csv`` of ``observe --catalogue``): ``t_start`` (s), ``friction_drop``,
        ``slip_m`` (m), optionally ``friction_before`` and ``friction_after``. Every event is
        used, kept in the means or not.
    normal_force : float, optional
        Fn (N): the stiffness in N/m.
    area : float, optional
        The fault's area (m²), with ``normal_force``: the stiffness per unit area (Pa/m).
    after_delay : float, optional
        When the catalogue's level after an event is read, in s after its onset: only the
        bounds of the bias it causes are reported (``after_bias``).

    Returns
    -------
    CatalogueConstants
        The estimates with their standard errors and assumptions.

    Raises
    ------
    ValueError
        A column missing, fewer than three events with a slip, a slip or a drop that is not
        positive, onsets that do not increase, a normal force, area or delay out of range.
    """
    onset, drop, slip = _checked(events)
    if normal_force is not None:
        check_positive("normal_force", normal_force)
    if area is not None:
        check_positive("area", area)
    kappa = _stiffness_per_fn(drop, slip)
    gain, dt, from_levels = _loading(events, onset, drop)
    if after_delay is not None and not 0.0 <= after_delay < dt.min():
        raise ValueError(f"after_delay = {after_delay:g} s must be from 0 to below the "
                         f"shortest recurrence interval ({dt.min():.6g} s)")
    rate = _ratio(gain, dt)
    vl = _speed(rate, kappa)
    k, k_area = _in_force(kappa, normal_force, area)
    bias = None if after_delay is None else {
        "after_delay_s": after_delay, "rate_low_by": after_delay / float(dt.mean()),
        "stiffness_low_by_at_most": after_delay * rate.value / float(np.median(drop)),
        "vl": "the two cancel but for the events' duration over ΔT"}
    valid = np.isfinite(slip)
    regression = float(drop[valid] @ slip[valid] / (slip[valid] @ slip[valid]))
    return CatalogueConstants(
        stiffness_per_fn=kappa, stiffness=k, stiffness_per_area=k_area, vl=vl,
        loading_rate=rate, stiffness_regression=regression,
        vl_median_interval=float(np.median(gain / dt)) / kappa.value,
        friction_before=(float(np.nanmedian(events["friction_before"])) if from_levels
                         else math.nan),
        n_events=int(valid.sum()), n_intervals=len(dt), after_bias=bias,
        notes=tuple(_notes(from_levels, bias)))


def _checked(events: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(onset, Δμ, slip) of ``events``, or ``ValueError`` naming what is missing or wrong."""
    missing = [c for c in ("t_start", "friction_drop", "slip_m") if c not in events]
    if missing:
        raise ValueError(f"the event table has no column {missing[0]!r} (the table of "
                         "read_catalogue: t_start, friction_drop, slip_m)")
    onset, drop, slip = (events[c].to_numpy(dtype=float) for c in
                         ("t_start", "friction_drop", "slip_m"))
    if len(onset) < MIN_EVENTS_CONSTANTS or not np.isfinite(onset).all():
        raise ValueError(f"{len(onset)} events with an onset: the constants need at least "
                         f"{MIN_EVENTS_CONSTANTS}")
    if (np.diff(onset) <= 0).any():
        i = int(np.flatnonzero(np.diff(onset) <= 0)[0]) + 1
        raise ValueError(f"event {i + 1}: onset {onset[i]:.9g} s is not after the previous one "
                         f"({onset[i - 1]:.9g} s)")
    for name, x, unit in (("friction_drop", drop, ""), ("slip_m", slip, " m")):
        bad = np.flatnonzero(np.isfinite(x) & ~(x > 0))
        if len(bad) or (name == "friction_drop" and not np.isfinite(x).all()):
            i = int(bad[0]) if len(bad) else int(np.flatnonzero(~np.isfinite(x))[0])
            raise ValueError(f"event {i + 1}: {name} = {x[i]:.6g}{unit} is not positive: an "
                             "event drops the stress and slips forward")
    if np.isfinite(slip).sum() < MIN_EVENTS_CONSTANTS:
        raise ValueError(f"{int(np.isfinite(slip).sum())} events have a slip: the stiffness "
                         f"(drop/slip) needs at least {MIN_EVENTS_CONSTANTS} (map the "
                         "catalogue's slip: --column slip=COLUMN:UNIT)")
    return onset, drop, slip


def _stiffness_per_fn(drop: np.ndarray, slip: np.ndarray) -> Estimate:
    """k/Fn = median(Δμ/slip) (1/m), its robust standard error."""
    ratio = (drop / slip)[np.isfinite(slip)]
    median = float(np.median(ratio))
    spread = 1.4826 * float(np.median(np.abs(ratio - median)))
    return Estimate(median, _MEDIAN_SE * spread / math.sqrt(len(ratio)), "1/m", "measured",
                    f"a one-degree-of-freedom spring: each event's friction drop is k/Fn times "
                    f"its slip; the median of {len(ratio)} events' drop/slip, its standard "
                    f"error √(π/2)·σr/√n from their robust spread σr = {spread:.4g} 1/m")


def _loading(events, onset, drop) -> tuple[np.ndarray, np.ndarray, bool]:
    """(friction regained between consecutive events, their intervals, whether from the
    levels before and after the events)."""
    dt = np.diff(onset)
    if {"friction_before", "friction_after"} <= set(events.columns):
        before, after = (events[c].to_numpy(dtype=float)
                         for c in ("friction_before", "friction_after"))
        gain = before[1:] - after[:-1]
        if np.isfinite(gain).all():
            return gain, dt, True
    return drop[1:], dt, False


def _ratio(gain: np.ndarray, dt: np.ndarray) -> Estimate:
    """The record's loading rate Σgain/Σdt (1/s), with the ratio estimator's standard error."""
    rate = float(gain.sum() / dt.sum())
    n = len(dt)
    se = math.sqrt(float(((gain - rate * dt) ** 2).sum()) / (n * (n - 1))) / float(dt.mean())
    return Estimate(rate, se, "1/s", "measured",
                    f"the friction regained over {n} intervals between events over their "
                    "duration; its standard error a ratio estimator's")


def _speed(rate: Estimate, kappa: Estimate) -> Estimate:
    """vL = rate/(k/Fn) (m/s), the two standard errors combined."""
    vl = rate.value / kappa.value
    se = vl * math.hypot(rate.se / rate.value, kappa.se / kappa.value)
    return Estimate(vl, se, "m/s", "measured",
                    "constant loading and a locked fault between events: the record's loading "
                    "rate over k/Fn (low if the fault creeps between events)")


def _in_force(kappa: Estimate, normal_force, area) -> tuple:
    """k (N/m) and k per unit area (Pa/m) from k/Fn, where the loads allow."""
    if normal_force is None:
        return None, None
    k = Estimate(kappa.value * normal_force, kappa.se * normal_force, "N/m", "measured",
                 f"k/Fn × Fn = {normal_force:.6g} N")
    if area is None:
        return k, None
    return k, Estimate(k.value / area, k.se / area, "Pa/m", "measured",
                       f"k over the fault's area {area:.6g} m²")


def _notes(from_levels: bool, bias) -> list[str]:
    notes = ["stiffness: the median of the events' drop/slip (a one-degree-of-freedom spring); "
             "load-point speed: the record's loading rate between events over k/Fn (constant "
             "loading, a locked fault: low if the fault creeps between events); mass: "
             + MASS_NOT_ESTIMABLE]
    if not from_levels:
        notes.append("the loading between events from the next event's drop: no levels before "
                     "and after the events (the level after them assumed not to drift)")
    if bias:
        notes.append(f"the level after each event is read {bias['after_delay_s']:g} s after its "
                     f"onset: the loading rate is low by {bias['rate_low_by']:.1%} and k by up "
                     f"to {bias['stiffness_low_by_at_most']:.1%}; in vL they cancel but for the "
                     "events' duration over ΔT (not corrected)")
    return notes


def box_lc(b_minus_a: float, normal_force: float, stiffness: float) -> tuple[float, float]:
    """``(Lc_hi, Lc_lo)`` (m) of the prior box the problem file suggests: the decade above the
    critical slip distance (b − a)·Fn/k (above it steady sliding is stable) and three decades
    below it."""
    hi = 10.0 ** math.ceil(math.log10(b_minus_a * normal_force / stiffness))
    return hi, hi / 1000.0


def catalogue_apparatus_toml(constants: CatalogueConstants, recurrence_s: float, name: str,
                             normal_force: float, mass: float | None = None,
                             a: float | None = None) -> str:
    """A problem file of the apparatus a catalogue implies: k and vL measured (module
    docstring), Fn given, the mass and the law's a given or assumed (the paper's), b and Lc
    placeholders for ``rsfbench invert`` to estimate.

    Parameters
    ----------
    constants : CatalogueConstants
        The estimates (with the stiffness in N/m: the normal force known).
    recurrence_s : float
        The mean recurrence interval (s): the simulated time is :data:`T_END_CYCLES` of them.
    name : str
        The problem's name.
    normal_force : float
        Fn (N).
    mass : float, optional
        The slider's mass (kg); None: the paper's, assumed.
    a : float, optional
        The friction law's direct effect; None: the paper's, assumed.

    Returns
    -------
    str
        The TOML text (:func:`problems.load_problem` reads it).

    Raises
    ------
    ValueError
        Without the stiffness in N/m, or with a mass, a or ΔT that is not positive.
    """
    if constants.stiffness is None:
        raise ValueError("the problem file needs the stiffness in N/m: give the normal stress "
                         "or force")
    check_positive("recurrence_s", recurrence_s)
    check_positive("normal_force", normal_force)
    m_how = "given" if mass is not None else "assumed: the paper's slider (Table 4)"
    a_how = "given" if a is not None else "assumed: the paper's, Indian metagabbro (Table 4)"
    mass = PAPER_MASS if mass is None else check_positive("mass", mass)
    a = PAPER_A if a is None else check_positive("a", a)
    k, vl = constants.stiffness, constants.vl
    b = a + 0.0005
    lc = 0.3 * (b - a) * normal_force / k.value          # k = 0.3 kc: stick–slip
    b_hi = a + 0.002
    lc_hi, lc_lo = box_lc(b_hi - a, normal_force, k.value)
    mu0 = constants.friction_before
    mu0_line = (f"mu0 = {mu0:.4g}                 # F0/Fn, measured: the median friction before "
                "the events\n" if math.isfinite(mu0) else "")
    return (f"# The apparatus of the catalogue {name!r}, as `rsfbench observe --catalogue` "
            "estimated it.\n# k and vl are measured from the catalogue (± 1 se in the comment); "
            "the mass and the\n# law's a are not in it: given, or assumed. b and lc are "
            "placeholders (the spring 0.3 of\n# its critical stiffness: stick-slip), not a fit: "
            "`rsfbench invert --problem THIS\n# --observations observations.json "
            f"--b-range {a:.6g},{b_hi:.6g} --lc-range {lc_lo:.0e},{lc_hi:.0e}` estimates "
            "them\n# (b from a, where stick-slip starts, to a + 0.002; Lc from three decades "
            "below to the\n# decade above the critical slip distance (b - a)·Fn/k at that b). SI "
            "units.\n"
            f"name = {json.dumps(name)}\n"
            f"mass = {mass:.6g}                 # kg, {m_how}\n"
            f"stiffness = {k.value:.6g}       # N/m, measured ± {k.se:.2g}\n"
            f"normal_force = {normal_force:.6g} # N, given\n"
            f"t_end = {T_END_CYCLES * recurrence_s:.6g}                # s: "
            f"{T_END_CYCLES:g} mean recurrence intervals\n{mu0_line}\n"
            "[law]                    # a: given or assumed; b, lc: placeholders\n"
            f"name = \"slip\"\na = {a:.6g}                # {a_how}\nb = {b:.6g}\n"
            f"lc = {lc:.3g}\nv0 = 1e-5\n\n"
            f"[loading]\nvl = {vl.value:.6g}                # m/s, measured ± {vl.se:.2g}\n")

"""Checks shared by the problem and algorithm dataclasses: a bad parameter fails at construction,
by name, before any work.

A number must be a real number of a numeric type: a string such as ``"0.01"``, a bool, None or an
array is refused here rather than failing mid-solve.

Every dimensional input (and the dimensionless ones a percentage could be typed for) has a
plausible range in the unit it is documented in (:data:`PLAUSIBLE`): a value outside it is
accepted with a :class:`UnitWarning` that names the parameter, its value and the unit expected
("normal_force = 5 N is implausibly small: the unit is newtons (N), not MPa ..."). A value that
no material or apparatus can have (μ0 ≥ 10, a ≥ 1) is refused (:func:`check_possible`). The
ranges are wide — every laboratory apparatus and natural fault is inside them — so a warning
means a unit slip (µm for m, MPa for N, percent for a fraction), not an unusual experiment.

A warning is attributed to this module, not to the caller, so Python's default filter shows each
distinct message once however many problems repeat it (every ``dataclasses.replace`` of a
problem validates it again); :func:`units_checked_already` silences the warnings where a caller
has warned once already (a sweep's points).
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import numbers
import warnings
from dataclasses import dataclass

import numpy as np

__all__ = ["check_finite", "check_positive", "check_non_negative", "check_count", "check_flag",
           "UnitWarning",
           "warn_implausible", "units_checked_already", "PLAUSIBLE", "Plausible",
           "check_possible", "implausible_message", "warn_unit", "RegularCycleWarning"]

_UNITS_CHECKED = contextvars.ContextVar("rsfbench_units_checked", default=False)


class UnitWarning(UserWarning):
    """A parameter outside the range its documented unit makes plausible (probably a unit slip)."""


class RegularCycleWarning(UnitWarning):
    """A standard deviation of observed events far below its plausible mean: a very regular
    cycle, not a unit slip; what it implies for an inversion (a posterior as narrow). A kind of
    :class:`UnitWarning` so that it is silenced and collected where they are (a sweep's
    points warn once)."""


def _real(name: str, value) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number, got {value!r} "
                         f"({type(value).__name__})")
    try:
        return float(value)
    except OverflowError:                # an int beyond the doubles (10**400)
        raise ValueError(f"{name} must be finite, got an integer of "
                         f"{len(str(abs(int(value))))} digits") from None


def check_finite(name: str, value) -> float:
    """Return ``value`` as a float, or raise ``ValueError`` naming it if it is not a finite real
    number of a numeric type."""
    x = _real(name, value)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return x


def check_positive(name: str, value) -> float:
    """Finite and > 0."""
    x = check_finite(name, value)
    if x <= 0:
        raise ValueError(f"{name} must be positive, got {value!r}")
    return x


def check_non_negative(name: str, value) -> float:
    """Finite and >= 0."""
    x = check_finite(name, value)
    if x < 0:
        raise ValueError(f"{name} must be non-negative, got {value!r}")
    return x


def check_count(name: str, value, minimum: int = 1) -> int:
    """An integer (an int, or a float with an integer value) ≥ ``minimum``."""
    x = check_finite(name, value)
    if x != int(x) or x < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(x)


def check_flag(name: str, value) -> bool:
    """True or False (a Python or numpy bool); ValueError for anything else (1, "yes")."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {value!r}")
    return bool(value)


@dataclass(frozen=True)
class Plausible:
    """A plausible range [``low``, ``high``) of ``|value|`` in ``unit``, with what to say below
    (``small``) and above (``large``) it. ``zero_ok``: 0 is an allowed limit (b = 0, mass = 0,
    a hold), never implausible. ``impossible``: ``|value|`` at or above it no material or
    apparatus has, and it is refused (:func:`check_possible`), with ``why``."""

    low: float
    high: float
    unit: str
    small: str
    large: str
    zero_ok: bool = True
    impossible: float = math.inf
    why: str = ""


_SPEED = Plausible(
    1e-12, 10.0, "m/s",
    "the unit is metres per second (m/s): 10 µm/s is 1e-05",
    "the unit is metres per second (m/s), not µm/s or mm/s: 10 µm/s is 1e-05")
_TIME = Plausible(
    1e-7, 1e10, "s",
    "the unit is seconds (s): shorter than the inertial period of any apparatus (~1 µs)",
    "the unit is seconds (s), not ms: 1e10 s is 300 years")

#: the plausible range of each parameter, by the name a variant of a problem gives it
#: (:func:`problems.variant`; the ensemble's axes are checked against it too). The ranges, and
#: why nothing real falls outside them:
PLAUSIBLE: dict[str, Plausible] = {
    # Lc: from 0.1 nm (smooth glass, single asperities) to 1 cm (natural gouge layers); the
    # paper's fits are 0.1–0.9 µm, laboratory Dc 1–100 µm
    "lc": Plausible(1e-10, 1e-2, "m", "the unit is metres (m): 0.3 µm is 3e-07",
                    "the unit is metres (m), not µm: 0.3 µm is 3e-07"),
    # a, b: laboratory values 1e-4 to 0.05 (Marone 1998); a ≥ 1 would change μ by more than
    # μ itself over a tenfold speed step, which no material does
    "a": Plausible(1e-5, 0.2, "", "a is a fraction (0.008): below 1e-5 the direct effect "
                   "vanishes", "a is a fraction (0.008), not a percentage (0.8)",
                   impossible=1.0, why="a ≥ 1 would change μ by more than μ itself over a "
                   "tenfold speed step: a is a fraction (0.008), not a percentage"),
    "b": Plausible(1e-5, 0.2, "", "b is a fraction (0.0092): below 1e-5 the state effect "
                   "vanishes (b = 0 turns it off)",
                   "b is a fraction (0.0092), not a percentage (0.92)",
                   impossible=1.0, why="b ≥ 1 would change μ by more than μ itself over a "
                   "tenfold speed step: b is a fraction (0.0092), not a percentage"),
    # speeds: from 1e-12 m/s (below any plate rate, 3e-10 m/s = 1 cm/yr) to just below
    # 10 m/s (high-velocity rotary shear reaches ~9 m/s); the reference v0 likewise
    "v0": _SPEED, "vl": _SPEED, "vlf": _SPEED, "velocity": _SPEED,
    # the slow loading of stick–slip: a load point that creeps while the fault sticks, from
    # plate rates to 1 cm/s (the paper's 75 µm/s; a fast phase, vlf, may be faster); 0.075 is
    # mm/s typed as m/s
    "vls": Plausible(1e-12, 1e-2, "m/s", _SPEED.small,
                     "the slow loading speed is in metres per second (m/s), not mm/s: "
                     "75 µm/s is 7.5e-05"),
    "overshoot_velocity": _SPEED, "reference_velocity": _SPEED,
    # a slip rate (an initial state's): down to 1e-20 m/s (a healed, locked fault), up to
    # seismic slip rates below 10 m/s
    "slip_rate": Plausible(1e-20, 10.0, "m/s", _SPEED.small, _SPEED.large),
    # times (t_end, switch times, the overshoot's duration): from 0.1 µs (shorter than the
    # inertial period 2π√(m/k) of a gram on the stiffest frame, ~1 µs) to 1e10 s (a natural
    # fault's century-long cycle; no laboratory test lasts a year)
    "t_end": _TIME, "time": _TIME, "df": _TIME, "overshoot_duration": _TIME,
    # Fn: from 10 N (the gentlest rock-friction tests, 0.1 MPa on 1 cm²) to 1e8 N (10 MPa on
    # 10 m²); the paper's shaking table is 1.33 MPa on 0.75 m², ~1e6 N. Below 10 N is a
    # stress in MPa typed for the force (5 MPa as 5 N), the commoner slip; a tribometer's
    # 1 N contact (paper on paper) warns, and runs
    "normal_force": Plausible(
        10.0, 1e8, "N",
        "the unit is newtons (N), not MPa or kN: Fn = σn × area (1.33 MPa on 0.75 m² is "
        "997500 N)",
        "the unit is newtons (N): a stress in Pa is not a force (Fn = σn × area; 1e8 N is "
        "10 MPa on 10 m²)"),
    # mass: from a gram (a small slider block) to 1e5 kg (the largest shaking tables); the
    # paper's is 1100 kg; 0 is the quasi-static slider
    "mass": Plausible(1e-3, 1e5, "kg", "the unit is kilograms (kg): 1 g is 0.001 (0 for the "
                      "quasi-static slider)", "the unit is kilograms (kg), not grams"),
    # k: from 1e3 N/m (a soft spring on a small sample) to 1e11 N/m (stiffer than any
    # load frame); the paper's is 1.48e8 N/m, Marone's rsfmodel apparatus 1e7 N/m
    "stiffness": Plausible(
        1e3, 1e11, "N/m",
        "the unit is N/m, not MN/m nor a friction per µm (k' in 1/µm is k'·Fn·1e6 N/m)",
        "the unit is N/m (the paper's is 1.48e8 N/m): a stress per metre (Pa/m) times the "
        "area is N/m"),
    # ηr = G S/(2 cs): from 1e-4 N s/m (a 1 mm² contact) to 1e12 N s/m (a 100 m × 100 m
    # patch in stiff rock); the paper's fault gives 4.1e6 N s/m
    "radiation_damping": Plausible(
        1e-4, 1e12, "N s/m", "the unit is N s/m: ηr = G S/(2 cs) (4.1e6 for the paper's fault)",
        "the unit is N s/m: ηr = G S/(2 cs) (4.1e6 for the paper's fault), not per µm/s"),
    # rock density (the shear-wave speed of radiation damping): from 1000 kg/m³ (porous
    # sediment) to below 2e4 (denser than any rock); metagabbro is ~3000
    "density": Plausible(1e3, 2e4, "kg/m³", "the unit is kg/m³, not g/cm³: 3 g/cm³ is 3000",
                         "the unit is kg/m³: no rock is denser than 2e4 kg/m³"),
    # μ0: from 0.01 (lubricated contacts) to below 2 (clean metals); rock 0.1–0.85. A
    # friction coefficient of 10 no material has: refused
    "mu0": Plausible(
        0.01, 2.0, "", "μ0 = F0/Fn is a friction coefficient (0.6 for rock)",
        "μ0 = F0/Fn is a friction coefficient (0.6 for rock), not a percentage nor a force",
        zero_ok=False, impossible=10.0,
        why="no material has a friction coefficient of 10 or more: μ0 = F0/Fn is "
            "dimensionless (0.6 for rock), not a percentage nor a force"),
    # observations: a recurrence interval from 0.1 ms (kHz stick-slip of a small stiff
    # apparatus) to 1e10 s (a natural fault's centuries)
    "recurrence_s": Plausible(
        1e-4, 1e10, "s", "the recurrence interval is in seconds (s), not hours",
        "the recurrence interval is in seconds (s), not ms (W2's is 3.1 s)"),
    # Δμ: from 1e-5 (the smallest drop a load cell resolves) to below 1 (the whole friction of
    # rock); a drop of 10 no friction coefficient allows: refused
    "friction_drop": Plausible(
        1e-5, 1.0, "", "Δμ is a drop of the friction coefficient (0.046), not of a stress",
        "Δμ is a drop of the friction coefficient, a fraction (0.046), not a percentage (4.6)",
        zero_ok=False, impossible=10.0,
        why="no friction coefficient drops by 10 or more: Δμ is a fraction (0.046), not a "
            "percentage"),
}
# σ of ΔT: the recurrence's range (a σ far below its mean is judged against the mean instead:
# a regular cycle, benchmarks.inversion.observations)
PLAUSIBLE["sigma_recurrence_s"] = Plausible(
    1e-4, 1e10, "s", "σ of ΔT is in seconds (s), as ΔT is",
    "σ of ΔT is in seconds (s), as ΔT is, not ms")
PLAUSIBLE["sigma_friction_drop"] = Plausible(
    1e-6, 1.0, "", "σ of Δμ is dimensionless, as Δμ is",
    "σ of Δμ is dimensionless (0.0046), not a percentage", zero_ok=False)


@contextlib.contextmanager
def units_checked_already():
    """No :class:`UnitWarning` inside: the caller has warned once already (a sweep builds
    thousands of problems from one axis). A context variable, not a warnings filter: filters
    are global, and a sweep's worker threads would save and restore each other's."""
    token = _UNITS_CHECKED.set(True)
    try:
        yield
    finally:
        _UNITS_CHECKED.reset(token)


def implausible_message(name: str, value: float, kind: str | None = None) -> str | None:
    """What :func:`warn_implausible` would say about ``value`` of parameter ``name`` (ranges of
    :data:`PLAUSIBLE` [``kind``], by default [``name``]), or None if it is plausible."""
    p = PLAUSIBLE[kind or name]
    x = abs(float(value))
    if (x == 0 and p.zero_ok) or p.low <= x < p.high:
        return None
    unit = f" {p.unit}" if p.unit else ""
    side, hint = ("small", p.small) if x < p.low else ("large", p.large)
    return (f"{name} = {value:g}{unit} is implausibly {side} (plausible: {p.low:g} to below "
            f"{p.high:g}{unit}): {hint}")


def warn_implausible(name: str, value: float, stacklevel: int | None = None,
                     kind: str | None = None) -> None:
    """Warn (:class:`UnitWarning`) if ``value`` of parameter ``name`` is outside its plausible
    range (:data:`PLAUSIBLE` [``kind``], by default [``name``]); no warning inside
    :func:`units_checked_already`. ``stacklevel``: where Python attributes the warning; by
    default this module, so that the default filter shows each distinct message once."""
    text = implausible_message(name, value, kind)
    if text is not None:
        warn_unit(text, stacklevel=stacklevel + 1 if stacklevel else 2)


def warn_unit(text: str, stacklevel: int = 2, category: type = UnitWarning) -> None:
    """Warn ``text`` as a :class:`UnitWarning` (or ``category``, a kind of it), unless inside
    :func:`units_checked_already` (for checks that are not one parameter against its range: a
    ratio, a derived speed)."""
    if not _UNITS_CHECKED.get():
        warnings.warn(text, category, stacklevel=stacklevel)


def check_possible(name: str, value: float, kind: str | None = None) -> float:
    """``value``, or ``ValueError`` if no material or apparatus can have it (``|value|`` at or
    beyond :attr:`Plausible.impossible` of :data:`PLAUSIBLE` [``kind``, by default ``name``]);
    then :func:`warn_implausible`."""
    p = PLAUSIBLE[kind or name]
    if abs(value) >= p.impossible:
        raise ValueError(f"{name} = {value:g} is impossible: {p.why}")
    warn_implausible(name, value, kind=kind)
    return value

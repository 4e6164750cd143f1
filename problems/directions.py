"""How the nondimensional problem moves with one physical parameter: the direction a forward
sensitivity follows (:mod:`integrators.own.sensitivity`).

The ODE form (:mod:`problems.formulations`) sees a physical parameter θ only through the
problem vector q (β, C, D, E, G, γ), the time scale Lc/v0 (which turns the fixed times in
seconds — the end, a loading switch, the overshoot's duration — into τ), the loading rates and
the initial state. Each entry of q is a monomial in the physical parameters (with mass:
β = b/a, C = k Lc²/(m v0²), D = a Fn Lc/(m v0²), E = vL/v0, G = ηr Lc/(m v0),
γ = (c/b) k Lc/Fn), so its derivative is exact: ∂q/∂θ = q·(power of θ)/θ, or the coefficient
where θ = 0 (damping, c). The initial state is not a monomial (a :class:`BalancedStart` solves
for a force balance): its derivative is a central difference of that algebra, no solve, with a
relative step of 1e−4: truncation ~1e−8 of the derivative; rounding, where the state is a
small difference of large forces (h0 = (Fs − F0)/(k Lc)), ~1e−16 of Fs over the force's change
across the step, 1e−8 for the paper's damping. The difference runs the start's algebra alone,
on the problem's parts remade without their checks (:func:`_start`), not on checked variants
of the whole problem (four a parameter, each checked in full).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from problems._validate import check_flag
from problems.formulations import N_Q, Q_BETA, Q_C, Q_D, Q_E, Q_G, Q_LAWP, to_ode_state
from problems.friction import compiled_law_code
from problems.loading import ConstantLoading, TwoSpeedLoading
from problems.slider import InitialState, SpringSlider, start_vector, variant, variant_fields

__all__ = ["Direction", "direction", "SENSITIVE", "ALIASES", "sensitivity_names",
           "SENSITIVITY_RTOL", "value_of", "fields_of", "sensitive_request", "warn_loose"]

#: the parameters a solve can be differentiated by (:func:`problems.slider.variant`'s names)
SENSITIVE = ("a", "b", "lc", "c", "stiffness", "mass", "normal_force", "radiation_damping",
             "vl", "vls", "vlf", "df", "slowdown", "initial_v", "initial_theta", "initial_fs")
#: short names users type for some of them
ALIASES = {"k": "stiffness", "m": "mass", "fn": "normal_force", "damping": "radiation_damping",
           "dc": "lc"}
#: the loosest rtol at which the gradients of ΔT and Δμ are within ~1e−4 of the exact
#: problem's (their error in the step control; results/gradients.md): looser, a solve with
#: sensitivities warns, and the commands that pick a tolerance themselves do not go looser
SENSITIVITY_RTOL = 1e-6
#: the relative step of the initial state's central difference (module docstring)
X0_STEP = 1e-4


@dataclass(frozen=True)
class Direction:
    """The derivative of what the ODE form sees along one parameter θ (per unit of θ).

    Parameters
    ----------
    name : str
        θ's name (:data:`SENSITIVE`).
    dq : numpy.ndarray
        ∂q/∂θ (layout of :mod:`problems.formulations`; its E entry is the slow rate's).
    de_fast : float
        ∂E_fast/∂θ of a two-speed loading's overshoot.
    dtau_fast : float
        ∂τ_fast/∂θ, the overshoot's duration in τ.
    dln_ts : float
        ∂ ln(Lc/v0)/∂θ: a time fixed in seconds moves in τ by −τ times it.
    dz0 : numpy.ndarray
        ∂z0/∂θ, the initial ODE state (h, u, s).
    d_force_h : float
        ∂(k Lc)/∂θ, newtons per unit of h.
    d_fn : float
        ∂Fn/∂θ.
    d_b : float
        ∂b/∂θ (the slip law's θ = Ψ b Fn).
    scale : float
        |θ| (1 where θ = 0): the size the sensitivities' error test weighs ∂z/∂θ by.
    """

    name: str
    dq: np.ndarray
    de_fast: float
    dtau_fast: float
    dln_ts: float
    dz0: np.ndarray
    d_force_h: float
    d_fn: float
    d_b: float
    scale: float = 1.0


def sensitive_request(algorithm, names, control) -> bool:
    """The error-control flag ``control`` (``sensitivity_error``) as a bool, checked; with
    ``names`` (not None), ValueError for an ``algorithm`` without forward sensitivities: the
    first checks of a request, before its names (:func:`sensitivity_names`)."""
    control = check_flag("sensitivity_error", control)
    if names is not None and not getattr(algorithm, "sensitive", False):
        raise ValueError(f"sensitivity: {algorithm.name} has no forward sensitivities; "
                         "Rodas5P and RadauIIA5 have")
    return control


def warn_loose(algorithm, above: int) -> None:
    """The warning for sensitivities at an rtol above :data:`SENSITIVITY_RTOL`, pointing
    ``above`` frames above the caller (1: the caller's caller)."""
    if algorithm.rtol > SENSITIVITY_RTOL:
        warnings.warn(f"sensitivity at rtol {algorithm.rtol:g}: gradients of event times can "
                      f"be far off, even in sign, above {SENSITIVITY_RTOL:g}",
                      stacklevel=above + 2)


def sensitivity_names(problem: SpringSlider, names) -> tuple[str, ...]:
    """``names`` (a string "b,lc", a sequence or a 1-d array of strings) as :data:`SENSITIVE`
    names, aliases resolved; ValueError naming one the problem does not have, a repeat, or a
    solve without mass."""
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    elif isinstance(names, np.ndarray) and names.ndim == 1:
        names = names.tolist()              # str items stay str (bytes, numbers are refused)
    if not (isinstance(names, (tuple, list)) and all(isinstance(n, str) for n in names)):
        raise ValueError(f"sensitivity: parameter names as a string 'b,lc', a sequence or a "
                         f"1-d array of strings, got {names!r}")
    names = tuple(ALIASES.get(n.strip().lower(), n.strip().lower()) for n in names)
    if not names:
        raise ValueError("sensitivity: name at least one parameter, e.g. ('b', 'lc')")
    if problem.mass <= 0.0:
        raise ValueError("sensitivity: the quasi-static limit (mass = 0 kg) has no forward "
                         "sensitivities yet; give the slider a mass")
    fields = fields_of(problem)
    for name in names:
        if name not in fields:
            raise ValueError(f"sensitivity: {problem.name!r} has no parameter {name!r}; it has "
                             f"{', '.join(fields)} (aliases: "
                             f"{', '.join(f'{k}={v}' for k, v in ALIASES.items())})")
    if len(set(names)) < len(names):
        raise ValueError(f"sensitivity: a parameter named twice in {names}")
    return names


def fields_of(problem: SpringSlider) -> tuple[str, ...]:
    """The :data:`SENSITIVE` names ``problem`` has."""
    have = set(variant_fields(problem))
    if not isinstance(problem.loading, (ConstantLoading, TwoSpeedLoading)):
        have -= {"vl", "vls", "vlf", "df"}
    elif not problem.nondimensional().two_speed:
        have -= {"vlf", "df"}               # no overshoot runs (df = 0)
    return tuple(n for n in SENSITIVE if n in have)


def value_of(problem: SpringSlider, name: str) -> float:
    """The value of ``problem``'s parameter ``name`` (a :data:`SENSITIVE` name), SI."""
    for obj in (problem.law, problem, problem.loading, problem.initial):
        if hasattr(obj, name):
            return float(getattr(obj, name))
    return float(getattr(problem.initial, name.removeprefix("initial_")))


#: the problem's own fields the start depends on (mass and t_end it does not)
_START_FIELDS = ("normal_force", "stiffness", "mu0", "radiation_damping")


def _has_field(obj, name: str) -> bool:
    return any(f.name == name for f in dataclasses.fields(obj))


def _unchecked(obj, name: str, value: float):
    """The frozen dataclass ``obj`` with its field ``name`` at ``value``, made without its
    ``__post_init__`` (its checks): for a step of :data:`X0_STEP` off a checked problem."""
    new = object.__new__(type(obj))
    for f in dataclasses.fields(obj):
        object.__setattr__(new, f.name, value if f.name == name else getattr(obj, f.name))
    return new


def _refused(problem: SpringSlider, name: str, value: float) -> bool:
    """Whether a checked :func:`~problems.slider.variant` refuses ``name`` at ``value``: asked
    only where a step crosses zero (a damping of 0 cannot go below; a slip law's b of 0 can,
    and its one-sided difference would be wrong: Ψ is 0 at b = 0 alone)."""
    try:                    # (no warnings filter here: fits run this in threads)
        variant(problem, **{name: value})
    except ValueError:
        return True
    return False


def _start(problem: SpringSlider, name: str, value: float) -> np.ndarray:
    """The initial ODE state z0 of ``problem`` with its field ``name`` (a
    :func:`~problems.slider.variant` name) at ``value``: the start's algebra alone
    (:meth:`~problems.slider.BalancedStart.resolve`, :func:`~problems.slider.start_vector`) on
    the parts remade unchecked. ``problem``'s own z0 where ``value`` is its own."""
    law, loading, initial = problem.law, problem.loading, problem.initial
    top = {f: getattr(problem, f) for f in _START_FIELDS}
    if name in top:
        top[name] = value
    elif _has_field(law, name):
        law = _unchecked(law, name, value)
    elif _has_field(loading, name):
        loading = _unchecked(loading, name, value)
    elif _has_field(initial, name.removeprefix("initial_")):
        initial = _unchecked(initial, name.removeprefix("initial_"), value)
    else:
        raise ValueError(f"the initial state has no parameter {name!r}")
    fn, mu0 = top["normal_force"], top["mu0"]
    ini = (initial if isinstance(initial, InitialState)
           else initial.resolve(law, fn, mu0, loading, top["radiation_damping"]))
    x0 = start_vector(law, fn, top["stiffness"], mu0, ini)
    return to_ode_state(compiled_law_code(law), law.b / law.a, x0)


def _natural_scale(problem: SpringSlider, name: str) -> float:
    """The size of θ at which it matters: for the damping the larger of m v0/Lc (G = 1) and
    Fs/v at the start (where ηr v is as large as the spring force: a step of m v0/Lc can move
    Fs by less than its rounding, as on a laboratory apparatus; the start is linear in ηr, so
    a long step costs nothing), 1 for c, else 0."""
    if name == "radiation_damping":
        ini = problem.initial_state
        return max(problem.mass * problem.law.v0 / problem.law.lc, abs(ini.fs) / ini.v)
    return 1.0 if name == "c" else 0.0


def _dz0(problem: SpringSlider, name: str, value: float) -> np.ndarray:
    """∂z0/∂θ by a central difference of the initial state's algebra (a forward three-point
    one where θ − δ is refused, as a damping below 0), of step X0_STEP times the larger of |θ|
    and θ's natural scale (a damping of 0 or 1 N s/m moves the forces by nothing a relative
    step sees)."""
    if name == "mass":                  # the start does not depend on it (_START_FIELDS)
        return np.zeros(3)
    step = X0_STEP * (max(abs(value), _natural_scale(problem, name)) or 1.0)
    up = _start(problem, name, value + step)
    if value - step < 0.0 <= value and _refused(problem, name, value - step):
        up2 = _start(problem, name, value + 2.0 * step)
        nd = problem.nondimensional()       # the base, made once per problem already
        base = to_ode_state(nd.law_code, nd.beta, nd.x0)
        return (-3.0 * base + 4.0 * up - up2) / (2.0 * step)
    return (up - _start(problem, name, value - step)) / (2.0 * step)


def direction(problem: SpringSlider, name: str) -> Direction:
    """The :class:`Direction` of ``problem`` along the parameter ``name`` (one of
    :func:`sensitivity_names`'s, which checks that ``problem`` has it); ValueError for a name
    not in :data:`SENSITIVE`."""
    if name not in SENSITIVE:
        raise ValueError(f"sensitivity: {name!r} is not a parameter a solve can be "
                         f"differentiated by; they are {', '.join(SENSITIVE)}")
    nd = problem.nondimensional()
    law, m, k, fn = problem.law, problem.mass, problem.stiffness, problem.normal_force
    lc, v0, a = law.lc, law.v0, law.a
    dq = np.zeros(N_Q)
    de_fast = dtau_fast = dln_ts = d_force_h = d_fn = d_b = 0.0
    beta, c, d, g, gam = nd.beta, nd.c, nd.d, nd.g, nd.law_param
    if name == "a":
        dq[Q_BETA], dq[Q_D] = -beta / a, d / a
    elif name == "b":
        dq[Q_BETA], d_b = 1.0 / a, 1.0
        dq[Q_LAWP] = -gam / law.b if law.b != 0.0 else 0.0
    elif name == "lc":
        dq[Q_C], dq[Q_D], dq[Q_G], dq[Q_LAWP] = 2 * c / lc, d / lc, g / lc, gam / lc
        dln_ts, dtau_fast, d_force_h = 1.0 / lc, -nd.tau_fast / lc, k
    elif name == "c":
        dq[Q_LAWP] = k * lc / (law.b * fn)
    elif name == "stiffness":
        dq[Q_C], dq[Q_LAWP], d_force_h = c / k, gam / k, lc
    elif name == "mass":
        dq[Q_C], dq[Q_D], dq[Q_G] = -c / m, -d / m, -g / m
    elif name == "normal_force":
        dq[Q_D], dq[Q_LAWP], d_fn = d / fn, -gam / fn, 1.0
    elif name == "radiation_damping":
        dq[Q_G] = lc / (m * v0)
    elif name in ("vl", "vls"):
        dq[Q_E] = 1.0 / v0
    elif name == "vlf":
        de_fast = 1.0 / v0
    elif name == "df":
        dtau_fast = v0 / lc
    value = value_of(problem, name)
    try:
        dz0 = _dz0(problem, name, value)
    except ValueError as exc:           # a start that cannot move (a slip law's θ at b = 0)
        raise ValueError(f"sensitivity: {problem.name!r} cannot be differentiated along "
                         f"{name!r}: {exc}") from None
    return Direction(name=name, dq=dq, de_fast=de_fast, dtau_fast=dtau_fast, dln_ts=dln_ts,
                     dz0=dz0, d_force_h=d_force_h, d_fn=d_fn, d_b=d_b,
                     scale=abs(value) if value != 0.0 else 1.0)

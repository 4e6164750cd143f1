"""The one-degree-of-freedom spring-slider with mass under rate-and-state friction (SPEC §1–2).

    m dv/dt  = Fs − Ft(v, θ) − ηr v          dFs/dt = k (vL(t) − v)          dθ/dt = law

and its two limits, each an option of the same problem: the quasi-static slider (``mass = 0``:
the force balance Fs = Ft + ηr v is algebraic, as in rsfmodel) and radiation damping
(``radiation_damping`` ηr > 0, N s/m, with or without mass: without mass it is the
quasi-dynamic slider of QDYN). The load-point velocity vL(t) is a piecewise-constant history
(:mod:`problems.loading`).

A :class:`SpringSlider` is data: parameters, loading, initial state and end time, validated at
construction. Variants are made with :func:`dataclasses.replace` or :meth:`SpringSlider.with_law`.

The initial state is either an :class:`InitialState` in physical units, kept as it is by every
variant, or the rule :class:`BalancedStart` (what every preset uses), resolved against the
problem's own law and loading: so ``window("W2", b=b, lc=lc)`` and
``window("W2").with_law(b=b, lc=lc)`` are the same problem.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import NamedTuple, Union

import numpy as np

from problems._validate import (PLAUSIBLE, check_finite, check_non_negative, check_positive,
                                check_possible, units_checked_already, warn_implausible,
                                warn_unit)
from problems.formulations import form_vector, ode_rhs, psi_rate, s_of_psi, to_ode_state
from problems.friction import AgingLaw, FrictionLaw, compiled_law_code
from problems.loading import LOADINGS, ConstantLoading, LoadHistory, TwoSpeedLoading, history_vector

__all__ = ["InitialState", "BalancedStart", "SpringSlider", "Nondimensional", "variant",
           "variant_fields",
           "steady_initial_state", "balanced_initial_state", "TAU_END_MAX"]

Loading = Union[ConstantLoading, TwoSpeedLoading, LoadHistory]
#: the longest run in units of τ = v0 t/Lc: at τ the spacing of doubles is 2.2e−16 τ, and the
#: stick phase needs steps of ~1e−3 in τ (a day of W1–W4 at Lc = 0.1 nm is ~1e9)
TAU_END_MAX = 1e12


@dataclass(frozen=True)
class InitialState:
    """Initial slip rate ``v`` (m/s), state ``theta`` (the law's units) and spring force ``fs`` (N).

    Parameters
    ----------
    v : float
        The slip rate (m/s, positive).
    theta : float
        The state, in the law's unit (N for the slip law, s for the aging and Nagata laws).
    fs : float
        The spring force (N).

    Raises
    ------
    ValueError
        For a slip rate that is not positive, or a state or force that is not finite.
    """

    v: float
    theta: float
    fs: float

    def __post_init__(self) -> None:
        check_finite("initial theta", self.theta)
        check_finite("initial fs", self.fs)
        warn_implausible("initial v", check_positive("initial slip rate v", self.v),
                         kind="slip_rate")


def steady_initial_state(law: FrictionLaw, fn: float, mu0: float, v_ss: float,
                         v: float | None = None) -> InitialState:
    """Steady sliding at ``v_ss`` (state and spring force at their steady values), optionally
    started at another slip rate ``v`` to perturb it.

    Parameters
    ----------
    law : FrictionLaw
        The friction law.
    fn : float
        The normal force (N).
    mu0 : float
        The reference friction coefficient F0/Fn (dimensionless).
    v_ss : float
        The steady sliding speed the state and spring force belong to (m/s).
    v : float, optional
        The initial slip rate (m/s); ``None`` takes ``v_ss``.

    Returns
    -------
    InitialState

    Raises
    ------
    ValueError
        For a slip rate that is not positive.
    """
    f0 = mu0 * fn
    return InitialState(v=v_ss if v is None else v, theta=law.steady_state(v_ss, fn),
                        fs=float(law.steady_friction(v_ss, fn, f0)))


def balanced_initial_state(law: FrictionLaw, fn: float, mu0: float, v: float,
                           theta: float, damping: float = 0.0) -> InitialState:
    """Slip rate ``v`` and state ``theta`` with the spring force balancing friction and
    radiation damping ``damping`` (Fs = Ft + ηr v, so dv/dt = 0): a start on the slow manifold,
    with no fast initial layer (and the only consistent start without mass).

    Parameters
    ----------
    law : FrictionLaw
        The friction law.
    fn : float
        The normal force (N).
    mu0 : float
        The reference friction coefficient F0/Fn (dimensionless).
    v : float
        The slip rate (m/s).
    theta : float
        The state, in the law's unit (N for the slip law, s for the aging and Nagata laws).
    damping : float
        The radiation damping ηr (N s/m).

    Returns
    -------
    InitialState

    Raises
    ------
    ValueError
        For a slip rate that is not positive.
    """
    return InitialState(v=v, theta=theta,
                        fs=float(law.friction(v, theta, fn, mu0 * fn)) + damping * v)


@dataclass(frozen=True)
class BalancedStart:
    """The start rule of the presets: sliding at the slow loading speed, with the state of steady
    sliding at a speed ``slowdown`` times slower (a slightly healed fault) and the spring force
    equal to friction (:func:`balanced_initial_state`: on the slow manifold, no fast inertial
    layer at the start).

    A rule, not values: it is resolved against the problem's own law, normal force, μ0 and
    loading, so a variant with other friction parameters starts from the same rule.

    Parameters
    ----------
    slowdown : float
        The state is steady sliding's at the initial slip rate divided by this (dimensionless,
        positive; default 1.1).

    Raises
    ------
    ValueError
        For a slowdown that is not positive.
    """

    slowdown: float = 1.1

    def __post_init__(self) -> None:
        check_positive("slowdown", self.slowdown)

    def resolve(self, law: FrictionLaw, fn: float, mu0: float, loading,
                damping: float = 0.0) -> InitialState:
        v = _initial_velocity(loading)
        with units_checked_already():       # v is the loading's, which warned for it already
            return balanced_initial_state(law, fn, mu0, v,
                                          law.steady_state(v / self.slowdown, fn), damping)


def _warn_implausible_start(law: FrictionLaw, fn: float, ini: InitialState) -> None:
    """Warn if an explicit initial state is implausible in its units: θ the state of steady
    sliding at a slip rate outside the plausible range (θ = Lc/v in s for the aging and Nagata
    laws, −b Fn ln(v/v0) in N for the slip law), or a spring force outside 0.001 to 10 times
    the normal force (a friction coefficient typed for a force, or a force in kN)."""
    p = PLAUSIBLE["slip_rate"]
    if isinstance(law, AgingLaw):
        ln_v, form, unit = math.log(law.lc / ini.theta), "Lc/θ", "s (Lc/v at steady sliding)"
    elif law.b != 0:
        ln_v = math.log(law.v0) - ini.theta / (law.b * fn)
        form, unit = "v0 exp(−θ/(b Fn))", "N (−b Fn ln(v/v0) at steady sliding)"
    else:
        ln_v = math.log(p.low)                        # b = 0: θ = 0, checked by the law
    if not math.log(p.low) <= ln_v < math.log(p.high):
        v = f"{math.exp(ln_v):.3g}" if abs(ln_v) < 700 else f"exp({ln_v:.4g})"
        warn_unit(f"initial theta = {ini.theta:g} is the {law.name} law's state of steady "
                  f"sliding at {form} = {v} m/s, implausible (plausible: {p.low:g} to below "
                  f"{p.high:g} m/s): θ is in {unit}", stacklevel=1)
    ratio = abs(ini.fs) / fn
    if ini.fs != 0 and not 1e-3 <= ratio < 10.0:
        warn_unit(f"initial fs = {ini.fs:g} N is {ratio:.3g} × normal_force = {fn:g} N, "
                  f"implausible (plausible: 0.001 to below 10 times it): fs is the spring "
                  f"force in newtons (μ Fn: 0.6 × {fn:g} N is {0.6 * fn:g} N), not a friction "
                  "coefficient", stacklevel=1)


def _initial_velocity(loading) -> float:
    """The slip rate a balanced start slides at: the load point's first velocity, or the
    reference velocity if the history opens with a hold."""
    first = loading.history.velocities[0]
    return first if first > 0 else loading.v_slow


class Nondimensional(NamedTuple):
    """The nondimensional problem of SPEC §2: w = v/v0, τ = v0 t/Lc, h, η, Ψ.

    ``x0`` is the initial (h, η, Ψ); ``e_slow`` is vL/v0 of the events' reference velocity,
    ``e_fast`` and ``tau_fast`` the overshoot's rate and duration (τ), ``tau_end`` the end of the
    run. ``c``, ``d``, ``g`` are C, D, G with mass and K, 0, R without (``quasi_static``;
    :mod:`problems.formulations`); ``law_param`` is the law's γ; ``history`` the loading's
    compiled form (:func:`problems.loading.history_vector`); ``grid_tau`` a time over which the
    slow phase changes by O(1) (half an inertial period π/√C with mass; without, the shortest of
    the time to load one Lc at the fastest load-point speed, the relaxation time 1/(K E) there
    and R/K), which backends without dense root finding use to space their scans.

    Parameters
    ----------
    law_code : int
        The law's code (0 slip, 1 aging, 2 Nagata).
    beta : float
        β = b/a (dimensionless).
    c, d, g : float
        The coefficients C, D, G with mass, K, 0, R without (dimensionless).
    e_slow, e_fast : float
        vL/v0 of the reference velocity and of the overshoot (dimensionless).
    tau_fast, tau_end : float
        The overshoot's duration and the end of the run, in τ = v0 t/Lc.
    x0 : numpy.ndarray
        The initial (h, η, Ψ), read-only.
    time_scale : float
        Seconds per unit of τ: Lc/v0 (s).
    force_h : float
        Newtons per unit of h: k Lc (N).
    force_eta : float
        Newtons per unit of η: A = a Fn (N).
    quasi_static : bool
        No mass: the force balance is algebraic.
    law_param : float
        The law's own parameter γ (dimensionless; 0 for the slip and aging laws).
    history : numpy.ndarray, optional
        The loading's compiled form.
    grid_tau : float
        The time over which the slow phase changes by O(1), in τ.
    """

    law_code: int
    beta: float
    c: float
    d: float
    e_slow: float
    e_fast: float
    tau_fast: float
    tau_end: float
    x0: np.ndarray
    time_scale: float     # seconds per unit of τ: Lc/v0
    force_h: float        # newtons per unit of h: k Lc
    force_eta: float      # newtons per unit of η: A = a Fn
    g: float = 0.0
    quasi_static: bool = False
    law_param: float = 0.0
    history: np.ndarray | None = None
    grid_tau: float = 1.0

    @property
    def two_speed(self) -> bool:
        """Events switch the loading to the overshoot."""
        return self.tau_fast > 0.0

    def q(self, e: float) -> np.ndarray:
        """The problem vector of :mod:`problems.formulations` under loading rate ``e``."""
        return form_vector(self, e)


@dataclass(frozen=True)
class SpringSlider:
    """Spring-slider with mass: ``mass`` (kg; 0 for the quasi-static limit), ``stiffness`` k
    (N/m), ``normal_force`` Fn (N), a friction ``law``, a ``loading`` protocol, an ``initial``
    state, the end time ``t_end`` (s) and ``radiation_damping`` ηr (N s/m, default 0).

    ``initial`` is an :class:`InitialState` (physical units, kept by every variant) or a rule,
    :class:`BalancedStart`, resolved against this problem's law and loading
    (:attr:`initial_state`). ``mu0`` = F0/Fn is the reference friction coefficient at v0; it only
    shifts the friction level (Urata et al. 2017, Sect. 4.1).

    Parameters
    ----------
    mass : float
        The slider's mass (kg, ≥ 0; 0 is the quasi-static limit).
    stiffness : float
        The spring's stiffness k (N/m, positive).
    normal_force : float
        The normal force Fn (N, positive).
    law : FrictionLaw
        :class:`SlipLaw`, :class:`AgingLaw` or :class:`NagataLaw`.
    loading : ConstantLoading, TwoSpeedLoading or LoadHistory
        The load point's velocity protocol.
    initial : InitialState or BalancedStart
        The initial state, or the rule that gives it.
    t_end : float
        The end of the run (s, positive; every switch of the loading before it).
    mu0 : float
        The reference friction coefficient F0/Fn at v0 (dimensionless, ≥ 0).
    name : str
        A label for tables and plots.
    radiation_damping : float
        ηr (N s/m, ≥ 0).

    Raises
    ------
    ValueError
        At construction, naming the field: a value out of its range, a law or loading of
        another class, an initial state that is not positive for an aging-type law, or without
        mass one whose spring force does not balance friction, a switch at or after ``t_end``,
        or a ``t_end`` too long for double precision in τ.
    """

    mass: float
    stiffness: float
    normal_force: float
    law: FrictionLaw
    loading: Loading
    initial: InitialState | BalancedStart
    t_end: float
    mu0: float = 0.6
    name: str = ""
    radiation_damping: float = 0.0

    def __post_init__(self) -> None:
        # refused if impossible, warned if implausible in its unit (problems._validate)
        for name, check in (("mass", check_non_negative), ("radiation_damping", check_non_negative),
                            ("stiffness", check_positive), ("normal_force", check_positive),
                            ("t_end", check_positive), ("mu0", check_non_negative)):
            check_possible(name, check(name, getattr(self, name)))
        if not isinstance(self.name, str):
            raise ValueError(f"name must be a string, got {self.name!r}")
        if not isinstance(self.law, FrictionLaw):
            raise ValueError(f"law must be a FrictionLaw (SlipLaw, AgingLaw, NagataLaw), got "
                             f"{self.law!r}")
        compiled_law_code(self.law)      # a law class the compiled forms do not know
        _check_forces(self.law, self.normal_force)
        if type(self.loading) not in LOADINGS:
            raise ValueError(f"loading must be ConstantLoading, TwoSpeedLoading or LoadHistory "
                             f"(the ones the integrators know; a subclass is refused), got "
                             f"{self.loading!r}")
        if not isinstance(self.initial, (InitialState, BalancedStart)):
            raise ValueError(f"initial must be an InitialState or a BalancedStart, got {self.initial!r}")
        ini = self.initial_state
        if isinstance(self.law, AgingLaw) and ini.theta <= 0:
            raise ValueError(f"initial theta must be positive for the {self.law.name} law, got "
                             f"{ini.theta!r}")
        self.law.psi(ini.theta, self.normal_force)     # the slip law with b = 0 needs θ = 0
        if isinstance(self.initial, InitialState):
            _warn_implausible_start(self.law, self.normal_force, ini)
        if self.mass == 0:
            balance = float(self.friction(ini.v, ini.theta)) + self.radiation_damping * ini.v
            # rounding of Fs only: a larger offset would be kept by the ODE form (K h − η is
            # its invariant) and projected away by IDA, two different problems
            if abs(ini.fs - balance) > 1e-12 * (abs(balance) + self.law.a * self.normal_force):
                raise ValueError(
                    f"initial fs = {ini.fs!r} N does not balance friction and damping "
                    f"(Ft + ηr v = {balance!r} N): without mass (quasi-static) the force balance "
                    "is a constraint; start from problems.balanced_initial_state or BalancedStart")
        late = [t for t in self.loading.history.switch_times if t >= self.t_end]
        if late:
            raise ValueError(f"the loading switches at t = {late[0]:g} s, at or after t_end = "
                             f"{self.t_end:g} s: shorten the history or lengthen t_end")
        tau_end = self.t_end * self.law.v0 / self.law.lc
        if tau_end > TAU_END_MAX:
            raise ValueError(f"t_end = {self.t_end:g} s is {tau_end:.3g} in τ = v0 t/Lc (Lc = "
                             f"{self.law.lc:g} m), beyond {TAU_END_MAX:g}: there double precision "
                             "cannot resolve the steps a run needs (t + h == t); shorten t_end")

    @functools.cached_property
    def initial_state(self) -> InitialState:
        """The initial (v, θ, Fs) in physical units: ``initial`` itself, or its rule resolved."""
        if isinstance(self.initial, InitialState):
            return self.initial
        return self.initial.resolve(self.law, self.normal_force, self.mu0, self.loading,
                                    self.radiation_damping)

    # --- derived quantities ---------------------------------------------------------------
    @property
    def f0(self) -> float:
        """Reference friction F0 = μ0 Fn (N)."""
        return self.mu0 * self.normal_force

    @property
    def kappa(self) -> float:
        """Normalized stiffness κ = k/kc with kc = Fn (b − a)/Lc (the paper's Table 3); negative
        for velocity strengthening (b < a), infinite at b = a (kc = 0)."""
        law = self.law
        kc = self.normal_force * (law.b - law.a) / law.lc
        return self.stiffness / kc if kc != 0.0 else math.inf

    def with_law(self, **changes) -> "SpringSlider":
        """A copy with friction-law parameters replaced, e.g. ``p.with_law(b=0.0094, lc=3e-7)``.

        A :class:`BalancedStart` rule is resolved again against the new law (so a preset's variant
        is the preset built with those parameters); an :class:`InitialState` is kept in physical
        units.
        """
        return dataclasses.replace(self, law=dataclasses.replace(self.law, **changes))

    # --- the dimensional system (SPEC §1) -------------------------------------------------
    def friction(self, v, theta):
        """Friction force Ft (N)."""
        return self.law.friction(v, theta, self.normal_force, self.f0)

    @property
    def steady_velocity(self) -> float:
        """The load point's speed at the end of the run (m/s): the history's last piece, or
        the reference speed if the history ends with a hold. Steady sliding, the stability of
        steady sliding and a run's end state are taken at it."""
        last = self.loading.history.velocities[-1]
        return last if last > 0 else self.loading.v_slow

    @property
    def quasi_static(self) -> bool:
        """No mass: the force balance is algebraic."""
        return self.mass == 0

    def rhs(self, t: float, y, vl: float | None = None) -> np.ndarray:
        """d/dt of y = (v, Fs, θ), with load-point velocity ``vl`` (default: the slow speed).
        Without mass, dv/dt is the derivative of the force balance Fs = Ft + ηr v."""
        v, fs, theta = y
        vl = self.loading.v_slow if vl is None else vl
        dfs = self.stiffness * (vl - v)
        dtheta = self.law.state_rate(v, theta, self.normal_force, dfs)
        if self.quasi_static:
            # dFs/dt = (A/v + ηr) dv/dt + ∂Ft/∂θ dθ/dt
            dft_dtheta = self.law.state_term_derivative(theta, self.normal_force)
            dv = (dfs - dft_dtheta * dtheta) / (self.law.a * self.normal_force / v
                                                 + self.radiation_damping)
        else:
            dv = (fs - self.friction(v, theta) - self.radiation_damping * v) / self.mass
        return np.array([dv, dfs, dtheta])

    # --- the nondimensional system (SPEC §2) ----------------------------------------------
    def nondimensional(self) -> Nondimensional:
        """Nondimensional parameters and initial state of SPEC §2 (computed once per problem;
        ``x0`` is read-only)."""
        return self._nondimensional

    @functools.cached_property
    def _nondimensional(self) -> Nondimensional:
        law, fn = self.law, self.normal_force
        A = law.a * fn
        m, k, lc, v0, eta_r = self.mass, self.stiffness, law.lc, law.v0, self.radiation_damping
        ts = lc / v0
        x0 = start_vector(law, fn, k, self.mu0, self.initial_state)
        x0.flags.writeable = False
        hist = history_vector(self.loading, v0, ts)
        hist.flags.writeable = False
        if m > 0:
            c, d, g = k * lc * lc / (m * v0 * v0), A * lc / (m * v0 * v0), eta_r * lc / (m * v0)
            grid_tau = math.pi / math.sqrt(c)
        else:
            c, d, g = k * lc / A, 0.0, eta_r * v0 / A
            # the time to load one Lc at the fastest speed, the relaxation time A/(k V) there,
            # and with damping R/K, the shortest an event can last (v ≲ Δη/R)
            e_max = max(self.loading.history.velocities + (self.loading.v_fast,)) / v0
            grid_tau = min(1.0 / e_max, 1.0 / (c * e_max), g / c if g > 0 else math.inf)
        law_param = law.stress_coefficient / law.b * k * lc / fn if law.stress_coefficient else 0.0
        loading = self.loading.history
        return Nondimensional(
            law_code=compiled_law_code(law), beta=law.b / law.a, c=c, d=d,
            e_slow=self.loading.v_slow / v0, e_fast=loading.v_fast / v0,
            tau_fast=loading.fast_duration / ts, tau_end=self.t_end / ts,
            x0=x0, time_scale=ts, force_h=k * lc, force_eta=A, g=g, quasi_static=m == 0,
            law_param=law_param, history=hist, grid_tau=grid_tau)

    def rhs_nondimensional(self, tau: float, x, e: float | None = None) -> np.ndarray:
        """d/dτ of x = (h, η, Ψ) (Eqs. 25–27 slip law, 25, 60, 61 aging law), at E = ``e``."""
        nd = self.nondimensional()
        e = nd.e_slow if e is None else e
        code, beta = nd.law_code, nd.beta
        z = to_ode_state(code, beta, x)
        f = np.empty(3)
        ode_rhs(form_vector(nd, e), z, f)
        return np.array([f[0], f[1] + beta * f[2], psi_rate(code, x[2], f[2])])

    def slip_rate_from_nondimensional(self, eta, psi):
        """w → v: the friction-law constraint w = exp(η − βΨ) or exp(η − β ln Ψ), in m/s."""
        beta = self.law.b / self.law.a
        return self.law.v0 * np.exp(eta - beta * s_of_psi(compiled_law_code(self.law), psi))

    def dimensional_state(self, h, eta, psi):
        """(v, Fs, θ) in SI units from the nondimensional (h, η, Ψ)."""
        k, lc = self.stiffness, self.law.lc
        return (self.slip_rate_from_nondimensional(eta, psi), self.f0 + k * lc * np.asarray(h),
                self.law.theta(np.asarray(psi), self.normal_force))


def start_vector(law: FrictionLaw, fn: float, stiffness: float, mu0: float,
                 ini: InitialState) -> np.ndarray:
    """SPEC §2's initial (h, η, Ψ) of the start ``ini``: ((Fs − F0)/(k Lc), (Ft − F0)/A, Ψ(θ)),
    F0 = μ0 Fn, A = a Fn (:meth:`SpringSlider.nondimensional`'s ``x0``)."""
    f0 = mu0 * fn
    return np.array([(ini.fs - f0) / (stiffness * law.lc),
                     (law.friction(ini.v, ini.theta, fn, f0) - f0) / (law.a * fn),
                     law.psi(ini.theta, fn)], dtype=float)


def _check_forces(law, fn: float) -> None:
    """ValueError when A = a·Fn or B = b·Fn (N; B only where b > 0) is not a positive finite
    double: every form divides by them, and a product that underflows to 0 or overflows
    leaves nothing to solve."""
    for name in ("a", "b"):
        value = getattr(law, name)
        force = value * fn
        if (name == "a" or value > 0) and not 0.0 < force < math.inf:
            raise ValueError(f"{name} * normal_force = {value!r} * {fn!r} N = {force!r} N, "
                             "beyond double precision: give the problem in other units")


#: the scalar fields :func:`variant` changes, by the part of the problem that holds them
_PROBLEM_FIELDS = ("mass", "stiffness", "normal_force", "mu0", "t_end", "radiation_damping")


def _scalar_fields(obj) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(obj)
                 if isinstance(getattr(obj, f.name), (int, float)))


def variant_fields(problem: SpringSlider) -> tuple[str, ...]:
    """The names :func:`variant` accepts for ``problem``: the law's a, b, lc, v0 (and its own,
    such as the Nagata law's c); the problem's mass, stiffness, normal_force, mu0, t_end,
    radiation_damping; its loading's scalars: vl (constant), vls, vlf, df (two speeds), the
    overshoot of a history; a :class:`BalancedStart`'s slowdown, or an :class:`InitialState`'s
    v, theta, fs as initial_v, initial_theta, initial_fs.

    Parameters
    ----------
    problem : SpringSlider
        The problem whose fields are listed.

    Returns
    -------
    tuple of str
        The field names, law's first.
    """
    initial = (("slowdown",) if isinstance(problem.initial, BalancedStart)
               else ("initial_v", "initial_theta", "initial_fs"))
    return (_scalar_fields(problem.law) + _PROBLEM_FIELDS + _scalar_fields(problem.loading)
            + initial)


def variant(problem: SpringSlider, **changes: float) -> SpringSlider:
    """``problem`` with scalar fields replaced by name, validated as any problem is:
    ``variant(p, b=0.0094, lc=3e-7, stiffness=1.2e8)``.

    Parameters
    ----------
    problem : SpringSlider
        The base problem, left as it is.
    **changes : float
        New values by field name, in the field's SI unit (:func:`variant_fields` lists them).

    Returns
    -------
    SpringSlider
        A new problem.

    Raises
    ------
    ValueError
        Naming an unknown field and the ones there are, or a value the problem refuses.

    Warns
    -----
    UnitWarning
        (:class:`~problems._validate.UnitWarning`) For the changed values only: the base problem
        warned for its own when it was made.
    """
    known = variant_fields(problem)
    unknown = [k for k in changes if k not in known]
    if unknown:
        raise ValueError(f"{unknown[0]!r} is not a field a variant of this problem can change; "
                         f"the fields are {', '.join(known)}")
    parts = {"law": {}, "loading": {}, "initial": {}, "problem": {}}
    law, loading = set(_scalar_fields(problem.law)), set(_scalar_fields(problem.loading))
    for name, value in changes.items():
        part = ("law" if name in law else "problem" if name in _PROBLEM_FIELDS
                else "loading" if name in loading else "initial")
        parts[part][name.removeprefix("initial_")] = value
    top = dict(parts["problem"])
    # a unit warning for what changes only: the base problem warned for its own values when it
    # was made (a value refused is refused all the same)
    with units_checked_already():
        for part in ("law", "loading", "initial"):
            if parts[part]:
                top[part] = dataclasses.replace(getattr(problem, part), **parts[part])
        out = dataclasses.replace(problem, **top)
    for name, value in changes.items():
        kind = "slip_rate" if name == "initial_v" else name
        if kind in PLAUSIBLE:
            warn_implausible(name, value, kind=kind)
    if isinstance(out.initial, InitialState) and set(changes) & {
            "initial_theta", "initial_fs", "normal_force", "b", "lc", "v0"}:
        _warn_implausible_start(out.law, out.normal_force, out.initial_state)
    return out

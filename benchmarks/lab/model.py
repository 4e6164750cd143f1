"""The forward model of a laboratory fit: μ(t) at a record's sample times, for given friction
parameters, on the record's own load-point history.

The slider is quasi-static by default (as rsfmodel, RSFit3000 and Marone's code), with mass or
radiation damping on request. Quasi-static and with no integrator asked for, it is solved by the
compiled model of :mod:`benchmarks.lab.two_state` (Rodas5P's stages at rtol = atol =
:data:`COMPILED_TOL`, the second state idle with one), which also gives the exact forward
sensitivities ∂μ/∂θ (:meth:`LabModel.sensitivities`): a fit then needs no finite differences.
Otherwise it is the project's :class:`problems.SpringSlider` solved with
:func:`integrators.solve` (``save_at`` the record's times, from the method's dense output). Its
stiffness is given as k′ = k/Fn, friction per metre of load-point displacement (RSFit3000's k in µm⁻¹ is
k′ · 10⁻⁶); without mass or damping the friction coefficient does not depend on Fn, which is
then the nominal :data:`NOMINAL_NORMAL_FORCE`. The run starts from steady sliding at the first
piece's speed, which is also the law's reference speed v0.

With ``states=2`` the law has a second state variable (b2, Dc2: two evolutions, one of which may
strengthen) and the slider is quasi-static: it is solved by its own compiled model
(:mod:`benchmarks.lab.two_state`), as no :class:`~problems.SpringSlider` holds two
states; ``algorithm`` then does not apply.

The friction μ the model returns is μ_ref + (Fs/Fn − μ0) + the trend: μ_ref the steady friction
at the first speed (a fit parameter), the trend a straight line in the load point's displacement
per piece of the history, continuous at the switches. By default (``detrend="steady"``,
:mod:`benchmarks.lab.steady_trend`) each piece's slope is read beforehand where the slider is
steady (before the step; after the evolution has ended, as Giacomel et al. 2024's steadystate
finds it) and held, its error carried into the fit's; a piece without a steady part has its
slope fitted. ``"piece"`` fits every slope with the rest, which can take up part of the
evolution; ``"one"`` is one line through the record; ``"none"`` no trend. The offset and the fitted slopes enter linearly; a held trend is
:attr:`LabModel.offset`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from problems.friction import law_parameters

__all__ = ["LabModel", "DETRENDS", "NOMINAL_NORMAL_FORCE", "LAB_MU0", "DEFAULT_ALGORITHM",
           "COMPILED_TOL", "WALL_BUDGET"]

#: N: the normal force of a model whose friction does not depend on it (quasi-static, undamped)
NOMINAL_NORMAL_FORCE = 1e4
#: the reference friction of the slider; the fit's own level is μ_ref, added on
LAB_MU0 = 0.6
#: the ways of detrending: the slopes per piece read where the slider is steady (the default),
#: a slope per piece of the history fitted with the rest, one slope, none
DETRENDS = ("steady", "piece", "one", "none")
#: (name, rtol = atol): the fit's integrator unless told (checked by the fit's solver check)
DEFAULT_ALGORITHM = ("Rodas5P", 1e-10)
#: rtol = atol of the compiled quasi-static model (:attr:`LabModel.compiled`) on (μ, L1, L2):
#: 1e-11 keeps its error (2e-12 in μ on the tests' synthetic step; 1e-11 at 1e-10, whose
#: elementary step control is looser than the engine's) under what the solver check resolves
#: on a noise-free record
COMPILED_TOL = 1e-11
#: s of wall time per solve unless told: a solve over it fails (NaN, never read as μ). A fit's
#: solves take milliseconds; the solver check's scipy Radau at 1e-12 about 3 ms a step, so a
#: long record may need more (a slide-hold-slide of 20,000 samples: about 40 s)
WALL_BUDGET = 120.0


@dataclass(frozen=True)
class LabModel:
    """μ(t) of ``law`` on ``record``'s history: the forward model of a laboratory fit.

    Parameters
    ----------
    record : LabRecord
        The laboratory record (:func:`~benchmarks.lab.step_data.lab_record_from`): its times
        (s), friction and load-point history.
    law : str
        A law of :data:`problems.LAWS` (default ``"aging"``).
    detrend : str
        How the level and trend of μ are taken out, one of :data:`DETRENDS` (default
        ``"steady"``).
    mass : float
        The slider's mass (kg; default 0, quasi-static).
    radiation_damping : float
        ηr (N s/m; default 0).
    normal_force : float or None
        Fn (N), needed with a mass or damping (μ then depends on it).
    algorithm : Algorithm or None
        The one-state model's integrator. None: the compiled quasi-static model where there
        is no mass or damping (:attr:`compiled`), else :data:`DEFAULT_ALGORITHM`.
    states : int
        1, or 2 for a second state variable (quasi-static only;
        :mod:`benchmarks.lab.two_state`).
    wall_budget : float or None
        Seconds per solve (None: no budget; the compiled model also has its step budget,
        ``MAX_STEPS``).
    steady_after : tuple of float, optional
        ``detrend="steady"``: per piece, the time (s) before which it is not steady, as a
        fitted model says (:func:`~benchmarks.lab.steady_trend.settled_after`; the fit sets
        it).
    steady_fitted : tuple of bool, optional
        ``detrend="steady"``: per piece, True to fit its slope with the rest rather than hold
        it (the fit sets it where a held slope would be less precise).

    Raises
    ------
    ValueError
        For an unknown law or detrend, states other than 1 or 2, a negative mass or damping,
        a mass or damping without a normal force, or two states with a mass, damping or an
        algorithm.
    """

    record: object
    law: str = "aging"
    detrend: str = "steady"
    mass: float = 0.0
    radiation_damping: float = 0.0
    normal_force: float | None = None
    algorithm: object = None
    states: int = 1
    wall_budget: float | None = WALL_BUDGET
    steady_after: tuple | None = None
    steady_fitted: tuple | None = None
    _basis: np.ndarray = field(init=False, repr=False, compare=False)
    _names: tuple = field(init=False, repr=False, compare=False)
    _steady: object = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self) -> None:
        from problems.friction import LAWS
        if self.law not in LAWS:
            raise ValueError(f"law must be one of {', '.join(LAWS)}, got {self.law!r}")
        if self.detrend not in DETRENDS:
            raise ValueError(f"detrend must be one of {', '.join(DETRENDS)}, got "
                             f"{self.detrend!r}")
        if self.states not in (1, 2):
            raise ValueError(f"states must be 1 or 2, got {self.states!r}")
        if self.states == 2 and (self.mass > 0 or self.radiation_damping > 0):
            raise ValueError("a second state variable is fitted on the quasi-static slider "
                             "only: no mass, no radiation damping")
        if self.states == 2 and self.algorithm is not None:
            raise ValueError("a second state variable has its own compiled model: no "
                             "algorithm to choose")
        from problems._validate import check_non_negative, check_positive
        check_non_negative("mass (kg)", self.mass)
        check_non_negative("radiation_damping (N s/m)", self.radiation_damping)
        if self.normal_force is not None:
            check_positive("normal_force (N)", self.normal_force)
        if self.wall_budget is not None:
            check_positive("wall_budget (s per solve)", self.wall_budget)
        elif self.mass > 0 or self.radiation_damping > 0:
            raise ValueError("a slider with mass or radiation damping needs the normal force "
                             "(N): the friction then depends on it")
        if self.algorithm is None and (self.mass > 0 or self.radiation_damping > 0):
            from integrators import make_algorithm
            name, tol = DEFAULT_ALGORITHM
            object.__setattr__(self, "algorithm", make_algorithm(name, rtol=tol, atol=tol))
        elif self.algorithm is not None and not self.algorithm.saves_at_times:
            raise ValueError(f"{self.algorithm.name} saves at its own step ends; a fit needs "
                             "μ at the record's times from a method's dense output")
        if self.detrend == "steady":
            from benchmarks.lab.steady_trend import steady_trend
            rec = self.record
            object.__setattr__(self, "_steady", steady_trend(rec.t, rec.mu, rec.velocities,
                                                             rec.switch_times,
                                                             after=self.steady_after,
                                                             fitted=self.steady_fitted))
        basis, names = self._trend_basis()
        object.__setattr__(self, "_basis", basis)
        object.__setattr__(self, "_names", names)

    @property
    def fn(self) -> float:
        return NOMINAL_NORMAL_FORCE if self.normal_force is None else self.normal_force

    @property
    def v0(self) -> float:
        return float(self.record.velocities[0])

    @property
    def linear_names(self) -> tuple[str, ...]:
        """The parameters that enter linearly: μ_ref and the trend's slopes (per metre of
        load-point travel): ``trend`` for one through the record, ``trend_i`` for piece i."""
        return self._names

    def linear_basis(self) -> np.ndarray:
        """(samples, 1 + slopes): the columns the linear parameters multiply."""
        return self._basis

    @property
    def steady(self):
        """The trend read where the slider is steady
        (:class:`~benchmarks.lab.steady_trend.SteadyTrend`), for ``detrend="steady"``; else
        None."""
        return self._steady

    @property
    def offset(self) -> np.ndarray:
        """The trend held fixed at each sample (``detrend="steady"``), else zeros: the fit
        takes it off the record's μ."""
        if self._steady is None:
            return np.zeros(len(self.record.t))
        return self._steady.offset

    def _trend_basis(self):
        rec = self.record
        t = rec.t
        bounds = np.concatenate(([0.0], rec.switch_times, [np.inf]))
        # the load point's displacement by the fitted history (not the noisy recorded one)
        x_at = np.concatenate(([0.0], np.cumsum(np.diff(bounds[:-1]) * rec.velocities[:-1])))
        columns, names = [np.ones_like(t)], ["mu_ref"]
        if self.detrend == "one":
            piece = rec.piece_index()
            columns.append(x_at[piece] + (t - bounds[piece]) * np.asarray(rec.velocities)[piece])
            names.append("trend")
        elif self.detrend in ("piece", "steady"):
            from benchmarks.lab.steady_trend import travel_columns
            fitted = self._steady.fitted if self._steady is not None else (True,) * len(
                rec.velocities)
            travel = (self._steady.columns if self._steady is not None else
                      travel_columns(t, rec.velocities, rec.switch_times))
            for i, v in enumerate(rec.velocities):
                # a hold moves no load point: no trend of its own; a steady slope is held
                if v > 0 and fitted[i]:
                    columns.append(travel[:, i])
                    names.append(f"trend_{i}")
        return np.column_stack(columns), tuple(names)

    def problem(self, a: float, b: float, dc: float, k: float, c: float | None = None):
        """The slider of these parameters (``dc`` in m, ``k`` = k′ in friction per m)."""
        from problems._validate import units_checked_already
        from problems.friction import law_from_name
        from problems.slider import BalancedStart, SpringSlider
        params = dict(a=a, b=b, lc=dc, v0=self.v0)
        if "c" in law_parameters(self.law):
            params["c"] = 2.0 if c is None else c
        with units_checked_already():      # a fit's trial values are no user's typing
            return SpringSlider(mass=self.mass, stiffness=k * self.fn, normal_force=self.fn,
                                law=law_from_name(self.law, **params),
                                loading=self.record.history, initial=BalancedStart(1.0),
                                t_end=float(self.record.t[-1]), mu0=LAB_MU0,
                                name=f"lab fit/{self.law}",
                                radiation_damping=self.radiation_damping)

    @property
    def parameters(self) -> tuple[str, ...]:
        """The law's parameters, in the order a fit lists them."""
        return (("a", "b", "dc", "k") + (("c",) if "c" in law_parameters(self.law) else ())
                + (("b2", "dc2") if self.states == 2 else ()))

    @property
    def compiled(self) -> bool:
        """True if the model is the compiled quasi-static one (:mod:`benchmarks.lab.two_state`,
        with exact sensitivities): two states, or one state without mass, damping or an
        integrator asked for (``algorithm`` None)."""
        return self.algorithm is None

    @property
    def integrator(self) -> str:
        """What solves the model, in words."""
        if self.compiled:
            return ("the compiled quasi-static model (Rodas5P's stages, exact sensitivities)"
                    if self.states == 1 else "the two-state model")
        return self.algorithm.name

    def sensitivities(self, names, a, b, dc, k, c=None, b2=None, dc2=None, rtol=None,
                      wall_budget=None):
        """(μ − μ0 at the record's times, ∂μ/∂θ there: one column per name of ``names``, a
        subset of :attr:`parameters`, steps): one solve of the compiled model
        (:func:`~benchmarks.lab.two_state.two_state_sensitivities`, within ``wall_budget`` s,
        default the model's); NaN where it failed.
        ValueError if the model is not :attr:`compiled`."""
        if not self.compiled:
            raise ValueError(f"sensitivities: the model solved by {self.integrator} has none; "
                             "the compiled quasi-static model has (no mass, damping or "
                             "integrator asked for)")
        from benchmarks.lab.two_state import two_state_sensitivities
        rec = self.record
        tol = COMPILED_TOL if rtol is None else rtol
        mu, steps, d = two_state_sensitivities(
            rec.t, rec.velocities, rec.switch_times, a, b, dc, k, tuple(names),
            b2=0.0 if b2 is None else b2, dc2=1.0 if dc2 is None else dc2, law=self.law,
            c=2.0 if c is None else c, mu0=LAB_MU0, rtol=tol, atol=tol,
            wall_budget=self.wall_budget if wall_budget is None else wall_budget)
        return mu - LAB_MU0, d, steps

    def response(self, a, b, dc, k, c=None, b2=None, dc2=None, algorithm=None,
                 wall_budget=None, rtol=None):
        """(μ − μ0 at the record's times, the Solution or, with the compiled model, the
        steps): the rate-and-state part of μ, without the level and the trend; NaN where the
        run failed (also over its ``wall_budget``, s: default the model's). ``rtol``: the
        compiled model's rtol = atol (default :data:`COMPILED_TOL`). An ``algorithm`` solves the
        :class:`~problems.SpringSlider` (one state) even where the model is compiled."""
        if algorithm is None and self.compiled or self.states == 2:
            mu, _, steps = self.sensitivities((), a, b, dc, k, c=c, b2=b2, dc2=dc2, rtol=rtol,
                                              wall_budget=wall_budget)
            return mu, steps
        from integrators import solve
        sol = solve(self.problem(a, b, dc, k, c), algorithm or self.algorithm,
                    save_at=self.record.t,
                    wall_budget=self.wall_budget if wall_budget is None else wall_budget)
        mu = np.full(len(self.record.t), np.nan)
        if sol.success:
            mu[:] = sol.fs / self.fn - LAB_MU0
        return mu, sol

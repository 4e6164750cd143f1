"""Before the experiment: how well would a planned velocity-step test resolve (a, b, Dc, k′)?

A :class:`Plan` is the load point's history (speeds and how long each is held), the sampling
rate, the friction's noise σ and the values the experimenter expects. Its expected standard
errors are the Fisher information's::

    Cov = σ² (Jᵀ P J)⁻¹

J the exact sensitivities of μ at the planned samples to the fitted coordinates (a, b, ln Dc,
ln k′, and the Nagata law's c), from the compiled model (:mod:`benchmarks.lab.two_state`), P the
projection off what the fit takes out linearly (the level, and with ``detrend`` "one" a slope
in the load point's travel, "piece" one per moving piece: the fit's own basis). It assumes the
law and the values given (the fit lands near them), white noise of σ (a noise whose long-run
variance is f times its variance widens every error by √f), and the history known; a parameter
the plan does not determine has an infinite error. :func:`check_plan` sets it against the
spread of repeated fits to records of the independent model (scipy's Radau on the published
equations, :mod:`benchmarks.lab.independent_model`) with that noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from problems.friction import LAWS, law_parameters

__all__ = ["Plan", "DETRENDS", "fisher_errors", "compare_plans", "check_plan", "varied",
           "undetermined", "SAMPLES", "PIECE_SAMPLES", "STABLE", "CHECK_MIN"]

#: what the planned fit takes out linearly besides the level (:class:`~benchmarks.lab.model.
#: LabModel`'s detrends that do not depend on the record: "steady" reads the record itself)
DETRENDS = ("none", "one", "piece")
#: the fewest and most samples a plan may have
SAMPLES = (20, 2_000_000)
#: the fewest fits of a check
CHECK_MIN = 10
#: the fewest samples of a piece (as the fit's history needs, history.MIN_SAMPLES)
PIECE_SAMPLES = 20
#: a plan's k′ must exceed the critical stiffness (b − a)/Dc by this factor: near it the
#: slider rings for long after each step and its errors are no velocity step's
STABLE = 1.2


@dataclass(frozen=True)
class Plan:
    """A planned velocity-step (or slide-hold-slide) test.

    Parameters
    ----------
    velocities : tuple of float
        The load point's speed on each piece (m/s; 0 a hold; the first > 0, the law's v0).
    durations : tuple of float
        How long each piece lasts (s).
    rate : float
        Samples per second (Hz), evenly spaced from 0.
    noise : float
        σ of the friction's white noise (dimensionless).
    a, b : float
        The expected direct and evolution effects.
    dc : float
        The expected critical slip (m).
    k : float
        The stiffness k′ in friction per metre of load-point travel (1/m).
    law : str
        A law of :data:`problems.LAWS`.
    c : float
        The Nagata law's stress coefficient (fitted with it).
    detrend : str
        One of :data:`DETRENDS`: what the fit takes out linearly besides the level.

    Raises
    ------
    ValueError
        For a bad value, named with its unit.
    """

    velocities: tuple
    durations: tuple
    rate: float
    noise: float
    a: float
    b: float
    dc: float
    k: float
    law: str = "aging"
    c: float = 2.0
    detrend: str = "none"

    def __post_init__(self) -> None:
        object.__setattr__(self, "velocities", tuple(float(v) for v in self.velocities))
        object.__setattr__(self, "durations", tuple(float(d) for d in self.durations))
        if len(self.velocities) < 2 or len(self.velocities) != len(self.durations):
            raise ValueError(f"a plan needs at least two pieces and one duration (s) per speed: "
                             f"got {len(self.velocities)} speeds, {len(self.durations)} "
                             "durations")
        if not all(math.isfinite(v) and v >= 0 for v in self.velocities) or not (
                self.velocities[0] > 0):
            raise ValueError("velocities must be finite and ≥ 0, the first > 0 (the law's "
                             "v0): got " + ", ".join(f"{v * 1e6:.6g}" for v in self.velocities)
                             + " µm/s")
        for name, value in (*((f"durations (s): {d!r}", d) for d in self.durations),
                            ("rate (Hz)", self.rate), ("noise (σ of μ)", self.noise),
                            ("a", self.a), ("dc (m)", self.dc), ("k (1/m)", self.k)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be positive and finite, got {value!r}")
        if not math.isfinite(self.b):
            raise ValueError(f"b must be finite, got {self.b!r}")
        if self.law not in LAWS:
            raise ValueError(f"law must be one of {', '.join(LAWS)}, got {self.law!r}")
        if self.detrend not in DETRENDS:
            raise ValueError(f"detrend must be one of {', '.join(DETRENDS)}, got "
                             f"{self.detrend!r}")
        n = self.samples
        if not SAMPLES[0] <= n <= SAMPLES[1]:
            raise ValueError(f"the plan has {n} samples ({sum(self.durations):g} s at "
                             f"{self.rate:g} Hz): {SAMPLES[0]} to {SAMPLES[1]} are planned")
        short = min(self.durations) * self.rate
        if short < PIECE_SAMPLES:
            raise ValueError(f"a piece of {min(self.durations):g} s at {self.rate:g} Hz has "
                             f"{short:.3g} samples: a fit needs {PIECE_SAMPLES} a piece")
        critical = (self.b - self.a) / self.dc
        if self.k <= STABLE * critical:
            raise ValueError(f"k (1/m) = {self.k:g} is not above the critical stiffness "
                             f"(b − a)/Dc = {critical:.4g} per m by a factor {STABLE:g}: the "
                             "slider would stick and slip (or nearly), not follow the steps")

    @property
    def samples(self) -> int:
        return int(math.floor(sum(self.durations) * self.rate + 1e-9)) + 1

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.samples) / self.rate

    @property
    def switch_times(self) -> tuple:
        return tuple(np.cumsum(self.durations)[:-1])

    @property
    def fitted(self) -> tuple:
        """The fitted parameters: a, b, dc, k and the law's own (c)."""
        return ("a", "b", "dc", "k") + (("c",) if "c" in law_parameters(self.law) else ())

    @property
    def values(self) -> dict:
        return {n: getattr(self, n) for n in self.fitted}

    def record(self, noise: float = 0.0, seed: int = 0):
        """A record of the plan by the independent model, with white noise of ``noise``, and
        the plan's own history (not one read off its displacement). ValueError if the model
        cannot run it."""
        from benchmarks.lab.independent_model import synthetic_record
        from benchmarks.lab.step_data import LabRecord
        t, switches = self.times, self.switch_times
        try:
            df = synthetic_record(t, self.velocities, switches, self.a, self.b, self.dc,
                                  self.k, law=self.law, c=self.c, noise=noise, seed=seed)
        except RuntimeError as exc:
            raise ValueError(f"the plan's record cannot be made ({exc}): are its values a "
                             "laboratory's?") from None
        edges = np.array([0.0, *switches, t[-1]])
        pieces = pd.DataFrame({"t_start_s": edges[:-1], "t_end_s": edges[1:],
                               "velocity_m_s": self.velocities,
                               "velocity_se_m_s": np.zeros(len(self.velocities)),
                               "samples": np.diff(np.searchsorted(t, edges, side="left"))})
        return LabRecord(t=t, mu=df.friction.to_numpy(float),
                         load_point=df.load_point_um.to_numpy(float) * 1e-6,
                         velocities=self.velocities, switch_times=switches, pieces=pieces,
                         source=f"plan, seed {seed}")

    def model(self, record=None):
        """The fit's :class:`~benchmarks.lab.model.LabModel` of the plan's record (noise-free
        unless given)."""
        from benchmarks.lab.model import LabModel
        return LabModel(self.record() if record is None else record, self.law,
                        detrend=self.detrend)


def _covariance(plan: Plan) -> np.ndarray:
    """σ²(JᵀPJ)⁻¹ in the fitted coordinates (a, b, ln Dc, ln k′, c): inf on the diagonal of a
    parameter the plan does not determine."""
    from benchmarks.lab.fit import _LOG
    model = plan.model()
    names = plan.fitted
    values = plan.values
    _, d, steps = model.sensitivities(names, **values)
    if steps < 0:
        raise ValueError("the plan's model failed to run: are its values a laboratory's?")
    d = d * np.array([values[n] if n in _LOG else 1.0 for n in names])
    basis = model.linear_basis()
    q, _ = np.linalg.qr(basis)
    j = d - q @ (q.T @ d)
    u, s, vt = np.linalg.svd(j, full_matrices=False)
    keep = s > s.max(initial=0.0) * 1e-10
    cov = (vt[keep].T / s[keep] ** 2) @ vt[keep] * plan.noise ** 2
    lost = np.abs(vt[~keep]).max(axis=0) > 1e-6 if (~keep).any() else np.zeros(len(names),
                                                                               bool)
    cov[lost, :] = cov[:, lost] = np.inf
    return cov


def fisher_errors(plan: Plan) -> pd.DataFrame:
    """The expected standard errors of the fitted parameters and a − b: ``parameter``,
    ``value``, ``unit``, ``se`` (in the unit), ``relative_se`` (se over the value's size; for
    Dc and k′, whose fit is in ln, the se of ln). Where the plan does not determine a
    parameter (its se inf), the others' are those with it held: said by :func:`undetermined`
    and the command."""
    from benchmarks.lab.fit import _LOG, PARAMETER_UNITS
    cov = _covariance(plan)
    names = plan.fitted
    rows = []
    for i, name in enumerate(names):
        value, var = plan.values[name], cov[i, i]
        se_coord = math.sqrt(var) if math.isfinite(var) else math.inf
        se = value * se_coord if name in _LOG else se_coord
        rel = se_coord if name in _LOG else se_coord / abs(value) if value else math.inf
        rows.append({"parameter": name, "value": value,
                     "unit": PARAMETER_UNITS.get(name, "1"), "se": se, "relative_se": rel})
    i, j = names.index("a"), names.index("b")
    var = cov[i, i] + cov[j, j] - 2 * cov[i, j]
    se = math.sqrt(max(var, 0.0)) if math.isfinite(var) else math.inf
    rows.append({"parameter": "a_minus_b", "value": plan.a - plan.b, "unit": "1", "se": se,
                 "relative_se": se / abs(plan.a - plan.b) if plan.a != plan.b else math.inf})
    return pd.DataFrame(rows)


def undetermined(errors: pd.DataFrame) -> list:
    """The parameters of :func:`fisher_errors`' table the plan does not determine."""
    return [n for n, se in zip(errors.parameter, errors.se) if not math.isfinite(se)]


def compare_plans(plans: dict, target: str = "dc") -> pd.DataFrame:
    """One row per named plan: each parameter's relative se (``<name>_rse``), the target's
    se in its unit, how many times smaller the target's relative se than the first plan's
    (``gain``; relative, as a variation may change the value itself), and ``best`` (True on
    the plan with the smallest finite relative se of ``target``; none if no plan determines
    it)."""
    rows = []
    for label, plan in plans.items():
        table = fisher_errors(plan).set_index("parameter")
        if target not in table.index:
            raise ValueError(f"target: the {plan.law} law's fit has no {target!r}; it fits "
                             f"{', '.join(table.index)}")
        row = {"design": label, "samples": plan.samples, "seconds": sum(plan.durations),
               f"{target}_se": table.at[target, "se"]}
        row.update({f"{n}_rse": table.at[n, "relative_se"] for n in table.index})
        rows.append(row)
    out = pd.DataFrame(rows)
    rse = out[f"{target}_rse"]
    out["gain"] = rse.iloc[0] / rse if math.isfinite(rse.iloc[0]) else np.nan
    finite = np.isfinite(rse)
    out["best"] = finite & (rse == rse[finite].min()) if finite.any() else False
    return out


def check_plan(plan: Plan, n: int = 100, seed: int = 0, progress=None) -> pd.DataFrame:
    """The Fisher errors against the spread of ``n`` fits (:func:`~benchmarks.lab.fit.fit_lab`,
    the plan's detrend) to records of the independent model with the plan's noise (seeds
    ``seed`` …): per fitted coordinate, ``fisher_se``, ``spread`` (the fits' standard
    deviation), ``ratio`` = fisher_se/spread, the fits' ``bias`` over the spread, and how many
    ``fits`` succeeded of the ``attempts``. ``progress(i, n)`` is called after each fit.
    ValueError for fewer than :data:`CHECK_MIN` fits (a spread of fewer says little)."""
    from benchmarks.lab.fit import _LOG, fit_lab
    if n < CHECK_MIN:
        raise ValueError(f"a check of {n} fits: at least {CHECK_MIN} (the spread of fewer is "
                         "no measure of an error)")
    names = plan.fitted
    cov = _covariance(plan)
    found = []
    for i in range(n):
        record = plan.record(noise=plan.noise, seed=seed + i)
        fit = fit_lab(plan.model(record), start=plan.values, uncertainty=False)
        if fit.success:
            found.append([math.log(fit.values[m]) if m in _LOG else fit.values[m]
                          for m in names])
        if progress is not None:
            progress(i + 1, n)
    found = np.array(found).reshape(-1, len(names))
    truth = np.array([math.log(plan.values[m]) if m in _LOG else plan.values[m]
                      for m in names])
    spread = found.std(axis=0, ddof=1) if len(found) > 1 else np.full(len(names), np.nan)
    fisher = np.sqrt(np.diag(cov))
    return pd.DataFrame({"parameter": [f"ln {m}" if m in _LOG else m for m in names],
                         "fisher_se": fisher, "spread": spread, "ratio": fisher / spread,
                         "bias": (found.mean(axis=0) - truth) / spread,
                         "fits": len(found), "attempts": n})


def varied(plan: Plan, **changes) -> Plan:
    """The plan with ``changes`` (its fields)."""
    return replace(plan, **changes)

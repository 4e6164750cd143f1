"""What an inversion is scored against (Eq. 10, 11): observed means with their σ, and optionally
the observed slip-weakening curves — typed in (``--obs-recurrence``, ``--obs-drop``, a window's
published means) or measured on a recording by ``rsfbench observe`` and read back from its
observations file.

**The observations file** (``observations.json``, written by :func:`write_observations`) holds
the number of events, the mean, standard deviation (``std``, over the events) and standard error
of the mean (``sem`` = std/√n) of ΔT, Δμ, the slip per event and the peak slip rate, their
per-event table (with a ``kept`` column, the means are of the kept events and
``metrics_all_events`` of all: the start-up of a record left out), the correlation of ΔT and
Δμ, the curves, the apparatus read from the record,
the notes on what was assumed, and where it all came from (the recording's file and hash, the
column mapping, the program's version and command).

**Which σ.** J1 uses ``std`` by default, as the paper does (its σT, σμ are "the standard
deviation of ΔTob and Δμ0ob"): the model's limit cycle is one deterministic cycle, and what it is
compared with is the spread of the laboratory's events around their mean — event-to-event
variability the model does not have, which does not shrink as more events are recorded. The
standard error says how well the mean itself is known; with it, a long record would make the
95 % region arbitrarily small around a model that cannot produce the scatter. The file records
both; ``sigma="sem"`` (``--sigma sem``) reads the other.

**The measurement chain** (``measurement``, from ``observe``): how the curves were read from the
recording — its rate, the filters (kind, order, cutoffs), the timing's smoothing and levels
(:mod:`benchmarks.physics.chain`). The inversion passes the model's curves through the same chain
before comparing them. A file written before the record existed has no ``measurement``: it reads
as "no chain", and the model's curves are compared as the model makes them (as before).

**The model's error** (``model_error``, ``rsfbench invert --model-error``): a σ_model per
observable, given as a fraction — of ΔT̄ for ``recurrence``, of Δμ̄ for ``drop`` and for
``curves`` (the friction an event loses: the curves' scale) — added in quadrature to what the
data say: σ² = σ_obs² + σ_model² in J1, and σ_model² on every contrast of the curves' covariance
(or per sample, noise model ``sample``). Default 0: the data's σ alone. It says how far the
model itself (one deterministic cycle, one friction law) may be from a laboratory's events.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.inversion.curve_likelihood import CURVE_NOISES, CurveLikelihood
from benchmarks.physics.chain import Chain
from benchmarks.physics.curves import check_curves
from benchmarks.records.files import BadResultsFile, read_json_record, write_output
from benchmarks.records.report import jsonable
from problems import WINDOWS
from problems._validate import (PLAUSIBLE, RegularCycleWarning, check_positive, check_possible,
                                implausible_message, warn_unit)

__all__ = ["Observations", "observations", "ASSUMED_SIGMA", "MIN_SIGMA_REL", "SIGMAS",
           "write_observations", "read_observations", "OBSERVATIONS_FORMAT", "MODEL_ERRORS",
           "check_model_error"]

#: σ below this fraction of its observed mean is refused: no forward solver resolves a limit
#: cycle's metrics that finely, and J1 = (Δ/σ)² would be the solver's noise (or overflow)
MIN_SIGMA_REL = 1e-9


@dataclass(frozen=True)
class Observations:
    """What a point is scored against: observed means and standard deviations (Eq. 10), and
    optionally the observed slip-weakening curves (Eq. 11). The four numbers must be positive
    and finite: ΔT̄ and its σ in s, Δμ̄ and its σ dimensionless (a fraction: W2's drop is 0.046).

    A value implausible in its unit warns (:class:`~problems._validate.UnitWarning`: a drop in
    percent, 8.4, or a σ in percent of a drop, ten times it); a drop of 10 or more, which no
    friction coefficient allows, is refused. The observations of a sweep are made once, so a
    sweep warns once."""

    recurrence_s: float
    sigma_recurrence_s: float
    friction_drop: float
    sigma_friction_drop: float
    curves: pd.DataFrame | None = None
    assumed_sigma: bool = False        # σ not measured: 10 % of the mean, say so in the output
    #: the curves' noise model, σ per sample (model "sample") and reading (std or sem) of the
    #: spread (model "scatter"): :mod:`benchmarks.inversion.curve_likelihood`; "none": the
    #: curves enter no likelihood, and a Misfit makes no model curves (a sweep still scores
    #: its J2 with them)
    curve_noise: str = "scatter"
    curve_sigma: float | None = None
    curve_reading: str = "std"
    #: the measurement chain the curves were read through (a
    #: :class:`~benchmarks.physics.chain.Chain`, applied to the model's curves too; None: none)
    curve_chain: object = None
    #: the model's error per observable, as fractions (:data:`MODEL_ERRORS`; module docstring)
    model_error: dict | None = None
    #: the curves' likelihood (None without curves), made from the above
    curve_likelihood: object = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for mean, sigma in (("recurrence_s", "sigma_recurrence_s"),
                            ("friction_drop", "sigma_friction_drop")):
            m = check_positive(mean, getattr(self, mean))
            s = check_positive(sigma, getattr(self, sigma))
            if s < MIN_SIGMA_REL * m:           # refused before any warning about it
                raise ValueError(f"{sigma} = {s:g} is below {MIN_SIGMA_REL:g} of the observed "
                                 f"mean {mean} = {m:g}: no forward solver resolves a limit "
                                 "cycle's metrics that finely (J1 would be the solver's noise, "
                                 "or overflow)")
            m = check_possible(mean, m)
            if implausible_message(mean, m) is None and s / m < REGULAR_SIGMA_REL:
                _warn_regular(mean, m, sigma, s)        # a regular cycle, not a unit slip
                continue
            s = check_possible(sigma, s)
            # σ beyond 3 means (every point would fit) is a σ in another unit than its mean's:
            # ms, percent (said once: not again when σ or the mean was warned for already)
            plausible = all(implausible_message(k, v) is None for k, v in ((mean, m), (sigma, s)))
            if plausible and not s / m < 3.0:
                unit = "seconds" if mean == "recurrence_s" else "a fraction, not a percentage"
                warn_unit(f"{sigma} = {s:g} is {s / m:.3g} × {mean} = {m:g}: implausible for "
                          "a standard deviation (plausible: below 3 times the mean); "
                          f"both are in one unit ({unit})", stacklevel=1)
        if not isinstance(self.assumed_sigma, (bool, np.bool_)):
            raise ValueError(f"assumed_sigma must be True or False, got {self.assumed_sigma!r}")
        if self.curve_noise not in (*CURVE_NOISES, "none"):
            raise ValueError(f"curve_noise must be one of {(*CURVE_NOISES, 'none')}, got "
                             f"{self.curve_noise!r}")
        object.__setattr__(self, "model_error", check_model_error(self.model_error))
        if self.curves is not None:
            object.__setattr__(self, "curves", check_curves(self.curves, "obs.curves"))
            if self.curve_noise != "none":
                object.__setattr__(self, "curve_likelihood", CurveLikelihood.from_curves(
                    self.curves, self.curve_noise, self.curve_sigma, self.curve_reading,
                    chain=self.curve_chain,
                    model_error=self.model_error["curves"] * self.friction_drop))

    @property
    def sigmas(self) -> tuple[float, float]:
        """σ of ΔT (s) and of Δμ in J1: σ² = σ_obs² + σ_model², σ_model the model error's
        fraction of the observed mean (0 by default: σ_obs alone)."""
        e = self.model_error
        return (math.hypot(self.sigma_recurrence_s, e["recurrence"] * self.recurrence_s),
                math.hypot(self.sigma_friction_drop, e["drop"] * self.friction_drop))


#: the observables a model error is given for: its σ_model is the fraction times ΔT̄, Δμ̄, and
#: Δμ̄ again for the curves (their scale: the friction an event loses), in μ per common slip
MODEL_ERRORS = ("recurrence", "drop", "curves")


def check_model_error(model_error) -> dict:
    """``model_error`` (observable → fraction ≥ 0, :data:`MODEL_ERRORS`; None: all 0) with
    every observable, or ``ValueError`` naming the one that is wrong."""
    model_error = {} if model_error is None else model_error
    if not isinstance(model_error, dict):
        raise ValueError(f"model_error must be a dict of {MODEL_ERRORS} to fractions, got "
                         f"{model_error!r}")
    unknown = sorted(set(model_error) - set(MODEL_ERRORS))
    if unknown:
        raise ValueError(f"model_error: unknown observable {unknown[0]!r} (expected "
                         f"{', '.join(MODEL_ERRORS)})")
    out = {}
    for key in MODEL_ERRORS:
        value = model_error.get(key, 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                math.isfinite(value) and 0 <= value < 1):
            raise ValueError(f"model_error {key} must be a fraction of its observed mean in "
                             f"[0, 1), got {value!r}")
        out[key] = float(value)
    return out


#: σ below this fraction of a plausible mean is a very regular cycle (said, with what it
#: implies), not a unit slip: a σ in another unit than its mean's is larger, not smaller (ms
#: for s, percent for a fraction)
REGULAR_SIGMA_REL = 1e-3


def _warn_regular(mean: str, m: float, sigma: str, s: float) -> None:
    """Say that σ is far below its mean: a regular cycle, and the narrow posterior it makes."""
    what = "ΔT" if mean == "recurrence_s" else "Δμ"
    # a drop below what a load cell resolves is said (an event's timing is resolved far
    # below a sampling interval, its σ is not)
    low = what == "Δμ" and implausible_message(sigma, s) is not None
    measured = (f"; it is also implausibly small for a measured σ of {what} (below "
                f"{PLAUSIBLE[sigma].low:g}: a record made by a model?)" if low else "")
    warn_unit(f"{sigma} = {s:g} is {s / m:.2g} × {mean} = {m:g}: the events repeat that "
              f"closely, a very regular cycle (not a unit slip: a σ in another unit than its "
              f"mean's is larger, not smaller). An inversion against it is as sharp: its 95 % "
              f"region holds {what} within about ±{245 * s / m:.2g} % of its mean, narrower "
              "than the model's own error (the solver's tolerance, a model that is not the "
              "apparatus) may be; widen σ where that matters" + measured,
              stacklevel=3, category=RegularCycleWarning)


#: σ assumed when none is given: 10 % of the observed mean (flagged in the output)
ASSUMED_SIGMA = 0.10


def observations(preset_name: str, obs_recurrence=None, sigma_recurrence=None, obs_drop=None,
                 sigma_drop=None, curves=None, curve_noise: str = "scatter",
                 curve_sigma: float | None = None,
                 model_error: dict | None = None) -> Observations:
    """Observations of a preset: a window's published means fill what is not given, and a
    missing σ is 10 % of its mean (``assumed_sigma`` says so); ``curves`` in the likelihood
    under ``curve_noise`` ("none": for the paper's J2 only); ``model_error``: the model's error
    per observable (:data:`MODEL_ERRORS`, default 0)."""
    if not isinstance(preset_name, str):
        raise ValueError(f"preset_name must be a preset's name (a string), got {preset_name!r}")
    w = WINDOWS.get(preset_name.upper())
    obs_recurrence = obs_recurrence if obs_recurrence is not None else (w and w.observed_recurrence)
    obs_drop = obs_drop if obs_drop is not None else (w and w.observed_drop)
    for name, value in (("obs_recurrence", obs_recurrence), ("obs_drop", obs_drop)):
        if value is None:
            raise ValueError(f"{name} is required for {preset_name!r} (it has no observed means)")
        check_positive(name, value)          # before a σ of 10 % is made of it
    assumed = sigma_recurrence is None or sigma_drop is None
    return Observations(
        recurrence_s=obs_recurrence,
        sigma_recurrence_s=(sigma_recurrence if sigma_recurrence is not None
                            else ASSUMED_SIGMA * obs_recurrence),
        friction_drop=obs_drop,
        sigma_friction_drop=sigma_drop if sigma_drop is not None else ASSUMED_SIGMA * obs_drop,
        curves=curves, assumed_sigma=assumed, curve_noise=curve_noise, curve_sigma=curve_sigma,
        model_error=model_error)


#: the σ an observations file offers: the events' standard deviation, the mean's standard error
SIGMAS = ("std", "sem")
#: the format's name and version, the first keys of the file
OBSERVATIONS_FORMAT = ("rsfbench observations", 1)
_METRIC_UNITS = {"recurrence_s": "s", "friction_drop": "", "slip_m": "m",
                 "peak_velocity_m_s": "m/s"}


def write_observations(path, events: pd.DataFrame, curves: pd.DataFrame | None = None,
                       apparatus: dict | None = None, how: dict | None = None, notes=(),
                       recording: dict | None = None, sigma: str = "std",
                       provenance: dict | None = None, settled: dict | None = None,
                       measurement: dict | None = None) -> dict:
    """Write the observations file ``path`` (module docstring) from a per-event table
    (``t_start``, ``t_end`` and the metrics) and return the document. Where the table has a
    ``kept`` column, the means, σ and correlation are over the kept events only, and
    ``metrics_all_events`` gives them over every event (σ with and without the dropped ones).

    Parameters
    ----------
    path : str or pathlib.Path
        The JSON file written.
    events : pandas.DataFrame
        One row per event: t_start, t_end (s) and the metrics (recurrence_s in s,
        friction_drop, …).
    curves : pandas.DataFrame, optional
        The slip-weakening curves (:func:`benchmarks.physics.check_curves`' columns).
    apparatus, how, recording, provenance : dict, optional
        What the record came from and how it was read, kept as given.
    settled : dict, optional
        Which events are the start-up and the outliers and what was done with them, kept as
        given (:mod:`benchmarks.lab.settled`).
    notes : sequence of str
        Remarks, kept as given.
    sigma : str
        Which spread the file names as σ: ``"std"`` or ``"sem"``.
    measurement : dict, optional
        The chain the curves were read through (:meth:`benchmarks.physics.chain.Chain.record`);
        None: no chain recorded (the model's curves are then compared as they are).

    Returns
    -------
    dict
        The document written.

    Raises
    ------
    ValueError
        For an unknown ``sigma``.
    """
    if sigma not in SIGMAS:
        raise ValueError(f"sigma must be one of {SIGMAS}, got {sigma!r}")
    used = events[events["kept"].astype(bool)] if "kept" in events else events
    metrics = _metrics(used)
    both = used[["recurrence_s", "friction_drop"]].dropna()
    corr = float(np.corrcoef(both.recurrence_s, both.friction_drop)[0, 1]) if len(both) > 2 \
        else math.nan
    doc = {"format": OBSERVATIONS_FORMAT[0], "version": OBSERVATIONS_FORMAT[1],
           "n_events": int(len(events)), "n_events_used": int(len(used)), "sigma": sigma,
           "sigma_means": ("std: the events' standard deviation (the paper's σ; the default) — "
                           "sem: the standard error of the mean, std/√n"),
           "metrics": metrics, "correlation_recurrence_drop": corr,
           "metrics_all_events": _metrics(events) if len(used) < len(events) else metrics,
           "settled": settled or {},
           "events": events.to_dict(orient="list"),
           "curves": None if curves is None else curves.to_dict(orient="list"),
           "measurement": measurement,
           "apparatus": apparatus or {}, "how": how or {}, "notes": list(notes),
           "recording": recording or {}, "provenance": provenance or {}}
    doc = jsonable(doc)
    write_output(Path(path), json.dumps(doc, indent=1))
    return doc


def _metrics(events: pd.DataFrame) -> dict:
    """n, mean, std and sem of each metric of :data:`_METRIC_UNITS` over ``events``."""
    metrics = {}
    for name, unit in _METRIC_UNITS.items():
        x = events[name].to_numpy(dtype=float) if name in events else np.array([])
        x = x[np.isfinite(x)]
        n = len(x)
        std = float(np.std(x, ddof=1)) if n > 1 else math.nan
        metrics[name] = {"n": n, "mean": float(np.mean(x)) if n else math.nan, "std": std,
                         "sem": std / math.sqrt(n) if n > 1 else math.nan, "unit": unit}
    return metrics


def read_observations(path, sigma: str | None = None, curve_noise: str = "scatter",
                      curve_sigma: float | None = None, model_error: dict | None = None,
                      chain: bool = True) -> Observations:
    """The :class:`Observations` of an observations file: the means of ΔT and Δμ, with the σ
    the file names (``std`` unless it says otherwise) or ``sigma``, and the curves if any, in
    the likelihood under ``curve_noise`` (:mod:`benchmarks.inversion.curve_likelihood`; the
    curves' spread read as the same σ); or ``ValueError`` naming the file and what is wrong.

    Parameters
    ----------
    path : str or pathlib.Path
        The observations file (:func:`write_observations`).
    sigma : str, optional
        ``"std"`` or ``"sem"``; ``None`` takes the file's.
    curve_noise : str
        The curves' noise model: ``"scatter"``, ``"sample"`` or ``"none"``.
    curve_sigma : float, optional
        The σ per sample of ``"sample"`` (units of μ, dimensionless).
    model_error : dict, optional
        The model's error per observable (:data:`MODEL_ERRORS`, fractions; default 0).
    chain : bool
        Pass the model's curves through the file's measurement chain (``measurement``); a file
        written before it was recorded has none, and its curves are compared as they are.

    Returns
    -------
    Observations

    Raises
    ------
    ValueError
        Naming the file and what is wrong with it, or an unknown ``sigma``.
    """
    if sigma is not None and sigma not in SIGMAS:
        raise ValueError(f"sigma must be one of {SIGMAS}, got {sigma!r}")
    try:
        doc = read_json_record(Path(path), ("format", "version", "metrics", "sigma"),
                               what="observations file")
    except BadResultsFile as exc:
        raise ValueError(str(exc)) from None
    if (doc.get("format"), doc.get("version")) != OBSERVATIONS_FORMAT:
        raise ValueError(f"observations file {path}: not an rsfbench observations file of "
                         f"version {OBSERVATIONS_FORMAT[1]} (format {doc.get('format')!r}, "
                         f"version {doc.get('version')!r})")
    which = sigma or doc["sigma"]
    try:
        m = {k: doc["metrics"][k] for k in ("recurrence_s", "friction_drop")}
        # None: what write_observations makes of NaN (JSON has none), a spread of < 2 events
        values = [math.nan if v is None else float(v) for v in (
            m["recurrence_s"]["mean"], m["recurrence_s"][which], m["friction_drop"]["mean"],
            m["friction_drop"][which])]
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"observations file {path}: its metrics lack the mean and {which} of "
                         "recurrence_s and friction_drop") from None
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"observations file {path}: the mean or {which} of ΔT or Δμ is not a "
                         f"number (from {doc['metrics']['recurrence_s'].get('n')} events: at "
                         "least two are needed)")
    curves = doc.get("curves")
    try:
        curves = pd.DataFrame(curves) if curves else None
        measured = Chain.from_record(doc.get("measurement")) if chain else None
        return Observations(*values, curves=curves, curve_noise=curve_noise,
                            curve_sigma=curve_sigma, curve_reading=which,
                            curve_chain=measured, model_error=model_error)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"observations file {path}: {exc}") from None

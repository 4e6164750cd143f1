"""The best fit drawn over the data it was fitted to: ``fit.png`` of ``rsfbench invert``.

One forward solve at the least-squares fit (:func:`model_at`: the misfit's problem, algorithm
and wall budget, and with observed curves the misfit's ``curve_dt``, so that the model's curve
is the one the curves' likelihood compares) gives the model's limit cycle. The figure
(:func:`fit_figure`) has one panel per mean of J1 and, with curves, one of the curves:

* ΔT and Δμ: each observed event (from the observations file's per-event table, against its
  onset) as a point, the mean ± σ the likelihood uses as a band (σ as the inversion read it:
  the events' std, their sem, or assumed), and the model's limit-cycle value at the fit as a
  line. With typed-in means (no per-event table) the band and the line only;
* the slip-weakening curves: each observed event shifted by its own best offset μ0 (Eq. 11's,
  in closed form: the likelihood compares shapes, not levels) to the events' common level, and
  the model's curve at that level; with the scatter model also the events' mean at the
  likelihood's common slips, which is what it compares. The curves' χ² at the fit is in the
  title.

Matplotlib is imported inside the functions, and the figure is a ``matplotlib.figure.Figure``
(no backend is chosen).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.ensemble import ensemble
from benchmarks.inversion.objectives import event_samples
from benchmarks.physics.metrics import CYCLES
from benchmarks.records.files import BadResultsFile, read_json_record, write_figure
from benchmarks.records.report import literal

__all__ = ["fit_figure", "plot_fit", "model_at", "observed_events", "MODEL_GID"]

#: the ``gid`` of every artist that draws the model at the fit (tests find them by it)
MODEL_GID = "model"
_METRICS = (("recurrence_s", "sigma_recurrence_s", "ΔT (s)", "recurrence interval"),
            ("friction_drop", "sigma_friction_drop", "Δμ", "friction drop"))


def model_at(misfit, b: float, lc: float) -> pd.Series:
    """The model at one point: one forward solve of ``misfit``'s problem and algorithm.

    Parameters
    ----------
    misfit : Misfit
        Its problem, algorithm, wall budget and, when its observations have curves,
        ``curve_dt`` (the model's curve is then made too, as the misfit makes it).
    b : float
        The evolution effect (dimensionless).
    lc : float
        The characteristic slip (m).

    Returns
    -------
    pandas.Series
        The ensemble's row (:func:`benchmarks.ensemble.ensemble`): ``classification``,
        ``retcode``, ``recurrence_s`` (s), ``friction_drop``, … and with curves
        ``curve_slip`` (m) and ``curve_friction``.
    """
    curves = misfit.obs.curves is not None
    table = ensemble(misfit.problem, misfit.algorithm, {"b": [float(b)], "lc": [float(lc)]},
                     wall_budget=misfit.wall_budget, workers=1,
                     curve_dt=misfit.curve_dt if curves else None, progress=False)
    return table.iloc[0]


def observed_events(path) -> pd.DataFrame | None:
    """The per-event table of an observations file (``events``: one row per event, its
    ``t_start`` (s), ``recurrence_s`` (s), ``friction_drop``, …), or None when it has none.

    Parameters
    ----------
    path : str or pathlib.Path
        An observations file (:func:`benchmarks.inversion.observations.write_observations`).

    Returns
    -------
    pandas.DataFrame or None
        Numeric columns as floats (a JSON null is NaN).

    Raises
    ------
    ValueError
        Naming the file, when it is not a JSON record or its table is not a table.
    """
    try:
        doc = read_json_record(Path(path), what="observations file")
    except BadResultsFile as exc:
        raise ValueError(str(exc)) from None
    table = doc.get("events")
    if not table:
        return None
    try:
        events = pd.DataFrame(table)
    except (TypeError, ValueError):
        raise ValueError(f"observations file {path}: its events are not a table (a column "
                         "name to a list of values, one per event)") from None
    for name in ("t_start", "recurrence_s", "friction_drop"):
        if name in events:
            events[name] = pd.to_numeric(events[name], errors="coerce")
    if "kept" in events:
        events["kept"] = events["kept"].astype(bool)
    return events if len(events) else None


def fit_figure(inv, events: pd.DataFrame | None = None, model: pd.Series | None = None):
    """The figure of the module docstring for an inversion.

    Parameters
    ----------
    inv : Inversion
        The inversion (:func:`benchmarks.inversion.invert.invert`); its fit is drawn.
    events : pandas.DataFrame, optional
        The observed events (:func:`observed_events`); None: the means only.
    model : pandas.Series, optional
        The model at the fit (:func:`model_at`); None: solved here.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes (ΔT, Δμ), three with observed curves.
    """
    from matplotlib.figure import Figure
    obs = inv.misfit.obs
    if model is None:
        model = model_at(inv.misfit, inv.fit.b, inv.fit.lc)
    cycle = model.classification in CYCLES and model.retcode == "Success"
    panels = 2 + (obs.curves is not None)
    fig = Figure(figsize=(4.6 * panels, 4.2), layout="constrained")
    axes = fig.subplots(1, panels)
    for ax, (name, sigma, label, what) in zip(axes, _METRICS):
        value = float(model[name]) if cycle else math.nan
        _draw_metric(ax, events, name, (getattr(obs, name), getattr(obs, sigma)), value, label)
        ax.set_title(f"{what}: observed and the model at the fit", fontsize=9)
        if obs.assumed_sigma:
            ax.text(0.02, 0.02, "σ assumed: 10 % of the mean", transform=ax.transAxes,
                    fontsize=7, color="0.4")
    if obs.curves is not None:
        _draw_curves(axes[2], obs, model if cycle else None)
    f = inv.fit
    fig.suptitle(f"{literal(inv.misfit.problem.name)}: least-squares fit b = {f.b:.5g}, Lc = "
                 f"{f.lc * 1e6:.4g} µm (misfit {f.misfit:.4g}), {inv.misfit.algorithm.name}"
                 + ("" if cycle else f" — no limit cycle at the fit ({model.classification}, "
                                     f"{model.retcode})"), fontsize=10)
    return fig


def _draw_metric(ax, events, name: str, observed: tuple, model: float, label: str) -> None:
    """One mean's panel: the events (if any), the likelihood's mean ± σ, the model's value."""
    mean, sigma = observed
    x = None
    if events is not None and name in events:
        y = events[name].to_numpy(dtype=float)
        x = (events.t_start.to_numpy(dtype=float) if "t_start" in events
             else np.arange(1.0, len(events) + 1))
        finite = np.isfinite(x) & np.isfinite(y)
        used = (events.kept.to_numpy(dtype=bool) if "kept" in events
                else np.ones(len(events), bool))
        ax.plot(x[finite & used], y[finite & used], "o", ms=3.5, color="C0",
                label=f"observed events in the means ({int((finite & used).sum())})")
        if (finite & ~used).any():          # observe's start-up, left out of the means
            ax.plot(x[finite & ~used], y[finite & ~used], "o", ms=4, mfc="none", color="0.5",
                    label=f"left out of the means ({int((finite & ~used).sum())})")
        ax.set_xlabel("event onset t (s)" if "t_start" in events else "event")
    else:
        ax.set_xticks([])
        ax.set_xlabel("typed-in means: no per-event table")
    ax.axhspan(mean - sigma, mean + sigma, color="C0", alpha=0.15,
               label=f"observed mean ± σ: {mean:.5g} ± {sigma:.2g}")
    ax.axhline(mean, color="C0", lw=0.8)
    if np.isfinite(model):
        ax.axhline(model, color="C3", lw=1.6, gid=MODEL_GID,
                   label=f"model's limit cycle at the fit: {model:.5g} "
                         f"({(model - mean) / sigma:+.2f} σ)")
    ax.set_ylabel(label)
    ax.legend(fontsize=7, loc="best")


def _draw_curves(ax, obs, model) -> None:
    """The observed curves at their best offsets, and the model's curve (module docstring)."""
    curves = obs.curves
    like = obs.curve_likelihood
    slip, friction = ((np.asarray(model.curve_slip, dtype=float),
                       np.asarray(model.curve_friction, dtype=float))
                      if model is not None and "curve_slip" in model else (np.empty(0),) * 2)
    drawn = like.curve(slip, friction) if like is not None else (slip, friction)
    events = [g.sort_values("slip_m") for _, g in curves.groupby("event_id", sort=False)]
    if len(slip) >= 2:
        s = event_samples(curves)
        r = np.interp(s.slip, *drawn) - s.friction
        offsets = np.bincount(s.event, r) / s.sizes        # each event's best μ0 (Eq. 11)
        level = offsets.mean()
    else:
        offsets, level = np.zeros(len(events)), 0.0
    for i, g in enumerate(events):
        ax.plot(g.slip_m * 1e6, g.friction + offsets[i] - level, ".-", ms=2, lw=0.5,
                color="0.55", alpha=0.7, label="observed events, each at its best offset"
                if i == 0 else None)
    if like is not None and like.noise == "scatter":
        ax.plot(like.slips * 1e6, like.mean, "s", ms=4, color="C0",
                label="their mean at the likelihood's common slips")
    if len(slip) >= 2:
        ax.plot(drawn[0] * 1e6, drawn[1] - level, color="C3", lw=1.6, gid=MODEL_GID,
                label="model's curve at the fit (its last event)"
                + ("" if drawn[0] is slip else ", its noisy phases read by a kernel"))
    else:
        ax.text(0.5, 0.5, "no model curve: no limit cycle at the fit", ha="center",
                transform=ax.transAxes)
    chi2 = (f"χ² = {like.chi2(slip, friction):.4g} on {like.dof} dof" if like is not None
            and len(slip) >= 2 else "in no likelihood" if like is None else "")
    ax.set_title(f"slip-weakening curves ({chi2})" if chi2 else "slip-weakening curves",
                 fontsize=9)
    ax.set_xlabel("slip since the event began (µm)")
    ax.set_ylabel(r"friction $F_t/F_n$ (offsets removed)")
    ax.legend(fontsize=7, loc="best")


def plot_fit(inv, path, events: pd.DataFrame | None = None) -> dict:
    """Write :func:`fit_figure` of ``inv`` to ``path`` (one forward solve at the fit) and
    return the model's values it drew.

    Parameters
    ----------
    inv : Inversion
        The inversion; its fit must have a finite misfit.
    path : str or pathlib.Path
        The PNG file (written as :func:`benchmarks.records.files.write_figure` writes).
    events : pandas.DataFrame, optional
        The observed events (:func:`observed_events`).

    Returns
    -------
    dict
        ``classification``, ``retcode``, ``recurrence_s`` (s), ``friction_drop`` and, with
        curves in the likelihood, ``chi2_curves``: the model at the fit.
    """
    model = model_at(inv.misfit, inv.fit.b, inv.fit.lc)
    write_figure(fit_figure(inv, events, model), Path(path), dpi=110)
    like = inv.misfit.obs.curve_likelihood
    out = {"classification": model.classification, "retcode": model.retcode,
           "recurrence_s": float(model.recurrence_s), "friction_drop": float(model.friction_drop)}
    if like is not None and "curve_slip" in model:
        out["chi2_curves"] = like.chi2(model.curve_slip, model.curve_friction)
    return out

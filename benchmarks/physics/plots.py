"""Figures of a run: slip rate and μ against time, and the friction–slip-rate phase portrait
(like Fig. 18 of Urata et al. 2017)."""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from integrators.core.plotting import draw_rate_and_friction
from benchmarks.records.files import write_figure

__all__ = ["plot_solution", "plot_work_precision", "plot_convergence"]


def plot_solution(solution, path, title: str | None = None) -> None:
    """Write a three-panel PNG of ``solution`` to ``path``.

    Parameters
    ----------
    solution : Solution
        The run drawn.
    path : str or pathlib.Path
        The PNG file.
    title : str, optional
        The figure's title; ``None``: the problem's and method's names.
    """
    p = solution.problem
    fig = Figure(figsize=(11, 6.5), layout="constrained")
    grid = fig.add_gridspec(2, 2, width_ratios=(1.6, 1))
    ax_v = fig.add_subplot(grid[0, 0])
    ax_mu = fig.add_subplot(grid[1, 0], sharex=ax_v)
    ax_ph = fig.add_subplot(grid[:, 1])

    draw_rate_and_friction(solution, ax_v, ax_mu)

    friction = (solution.ft - p.f0) / p.normal_force
    ax_ph.semilogx(solution.v, friction, lw=0.5, color="0.7", label="whole run")
    starts = solution.events["t_start"].to_numpy()
    if len(starts) >= 2:    # the last complete cycle, start to start
        cycle = (solution.t >= starts[-2]) & (solution.t <= starts[-1])
        ax_ph.semilogx(solution.v[cycle], friction[cycle], lw=1.2, color="C2", label="last cycle")
    ax_ph.legend(loc="lower left", fontsize=8)
    ax_ph.set_xlabel("slip rate v (m/s)")
    ax_ph.set_ylabel(r"$(F_t - F_0)/F_n$")
    ax_ph.set_title("friction against slip rate", fontsize=10)

    law = p.law
    fig.suptitle(title or (f"{p.name}: {type(solution.algorithm).__name__}, "
                           f"b = {law.b:.5g}, Lc = {law.lc * 1e6:.4g} µm, k = {p.stiffness:.3g} N/m"),
                 fontsize=11)
    write_figure(fig, path, dpi=110)


def _styles(keys):
    """A (colour, marker) per integrator: ten colours × four markers tell ~40 lines apart."""
    colors = matplotlib.colormaps["tab10"].colors
    markers = "os^D"
    names = sorted({k[0] for k in keys}, key=str.lower)
    return {n: (colors[i % 10], markers[(i // 10) % 4]) for i, n in enumerate(names)}


def plot_work_precision(df, path, error: str = "err_recurrence", title: str | None = None) -> None:
    """Log–log work-precision diagram of one problem: ``error`` against wall time (left) and
    against rhs evaluations (right), one line per (integrator, rhs tier); numba tier solid,
    Python tier dashed. Runs that failed or ran out of budget are crosses on the top edge at
    the cost they incurred (the error they would have had is unknown).

    Parameters
    ----------
    df : pandas.DataFrame
        One problem's rows of a work-precision study.
    path : str or pathlib.Path
        The PNG file.
    error : str
        The error column drawn.
    title : str, optional
        The figure's title.
    """
    keys = list(df.groupby(["integrator", "rhs_tier"], sort=False).groups)
    look = _styles(keys)
    fig = Figure(figsize=(14, 6.5), layout="constrained")
    axes = fig.subplots(1, 2, sharey=True)
    ok = df[(df.retcode == "Success") & (df[error] > 0)]
    top = 10 ** np.ceil(np.log10(ok[error].max())) if len(ok) else 1.0
    for (name, tier) in keys:
        g = df[(df.integrator == name) & (df.rhs_tier == tier)].sort_values("setting", ascending=False)
        good = g[(g.retcode == "Success") & (g[error] > 0)]
        bad = g[~g.retcode.isin(["Success", "Skipped"])]
        color, marker = look[name]
        style = dict(color=color, ls="-" if tier == "numba" else "--", marker=marker, ms=3.5,
                     lw=1.1)
        for ax, x in zip(axes, ("wall_s", "nfev")):
            label = f"{name} [{tier}]"
            ax.loglog(good[x], good[error], label=label, **style)
            if len(bad):
                ax.loglog(bad[x], np.full(len(bad), top), "x", color=color, ms=7, mew=1.5)
    axes[0].set_xlabel("wall time (s), minimum over repeats, after warm-up")
    axes[1].set_xlabel("right-hand-side evaluations")
    axes[0].set_ylabel(f"{error} (relative, vs. reference)")
    for ax in axes:
        ax.grid(True, which="major", alpha=0.3)
    axes[1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5), ncol=1,
                   title="solid: numba rhs, dashed: Python rhs\n×: failed / out of budget",
                   title_fontsize=7)
    fig.suptitle(title or f"work-precision: {df.problem.iloc[0]}", fontsize=11)
    write_figure(fig, path, dpi=100)


def plot_convergence(df, orders: dict, path, error: str = "err_recurrence",
                     title: str | None = None) -> None:
    """Error against step size (Δτcnst) of the fixed-step methods, with the fitted slopes.

    Parameters
    ----------
    df : pandas.DataFrame
        A convergence study's table (:func:`benchmarks.devtools.convergence_study`).
    orders : dict of str to float
        The fitted order of each method.
    path : str or pathlib.Path
        The PNG file.
    error : str
        The error column drawn.
    title : str, optional
        The figure's title.
    """
    fig = Figure(figsize=(7.5, 5.5), layout="constrained")
    ax = fig.subplots()
    for i, (name, g) in enumerate(df.groupby("integrator", sort=False)):
        g = g.sort_values("dtau_cnst")
        fitted = g[g.fitted]
        ax.loglog(g.dtau_cnst, g[error], "o", color=f"C{i}", mfc="none")
        ax.loglog(fitted.dtau_cnst, fitted[error], "o-", color=f"C{i}",
                  label=f"{name}: observed order {orders.get(name, float('nan')):.2f}")
    floor = df.reference_agreement.max()
    ax.axhline(floor, color="0.5", ls=":", lw=1, label="reference agreement (error floor)")
    ax.set_xlabel(r"$\Delta\tau_{cnst}$ (with $\Delta\tau_{max}$ scaled alike)")
    ax.set_ylabel(f"{error} (relative)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, title="filled: points in the least-squares fit", title_fontsize=8)
    ax.set_title(title or f"convergence: {df.problem.iloc[0]}", fontsize=11)
    write_figure(fig, path, dpi=110)

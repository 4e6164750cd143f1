"""Figures of a run: slip rate and μ against time, a zoom on one event (from the dense output,
the saved samples marked), and the friction–slip-rate phase portrait (like Fig. 18 of Urata et
al. 2017)."""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from integrators.core.plotting import draw_rate_and_friction
from benchmarks.records.files import write_figure
from benchmarks.records.report import literal

__all__ = ["plot_solution", "draw_event_zoom", "event_zoom_window", "plot_work_precision",
           "plot_convergence"]


def plot_solution(solution, path, title: str | None = None, saved=None) -> None:
    """Write a five-panel PNG of ``solution`` to ``path``: the slip rate and μ against time,
    the same over a window about the last complete event (:func:`draw_event_zoom`), and the
    phase portrait.

    Parameters
    ----------
    solution : Solution
        The run drawn (``Solution.resolved()``: each event from the dense output).
    path : str or pathlib.Path
        The PNG file.
    title : str, optional
        The figure's title; ``None``: the problem's and method's names.
    saved : pandas.DataFrame, optional
        The run's saved samples (:meth:`Solution.to_dataframe`'s columns: t, v, mu, ft),
        marked on the zoom; ``None``: not marked.
    """
    p = solution.problem
    fig = Figure(figsize=(15, 6.5), layout="constrained")
    grid = fig.add_gridspec(2, 3, width_ratios=(1.6, 1, 1))
    ax_v = fig.add_subplot(grid[0, 0])
    ax_mu = fig.add_subplot(grid[1, 0], sharex=ax_v)
    ax_zv = fig.add_subplot(grid[0, 1])
    ax_zmu = fig.add_subplot(grid[1, 1], sharex=ax_zv)
    ax_ph = fig.add_subplot(grid[:, 2])

    draw_rate_and_friction(solution, ax_v, ax_mu)
    draw_event_zoom(solution, ax_zv, ax_zmu, saved)
    _draw_phase(solution, ax_ph)

    law = p.law
    fig.suptitle(title or (f"{literal(p.name)}: {type(solution.algorithm).__name__}, "
                           f"b = {law.b:.5g}, Lc = {law.lc * 1e6:.4g} µm, k = {p.stiffness:.3g} N/m"),
                 fontsize=11)
    write_figure(fig, path, dpi=110)


def _draw_phase(solution, ax) -> None:
    """Friction against slip rate: the whole run, and its last complete cycle."""
    p = solution.problem
    friction = (solution.ft - p.f0) / p.normal_force
    ax.semilogx(solution.v, friction, lw=0.5, color="0.7", label="whole run")
    starts = solution.events["t_start"].to_numpy()
    if len(starts) >= 2:    # the last complete cycle, start to start
        cycle = (solution.t >= starts[-2]) & (solution.t <= starts[-1])
        ax.semilogx(solution.v[cycle], friction[cycle], lw=1.2, color="C2", label="last cycle")
    ax.legend(loc="lower left", fontsize=8)
    ax.set_xlabel("slip rate v (m/s)")
    ax.set_ylabel(r"$(F_t - F_0)/F_n$")
    ax.set_title("friction against slip rate", fontsize=10)


#: the zoom's window: the event's duration this many times before its start and after its end
ZOOM_MARGIN = 1.0


def event_zoom_window(solution) -> tuple[int, float, float] | None:
    """``(index, t0, t1)``: the last complete event of ``solution`` and the window (s) about it
    that :func:`draw_event_zoom` draws (its duration :data:`ZOOM_MARGIN` times on each side,
    within the run); None without a complete event.

    Parameters
    ----------
    solution : Solution
        The run.

    Returns
    -------
    tuple or None
        The event's row in ``event_array``, and the window's start and end (s).
    """
    events = np.asarray(solution.event_array)
    if not len(events):
        return None
    start, end = float(events[-1, 0]), float(events[-1, 1])
    pad = ZOOM_MARGIN * (end - start)
    return len(events) - 1, max(start - pad, 0.0), min(end + pad, solution.t_reached)


def draw_event_zoom(solution, ax_v, ax_mu, saved=None) -> None:
    """The last complete event of ``solution`` over :func:`event_zoom_window`: the slip rate
    (log) above, the spring's μ = Fs/Fn and the fault's Ft/Fn below, against the time since
    the event began (ms); ``saved`` (the run's saved samples) marks them in the window.

    Parameters
    ----------
    solution : Solution
        The run drawn (resolved: its events from the dense output).
    ax_v, ax_mu : matplotlib.axes.Axes
        The two panels.
    saved : pandas.DataFrame, optional
        The run's saved samples (:meth:`Solution.to_dataframe`'s columns: t, v, mu, ft);
        ``None``: none marked.
    """
    window = event_zoom_window(solution)
    if window is None:
        ax_v.text(0.5, 0.5, "no complete event to zoom on", ha="center", transform=ax_v.transAxes)
        return
    i, t0, t1 = window
    start = float(solution.event_array[i, 0])
    # what Solution.resolved() can resolve: a successful run of a method with dense output
    dense = solution.success and solution.algorithm.saves_at_times
    inside = (solution.t >= t0) & (solution.t <= t1)
    ms = (solution.t[inside] - start) * 1e3
    fn = solution.problem.normal_force
    ax_v.semilogy(ms, solution.v[inside], lw=1.0, color="C0",
                  label="dense output" if dense else "the saved samples, joined")
    ax_mu.plot(ms, solution.mu[inside], lw=1.0, color="C1", label=r"spring $F_s/F_n$")
    ax_mu.plot(ms, solution.ft[inside] / fn, lw=1.0, color="C2", label=r"fault $F_t/F_n$")
    if saved is not None:
        t = saved["t"].to_numpy()
        kept = (t >= t0) & (t <= t1)
        at = (t[kept] - start) * 1e3
        dot = dict(ls="none", marker="o", color="k", ms=3 if kept.sum() <= 150 else 1)
        ax_v.semilogy(at, saved["v"].to_numpy()[kept], **dot,
                      label=f"saved samples ({int(kept.sum())} in the window)")
        ax_mu.plot(at, saved["mu"].to_numpy()[kept], **dot)
        ax_mu.plot(at, saved["ft"].to_numpy()[kept] / fn, **dot)
    n, duration = len(solution.event_array), float(np.diff(solution.event_array[i, :2])[0])
    ax_v.set_title(f"event {i + 1} of {n}: t = {start:.6g} s, {duration * 1e3:.3g} ms long",
                   fontsize=10)
    ax_v.set_ylabel("slip rate v (m/s)")
    ax_v.legend(loc="best", fontsize=7)
    ax_mu.set_xlabel("time since the event began (ms)")
    ax_mu.set_ylabel("friction")
    ax_mu.legend(loc="best", fontsize=7)


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

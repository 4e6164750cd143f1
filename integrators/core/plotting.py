"""A figure of one solve (:meth:`integrators.core.solution.Solution.plot`): the slip rate on a
log scale and μ = Fs/Fn against time, events marked. Matplotlib is imported only here."""

from __future__ import annotations

import os

import numpy as np

__all__ = ["plot_run", "draw_rate_and_friction", "check_figure_path"]


def check_figure_path(path):
    """``path`` if a figure can be written there: None (no file), a file name (str or
    path-like) whose suffix matplotlib writes (.png, .pdf, .svg, ...), or an open binary file;
    else one ``ValueError`` line naming the parameter, its value and what is accepted, before
    any work."""
    if path is None or (hasattr(path, "write") and not isinstance(path, (str, bytes))):
        return path
    accepted = "a file name ending in .png, .pdf or .svg (or None: no file)"
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be {accepted}, got {path!r} ({type(path).__name__})")
    suffix = os.path.splitext(os.fspath(path))[1].lower().lstrip(".")
    from matplotlib.backend_bases import FigureCanvasBase
    if suffix not in FigureCanvasBase.get_supported_filetypes():
        raise ValueError(f"path must be {accepted}, got {os.fspath(path)!r}"
                         + (f" (matplotlib does not write .{suffix})" if suffix else
                            " (no suffix)"))
    return path


def plot_run(sol, path=None, title: str | None = None):
    """Two panels of ``sol`` (a :class:`~integrators.core.solution.Solution`, drawn as given:
    :meth:`~integrators.core.solution.Solution.plot` passes the run with its events resolved);
    written to ``path`` (.png, .pdf or .svg) when given (:func:`check_figure_path`). Returns the
    matplotlib Figure."""
    check_figure_path(path)
    import matplotlib.pyplot as plt
    p = sol.problem
    fig, (ax_v, ax_mu) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True, layout="constrained")
    draw_rate_and_friction(sol, ax_v, ax_mu)
    fig.suptitle(title or f"{p.name or 'problem'}: {sol.algorithm.name}, {sol.retcode.value}, "
                          f"{len(sol.event_array)} events", fontsize=11)
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig


def draw_rate_and_friction(sol, ax_v, ax_mu) -> None:
    """The two time panels of a run on the given axes: the slip rate (log) with the slow
    loading speed and each event's start marked, and μ = Fs/Fn."""
    ax_v.semilogy(sol.t, sol.v, lw=0.8, color="C0")
    ax_v.axhline(sol.problem.loading.v_slow, color="0.6", lw=0.6, ls="--",
                 label="slow loading speed")
    ax_v.set_ylabel("slip rate v (m/s)")
    ax_v.legend(loc="lower right", fontsize=8)
    for t0 in np.asarray(sol.event_array)[:, 0]:
        ax_v.axvline(t0, color="C3", lw=0.4, alpha=0.4)
    ax_mu.plot(sol.t, sol.mu, lw=0.8, color="C1")
    ax_mu.set_xlabel("time t (s)")
    ax_mu.set_ylabel(r"$\mu = F_s/F_n$")

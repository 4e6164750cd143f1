"""Figures of a run: slip rate and μ against time, and the friction–slip-rate phase portrait
(like Fig. 18 of Urata et al. 2017)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

__all__ = ["plot_solution"]


def plot_solution(solution, path, title: str | None = None) -> None:
    """Write a three-panel PNG of ``solution`` to ``path``."""
    p = solution.problem
    fig = plt.figure(figsize=(11, 6.5), layout="constrained")
    grid = fig.add_gridspec(2, 2, width_ratios=(1.6, 1))
    ax_v = fig.add_subplot(grid[0, 0])
    ax_mu = fig.add_subplot(grid[1, 0], sharex=ax_v)
    ax_ph = fig.add_subplot(grid[:, 1])

    ax_v.semilogy(solution.t, solution.v, lw=0.8, color="C0")
    ax_v.axhline(p.loading.v_slow, color="0.6", lw=0.6, ls="--", label="slow loading speed")
    ax_v.set_ylabel("slip rate v (m/s)")
    ax_v.legend(loc="lower right", fontsize=8)
    for t0 in solution.events["t_start"]:
        ax_v.axvline(t0, color="C3", lw=0.4, alpha=0.4)

    ax_mu.plot(solution.t, solution.mu, lw=0.8, color="C1")
    ax_mu.set_xlabel("time t (s)")
    ax_mu.set_ylabel(r"$\mu = F_s/F_n$")

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
    fig.savefig(path, dpi=110)
    plt.close(fig)

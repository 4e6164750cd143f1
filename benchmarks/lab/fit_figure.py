"""The figure of ``rsfbench lab fit``: the record and the fit against the load point's
travel, the residuals below, and each profile in its own panel.

It is drawn in two parts: :class:`FitFigure` draws the record, the fit and the residuals as
soon as the fit is made (``lab fit`` does so while other processes take the profiles, and
matplotlib's import with it) and lays out the profiles' panels empty;
:meth:`FitFigure.finish` draws the profiles into them when they are back."""

from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure

from benchmarks.lab.figures import envelope
from benchmarks.records.report import literal

__all__ = ["FitFigure"]

#: Δ squares / (f σ²) of a profile's 95 % interval (χ² of one degree of freedom)
CHI2_95 = 3.841


class FitFigure:
    """The figure of ``fit`` (a :class:`~benchmarks.lab.fit.LabFit`), laid out, with an
    empty panel below for the profile of each of ``names`` (none: no row of panels)."""

    def __init__(self, fit, names=()):
        rec = fit.model.record
        panels = len(names)
        cols = max(panels, 1)
        self.figure = fig = Figure(figsize=(max(8, 2.6 * cols), 7.6 if panels else 5.6))
        grid = fig.add_gridspec(3 if panels else 2, cols,
                                height_ratios=[3, 1.4, 2][:2 + bool(panels)])
        x = rec.load_point * 1e6
        ax = fig.add_subplot(grid[0, :])
        states = "" if fit.model.states == 1 else ", two state variables"
        ax.plot(*envelope(x, rec.mu), lw=0.5, color="0.6", label="record")
        ax.plot(*envelope(x, fit.mu_model), lw=1.2, color="C3",
                label=f"fit ({fit.model.law} law{states})")
        for s in rec.switch_times:
            ax.axvline(float(x[min(int((rec.t < s).sum()), len(x) - 1)]), color="k", lw=0.5,
                       ls=":")
        ax.set_ylabel("μ")
        ax.legend(fontsize=8)
        ax = fig.add_subplot(grid[1, :])
        ax.plot(*envelope(x, rec.mu - fit.mu_model), lw=0.5, color="C0")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel("residual")
        ax.set_xlabel("load-point displacement (µm)")
        fig.suptitle(literal(Path(rec.source).name), fontsize=9)
        self.axes = [self._panel(fig.add_subplot(grid[2, j]), j, name)
                     for j, name in enumerate(names)]
        # laid out now, with the profiles' panels empty: their data change no label's size
        fig.tight_layout()

    @staticmethod
    def _panel(ax, j: int, name: str):
        """A profile's empty panel: its axes, labels and the 95 % level."""
        from benchmarks.lab.fit import _LOG
        ax.axhline(CHI2_95, color="k", lw=0.5, ls="--")
        if name in _LOG:
            ax.set_xscale("log")
        ax.set_ylim(0, 10)
        ax.set_xlabel(f"{name}{' (µm)' if name in ('dc', 'dc2') else ''}", fontsize=8)
        ax.tick_params(labelsize=7)
        if j == 0:
            ax.set_ylabel("Δ squares / (f σ²)", fontsize=8)
        return ax

    def finish(self, profiles: dict) -> Figure:
        """The figure with ``profiles`` (name → a
        :class:`~benchmarks.lab.profile_intervals.LabProfile`, in the order of the panels'
        names) drawn."""
        if len(profiles) != len(self.axes):
            raise ValueError(f"{len(profiles)} profiles for {len(self.axes)} panels")
        for ax, (name, prof) in zip(self.axes, profiles.items()):
            scale = 1e6 if name in ("dc", "dc2") else 1.0
            ax.plot(prof.points[name] * scale, prof.points.delta, "o-", ms=2.5, color="C2")
            ax.axvline(prof.value * scale, color="C3", lw=0.6)
        return self.figure

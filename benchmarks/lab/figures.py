"""The figure of ``rsfbench observe``: the recording with its events marked, the metrics event by
event, and the slip-weakening curves."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from benchmarks.records.files import write_figure
from benchmarks.records.report import literal

__all__ = ["plot_recording", "envelope"]

#: samples drawn of the record at most (a 4-million-row record is drawn from every k-th)
MAX_DRAWN = 50_000


def envelope(x, y, most: int = 4000):
    """``(x, y)`` to draw as a line of at most ``most`` points: in each of ``most`` // 2 runs
    of consecutive samples, the lowest and the highest in their order, so that a glitch or the
    noise's band looks as it does drawn whole (a line of 75,000 samples took most of a
    second to draw at the figure's resolution)."""
    x, y = np.asarray(x), np.asarray(y)
    bins = most // 2
    if len(y) <= most or bins < 1:
        return x, y
    edges = np.linspace(0, len(y), bins + 1).astype(np.int64)
    keep = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        part = y[lo:hi]
        keep.extend(sorted({lo + int(np.argmin(part)), lo + int(np.argmax(part))}))
    keep = np.asarray(keep)
    return x[keep], y[keep]


def plot_recording(rec, analysis, path) -> Path:
    """Write the figure of ``analysis`` (:class:`~benchmarks.lab.events.Analysis`)
    of the recording ``rec`` to ``path`` (PNG)."""
    ev = analysis.events
    has_curves = analysis.curves is not None and len(analysis.curves)
    fig = Figure(figsize=(9, 9 if has_curves else 6.5), constrained_layout=True)
    axes = fig.subplots(3 if has_curves else 2, 1)
    step = max(1, len(rec.t) // MAX_DRAWN)
    mu = rec["shear_force"] / rec["normal_force"]
    ax = axes[0]
    ax.plot(rec.t[::step], mu[::step], lw=0.5, color="0.3")
    for t0 in ev.t_start:
        ax.axvline(t0, color="tab:red", lw=0.6, alpha=0.6)
    ax.set(xlabel="time (s)", ylabel="Fs/Fn",
           title=f"{literal(Path(rec.source).name)}: {len(ev)} complete events (red: their "
                 "starts)")
    ax = axes[1]
    ax.plot(ev.t_start, ev.recurrence_s, "o-", ms=3, color="tab:blue")
    ax.set(xlabel="event start (s)", ylabel="ΔT (s)")
    ax.tick_params(axis="y", colors="tab:blue")
    twin = ax.twinx()
    twin.plot(ev.t_start, ev.friction_drop, "s-", ms=3, color="tab:orange")
    twin.set_ylabel("Δμ")
    twin.tick_params(axis="y", colors="tab:orange")
    ax.set_title(f"ΔT = {ev.recurrence_s.mean():.4g} ± {ev.recurrence_s.std():.2g} s, "
                 f"Δμ = {ev.friction_drop.mean():.4g} ± {ev.friction_drop.std():.2g} "
                 "(mean ± standard deviation)")
    if has_curves:
        ax = axes[2]
        for _, g in analysis.curves.groupby("event_id"):
            ax.plot(g.slip_m * 1e6, g.friction, lw=0.6, alpha=0.7)
        ax.set(xlabel="slip since the event started (µm)", ylabel="Ft/Fn = (Fs − m·a)/Fn",
               title="slip-weakening curves, one per event")
    path = Path(path)
    write_figure(fig, path, dpi=110)
    return path

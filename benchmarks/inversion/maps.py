"""Maps of a sweep over (b, log Lc), drawn like Urata et al. (2017) Figs. 8 and 10a.

Colour: the simulated recurrence interval ΔT, friction drop Δμ, J1 and (with slip-weakening
curves) J. Marks: gray circles, stable sliding; crosses, multiple recurrence; dots, not converged
(run longer); red x, failed;
open diamonds, the 95 % region J1 ≤ 5.99 (on the J panel: the possible range J ≤ 2α1); a star,
the best point; a white plus, a reference point such as the published best fit.
"""

from __future__ import annotations

import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from benchmarks.records.files import write_figure

__all__ = ["plot_sweep"]

_PANELS = (("recurrence_s", "ΔT (s)", False), ("friction_drop", "Δμ", False),
           ("J1", "J1", True), ("J", "J", True))


def plot_sweep(table, path, title: str = "", mark=None, best=None,
               mark_label: str = "published") -> None:
    """Write the maps of ``table`` (a sweep table) to ``path``. ``mark`` = (b, Lc in m) is drawn
    as a reference point labelled ``mark_label``; ``best`` = (b, Lc) as the star."""
    # no limit cycle anywhere in the grid: one panel of the classes alone
    panels = ([p for p in _PANELS if p[0] in table and table[p[0]].notna().any()]
              or [(None, "no limit cycle in the grid", False)])
    fig = Figure(figsize=(4.2 * max(len(panels), 1), 3.8), constrained_layout=True)
    axes = fig.subplots(1, max(len(panels), 1), squeeze=False)
    b = table.b.to_numpy()
    y = np.log10(table.lc_m.to_numpy() * 1e6)
    for ax, (col, label, log) in zip(axes[0], panels):
        if col is None:
            _classes(ax, table, b, y)
            ax.set(xlabel="b", ylabel="log10 Lc (µm)", title=label)
            continue
        z = table[col].to_numpy(dtype=float)
        ok = np.isfinite(z) & (z > 0 if log else True)
        norm = LogNorm(vmin=max(np.nanmin(z[ok]), 1e-3), vmax=np.nanmax(z[ok])) if log and ok.any() else None
        sc = ax.scatter(b[ok], y[ok], c=z[ok], s=_size(b, y), marker="s", norm=norm,
                        cmap="viridis_r" if log else "viridis", linewidths=0)
        fig.colorbar(sc, ax=ax, label=label)
        region = table["possible" if col == "J" else "in_region"].to_numpy(dtype=bool)
        ax.scatter(b[region], y[region], s=14, marker="D", facecolors="none", edgecolors="w",
                   linewidths=0.8, label="J ≤ 2α1" if col == "J" else "J1 ≤ 5.99 (95 %)")
        _classes(ax, table, b, y)
        if best is not None:
            ax.scatter([best[0]], [np.log10(best[1] * 1e6)], marker="*", s=160, c="gold",
                       edgecolors="k", label="best", zorder=5)
        if mark is not None:
            ax.scatter([mark[0]], [np.log10(mark[1] * 1e6)], marker="P", s=90, c="w",
                       edgecolors="k", label=mark_label, zorder=5)
        ax.set_xlabel("b")
        ax.set_ylabel("log10 Lc (µm)")
        ax.set_title(label)
    if axes[0][0].get_legend_handles_labels()[0]:
        axes[0][0].legend(fontsize=6, loc="lower right")
    if title:
        fig.suptitle(title)
    write_figure(fig, path, dpi=110)


#: the marks of the runs that are not a limit cycle, by classification
_CLASS_MARKS = (("stable sliding", dict(marker="o", c="0.6", s=10)),
                ("multiple recurrence", dict(marker="+", c="k", s=18)),
                ("oscillation about vL", dict(marker="^", c="tab:purple", s=12)),
                ("not converged", dict(marker=".", c="0.3", s=10)),
                ("too short to classify", dict(marker="v", c="tab:orange", s=12)),
                ("failed", dict(marker="x", c="r", s=18)))


def _classes(ax, table, b, y) -> None:
    """Every class but stick-slip (the colours), each with its mark (a class without one: a
    small star)."""
    marks = dict(_CLASS_MARKS)
    for cls in sorted(set(table.classification.dropna()) - {"stick-slip"}):
        sel = (table.classification == cls).to_numpy()
        ax.scatter(b[sel], y[sel], label=cls,
                   **marks.get(cls, dict(marker="*", c="tab:brown", s=14)))


def _size(b, y) -> float:
    """Marker area that roughly tiles the grid."""
    nb, ny = max(len(np.unique(b)), 1), max(len(np.unique(y)), 1)
    return max(8.0, 9000.0 / max(nb, ny) ** 2)

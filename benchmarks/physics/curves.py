"""Slip-weakening curves: a run's, and the files observed ones are read from.

Slip-weakening curves (observed or synthetic) are CSV files with one row per sample and the
columns ``event_id`` (any label; rows of one event together), ``slip_m`` (slip since the start
of that event, m) and ``friction`` (the shear force on the fault over the normal force, Ft/Fn).
The synthetic curve of a simulation is its last complete event: the friction Ft/Fn against the
slip since the event started; it is linearly interpolated at the observed slips and held at its
end values outside its range (before the event the fault is stuck, after it the slip no longer
grows).

Why friction and not the spring force: Eq. 11 compares "the shear force divided by the normal
force", which the experiments estimate as Ft = Fs − m·a. The spring force against slip is, during
an event, the spring's unloading line Fs = Fs0 − k·slip (+ the slow load-point motion), of slope
−k/Fn whatever (b, Lc): a J2 on Fs/Fn carries almost no information on the friction law. Ft/Fn
against slip is the slip-weakening curve itself, whose shape (the weakening distance ∝ Lc, the
drop ∝ b − a) is what J2 constrains.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.records.files import read_table, write_table

__all__ = ["CURVE_COLUMNS", "read_curves", "check_curves", "write_curves", "event_curve",
           "event_window", "sample_curves"]

CURVE_COLUMNS = ("event_id", "slip_m", "friction")


def read_curves(path) -> pd.DataFrame:
    """Observed slip-weakening curves from a CSV with :data:`CURVE_COLUMNS` (see the module doc),
    or ``ValueError`` naming the file and what is wrong (:func:`check_curves`).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Returns
    -------
    pandas.DataFrame
        ``event_id``, ``slip_m`` (m), ``friction`` (dimensionless).

    Raises
    ------
    ValueError
        Naming the file and what is wrong.
    """
    df = read_table(path, CURVE_COLUMNS, what="slip-weakening file",
                    hint="it needs the columns event_id, slip_m (m), friction (Ft/Fn)")
    return check_curves(df, f"slip-weakening file {path}")


def check_curves(df, source: str = "slip-weakening curves") -> pd.DataFrame:
    """``df`` as curves (:data:`CURVE_COLUMNS`, numbers finite, every event_id given, at least
    two samples per event), or ``ValueError`` naming ``source`` and what is wrong.

    Parameters
    ----------
    df : pandas.DataFrame
        The curves: ``event_id``, ``slip_m`` (m), ``friction`` (dimensionless).
    source : str
        What the curves are, for messages.

    Returns
    -------
    pandas.DataFrame
        The curves, checked.

    Raises
    ------
    ValueError
        Naming ``source`` and what is wrong.
    """
    if not isinstance(df, pd.DataFrame):
        raise ValueError(f"{source} must be a DataFrame with columns {list(CURVE_COLUMNS)}, "
                         f"got {type(df).__name__}")
    missing = [c for c in CURVE_COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(f"{source} lacks the columns {missing}; it needs {list(CURVE_COLUMNS)}")
    df = df[list(CURVE_COLUMNS)].copy()
    for c in ("slip_m", "friction"):
        values = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(values)
        if bad.any():
            raise ValueError(f"{source}: column {c} is not a finite number in row "
                             f"{int(np.argmax(bad)) + 2}")
        df[c] = values
    if df.event_id.isna().any():
        raise ValueError(f"{source}: event_id is empty in row "
                         f"{int(np.argmax(df.event_id.isna().to_numpy())) + 2}")
    sizes = df.groupby("event_id", sort=False).size()
    if len(sizes) == 0 or (sizes < 2).any():
        first = sizes.index[sizes < 2][0] if len(sizes) else None
        raise ValueError(f"{source}: " + (f"event {first!r} has fewer than two samples"
                                           if len(sizes) else "no curve"))
    return df


def write_curves(df: pd.DataFrame, path) -> None:
    """Write the curves to ``path`` (CSV), never over a file of the user's
    (:func:`benchmarks.records.files.writing`).

    Parameters
    ----------
    df : pandas.DataFrame
        The curves (:data:`CURVE_COLUMNS`).
    path : str or pathlib.Path
        The CSV file.
    """
    write_table(df[list(CURVE_COLUMNS)], path)


def event_curve(sol, index: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """Synthetic slip-weakening curve of event ``index`` (default: the last complete one): the
    friction Ft/Fn against the slip since the event started (module docstring).

    Uses the saved trajectory, so solve with a ``save_every`` that resolves the event. The slip
    since the event started is Δu = vL·(t − t_start) − ΔFs/k, exact for the spring with the load
    point at its slow speed (the fast phase of two-speed loading starts when an event ends).
    Returns empty arrays when the run has no complete event.

    Parameters
    ----------
    sol : Solution
        A run saved finely enough to resolve the event.
    index : int
        The event's row in ``sol.events``.

    Returns
    -------
    slip : numpy.ndarray
        The slip since the event started (m).
    friction : numpy.ndarray
        Ft/Fn (dimensionless).
    """
    if not len(sol.events):
        return np.empty(0), np.empty(0)
    t, slip, _ = event_window(sol, index)
    return slip, np.interp(t, sol.t, sol.ft) / sol.problem.normal_force


def event_window(sol, index: int = -1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The saved times inside event ``index`` with its start and end, the slip since its start
    at those times (exact: see :func:`event_curve`) and the spring force there (N)."""
    ev = sol.events.iloc[index]
    p = sol.problem
    inside = (sol.t > ev.t_start) & (sol.t < ev.t_end)
    t = np.concatenate(([ev.t_start], sol.t[inside], [ev.t_end]))
    fs = np.interp(t, sol.t, sol.fs)
    return t, p.loading.v_slow * (t - t[0]) - (fs - fs[0]) / p.stiffness, fs


def sample_curves(sol, n_events: int = 3, n_points: int = 25, noise: float = 0.0,
                  seed: int = 0, curve=event_curve, spacing: str = "slip") -> pd.DataFrame:
    """Curves in the format of :func:`read_curves` from the last ``n_events`` events of ``sol``
    (``curve(sol, index)``: :func:`event_curve` by default), each sampled at ``n_points`` points
    inside the event, plus Gaussian noise of std ``noise``. ``spacing="slip"``: at (j + ½)/n of
    its total slip; ``"time"``: at (j + ½)/n of its duration, as a recorder samples (many points
    at the slow start, where the weakening over a few Lc happens), from the saved trajectory
    (save finely). Not at the ends: there the curve is vertical (the friction changes while the
    slip does not), where a sample would weigh the slip at which a curve ends, not its shape.

    Parameters
    ----------
    sol : Solution
        The run.
    n_events, n_points : int
        The events taken (the last ones) and the samples per event.
    noise : float
        σ of the Gaussian noise on the friction (dimensionless).
    seed : int
        The random generator's seed.
    curve : callable
        ``curve(sol, index) -> (slip, friction)``.
    spacing : str
        ``"slip"`` or ``"time"``.

    Returns
    -------
    pandas.DataFrame
        ``event_id``, ``slip_m`` (m), ``friction``.
    """
    if spacing not in ("slip", "time"):
        raise ValueError(f"spacing must be 'slip' or 'time', got {spacing!r}")
    rng = np.random.default_rng(seed)
    frames = []
    for i in range(n_events):
        index = len(sol.events) - n_events + i
        slip, mu = curve(sol, index=index)
        if spacing == "slip":
            s = (np.arange(n_points) + 0.5) / n_points * slip[-1]
            f = np.interp(s, slip, mu)
        else:
            t, _, _ = event_window(sol, index)
            at = t[0] + (np.arange(n_points) + 0.5) / n_points * (t[-1] - t[0])
            s, f = np.interp(at, t, slip), np.interp(at, t, mu)
        frames.append(pd.DataFrame({"event_id": i + 1, "slip_m": s,
                                    "friction": f + noise * rng.standard_normal(n_points)}))
    return pd.concat(frames, ignore_index=True)

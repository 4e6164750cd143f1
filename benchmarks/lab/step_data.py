"""A laboratory velocity-step or slide-hold-slide record, read for a fit: the friction, the load
point, and the load point's history found in it.

Its columns are mapped to channels as for ``observe`` (``CHANNEL=COLUMN[:UNIT]``, converted to
SI on reading):

=================  =======  ======================================================================
channel            SI unit  what it is
=================  =======  ======================================================================
``time``           s        required: increasing (the sampling interval may change, as when a
                            machine samples faster after a step, but not jump)
``friction``       1        μ, the shear over the normal force; or else
``shear_force``    N        with ``normal_force`` (a column, or a constant in N)
``load_point``     m        the load point's displacement; or else
``load_velocity``  m/s      its velocity, each sample's held until the next (integrated)
=================  =======  ======================================================================

**The history** (the load point's speeds and switch times) is found in the displacement by
:func:`benchmarks.lab.history.find_history`. The record's time starts at 0 at its first
sample (the file's time there is kept as ``t_offset``); the fit starts from steady sliding at
the first piece's speed.

Refused in one line: what :func:`~benchmarks.lab.history.find_history` refuses (no
step, an opening hold, a load point too fast for its unit or moving back), a friction no
friction coefficient has (a percentage, a force in kN read as N), a gap in the times, besides
what every recording is refused for (missing or non-numeric values, times that do not
increase).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.lab.channels import MU_RANGE, UNITS, column_map, column_values, read_table
from benchmarks.lab.history import MIN_SAMPLES, find_history
from problems._validate import units_checked_already
from problems.loading import LoadHistory

__all__ = ["LabRecord", "read_lab_record", "lab_record_from", "LAB_CHANNELS"]

#: each channel of a laboratory record and its SI unit
LAB_CHANNELS = {"time": "s", "friction": "1", "shear_force": "N", "normal_force": "N",
                "load_point": "m", "load_velocity": "m/s"}


@dataclass(frozen=True)
class LabRecord:
    """A record in SI units, its time from 0 at the first sample: ``t`` (s), ``mu``, the
    ``load_point`` displacement (m, from 0), and the history found in it: ``velocities`` (m/s)
    between ``switch_times`` (s), one more velocity than switch times; ``pieces`` has each
    piece's fitted speed and its standard error
    (:data:`~benchmarks.lab.history.PIECE_COLUMNS`). ``t_offset`` is the
    file's time of the first sample; ``source``, ``sha256`` and ``columns`` say where it came
    from.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times from 0 (s).
    mu : numpy.ndarray
        The friction coefficient (dimensionless).
    load_point : numpy.ndarray
        The load point's displacement from 0 (m).
    velocities : tuple of float
        The history's velocities (m/s).
    switch_times : tuple of float
        The history's switch times (s).
    pieces : pandas.DataFrame
        Each piece's fitted speed (m/s) and its standard error.
    t_offset : float
        The file's time of the first sample (s).
    source, sha256 : str
        The file and its hash.
    columns : dict
        Each channel's column in the file.
    file_t : numpy.ndarray or None
        The file's times of the samples (s) when ``t`` runs on another clock
        (:mod:`benchmarks.lab.clock`); None when ``t + t_offset`` is the file's time.
    """

    t: np.ndarray = field(repr=False)
    mu: np.ndarray = field(repr=False)
    load_point: np.ndarray = field(repr=False)
    velocities: tuple
    switch_times: tuple
    pieces: pd.DataFrame = field(repr=False)
    t_offset: float = 0.0
    source: str = "table"
    sha256: str = ""
    columns: dict = field(default_factory=dict)
    file_t: np.ndarray | None = field(default=None, repr=False)

    @property
    def history(self):
        """The load point's history as a :class:`problems.loading.LoadHistory`."""
        with units_checked_already():       # a record's speeds are what they are
            return LoadHistory(velocities=tuple(self.velocities),
                               switch_times=tuple(self.switch_times))

    def file_time(self, s):
        """The file's time (s) of the record's time ``s`` (s from its first sample, on the
        model's clock): ``s + t_offset``, or on another clock (``file_t``) interpolated between
        the samples."""
        if self.file_t is None:
            return np.asarray(s, dtype=float) + self.t_offset
        return np.interp(s, self.t, self.file_t)

    def piece_index(self) -> np.ndarray:
        """The piece of the history each sample is in (a switch time belongs to the piece after
        it)."""
        return np.searchsorted(np.asarray(self.switch_times), self.t, side="right")


def read_lab_record(path, columns, normal_force: float | None = None,
                    window: tuple[float, float] | None = None) -> LabRecord:
    """The record in ``path`` with ``columns`` (channel → ``(column, unit)`` or specs
    ``CHANNEL=COLUMN[:UNIT]``); ``normal_force`` (N) stands for a normal-force column;
    ``window`` = (start, end) in the file's time (s) keeps that part only.

    Parameters
    ----------
    path : str or pathlib.Path
        The record's file.
    columns : dict or list of str
        Channel → ``(column, unit)``, or specs ``CHANNEL=COLUMN[:UNIT]``.
    normal_force : float, optional
        The normal force (N), standing for a normal-force column.
    window : tuple of float, optional
        (start, end) in the file's time (s).

    Returns
    -------
    LabRecord

    Raises
    ------
    ValueError
        Naming the file and what is wrong with it or with the mapping.
    """
    mapping = _mapping(columns, normal_force)
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"record {path} does not exist" if not path.exists()
                         else f"record {path} is not a file")
    table = read_table(path, sorted({column for column, _ in mapping.values()}))
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    return lab_record_from(table, mapping, normal_force, window, source=str(path), sha256=digest)


def _mapping(columns, normal_force):
    mapping = column_map(columns, LAB_CHANNELS, required=("time",))
    if ("friction" in mapping) == ("shear_force" in mapping):
        raise ValueError("map the friction channel (μ) or the shear_force channel (with the "
                         "normal force), one of them")
    if "shear_force" in mapping and "normal_force" not in mapping and normal_force is None:
        raise ValueError("a shear_force needs the normal force: map a normal_force column, or "
                         "give the constant normal force (N)")
    if "friction" in mapping and ("normal_force" in mapping or normal_force is not None):
        raise ValueError("the friction channel is μ already: a normal force is not needed")
    if ("load_point" in mapping) == ("load_velocity" in mapping):
        raise ValueError("map the load_point channel (displacement) or the load_velocity "
                         "channel, one of them")
    return mapping


def lab_record_from(table: pd.DataFrame, columns, normal_force: float | None = None,
                    window: tuple[float, float] | None = None, source: str = "table",
                    sha256: str = "") -> LabRecord:
    """A :class:`LabRecord` of a DataFrame already in memory (the checks of
    :func:`read_lab_record`).

    Parameters
    ----------
    table : pandas.DataFrame
        The record's columns.
    columns, normal_force, window
        As :func:`read_lab_record`.
    source, sha256 : str
        Where the table came from, for messages and provenance.

    Returns
    -------
    LabRecord

    Raises
    ------
    ValueError
        As :func:`read_lab_record`."""
    mapping = _mapping(columns, normal_force)
    missing = [c for c, _ in mapping.values() if c not in table.columns]
    if missing:
        raise ValueError(f"{source} has no column {missing[0]!r}; its columns: "
                         f"{', '.join(map(str, table.columns))}")
    data = {channel: column_values(table[column], column, source) * UNITS[unit][1]
            for channel, (column, unit) in mapping.items()}
    names = {channel: column for channel, (column, _) in mapping.items()}
    t = data["time"]
    if window is not None:
        keep = _window(t, window, source)
        t, data = t[keep], {k: v[keep] for k, v in data.items()}
    _check_time(t, names["time"], source)
    if "friction" in data:
        mu = data["friction"]
    else:
        fn = data["normal_force"] if "normal_force" in data else normal_force
        if not np.all(np.asarray(fn) > 0):
            raise ValueError(f"{source}: the normal force must be positive (N)")
        mu = data["shear_force"] / fn
    median = float(np.median(mu))
    if not MU_RANGE[0] <= median <= MU_RANGE[1]:
        what = names.get("friction") or names["shear_force"]
        raise ValueError(f"{source}: column {what!r} gives a friction coefficient of "
                         f"{median:.4g} (median): no friction coefficient is; a unit is off "
                         "(a percentage, or a force in kN read as N)")
    if "load_point" in data:
        x = data["load_point"]
    else:
        v = data["load_velocity"]
        # a speed holds over its sample's interval, as a commanded speed does (a trapezoid
        # would put each switch half a sample early)
        x = np.concatenate(([0.0], np.cumsum(v[:-1] * np.diff(t))))
    t0 = float(t[0])
    t, x = t - t0, x - x[0]
    channel = names.get("load_point") or names["load_velocity"]
    velocities, switches, pieces = find_history(t, x, what=f"{source}: the load point "
                                                f"({channel!r})", t_offset=t0)
    return LabRecord(t=t, mu=np.asarray(mu, dtype=float), load_point=x, velocities=velocities,
                     switch_times=switches, pieces=pieces, t_offset=t0, source=source,
                     sha256=sha256, columns=names)


def _check_time(t: np.ndarray, column: str, source: str) -> None:
    d = np.diff(t)
    if (d <= 0).any():
        i = int(np.argmax(d <= 0)) + 1
        raise ValueError(f"{source}: column {column!r} row {i + 2}: t = {t[i]:.9g} s after "
                         f"t = {t[i - 1]:.9g} s: times must increase")
    # a gap: far longer than the sampling on both sides of it
    step = pd.Series(d).rolling(21, center=True, min_periods=1).median().to_numpy()
    gap = d > 20 * np.minimum(np.roll(step, 1), np.roll(step, -1))
    gap[[0, -1]] = False
    if gap.any():
        i = int(np.argmax(gap))
        raise ValueError(f"{source}: column {column!r}: a gap of {d[i]:.6g} s after row {i + 2} "
                         f"(t = {t[i]:.9g} s): cut the record there, or fill the gap")


def _window(t, window, source):
    try:
        start, end = (float(w) for w in window)
    except (TypeError, ValueError):
        raise ValueError(f"window must be (start, end) in s, got {window!r}") from None
    if not start < end:
        raise ValueError(f"window ({start:g}, {end:g}) s: its start must come before its end")
    keep = (t >= start) & (t <= end)
    if keep.sum() < 2 * MIN_SAMPLES:
        raise ValueError(f"{source}: window ({start:g}, {end:g}) s holds {int(keep.sum())} "
                         f"samples (the record runs from {t[0]:.9g} to {t[-1]:.9g} s)")
    return keep

"""A laboratory recording, read and checked before anything is measured on it.

A recording is a table of samples (CSV, or Parquet with the ``ensemble`` extra) whose columns are
mapped to **channels**, each in a stated unit and converted to SI on reading:

=====================  ========  ==================================================================
channel                SI unit   what it is
=====================  ========  ==================================================================
``time``               s         required: strictly increasing, evenly sampled
``shear_force``        N         required (or one of the next two): the load cell's force, the
                                 spring force Fs
``shear_stress``       Pa        instead of ``shear_force``: Fs = τ × ``area``
``friction``           1         instead of ``shear_force``: Fs/Fn, dimensionless; Fs = μ × Fn
``normal_force``       N         a column, or the constant ``normal_force`` of the apparatus
``normal_stress``      Pa        instead of ``normal_force``: Fn = σn × ``area``
``acceleration``       m/s²      the slider's (the upper specimen's, a1)
``acceleration_lower`` m/s²      the lower specimen's (a2): the slip accelerates at a1 − a2
``slip``               m         the fault's slip, from a displacement transducer across it
``table``              m         the load point's position (the shaking table, the actuator)
=====================  ========  ==================================================================

A column is named with its unit as ``CHANNEL=COLUMN:UNIT`` (the unit defaults to the SI one):
``shear_force=Load:kN``, ``slip=LDT:mm``, ``acceleration=a1:g``. Units: s, ms, µs (us); N, kN,
MN; Pa, kPa, MPa; m, mm, µm (um), nm; m/s2, mm/s2, g; 1 (dimensionless). The unit is what
follows the column's last colon when it is one of these (a column's own name may hold colons
and brackets: ``onset=event_starttime[s]:s``). A stress is a force only with the fault's area
(``area``, m²): a stress channel without it is refused.

What is refused before any measure, in one line naming the column and the row: a column that is
missing or not a number, missing values (a run of NaN), times that do not increase, repeat, jump
(a gap of over 1.5 sampling intervals) or are unevenly sampled, a time column of dates or
durations (give seconds), a force or an acceleration clipped at its extreme (a saturated sensor:
two separate runs of ``SATURATED_RUN`` samples or more at the channel's largest or smallest value,
inside the record), and a shear force whose ratio to the normal force no friction coefficient
has (one of them in another unit). Other units slips are caught where two channels measure the
same thing (:mod:`benchmarks.lab.events`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np
import pandas as pd

from problems._validate import check_positive

__all__ = ["CHANNELS", "SHEAR_CHANNELS", "NORMAL_CHANNELS", "UNITS", "Recording", "read_recording", "column_spec", "explicit_unit",
           "recording_from", "column_map", "read_table", "column_values"]

#: each channel and its SI unit
CHANNELS = {"time": "s", "shear_force": "N", "shear_stress": "Pa", "friction": "1",
            "normal_force": "N", "normal_stress": "Pa", "acceleration": "m/s2",
            "acceleration_lower": "m/s2", "slip": "m", "table": "m"}
#: the channels that can stand for the shear force, and for the normal force (one of each)
SHEAR_CHANNELS = ("shear_force", "shear_stress", "friction")
NORMAL_CHANNELS = ("normal_force", "normal_stress")
#: a unit: the SI unit it converts to and its factor
UNITS = {"s": ("s", 1.0), "ms": ("s", 1e-3), "us": ("s", 1e-6), "µs": ("s", 1e-6),
         "N": ("N", 1.0), "kN": ("N", 1e3), "MN": ("N", 1e6),
         "Pa": ("Pa", 1.0), "kPa": ("Pa", 1e3), "MPa": ("Pa", 1e6),
         "m": ("m", 1.0), "mm": ("m", 1e-3), "um": ("m", 1e-6), "µm": ("m", 1e-6),
         "nm": ("m", 1e-9), "m/s2": ("m/s2", 1.0), "m/s^2": ("m/s2", 1.0),
         "mm/s2": ("m/s2", 1e-3), "g": ("m/s2", 9.80665),
         "m/s": ("m/s", 1.0), "mm/s": ("m/s", 1e-3), "um/s": ("m/s", 1e-6),
         "µm/s": ("m/s", 1e-6), "1": ("1", 1.0)}
#: a friction coefficient Fs/Fn beyond these is a unit slip (kN against N is 10³ off)
MU_RANGE = (0.01, 3.0)
#: samples at a channel's extreme value in a row, in two separate places, that make it saturated
#: (one such run is a peak of a quantised signal that is flat within one step)
SATURATED_RUN = 20
#: the channels that clip (a slip or a table position is at its extremes at the record's ends,
#: a held normal force all along)
_CLIPPED = ("shear_force", "acceleration", "acceleration_lower")


@dataclass(frozen=True)
class Recording:
    """Samples in SI units: ``t`` (s) and one array per channel in ``channels``; ``columns``
    names each channel's column in the file (for messages), ``source`` the file and ``sha256``
    its hash. ``normal_force`` is a channel array even when the apparatus gave a constant.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times (s).
    channels : dict of str to numpy.ndarray
        Each channel's samples in SI units (:data:`UNITS`).
    columns : dict of str to str
        Each channel's column in the file.
    source, sha256 : str
        The file and its hash.
    """

    t: np.ndarray = field(repr=False)
    channels: dict = field(repr=False)
    columns: dict
    source: str
    sha256: str = ""

    @property
    def rate(self) -> float:
        """Samples per second."""
        return float((len(self.t) - 1) / (self.t[-1] - self.t[0]))

    @property
    def dt(self) -> float:
        return 1.0 / self.rate

    def has(self, channel: str) -> bool:
        return channel in self.channels

    def __getitem__(self, channel: str) -> np.ndarray:
        return self.channels[channel]

    def where(self, channel: str) -> str:
        """How a message names a channel: its column and its channel."""
        column = self.columns.get(channel)
        return f"column {column!r} ({channel})" if column else channel


def column_spec(text: str, channels: dict | None = None) -> tuple[str, str, str]:
    """``CHANNEL=COLUMN[:UNIT]`` → (channel, column, unit), or ``ValueError`` naming what is
    wrong. A column's own name may hold a colon: only a known unit after the last one counts.
    ``channels``: channel → SI unit (default :data:`CHANNELS`)."""
    known = CHANNELS if channels is None else channels
    channel, sep, rest = str(text).partition("=")
    channel = channel.strip()
    if not sep or not rest:
        raise ValueError(f"column mapping {text!r}: expected CHANNEL=COLUMN[:UNIT] "
                         f"(channels: {', '.join(known)})")
    if channel not in known:
        raise ValueError(f"column mapping {text!r}: unknown channel {channel!r}; expected one "
                         f"of {', '.join(known)}")
    si = known[channel] if isinstance(known[channel], tuple) else (known[channel],)
    column, sep, unit = rest.rpartition(":")
    if not sep or unit not in UNITS:
        column, unit = rest, si[0]
    if UNITS[unit][0] not in si:
        units = ", ".join(u for u, (base, _) in UNITS.items() if base in si)
        raise ValueError(f"column mapping {text!r}: {unit} is not a unit of {channel} (in "
                         f"{' or '.join(si)}: {units})")
    return channel, column, unit


def explicit_unit(channel: str, column: str, unit: str,
                  channels: dict | None = None) -> tuple[str, str, str]:
    """(channel, column, unit) checked as :func:`column_spec` checks a spec, the unit given on
    its own (so that one none of ours is refused by name, not taken as part of the column's)."""
    if unit not in UNITS:
        raise ValueError(f"column {column!r} ({channel}): {unit!r} is not a known unit (units: "
                         f"{', '.join(UNITS)})")
    return column_spec(f"{channel}={column}:{unit}", channels)


def read_recording(path, columns, normal_force: float | None = None,
                   area: float | None = None) -> Recording:
    """The recording in ``path`` (``.csv``, ``.txt``, ``.tsv`` or ``.parquet``) with
    ``columns`` (channel → ``(column, unit)``, or specs ``CHANNEL=COLUMN:UNIT``), checked (see
    the module docstring); ``normal_force`` (N) stands for a normal-force column; ``area`` (m²)
    turns stress channels into forces.

    Parameters
    ----------
    path : str or os.PathLike
        The recording's file.
    columns : dict or list of str
        Channel → ``(column, unit)``, or specs ``CHANNEL=COLUMN:UNIT``.
    normal_force : float, optional
        The normal force (N), standing for a normal-force column.
    area : float, optional
        The fault's area (m²): a stress channel times it is a force.

    Returns
    -------
    Recording

    Raises
    ------
    ValueError
        Naming the file, column or row that is wrong.
    """
    if not isinstance(path, (str, PathLike)):
        raise ValueError(f"path must be the recording's file name (str or os.PathLike), got "
                        f"{path!r}")
    if columns is None or isinstance(columns, (str, bytes)):
        raise ValueError(f"columns must map channels to columns: a dict, or a list of "
                        f"'CHANNEL=COLUMN:UNIT' specs, got {columns!r}")
    mapping = column_map(columns)
    _check_force_channels(mapping, normal_force, area)       # before the file is read
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"recording {path} does not exist" if not path.exists()
                         else f"recording {path} is not a file")
    wanted = sorted({column for column, _ in mapping.values()})
    table = read_table(path, wanted)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    return recording_from(table, mapping, normal_force, source=str(path), sha256=digest,
                          area=area)


def recording_from(table: pd.DataFrame, columns, normal_force: float | None = None,
                   source: str = "table", sha256: str = "", area: float | None = None) -> Recording:
    """A :class:`Recording` of a DataFrame already in memory (the checks of
    :func:`read_recording`).

    Parameters
    ----------
    table : pandas.DataFrame
        The recording's columns.
    columns, normal_force, area
        As :func:`read_recording`.
    source, sha256 : str
        Where the table came from, for messages and provenance.

    Returns
    -------
    Recording

    Raises
    ------
    ValueError
        As :func:`read_recording`.
    """
    mapping = column_map(columns)
    _check_force_channels(mapping, normal_force, area)
    missing = [c for c, _ in mapping.values() if c not in table.columns]
    if missing:
        raise ValueError(f"{source} has no column {missing[0]!r}; its columns: "
                         f"{', '.join(map(str, table.columns))}")
    channels = {}
    for channel, (column, unit) in mapping.items():
        channels[channel] = column_values(table[column], column, source) * UNITS[unit][1]
    t = channels.pop("time")
    names = {channel: column for channel, (column, _) in mapping.items()}
    _check_time(t, names["time"], source)
    if normal_force is not None:
        channels["normal_force"] = np.full(len(t), check_positive("normal_force", normal_force))
    _forces(channels, names, area)
    for channel in _CLIPPED:
        if channel in names and channel in channels:
            _check_saturation(channels[channel], names[channel], channel, source)
    _check_friction(channels["shear_force"], channels["normal_force"], names, source)
    return Recording(t, channels, names, source, sha256)


def column_map(columns, channels: dict | None = None,
               required=("time", SHEAR_CHANNELS)) -> dict[str, tuple[str, str]]:
    """channel → (column, unit) from a dict (channel → column or (column, unit)) or specs
    ``CHANNEL=COLUMN[:UNIT]``, checked against ``channels`` (default :data:`CHANNELS`); the
    ``required`` channels must be mapped (an item that is a tuple: one of them)."""
    known = CHANNELS if channels is None else channels
    if isinstance(columns, dict):
        mapping = {}
        for channel, spec in columns.items():
            si = known.get(channel, "")
            column, unit = spec if isinstance(spec, tuple) else (
                spec, si[0] if isinstance(si, tuple) else si)
            channel, column, unit = explicit_unit(channel, column, unit, known)
            mapping[channel] = (column, unit)
    else:
        mapping = {}
        for spec in columns:
            channel, column, unit = column_spec(spec, known)
            if channel in mapping:
                raise ValueError(f"channel {channel} is mapped twice ({mapping[channel][0]!r} "
                                 f"and {column!r})")
            mapping[channel] = (column, unit)
    for need in required:
        options = need if isinstance(need, tuple) else (need,)
        if not any(c in mapping for c in options):
            raise ValueError(f"map a column to the {' or the '.join(options)} channel "
                             f"({options[0]}=COLUMN:UNIT)")
    return mapping


def read_table(path: Path, wanted: list[str]) -> pd.DataFrame:
    """The ``wanted`` columns of the table in ``path`` (CSV, TSV, TXT, DAT or Parquet)."""
    suffix = path.suffix.lower()
    try:
        if suffix == ".parquet":
            from benchmarks.records.optional import require
            require("pyarrow", "ensemble", "a Parquet recording")
            import pyarrow.parquet as pq
            names = pq.read_schema(path).names
            _has(wanted, names, path)
            return pd.read_parquet(path, columns=wanted)
        if suffix not in (".csv", ".txt", ".tsv", ".dat"):
            raise ValueError(f"recording {path}: expected a .csv, .txt, .tsv, .dat or .parquet "
                             "file")
        with open(path, encoding="utf-8", errors="replace") as f:
            header = f.readline()
        sep = "\t" if "\t" in header else ";" if header.count(";") > header.count(",") else ","
        # the names as pandas reads them (a quoted name loses its quotes)
        names = [str(n).strip() for n in pd.read_csv(path, sep=sep, nrows=0).columns]
        _has(wanted, names, path)
        return pd.read_csv(path, sep=sep, usecols=lambda n: n.strip() in wanted,
                           engine="c", skipinitialspace=True).rename(columns=str.strip)
    except (UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise ValueError(f"recording {path} is not a readable table "
                         f"({type(exc).__name__})") from None
    except OSError as exc:
        raise ValueError(f"recording {path} cannot be read: {exc.strerror or exc}") from None


def _check_force_channels(mapping: dict, normal_force, area) -> None:
    """One channel for each force, a normal force from somewhere, and an area for a stress:
    refused by name before the file is read."""
    for group in (SHEAR_CHANNELS, NORMAL_CHANNELS):
        both = [c for c in group if c in mapping]
        if len(both) > 1:
            raise ValueError(f"{both[0]} and {both[1]} are one force: map one column to one of "
                             f"{', '.join(group)}")
    given = [c for c in NORMAL_CHANNELS if c in mapping]
    if given and normal_force is not None:
        raise ValueError(f"the normal force is a column ({given[0]}) or a constant "
                         "(normal_force), not both")
    if not given and normal_force is None:
        raise ValueError("the normal force is needed: map a column to normal_force (N) or "
                         "normal_stress (Pa, with the area), or give the apparatus's constant "
                         "normal force (N) or normal stress (Pa, with the area)")
    if area is not None:
        check_positive("area", area)
    for channel in ("shear_stress", "normal_stress"):
        if channel in mapping and area is None:
            raise ValueError(f"column {mapping[channel][0]!r} ({channel}) is a stress: give "
                             "the fault's area in m² (--area M2) to make it a force (stress × "
                             "area)")


def _forces(channels: dict, names: dict, area) -> None:
    """The stress and friction channels made forces: Fs = τ·A or μ·Fn, Fn = σn·A (in place;
    ``names`` keeps each force's column, for messages)."""
    if "normal_stress" in channels:
        channels["normal_force"] = channels.pop("normal_stress") * area
        names["normal_force"] = names.pop("normal_stress")
    if "shear_stress" in channels:
        channels["shear_force"] = channels.pop("shear_stress") * area
        names["shear_force"] = names.pop("shear_stress")
    elif "friction" in channels:
        channels["shear_force"] = channels.pop("friction") * channels["normal_force"]
        names["shear_force"] = names.pop("friction")


def _has(wanted, names, path) -> None:
    missing = [c for c in wanted if c not in names]
    if missing:
        c = missing[0]
        unit = c.rsplit(":", 1)[1] if ":" in c else ""
        if unit.strip() and unit not in UNITS:      # COLUMN:UNIT, the unit none of ours
            raise ValueError(f"recording {path}: {unit!r} in {c!r} is not a known unit (units: "
                             f"{', '.join(UNITS)}) and the file has no column {c!r}")
        raise ValueError(f"recording {path} has no column {c!r}; its columns: "
                         f"{', '.join(names)}")


def _row(i: int) -> int:
    """The file's row of sample ``i`` (1-based, after the header line)."""
    return int(i) + 2


def column_values(series: pd.Series, column: str, source: str) -> np.ndarray:
    """A column as finite floats, or a refusal naming the first bad row."""
    if pd.api.types.is_datetime64_any_dtype(series) or pd.api.types.is_timedelta64_dtype(series):
        raise ValueError(f"{source}: column {column!r} holds {series.dtype} values (dates or "
                         "durations); give it as numbers in a stated unit (seconds since the "
                         "start, say)")
    values = pd.to_numeric(series, errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(values)
    if bad.any():
        i = int(np.argmax(bad))
        raw = series.iloc[i]
        if isinstance(raw, str) and raw.strip() and raw.strip().lower() not in ("nan", "na"):
            raise ValueError(f"{source}: column {column!r} row {_row(i)} is not a number "
                             f"({raw!r})")
        run = int(np.argmax(~bad[i:])) if (~bad[i:]).any() else len(bad) - i
        raise ValueError(f"{source}: column {column!r} has no value from row {_row(i)} "
                         f"({run} sample{'s' if run > 1 else ''} missing): fill or cut them")
    if len(values) < 3:
        raise ValueError(f"{source}: {len(values)} rows; a recording needs many samples")
    return values


def _check_time(t: np.ndarray, column: str, source: str) -> None:
    d = np.diff(t)
    back = d <= 0
    if back.any():
        i = int(np.argmax(back)) + 1
        what = "repeats" if d[i - 1] == 0 else "goes back to"
        raise ValueError(f"{source}: column {column!r} row {_row(i)} {what} t = {t[i]:.9g} s "
                         f"after t = {t[i - 1]:.9g} s: times must increase")
    step = float(np.median(d))
    gap = d > 1.5 * step
    if gap.any():
        i = int(np.argmax(gap))
        raise ValueError(f"{source}: column {column!r}: a gap of {d[i]:.6g} s after row "
                         f"{_row(i)} (t = {t[i]:.9g} s; the sampling interval is {step:.6g} s)")
    uneven = d < 0.5 * step
    if uneven.any():
        i = int(np.argmax(uneven))
        raise ValueError(f"{source}: column {column!r} row {_row(i + 1)}: samples "
                         f"{d[i]:.6g} s apart where the sampling interval is {step:.6g} s: "
                         "the recording must be evenly sampled")


def _check_saturation(x: np.ndarray, column: str, channel: str, source: str) -> None:
    for extreme, which in ((x.max(), "maximum"), (x.min(), "minimum")):
        at = x == extreme
        if at.sum() < 2 * SATURATED_RUN:
            continue
        # the runs of samples at the extreme, inside the record, long enough to be a clip
        edges = np.flatnonzero(np.diff(np.concatenate(([0], at.view(np.int8), [0]))))
        starts, ends = edges[::2], edges[1::2]
        clip = (ends - starts >= SATURATED_RUN) & (starts > 0) & (ends < len(x))
        if clip.sum() >= 2:
            k = int(np.flatnonzero(clip)[0])
            raise ValueError(f"{source}: column {column!r} ({channel}) is stuck at its "
                             f"{which} {extreme:.6g} from row {_row(starts[k])} for "
                             f"{ends[k] - starts[k]} samples, and {int(clip.sum()) - 1} more "
                             "time(s): a saturated sensor cannot be measured on")


def _check_friction(fs: np.ndarray, fn: np.ndarray, names: dict, source: str) -> None:
    with np.errstate(divide="ignore", invalid="ignore"):
        mu = np.median(fs / fn)
    if not MU_RANGE[0] <= mu <= MU_RANGE[1]:
        normal = (f"column {names['normal_force']!r}" if "normal_force" in names
                  else "the normal force")
        raise ValueError(f"{source}: column {names['shear_force']!r} (shear_force) over "
                         f"{normal} is {mu:.4g} (median): no friction coefficient is; one of "
                         f"them is in another unit (a shear force in kN read as N is 10³ off)")

"""An event catalogue in: the observations of an inversion from a table of stick–slip events
(``rsfbench observe --catalogue``), as laboratories often publish them — one row per event, in
stresses, not a force record.

Columns are mapped to **catalogue channels** as a recording's are (``CHANNEL=COLUMN[:UNIT]``,
the unit after the column's last colon; :func:`benchmarks.lab.channels.column_spec`):

=========================  ===========  ========================================================
channel                    SI unit      what it is
=========================  ===========  ========================================================
``onset``                  s            required: the event's start; ΔT is from one onset to
                                        the next (the first event has none)
``shear_stress_before``    Pa           the shear stress before the event, and …
``shear_stress_after``     Pa           … after it: Δμ = (before − after)/σn
``friction_before``        1            or the friction (τ/σn) before and after:
``friction_after``         1            Δμ = before − after
``drop``                   1 or Pa      or the drop itself: in a stress unit (Pa, kPa, MPa) a
                                        shear-stress drop, Δμ = drop/σn; without a unit (or
                                        ``:1``) a friction drop, Δμ = drop
``slip``                   m            optional: the slip per event
``duration``               s            optional: how long the event lasted (its end = onset +
                                        duration)
``peak_slip_rate``         m/s          optional
=========================  ===========  ========================================================

Exactly one way of the drop is mapped. A stress is turned into friction by the normal stress σn
(``normal_stress`` in Pa, or ``normal_force`` in N over the ``area``); a catalogue in stresses
needs the fault's ``area`` (m²) in any case, as a recording's stress channels do, so that the
apparatus's normal force σn × area is in the observations (the forward model's Fn).

Refused in one line, before anything is written: fewer than :data:`MIN_EVENTS` events, onsets
that do not increase (the row named), a drop that is not positive (the row named), a stress
without an area, a unit none of ours, a missing or non-numeric value, a friction before the
events that no friction coefficient has (a stress in another unit). The start-up and the
outliers are found as on a recording (:mod:`benchmarks.lab.settled`).

With the slip per event, the stiffness and the load-point speed the catalogue does not state
are estimated from it (:mod:`benchmarks.lab.catalogue_constants`), and with the normal force
known, :func:`observe_catalogue` writes ``apparatus.toml``: a problem file with k and vL
measured, the mass and the friction law's a given or assumed, b and Lc placeholders.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.inversion.observations import SIGMAS, write_observations
from benchmarks.lab.channels import MU_RANGE, UNITS, column_map, column_values, read_table
from benchmarks.lab.observe_recording import (OPTIONAL_FILES, check_window, observe_files,
                                              settled_summary)
from benchmarks.lab.catalogue_constants import (PAPER_MASS, catalogue_apparatus_toml,
                                                estimate_constants)
from benchmarks.lab.settled import judge
from benchmarks.records.files import claim_outputs, remove_own, write_output, write_table
from problems._validate import check_positive

__all__ = ["CATALOGUE_CHANNELS", "read_catalogue", "observe_catalogue", "MIN_EVENTS",
           "DROP_WAYS"]

#: each catalogue channel and its SI unit (a tuple: either; the first is the default)
CATALOGUE_CHANNELS = {"onset": "s", "shear_stress_before": "Pa", "shear_stress_after": "Pa",
                      "friction_before": "1", "friction_after": "1", "drop": ("1", "Pa"),
                      "slip": "m", "duration": "s", "peak_slip_rate": "m/s"}
#: the ways of giving the drop: exactly one is mapped
DROP_WAYS = (("shear_stress_before", "shear_stress_after"), ("friction_before", "friction_after"),
             ("drop",))
#: the fewest events of a catalogue: two recurrence intervals, a mean and a scatter
MIN_EVENTS = 3


def read_catalogue(path, columns, area: float | None = None,
                   normal_force: float | None = None,
                   normal_stress: float | None = None) -> tuple[pd.DataFrame, dict]:
    """The per-event table of the catalogue ``path`` (module docstring), and what it was read
    with.

    Parameters
    ----------
    path : str or pathlib.Path
        The catalogue (CSV, TSV, TXT, DAT or Parquet; one row per event).
    columns : dict or list of str
        Catalogue channel → ``(column, unit)``, or specs ``CHANNEL=COLUMN[:UNIT]``.
    area : float, optional
        The fault's area (m²); required when a stress is mapped.
    normal_force : float, optional
        The normal force (N): σn = normal_force / area.
    normal_stress : float, optional
        The normal stress (Pa).

    Returns
    -------
    events : pandas.DataFrame
        One row per event: ``t_start`` (s), ``t_end`` (s, NaN without a duration),
        ``recurrence_s``, ``friction_drop``, ``slip_m``, ``peak_velocity_m_s``, and
        ``friction_before``, ``friction_after`` (τ/σn or the friction columns; NaN when the
        drop is given as such): the loading between events
        (:mod:`benchmarks.lab.catalogue_constants`).
    info : dict
        ``normal_stress`` (Pa), ``normal_force`` (N, None without an area), ``area``,
        ``drop_from`` (which channels), ``columns``, ``sha256``, ``rows``.

    Raises
    ------
    ValueError
        Naming the column, row or option that is wrong (module docstring).
    """
    mapping = column_map(columns, CATALOGUE_CHANNELS, required=("onset",))
    way = _drop_way(mapping)
    sigma_n = _normal_stress(mapping, way, area, normal_force, normal_stress)
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"catalogue {path} does not exist" if not path.exists()
                         else f"catalogue {path} is not a file")
    try:
        table = read_table(path, sorted({c for c, _ in mapping.values()}))
    except ValueError as exc:                   # its messages name a recording
        raise ValueError(str(exc).replace("recording ", "catalogue ", 1)) from None
    if len(table) < MIN_EVENTS:
        raise ValueError(f"catalogue {path}: {len(table)} event{'s' if len(table) != 1 else ''}"
                         f"; a mean recurrence interval and its scatter need at least "
                         f"{MIN_EVENTS}")
    values = {ch: column_values(table[col], col, str(path)) * UNITS[unit][1]
              for ch, (col, unit) in mapping.items()}
    onset = values["onset"]
    _check_onsets(onset, mapping["onset"][0], path)
    drop, before, after = _friction_drop(values, mapping, way, sigma_n, path)
    n = len(onset)
    nan = np.full(n, math.nan)
    events = pd.DataFrame({
        "t_start": onset, "t_end": onset + values["duration"] if "duration" in values else nan,
        "recurrence_s": np.concatenate(([math.nan], np.diff(onset))), "friction_drop": drop,
        "slip_m": values.get("slip", nan), "peak_velocity_m_s": values.get("peak_slip_rate", nan),
        "friction_before": nan if before is None else before,
        "friction_after": nan if after is None else after})
    info = {"normal_stress": sigma_n, "area": area,
            "normal_force": None if sigma_n is None or area is None else sigma_n * area,
            "drop_from": list(way), "rows": n,
            "columns": {c: {"column": col, "unit": unit} for c, (col, unit) in mapping.items()},
            "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}
    return events, info


def observe_catalogue(path, columns, out, area: float | None = None,
                      normal_force: float | None = None, normal_stress: float | None = None,
                      sigma: str = "std", window=None, keep_startup: bool = False,
                      provenance: dict | None = None, mass: float | None = None,
                      after_delay: float | None = None) -> dict:
    """Read the catalogue ``path`` and write ``observations.json`` (means, σ, the per-event
    table; no curves) and ``events.csv`` to ``out``, as ``rsfbench observe`` does for a
    recording, and ``apparatus.toml`` when the catalogue has slips and the normal force is
    known (:mod:`benchmarks.lab.catalogue_constants`: k and vL estimated from it, the mass and
    the law's a given or assumed); returns the document with the files written (``files``)
    and the estimates (``constants``, None without slips).

    Parameters
    ----------
    path : str or pathlib.Path
        The catalogue.
    columns : dict or list of str
        As :func:`read_catalogue`.
    out : str or pathlib.Path
        The directory written into.
    area, normal_force, normal_stress : float, optional
        As :func:`read_catalogue` (m², N, Pa).
    sigma : str
        ``"std"`` or ``"sem"``: the spread the observations name as σ.
    window : tuple of float, optional
        (start, end) in s: only the events whose onset is inside.
    keep_startup : bool
        Keep the start-up events in the means (:mod:`benchmarks.lab.settled`).
    provenance : dict, optional
        Kept in the document as given.
    mass : float, optional
        The slider's mass (kg) for ``apparatus.toml``; None: the paper's, assumed (a
        catalogue cannot tell it).
    after_delay : float, optional
        When the catalogue's level after an event is read, s after its onset: the bias it
        causes in k and the loading rate is stated (not corrected).

    Returns
    -------
    dict
        The observations document, with ``files`` and ``constants``.

    Raises
    ------
    ValueError
        As :func:`read_catalogue`; a window outside the catalogue or with too few events; as
        :func:`~benchmarks.lab.catalogue_constants.estimate_constants`. All before anything
        is written.
    """
    if sigma not in SIGMAS:
        raise ValueError(f"sigma must be one of {SIGMAS}, got {sigma!r}")
    window = check_window(window)
    if mass is not None:
        check_positive("mass", mass)
    out = Path(out)
    claim_outputs(observe_files(out))
    events, info = read_catalogue(path, columns, area, normal_force, normal_stress)
    events = _inside(events, window, path)
    settling = judge(events, keep_startup, when=events.t_start)
    events = settling.mark(events)
    constants = _constants(events, info, after_delay)
    files = {"observations": out / "observations.json", "events": out / "events.csv"}
    text = None
    if constants is not None and constants.stiffness is not None:
        text = catalogue_apparatus_toml(constants, float(events.recurrence_s[events.kept].mean()),
                                        Path(path).stem, info["normal_force"], mass)
        files["apparatus"] = out / "apparatus.toml"
    doc = _write(events, info, settling, constants, files, text, window, path, sigma,
                 provenance, mass)
    for name in OPTIONAL_FILES.values():          # an earlier run's, of other observations
        if out / name not in files.values():
            remove_own(out / name)
    doc["files"] = {k: str(v) for k, v in files.items()}
    doc["constants"] = None if constants is None else constants.as_dict()
    return doc


def _constants(events, info, after_delay):
    """The estimates of k and vL, or None when the catalogue has no slips (its note then says
    so); refusals of the rest (:func:`estimate_constants`)."""
    if not np.isfinite(events.slip_m).any():
        if after_delay is not None:
            raise ValueError("after_delay is for the estimates of k and vL, which need the "
                             "slip per event: map slip")
        return None
    return estimate_constants(events, info["normal_force"], info["area"], after_delay)


def _write(events, info, settling, constants, files, text, window, path, sigma, provenance,
           mass) -> dict:
    """Write events.csv, observations.json and apparatus.toml (``text``, if any); the
    document."""
    notes = [f"an event catalogue: ΔT from consecutive onsets (the first event has none); Δμ "
             f"from {' − '.join(info['drop_from'])}"
             + (f" over σn = {info['normal_stress']:.6g} Pa" if info["normal_stress"] else ""),
             *settling.notes]
    apparatus = {"normal_force": info["normal_force"], "normal_stress": info["normal_stress"],
                 "area": info["area"]}
    how = {"drop": " − ".join(info["drop_from"])}
    if constants is None:
        notes.append("no slip per event: k and vL are not estimated and no apparatus.toml is "
                     "written (map slip)")
    else:
        notes += list(constants.notes)
        apparatus.update(stiffness=constants.stiffness and constants.stiffness.value,
                         vls=constants.vl.value)
        how.update(stiffness=constants.stiffness_per_fn.assumption, vls=constants.vl.assumption)
        if text is not None:
            apparatus["mass"] = PAPER_MASS if mass is None else mass
            how["mass"] = ("given" if mass is not None else "assumed: the paper's slider "
                           "(Table 4); a catalogue cannot tell the mass")
    recording = {"file": str(path), "kind": "catalogue", "sha256": info["sha256"],
                 "rows": info["rows"], "window_s": None if window is None else list(window),
                 "columns": info["columns"]}
    write_table(events, files["events"])
    doc = write_observations(files["observations"], events, None, apparatus, how, notes,
                             recording, sigma,
                             {**(provenance or {}),
                              "files_written": [str(v) for v in files.values()]},
                             settled_summary(settling))
    if text is not None:
        write_output(files["apparatus"], text)
    return doc


def _inside(events: pd.DataFrame, window, path) -> pd.DataFrame:
    """The events whose onset is in ``window`` (all when None); the first one's ΔT, from an
    onset outside, is kept (it is a real interval)."""
    if window is None:
        return events
    onset = events.t_start.to_numpy()
    if window[0] > onset[-1] or window[1] < onset[0]:
        raise ValueError(f"window {window[0]:g} to {window[1]:g} s is outside the catalogue "
                         f"{path}, whose onsets run from {onset[0]:.9g} to {onset[-1]:.9g} s")
    inside = (onset >= window[0]) & (onset <= window[1])
    if inside.sum() < MIN_EVENTS:
        raise ValueError(f"window {window[0]:g} to {window[1]:g} s holds {int(inside.sum())} "
                         f"events of {path}; at least {MIN_EVENTS} are needed")
    return events[inside].reset_index(drop=True)


def _drop_way(mapping: dict) -> tuple:
    """The one way of the drop mapped (:data:`DROP_WAYS`), or ``ValueError``."""
    mapped = [way for way in DROP_WAYS if any(c in mapping for c in way)]
    half = [way for way in mapped if not all(c in mapping for c in way)]
    if half:
        missing = next(c for c in half[0] if c not in mapping)
        raise ValueError(f"map {missing} too: the drop is {' − '.join(half[0])}")
    if len(mapped) != 1:
        ways = "; ".join(" and ".join(w) for w in DROP_WAYS)
        raise ValueError(f"map exactly one way of the drop ({ways}); got "
                         f"{'none' if not mapped else ' and '.join('/'.join(w) for w in mapped)}")
    return mapped[0]


def _normal_stress(mapping, way, area, normal_force, normal_stress) -> float | None:
    """σn (Pa) when a stress must become friction; the checks of an area and a normal load."""
    stresses = [c for c in (*way, "drop") if c in mapping and
                UNITS[mapping[c][1]][0] == "Pa"]
    if area is not None:
        check_positive("area", area)
    if normal_force is not None and normal_stress is not None:
        raise ValueError("give the normal stress (Pa) or the normal force (N), not both")
    if stresses and area is None:
        raise ValueError(f"column {mapping[stresses[0]][0]!r} ({stresses[0]}) is a stress: give "
                         "the fault's area in m² (--area M2)")
    if normal_force is not None:
        if area is None:
            raise ValueError("normal_force needs the fault's area (--area M2) to be a stress "
                             "(σn = Fn / area)")
        return check_positive("normal_force", normal_force) / area
    if normal_stress is not None:
        return check_positive("normal_stress", normal_stress)
    if stresses:
        raise ValueError(f"column {mapping[stresses[0]][0]!r} ({stresses[0]}) is a stress: give "
                         "the normal stress (--normal-stress PA) or force (--normal-force N) "
                         "to turn it into friction (μ = τ/σn)")
    return None


def _check_onsets(onset: np.ndarray, column: str, path) -> None:
    back = np.flatnonzero(np.diff(onset) <= 0)
    if len(back):
        i = int(back[0]) + 1
        raise ValueError(f"catalogue {path}: column {column!r} row {i + 2}: onset "
                         f"{onset[i]:.9g} s is not after the previous one ({onset[i - 1]:.9g} "
                         "s): the events must be in time order, each once")


def _friction_drop(values, mapping, way, sigma_n, path) -> tuple:
    """``(Δμ, μ before, μ after)`` per event from the mapped way (the last two None for a
    drop given as such), checked: Δμ positive, from a plausible friction."""
    def mu(channel):
        x = values[channel]
        return x / sigma_n if UNITS[mapping[channel][1]][0] == "Pa" else x
    if len(way) == 2:
        before = mu(way[0])
        level = float(np.median(before))
        if not MU_RANGE[0] <= level <= MU_RANGE[1]:
            raise ValueError(f"catalogue {path}: column {mapping[way[0]][0]!r} ({way[0]}) "
                             f"gives a friction of {level:.4g} (median) before the events: no "
                             "friction coefficient is; a stress or the normal stress is in "
                             "another unit (MPa read as Pa is 10⁶ off)")
        after = mu(way[1])
        drop = before - after
    else:
        before = after = None
        drop = mu("drop")
    bad = np.flatnonzero(~(drop > 0))
    if len(bad):
        i = int(bad[0])
        column = mapping[way[-1]][0] if len(way) == 1 else f"{mapping[way[0]][0]!r} − " \
            f"{mapping[way[1]][0]!r}"
        raise ValueError(f"catalogue {path}: row {i + 2}: the drop ({column}) is "
                         f"{drop[i]:.6g} in friction, not positive: a stick–slip event drops "
                         "the stress (before and after swapped?)")
    return drop, before, after

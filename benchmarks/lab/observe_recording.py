"""From a laboratory recording to the observations an inversion uses (``rsfbench observe``).

:func:`observe` reads a recording (:mod:`benchmarks.lab.channels`), measures its events,
the fault's friction and the apparatus (:mod:`benchmarks.lab.events`) and writes, in
one directory:

* ``observations.json`` — the observations file (:mod:`benchmarks.inversion.observations`):
  what ``rsfbench invert --observations`` and ``rsfbench sweep --observations`` read, and
  :func:`~benchmarks.inversion.observations.read_observations` in Python; with curves, its
  ``measurement`` is the chain they were read through (:mod:`benchmarks.physics.chain`), which
  the inversion applies to the model's curves too;
* ``events.csv`` — one row per event: ``t_start``, ``t_end`` (s), ``recurrence_s``,
  ``friction_drop``, ``slip_m``, ``peak_velocity_m_s``, and whether it is in the means
  (``kept``), why not (``reason``: ``start-up`` or ``outlier``) and its distance from the
  settled cycle (``z_max``, robust σ): :mod:`benchmarks.lab.settled`; the start-up is left out
  of the means (and of the curves) unless ``keep_startup``;
* ``curves.csv`` — the slip-weakening curves (``event_id``, ``slip_m``, ``friction``: Ft/Fn),
  when the record has accelerations and the mass is known;
* ``apparatus.toml`` — a problem file of the apparatus as the record shows it (k, the loading,
  m, Fn; the friction law's a, b, Lc are placeholders to be inverted), when k, vLs, the mass
  and Fn are known (the mass is given, ``--mass``): ``rsfbench simulate --problem`` runs it;
* ``observe.png`` — the record with its events marked, the metrics event by event, the curves.

No file of the user's is replaced: a file of one of these names in ``out`` that rsfbench did
not write (or that was changed since) is refused before any work, unless ``--overwrite``
(:func:`benchmarks.records.files.writing`). An optional file this run does not write is removed
from ``out`` if an earlier run wrote it and nobody changed it since, so that every file in the
directory is of the same observations; a file of anyone else's stays.

A column file (TOML) maps the columns and gives the apparatus's constants::

    [columns]                                # CHANNEL = "COLUMN" (SI unit) or a table
    time = "Time(s)"
    shear_force = {column = "Load", unit = "kN"}
    acceleration = {column = "a1", unit = "g"}
    slip = {column = "LDT", unit = "mm"}
    table = {column = "Table", unit = "mm"}

    [apparatus]
    normal_force = 997500.0                  # N, when no column holds it (or normal_stress, Pa)
    area = 0.75                              # m², for stress channels and normal_stress
    mass = 1100.0                            # kg: Ft = Fs − m·a
    vls = 7.5e-5                             # m/s, optional (else from the table's position)
    stiffness = 1.48e8                       # N/m, optional (else measured)
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import replace
from pathlib import Path

from benchmarks.inversion.observations import SIGMAS, write_observations
from benchmarks.lab.channels import CHANNELS, column_map, explicit_unit, read_recording
from benchmarks.lab.events import analyse
from benchmarks.lab.settled import JUDGED, MIN_SETTLED, STANDS_OUT, Z_DIFFERS, judge
from benchmarks.lab.figures import plot_recording
from benchmarks.physics.chain import Chain
from benchmarks.records.files import claim_outputs, remove_own, write_output, write_table
from problems._validate import check_positive

__all__ = ["observe", "observe_files", "read_column_file", "apparatus_toml", "APPARATUS_KEYS"]

#: the constants a column file's [apparatus] table may give, and their units
APPARATUS_KEYS = {"normal_force": "N", "mass": "kg", "vls": "m/s", "stiffness": "N/m",
                  "area": "m2", "normal_stress": "Pa"}


def read_column_file(path) -> tuple[dict, dict]:
    """``(columns, apparatus)`` of a column file (module docstring): channel → (column, unit),
    and the constants by name; or ``ValueError`` naming the file and the key."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"column file {path} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"column file {path} cannot be read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"column file {path} is not TOML: {exc}") from None
    unknown = sorted(set(data) - {"columns", "apparatus"})
    if unknown:
        raise ValueError(f"column file {path}: unknown table {unknown[0]!r} (expected "
                         "[columns] and [apparatus])")
    for table in ("columns", "apparatus"):
        if not isinstance(data.get(table, {}), dict):
            raise ValueError(f"column file {path}: {table} must be a table ([{table}]), got "
                             f"{data[table]!r}")
    columns = {}
    for channel, spec in data.get("columns", {}).items():
        if isinstance(spec, dict):
            extra = sorted(set(spec) - {"column", "unit"})
            if extra or "column" not in spec:
                raise ValueError(f"column file {path}: columns.{channel} needs column = "
                                 f"\"NAME\" and optionally unit = \"UNIT\" (got {sorted(spec)})")
            column, unit = str(spec["column"]), str(spec.get("unit", CHANNELS.get(channel, "")))
        elif isinstance(spec, str):
            column, unit = spec, CHANNELS.get(channel, "")
        else:
            raise ValueError(f"column file {path}: columns.{channel} must be a column name or "
                             f"a table, got {spec!r}")
        try:
            channel, column, unit = explicit_unit(channel, column, unit)
        except ValueError as exc:
            raise ValueError(f"column file {path}: {exc}") from None
        columns[channel] = (column, unit)
    apparatus = {}
    for key, value in data.get("apparatus", {}).items():
        if key not in APPARATUS_KEYS:
            raise ValueError(f"column file {path}: unknown key apparatus.{key} (expected "
                             f"{', '.join(APPARATUS_KEYS)})")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not \
                math.isfinite(value) or value <= 0:
            raise ValueError(f"column file {path}: apparatus.{key} must be a positive number "
                             f"in {APPARATUS_KEYS[key]}, got {value!r}")
        apparatus[key] = float(value)
    return columns, apparatus


#: the files ``observe`` writes only when the record allows (module docstring)
OPTIONAL_FILES = {"curves": "curves.csv", "apparatus": "apparatus.toml", "figure": "observe.png"}


def observe(path, columns, out, normal_force: float | None = None, mass: float | None = None,
            vls: float | None = None, stiffness: float | None = None, sigma: str = "std",
            plot: bool = True, provenance: dict | None = None, area: float | None = None,
            normal_stress: float | None = None, window=None,
            keep_startup: bool = False) -> dict:
    """Measure the recording ``path`` and write the files of the module docstring to ``out``;
    returns the observations document with the files written (``files``).

    Parameters
    ----------
    path : str or pathlib.Path
        The recording's file.
    columns : dict or list of str
        Channel → ``(column, unit)``, or specs ``CHANNEL=COLUMN:UNIT``.
    out : str or pathlib.Path
        The directory written into.
    normal_force : float, optional
        The normal force (N), standing for a normal-force column.
    mass : float, optional
        The slider's mass (kg).
    vls, stiffness : float, optional
        The slow load-point speed (m/s) and stiffness (N/m), instead of measuring them.
    sigma : str
        ``"std"`` or ``"sem"``: the spread the observations name as σ.
    plot : bool
        Also draw the figures.
    provenance : dict, optional
        Kept in the document as given.
    area : float, optional
        The fault's area (m²): stress channels times it are forces.
    normal_stress : float, optional
        The normal stress (Pa), standing for a normal-force column: Fn = σn × ``area``.
    window : tuple of float, optional
        (start, end) in the file's time (s): only that part of the record is measured.
    keep_startup : bool
        Keep the start-up events in the means (:mod:`benchmarks.lab.settled`; they are found
        and named either way).

    Returns
    -------
    dict
        The observations document, with ``files``.

    Raises
    ------
    ValueError
        As :func:`read_recording` and :func:`analyse`; a window outside the record.
    """
    if sigma not in SIGMAS:
        raise ValueError(f"sigma must be one of {SIGMAS}, got {sigma!r}")
    window = check_window(window)
    normal_force = normal_from_stress(normal_force, normal_stress, area)
    out = Path(out)
    claim_outputs(observe_files(out))          # before the work: a user's file there is refused
    rec = read_recording(path, columns, normal_force=normal_force, area=area)
    rec = crop(rec, window)
    found = analyse(rec, mass=mass, vls=vls, stiffness=stiffness)
    settling = judge(found.events, keep_startup, when=found.events.t_start)
    events, curves = settling.mark(found.events), found.curves
    if curves is not None and settling.dropped:       # event_id: the row in events, from 1
        curves = curves[events.kept.to_numpy()[curves.event_id.to_numpy() - 1]]
    recording = {"file": str(path), "sha256": rec.sha256, "rows": len(rec.t),
                 "rate_hz": rec.rate, "duration_s": float(rec.t[-1] - rec.t[0]),
                 "window_s": None if window is None else list(window),
                 "columns": {c: {"column": col, "unit": unit}
                             for c, (col, unit) in column_map(columns).items()},
                 "slip_from": found.slip_source, "noise": found.noise}
    files = _write(out, path, rec, found, events, curves, recording, settling, sigma, plot,
                   provenance, area)
    doc = files.pop("doc")
    doc["files"] = {k: str(v) for k, v in files.items()}
    return doc


def _write(out, path, rec, found, events, curves, recording, settling, sigma, plot, provenance,
           area) -> dict:
    """Write observe's files (module docstring); their paths by key, and the document
    (``doc``)."""
    files = {"observations": out / "observations.json", "events": out / "events.csv"}
    write_table(events, files["events"])
    if curves is not None:
        files["curves"] = out / "curves.csv"
        write_table(curves, files["curves"])
    text = apparatus_toml(found.apparatus, events[events.kept], Path(path).stem, found.how)
    if text is not None:
        files["apparatus"] = out / "apparatus.toml"
    if plot:
        files["figure"] = out / "observe.png"
    doc = write_observations(files["observations"], events, curves,
                             {**found.apparatus, "area": area}, found.how,
                             [*found.notes, *settling.notes], recording, sigma,
                             {**(provenance or {}),
                              "files_written": [str(v) for v in files.values()]},
                             settled_summary(settling),
                             measurement=None if curves is None else Chain.observed(
                                 rec.rate, found.slip_source, found.noise,
                                 found.apparatus["vls"]).record())
    if text is not None:
        write_output(files["apparatus"], text)
    if plot:
        plot_recording(rec, found, files["figure"])
    for key, name in OPTIONAL_FILES.items():      # an earlier run's, of other observations
        if key not in files:
            remove_own(out / name)
    return {**files, "doc": doc}


def check_window(window) -> tuple[float, float] | None:
    """``(start, end)`` in s as floats, or ``ValueError`` unless both are finite and
    start < end (None: the whole record)."""
    if window is None:
        return None
    try:
        start, end = (float(x) for x in window)
    except (TypeError, ValueError):
        raise ValueError(f"window must be two times START END in s, got {window!r}") from None
    if not (math.isfinite(start) and math.isfinite(end)):
        raise ValueError(f"window must be two finite times in s, got {start:g} {end:g}")
    if start >= end:
        raise ValueError(f"window START = {start:g} s must be before END = {end:g} s")
    return start, end


def crop(rec, window):
    """The part of the recording ``rec`` inside ``window`` (s, the file's time; None: all), or
    ``ValueError`` if the window reaches outside the record (half a sampling interval is
    allowed)."""
    if window is None:
        return rec
    start, end = window
    t0, t1, half = float(rec.t[0]), float(rec.t[-1]), 0.5 * rec.dt
    if start < t0 - half or end > t1 + half:
        raise ValueError(f"window {start:g} to {end:g} s reaches outside the record "
                         f"{rec.source}, which runs from t = {t0:.9g} to {t1:.9g} s")
    inside = (rec.t >= start) & (rec.t <= end)
    if inside.sum() < 3:
        raise ValueError(f"window {start:g} to {end:g} s holds {int(inside.sum())} samples of "
                         f"{rec.source}: too few to measure")
    return replace(rec, t=rec.t[inside], channels={k: v[inside] for k, v in
                                                    rec.channels.items()})


def normal_from_stress(normal_force, normal_stress, area) -> float | None:
    """The normal force (N) from a constant normal stress (Pa) times the area (m²); a normal
    force as given. Both, or a stress without an area: ``ValueError``."""
    if normal_stress is None:
        return normal_force
    if normal_force is not None:
        raise ValueError("give the normal force (N) or the normal stress (Pa), not both")
    if area is None:
        raise ValueError(f"normal_stress = {normal_stress:g} Pa is a stress: give the fault's "
                         "area in m² (--area M2) to make it a force (stress × area)")
    return check_positive("normal_stress", normal_stress) * check_positive("area", area)


def settled_summary(settling) -> dict:
    """What observations.json says of the start-up and the outliers (1-based event numbers,
    as the rows of events.csv)."""
    return {"rule": (f"robust z = (x − median)/(1.4826 MAD) over the settled events, on "
                     f"{', '.join(JUDGED)}; an event differs beyond {Z_DIFFERS:g}; the start-up "
                     f"is the leading run of such events when the first is {STANDS_OUT:g}× "
                     f"as far as any later one and {MIN_SETTLED} or more are left; outliers "
                     "(later ones) are kept"),
            "z_threshold": Z_DIFFERS,
            "startup_events": [i + 1 for i in settling.startup],
            "outlier_events": [i + 1 for i in settling.outliers],
            "dropped_events": [i + 1 for i in settling.dropped],
            "startup_kept": settling.keep_startup, "outliers_kept": True}


def observe_files(out) -> list[Path]:
    """Every file :func:`observe` may write to ``out``."""
    return [Path(out) / n for n in ("observations.json", "events.csv", *OPTIONAL_FILES.values())]


def apparatus_toml(apparatus: dict, events, name: str, how: dict | None = None) -> str | None:
    """A problem file of the apparatus the record shows (module docstring), or None when its
    stiffness, slow loading speed, mass or normal force is unknown."""
    need = ("stiffness", "vls", "mass", "normal_force")
    if any(apparatus.get(k) is None for k in need):
        return None
    a = apparatus
    how = how or {}
    said = {key: "given" if how.get(key) == "given" else "measured" for key in ("stiffness", "vls")}
    recurrence = float(events["recurrence_s"].mean())
    t_end = 10.0 * recurrence if math.isfinite(recurrence) else 40.0
    two_speed = a.get("df") and a.get("vlf") and a["df"] > 0
    loading = (f"vls = {a['vls']:.6g}               # m/s, {said['vls']}\n"
               f"vlf = {a['vlf']:.6g}               # m/s, measured\n"
               f"df = {a['df']:.6g}                 # s, measured\n" if two_speed else
               f"vl = {a['vls']:.6g}                # m/s, {said['vls']}\n")
    return (f"# The apparatus of the recording {name!r}, as `rsfbench observe` measured it.\n"
            "# k, the loading, m and Fn are the record's; the friction law's a, b and Lc are\n"
            "# placeholders (the paper's W2 fit): `rsfbench invert --problem THIS --observations"
            "\n# observations.json --b-range 0.0086,0.0102 --lc-range 3e-8,3e-6` estimates b and"
            "\n# Lc in that prior box (the placeholders ± 0.0008 and ÷× 10: choose your own).\n"
            "# SI units.\n"
            f"name = {json.dumps(name)}\n"
            f"mass = {a['mass']:.6g}                 # kg, given\n"
            f"stiffness = {a['stiffness']:.6g}       # N/m, {said['stiffness']}\n"
            f"normal_force = {a['normal_force']:.6g} # N\n"
            f"t_end = {t_end:.6g}                    # s: ten mean recurrence intervals\n\n"
            "[law]                    # placeholders: edit, or invert\n"
            "name = \"slip\"\na = 0.008\nb = 0.0094\nlc = 3e-7\nv0 = 1e-5\n\n"
            f"[loading]\n{loading}")

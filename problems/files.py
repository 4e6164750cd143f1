"""A spring-slider from a file: a user's own apparatus, in TOML or JSON, SI units.

    name = "my apparatus"      # optional
    mass = 1100.0              # kg (0: quasi-static)
    stiffness = 1.48e8         # N/m
    normal_force = 997500.0    # N
    t_end = 40.0               # s
    mu0 = 0.6                  # optional, F0/Fn (default 0.6)
    radiation_damping = 0.0    # optional, N s/m (default 0)

    [law]
    name = "slip"              # or "aging", or "nagata" (with c = 2.0, its stress coefficient)
    a = 0.008
    b = 0.0094
    lc = 3e-7                  # m
    v0 = 1e-5                  # m/s, optional (default 1e-5)

    [loading]                  # vl = ... (constant), or the two speeds:
    vls = 7.5e-5               # m/s
    vlf = 1.9717e-3            # m/s
    df = 0.042                 # s
    # or a history: velocities = [1e-6, 0.0, 1e-6] (m/s; 0 holds) and switch_times = [10, 110]
    # (s), optionally with overshoot_velocity, overshoot_duration and reference_velocity

    [initial]                  # optional: slowdown = 1.1 (the presets' rule, the default),
    slowdown = 1.1             # or v (m/s), theta (the law's units), fs (N)

The same keys as JSON objects (a key given twice is refused, as TOML does). Every key is
checked: an unknown or missing one, a value that is not a number, an overshoot's velocity
without its duration (or the reverse), or a value the problem refuses is a ``ValueError`` naming
the file and the key, in one line. A value implausible in its unit (a normal force in MPa, a
speed in µm/s) is read with a :class:`~problems._validate.UnitWarning` naming the key, the value
and the unit expected: the problem's own, word for word, so that a command shows it once however
often the problem is varied afterwards.
"""

from __future__ import annotations

import json
import math
import os
import tomllib
from pathlib import Path

from problems.friction import LAWS, law_from_name, law_parameters
from problems.loading import ConstantLoading, LoadHistory, TwoSpeedLoading
from problems.slider import BalancedStart, InitialState, SpringSlider

__all__ = ["load_problem", "problem_dict", "PROBLEM_SUFFIXES"]

PROBLEM_SUFFIXES = (".toml", ".json")
#: a problem file is a few hundred bytes; a history of 10⁴ pieces is ~300 kB
MAX_FILE_BYTES = 10_000_000
_TOP = {"mass", "stiffness", "normal_force", "t_end", "mu0", "name", "law", "loading", "initial",
        "radiation_damping"}
_HISTORY_SCALARS = ("overshoot_velocity", "overshoot_duration", "reference_velocity")
_REQUIRED = ("mass", "stiffness", "normal_force", "t_end", "law", "loading")


def load_problem(path) -> SpringSlider:
    """The :class:`SpringSlider` a TOML or JSON file describes (the keys: module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        A ``.toml`` or ``.json`` file, SI units.

    Returns
    -------
    SpringSlider
        Named by the file's ``name``, else by its stem.

    Raises
    ------
    ValueError
        In one line naming the file (and the key): a file that cannot be read or parsed, an
        unknown or missing key, a value that is not a number, or one the problem refuses.

    Warns
    -----
    UnitWarning
        For a value implausible in its unit, naming the key, the value and the unit expected.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"the problem file must be a path, got {_show(path)}")
    path = Path(path)
    if path.suffix.lower() not in PROBLEM_SUFFIXES:
        raise ValueError(f"problem file {path} must end in .toml or .json")
    try:
        # a regular file only: reading a FIFO waits for a writer, a device never ends
        if path.exists() and not path.is_file():
            raise ValueError(f"the problem file {path} is not a regular file")
        if path.exists() and path.stat().st_size > MAX_FILE_BYTES:
            raise ValueError(f"the problem file {path} holds {path.stat().st_size} bytes, more "
                             f"than any problem file ({MAX_FILE_BYTES} bytes)")
        raw = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"cannot read the problem file {path}: {exc.strerror}") from None
    try:
        text = raw.decode("utf-8-sig")          # a byte-order mark (Windows editors) is no error
        data = (tomllib.loads(text) if path.suffix.lower() == ".toml"
                else json.loads(text, object_pairs_hook=_unique_keys))
    except (tomllib.TOMLDecodeError, ValueError) as exc:     # JSON, Unicode, a repeated key
        raise ValueError(f"problem file {path} is not valid {path.suffix[1:].upper()}: "
                         f"{' '.join(str(exc).split())}") from None
    except RecursionError:
        raise ValueError(f"problem file {path} is not valid {path.suffix[1:].upper()}: it nests "
                         "deeper than any problem does") from None
    try:
        return problem_from_dict(data, default_name=path.stem)
    except ValueError as exc:
        raise ValueError(f"problem file {path}: {exc}") from None


def _unique_keys(pairs) -> dict:
    """A JSON object, refused if a key repeats (json keeps the last silently; TOML refuses)."""
    out = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"the key {key!r} appears twice in one object")
        out[key] = value
    return out


def problem_from_dict(data, default_name: str = "") -> SpringSlider:
    """The problem of a parsed file (module docstring for the keys)."""
    table = _table(data, "the file")
    _keys(table, _TOP, _REQUIRED, "the file")
    law = _table(table["law"], "[law]")
    name = law.get("name")
    known = isinstance(name, str) and name.lower() in LAWS
    own = law_parameters(name) if known else ()
    _keys(law, {"name", "a", "b", "lc", "v0", *own}, ("name", "a", "b", "lc"), "[law]")
    if not known:
        raise ValueError(f"[law] name: law must be one of {sorted(LAWS)}, got {_show(name)}")
    law = law_from_name(law["name"], **{k: _number(law, k, "[law]") for k in law if k != "name"})
    loading = _table(table["loading"], "[loading]")
    if "vl" in loading:
        _keys(loading, {"vl"}, ("vl",), "[loading]")
        loading = ConstantLoading(_number(loading, "vl", "[loading]"))
    elif "velocities" in loading:
        _keys(loading, {"velocities", "switch_times", *_HISTORY_SCALARS}, ("velocities",),
              "[loading] (a history)")
        # one of the overshoot's two keys alone would be ignored (no duration) or refused
        # without naming the missing key
        given = [k for k in ("overshoot_velocity", "overshoot_duration") if k in loading]
        if len(given) == 1:
            other = ({"overshoot_velocity", "overshoot_duration"} - set(given)).pop()
            raise ValueError(f"[loading] has {given[0]} without {other}: an overshoot needs "
                             "both (m/s and s)")
        lists = {k: tuple(_number({f"{k}[{i}]": x}, f"{k}[{i}]", "[loading]")
                          for i, x in enumerate(_list(loading, k)))
                 for k in ("velocities", "switch_times") if k in loading}
        loading = LoadHistory(**lists, **{k: _number(loading, k, "[loading]")
                                          for k in _HISTORY_SCALARS if k in loading})
    elif not set(loading) & {"vls", "vlf", "df"}:
        raise ValueError(f"[loading] must be vl (m/s: constant), or vls, vlf, df (two speeds), "
                         f"or velocities (m/s) with switch_times (s) (a history); got the keys "
                         f"{', '.join(sorted(loading)) or 'none'}")
    else:
        _keys(loading, {"vls", "vlf", "df"}, ("vls", "vlf", "df"), "[loading] (or vl alone)")
        loading = TwoSpeedLoading(**{k: _number(loading, k, "[loading]") for k in loading})
    initial = _table(table.get("initial", {}), "[initial]")
    _keys(initial, {"slowdown", "v", "theta", "fs"}, (), "[initial]")
    if "slowdown" in initial and len(initial) > 1:
        raise ValueError("[initial] is slowdown alone (the presets' rule) or v, theta, fs (an "
                         f"explicit state), not both: got {', '.join(sorted(initial))}")
    if set(initial) <= {"slowdown"}:
        initial = BalancedStart(**{k: _number(initial, k, "[initial]") for k in initial})
    else:
        _keys(initial, {"v", "theta", "fs"}, ("v", "theta", "fs"), "[initial] (or slowdown alone)")
        initial = InitialState(**{k: _number(initial, k, "[initial]") for k in initial})
    name = table.get("name", default_name)
    if not isinstance(name, str):
        raise ValueError(f"name must be a string, got {_show(name)}")
    scalars = {k: _number(table, k, "the file") for k in ("mass", "stiffness", "normal_force",
                                                           "t_end", "mu0", "radiation_damping")
               if k in table}
    return SpringSlider(law=law, loading=loading, initial=initial, name=name, **scalars)


def problem_dict(problem: SpringSlider) -> dict:
    """The file form of ``problem`` (what :func:`problem_from_dict` reads back)."""
    import dataclasses
    initial = dataclasses.asdict(problem.initial)
    loading = {k: list(v) if isinstance(v, tuple) else v
               for k, v in dataclasses.asdict(problem.loading).items() if v is not None}
    return {"name": problem.name, "mass": problem.mass, "stiffness": problem.stiffness,
            "normal_force": problem.normal_force, "t_end": problem.t_end, "mu0": problem.mu0,
            "radiation_damping": problem.radiation_damping,
            "law": {"name": problem.law.name, **dataclasses.asdict(problem.law)},
            "loading": loading, "initial": initial}


def _show(value) -> str:
    """``repr(value)``, cut short: a message is one line, whatever the file holds."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _table(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise ValueError(f"{where} must be a table of keys, got {_show(value)}")
    return value


def _keys(table: dict, allowed: set, required, where: str) -> None:
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise ValueError(f"unknown key {_show(unknown[0])} in {where}; the keys are "
                         f"{', '.join(sorted(allowed))}")
    missing = [k for k in required if k not in table]
    if missing:
        raise ValueError(f"{where} lacks the key {missing[0]!r}")


def _list(table: dict, key: str) -> list:
    value = table[key]
    if not isinstance(value, list):
        raise ValueError(f"{key} in [loading] must be a list of numbers, got {_show(value)}")
    return value


def _number(table: dict, key: str, where: str) -> float:
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{key} in {where} must be a finite number, got {_show(value)}")
    try:
        x = float(value)
    except OverflowError:                    # an integer beyond the doubles
        raise ValueError(f"{key} in {where} must be a finite number, got an integer of "
                         f"{len(str(abs(value)))} digits") from None
    if not math.isfinite(x):
        raise ValueError(f"{key} in {where} must be a finite number, got {_show(value)}")
    return x

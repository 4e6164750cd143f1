"""Probe cases: ``rsfbench observe`` — a recording as a user brings one, and as a hostile one does:
every defect of the samples refused in one line that names the column and the row (or the
file), the observations file read back by ``sweep`` and refused when it is not one, ``--json``
one document either way."""

from __future__ import annotations

import functools
import json

import numpy as np
import pandas as pd

from probe.harness import Case, Observed, Wrong, cli, cli_outcome, one_json

__all__ = ["cases"]

KIND = "observe"
_MAP = ("--column", "time=t", "--column", "shear_force=Fs:kN", "--normal-force", "997500")


@functools.cache
def _good() -> pd.DataFrame:
    """W2 (slip law) recorded for 20 s from t = 5 s at 10 kHz with 1 % noise: Fs in kN, the
    slip and the table in mm, the acceleration in m/s²."""
    from benchmarks.lab.synthetic import synthetic_recording
    from problems import preset
    table, _ = synthetic_recording(preset("W2", law="slip", t_end=20.0), t_skip=5.0,
                                   noise=0.01, drift=0.01, seed=9)
    return pd.DataFrame({"t": table.time, "Fs": table.shear_force / 1e3,
                         "a1": table.acceleration, "LDT": table.slip * 1e3,
                         "Table": table.table * 1e3})


def _sawtooth(n: int = 4000, rate: float = 1000.0) -> pd.DataFrame:
    t = np.arange(n) / rate
    return pd.DataFrame({"t": t, "Fs": 997.5 * (0.58 + 0.04 * ((t / 0.5) % 1.0))})


def _refused(name, make, args=_MAP, names="", json_mode=False):
    def run(tmp):
        path = tmp / "rec.csv"
        make().to_csv(path, index=False)
        argv = [str(a).replace("{tmp}", str(tmp)) for a in args]
        return cli_outcome(cli("observe", str(path), *argv, "--out", str(tmp / "o"),
                               *(["--json"] if json_mode else [])), json_mode)
    return Case(KIND, name, run, "refused", names=names, timeout=60)


def _defects() -> list[Case]:
    saw = _sawtooth
    defects = {
        "times that go back": (lambda: saw().assign(t=saw().t.where(saw().index != 50, 0.0)),
                               "row 52"),
        "a repeated time": (lambda: saw().assign(t=saw().t.where(saw().index != 50,
                                                                  saw().t[49])), "row 52"),
        "a gap in the times": (lambda: saw().assign(t=saw().t + 2.0 * (saw().index >= 900)),
                               "row 901"),
        "a run of missing forces": (lambda: saw().assign(Fs=saw().Fs.where(
            (saw().index < 10) | (saw().index > 30))), "row 12"),
        "a word among the forces": (lambda: saw().assign(Fs=saw().Fs.astype(object).where(
            saw().index != 3, "n/a")), "row 5"),
        "a saturated load cell": (lambda: saw().assign(Fs=np.minimum(saw().Fs, 615.0)),
                                  "stuck at its maximum"),
        "a force in N mapped as kN": (lambda: saw().assign(Fs=saw().Fs * 1e3), "'Fs'"),
        "a flat force: no event": (lambda: saw().assign(Fs=600.0 + 0.01 * np.sin(saw().t)),
                                   "no stick–slip event"),
        "one event only": (lambda: saw().iloc[:1200], "1 complete stick–slip event"),
    }
    out = [_refused(f"a recording with {name}", make, names=names)
           for name, (make, names) in defects.items()]
    out.append(_refused("--json refusal: times that go back", defects["times that go back"][0],
                        names="row 52", json_mode=True))
    mapping = {
        "no column mapped": (("--normal-force", "997500"), "--column"),
        "an unknown channel": (("--column", "time=t", "--column", "force=Fs"), "force"),
        "a unit not of its channel": (("--column", "time=t", "--column", "shear_force=Fs:mm",
                                       "--normal-force", "997500"), "mm"),
        "a column the file lacks": (("--column", "time=t", "--column", "shear_force=Load",
                                     "--normal-force", "997500"), "Load"),
        "no normal force": (("--column", "time=t", "--column", "shear_force=Fs:kN"),
                            "normal_force"),
        "a column file that is not TOML": (("--columns", "{tmp}/rec.csv"), "not TOML"),
    }
    out += [_refused(name, _sawtooth, args, names) for name, (args, names) in mapping.items()]
    return out


def _observed(tmp) -> Observed:
    """The good recording observed: ok, --json one document, its numbers the model's."""
    path = tmp / "rec.csv"
    _good().to_csv(path, index=False)
    run = cli("observe", str(path), "--column", "time=t", "--column", "shear_force=Fs:kN",
              "--column", "acceleration=a1", "--column", "slip=LDT:mm", "--column",
              "table=Table:mm", "--normal-force", "997500", "--mass", "1100", "--out",
              str(tmp / "o"), "--json")
    got = cli_outcome(run, json_mode=True)
    doc = one_json(run.out)
    if got.outcome != "ok" or doc["n_events"] != 4:
        raise Wrong(f"{got.outcome}, {doc.get('n_events')} events: {run.err[-300:]}")
    drop = doc["metrics"]["friction_drop"]["mean"]
    if abs(drop / 0.0452141 - 1) > 0.005:              # W2's own Δμ (its event table)
        raise Wrong(f"Δμ = {drop:.6g}, the model's is 0.0452141")
    return Observed("ok", f"{doc['n_events']} events, Δμ = {drop:.6g}")


def _sweep_reads(tmp) -> Observed:
    _observed(tmp)
    run = cli("sweep", "--preset", "W2", "--b", "0.0094:0.0094:0.0001", "--lc", "3e-7:3e-7:1",
              "--t-end", "12", "--observations", str(tmp / "o" / "observations.json"),
              "--workers", "1", "--no-progress", "--no-plot", "--out", str(tmp / "s"), "--json")
    got = cli_outcome(run, json_mode=True)
    doc = one_json(run.out)
    seen = doc.get("observations", {}).get("recurrence_s", 0.0)
    if got.outcome != "ok" or abs(seen / 3.0441 - 1) > 1e-3:     # W2's own ΔT, as observed
        raise Wrong(f"{got.outcome}, ΔT {seen!r}: {run.out[:300]} {run.err[-300:]}")
    return got


def _invert_reads(tmp) -> Observed:
    """invert --observations: the file's means and σ are what the inversion scores against."""
    _observed(tmp)
    path = tmp / "o" / "observations.json"
    run = cli("invert", "--preset", "W2", "--t-end", "12", "--integrator", "Rodas5P", "--rtol",
              "1e-4", "--atol", "1e-4", "--steps", "0", "--profile-points", "3", "--observations",
              str(path), "--out", str(tmp / "i"), "--no-progress", "--json")
    got = cli_outcome(run, json_mode=True)
    seen = one_json(run.out).get("observations", {})
    metrics = json.loads(path.read_text())["metrics"]
    want = {"recurrence_s": metrics["recurrence_s"]["mean"],
            "sigma_recurrence_s": metrics["recurrence_s"]["std"],
            "friction_drop": metrics["friction_drop"]["mean"],
            "sigma_friction_drop": metrics["friction_drop"]["std"]}
    if got.outcome != "ok" or any(seen.get(k) != v for k, v in want.items()):
        raise Wrong(f"{got.outcome}, observations {seen!r} against the file's {want!r}: "
                    f"{run.err[-300:]}")
    return got


_BAD_FILE_RUNS = {
    "sweep": ("sweep", "--preset", "W2", "--b", "0.0094:0.0094:0.0001", "--lc", "3e-7:3e-7:1"),
    "invert": ("invert", "--preset", "W2", "--steps", "0", "--profile-points", "3"),
}


def _bad_file(content: str, extra=(), command="sweep"):
    def run(tmp):
        path = tmp / "observations.json"
        path.write_text(content)
        return cli_outcome(cli(*_BAD_FILE_RUNS[command], "--observations", str(path), *extra,
                               "--out", str(tmp / "s")))
    return run


def cases() -> list[Case]:
    good = json.dumps({"format": "rsfbench observations", "version": 1, "sigma": "std",
                       "metrics": {"recurrence_s": {"mean": 3.0, "std": 0.1},
                                   "friction_drop": {"mean": 0.045, "std": 0.002}}})
    return _defects() + [
        Case(KIND, "a recording of W2 observed: its Δμ is the model's", _observed, "ok",
             timeout=120),
        Case(KIND, "sweep --observations reads the file observe wrote", _sweep_reads, "ok",
             timeout=180),
        Case(KIND, "--observations with --obs-recurrence", _bad_file(
            good, ("--obs-recurrence", "3")), names="--obs-recurrence"),
        Case(KIND, "--observations of another format", _bad_file(
            good.replace("rsfbench observations", "other")), names="--observations"),
        Case(KIND, "--observations without the σ it names", _bad_file(
            good.replace('"std": 0.1', '"sem": 0.1')), names="--observations"),
        Case(KIND, "--observations that is not JSON", _bad_file("{"), names="--observations"),
        Case(KIND, "invert --observations reads the file observe wrote", _invert_reads, "ok",
             slow=True, timeout=300),
        Case(KIND, "invert --observations with --obs-drop", _bad_file(
            good, ("--obs-drop", "0.04"), "invert"), names="--obs-drop"),
        Case(KIND, "invert --observations that is not JSON", _bad_file("[1,", (), "invert"),
             names="--observations"),
        Case(KIND, "invert --observations from one event (σ not a number)", _bad_file(
            good.replace('"std": 0.1', '"std": NaN'), (), "invert"), names="--observations"),
        Case(KIND, "invert --observations whose curves' columns differ in length", _bad_file(
            good[:-1] + ', "curves": {"event_id": [1, 1], "slip_m": [0.0], "friction": [0.6]}}',
            (), "invert"), names="--observations"),
    ]

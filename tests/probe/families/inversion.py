"""Probe cases: inversion — ``rsfbench invert``, the ``calibration`` and ``solver-effect``
studies, and the profile intervals they report.

Families, complete by construction:

* every numeric flag of the three commands × its bad values (zero, one, negative, fractional,
  text, non-finite, huge): one line, exit 2, before any work (a case that did work would hang
  past its limit); a few with ``--json``: one JSON document;
* every friction law of ``invert`` (the Nagata law has no published box: refused without one,
  inverted with one);
* profile intervals on analytic misfits (closed forms): few points, small σ, a scan that misses
  the valley, a line that cannot be repaired, a refinement budget of 0 — each interval checked
  against the closed form, or its warning;
* W2 with a small σ and few profile points, end to end (slow);
* Ctrl-C in each long phase of each command (slow, subprocesses): one line, exit 130.
"""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from interruptible import as_typed
from probe.harness import Case, Observed, Wrong, cli, cli_outcome

__all__ = ["cases"]

ROOT = Path(__file__).resolve().parents[3]
Z95 = 1.959963984540054
_FAST = ("--integrator", "Rodas5P", "--rtol", "1e-4", "--atol", "1e-4")
_INVERT = ("invert", "--preset", "W4", "--t-end", "15", *_FAST, "--out", "{tmp}/i")
_EXAMPLE = str(Path(__file__).resolve().parents[3] / "docs" / "examples" / "apparatus.toml")


def _cli_case(name, args, expect="refused", names="", json_mode=False, check=None,
              slow=False, timeout=60.0):
    def run(tmp):
        got = cli_outcome(cli(*[str(a).replace("{tmp}", str(tmp)) for a in args]), json_mode)
        if expect == "refused" and (tmp / "i").exists():
            raise Wrong(f"refused after making its output directory: {got.detail}")
        if check is not None:
            return check(tmp, got)
        return got
    return Case("inversion", name, run, expect, names=names, slow=slow, timeout=timeout)


# --- every numeric flag of every command × its bad values --------------------------------------

_VALUES = {"p": ("0", "-5", "inf", "nan", "abc"), "c": ("0", "-1", "1.5", "abc"),
           "s": ("-1", "1.5", "abc")}


def _flag_cases():
    commands = {
        "invert": (_INVERT, {"--walkers": ("c", "3", "100000"),
                             "--steps": ("s", "1", "10000000"),
                             "--profile-points": ("c", "2", "100000"), "--seed": ("s",),
                             "--workers": ("c", "100000"), "--t-end": ("p",),
                             "--wall-budget": ("p",), "--accuracy": ("p",),
                             "--obs-recurrence": ("p",), "--sigma-recurrence": ("p", "1e-15"),
                             "--obs-drop": ("p",), "--sigma-drop": ("p", "1e-15")}),
    }
    out = []
    for command, (base, flags) in commands.items():
        for flag, (kind, *extra) in flags.items():
            for value in _VALUES[kind] + tuple(extra):
                out.append(_cli_case(f"{command} {flag} {value}", base + (f"{flag}={value}",),
                                     names=flag))
    pairs = {"--b-range": ("0.01,0.009", "a,b", "0.01", "-1,0.01", "nan,0.01", "0.001,1.5"),
             "--lc-range": ("0,1e-6", "1e-6,1e-7", "a,b", "1e-300,1e-6", "1e-7,inf")}
    for flag, specs in pairs.items():
        for spec in specs:
            out.append(_cli_case(f"invert {flag} {spec}", _INVERT + (f"{flag}={spec}",),
                                 names=flag))
    out += [
        _cli_case("invert --walkers 5000 --steps 5000 (10⁷ solves and more)",
                  _INVERT + ("--method", "emcee", "--walkers", "5000", "--steps", "5000"), names="--walkers"),
        _cli_case("invert --t-end 1e6 (over 10,000 cycles a solve)",
                  _INVERT + ("--t-end", "1e6"), names="--t-end"),
        _cli_case("invert --walkers 5000 --steps 5000 with the grid (its last resort's chain)",
                  _INVERT + ("--walkers", "5000", "--steps", "5000"), names="--walkers"),
        _cli_case("invert --grid 5 --method emcee", _INVERT + ("--grid", "5", "--method",
                                                               "emcee"), names="--grid"),
        _cli_case("invert --grid 2", _INVERT + ("--grid", "2"), names="--grid"),
        _cli_case("invert --grid 100000", _INVERT + ("--grid", "100000"), names="--grid"),
        _cli_case("invert --method mcmc", _INVERT + ("--method", "mcmc"), names="--method"),
        _cli_case("invert --curve-sigma 0.01 with the scatter model",
                  _INVERT + ("--curve-sigma", "0.01"), names="--curve-sigma"),
        _cli_case("solver-effect --n 3", ("solver-effect", "--problem", _EXAMPLE,
                                          "--observations", _EXAMPLE, "--b-range",
                                          "0.0086,0.0102", "--lc-range", "3e-8,3e-6", "--n",
                                          "3", "--out", "{tmp}/i"), names="--n"),
        _cli_case("solver-effect --observations a problem file",
                  ("solver-effect", "--problem", _EXAMPLE, "--observations", _EXAMPLE,
                   "--b-range", "0.0086,0.0102", "--lc-range", "3e-8,3e-6", "--out",
                   "{tmp}/i"), names="--observations"),
        _cli_case("solver-effect --b-range reaching b = 1.5",
                  ("solver-effect", "--problem", _EXAMPLE, "--observations", _EXAMPLE,
                   "--b-range", "0.001,1.5", "--lc-range", "3e-8,3e-6", "--out", "{tmp}/i"),
                  names="b = 1.5"),
        _cli_case("work-precision --observations a problem file",
                  ("work-precision", "--problem", _EXAMPLE, "--observations", _EXAMPLE,
                   "--out", "{tmp}/i"), names="--observations"),
        _cli_case("compare --problem with --law", ("compare", "--problem", _EXAMPLE, "--law",
                                                   "aging", "--rtol", "1e-6", "--atol",
                                                   "1e-6"), names="--law"),
        _cli_case("study calibration: check_seeds 5 > seeds 2",
                  ("study", "calibration", "--out", "{tmp}/i", "--set", "seeds=2", "--set",
                   "check_seeds=5"), names="check_seeds"),
    ]
    for name, args in (("invert --walkers 3 --json", _INVERT + ("--walkers", "3")),
                       ("invert --law nagata --json", _INVERT + ("--law", "nagata"))):
        out.append(_cli_case(name, args + ("--json",), json_mode=True))
    return out


# --- every law ---------------------------------------------------------------------------------

def _fit_inside(tmp, got, law="slip"):
    """The JSON document's fit lies in both profile intervals, or a warning says why not."""
    doc = json.loads((tmp / "i" / "inversion.json").read_text())
    if doc["law"] != law:
        raise Wrong(f"inverted the {doc['law']} law, asked for {law}")
    if got.outcome == "retcode":
        if doc["fit"]["success"] is not False:
            raise Wrong(f"exit 1 without a failed fit: {doc['fit']}")
        return got
    f = doc["fit"]
    for name, x in (("b", f["b"]), ("log10_lc", f["log10_lc"])):
        p = doc["profiles"][name]
        if not p["low"] <= x <= p["high"] and not p["warnings"]:
            raise Wrong(f"the fit's {name} = {x:.6g} is outside its own interval "
                        f"[{p['low']:.6g}, {p['high']:.6g}] with no warning")
        if not p["resolved"] and not p["warnings"]:
            raise Wrong(f"the {name} interval is not resolved and no warning says so")
    return Observed("warned" if any(p["warnings"] for p in doc["profiles"].values()) else "ok",
                    f"b in [{doc['profiles']['b']['low']:.5g}, {doc['profiles']['b']['high']:.5g}]")


def _law_cases():
    box = ("--b-range", "0.0095,0.0111", "--lc-range", "1e-8,1e-6")
    run = _INVERT + ("--steps", "0", "--profile-points", "3", "--json")
    out = [
        _cli_case("invert --law nagata without a box (no published fit)",
                  _INVERT + ("--law", "nagata"), names="--law nagata"),
        _cli_case("invert --problem FILE --law aging (a file names its law)",
                  ("invert", "--problem", ROOT / "docs" / "examples" / "apparatus.toml",
                   "--law", "aging", "--obs-recurrence", "3", "--obs-drop", "0.04",
                   *box, "--out", "{tmp}/i"), names="--law"),
    ]
    for law, extra in (("slip", ()), ("aging", ()),
                       ("nagata", ("--b-range", "0.008,0.012", "--lc-range", "1e-8,1e-6"))):
        out.append(_cli_case(f"invert W4 --law {law}, 3 profile points: the fit in its intervals",
                             run + ("--law", law, *extra), expect="ok", json_mode=True,
                             check=lambda tmp, got, law=law: _fit_inside(tmp, got, law),
                             slow=True, timeout=900))
    return out


# --- profile intervals on analytic misfits -------------------------------------------------------

class _Valley:
    """J1 = ((b − b0)/sb)² + ((l − l0 − c (b − b0))/sl)², l = log10 Lc; the scan points (the
    nodes of a 21- or 41-point scan of log10 Lc over (1e-8, 1e-5) m: a search's points fall
    between them) of the b values in ``holes`` within ``width`` of the valley have no cycle."""

    def __init__(self, sb, sl, c=300.0, holes=(), width=0.0):
        self.sb, self.sl, self.c, self.holes, self.width = sb, sl, c, holes, width

    def evaluate(self, b, lc):
        b, l = np.atleast_1d(np.asarray(b, float)), np.log10(np.atleast_1d(lc))
        valley = -6.5 + self.c * (b - 0.0094)
        J = ((b - 0.0094) / self.sb) ** 2 + ((l - valley) / self.sl) ** 2
        cycle = np.ones(b.shape, bool)
        node = np.isclose(l[:, None], np.linspace(-8.0, -5.0, 41), rtol=0, atol=1e-9).any(axis=1)
        for h in self.holes:
            cycle &= ~(np.isclose(b, h, rtol=0, atol=1e-12) & (np.abs(l - valley) < self.width)
                       & node)
        return pd.DataFrame({"misfit": np.where(cycle, J, 2e6),
                             "log_likelihood": np.where(cycle, -0.5 * J, -np.inf)})


def _closed_form(points, sb, sl, refine=12, holes=False, expect_resolved=True):
    def run(tmp):
        from benchmarks.inversion.profile import profile
        values = np.linspace(0.0086, 0.0102, points)
        m = _Valley(sb, sl, holes=(values[2], values[-3]) if holes else (), width=0.35)
        p = profile(m, "b", values, (1e-8, 1e-5), refine=refine)
        half = Z95 * sb
        if not expect_resolved:
            if p.resolved or not p.warnings:
                raise Wrong(f"a one-cell interval [{p.low}, {p.high}] reported as resolved")
            if not (p.low <= 0.0094 - half and p.high >= 0.0094 + half):
                raise Wrong(f"the unresolved interval [{p.low}, {p.high}] is not the points "
                            "about the true one")
            return Observed("warned", p.warnings[0])
        if not (p.resolved and p.monotone) or p.warnings:
            raise Wrong(f"resolved {p.resolved}, monotone {p.monotone}: {p.warnings}")
        for got, want in ((p.low, 0.0094 - half), (p.high, 0.0094 + half)):
            if abs(got - want) > 0.02 * 2 * half:
                raise Wrong(f"interval end {got:.7g}, closed form {want:.7g}")
        return Observed("ok", f"[{p.low:.7g}, {p.high:.7g}]")
    return run


def _unrepairable(tmp):
    from benchmarks.inversion.profile import profile

    class Broken(_Valley):           # b = 0.0092 has no cycle but at Lc < 1e-7.9 (J1 50)
        def evaluate(self, b, lc):
            t = super().evaluate(b, lc)
            bad = np.isclose(np.atleast_1d(b), 0.0092, rtol=0, atol=1e-12)
            low = np.log10(np.atleast_1d(lc)) < -7.9
            t.loc[bad, ["misfit", "log_likelihood"]] = [2e6, -np.inf]
            t.loc[bad & low, ["misfit", "log_likelihood"]] = [50.0, -25.0]
            return t
    p = profile(Broken(3e-4, 0.05, c=0.0), "b", np.linspace(0.0086, 0.0102, 9), (1e-8, 1e-5),
                refine=2)
    if p.monotone or not p.warnings:
        raise Wrong("a profile with a spike of 50 among values < 2 is called monotone")
    half = Z95 * 3e-4
    if not (p.low <= 0.0094 - 0.98 * half and p.high >= 0.0094 + 0.98 * half):
        raise Wrong(f"the jagged profile's interval [{p.low}, {p.high}] cuts the true one")
    return Observed("warned", p.warnings[0])


def _best_inside(tmp):
    from benchmarks.inversion.profile import profile
    b_fit = 0.0094 + 1e-7
    best = (b_fit, 10 ** (-6.5 + 300.0 * 1e-7), 0.01)
    p = profile(_Valley(1e-6, 1e-3), "b", np.linspace(0.0086, 0.0102, 3), (1e-8, 1e-5),
                best=best)
    if not p.low <= b_fit <= p.high:
        raise Wrong(f"the best fit b = {b_fit} is outside its interval [{p.low}, {p.high}]")
    return Observed("ok")


def _api_refused(name, make, names):
    def run(tmp):
        make()
        raise Wrong("accepted")
    return Case("inversion", name, run, "refused", names=names)


class _NoWork:
    """A misfit whose every evaluation is work that a refusal must come before."""

    def __init__(self):
        from problems import preset
        self.problem = preset("W4", law="slip", t_end=15.0)

    def evaluate(self, *a, **k):
        raise Wrong("a forward solve ran before the refusal")


def _invert(**kw):
    from benchmarks.inversion.invert import invert
    return invert(_NoWork(), kw.pop("b_range", (0.0095, 0.0111)),
                  kw.pop("lc_range", (1e-8, 1e-6)), **kw)


def _api_cases():
    from benchmarks.inversion.calibration import coverage
    from benchmarks.inversion.misfit import Misfit
    from benchmarks.inversion.profile import profile
    from benchmarks.inversion.published import prior_box
    from benchmarks.inversion.observations import Observations
    box = ((0.008, 0.011), (1e-8, 1e-5))
    out = [Case("inversion", f"profile of an analytic valley: {n} points, σ_b = {sb:g}",
                _closed_form(n, sb, sl), "ok")
           for n, sb, sl in ((3, 1e-4, 0.05), (5, 1e-6, 1e-3), (21, 1e-6, 1e-3))]
    out += [
        Case("inversion", "profile whose scan misses the valley at two values: repaired",
             _closed_form(9, 4e-4, 0.05, holes=True), "ok"),
        Case("inversion", "profile with refine=0 and a valley narrower than a cell: warned",
             _closed_form(3, 1e-6, 1e-3, refine=0, expect_resolved=False), "warned"),
        Case("inversion", "profile with a line that cannot be repaired: warned, hull kept",
             _unrepairable, "warned"),
        Case("inversion", "profile with a best fit off the grid: inside its interval",
             _best_inside, "ok"),
        _api_refused("profile(parameter='lc')", lambda: profile(_Valley(1, 1), "lc", [1, 2],
                                                                (0.008, 0.01)), "parameter"),
        _api_refused("profile(scan=1)", lambda: profile(_Valley(1, 1), "b", [0.009, 0.01],
                                                        (1e-8, 1e-5), scan=1), "scan"),
        _api_refused("invert(profile_points=2)", lambda: _invert(profile_points=2),
                     "profile_points"),
        _api_refused("invert(profile_points=True)", lambda: _invert(profile_points=True),
                     "profile_points"),
        _api_refused("invert(steps=-1)", lambda: _invert(steps=-1), "steps"),
        _api_refused("invert(walkers=3)", lambda: _invert(walkers=3, method="emcee"), "walkers"),
        _api_refused("invert(walkers × steps > 10⁷)", lambda: _invert(walkers=10_000,
                                                                      steps=10_000,
                                                                      method="emcee"), "walkers"),
        _api_refused("invert(b_range up to 1.5)", lambda: _invert(b_range=(0.001, 1.5)),
                     "b = 1.5"),
        _api_refused("invert(lc_range from 1e-300 m)", lambda: _invert(lc_range=(1e-300, 1e-6)),
                     "Lc = 1e-300"),
        _api_refused("prior_box of the Nagata law", lambda: prior_box("W2", "nagata"),
                     "nagata"),
        _api_refused("coverage(check_seeds=5, seeds=2)",
                     lambda: coverage(None, (0.0094, 3e-7), None, *box, seeds=2,
                                      check_seeds=5), "check_seeds"),
        _api_refused("coverage(check_seeds=-1)",
                     lambda: coverage(None, (0.0094, 3e-7), None, *box, check_seeds=-1),
                     "check_seeds"),
        _api_refused("Misfit with σ of ΔT 1e-15 s",
                     lambda: Misfit(_NoWork().problem, Observations(3.0, 1e-15, 0.04, 0.004),
                                    _rodas()), "sigma_recurrence_s"),
    ]
    return out


def _rodas():
    from integrators import Rodas5P
    return Rodas5P(rtol=1e-4, atol=1e-4)


# --- W2 with a small σ and few points, end to end (the defect's case) ---------------------------

def _w2_small_sigma(tmp):
    from benchmarks.ensemble import ensemble
    from benchmarks.inversion.invert import invert
    from benchmarks.inversion.misfit import Misfit
    from benchmarks.inversion.observations import Observations
    from integrators import Rodas5P
    from problems import preset
    algorithm = Rodas5P(rtol=1e-6, atol=1e-6)
    problem = preset("W2", law="slip", t_end=20.0)
    c = ensemble(problem, algorithm, {"b": [0.0094], "lc": [3e-7]}, progress=False).iloc[0]
    obs = Observations(c.recurrence_s * 1.0006, 0.002 * c.recurrence_s,
                       c.friction_drop * 0.999, 0.002 * c.friction_drop)    # +0.3 σ, −0.5 σ
    inv = invert(Misfit(problem, obs, algorithm), (0.0086, 0.0102), (3e-8, 3e-6), steps=0,
                 profile_points=5)
    for name, fit_x, truth in (("b", inv.fit.b, 0.0094),
                               ("log10_lc", np.log10(inv.fit.lc), np.log10(3e-7))):
        p = inv.profiles[name]
        if not (p.low <= fit_x <= p.high and p.low < truth < p.high):
            raise Wrong(f"{name}: [{p.low:.6g}, {p.high:.6g}] excludes the fit {fit_x:.6g} or "
                        f"the truth {truth:.6g} (J1 = 0.34 there)")
        if not p.resolved or p.warnings:
            raise Wrong(f"{name}: {p.warnings}")
    return Observed("ok", f"b in [{inv.profiles['b'].low:.6g}, {inv.profiles['b'].high:.6g}]")


def _calibration_no_checks(tmp):
    got = cli_outcome(cli("study", "calibration", "--out", tmp / "c", "--set", "seeds=3",
                          "--set", "n=5", "--set", "check_seeds=0"))
    if got.outcome != "ok":
        return got
    text = (tmp / "c" / "calibration.md").read_text()
    if "No seed was checked" not in text:
        raise Wrong("the report does not say that no seed was checked")
    return got


# --- Ctrl-C in each long phase -------------------------------------------------------------------

def _interrupt(args, ready, settle=2.0, prepare=None):
    """Run ``rsfbench ARGS`` (after ``prepare(tmp)``), wait until ``ready(tmp, stdout so far)``,
    then Ctrl-C: one line that says it was interrupted, exit 130 (or 1), no traceback, within
    120 s."""
    def run(tmp):
        import threading
        if prepare is not None:
            prepare(tmp)
        argv = [str(a).replace("{tmp}", str(tmp)) for a in args]
        proc = subprocess.Popen([sys.executable, "-m", "benchmarks.cli", *argv], cwd=ROOT,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=as_typed)
        lines: list[str] = []
        reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)
        reader.start()
        deadline = time.time() + 600
        while time.time() < deadline and not ready(tmp, "".join(lines)) and proc.poll() is None:
            time.sleep(0.2)
        if proc.poll() is not None:
            raise Wrong(f"finished (exit {proc.returncode}) before it could be interrupted")
        time.sleep(settle)
        proc.send_signal(signal.SIGINT)
        try:
            err = proc.stderr.read() if proc.wait(timeout=120) is not None else ""
        except subprocess.TimeoutExpired:
            proc.kill()
            raise Wrong("did not stop within 120 s of Ctrl-C") from None
        # a study prints its progress on stderr (the command's stdout is its summary): what
        # must hold is one error line, the last, and no traceback
        errors = [x for x in err.strip().splitlines() if x.startswith("rsfbench: error")]
        last = err.strip().splitlines()[-1] if err.strip() else ""
        if "Traceback" in err or proc.returncode not in (130, 1) or len(errors) != 1 \
                or last != errors[0] or "interrupted" not in last:
            at = err.find("Traceback")
            shown = err[at:at + 600] + " ... " + err[-200:] if at >= 0 else err[-400:]
            raise Wrong(f"exit {proc.returncode}, stderr: {shown!r}")
        return Observed("retcode", errors[0])
    return run


def _interrupt_cases():
    invert = ("invert", "--preset", "W4", "--t-end", "15", *_FAST, "--method", "emcee", "--walkers", "8",
              "--steps", "100000", "--profile-points", "5", "--out", "{tmp}/i", "--no-progress")
    out = [Case("inversion", f"Ctrl-C during invert's {phase}",
                _interrupt(invert, lambda tmp, seen, text=text: text in seen), "retcode",
                slow=True, timeout=900)
           for phase, text in (("fit", "least-squares fit"), ("profile", "profile of b"),
                               ("posterior", "posterior:"))]
    out.append(Case("inversion", "Ctrl-C during calibration",
                    _interrupt(("study", "calibration", "--out", "{tmp}/o", "--set", "seeds=50",
                                "--set", "n=21"), lambda tmp, seen: (tmp / "o").exists(),
                               settle=8.0), "retcode", slow=True, timeout=900))
    # solver-effect reads the full work-precision study's wp_full.csv (refused without it): the
    # project's record is copied in first, and the Ctrl-C comes 20 s into the run, after the
    # start-up and the code's hash (a few seconds), inside the inversions
    out.append(Case("inversion", "Ctrl-C during solver-effect",
                    _interrupt(("study", "solver-effect", "--out", "{tmp}/o", "--set", "n=5"),
                               lambda tmp, seen: True, settle=20.0, prepare=_with_wp_full),
                    "retcode", slow=True, timeout=900))
    return out


def _with_wp_full(tmp):
    (tmp / "o").mkdir()
    shutil.copyfile(ROOT / "results" / "wp_full.csv", tmp / "o" / "wp_full.csv")


def cases() -> list[Case]:
    return (_flag_cases() + _law_cases() + _api_cases()
            + [Case("inversion", "invert W2 with σ = 0.2 % and 5 profile points: the fit and "
                    "the truth in both intervals", _w2_small_sigma, "ok", slow=True,
                    timeout=900),
               Case("inversion", "study calibration, check_seeds=0, writes its report",
                    _calibration_no_checks, "ok", slow=True, timeout=900)]
            + _interrupt_cases())

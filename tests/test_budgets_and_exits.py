"""Issue 45, items 5 and 6: every solve of an inversion, a lab fit and a solver check has a
budget, and one over it is a failure that is counted and never read as physics; the commands
end in one line (no traceback) where a hostile run found one; --version and --help on stdout.

The budgets here are tiny on purpose: a solve stopped by one fails in milliseconds, so these
tests are fast; none asserts a speed."""

import json
import re
import subprocess
import sys
import warnings

import numpy as np
import pandas as pd
import pytest

from interruptible import as_typed

from benchmarks.lab.independent_model import reference_friction, synthetic_record
from benchmarks.lab.fit import LabFitWarning
from benchmarks.lab.model import LabModel
from benchmarks.lab.step_data import lab_record_from

COLUMNS = ["time=time_s", "load_point=load_point_um:um", "friction=friction"]
TRUTH = dict(a=0.006, b=0.009, dc=10e-6, k=3e3)
#: s: a budget no solve meets (each stops at its first check of the clock)
TINY = 1e-9


def _cli(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "benchmarks.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


def _step_record():
    t = np.linspace(0.0, 30.0, 1500)
    df = synthetic_record(t, (1e-6, 1e-5), (10.0,), **TRUTH, noise=6e-4, seed=8)
    return lab_record_from(df, COLUMNS)


# --- --version and --help: the command's output, on the standard output --------------------
@pytest.mark.parametrize("args, starts", [
    (["--version"], "rsfbench "),
    (["--help"], "usage: rsfbench"),
    (["simulate", "--help"], "usage: rsfbench simulate"),
    (["lab", "fit", "--help"], "usage: rsfbench lab fit"),
])
def test_version_and_help_are_on_the_standard_output(args, starts):
    """``$(rsfbench --version)`` was empty: main() points sys.stdout at the standard error
    while a command runs, and --version and --help printed there."""
    out = _cli(*args)
    assert out.returncode == 0
    assert out.stdout.startswith(starts), (out.stdout[:200], out.stderr[:200])
    assert starts not in out.stderr


# --- one line, not a traceback --------------------------------------------------------------
@pytest.mark.parametrize("path, columns, match", [
    (None, ["time=t:s", "shear_force=fs:N"], "path must be the recording's file name"),
    ("rec.csv", None, "columns must map channels"),
])
def test_read_recording_names_a_missing_argument(path, columns, match):
    from benchmarks.lab.channels import read_recording
    with pytest.raises(ValueError, match=match):
        read_recording(path, columns, normal_force=1e6)


def test_work_precision_refuses_a_problem_without_stick_slip(tmp_path):
    """A steady slider has no event: before, its references crawled at 1e-12 (over 2 minutes
    for 13 s of 40 here) or disagreed, and the command ended in an internal error (exit 3)."""
    problem = tmp_path / "steady.toml"
    problem.write_text('name = "steady"\nmass = 1100.0\nstiffness = 1.184e8\n'
                       'normal_force = 997500.0\nt_end = 40.0\nmu0 = 0.6\n\n'
                       '[law]\nname = "slip"\na = 0.008\nb = 0.004\nlc = 3e-7\nv0 = 1e-5\n\n'
                       '[loading]\nvl = 7.5e-5\n\n[initial]\nslowdown = 1.1\n')
    out = _cli("work-precision", "--problem", problem, "--out", tmp_path / "wp", "--json")
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1
    assert "no stick–slip events to measure" in out.stderr
    assert json.loads(out.stdout)["exit_status"] == 2


def test_a_ctrl_c_in_the_lab_posterior_is_one_exception_and_no_emcee_traceback(
        monkeypatch, capsys):
    """emcee prints a traceback for any exception of the log-probability, an interruption
    included; the posterior holds a Ctrl-C until its step ends, then raises it."""
    pytest.importorskip("emcee")
    from benchmarks.lab import fit as lab_fit
    from benchmarks.lab.sampling import sample_lab
    fit = lab_fit.fit_lab(LabModel(_step_record(), "aging", detrend="none"))
    calls = {"n": 0}
    residual = lab_fit._Problem.residual

    def interrupted(self, x):
        calls["n"] += 1
        if calls["n"] == 25:                       # in the posterior's first steps
            raise KeyboardInterrupt
        return residual(self, x)

    monkeypatch.setattr(lab_fit._Problem, "residual", interrupted)
    capsys.readouterr()
    with pytest.raises(KeyboardInterrupt, match=r"interrupted at step [1-3] of 40"):
        sample_lab(fit, walkers=10, steps=40)
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "emcee" not in out + err


# --- budgets: a solve over its budget is a counted failure, never physics -------------------
def test_a_lab_solve_over_its_budget_is_no_friction_and_fails_the_check():
    from benchmarks.lab.checks import check_lab_solver
    from benchmarks.lab.fit import fit_lab
    rec = _step_record()
    model = LabModel(rec, "aging", detrend="none")
    assert model.wall_budget is not None           # a budget by default
    fit = fit_lab(model)
    assert fit.success and fit.failed_solves == 0
    import dataclasses

    from integrators import make_algorithm
    starved = dataclasses.replace(model, wall_budget=TINY)
    p = {n: fit.values[n] for n in fit.free}
    mu, run = starved.response(**p, algorithm=make_algorithm("scipy-Radau", 1e-8, 1e-8))
    assert run.retcode.value == "WallTime" and np.isnan(mu).all()
    check = check_lab_solver(dataclasses.replace(fit, model=starved))
    assert check["checked"] and not check["passed"] and not check["references_agree"]
    # the fit's own model (compiled) runs out first; a reference through solve says WallTime
    assert "did not finish" in check["reason"] and "wall budget" in check["reason"]
    # a step budget of 3 (the project's slider, by finite differences): every solve of the
    # fit runs out; a failed fit that counts them
    steps = dataclasses.replace(model, algorithm=dataclasses.replace(
        make_algorithm("Rodas5P", 1e-10, 1e-10), max_steps=3))
    with warnings.catch_warnings():          # it says what failed: asserted here instead
        warnings.simplefilter("ignore", LabFitWarning)
        failed = fit_lab(steps, start=p)
    assert not failed.success and failed.failed_solves == failed.solves > 0


def test_the_independent_reference_stops_at_its_budget():
    rec = _step_record()
    with pytest.raises(RuntimeError, match="ran out of its wall budget"):
        reference_friction(rec.t, rec.velocities, rec.switch_times, **TRUTH, wall_budget=TINY)
    with pytest.raises(ValueError, match="wall_budget"):
        reference_friction(rec.t, rec.velocities, rec.switch_times, **TRUTH, wall_budget=0.0)


def _misfit(wall_budget=None, max_steps=None):
    import dataclasses

    from benchmarks.inversion import Misfit
    from benchmarks.inversion.misfit import synthetic
    from integrators import make_algorithm
    from problems import window
    algorithm = make_algorithm("Rodas5P", rtol=1e-6, atol=1e-6)
    if max_steps is not None:
        algorithm = dataclasses.replace(algorithm, max_steps=max_steps)
    return Misfit(window("W2", "slip"), synthetic(0.9, 0.02, 0.05, seed=0), algorithm,
                  wall_budget=wall_budget, workers=1)


def test_an_inversion_point_over_its_budget_is_a_failed_point_and_counted():
    """A step budget of 5 (W2's points need thousands): every solve runs out of it."""
    from benchmarks.inversion.adaptive import grid_posterior
    from benchmarks.inversion.objectives import NO_CYCLE_J1
    misfit = _misfit(max_steps=5)
    table = misfit.evaluate([0.0092, 0.0094], [3e-7, 3e-7])
    assert (table.retcode == "MaxSteps").all() and (table.classification == "failed").all()
    assert np.isneginf(table.log_likelihood).all() and (table.misfit == NO_CYCLE_J1).all()
    assert misfit.failures == {"solves": 2, "failed": 2, "over_budget": 2,
                               "wall_budget_s": None}
    post = grid_posterior(misfit, (0.0088, 0.0096), (1e-7, 1e-6), n=3)
    assert post.n_failed == 9 and post.cells.failed.all() and not post.cells.mass.any()
    assert misfit.failures["failed"] == 11
    ok = _misfit()                       # the same points within their budget: counted
    assert (ok.evaluate([0.0092], [3e-7]).retcode == "Success").all()
    assert ok.failures == {"solves": 1, "failed": 0, "over_budget": 0, "wall_budget_s": None}


def test_the_solver_check_reads_no_cycle_from_an_unfinished_reference():
    """A reference stopped by its budget vouches for nothing: the check says its solves did
    not finish, rather than that the box has no limit cycle."""
    from benchmarks.inversion.misfit import synthetic
    from benchmarks.inversion.solver_check import WALL_BUDGET, check_solver
    from integrators import make_algorithm
    from problems import window
    assert WALL_BUDGET is not None
    check = check_solver(window("W2", "slip"), make_algorithm("Rodas5P", rtol=1e-6, atol=1e-6),
                         synthetic(0.9, 0.02, 0.05, seed=0), (0.0088, 0.0096), (1e-7, 1e-6),
                         workers=1, wall_budget=TINY)
    assert not check.passed and check.nothing_to_check
    # every reference solve stopped: the message leads with it (and the budget)
    assert check.message.startswith("every one of the references' 28 solves failed or ran "
                                    "out of its budget")


def test_invert_has_a_budget_per_solve_by_default():
    from benchmarks.cli.main import build_parser
    args = build_parser().parse_args(["invert", "--preset", "W2"])
    assert args.wall_budget is not None and args.wall_budget > 0
    args = build_parser().parse_args(["lab", "fit", __file__, "--column", "time=t"])
    assert args.wall_budget is not None and args.wall_budget > 0


@pytest.mark.slow                      # a few seconds of solves: make test-slow
def test_an_invert_whose_solves_run_out_says_how_many(tmp_path):
    out = _cli("invert", "--preset", "W2", "--b-range", "0.0088,0.0096", "--lc-range",
               "1e-7,1e-6", "--no-solver-check", "--grid", "3", "--profile-points", "3",
               "--wall-budget", "1e-9", "--out", tmp_path / "inv", "--json", "--workers", "1")
    assert out.returncode == 1 and "Traceback" not in out.stderr
    doc = json.loads(out.stdout)
    assert doc["solves"]["over_budget"] > 0 and doc["solves"]["wall_budget_s"] == 1e-9
    assert doc["solves"]["failed"] >= doc["solves"]["over_budget"]
    assert "forward solves failed" in out.stderr and "never read as one" in out.stderr


@pytest.mark.parametrize("stop, status, what", [
    ("raise KeyboardInterrupt", 130, "Ctrl-C"),
    ("os.kill(os.getpid(), signal.SIGTERM); time.sleep(5)", 143, "SIGTERM")])
def test_a_stop_while_the_command_line_imports_is_one_line(tmp_path, stop, status, what):
    """The console script imports the harness (about a second: numba, scipy, the registry)
    before main() can catch anything: a Ctrl-C there was a traceback and a death by SIGINT
    (exit −2), a SIGTERM a silent death (a hostile probe). Each is made here at the import of
    the command line, as one at that moment would be."""
    from pathlib import Path
    script = Path(sys.executable).parent / "rsfbench"
    if not script.exists():
        pytest.skip("no rsfbench console script next to this Python (not installed)")
    (tmp_path / "sitecustomize.py").write_text(
        "import os, signal, sys, time\n"
        "class Interrupt:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'benchmarks.cli.main':\n"
        f"            {stop}\n"
        "sys.meta_path.insert(0, Interrupt())\n")
    import os
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    out = subprocess.run([str(script), "--version"], capture_output=True, text=True,
                         timeout=120, env=env)
    assert out.returncode == status, (out.returncode, out.stderr[-500:])
    assert "Traceback" not in out.stderr and out.stdout == ""
    assert out.stderr.strip() == f"rsfbench: error: interrupted ({what}) while starting"


@pytest.mark.slow                      # a fit, then a posterior interrupted: make test-slow
def test_a_ctrl_c_in_lab_fit_posterior_is_one_line_and_exit_130():
    """emcee printed its traceback for the interruption (found by a hostile run); now one line
    says where it stopped, and nothing is written."""
    pytest.importorskip("emcee")
    from pathlib import Path
    basalt = (Path(__file__).resolve().parent / "data" / "lab-velocity-steps"
              / "velstep4_BRAVA_expb819_basalt.txt")
    code, text = _interrupted_run(
        ["lab", "fit", str(basalt), "--column=time=Time(s):s", "--column=friction=Friction",
         "--column=load_point=Displ(microns):um", "--posterior", "--steps", "100000",
         "--no-profiles", "--no-solver-check"],
        "stderr", b"it/s", pause=1.0)               # emcee's progress bar: it is sampling
    assert code == 130, text[-1000:]
    assert "Traceback" not in text and "emcee:" not in text
    last = text.replace("\r", "\n").strip().splitlines()[-1]
    assert re.fullmatch(r"rsfbench: error: lab fit interrupted \(Ctrl-C\): the posterior was "
                        r"interrupted at step \d+ of 100000; nothing written", last), last


@pytest.mark.parametrize("where", ["log_prob", "emcee", "signal", "sigterm"])
def test_a_ctrl_c_in_a_posterior_names_the_step_it_came_in(where):
    """Inside the solves the Ctrl-C is caught and held until the step ends; a real SIGINT
    anywhere else in the step (emcee's code, the log-probability after its solves: emcee would
    print a traceback) only marks the run stopped; off the main thread, where Python's own
    handler stays, it arrives bare. Each way one KeyboardInterrupt names the step (a bare one
    gave "interrupted (Ctrl-C): ; nothing written"). A SIGTERM that the command line takes
    (stop_on_sigterm) is held as a Ctrl-C is, and the stop is said to be a SIGTERM's."""
    import os
    import signal
    from benchmarks.inversion.posterior import CtrlC, run_sampler
    from benchmarks.records import interrupts

    def solve():
        raise KeyboardInterrupt                    # a Ctrl-C during the solves

    class Sampler:
        def sample(self, p0, iterations, progress):
            for step in range(1, iterations + 1):
                if step == 4:
                    if where == "emcee":
                        raise KeyboardInterrupt
                    if where in ("signal", "sigterm"):      # outside stopped.call
                        os.kill(os.getpid(), signal.SIGTERM if where == "sigterm"
                                else signal.SIGINT)
                    else:
                        assert stopped.call(solve) is None
                yield step

    stopped, before = CtrlC(), signal.getsignal(signal.SIGINT)
    term = signal.getsignal(signal.SIGTERM)
    try:
        if where == "sigterm":
            interrupts.stop_on_sigterm()
        handler = signal.getsignal(signal.SIGTERM)
        with pytest.raises(KeyboardInterrupt,
                           match=r"^the posterior was interrupted at step 4 of 10$"):
            run_sampler(Sampler(), None, 10, False, stopped)
        assert signal.getsignal(signal.SIGINT) is before                    # given back
        assert signal.getsignal(signal.SIGTERM) is handler
        assert interrupts.stopped_by()[0] == ("SIGTERM" if where == "sigterm" else "Ctrl-C")
    finally:
        signal.signal(signal.SIGTERM, term)
        interrupts._TERMINATED.clear()
    stopped = CtrlC()
    run_sampler(Sampler(), None, 3, False, stopped)       # ends before step 4: no interruption
    assert not stopped


def test_a_ctrl_c_that_compiled_code_passes_on_is_an_interrupt():
    """numba's compiled code hit by a Ctrl-C while it calls back into Python raises a
    SystemError whose context is the KeyboardInterrupt (a hostile probe: exit 3, "internal
    error"): it counts as an interrupt; a SystemError of its own does not."""
    from benchmarks.cli.main import _interrupted
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("returned a result with an exception set")
    except SystemError as exc:
        assert isinstance(_interrupted(exc), KeyboardInterrupt)
    assert _interrupted(SystemError("a bug")) is None


@pytest.mark.parametrize("args,status", [(["--version"], 0),
                                         (["lab", "fit", "/nonexistent", "--json"], 2)])
def test_a_closed_standard_output_is_no_crash(args, status):
    """Started with its standard output closed (``>&-``), Python leaves ``sys.stdout`` None:
    rsfbench failed with an AttributeError before any command ran (a hostile probe). Its
    output now goes nowhere, its errors still to the standard error, with their status."""
    import os
    import subprocess
    import sys
    run = subprocess.run([sys.executable, "-m", "benchmarks.cli", *args],
                         preexec_fn=lambda: os.close(1), stderr=subprocess.PIPE, text=True,
                         timeout=120)
    assert run.returncode == status, run.stderr
    assert "Traceback" not in run.stderr and "AttributeError" not in run.stderr
    if status:
        assert run.stderr.count("\n") == 1 and "does not exist" in run.stderr


@pytest.mark.slow                      # a fit, then the nested draws interrupted
def test_a_ctrl_c_in_the_nested_draws_leaves_no_directory_it_made(tmp_path):
    """invert --nuisance said 'nothing written to DIR' on Ctrl-C but left DIR behind, empty
    (a hostile run): the directory this run made is removed again when it is empty."""
    out = tmp_path / "made_here"
    code, text = _interrupted_run(
        ["invert", "--preset", "W2", "--law", "slip", "--nuisance", "k=3%", "--nuisance",
         "vls=2%", "--steps", "5000", "--no-solver-check", "--out", str(out)],
        "stdout", b"draws of the constants", pause=2.0)   # the command says it starts them
    assert code == 130 and "Traceback" not in text, text[-1000:]
    assert "nothing written" in text and not out.exists()


def test_a_sigterm_a_library_swallowed_still_ends_with_143(capsys):
    """ctypes prints an exception raised in a callback (numba's compiler's) and goes on: a
    SIGTERM there was lost, and the run ended with status 0 (a hostile probe)."""
    from benchmarks.cli.main import _swallowed
    from benchmarks.records import interrupts
    assert _swallowed(0) == 0 and capsys.readouterr().err == ""
    interrupts.note_sigterm()
    try:
        assert _swallowed(2) == 2
        assert _swallowed(0) == 143
        assert "SIGTERM came while a library held" in capsys.readouterr().err
    finally:
        interrupts._TERMINATED.clear()


def test_a_sigterm_while_a_file_is_written_leaves_no_temporary_and_exit_143(tmp_path):
    """A SIGTERM killed the process mid-write and left its 0-byte temporary (a hostile probe).
    It now takes the Ctrl-C path: the temporary removed, no output file, one line, status
    143. The write is held in its fsync (patched to sleep) until the SIGTERM comes."""
    import os
    import signal
    import time
    from pathlib import Path
    (tmp_path / "sitecustomize.py").write_text(
        "import os, time\n"
        "_fsync = os.fsync\n"
        "def fsync(fd):\n"
        "    time.sleep(60)\n"
        "    return _fsync(fd)\n"
        "os.fsync = fsync\n")
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(root)])}
    proc = subprocess.Popen([sys.executable, "-m", "benchmarks.cli", "simulate", "--preset",
                             "paper-example", "--t-end", "1", "--save", "out.csv"],
                            cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        started = time.monotonic()
        while not list(tmp_path.glob(".rsfbench-tmp-*")):
            assert time.monotonic() - started < 120 and proc.poll() is None
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 143, err[-500:]
    assert err.decode().strip().splitlines()[-1] == "rsfbench: error: interrupted (SIGTERM)"
    assert not list(tmp_path.glob(".rsfbench-tmp-*")) and not (tmp_path / "out.csv").exists()


def _interrupted_run(command: list, stream: str, marker: bytes, pause: float):
    """``(exit status, text)``: ``rsfbench COMMAND`` run until ``marker`` appears on its
    ``stream`` ("stdout" or "stderr"), then ``pause`` s, then SIGINT; the text is what that
    stream said before it and the standard error after."""
    import os
    import select
    import signal
    import time
    proc = subprocess.Popen([sys.executable, "-m", "benchmarks.cli", *command],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=as_typed)
    said, started, pipe = b"", time.monotonic(), getattr(proc, stream)
    try:
        while marker not in said:
            assert time.monotonic() - started < 600 and proc.poll() is None, said[-500:]
            if select.select([pipe], [], [], 1.0)[0]:
                said += os.read(pipe.fileno(), 65536)
        time.sleep(pause)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    return proc.returncode, (said + err).decode()


def test_a_signal_during_an_uninterrupted_block_is_raised_after_it():
    """A file renamed and the entry listing it go together. The block masked SIGINT and SIGTERM
    in the main thread, but another thread (numba's, a pool's) takes a signal sent to the
    process, and its Python handler then ran in the main thread inside the block (a review's
    check). It is now deferred by the block's own handlers: here with an idle thread alive."""
    import os
    import signal
    import threading
    import time
    from benchmarks.records import interrupts
    from benchmarks.records.interrupts import Terminated, stop_on_sigterm, stopped_by, uninterrupted
    idle = threading.Event()
    other = threading.Thread(target=idle.wait, daemon=True)
    other.start()
    before, sigint = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)
    try:
        stop_on_sigterm()
        signal.signal(signal.SIGINT, signal.default_int_handler)   # a runner may ignore it
        for signum, raised in ((signal.SIGINT, KeyboardInterrupt), (signal.SIGTERM, Terminated)):
            done = []
            with pytest.raises(raised):
                with uninterrupted():
                    os.kill(os.getpid(), signum)
                    time.sleep(0.05)                # a handler would have run by now
                    done.append(True)
            assert done == [True]
        assert stopped_by() == ("SIGTERM", 143)
    finally:
        signal.signal(signal.SIGTERM, before)
        signal.signal(signal.SIGINT, sigint)
        interrupts._TERMINATED.clear()              # later tests' Ctrl-C is a Ctrl-C
        idle.set()

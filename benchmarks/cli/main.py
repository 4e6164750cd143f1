"""``rsfbench``: the command line of the harness.

    rsfbench simulate --preset W2 --law aging --json
    rsfbench windows --out results          # W1–W4 limit cycles, both laws, CSV + Markdown
    rsfbench integrators                    # the registry
    rsfbench work-precision --study quick   # every integrator over a ladder of settings
    rsfbench convergence --json             # observed orders of the fixed-step methods
    rsfbench convergence --fixed-steps      # ... and of the compiled stiff methods, control off
    rsfbench sweep --preset W2 --b 0.009:0.0098:0.0001 --lc 1e-7:1e-6:9log --json
    rsfbench reproduce --out results        # what `make reproduce` runs (--full: reproduce-full)
    rsfbench study --list                   # the studies behind results/, one by one:
    rsfbench study speedup --set scipy_budget=3600   # the paper's 1/10,000 claim
    rsfbench readme [--check]               # refill the README's numbers from results/
    rsfbench lab shs --holds 1 10 100       # a slide-hold-slide test and its healing
    rsfbench lab fit rec.txt --column ...   # (a, b, Dc) of a velocity-step record
    rsfbench observe rec.csv --columns rec.toml   # a recording in: observations.json out
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import os
import shlex
import signal
import sys
import warnings

from benchmarks.cli import (
    args as cli_args,
    design,
    invert,
    lab,
    observe,
    reproduce,
    self_check,
    simulate,
    solver_effect,
    sweep,
    work_precision,
)
from benchmarks.cli.args import (
    Parser,
    RunStopped,
    ShowVersion,
    add_overwrite_options,
    say,
    stop_on_sigterm,
    stopped_by,
    wants_json,
)
from benchmarks.records.files import allow_overwrite, begin_run
from benchmarks.records.optional import MissingExtra

__all__ = ["main", "build_parser", "COMMANDS", "exit_program"]

#: the command modules, each adding its commands' parsers (``add_parsers``) in this order: the
#: order of ``rsfbench --help``'s list
COMMANDS = (simulate, work_precision, reproduce, sweep, invert, lab, observe, solver_effect,
            self_check, design)


def build_parser() -> Parser:
    """The ``rsfbench`` parser: one subcommand per parser that the modules of
    :data:`COMMANDS` add.

    Returns
    -------
    argparse.ArgumentParser
        The parser (its errors are one line and exit status 2).
    """
    parser = Parser(prog="rsfbench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--version", action=ShowVersion)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parsers(sub)
    add_overwrite_options(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run one command; return its exit status: 0 done, 1 the run failed (its retcode, or one
    line, says why), 2 a usage error (one line on stderr; with --json also one JSON document on
    stdout), 3 an internal error, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM).

    Whatever a library writes to the standard output (assimulo's Fortran and SUNDIALS' warnings,
    also from pool workers) goes to the standard error instead, so that the standard output holds
    the command's own output only: with ``--json``, exactly one JSON document. Run as a program
    (``argv`` None) the redirection is kept until exit, when Fortran flushes its buffers.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after ``rsfbench`` (default: the program's, ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (above); a command's errors never leave as a traceback.
    """
    json_mode = wants_json(argv)
    with _library_output_to_stderr(keep=argv is None), warnings.catch_warnings():
        warnings.showwarning = _show_warning
        status = 130
        try:
            if argv is None:
                stop_on_sigterm()                 # a SIGTERM cleans up as a Ctrl-C does
            status = _swallowed(_command(argv, json_mode))
        except KeyboardInterrupt:                 # a Ctrl-C while an error was being said:
            status = stopped_by()[1]              # that line stands
        finally:
            if argv is None:                      # a program whose status is decided: a
                _leave_on_stops(status)           # Ctrl-C while it exits leaves with it
        return status


#: modules whose compiled code prints (Fortran's unit 6, C's stdio): where one is loaded, the
#: program exits the usual way, which flushes their buffers
_PRINTING = ("assimulo", "numbalsoda", "scikits.odes", "scikits_odes_sundials", "sksundae")


def exit_program(status: int):
    """End the program ``rsfbench`` with ``status``, its output flushed and the exit handlers
    run. Where no thread but this one runs and no module of :data:`_PRINTING` is loaded, the
    interpreter's teardown (freeing numba's, scipy's and matplotlib's modules object by
    object: 0.3–0.5 s after a lab fit, timed by hand) is skipped; else ``sys.exit``."""
    import atexit
    import threading
    if threading.active_count() > 1 or any(m in sys.modules for m in _PRINTING):
        sys.exit(status)
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr, cli_args._OUTPUT, sys.__stdout__, sys.__stderr__):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(status)


def _swallowed(status: int) -> int:
    """``status``, or 143 with one line where a SIGTERM came and a library swallowed the
    interruption it raised (ctypes prints an exception raised in a callback, as numba's
    compiler's, and goes on): the command finished, and its files are whole."""
    if status != 0 or stopped_by()[1] != 143:
        return status
    print("rsfbench: error: a SIGTERM came while a library held the interpreter; the command "
          "finished (its files are whole)", file=sys.stderr)
    return 143


def _leave_on_stops(status: int) -> None:
    """From now on a Ctrl-C or SIGTERM leaves at once with ``status``. signal.signal runs a
    signal's handler that is pending before it sets the new one: a second stop, raised there,
    is taken and the handler set again."""
    for signum in (signal.SIGTERM, signal.SIGINT):
        while True:
            try:
                signal.signal(signum, functools.partial(_leave, status))
                break
            except KeyboardInterrupt:
                continue


def _leave(status: int, signum, frame) -> None:
    """Leave now with ``status``: a Ctrl-C after the command's status was decided."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


def _command(argv: list[str] | None, json_mode: bool) -> int:
    """Parse ``argv``, run the command, and turn what it raises into one line and a status."""
    args = None
    try:
        begin_run()                               # nothing written yet, no inputs known
        args = build_parser().parse_args(argv)
        allow_overwrite(getattr(args, "overwrite", False))
        args.command_line = shlex.join(["rsfbench", *(sys.argv[1:] if argv is None else argv)])
        return args.func(args)
    except ValueError as exc:                     # a user's mistake: say which, no traceback
        return _fail(_one_line(exc), 2, json_mode)
    except (RunStopped, OSError, MissingExtra) as exc:   # the run could not go on: say why
        return _fail(_one_line(exc), 1, json_mode)
    except KeyboardInterrupt as exc:              # a command may say what it kept
        return _interrupt(exc, args, json_mode)
    except Exception as exc:                      # a bug: one line, the traceback on request
        if _interrupted(exc) is not None:         # a Ctrl-C that compiled code passed on
            return _interrupt(_interrupted(exc), args, json_mode)
        if os.environ.get("RSFBENCH_DEBUG"):
            raise
        return _fail(f"internal error: {type(exc).__name__}: {_one_line(exc)} (set "
                     "RSFBENCH_DEBUG=1 for the traceback; please report it)", 3, json_mode)


def _interrupt(exc: KeyboardInterrupt, args, json_mode: bool) -> int:
    """The one line of a Ctrl-C or SIGTERM (``exc``'s own words if it has any), status 130 or
    143."""
    kept = (" (a sweep keeps its finished points: run it again to resume)"
            if getattr(args, "command", None) == "sweep" else "")
    what, status = stopped_by()
    return _fail(_one_line(exc) if str(exc) else f"interrupted ({what}){kept}", status,
                 json_mode)


def _interrupted(exc: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C that caused ``exc``, or None: numba's compiled code hit by one while it
    calls back into Python returns "a result with an exception set", a SystemError whose
    context is the KeyboardInterrupt."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _one_line(exc: BaseException) -> str:
    text = str(exc) if str(exc) else type(exc).__name__
    if isinstance(exc, OSError) and exc.filename is not None:
        text = f"{exc.strerror or text}: {exc.filename}"
    return " ".join(text.split())


def _fail(message: str, status: int, json_mode: bool) -> int:
    prefix = "" if message.startswith("rsfbench") else "rsfbench: error: "
    print(f"{prefix}{message}", file=sys.stderr)
    if json_mode:
        try:
            say(json.dumps({"error": message, "exit_status": status}))
        except OSError:                   # the standard output is gone (a closed pipe, a
            pass                          # full disk): the standard error has said it
    return status


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"rsfbench: warning: {' '.join(str(message).split())}", file=sys.stderr)


def _stdout_to_devnull() -> None:
    """Descriptor 1 and ``sys.stdout`` on /dev/null: a program started with its standard
    output closed runs as one whose output nobody reads (Python leaves ``sys.stdout`` None,
    and every print, and the redirection below, would fail)."""
    fd = os.open(os.devnull, os.O_WRONLY)
    if fd != 1:
        os.dup2(fd, 1)
        os.close(fd)
    sys.stdout = sys.__stdout__ = io.TextIOWrapper(os.fdopen(1, "wb", closefd=False),
                                                   encoding="utf-8", line_buffering=True)


@contextlib.contextmanager
def _library_output_to_stderr(keep: bool):
    """While a command runs, the standard output is the standard error — for Python code
    (``sys.stdout``) and for C and Fortran (file descriptor 1) — and :func:`say` writes to the
    standard output as it was. ``keep``: leave descriptor 1 on the standard error at the end (a
    program exits next, and Fortran flushes unit 6 at exit)."""
    if sys.stdout is None:                    # started with it closed (>&-): to /dev/null
        _stdout_to_devnull()
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    entry, mine = sys.stdout, None
    if sys.stdout is sys.__stdout__:          # the real stdout: write to it by the saved copy
        mine = io.TextIOWrapper(os.fdopen(os.dup(saved), "wb", buffering=0),
                                encoding=entry.encoding, errors=entry.errors, line_buffering=True)
    outer = cli_args._OUTPUT                  # a command run by a command (the probe)
    cli_args._OUTPUT = mine or entry          # under a test's capture: the capture
    sys.stdout = sys.stderr
    try:
        yield
    finally:
        sys.stdout = entry
        cli_args._OUTPUT = outer
        if mine is not None:
            mine.close()
        if not keep:
            os.dup2(saved, 1)
        os.close(saved)


if __name__ == "__main__":
    sys.exit(main())

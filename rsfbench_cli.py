"""The ``rsfbench`` console script (``[project.scripts]``): :func:`benchmarks.cli.main.main`,
imported inside a handler so that a Ctrl-C or SIGTERM while the harness imports — a second or
more (numba, scipy, the integrators' registry) before ``main()`` can catch anything — ends as
one while a command runs does: one line on the standard error and exit status 130 (143 for a
SIGTERM), not a traceback and a death by the signal. It sits outside the ``benchmarks`` package
on purpose: importing any module of that package first runs its ``__init__``, which imports the
integrators.
"""

import signal
import sys

__all__ = ["main"]


class _Terminated(KeyboardInterrupt):
    """A SIGTERM while the harness imports (``main()`` takes SIGTERM over after that)."""


def _terminated(signum, frame):
    raise _Terminated


def main(argv: list[str] | None = None) -> int:
    """:func:`benchmarks.cli.main.main` (``argv``: the arguments, default the command line's)."""
    try:
        if argv is None:
            signal.signal(signal.SIGTERM, _terminated)
        from benchmarks.cli.main import exit_program, main as run
    except KeyboardInterrupt as exc:
        what, status = ("SIGTERM", 143) if isinstance(exc, _Terminated) else ("Ctrl-C", 130)
        print(f"rsfbench: error: interrupted ({what}) while starting", file=sys.stderr)
        return status
    status = run(argv)
    if argv is None:                   # the program: it ends here (exit_program)
        exit_program(status)
    return status


if __name__ == "__main__":
    sys.exit(main())

"""The ``rsfbench`` console script (``[project.scripts]``): :func:`benchmarks.cli.main.main`,
imported inside a handler so that a Ctrl-C while the harness imports — a second or more (numba,
scipy, the integrators' registry) before ``main()`` can catch anything — ends as one while a
command runs does: one line on the standard error and exit status 130, not a traceback and a
death by SIGINT. It sits outside the ``benchmarks`` package on purpose: importing any module of
that package first runs its ``__init__``, which imports the integrators.
"""

import sys

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """:func:`benchmarks.cli.main.main` (``argv``: the arguments, default the command line's)."""
    try:
        from benchmarks.cli.main import exit_program, main as run
    except KeyboardInterrupt:
        print("rsfbench: error: interrupted (Ctrl-C) while starting", file=sys.stderr)
        return 130
    status = run(argv)
    if argv is None:                   # the program: it ends here (exit_program)
        exit_program(status)
    return status


if __name__ == "__main__":
    sys.exit(main())

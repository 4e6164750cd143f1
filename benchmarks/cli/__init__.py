"""``rsfbench``, the command line: :func:`main` (the console script) and the parser; one module
per group of commands beside :mod:`~benchmarks.cli.main`, and what they share in
:mod:`~benchmarks.cli.args`."""

from benchmarks.cli.main import build_parser, main

__all__ = ["main", "build_parser"]

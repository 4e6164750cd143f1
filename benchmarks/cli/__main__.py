"""``python -m benchmarks.cli``: the same as the ``rsfbench`` console script."""

from benchmarks.cli.main import exit_program, main

exit_program(main())

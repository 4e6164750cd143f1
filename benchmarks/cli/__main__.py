"""``python -m benchmarks.cli``: the same as the ``rsfbench`` console script."""

import sys

from benchmarks.cli.main import main

sys.exit(main())

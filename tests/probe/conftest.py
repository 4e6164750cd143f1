"""``--probe-report DIR``: write every case's outcome to ``DIR/reliability.csv`` and the table of
kinds and outcomes to ``DIR/reliability.md`` when the run ends (the ``probe`` study)."""

import time
from pathlib import Path

import pytest

ROWS = pytest.StashKey[list]()


def pytest_addoption(parser):
    parser.addoption("--probe-report", metavar="DIR", type=Path,
                     help="write reliability.csv and reliability.md there (default: none)")


def pytest_configure(config):
    config.stash[ROWS] = []


@pytest.fixture
def observe(request):
    """Run a case, record its row (kind, case, expected, observed, detail, slow, seconds) and
    return what was observed."""
    from probe.harness import run_case

    def run(case):
        start = time.perf_counter()
        got = run_case(case)
        request.config.stash[ROWS].append({
            "kind": case.kind, "case": case.name, "expected": case.expect,
            "observed": got.outcome, "as_expected": got.outcome == case.expect,
            "detail": got.detail, "slow": case.slow, "seconds": time.perf_counter() - start})
        return got
    return run


def pytest_sessionfinish(session, exitstatus):
    out, rows = session.config.getoption("--probe-report"), session.config.stash[ROWS]
    if out is not None and rows:
        import pandas as pd

        from probe.harness import write_probe
        print("\n" + write_probe(pd.DataFrame(rows), out))

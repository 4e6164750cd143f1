"""The reliability probe (tests/probe/cases.py): every case must end as it is expected to —
refused with one clear line, a failure retcode, a warning, a recovered file, or a checked
answer — and never as a traceback, a hang or a silently wrong result. The slow cases (kills,
subprocesses, a Dask cluster) are marked ``slow``: ``make test-slow`` runs them."""

import pytest

from probe.harness import BAD_OUTCOMES, OUTCOMES, run_case
from probe.cases import cases

CASES = cases()


#: cases of 8–10 s each on 2 cores (`pytest --durations`, 2026-11-28), run by ``make test-slow``
#: so that ``make test`` stays within its budget; the same behaviours keep faster cases there
LONG = {"budgets/CyRK-BDF: wall budget 0.5 s",
        "classification/sundials-CVODE-BDF: a switch 1 ulp, 1e-15\u20261e-6 s before t_end = 0.05 s, "
        "or at 0+",
        "classification/sundials-CVODE-BDF: a switch 1 ulp, 1e-15\u20261e-6 s before t_end = 2 s, "
        "or at 0+"}


def _study_only(cases) -> set[str]:
    """The slow cases only the probe study runs (``rsfbench study probe`` runs every case).
    A backend matrix is a kind of slow case run once per backend ("NAME: scenario", NAME
    registered) for one or more scenarios; ``make test-slow`` runs one backend per library of
    each, the libraries taking the scenarios in turn. The two matrices took 11.4 of the slow
    cases' 16 min (``results/reliability.csv``, column ``seconds``, the study's last run)."""
    from integrators import REGISTRY
    matrices: dict[tuple[str, str], dict[str, dict[str, list[str]]]] = {}
    for case in cases:
        backend, _, scenario = case.name.partition(": ")
        if case.slow and scenario and backend in REGISTRY.names():
            family = (case.kind, " ".join(w.strip(",") for w in scenario.split()[:2]))
            matrices.setdefault(family, {}).setdefault(REGISTRY[backend].package, {}) \
                .setdefault(scenario, []).append(case.id)
    study = set()
    for libraries in matrices.values():
        for turn, library in enumerate(sorted(libraries)):
            scenarios = libraries[library]
            kept = scenarios[sorted(scenarios)[turn % len(scenarios)]][0]
            study |= {i for ids in scenarios.values() for i in ids} - {kept}
    return study


def _param(case, study_only):
    marks = [pytest.mark.slow] if case.slow or case.id in LONG else []
    if case.id in study_only:
        marks.append(pytest.mark.study)
    return pytest.param(case, id=case.id, marks=marks)


#: slow cases whose behaviour a test that ``make test-slow`` runs checks too, left to the probe
#: study (CI time: 130 s of the slow cases' ~10 min, ``results/reliability.csv``), with that test
COVERED_ELSEWHERE = {
    "observe/invert --observations reads the file observe wrote":
        "tests/test_pages_run.py (the README and the tutorial run observe, then invert "
        "--observations on the file it wrote)",
    "store/sweep: the Dask scheduler lost mid-sweep":
        "tests/test_store.py::test_losing_the_dask_scheduler_stops_the_run_keeping_its_chunks",
    "store/sweep --json: the Dask scheduler lost mid-sweep":
        "tests/test_store.py::test_losing_the_dask_scheduler_stops_the_run_keeping_its_chunks",
}
STUDY_ONLY = _study_only(CASES) | set(COVERED_ELSEWHERE)


@pytest.mark.parametrize("case", [_param(c, STUDY_ONLY) for c in CASES])
def test_probe_case(case, observe):
    got = observe(case)
    assert got.outcome not in BAD_OUTCOMES, f"{got.outcome}: {got.detail}"
    assert got.outcome == case.expect, f"expected {case.expect}, observed {got.outcome}: {got.detail}"


def test_the_long_cases_exist():
    assert LONG <= {c.id for c in CASES}
    assert set(COVERED_ELSEWHERE) <= {c.id for c in CASES if c.slow}


def test_make_test_slow_runs_every_library_of_each_backend_matrix():
    from integrators import REGISTRY

    def library(case):
        return case.kind, REGISTRY[case.name.partition(": ")[0]].package
    matrix = [c for c in CASES if c.id in STUDY_ONLY and c.id not in COVERED_ELSEWHERE]
    kept = {library(c) for c in CASES if c.slow and c.id not in STUDY_ONLY
            and c.name.partition(": ")[0] in REGISTRY.names()}
    assert len(matrix) > 50               # the switch ladder and the explicit load histories
    assert {library(c) for c in matrix} <= kept


def test_the_probe_is_at_least_300_cases_of_every_kind():
    from probe.harness import KIND_TITLES
    assert len(CASES) >= 300
    assert {c.kind for c in CASES} == set(KIND_TITLES)
    assert len({c.id for c in CASES}) == len(CASES)          # one id each
    assert {c.expect for c in CASES} <= set(OUTCOMES)


def test_the_probe_catches_what_it_should():
    """The probe's own verdicts: a traceback, a hang and a wrong answer are seen as such."""
    import time
    from probe.harness import Case, Wrong

    def boom(tmp):
        raise KeyError("x")

    def wrong(tmp):
        raise Wrong("silently wrong")

    def hang(tmp):
        while True:
            time.sleep(0.01)

    assert run_case(Case("physics", "t", boom, "ok")).outcome == "traceback"
    assert run_case(Case("physics", "w", wrong, "ok")).outcome == "wrong"
    assert run_case(Case("physics", "h", hang, "ok", timeout=0.3)).outcome == "hang"
    assert run_case(Case("physics", "r", lambda tmp: int("x"), "refused")).outcome == "refused"

"""``sol(t)``, ``resolved()`` and ``plot()`` cannot crash (issue 45, item 3): a repeated solve
is the same run within its accuracy, not bit for bit; where it is not, ``resolved()`` draws the
run as saved with a warning and ``sol(t)`` refuses in one line naming what disagreed."""

import dataclasses
import warnings

import pytest

from benchmarks.cli import main
from integrators import Rodas5P, make_algorithm, solve
from integrators.core.solution import REPEAT_FACTOR, RunNotRepeated
from problems import paper_example, window

#: W2 with the fault's radiation damping and no mass (the family study's quasi-dynamic slider,
#: 3e-7 m Lc): a problem file as a user writes it
QUASI_DYNAMIC = """\
name = "W2 quasi-dynamic"
mass = 0.0
stiffness = 1.48e8
normal_force = 997500.0
t_end = 7.0
mu0 = 0.6
radiation_damping = 4.0e6

[law]
name = "aging"
a = 0.008
b = 0.0094
lc = 3e-7
v0 = 1e-5

[loading]
vls = 7.5e-5
vlf = 1.9717e-3
df = 0.042

[initial]
slowdown = 1.1
"""


def _not_resolved(record) -> list[str]:
    return [str(w.message) for w in record if "not resolved" in str(w.message)]


def test_simulate_plot_of_a_quasi_dynamic_file_with_the_default_integrator(tmp_path, capsys):
    # the recommended Exprb43 at 1e-3 repeats its steps (2114), but the repeat's denser grid
    # raised fs_max_before by up to 64 N, first in event 58 of 71 (save points counted
    # towards the largest spring force until 4bef9e2): bit for bit, that was "did not repeat
    # its run", exit 3 (internal error)
    path = tmp_path / "qd.toml"
    path.write_text(QUASI_DYNAMIC)
    figure = tmp_path / "qd.png"
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        rc = main(["simulate", "--problem", str(path), "--plot", str(figure), "--json"])
    err = capsys.readouterr().err
    assert rc == 0 and figure.stat().st_size > 10_000, err
    assert "internal error" not in err and "not resolved" not in err
    assert not _not_resolved(record)


@pytest.mark.parametrize("name", ["scipy-Radau", "sundials-CVODE-BDF", "scipy-LSODA"])
def test_a_library_whose_repeat_moves_its_roots_resolves_its_events(name):
    # W2, 5 s, rtol 1e-6: the repeat's events differ from the run's (measured over 10 s:
    # scipy-Radau 2e-11 and LSODA 2e-15 relative, rounding in the root brackets the save times
    # move; SUNDIALS CVODE 2.1e-5, other steps) and bit for bit resolved() raised
    sol = solve(window("W2", t_end=5.0), make_algorithm(name, rtol=1e-6, atol=1e-6),
                max_points=2000)
    assert sol.success and len(sol.event_array) >= 2
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        fine = sol.resolved()
    assert not _not_resolved(record)
    assert fine is not sol and len(fine.t) >= len(sol.t) + 150 * len(sol.event_array)
    assert fine.event_array is sol.event_array                  # the run's own record
    # the dense output reaches each event's root-found peak (to the 1/200 of an event the
    # resolved grid samples, and the repeat's own 21·rtol measured)
    for t0, t1, v_peak in sol.event_array[:, [0, 1, 4]]:
        inside = (fine.t >= t0) & (fine.t <= t1)
        assert fine.v[inside].max() == pytest.approx(v_peak, rel=2e-3)


@pytest.fixture(scope="module")
def paper_run():
    return solve(paper_example(t_end=6.0), Rodas5P(rtol=1e-8, atol=1e-8), max_points=300)


def _moved(sol, row, column, factor):
    """``sol`` whose repeat moves one entry of the events table by ``factor``."""
    def rerun(times):
        again = sol.rerun(times)
        ev = again.event_array.copy()
        ev[row, column] *= factor
        return dataclasses.replace(again, event_array=ev)
    return dataclasses.replace(sol, rerun=rerun)


def test_a_repeat_within_the_tolerance_is_the_same_run(paper_run):
    tol = REPEAT_FACTOR * 1e-8
    close = _moved(paper_run, 1, 0, 1.0 + 0.5 * tol)
    assert close(paper_run.t[:5]).equals(paper_run(paper_run.t[:5]))
    # every column counts, fs_max_before too (no save point moves it since 4bef9e2)
    with pytest.raises(RunNotRepeated, match="fs_max_before"):
        _moved(paper_run, 1, 2, 1.01)(1.0)


def test_a_repeat_that_differs_is_refused_by_sol_and_drawn_as_saved(paper_run, tmp_path):
    far = _moved(paper_run, 1, 0, 1.0 + 3 * REPEAT_FACTOR * 1e-8)
    with pytest.raises(RunNotRepeated, match=r"^sol\(t\): Rodas5P did not repeat its run .*"
                                             r"event 2 of \d+: t_start .* more than 1e-06"):
        far(1.0)
    assert issubclass(RunNotRepeated, ValueError)          # the CLI's one line, not exit 3
    with pytest.warns(RuntimeWarning, match="not resolved: sol\\(t\\): Rodas5P did not repeat"):
        assert far.resolved() is far
    with pytest.warns(RuntimeWarning, match="not resolved"):
        far.plot(tmp_path / "far.png")
    assert (tmp_path / "far.png").stat().st_size > 10_000

    def fewer(times):
        again = paper_run.rerun(times)
        return dataclasses.replace(again, event_array=again.event_array[:-1])
    with pytest.raises(RunNotRepeated, match=r"(\d+) events against the run's \d+"):
        dataclasses.replace(paper_run, rerun=fewer)(1.0)


@pytest.mark.parametrize("bad, shown", [(5, "5 (int)"), (3.5, "3.5 (float)"),
                                        ("run.txt", "'run.txt' (matplotlib does not write .txt)"),
                                        ("run", "'run' (no suffix)")])
def test_plot_refuses_what_is_not_a_figure_file_in_one_line(paper_run, bad, shown):
    with pytest.raises(ValueError) as info:
        paper_run.plot(bad)
    text = str(info.value)
    assert text == ("path must be a file name ending in .png, .pdf or .svg (or None: no file), "
                    f"got {shown}")


def test_lab_shs_with_a_nanosecond_hold_never_exits_3(capsys):
    rc = main(["lab", "shs", "--holds", "1e-9"])
    err = capsys.readouterr().err
    assert rc in (0, 1, 2) and "internal error" not in err and len(err.splitlines()) <= 1, err

"""numbalsoda's LSODA port when the right-hand side turns to inf, and why the adapters' rows
survive it.

The adapters stop LSODA from inside the right-hand side by returning inf (docs/external-
adapters.md), where what LSODA does then is described: mostly NaN states. Rarely it
"succeeds" a step without reaching the output time, calls ``intdy`` there, which refuses (the
time is past tcur: it prints ``intdy -- t = … illegal``), ignores the refusal and returns as
the row at that time whatever its work vector holds: not the solution there (LSODA.cpp, the
itask = 1 return after ``stoda``, which does not read intdy's flag). The first test pins
that on a one-line problem; the second, that on a case where it happens inside an adapter, the
row is one the adapter does not use (it comes after the stop).
"""

import re

import numpy as np
import pytest

import integrators as I
import problems as P
from integrators import REGISTRY

numbalsoda = pytest.importorskip("numbalsoda")
ILLEGAL = re.compile(r"intdy -- t = (\S+) illegal")


def _decay_then_inf():
    """du/dt = −u until t = 1, inf from then on (the adapters' stop, reduced to one line)."""
    from numba import carray, cfunc

    @cfunc(numbalsoda.lsoda_sig)
    def rhs(t, u, du, p):
        out = carray(du, (1,))
        out[0] = -u[0] if t < 1.0 else np.inf
    return rhs.address


def test_an_inf_right_hand_side_makes_a_row_that_is_not_the_solution(capfd):
    t_eval = np.linspace(0.0, 2.0, 21)
    usol, success = numbalsoda.lsoda(_decay_then_inf(), np.array([1.0]), t_eval,
                                     rtol=1e-8, atol=1e-10)
    err = capfd.readouterr().err
    before = t_eval < 1.0
    # before the switch the rows are the solution, e^−t to the tolerance...
    np.testing.assert_allclose(usol[before, 0], np.exp(-t_eval[before]), rtol=1e-7)
    # ...at t = 1 intdy refused, and the row is finite but wrong: measured 0.367918 for
    # e^−1 = 0.367879, 3.9e−5 relative at a tolerance of 1e−8
    assert 1.0 in [float(s) for s in ILLEGAL.findall(err)], err[:400]
    assert np.isfinite(usol[10, 0]) and abs(usol[10, 0] / np.exp(-1.0) - 1.0) > 1e-6
    # the next output time's intdy is checked: the call fails there (success is False)
    assert "trouble from intdy" in err and not success


def _watch_calls(monkeypatch, capfd):
    """Wrap the adapters' one lsoda call so that each call's stderr is read after it: returns
    the list it fills with (intdy warning times, the call's t_eval, rows used, stopped?)."""
    from integrators.external import numbalsoda_backend as nb

    calls, run = [], nb._LsodaStepper._run

    def watched(self, z0, t_eval, *args, **kw):
        capfd.readouterr()
        rows, n, ok = run(self, z0, t_eval, *args, **kw)
        warned = [float(s) for s in ILLEGAL.findall(capfd.readouterr().err)]
        calls.append((warned, np.asarray(t_eval, dtype=float), n, self._data[nb._KILL] != 0.0))
        return rows, n, ok

    monkeypatch.setattr(nb._LsodaStepper, "_run", watched)
    return calls


def test_an_intdy_warning_inside_the_adapter_is_past_the_rows_it_uses(monkeypatch, capfd):
    # W4/aging over 40 s at 1e−7: 194 stops, one of them (a stuck cold start at τ ≈ 676)
    # followed by an intdy warning (measured); the warned row is after the stop
    calls = _watch_calls(monkeypatch, capfd)
    sol = I.solve(P.window("W4", "aging", t_end=40.0),
                  REGISTRY["numbalsoda-LSODA"](rtol=1e-7, atol=1e-7))
    assert sol.success, sol.message
    warned_calls = [c for c in calls if c[0]]
    assert warned_calls, "no intdy warning: this test no longer sees what it is about"
    for warned, t_eval, n, stopped in warned_calls:
        assert stopped, (warned, n)
        # printed with %g (6 digits): no warning at or before the last row used
        assert min(warned) > float(f"{t_eval[n - 1]:g}"), (warned, t_eval[n - 1])

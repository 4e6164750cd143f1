"""Which measured events belong to the settled stick–slip cycle: the start-up and the outliers.

A recording (or a catalogue) that begins near steady sliding, or after a hold, starts with
events that are not the limit cycle's: the first sticks are shorter or longer, the first drops
larger. Averaged with the rest they move the mean and make its σ the size of the transient,
not of the cycle's scatter (on a 10 kHz recording of the paper's W2 apparatus made with scipy's
Radau from near steady sliding, the two start-up events bias the mean ΔT by −1.3 % and σ(ΔT)
by 24,000×). :func:`judge` finds them.

**How far an event is from the cycle.** For each of ΔT, Δμ and the slip per event
(:data:`JUDGED`), an event's distance is ``z = (x − median)/σ_r`` with the robust
``σ_r = 1.4826 · MAD`` (the median absolute deviation, which a few odd events do not move),
over the events taken as settled; σ_r is held above :data:`SIGMA_FLOOR` of the median, so that
a cycle that repeats to the last digit does not make every event infinitely far. An event's
score is its largest ``|z|``; it *differs* from the cycle when the score exceeds
:data:`Z_DIFFERS`. Robust σ is what makes the rule hold at both ends of the scatter: on a model
record whose events repeat to 1e−6 a start-up event 1 % off is ~10⁴ σ away; on a laboratory
record with 20 % scatter it must be several times that 20 % away to be called different.

**The start-up** is the run of leading events that differ, when it stands out: the first event
differs :data:`STANDS_OUT` times more than any event after the run does (else the record is
irregular throughout, and
its first events are as ordinary as its others), and at least :data:`MIN_SETTLED` events are
left. The settled events are those after it; the medians and σ_r are taken again over them,
until the run stops changing (a long start-up makes the first medians its own). The start-up is
dropped from the means by default; ``keep_startup`` keeps it (and it is still named).

**Outliers** are the events after the start-up that differ. They are named with their distance,
and **kept** in the means: on a genuinely irregular record an odd event is part of the scatter
the model is compared with (σ is that scatter, the paper's σT, σμ), and dropping it would
narrow σ by a choice, not by a measurement. Look at them (``observe.png``), and crop the record
(``--window``) where one is an artefact.

On a real catalogue (NIED's 4-m apparatus, ``fb03-087``, 56 events, ~20 % scatter) the first
event's drop and slip are ~3× the others' (≳ 10 σ_r): a start-up; its later odd recurrence
intervals are outliers, kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

__all__ = ["Settling", "judge", "spread", "JUDGED", "Z_DIFFERS", "STANDS_OUT", "MIN_SETTLED", "SIGMA_FLOOR", "MAD_SIGMA"]

#: the metrics an event is judged on (the per-event table's columns)
JUDGED = ("recurrence_s", "friction_drop", "slip_m")
#: an event whose largest absolute z exceeds this differs from the cycle. A normal scatter
#: exceeds 5 σ once in ~1.7 million; the start-up's further condition (module docstring) keeps a
#: heavy-tailed record's first event from being dropped for being as odd as its others
Z_DIFFERS = 5.0
#: the first event of a start-up is at least this many times as far from the cycle as any later
#: event: a heavy-tailed record's odd first event is not. Measured on 300 records each of 10,
#: 30 and 60 events with 20 % scatter, without a start-up: taken for one in 2 % of the records
#: of 10 events (Student-t of 3 degrees of freedom, or skewed lognormal), none of 30 or 60
#: (with a factor of 1: 2–5 %); of normal scatter 0.3 % at 10 events, none at 30 or 60
STANDS_OUT = 2.0
#: the fewest events left after a start-up: fewer, and the record has not settled (or has no
#: cycle to settle on), and nothing is dropped
MIN_SETTLED = 3
#: σ_r is at least this fraction of the median (its size): a cycle that repeats to rounding
#: is not made infinitely sharp (observations refuse a σ below 1e−9 of its mean)
SIGMA_FLOOR = 1e-9
#: the MAD of a normal distribution times this is its σ
MAD_SIGMA = 1.4826
#: the rounds of taking the medians again over the settled events, at most
ROUNDS = 5


@dataclass(frozen=True)
class Settling:
    """The events' verdict (module docstring): the start-up's and the outliers' row numbers
    (0-based) in the table judged, each event's distance from the settled cycle (``z``: one
    column per metric of :data:`JUDGED`, in σ_r of the settled events, signed), whether the
    start-up is kept, and what to say about it.

    Parameters
    ----------
    startup, outliers : list of int
        Rows of the start-up and of the outliers.
    z : pandas.DataFrame
        Per event and metric, (x − median)/σ_r over the settled events.
    keep_startup : bool
        The start-up stays in the means.
    notes : list of str
        What was found, for the output.
    """

    startup: list = field(default_factory=list)
    outliers: list = field(default_factory=list)
    z: pd.DataFrame = field(default=None, repr=False)
    keep_startup: bool = False
    notes: list = field(default_factory=list)

    @property
    def dropped(self) -> list:
        """Rows left out of the means: the start-up unless kept (outliers are kept)."""
        return [] if self.keep_startup else list(self.startup)

    def mark(self, events: pd.DataFrame) -> pd.DataFrame:
        """``events`` with the verdict's columns: ``kept`` (in the means), ``reason``
        ("start-up", "outlier" or ""), ``z_max`` (the largest absolute z over
        :data:`JUDGED`)."""
        out = events.copy()
        reason = np.full(len(out), "", dtype=object)
        reason[self.startup] = "start-up"
        reason[self.outliers] = "outlier"
        kept = np.ones(len(out), dtype=bool)
        kept[self.dropped] = False
        out["kept"], out["reason"] = kept, reason
        out["z_max"] = _score(self.z)
        return out


def judge(events: pd.DataFrame, keep_startup: bool = False, when=None) -> Settling:
    """Find the start-up and the outliers of a per-event table (module docstring).

    Parameters
    ----------
    events : pandas.DataFrame
        One row per event, in time order, with any of :data:`JUDGED` (NaN where unknown).
    keep_startup : bool
        Keep the start-up in the means (it is still found and named).
    when : array-like, optional
        Each event's time (s), to name it by; default: none.

    Returns
    -------
    Settling
    """
    n = len(events)
    judged = [m for m in JUDGED if m in events]
    x = events[judged].to_numpy(dtype=float) if judged else np.empty((n, 0))
    lead, settled = 0, np.ones(n, dtype=bool)
    for _ in range(ROUNDS):
        score = _score(_distances(x, settled))
        run = _leading_run(score)
        later = STANDS_OUT * score[run:].max(initial=0.0)
        if run <= lead or n - run < MIN_SETTLED or score[0] <= later:
            break                                   # no (longer) start-up that stands out
        lead, settled = run, np.arange(n) >= run
    z = _distances(x, settled)
    z = pd.DataFrame(z, columns=judged, index=events.index)
    score = _score(z)
    startup = list(range(lead))
    outliers = [i for i in range(lead, n) if score[i] > Z_DIFFERS]
    notes = _say(events, z, startup, outliers, keep_startup, when, _unsettled(score, lead, n))
    return Settling(startup, outliers, z, bool(keep_startup), notes)


def _distances(x: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(x − median)/σ_r per column, the medians and σ_r over the ``reference`` rows."""
    z = np.full(x.shape, np.nan)
    for j in range(x.shape[1]):
        ref = x[reference, j]
        ref = ref[np.isfinite(ref)]
        if len(ref) < MIN_SETTLED:
            continue                                # too few values to judge by
        med = float(np.median(ref))
        sigma = max(MAD_SIGMA * float(np.median(np.abs(ref - med))), SIGMA_FLOOR * abs(med),
                    np.finfo(float).tiny)
        z[:, j] = (x[:, j] - med) / sigma
    return z


def _score(z) -> np.ndarray:
    """Each row's largest |z| (0 where none is known)."""
    a = np.abs(np.asarray(z, dtype=float))
    if a.size == 0:
        return np.zeros(len(a))
    return np.where(np.isfinite(a), a, 0.0).max(axis=1)


def _leading_run(score: np.ndarray) -> int:
    """How many events in a row from the first differ from the cycle."""
    differs = score > Z_DIFFERS
    return int(np.argmin(differs)) if not differs.all() else len(differs)


def _unsettled(score: np.ndarray, lead: int, n: int) -> str | None:
    """What to say when the leading events differ but were not taken as a start-up."""
    run = _leading_run(score)
    if lead or run == 0:
        return None
    if n - run < MIN_SETTLED:
        return (f"the first {run} of {n} events differ from the rest: too few are left to "
                "call the rest a settled cycle, so none is dropped (has the record settled?)")
    return (f"the first {run} event{'s' if run > 1 else ''} differ{'s' if run == 1 else ''} "
            "from the others, but no more than later events do: the record is irregular "
            "throughout, and they are kept as ordinary events")


def _name(events, when, i: int) -> str:
    at = "" if when is None else f" (t = {float(np.asarray(when)[i]):.6g} s)"
    return f"event {i + 1}{at}"


def _worst(z: pd.DataFrame, i: int) -> str:
    """'ΔT by +8.1e+04 σ' for the metric of row ``i`` farthest from the cycle."""
    row = z.iloc[i].abs()
    if row.isna().all():
        return "–"
    metric = row.idxmax()
    label = {"recurrence_s": "ΔT", "friction_drop": "Δμ", "slip_m": "slip"}[metric]
    return f"{label} by {z.iloc[i][metric]:+.3g} σ"


def _say(events, z, startup, outliers, keep, when, unsettled) -> list:
    notes = []
    if startup:
        which = "; ".join(f"{_name(events, when, i)}: {_worst(z, i)}" for i in startup)
        fate = ("kept in the means (--keep-startup)" if keep else
                "left out of the means (--keep-startup keeps the start-up)")
        first = (f"the first {len(startup)} events differ" if len(startup) > 1 else
                 "the first event differs")
        notes.append(f"start-up: {first} from the settled cycle by more than {Z_DIFFERS:g} "
                     f"robust σ ({which}): {fate}")
    if outliers:
        shown = outliers[:6]
        which = "; ".join(f"{_name(events, when, i)}: {_worst(z, i)}" for i in shown)
        more = f"; and {len(outliers) - len(shown)} more" if len(outliers) > len(shown) else ""
        notes.append(f"outliers: {len(outliers)} later event{'s' if len(outliers) > 1 else ''} "
                     f"differ{'s' if len(outliers) == 1 else ''} from the cycle by more than {Z_DIFFERS:g} robust σ ({which}{more}): "
                     "kept in the means, as part of the record's scatter (crop with --window "
                     "if one is an artefact)")
    if unsettled:
        notes.append(unsettled)
    return notes


def spread(events: pd.DataFrame, metrics, rows=None) -> dict:
    """``{metric: {"n", "mean", "std"}}`` over ``rows`` of ``events`` (default: all), NaN
    ignored: σ with and without the dropped events, for the report."""
    table = events if rows is None else events.iloc[list(rows)]
    out = {}
    for name in metrics:
        x = table[name].to_numpy(dtype=float) if name in table else np.array([])
        x = x[np.isfinite(x)]
        out[name] = {"n": len(x), "mean": float(np.mean(x)) if len(x) else math.nan,
                     "std": float(np.std(x, ddof=1)) if len(x) > 1 else math.nan}
    return out

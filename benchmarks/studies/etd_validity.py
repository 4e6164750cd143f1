"""How far the ETD family's runs are from its step-rule check: ``rsfbench study
etd-validity``.

Each ETD step checks Eq. 53 at the fastest state it evaluated (``integrators/own/etd.py``, module
docstring): a step slipping more than ``rule_ratio_max`` = 100 times what the rule allows stops
the run (``Unresolved``). This study records the largest ratio of every run
(``Solution.meta["step_rule_max"]``) for ETD2 and ETDIterated at the paper's settings on the
problems the project studies — the paper example and W1–W4 at their best fits under both laws,
and a 3 × 3 subsample of each Section 4 sweep grid — and on the problems the check exists for:
a start out of force balance (the paper example's start kept under a = 0.001) and strong
weakening (b/a = 100), where an adaptive method finds an event within milliseconds. A problem
the method refuses before any work (its steps would outgrow steady sliding's instability,
:meth:`integrators.ETD2.check_problem`) is a row with retcode ``Refused`` and the reason.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pandas as pd
from tqdm.auto import tqdm

from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import fmt, markdown_table
from benchmarks.studies.classification import _runs
from benchmarks.studies.study import Study, markdown_file
from integrators import ETD2, ETDIterated, ProblemNotSupported, Rodas5P, solve
from problems import paper_example, preset

__all__ = ["STUDY", "etd_validity", "write_etd_validity"]


def _problems():
    out = [(group, preset(name, law=law, b=b, lc=lc, t_end=t_end))
           for group, name, law, b, lc, t_end in _runs() if group != "oscillation"]
    p0 = paper_example()
    unbalanced = dataclasses.replace(p0, initial=p0.initial_state).with_law(a=0.001)
    out.append(("outside the rule", unbalanced))
    out.append(("outside the rule", paper_example(b=0.02, lc=5e-6).with_law(a=0.0002)))
    return out


def etd_validity(progress: bool = True) -> pd.DataFrame:
    """One row per (problem, method): retcode, events, the largest step-rule ratio, and for the
    problems the check exists for, the first event an adaptive method finds."""
    rows = []
    jobs = [(g, p, m) for g, p in _problems() for m in (ETD2(), ETDIterated())]
    for group, p, method in tqdm(jobs, desc="ETD validity", disable=not progress):
        row = {"group": group, "problem": p.name, "b": p.law.b, "a": p.law.a,
               "lc_um": p.law.lc * 1e6, "method": method.name}
        try:
            sol = solve(p, method, max_points=2, wall_budget=60)
        except ProblemNotSupported as refusal:
            row.update(retcode="Refused", n_events=0, step_rule_max=float("nan"),
                       first_event_s=float("nan"), message=str(refusal))
        else:
            row.update(retcode=sol.retcode.value, n_events=len(sol.events),
                       step_rule_max=sol.meta.get("step_rule_max"), message=sol.message,
                       first_event_s=(float(sol.events.t_start.iloc[0]) if len(sol.events)
                                      else float("nan")))
        if group == "outside the rule":
            ref = solve(p, Rodas5P(rtol=1e-6, atol=1e-6), max_points=2, wall_budget=60)
            row["reference_first_event_s"] = (float(ref.events.t_start.iloc[0])
                                              if len(ref.events) else float("nan"))
        rows.append(row)
    return pd.DataFrame(rows)


def write_etd_validity(table: pd.DataFrame, out: Path) -> str:
    """``etd_validity.csv`` and ``.md`` in ``out``; returns the Markdown."""
    out.mkdir(parents=True, exist_ok=True)
    write_table(table, out / "etd_validity.csv")
    good = table[table.group != "outside the rule"]
    summary = (good.groupby(["group", "method"], sort=False)
               .agg(runs=("problem", "size"),
                    succeeded=("retcode", lambda r: int((r == "Success").sum())),
                    largest_ratio=("step_rule_max", "max")).reset_index())
    summary["largest_ratio"] = summary.largest_ratio.map(lambda x: fmt(x, ".3g"))
    stops = table[table.group == "outside the rule"][
        ["problem", "a", "b", "lc_um", "method", "retcode", "n_events", "step_rule_max",
         "first_event_s", "reference_first_event_s"]]
    stops = stops.assign(
        reference_first_event_s=stops.reference_first_event_s.map(lambda x: fmt(x * 1e3, ".3g")),
        first_event_s=stops.first_event_s.map(lambda x: fmt(x * 1e3, ".3g")),
        step_rule_max=stops.step_rule_max.map(lambda x: fmt(x, ".3g")),
        a=stops.a.map(lambda x: fmt(x, "g"))).rename(
        columns={"reference_first_event_s": "Rodas5P's first event (ms)",
                 "first_event_s": "first event (ms)", "step_rule_max": "largest ratio"})
    text = ("The largest slip of a step over what Eq. 53 allows (at the fastest state the step "
            f"evaluated), per run; the check stops a run above {ETD2().rule_ratio_max:g}.\n\n"
            + markdown_table(summary)
            + "\nThe problems the check exists for (a start out of force balance; b/a = 100), "
            "against Rodas5P's first event (``Refused``: refused before any work, its steps "
            "would outgrow steady sliding's instability):\n\n"
            + markdown_table(stops))
    write_output(out / "etd_validity.md", text)
    return text


def run(out: Path) -> None:
    print(write_etd_validity(etd_validity(), out))


STUDY = Study("etd-validity", "The ETD family's step-rule check (`etd_validity.*`)", 160, run,
              report=markdown_file("etd_validity.md"),
              writes=("etd_validity.csv", "etd_validity.md"), minutes=3.7)

"""What ``make reproduce`` runs: the studies of :mod:`benchmarks.studies`, each writing its files
to ``results/``; ``results/REPORT.md`` assembling their sections; the README's generated blocks.

The plan is built from the studies' declarations (:class:`benchmarks.studies.study.Study`): a
study module declares its name, the files it reads and writes, its plan and expected minutes,
and gives its report section; :func:`studies` finds them. The quick plan (``make reproduce``)
runs the quick studies and keeps the files of the full ones; the full plan (``make
reproduce-full``, ``rsfbench reproduce --full``) runs them all. Either reuses a study whose
inputs did not change (:mod:`benchmarks.pipeline.manifest`: ``results/manifest.json`` records
what each read and wrote); ``force`` reruns every study of the plan, ``only`` one
(``rsfbench study NAME``). A full study the quick plan keeps although its inputs changed is
reported as stale, at the end and in ``REPORT.md``, where each section names the commit it came
from.

A study's outputs are the files matching its declared patterns, never found by what changed; a
run that writes a file no study declares, or that leaves a declared pattern unmatched, fails.
When ``out`` is the project's ``results/``, the README's generated blocks are refilled last
(:mod:`benchmarks.pipeline.readme`). ``docs/reproduce.md`` lists the studies and their times.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import pandas as pd

from benchmarks.pipeline import manifest as M
from benchmarks.pipeline.plan import check_plan, list_markdown, studies, study_inputs, study_named
from benchmarks.pipeline.readme import ROOT, refresh_pages
from benchmarks.records.files import BadResultsFile, adopt, claim_outputs, permit, write_output
from benchmarks.records.provenance import provenance
from benchmarks.records.report import markdown_table
from benchmarks.studies.study import matches

__all__ = ["reproduce", "run_steps", "describe", "summary", "studies", "study_named",
           "check_plan", "list_markdown"]


def _section(title: str) -> None:
    print(f"\n== {title} ==", flush=True)


def reproduce(out: Path, full: bool = False, force: bool = False, start: str | None = None,
              only: str | None = None, dry_run: bool = False,
              settings: dict | None = None) -> list[dict]:
    """Bring ``out`` up to date (see the module docstring) and write ``REPORT.md``; return one
    row per step considered (``step``, ``status``, ``why``).

    ``full``: the full plan. ``force``: rerun every step of the plan, reusing none. ``start``:
    begin at this step (the earlier ones are left alone). ``only``: rerun this step alone, quick
    or full. ``settings``: values of the ``only`` study's settings, by name (a rerun with them is
    recorded as such: the study reruns on the next plan). ``dry_run``: say what would run, run
    nothing, write nothing."""
    plan = studies()
    names = [s.name for s in plan]
    for what, name in (("start", start), ("only", only)):
        if name is not None and name not in names:
            raise ValueError(f"unknown study {name!r} ({what}): expected one of "
                             f"{', '.join(names)}")
    if only and start:
        raise ValueError("only and start exclude each other")
    if start and not full and study_named(start, plan).full:
        raise ValueError(f"study {start!r} is in the full plan only: add --full (full=True), or "
                         f"rerun it alone with `rsfbench study {start}`")
    if settings and not only:
        raise ValueError("settings apply to one study: name it (only=NAME, `rsfbench study "
                         "NAME --set KEY=VALUE`)")
    overrides = study_named(only, plan).checked(settings) if settings else {}
    steps = [dataclasses.replace(s, settings={**s.settings, **overrides})
             if s.name == only and overrides else s for s in plan]
    if only:
        modes = {only: "run"}
    else:
        first = names.index(start) if start else 0
        modes = {s.name: ("keep" if s.full and not full else "run" if force else "check")
                 for s in steps[first:]}
    out = Path(out)
    if not dry_run:
        if not M.read_manifest_or_none(out):   # not a results store: a user's REPORT.md
            claim_outputs([out / "REPORT.md"])  # is refused before the work
        out.mkdir(parents=True, exist_ok=True)
    rows = run_steps(steps, out, modes, dry_run=dry_run)
    if dry_run:
        return rows
    if M.read_manifest_or_none(out):          # a results store's report is the pipeline's
        permit([out / "REPORT.md"])
    write_output(out / "REPORT.md", report_markdown(plan, out))
    print(f"\nwritten: {out / 'REPORT.md'}")
    if out.resolve() == (ROOT / "results").resolve():    # the README and docs quote these files
        stale = refresh_pages()
        print(f"generated blocks refilled: {', '.join(stale) or 'none changed'}")
    return rows


def run_steps(steps, out: Path, modes: dict[str, str], dry_run: bool = False,
              **code) -> list[dict]:
    """Take each step of ``steps`` named in ``modes`` in order: ``run`` reruns it, ``check``
    reruns it unless its inputs and files are unchanged (then it is reused), ``keep`` only
    says whether its files are up to date. Each step that ran is recorded in ``out``'s
    manifest at once. ``code``: :func:`benchmarks.pipeline.manifest.step_inputs`' ``root``,
    ``packages`` and ``whole``.

    The manifest on disk is read again before each step and before each record is written, so
    that two runs of different steps (``rsfbench study NAME``) at once keep each other's records."""
    said = []

    def current() -> dict[str, dict]:
        try:
            return M.read_manifest(out)
        except BadResultsFile as exc:
            if not said:                     # once, not before every step
                print(f"{exc}: every step reruns")
                said.append(exc)
            return {}

    order = [s.name for s in steps]
    rows = []
    for step in steps:
        mode = modes.get(step.name)
        if mode is None:
            continue
        inputs = study_inputs(step, out, **code)
        ok, why = M.reusable(current().get(step.name), inputs, out)
        if mode == "keep" or (mode == "check" and ok):
            row = {"step": step.name, "status": "reused" if ok else "stale",
                   "why": why if ok else f"{why}; `make reproduce-full` reruns it"}
        elif dry_run:
            written = [s for s in steps if any(r["step"] == s.name and r["status"] == "would run"
                                               for r in rows)]
            missing = [r for r in step.reads if not (out / r).is_file()
                       and not any(s.declares(r) for s in written)]
            row = ({"step": step.name, "status": "would fail", "why": f"reads {missing[0]}, "
                    "which is not there and no earlier study of this run writes"} if missing else
                   {"step": step.name, "status": "would run",
                    "why": "rerun as asked" if mode == "run" else why, "minutes": step.minutes})
        else:
            row = None
        if row is not None:
            rows.append(row)
            if not dry_run:
                print(describe(row), flush=True)
            continue
        why = "rerun as asked" if mode == "run" else why
        missing = [r for r in step.reads if not (out / r).is_file()]
        if missing:
            raise FileNotFoundError(f"step {step.name} reads {out / missing[0]}, which is not "
                                    "there: run the step that writes it first (`rsfbench "
                                    f"reproduce --full --out {out}`)")
        _refuse_foreign_files(step, out)
        _section(step.title)
        print(f"({why})", flush=True)
        before = M.snapshot(out)
        started = time.perf_counter()
        try:
            step.run(out, **step.settings)
        finally:                              # also a step stopped half-way: what it wrote
            try:                              # is rsfbench's (a full disk: the step's own
                adopt(out / p for p in M.written_since(before, out))    # error is the one
            except OSError:                                              # said)
                pass
        wall = time.perf_counter() - started
        outputs = _declared_outputs(step, steps, out, before)
        records = current()
        records[step.name] = M.make_record(step.name, step.plan, inputs, outputs, wall)
        M.write_manifest(out, records, order)
        rows.append({"step": step.name, "status": "ran", "why": why})
    return rows


def _refuse_foreign_files(study, out: Path) -> None:
    """Before a study runs: a file its declared patterns match is a user's, and refused unless
    ``--overwrite`` (:mod:`benchmarks.records.files`), when the directory's manifest (a
    readable one: a file merely named so says nothing) does not list it as a step's output and
    rsfbench's ledger does not know it, unchanged. A listed file is the pipeline's record: the
    step writes it again, even if it was edited since (a record changed by hand is stale, and
    the rerun restores it)."""
    out = Path(out)
    if not out.is_dir():
        return
    found = [p for pattern in study.writes for p in sorted(out.glob(pattern)) if p.is_file()]
    records = M.read_manifest_or_none(out) or {}
    listed = {rel for r in records.values() for rel in r.get("outputs", {})}
    mine = [p for p in found if p.relative_to(out).as_posix() in listed]
    claim_outputs(p for p in found if p not in mine)      # the ledger's pass; others refused
    permit(found)


def _declared_outputs(study, plan, out: Path, before: dict) -> dict[str, str]:
    """Relative path → hash of the files ``study`` wrote in this run that it declares;
    ``RuntimeError`` if a declared pattern matched no file written in this run (a file left
    from an earlier run does not count) or it wrote a file that no study of ``plan`` declares
    (a file another study declares may be that study's, running at the same time)."""
    written = M.written_since(before, out)
    outputs = {p: h for p, h in written.items() if study.declares(p)}
    unmatched = [pattern for pattern in study.writes
                 if not any(matches(p, pattern) for p in outputs)]
    if unmatched:
        raise RuntimeError(f"study {study.name} declares {', '.join(unmatched)} but wrote no "
                           f"such file in {out} in this run")
    stray = [p for p in written if not any(s.declares(p) for s in plan)]
    if stray:
        raise RuntimeError(f"study {study.name} wrote {', '.join(stray[:5])} in {out}, which no "
                           "study declares: add them to its STUDY.writes")
    return outputs


def describe(row: dict) -> str:
    """One line for a row of :func:`run_steps`."""
    if row["status"] == "reused":
        return f"{row['step']}: reused (inputs unchanged)"
    if row["status"] == "stale":
        return f"{row['step']}: kept, a step of the full plan ({row['why']})"
    if row["status"] == "would run":
        return f"{row['step']}: would run ({row['why']}; ~{_duration(60 * row['minutes'])})"
    return f"{row['step']}: {row['status']} ({row['why']})"


def summary(rows: list[dict]) -> str:
    """One line: how many steps ran (or would, and for how long) and were reused, which would
    fail for a file they read, and which full steps are stale."""
    would = [r["minutes"] for r in rows if r["status"] == "would run"]
    ran = [r["step"] for r in rows if r["status"] == "ran"]
    reused = [r["step"] for r in rows if r["status"] == "reused"]
    stale = [r["step"] for r in rows if r["status"] == "stale"]
    fail = [r["step"] for r in rows if r["status"] == "would fail"]
    text = (f"{_steps(len(would))} would run (~{_duration(60 * sum(would))}), " if would
            else f"{_steps(len(ran))} ran, ") + f"{len(reused)} reused"
    text += f"; would fail, a file they read missing: {', '.join(fail)}" if fail else ""
    return text + (f"; stale, kept from an earlier run: {', '.join(stale)} (`make "
                   "reproduce-full` reruns them)" if stale else "")


def _steps(n: int) -> str:
    return f"{n} " + ("study" if n == 1 else "studies")


def _step_states(plan, out: Path, **code) -> list[dict]:
    """One row per study: its plan, its last run (from the manifest) and whether its files are
    up to date with its inputs."""
    try:
        records = M.read_manifest(out)
    except BadResultsFile:
        records = {}
    rows = []
    for step in plan:
        r = records.get(step.name)
        ok, why = M.reusable(r, study_inputs(step, out, **code), out)
        rows.append({"step": step.name, "plan": "full" if step.full else "quick",
                     "last run": r["finished"] if r else "", "commit": r["git_commit"] if r else "",
                     "took": _duration(r["wall_s"]) if r else "",
                     "files": "up to date" if ok else why})
    return rows


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 100 else f"{seconds / 60:.1f} min"


def report_markdown(plan, out: Path, **code) -> str:
    """``REPORT.md``: each study's section (its ``report`` of its files), headed by its title and
    the commit of its last run, marked stale when its inputs changed since; then the table of
    the studies. ``code``: as for :func:`run_steps`."""
    meta = provenance()
    states = {r["step"]: r for r in _step_states(plan, out, **code)}
    parts = [f"""# rsfbench report

Assembled by `make reproduce` (`rsfbench reproduce --out results`) on {meta['date']}, commit
`{meta['git_commit']}`, {meta['cpu']} ({meta['n_cpus']} CPUs), Python {meta['python']},
numpy {meta['v_numpy']}, scipy {meta['v_scipy']}, numba {meta['v_numba']}. Every number below
is in a file of this directory, written by a study of `rsfbench reproduce`; each section says
the commit of the run it comes from and is marked stale when the study's inputs have changed
since (`manifest.json`); the last section lists the studies.
"""]
    for study in plan:
        if study.report is None:
            continue
        state = states[study.name]
        try:
            body = study.report(out)
        except FileNotFoundError as exc:
            body = f"Not run yet ({exc.filename} is missing): `rsfbench study {study.name}`.\n"
        except Exception as exc:      # one unreadable section must not lose the whole report
            body = (f"This section could not be read back: {type(exc).__name__}: {exc} "
                    f"(`rsfbench study {study.name}` rewrites its files).\n")
        mark = ("" if state["files"] == "up to date" else
                f"**Stale**: {state['files']}; `rsfbench study {study.name}` reruns it.\n\n")
        origin = (f"*From the run at commit `{state['commit']}` ({state['last run']}).*\n\n"
                  if state["commit"] else "")
        parts.append(f"## {study.title}\n\n{mark}{origin}{body.rstrip()}\n")
    parts.append("## The studies (`manifest.json`)\n\n\"Up to date\": the study's code, package "
                 "versions, settings, files read and (for timings) machine\nare those it last ran "
                 "on. `make reproduce` reruns the quick studies that are not; `make\n"
                 "reproduce-full` also the full ones.\n\n"
                 + markdown_table(pd.DataFrame(list(states.values()))))
    return "\n".join(parts)

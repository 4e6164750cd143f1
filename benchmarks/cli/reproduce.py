"""``rsfbench readme``, ``reproduce`` and ``study``: the results directory brought up to date,
whole or one study at a time, and the README refilled from it.

    rsfbench reproduce --out results        # what `make reproduce` runs (--full: reproduce-full)
    rsfbench study --list                   # the studies behind results/, one by one:
    rsfbench study speedup --set scipy_budget=3600   # the paper's 1/10,000 claim
    rsfbench readme [--check]               # refill the README's numbers from results/
"""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.cli.args import out_dir, say

__all__ = ["add_parsers"]

REPRODUCE_HELP = """\
Bring the results directory up to date, write its REPORT.md and, for the
project's results/, refill the README's generated blocks.

The quick plan (the default; `make reproduce`) runs the quick studies; the
full plan (--full; `make reproduce-full`) also the long ones. The quick plan
keeps the files of the full studies and says which are stale. `rsfbench study
--list` lists the studies, their plan, minutes and files.

A study is reused, not rerun, when its code, the package versions, its
settings, the files it reads and, for a timing, the machine are those of its
last run, and the files it wrote are there unchanged (results/manifest.json).
--force reruns every study of the plan; `rsfbench study NAME` reruns one.
See docs/reproduce.md."""

STUDY_HELP = """\
Run one study of the pipeline, whatever its inputs: it writes its declared
files to --out, records them in the manifest and rewrites REPORT.md. --set
changes one of its settings (`--list --json` shows each study's settings,
defaults and limits), and the next `rsfbench reproduce` reruns it at its
defaults. --list lists the studies: plan, minutes, files read and written."""


def cmd_readme(args) -> int:
    from benchmarks.pipeline.readme import refresh_pages
    stale = refresh_pages(check=args.check)
    verb = "out of date" if args.check else "refilled"
    say(f"generated blocks {verb}: {', '.join(stale)}" if stale
        else "generated blocks up to date (README and docs)")
    return 1 if stale and args.check else 0


def cmd_reproduce(args) -> int:
    from benchmarks.pipeline.reproduce import describe, reproduce, summary
    rows = reproduce(Path(args.out), full=args.full, force=args.force, start=args.start,
                     dry_run=args.dry_run)
    if args.dry_run:
        for row in rows:
            say(describe(row))
    say(summary(rows))
    return 0


def cmd_study(args) -> int:
    from benchmarks.pipeline.reproduce import describe, list_markdown, reproduce, studies, summary
    if args.list:
        if args.name or args.settings:
            raise ValueError("--list takes no study name or --set")
        if args.json:
            say(json.dumps([{"name": s.name, "title": s.title, "plan": s.plan,
                             "minutes": s.minutes, "reads": list(s.reads),
                             "writes": list(s.writes), "settings": s.settings,
                             "limits": s.limits,
                             "timed": s.timed} for s in studies()], indent=2))
        else:
            say(list_markdown(), end="")
        return 0
    if not args.name:
        raise ValueError("name a study (`rsfbench study --list` lists them)")
    if args.json:
        raise ValueError("--json goes with --list")
    settings = dict(_setting(text) for text in args.settings)
    rows = reproduce(Path(args.out), only=args.name, dry_run=args.dry_run,
                     settings=settings or None)
    if args.dry_run:
        for row in rows:
            say(describe(row))
    say(summary(rows))
    return 0


def _setting(text: str) -> tuple[str, object]:
    """``KEY=VALUE`` of ``--set``: the value as an int, a float or the word itself."""
    key, sep, value = text.partition("=")
    if not sep or not key.isidentifier():
        raise ValueError(f"--set: expected KEY=VALUE, got {text!r}")
    for kind in (int, float):
        try:
            return key, kind(value)
        except ValueError:
            pass
    return key, value


def add_parsers(sub) -> None:
    rd = sub.add_parser("readme", help="refill the generated blocks of the README and the docs "
                        "from results/")
    rd.add_argument("--check", action="store_true",
                    help="only say which blocks are out of date (exit status 1 if any)")
    rd.set_defaults(func=cmd_readme)

    r = sub.add_parser("reproduce", help="bring results/ up to date (what `make reproduce` runs)",
                       description=REPRODUCE_HELP)
    r.add_argument("--out", type=out_dir, default="results", metavar="DIR",
                   help="directory of the results")
    r.add_argument("--full", action="store_true",
                   help="the full plan: also the long studies (about 3.5 h on 2 cores; "
                        "`rsfbench study --list` says which) (default: the quick plan)")
    r.add_argument("--force", action="store_true",
                   help="rerun every study of the plan, reusing none (default: reuse the "
                        "studies whose inputs did not change)")
    r.add_argument("--dry-run", action="store_true",
                   help="say which studies would run and why, run nothing")
    r.add_argument("--from", dest="start", metavar="STUDY",
                   help="start at this study of the plan, leaving the earlier ones alone "
                        "(default: the first)")
    r.set_defaults(func=cmd_reproduce)

    st = sub.add_parser("study", help="run one study of the pipeline (or --list them)",
                        description=STUDY_HELP)
    st.add_argument("name", nargs="?", metavar="NAME",
                    help="the study to run (default: none; --list lists them)")
    st.add_argument("--list", action="store_true",
                    help="list the studies: plan, expected minutes, files read and written")
    st.add_argument("--out", type=out_dir, default="results", metavar="DIR",
                    help="directory of the results (default: results)")
    st.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE",
                    help="a setting of the study, by name (a number or a word; repeatable; "
                         "default: the study's own, which --list --json shows)")
    st.add_argument("--dry-run", action="store_true", help="say what would run, run nothing")
    st.add_argument("--json", action="store_true", help="with --list: one JSON array")
    st.set_defaults(func=cmd_study)

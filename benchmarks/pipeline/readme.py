"""``rsfbench readme``: the numbers of the README and of the docs pages, refilled from
``results/``.

Every number a page quotes sits in a generated block::

    <!-- rsfbench: results/speedup.md -->
    ...
    <!-- /rsfbench -->

whose body is a line saying where it comes from — the study that wrote the file, the commit and
date of that run (``results/manifest.json``) and whether the study's inputs other than the
machine have changed since (then the block is labelled stale) — and its source, rendered: a
results file verbatim (``results/X.md``), one of its
tables (``results/X.md table 2``, counting from 1), the recommendation bullets
(``recommendation``, from ``results/wp_quick.csv`` and ``wp_external.csv``) or the convergence bullets
(``convergence``, from ``results/convergence_paper-example_slip.json``). ``make reproduce`` ends
with it, and a test checks that the committed README matches the committed results, so the prose
around the blocks carries no number of its own.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pandas as pd

from benchmarks.devtools.work_precision import ADVICE_FILES, recommend
from benchmarks.pipeline import manifest as M
from benchmarks.pipeline.plan import studies, study_inputs
from integrators import REGISTRY

__all__ = ["fill", "render", "refresh", "refresh_pages", "pages", "RECOMMENDATION_LEVELS"]

ROOT = Path(__file__).resolve().parents[2]
RECOMMENDATION_LEVELS = (1e-3, 1e-6)          # the advice reads "to 1e−3, use X; to 1e−6, use Y"
_BLOCK = re.compile(r"(<!-- rsfbench: (?P<source>[^>]*?) -->\n)(?P<body>.*?)(<!-- /rsfbench -->)",
                    re.S)
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _power_of_ten(x: float) -> str:
    """10⁻³ for 0.001; other values as ``%g``."""
    e = math.log10(x)
    return f"10{str(round(e)).translate(_SUPERSCRIPT)}" if abs(e - round(e)) < 1e-9 else f"{x:g}"


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.3g} ms"


def recommendation(root: Path = ROOT) -> str:
    """The README's advice, one bullet per level of ``RECOMMENDATION_LEVELS``."""
    out = Path(root) / "results"
    study = pd.concat([pd.read_csv(out / f) for f in ADVICE_FILES], ignore_index=True)
    advice = recommend(study, RECOMMENDATION_LEVELS)
    n = study.problem.nunique()
    lines = []
    for _, a in advice.iterrows():
        head = f"* **for recurrence intervals to {_power_of_ten(a.level)}, "
        if pd.isna(a.get("integrator")):
            lines.append(head + "no setting of the study is reliably within the level.**")
            continue
        what = "rtol = atol" if REGISTRY[a.integrator].adaptive else "Δτcnst"
        line = (head + f"use `{a.integrator}`** at {what} = {a.setting:g}: worst error "
                f"{a.worst_error:.2g}, {_ms(a.total_wall_s)} for the {n} problems")
        if isinstance(a.next_integrator, str):
            line += (f"; the next best method, {a.next_integrator}, takes "
                     f"{_ms(a.next_total_wall_s)}")
        lines.append(line + ";")
    lines[-1] = lines[-1][:-1] + "."
    return "\n".join(lines)


def convergence(root: Path = ROOT, problem: str = "paper-example_slip") -> str:
    """One bullet per ETD method: observed and declared order, error at the finest step."""
    summary = json.loads((root / "results" / f"convergence_{problem}.json").read_text())
    ladder = pd.read_csv(root / "results" / f"convergence_{problem}.csv")
    lines = []
    for name, order in summary["orders"].items():
        d = summary["declared"][name]
        declared = f"declared {d['order']}"
        if d["stiff_order"] == 0:
            declared += ", no clean order on this stiff problem"
        elif d["stiff_order"] is not None and d["stiff_order"] != d["order"]:
            declared += f", {d['stiff_order']} on this stiff problem"
        finest = ladder[ladder.integrator == name].factor.min()
        lines.append(f"* {name}: observed order {order:.2f} ({declared}); error "
                     f"{summary['finest_error'][name]:.2g} at {_fraction(finest)} of the "
                     f"paper's steps.")
    return "\n".join(lines)


def _fraction(factor: float) -> str:
    return f"1/{round(1 / factor)}" if factor < 1 else f"{factor:g}×"


def _table(text: str, n: int, source: str) -> str:
    tables, current = [], []
    for line in text.splitlines() + [""]:
        if line.startswith("|"):
            current.append(line)
        elif current:
            tables.append("\n".join(current))
            current = []
    if not 1 <= n <= len(tables):
        raise ValueError(f"{source}: there is no table {n} (the file has {len(tables)})")
    return tables[n - 1]


def render(source: str, root: Path = ROOT) -> str:
    """The body of a block with this source (see the module docstring)."""
    if source == "recommendation":
        return recommendation(root)
    if source == "convergence":
        return convergence(root)
    m = re.fullmatch(r"(results/\S+\.md)(?: table (\d+))?", source)
    if m is None:
        raise ValueError(f"unknown README block source {source!r}: expected 'results/X.md', "
                         f"'results/X.md table N', 'recommendation' or 'convergence'")
    path = root / m.group(1)
    if not path.exists():
        raise FileNotFoundError(f"README block {source!r}: {path} does not exist (run `make "
                                f"reproduce`)")
    text = path.read_text()
    return _table(text, int(m.group(2)), source) if m.group(2) else _demoted(text.strip())


def _demoted(text: str) -> str:
    """A results file's headings one level down, so that the file sits under the page's own
    title and sections (lines inside code fences kept)."""
    lines, fenced = [], False
    for line in text.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        lines.append("#" + line if line.startswith("#") and not fenced else line)
    return "\n".join(lines)


_NOW: dict = {}          # a study's inputs now, computed once per fill or refresh
#: judge a block's staleness with the package versions of its record, not those installed (a
#: check run in another environment than the lock file's, such as ``pip install .``)
RECORDED_VERSIONS = False


def origin(source: str, root: Path = ROOT) -> str:
    """The line that says where a block comes from (see the module docstring), or "" where the
    results have no manifest or no study writes the file."""
    out = Path(root) / "results"
    name = {"recommendation": "wp_external.csv",      # the later of its two studies
            "convergence": "convergence_paper-example_slip.json"}.get(source)
    name = name or source.split()[0].removeprefix("results/")
    try:
        records = M.read_manifest(out)
    except M.BadResultsFile:
        return ""
    study = next((s for s in studies() if s.declares(name)), None)
    record = records.get(study.name) if study is not None else None
    if record is None:
        return ""
    key = (study.name, str(root))
    if key not in _NOW:
        _NOW[key] = study_inputs(study, out, root=Path(root))
    now = _NOW[key]
    now = {**now, "machine": record["inputs"].get("machine")}  # another machine: not stale
    if RECORDED_VERSIONS:
        now["versions"] = record["inputs"].get("versions")
    when = f"the study `{study.name}` at commit `{record['git_commit']}`, " \
           f"{record['finished'][:10]}"
    ok, why = M.reusable(record, now, out)
    if ok:
        return f"<sub>From {when}; its inputs and files are unchanged since.</sub>\n\n"
    then = record["inputs"]
    kinds = [k for k in ("code", "versions", "settings", "reads") if then.get(k) != now.get(k)]
    what = (f"its {' and '.join(kinds)} changed since" if kinds
            else f"its files changed since ({why})")
    return (f"<sub>**Stale**: from {when}; {what} (`rsfbench reproduce --dry-run` says how): "
            f"`rsfbench study {study.name}` reruns it.</sub>\n\n")


def fill(readme: str, root: Path = ROOT) -> str:
    """``readme`` with every generated block re-rendered."""
    _NOW.clear()
    return _BLOCK.sub(lambda m: f"{m.group(1)}{_body(m.group('source'), root)}\n{m.group(4)}",
                      readme)


def _body(source: str, root: Path) -> str:
    return origin(source, root) + render(source, root)


def refresh(path: Path = ROOT / "README.md", check: bool = False,
            root: Path | None = None) -> list[str]:
    """Rewrite the blocks of the page ``path`` (or with ``check`` only compare), rendered from
    ``root``'s results (default: the page's directory); returns the sources of the blocks that
    were out of date.

    Parameters
    ----------
    path : pathlib.Path
        The page (default: the README).
    check : bool
        Only compare; write nothing.
    root : pathlib.Path, optional
        The directory the results are read from; ``None``: the page's.

    Returns
    -------
    list of str
        The sources of the blocks that were out of date.
    """
    root = path.parent if root is None else root
    old = path.read_text()
    _NOW.clear()
    stale = [m.group("source") for m in _BLOCK.finditer(old)
             if m.group("body").rstrip("\n") != _body(m.group("source"), root)]
    if stale and not check:
        path.write_text(fill(old, root))
    return stale


def pages(root: Path = ROOT) -> list[Path]:
    """The pages that quote results: the README and each page of ``docs/`` holding a block."""
    docs = sorted(p for p in (root / "docs").glob("*.md") if _BLOCK.search(p.read_text()))
    return [root / "README.md", *docs]


def refresh_pages(check: bool = False, root: Path = ROOT) -> list[str]:
    """:func:`refresh` on every page of :func:`pages`; the stale blocks as ``page: source``."""
    return [f"{page.relative_to(root)}: {source}" for page in pages(root)
            for source in refresh(page, check, root)]

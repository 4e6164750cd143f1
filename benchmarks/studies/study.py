"""How a study declares itself: one module of :mod:`benchmarks.studies` with a module-level
``STUDY = Study(...)``.

A declaration says what the pipeline needs to plan and reuse the study without running it: its
name (``rsfbench study NAME``), the files it reads (another study's, in ``results/``) and those
it writes (glob patterns, relative to the output directory: the only files recorded as its
outputs; writing any other is an error), its plan (``quick``: ``make reproduce``; ``full``:
``make reproduce-full`` only), its place in the plan and the report, and its expected minutes on
2 cores. ``run(out, **settings)`` writes the files; ``report(out)`` returns the study's section of
``REPORT.md`` (Markdown, no heading), read back from its files so that a reused study reports too.

Adding a study is one new file here; :func:`benchmarks.pipeline.reproduce.studies` finds it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

__all__ = ["Study", "PLANS", "markdown_file"]

#: the plans a study can be in
PLANS = ("quick", "full")


@dataclass(frozen=True, eq=False)
class Study:
    """A study's declaration (see the module docstring). ``timed``: its numbers are timings (the
    machine is an input of its reuse). ``settings``: the keyword arguments of ``run``.
    ``data``: project files it reads, relative to the project. ``modules``: project modules it
    runs without importing them (a command line run as a program)."""

    name: str
    title: str
    order: int
    run: Callable[..., object]
    writes: tuple[str, ...]
    report: Callable[[Path], str] | None = None
    plan: str = "quick"
    minutes: float = 0.0
    timed: bool = False
    settings: dict = field(default_factory=dict)
    reads: tuple[str, ...] = ()
    data: tuple[str, ...] = ()
    modules: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not re.fullmatch(r"[a-z][a-z0-9-]*", self.name):
            raise ValueError(f"study name {self.name!r}: lower-case words joined by '-'")
        if self.plan not in PLANS:
            raise ValueError(f"study {self.name}: plan must be one of {PLANS}, got {self.plan!r}")
        if not self.writes:
            raise ValueError(f"study {self.name} declares no files it writes")
        for pattern in (*self.writes, *self.reads):
            if Path(pattern).is_absolute() or ".." in Path(pattern).parts:
                raise ValueError(f"study {self.name}: {pattern!r} is not relative to the output "
                                 "directory")
            if "**" in pattern:
                raise ValueError(f"study {self.name}: {pattern!r}: a pattern names each level "
                                 "of its path ('*' within one, not '**')")
        if not self.minutes > 0:
            raise ValueError(f"study {self.name}: expected minutes must be positive")

    @property
    def full(self) -> bool:
        """In the full plan only."""
        return self.plan == "full"

    def outputs(self, out: Path) -> list[str]:
        """The files in ``out`` that match the declared patterns, relative, sorted."""
        out = Path(out)
        return sorted({p.relative_to(out).as_posix() for pattern in self.writes
                       for p in out.glob(pattern) if p.is_file()})

    def declares(self, relative: str) -> bool:
        """Does a declared pattern match the file ``relative`` (to the output directory)?"""
        return any(Path(relative).match(pattern) and
                   len(Path(relative).parts) == len(Path(pattern).parts)
                   for pattern in self.writes)


def markdown_file(name: str, part: int | None = None, drop_lines: int = 0):
    """A ``report``: the Markdown file ``name`` of the output directory, or its ``part``-th
    piece split at second-level headings, without its first ``drop_lines`` lines."""
    def report(out: Path) -> str:
        text = (Path(out) / name).read_text(encoding="utf-8")
        if part is not None:
            text = text.split("\n## ")[part]
        return text.split("\n", drop_lines)[drop_lines] if drop_lines else text
    return report

"""How a study declares itself: one module of :mod:`benchmarks.studies` with a module-level
``STUDY = Study(...)``; a module that owns the work of several studies declares them together,
``STUDIES = (Study(...), ...)``.

A declaration says what the pipeline needs to plan and reuse the study without running it: its
name (``rsfbench study NAME``), the files it reads (another study's, in ``results/``) and those
it writes (glob patterns, relative to the output directory: the only files recorded as its
outputs; writing any other is an error), its plan (``quick``: ``make reproduce``; ``full``:
``make reproduce-full`` only), its place in the plan and the report, and its expected minutes on
2 cores. ``settings`` are the keyword arguments of ``run`` with their defaults (numbers or words;
``rsfbench study NAME --set KEY=VALUE`` changes one), ``limits`` the inclusive range of a numeric
one; ``check(settings)`` refuses a combination of them (``ValueError``) before any work.
``run(out, **settings)`` writes the files; ``report(out)`` returns the study's section of
``REPORT.md`` (Markdown, no heading), read back from its files so that a reused study reports too.

Adding a study is one new file here, or one more declaration in the module that owns its work;
:func:`benchmarks.pipeline.reproduce.studies` finds it.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

__all__ = ["Study", "PLANS", "markdown_file", "matches"]

#: the plans a study can be in
PLANS = ("quick", "full")


@dataclass(frozen=True, eq=False)
class Study:
    """A study's declaration (see the module docstring). ``timed``: its numbers are timings (the
    machine is an input of its reuse). ``data``: project files it reads, relative to the project. ``modules``: project modules it
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
    limits: dict = field(default_factory=dict)
    check: Callable[[dict], None] | None = None
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
        if set(self.limits) - set(self.settings):
            raise ValueError(f"study {self.name}: limits of unknown settings "
                             f"{sorted(set(self.limits) - set(self.settings))}")
        if not self.minutes > 0:
            raise ValueError(f"study {self.name}: expected minutes must be positive")

    @property
    def full(self) -> bool:
        """In the full plan only."""
        return self.plan == "full"

    def declares(self, relative: str) -> bool:
        """Does a declared pattern match the file ``relative`` (to the output directory)?"""
        return any(matches(relative, pattern) for pattern in self.writes)

    def checked(self, settings: dict) -> dict:
        """``settings`` (by name) if they are this study's and within its limits, else
        ``ValueError`` naming the setting, the value and what is expected."""
        unknown = sorted(set(settings) - set(self.settings))
        if unknown:
            known = ", ".join(f"{k} (default {v!r})" for k, v in self.settings.items())
            raise ValueError(f"study {self.name} has no setting {', '.join(unknown)}; its "
                             f"settings: {known or 'none'}")
        for key, value in settings.items():
            default, number = self.settings[key], (int, float)
            if isinstance(default, number) and not isinstance(default, bool) and (
                    isinstance(value, bool) or not isinstance(value, number)
                    or isinstance(default, int) and not isinstance(value, int)):
                kind = "a whole number" if isinstance(default, int) else "a number"
                raise ValueError(f"study {self.name}: setting {key} must be {kind}, as its "
                                 f"default {default!r} is; got {value!r}")
            if isinstance(default, str):
                continue
            low, high = self.limits.get(key, (-math.inf, math.inf))
            # an int compares with the limits as it is (math.isfinite of a 400-digit one
            # would overflow); a float is also refused as NaN or infinite
            if not (low <= value <= high and (isinstance(value, int) or math.isfinite(value))):
                shown = f"{value!r}" if len(repr(value)) <= 30 else f"{repr(value)[:20]}…"
                raise ValueError(f"study {self.name}: setting {key} = {shown} is outside "
                                 f"[{low:g}, {high:g}]")
        if self.check is not None:
            self.check({**self.settings, **settings})
        return settings


def matches(relative: str, pattern: str) -> bool:
    """Does the glob ``pattern`` match the file ``relative``, level by level?"""
    return (len(Path(relative).parts) == len(Path(pattern).parts)
            and Path(relative).match(pattern))


def markdown_file(name: str):
    """A ``report``: the Markdown file ``name`` of the output directory."""
    return lambda out: (Path(out) / name).read_text(encoding="utf-8")

"""Does the choice of solver change what is inferred?

For each window and law, the data are the published means with σ = 10 % of each (assumed, as in
:mod:`benchmarks.studies.paper_sweeps`), and for W2/slip also one synthetic set (ΔT and Δμ of the
reference at the published fit, plus noise of σ = 5 %, seed 0). The prior is uniform in
(b, log10 Lc) on the paper sweep's box around the published fit. With the setting
``observations`` (``rsfbench study solver-effect --set observations=FILE``: an observations file
of ``rsfbench observe``) one's own data are the data set ``yours`` beside them, on each window
and law of the settings ``windows`` and ``laws`` (W2 and slip alone: ``--set windows=W2 --set
laws=slip``) — the question for a recording of an apparatus that is one of the windows. For an
apparatus of one's own, ``rsfbench solver-effect --problem FILE --observations FILE`` inverts
``yours`` on that problem alone (``own``); its quick mode compares only the own methods' front
settings and the paper's ETD2 (:data:`~benchmarks.inversion.solver_effect.QUICK_LADDERS`) on
:data:`~benchmarks.inversion.solver_effect.QUICK_N`-node grids.
Every candidate setting inverts the same data and is compared with the inversion by a tight
reference setting, by the rule of :mod:`benchmarks.inversion.solver_effect`, which also writes
the files, their report and figure (:func:`~benchmarks.inversion.solver_effect.write_solver_effect`,
which the command calls too); this module is the study: its settings, its run into
``results/`` and its section of ``REPORT.md``.
"""

from __future__ import annotations

from pathlib import Path

from benchmarks.inversion.observations import read_observations
from benchmarks.inversion.solver_effect import write_solver_effect
from benchmarks.studies.study import Study
from problems import WINDOWS

__all__ = ["STUDY"]


def run(out: Path, n: int, windows: str, laws: str, observations: str) -> None:
    yours = read_observations(observations, curve_noise="none") if observations else None
    write_solver_effect(out, n=n, windows=_words(windows), laws=_words(laws), yours=yours,
                        study_csv=out / "wp_full.csv", progress=True)
    print((out / "solver_effect.md").read_text().split("\n## ")[1])


def report(out: Path) -> str:
    section = (out / "solver_effect.md").read_text().split("\n## ")[1].split("\n", 1)[1]
    return (f"{section}\nEvery window and law: `solver_effect.md`.\n\n"
            "![solver effect](solver_effect.png)\n")


def _words(text: str) -> tuple[str, ...]:
    return tuple(w.strip() for w in text.split(",") if w.strip())


def check(settings: dict) -> None:
    """Refuse an unknown window or law, and an observations file that cannot be read, before
    any work."""
    for key, known in (("windows", WINDOWS), ("laws", ("slip", "aging"))):
        words = _words(settings[key])
        bad = [w for w in words if w not in known]
        if bad or not words:
            raise ValueError(f"study solver-effect: setting {key} = {settings[key]!r}: expected "
                             f"some of {', '.join(known)}, joined by commas")
    if settings["observations"]:
        try:
            read_observations(settings["observations"], curve_noise="none")
        except ValueError as exc:
            raise ValueError(f"study solver-effect: setting observations: {exc}") from None


STUDY = Study("solver-effect", "The solver's effect on the inferred (b, Lc) (`solver_effect.*`)",
              220, run, report=report, plan="full", timed=True, reads=("wp_full.csv",),
              settings={"n": 31, "windows": "W1,W2,W3,W4", "laws": "slip,aging",
                        "observations": ""}, limits={"n": (5, 301)}, check=check,
              writes=("solver_effect.csv", "solver_effect.md", "solver_effect.png",
                      "solver_effect_recommendation.csv"), minutes=101)

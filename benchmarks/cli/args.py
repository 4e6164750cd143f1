"""What every ``rsfbench`` command shares: checked argument types, the problem and integrator
options, and a parser whose errors are one line.

Every value is checked while the command line is parsed, before any work: a number is finite
and in range (``--t-end 0`` and ``--wall-budget -1`` are refused), a path to write is writable,
a file to read exists. ``--help`` states every option's default and unit.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
import warnings
from pathlib import Path

from benchmarks.ensemble.executors import RunStopped
from benchmarks.inversion.observations import observations, read_observations
from benchmarks.records.files import note_input
from benchmarks.records.interrupts import stop_on_sigterm, stopped_by
from benchmarks.records.provenance import version_line
from integrators import algorithm_class, make_algorithm
from problems import LAWS, load_problem, preset, variant

__all__ = ["say", "show_progress", "RunStopped", "stop_on_sigterm", "stopped_by", "Parser",
           "HelpFormatter", "positive", "non_negative", "finite", "pair",
           "count", "seed", "bounded", "steps_or_none", "workers", "b_lc", "b_range", "lc_range",
           "quantity", "SPEED", "TIME", "out_dir", "out_file", "in_file", "preset_name", "flagged",
           "add_problem_options", "add_integrator_options", "add_overwrite_options",
           "integrator_from_args",
           "problem_from_args", "add_problem_choice", "add_observation_options",
           "check_observation_options", "observations_from_args", "ACCURACY",
           "sensitivity_request", "sensitive_default", "add_sensitivity_option",
           "check_no_tolerances"]

#: the relative error in ΔT the default integrator must reach
ACCURACY = 1e-3
#: where :func:`say` writes while a command runs (set by :func:`benchmarks.cli.main`)
_OUTPUT = None


def show_progress(args) -> bool:
    """Progress bars on the standard error: not with ``--json`` or ``--no-progress``, and not
    when the standard error is not a terminal (a log file would fill with redrawn bars)."""
    return (not getattr(args, "json", False) and not getattr(args, "no_progress", False)
            and sys.stderr.isatty())


def say(*args, **kwargs) -> None:
    """``print`` to the command's own output: the standard output as it was when the command
    started. Anything else written to the standard output while a command runs (a library's
    messages, from Python or C) goes to the standard error (:func:`benchmarks.cli.main`)."""
    print(*args, file=_OUTPUT or sys.stdout, **kwargs)


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Appends "(default: X)" to an option's help unless the help already says its default, the
    option is a flag, or it has no default (then its help says what happens without it)."""

    def _get_help_string(self, action):
        text = action.help or ""
        if ("default" in text or action.default is None or action.default is False
                or action.default == argparse.SUPPRESS or action.required
                or isinstance(action, argparse._HelpAction)):
            return text
        value = (" ".join(map(str, action.default)) if isinstance(action.default, list)
                 else action.default)
        return f"{text} (default: {value})"


#: a negative number, exponent included (no option of rsfbench's looks like one)
_NEGATIVE_NUMBER = re.compile(r"^-((\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|inf|infinity|nan)$",
                              re.IGNORECASE)


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line (no usage block), exit status 2."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)
        # "-1e-4" is a value, not an option: argparse's own rule knows -1 and -.5 alone
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def print_help(self, file=None):
        # --help is the command's output: the standard output as it was (main() points
        # sys.stdout at the standard error while a command runs)
        super().print_help(file if file is not None else _OUTPUT or sys.stdout)

    def error(self, message):
        raise UsageError(f"{self.prog}: {message}{self._unit_of(message)} (see {self.prog} --help)")

    def _unit_of(self, message: str) -> str:
        """"; in s" and the like for a refused value of a flag whose metavar is a unit."""
        if not message.startswith("argument "):
            return ""
        flags = message[len("argument "):].split(":", 1)[0].split("/")
        for action in self._actions:
            if set(flags) & set(action.option_strings):
                unit = _METAVAR_UNITS.get(action.metavar)
                return f"; a value in {unit}" if unit and f" {unit}" not in message else ""
        return ""


#: the units that a flag's metavar names (``--t-end S``)
_METAVAR_UNITS = {"S": "s", "M_S": "m/s", "KG": "kg", "N_PER_M": "N/m", "N_S_PER_M": "N s/m",
                  "LC_M": "m"}


class UsageError(ValueError):
    """A command line that does not parse; the message is the one line to print."""


def _number(text: str, what: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{what}, got {text!r}") from None
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"{what}, got {text!r}")
    return x


def positive(text: str) -> float:
    """A finite number > 0."""
    x = _number(text, "must be a finite positive number")
    if x <= 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return x


def non_negative(text: str) -> float:
    """A finite number ≥ 0."""
    x = _number(text, "must be a finite number ≥ 0")
    if x < 0:
        raise argparse.ArgumentTypeError(f"must be ≥ 0, got {text!r}")
    return x


def pair(text: str, form: str, ok, need: str) -> tuple[float, float]:
    """Two comma-separated finite numbers ``x,y`` with ``ok(x, y)``; otherwise an argparse error
    saying the ``form`` (e.g. ``B,LC (two numbers, Lc in m)``) or what they ``need``."""
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {form}, got {text!r}") from None
    if not (math.isfinite(x) and math.isfinite(y) and ok(x, y)):
        raise argparse.ArgumentTypeError(f"needs {need}, got {text!r}")
    return x, y


def b_lc(text: str) -> tuple[float, float]:
    """``B,LC``: b ≥ 0 and Lc > 0 in metres, e.g. ``0.0094,3e-7``."""
    return pair(text, "B,LC (two numbers, Lc in m)", lambda b, lc: b >= 0 and lc > 0,
                "b ≥ 0 and Lc > 0 (finite)")


def finite(text: str) -> float:
    """A finite number."""
    return _number(text, "must be a finite number")


def count(text: str, minimum: int = 1) -> int:
    """An integer ≥ 1 (≥ ``minimum``)."""
    try:
        n = int(text)
    except ValueError:
        n = minimum - 1
    if n < minimum:
        raise argparse.ArgumentTypeError(f"must be an integer ≥ {minimum}, got {text!r}")
    return n


def seed(text: str) -> int:
    """An integer ≥ 0 (a random seed)."""
    return count(text, minimum=0)


def relative_error(text: str) -> float:
    """A type: a relative error, above 0 and below 1 (1e-3: 0.1 %)."""
    x = positive(text)
    if not x < 1.0:
        raise argparse.ArgumentTypeError(f"must be a relative error above 0 and below 1 (1e-3 "
                                         f"is 0.1 %), got {text!r}")
    return x


def bounded(minimum: int, maximum: int, why: str):
    """A type: an integer from ``minimum`` to ``maximum``; above it, ``why`` says what breaks."""
    def check(text: str) -> int:
        n = count(text, minimum)
        if n > maximum:
            raise argparse.ArgumentTypeError(f"must be an integer from {minimum} to "
                                             f"{maximum:,} ({why}), got {text!r}")
        return n
    check.__name__ = "integer"
    return check


def steps_or_none(maximum: int):
    """A type: 0 (no posterior) or an integer from 2 to ``maximum`` (emcee's steps per
    walker)."""
    def check(text: str) -> int:
        n = count(text, 0)
        if n == 1 or n > maximum:
            raise argparse.ArgumentTypeError(f"must be 0 (no posterior) or an integer from 2 to "
                                             f"{maximum:,}, got {text!r}")
        return n
    check.__name__ = "steps"
    return check


#: emcee's steps per walker at most
MAX_STEPS = 1_000_000
#: emcee's walkers at most
MAX_WALKERS = 10_000
#: the type of ``--steps``: emcee's steps per walker, 0 for no posterior
chain_steps = steps_or_none(MAX_STEPS)
#: the type of ``--walkers``
chain_walkers = bounded(4, MAX_WALKERS, "each step solves every walker at once")


def workers(text: str) -> int:
    """An integer from 1 to 4 × the cores: more only adds start-up time and memory."""
    most = 4 * (os.cpu_count() or 1)
    return bounded(1, most, f"4 × this machine's {os.cpu_count()} cores; more workers only "
                   "add start-up time and memory")(text)


def b_range(text: str):
    """``LO,HI``: 0 ≤ LO < HI, the box of b."""
    return pair(text, "LO,HI (two numbers)", lambda lo, hi: 0 <= lo < hi, "0 ≤ LO < HI (finite)")


def lc_range(text: str):
    """``LO,HI``: 0 < LO < HI in metres, the box of Lc."""
    return pair(text, "LO,HI (two numbers, in m)", lambda lo, hi: 0 < lo < hi,
                "0 < LO < HI (finite, in m)")


def quantity(kind, what: str):
    """``kind`` (a checked number type), whose refusal also says the quantity and its unit."""
    def check(text: str) -> float:
        try:
            return kind(text)
        except argparse.ArgumentTypeError as exc:
            raise argparse.ArgumentTypeError(f"{exc}; {what}") from None
    check.__name__ = kind.__name__
    return check


SPEED, TIME = quantity(positive, "a speed in m/s"), quantity(positive, "a time in s")


def numbers(what: str, example: str):
    """An argparse type: comma-separated numbers (``what`` and an ``example`` in its error)."""
    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(float(v) for v in text.split(","))
        except ValueError:
            values = ()
        if not values or not all(math.isfinite(v) for v in values):
            raise argparse.ArgumentTypeError(f"expected finite {what} separated by commas "
                                             f"({example}), got {text!r}")
        return values
    return parse


def _writable_dir(path: Path, what: str) -> None:
    """``path`` is a directory that exists or can be made, and can be written in."""
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise argparse.ArgumentTypeError(f"{what}: {probe} is not a directory")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{what}: {probe} is not writable")


def out_dir(text: str) -> Path:
    """A directory to write into: it exists or can be created, and is writable."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} exists and is not a directory")
    _writable_dir(path, repr(text))
    return path


def out_file(*suffixes: str):
    """A type: a file to write, with one of ``suffixes``, in a writable (or creatable) place."""
    def check(text: str) -> Path:
        path = Path(text)
        if suffixes and path.suffix.lower() not in suffixes:
            raise argparse.ArgumentTypeError(f"{text!r} must end in {' or '.join(suffixes)}")
        if path.is_dir():
            raise argparse.ArgumentTypeError(f"{text!r} is a directory, not a file")
        if path.exists() and not os.access(path, os.W_OK):
            raise argparse.ArgumentTypeError(f"{text!r} is not writable")
        _writable_dir(path.parent, repr(text))
        return path
    check.__name__ = "file to write"
    return check


def in_file(text: str) -> Path:
    """A file to read: it exists, is a file and is readable."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text!r} does not exist")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text!r} is not a file")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"{text!r} is not readable")
    note_input(path)                      # never written over by this run (records.files)
    return path


#: the commands whose files never replace a user's (:mod:`benchmarks.records.files`)
GUARDED_COMMANDS = ("simulate", "observe", "invert", "sweep", "solver-effect", "fit", "shs",
                    "step", "compare", "slip-weakening", "study", "reproduce",
                    "work-precision", "convergence", "windows", "design")


def add_overwrite_options(sub) -> None:
    """``--overwrite`` on each command of :data:`GUARDED_COMMANDS` that writes files."""
    for name, p in sub.choices.items():
        for action in p._actions:                      # lab's step, shs and fit
            if isinstance(action, argparse._SubParsersAction):
                add_overwrite_options(action)
        writes = {"out", "save", "plot"} & {a.dest for a in p._actions}
        if name in GUARDED_COMMANDS and writes:
            p.add_argument("--overwrite", action="store_true",
                           help="replace existing files of the names this command writes "
                                "even when rsfbench did not write them (default: such a file "
                                "is refused before any work; a file rsfbench wrote and nobody "
                                "changed is replaced; an input never is)")


def preset_name(text: str) -> str:
    """A preset's name as the registry spells it: ``paper-example`` or ``W1``..``W4``."""
    return "paper-example" if text.lower() == "paper-example" else text.upper()


def add_problem_choice(p, preset_names, what: str) -> None:
    """--preset NAME or --problem FILE (one of them required), and --law of a preset."""
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--preset", choices=preset_names, type=preset_name,
                       help=f"{what} (no default: --preset or --problem is required)")
    which.add_argument("--problem", type=in_file, metavar="FILE",
                       help="or your own apparatus: a TOML or JSON file (mass, stiffness, "
                            "normal_force, t_end, [law], [loading], [initial]; SI units; "
                            "docs/examples/apparatus.toml is one; no default)")
    p.add_argument("--law", choices=tuple(LAWS),
                   help="friction law of --preset (default: slip; nagata: the aging law's best "
                        "fit with the Nagata law's c = 2)")


def add_problem_options(p, preset_names, t_end_help: str = "simulated time in s (default: the "
                        "preset's or the file's: 20 s for paper-example, 40 s for W1–W4)") -> None:
    """--preset or --problem, --law, --b, --lc, --t-end: a problem with its friction parameters
    replaced."""
    add_problem_choice(p, preset_names, "the problem: the paper's speed-up example or a window "
                       "of its Table 2")
    p.add_argument("--b", type=non_negative, help="evolution parameter b, dimensionless "
                   "(default: the preset's best fit, or the file's)")
    p.add_argument("--lc", type=positive, metavar="LC_M", help="critical slip distance Lc in "
                   "metres, e.g. 3e-7 for 0.3 µm (default: the preset's best fit, or the file's)")
    p.add_argument("--t-end", type=positive, metavar="S", help=t_end_help)


def problem_from_args(args, fields=("b", "lc", "t_end")):
    """The problem of --preset (with --law) or --problem FILE, with the given options among
    ``fields`` (--b, --lc, --t-end) replaced (ValueError for --law with a file: the file names
    its law)."""
    given = {k: getattr(args, k, None) for k in fields}
    changes = {k: v for k, v in given.items() if v is not None}
    if getattr(args, "problem", None) is not None:
        if args.law is not None:
            raise ValueError("--law applies to --preset; a problem file names its law in [law]")
        problem = load_problem(args.problem)
        return variant(problem, **changes) if changes else problem
    return preset(args.preset, law=args.law or "slip", **changes)


def add_observation_options(p) -> None:
    """--obs-recurrence, --sigma-recurrence, --obs-drop, --sigma-drop: the observed means and
    their σ (a window's published means by default; σ 10 % of the mean, flagged, by default)."""
    p.add_argument("--obs-recurrence", type=positive, metavar="S",
                   help="observed mean ΔT in s (default: the window's published mean)")
    p.add_argument("--sigma-recurrence", type=positive, metavar="S",
                   help="σ of ΔT in s (default: 10 %% of the mean, flagged as an assumption)")
    p.add_argument("--obs-drop", type=positive, metavar="X",
                   help="observed mean friction drop Δμ, dimensionless (default: the window's "
                        "published mean)")
    p.add_argument("--sigma-drop", type=positive, metavar="X",
                   help="σ of Δμ (default: 10 %% of the mean, flagged as an assumption)")
    p.add_argument("--observations", type=in_file, metavar="FILE.json",
                   help="an observations file of `rsfbench observe`: its means, their σ and "
                        "its curves, instead of the four options above (default: none)")


def model_error_spec(text: str) -> dict:
    """``--model-error``: ``OBSERVABLE=FRACTION,…`` (recurrence, drop, curves; fractions of
    ΔT̄, Δμ̄ and Δμ̄ in [0, 1)), as a dict; an argparse error naming what is wrong."""
    from benchmarks.inversion.observations import check_model_error
    out = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        name, sep, value = part.partition("=")
        try:
            out[name.strip()] = float(value) if sep else None
            if not sep:
                raise ValueError(f"{part!r} is not OBSERVABLE=FRACTION")
            check_model_error(out)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    if not out:
        raise argparse.ArgumentTypeError("give OBSERVABLE=FRACTION, e.g. recurrence=0.01")
    return out


def add_model_error_options(p) -> None:
    """--model-error and --curve-chain: what the model itself may miss, and whether its curves
    go through the recording's measurement chain."""
    p.add_argument("--model-error", type=model_error_spec, metavar="OBS=FRAC,…",
                   help="the model's own error per observable, added in quadrature to the "
                        "data's σ (σ² = σ_obs² + σ_model²): recurrence=F (σ_model = F × ΔT̄), "
                        "drop=F (F × Δμ̄), curves=F (F × Δμ̄ in μ at each common slip of the "
                        "curves); fractions in [0, 1), e.g. recurrence=0.001,curves=0.01 "
                        "(default: 0 for each: the data's σ alone)")
    p.add_argument("--curve-chain", choices=("recorded", "none"), default="recorded",
                   help="pass the model's curves through the measurement chain that observe "
                        "recorded in the observations file (its rate, filters and event "
                        "timing; a file without one has none) or compare them as the model "
                        "makes them (default: recorded)")


def check_observation_options(args, problem, published: bool) -> None:
    """Refuse a problem without published means when --obs-recurrence or --obs-drop is
    missing, and an observations file with any of them."""
    if getattr(args, "observations", None) is not None:
        given = [flag for field, flag in _OBSERVATION_FLAGS
                 if getattr(args, _DEST[field]) is not None]
        if given:
            raise ValueError(f"--observations holds the means and their σ: drop {given[0]}")
        return
    if not published:                      # the flags a window's published means fill
        for flag, value in (("--obs-recurrence", args.obs_recurrence),
                            ("--obs-drop", args.obs_drop)):
            if value is None:
                raise ValueError(f"{flag} is required for {problem.name or 'this problem'} (it "
                                 "has no observed means)")


def observations_from_args(args, published: bool, curves=None):
    """The observations of the options (a window's published means fill what is not given),
    or of the observations file (``--observations``)."""
    if getattr(args, "observations", None) is not None:
        try:
            return read_observations(args.observations,
                                     curve_noise=getattr(args, "curve_noise", "none"),
                                     curve_sigma=getattr(args, "curve_sigma", None),
                                     model_error=getattr(args, "model_error", None),
                                     chain=getattr(args, "curve_chain", "recorded") != "none")
        except ValueError as exc:
            raise ValueError(f"--observations: {exc}") from None
    try:
        return observations(args.preset if published else "", args.obs_recurrence,
                            args.sigma_recurrence, args.obs_drop, args.sigma_drop, curves,
                            getattr(args, "curve_noise", "none"),
                            getattr(args, "curve_sigma", None),
                            getattr(args, "model_error", None))
    except ValueError as exc:       # name the flag of the value refused
        text = str(exc)
        for field, flag in _OBSERVATION_FLAGS:
            if text.startswith(f"{field} ="):
                raise ValueError(f"{flag}: {text}") from None
        raise


#: the fields of the observations and the flags that set them (sigmas first: their names
#: contain the means')
_OBSERVATION_FLAGS = (("sigma_recurrence_s", "--sigma-recurrence"),
                      ("sigma_friction_drop", "--sigma-drop"),
                      ("recurrence_s", "--obs-recurrence"), ("friction_drop", "--obs-drop"))
_DEST = {"sigma_recurrence_s": "sigma_recurrence", "sigma_friction_drop": "sigma_drop",
         "recurrence_s": "obs_recurrence", "friction_drop": "obs_drop"}


class ShowVersion(argparse.Action):
    """``--version``: the package's version, the checkout's commit and Python's, then exit."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS,
                         help="print the version (package, commit of a checkout, Python) and exit")

    def __call__(self, parser, namespace, values, option_string=None):
        say(version_line())             # the command's output: stdout, also under main()
        parser.exit(0)


def add_integrator_options(p, default: str | None = None) -> None:
    """--integrator, --rtol, --atol, --rhs, --accuracy: named, or the study's recommendation."""
    p.add_argument("--integrator", default=default, metavar="NAME",
                   help=("registry name, see `rsfbench integrators`" + (
                       f" (default: {default})" if default else " (default: the integrator and "
                       "tolerance the work-precision studies recommend for --accuracy)")))
    p.add_argument("--rtol", type=positive, help="relative tolerance of an adaptive integrator "
                   "(required with --integrator NAME of an adaptive method; no default accuracy)")
    p.add_argument("--atol", type=positive, help="absolute tolerance on (h, ln w, Ψ or ln Ψ), "
                   "nondimensional (required with --rtol; no default accuracy)")
    p.add_argument("--rhs", choices=("numba", "python"),
                   help="right-hand side of an adaptive integrator: compiled or plain Python "
                        "(default: numba)")
    p.add_argument("--accuracy", type=relative_error, default=ACCURACY, metavar="REL",
                   help="relative error in the recurrence interval the recommended integrator "
                        "must reach, when no --integrator is named")


def flagged(flag: str, function, *args):
    """``function(*args)``, its ``ValueError`` prefixed by the flag whose value was wrong."""
    try:
        return function(*args)
    except ValueError as exc:
        raise ValueError(f"{flag}: {exc}") from None


def integrator_from_args(args):
    """``(algorithm, why)``: the named integrator with its options, or the recommendation."""
    from benchmarks.devtools.recommendation import recommended
    if args.integrator:
        if getattr(args, "accuracy", ACCURACY) != ACCURACY:
            raise ValueError("--accuracy chooses the recommended integrator and checks it on "
                             "your box; with --integrator it has no effect: drop one of them")
        cls = flagged("--integrator", algorithm_class, args.integrator)
        return (make_algorithm(cls.name, rtol=args.rtol, atol=args.atol, rhs=args.rhs),
                f"{cls.name}, as asked (--integrator)")
    check_no_tolerances(args)
    return recommended(args.accuracy)


def check_no_tolerances(args) -> None:
    """--rtol, --atol and --rhs without --integrator: refused (ValueError)."""
    if args.rtol is not None or args.atol is not None or args.rhs is not None:
        raise ValueError("--rtol, --atol and --rhs need --integrator NAME (without it the "
                         "recommended integrator comes with its own tolerance)")


def sensitivity_request(args, problem, algorithm, why):
    """(parameter names, the algorithm, why) for --sensitivity: the names checked against the
    problem; without --integrator, the fastest setting of the recommendation's front that has
    forward sensitivities at rtol ≤ SENSITIVITY_RTOL and reaches --accuracy (else Rodas5P at
    that rtol); a named method without sensitivities is refused (ValueError)."""
    if args.sensitivity is None:
        return (), algorithm, why
    from problems.directions import sensitivity_names
    names = sensitivity_names(problem, args.sensitivity)
    if args.integrator:
        if not getattr(algorithm, "sensitive", False):
            raise ValueError(f"--sensitivity: {algorithm.name} has no forward sensitivities; "
                             "use --integrator Rodas5P or RadauIIA5")
        return names, algorithm, why
    return (names, *sensitive_default(args.accuracy, "--sensitivity"))


def sensitive_default(accuracy: float, flag: str):
    """``(algorithm, why)``: the fastest setting of the recommendation's front that has forward
    sensitivities at rtol ≤ SENSITIVITY_RTOL and reaches ``accuracy``, else Rodas5P at that
    rtol (``flag`` names the option that asked, in ``why``)."""
    from benchmarks.devtools.recommendation import recommended
    from integrators import make_algorithm
    from problems.directions import SENSITIVITY_RTOL
    algorithm, why = recommended(accuracy, sensitive=True)
    if getattr(algorithm, "sensitive", False):
        return algorithm, why
    why = (f"Rodas5P at rtol {SENSITIVITY_RTOL:g}, for {flag} (the front has no setting with "
           "forward sensitivities)")
    return make_algorithm("Rodas5P", rtol=SENSITIVITY_RTOL, atol=SENSITIVITY_RTOL), why


def add_sensitivity_option(p, what: str) -> None:
    """--sensitivity NAMES: the gradients ``what`` says, along the named parameters."""
    p.add_argument("--sensitivity", metavar="NAMES",
                   help="parameters to differentiate by, comma-separated (a, b, lc, c, k, m, "
                        "fn, damping, vl, vls, vlf, df, the initial state's): the gradients "
                        f"{what}; the front's fastest method with them at rtol ≤ 1e-6 for "
                        "--accuracy unless --integrator says otherwise "
                        "(default: none)")


def add_solver_check_option(p) -> None:
    """--no-solver-check: skip the check of the integrator on the problem's own box."""
    p.add_argument("--no-solver-check", action="store_true",
                   help="do not check the integrator first against a tight reference on the "
                        "box's corners and centre (σ/10; default: check, and tighten or refuse)")


def checked_integrator(args, problem, obs, b_range, lc_range, algorithm, why: str,
                       keep_method: bool = False, held: str | None = None):
    """``(algorithm, why, check)``: the integrator checked on ``problem``'s box for ``obs``
    (:func:`benchmarks.inversion.solver_check.check_solver`), tightened if it had to be (a
    recommended one along the work-precision front, which may change the method, unless
    ``keep_method``); ``ValueError`` when no setting passes; ``check`` None with
    --no-solver-check, which also takes the recommendation as it is (no race on the box).
    ``held``: the setting (``repr``) of a store the run resumes, kept where it is a
    contender."""
    from benchmarks.inversion.solver_check import check_solver
    if args.no_solver_check:
        return algorithm, why + " (not checked on this problem: --no-solver-check)", None
    from benchmarks.inversion.solver_check import WALL_BUDGET, tighter
    talk = (lambda text: None) if args.json else (lambda text: say(f"… {text}"))
    step = tighter
    if not getattr(args, "integrator", None) and not keep_method:   # the recommendation:
        from benchmarks.devtools.recommendation import tighter_on_front
        step = lambda alg: tighter_on_front(alg) or tighter(alg)  # noqa: E731
    # a recommended setting is checked on the level it was chosen for, too
    level = None if getattr(args, "integrator", None) else getattr(args, "accuracy", None)
    if level is not None and not keep_method:          # the recommendation, or a near-equal
        from benchmarks.inversion.solver_check import recommended_on_box
        algorithm, why = recommended_on_box(problem, level, b_range, lc_range,
                                            getattr(args, "wall_budget", None) or WALL_BUDGET,
                                            say=talk, held=held)
    check = check_solver(problem, algorithm, obs, b_range, lc_range, next_setting=step,
                         workers=getattr(args, "workers", None), say=talk,
                         wall_budget=getattr(args, "wall_budget", None) or WALL_BUDGET,
                         level=level)
    if check.nothing_to_check:
        warnings.warn(f"the integrator is not checked on this problem: {check.message}",
                      stacklevel=1)
        return algorithm, f"{why} (not checked on this problem: {check.message})", check
    if not check.passed:
        raise ValueError(f"the integrator check on this problem failed: {check.message}")
    if check.algorithm is not algorithm:
        why = f"{why}; tightened on this problem's box: {check.message}"
    else:
        why = f"{why}; checked on this problem's box: {check.message}"
    return check.algorithm, why, check


def wants_json(argv: list[str]) -> bool:
    """Did the command line ask for one JSON document (``--json`` before any ``--``)?"""
    argv = sys.argv[1:] if argv is None else argv
    return "--json" in (argv[:argv.index("--")] if "--" in argv else argv)

"""The one registry of integrators, and the base class every algorithm derives from.

Tests, benchmarks and the CLI iterate over :data:`REGISTRY`; adding an algorithm class with
:func:`register` enrolls it everywhere. The adapters to external libraries are *declared* by
name (:meth:`Registry.declare`) and imported on first use: looking one name up (``[]``, ``get``,
``in``) imports its module; iterating or ``len`` imports every declared module (a library that
fails to import is left out, with the reason in :data:`UNAVAILABLE`).

Families are tags, not spellings (DiffEqDevTools' ``:tags`` and ``filter_by_tags``): each class
carries :attr:`Algorithm.tags`, derived from the facts it declares, and a study takes a family
with :meth:`Registry.select` (``REGISTRY.select("lsoda", "compiled")``), never by a library
name or a pattern of names.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Mapping
from typing import ClassVar

from problems._validate import check_count, check_positive

__all__ = ["Algorithm", "AdaptiveAlgorithm", "ProblemNotSupported", "REGISTRY", "Registry",
           "UNAVAILABLE", "register", "algorithm_class", "make_algorithm", "filter_by_tags",
           "LIBRARIES", "KINDS", "CODES", "TAGS"]

#: the library tags, one per algorithm (:attr:`Algorithm.package`): "own" is this project's
#: compiled methods, "sundials-c" SUNDIALS called from C; the others name the Python package
LIBRARIES = ("own", "scipy", "numbalsoda", "scikits-odes", "assimulo", "scikit-sundae",
             "sundials-c", "cyrk")
#: the kind tags, one per algorithm (:attr:`Algorithm.kind`): "explicit" and "implicit" are
#: Runge–Kutta methods (implicit: Radau IIA, additive IMEX), "multistep" BDF, Adams and LSODA
KINDS = ("explicit", "implicit", "rosenbrock", "exponential", "multistep")
#: the numerical codes more than one adapter calls (:attr:`Algorithm.code`): a tag, so that a
#: study takes every way of calling one (SUNDIALS' CVODE, IDA and ARKODE; LSODA and its ports)
CODES = ("sundials", "lsoda")
#: every tag an algorithm may carry ("sensitivities": forward sensitivities, ``solve(...,
#: sensitivity=...)``)
TAGS = frozenset((*LIBRARIES, *KINDS, *CODES, "compiled", "adaptive", "fixed-step", "stiff",
                  "dense-output", "events", "dae", "sensitivities"))


class ProblemNotSupported(ValueError):
    """A method that cannot integrate a problem at all (the paper's ETD without mass): raised by
    :meth:`Algorithm.check_problem` before any work."""


@dataclasses.dataclass(frozen=True)
class Algorithm:
    """Options of an integration method, never state. Subclasses are frozen dataclasses.

    Class attributes describe the method: ``family``, ``order`` (classical order, in the
    non-stiff limit), ``stiff_order`` (observed order on the stiff stick–slip problem, where it
    differs: order reduction; 0 when the error meets a step-independent floor there),
    ``adaptive``, ``library``. ``tags`` is derived from the facts, when the class is made: the
    ``package`` and the ``kind`` (one of :data:`LIBRARIES` and :data:`KINDS`, required of a
    registered class), the ``code`` if set, "compiled", "adaptive" or "fixed-step", "stiff",
    "dense-output" (``saves_at_times``), "events" (``locates_events``) and "dae" where true.
    A new method gets its tags by declaring its facts; no class sets ``tags`` itself.

    The base class takes no options; each method's class lists its own under ``Parameters``.
    """

    name: ClassVar[str] = ""
    family: ClassVar[str] = ""
    order: ClassVar[int] = 0
    stiff_order: ClassVar[int | None] = None     # None: same as ``order``
    adaptive: ClassVar[bool] = False
    stiff: ClassVar[bool] = True
    library: ClassVar[str] = ""
    #: it saves at any given times (``solve(..., save_at=)``) from its dense output
    saves_at_times: ClassVar[bool] = True
    #: the library tag (:data:`LIBRARIES`), the kind (:data:`KINDS`), the shared code
    #: (:data:`CODES`, or none)
    package: ClassVar[str] = ""
    kind: ClassVar[str] = ""
    code: ClassVar[str] = ""
    #: its step loop calls a compiled right-hand side without the interpreter (numba, C, C++)
    compiled: ClassVar[bool] = False
    #: it reports the stick–slip events (``Solution.events``); it integrates the implicit (DAE)
    #: form
    locates_events: ClassVar[bool] = True
    dae: ClassVar[bool] = False
    #: it can stop a run on its settled cycle (``solve(..., settle=)``)
    settles: ClassVar[bool] = False
    tags: ClassVar[frozenset[str]] = frozenset()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        flags = {"compiled": cls.compiled, "stiff": cls.stiff, "dense-output": cls.saves_at_times,
                 "events": cls.locates_events, "dae": cls.dae,
                 "sensitivities": getattr(cls, "sensitive", False)}
        cls.tags = frozenset({cls.package, cls.kind, cls.code,
                              "adaptive" if cls.adaptive else "fixed-step",
                              *(tag for tag, true in flags.items() if true)} - {""})

    @classmethod
    def library_version(cls) -> str:
        return ""

    def run(self, problem, output, budget, progress):
        """Integrate ``problem``; return an :class:`integrators.core.solution.RawRun`."""
        raise NotImplementedError

    def check_problem(self, problem) -> None:
        """:class:`ProblemNotSupported`, before any work, if the method cannot integrate
        ``problem`` at all (the paper's ETD without mass, say); nothing for a method that can."""

    def options(self) -> dict:
        return dataclasses.asdict(self)


def _options_section(cls) -> str:
    """The numpydoc Parameters and Raises of a method whose options are
    :class:`AdaptiveAlgorithm`'s: written once here, appended to each such class's docstring
    (with its default ``max_steps`` and its right-hand-side tiers)."""
    if tuple(cls.rhs_tiers) == ("numba", "python"):
        tiers = '``"numba"`` (compiled) or ``"python"`` (plain numpy)'
    else:
        tiers = " or ".join(f'``"{t}"``' for t in cls.rhs_tiers) + " only"
        tiers += " (the compiled step loop)" if cls.rhs_tiers == ("numba",) else ""
    mantissa, exponent = f"{cls.max_steps:.0e}".split("e")
    return f"""    Parameters
    ----------
    rtol, atol : float
        The relative and absolute tolerances (required; ``atol`` applies to every component
        of the nondimensional state, O(1–100)).
    max_steps : int
        The budget of accepted steps over the whole solve (retcode ``MaxSteps``; default
        {mantissa}e{int(exponent)}).
    rhs : str
        The right-hand side's tier: {tiers}.

    Raises
    ------
    ValueError
        Without both tolerances, for an rtol outside [100 ulps, 1), a non-positive atol or an
        rhs tier the method does not offer.
    """


@dataclasses.dataclass(frozen=True)
class AdaptiveAlgorithm(Algorithm):
    """Options every adaptive method takes: ``rtol`` and ``atol`` (required: there is no default
    accuracy), the step budget ``max_steps`` (accepted steps over the whole solve, summed over
    restarts) and ``rhs``, the tier of the right-hand side: ``"numba"`` (compiled) or
    ``"python"`` (plain numpy, what a user would write).

    ``atol`` applies to every component of the shared state (h, ln w, Ψ or ln Ψ; O(1–100)).
    """

    rtol: float = None
    atol: float = None
    max_steps: int = 50_000_000
    rhs: str = "numba"

    adaptive: ClassVar[bool] = True
    #: the right-hand-side tiers the library can call, and why if not both
    rhs_tiers: ClassVar[tuple[str, ...]] = ("numba", "python")
    rhs_tiers_reason: ClassVar[str] = ""

    def __post_init__(self) -> None:
        if self.rtol is None or self.atol is None:
            raise ValueError(f"{self.name} needs explicit rtol and atol (no default accuracy), "
                             f"got rtol={self.rtol!r}, atol={self.atol!r}")
        check_positive("atol", self.atol)
        if not RTOL_MIN <= check_positive("rtol", self.rtol) < 1.0:
            raise ValueError(f"rtol must be in [{RTOL_MIN:.1e}, 1) (a relative tolerance below "
                             f"100 ulps cannot be met in double precision), got {self.rtol!r}")
        if not isinstance(self.rhs, str) or self.rhs not in self.rhs_tiers:
            why = f" ({self.rhs_tiers_reason})" if self.rhs_tiers_reason else ""
            raise ValueError(f"rhs must be one of {self.rhs_tiers} for {self.name}, "
                             f"got {self.rhs!r}{why}")
        check_count("max_steps", self.max_steps)

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        own = {k for k, v in cls.__dict__.get("__annotations__", {}).items()
               if "ClassVar" not in str(v)} - {"rtol", "atol", "max_steps", "rhs"}
        if cls.__doc__ and "Parameters\n" not in cls.__doc__ and not own:
            cls.__doc__ = cls.__doc__.rstrip() + "\n\n" + _options_section(cls)

    def make_stepper(self, nd, budget):
        """The backend's adapter to the segment protocol (:mod:`integrators.core.segments`)."""
        raise NotImplementedError

    def run(self, problem, output, budget, progress):
        from integrators.core.segments import run_segments
        stepper = self.make_stepper(problem.nondimensional(), budget)
        try:
            raw = run_segments(problem, stepper, output, budget, progress)
        finally:   # adapters that hold a library solver fold its counters in and release it
            finish = getattr(stepper, "finish", None)
            if finish is not None:
                finish()
        raw.stats = stepper.stats      # with the counters ``finish`` folded in
        return raw


def make_algorithm(name: str, rtol: float | None = None, atol: float | None = None,
                   rhs: str | None = None, **options) -> Algorithm:
    """Build a registry entry from CLI-style options, with a clear error for options the method
    does not take (a fixed-step method has no tolerances, an adaptive one needs both).

    Parameters
    ----------
    name : str
        The registry name, any case (``"Rodas5P"``, ``"scipy-LSODA"``).
    rtol, atol : float, optional
        The tolerances of an adaptive method (dimensionless; a fixed-step method refuses them).
    rhs : str, optional
        The right-hand side's tier of an adaptive method: ``"numba"`` or ``"python"``.
    **options
        The method's other options by name (``dtau_max``, ``max_steps``, …).

    Returns
    -------
    Algorithm
        An instance of the named class.

    Raises
    ------
    ValueError
        For an unknown or unavailable name, an option the method does not take, or a value it
        refuses.
    """
    cls = algorithm_class(name)
    given = dict(options)
    if cls.adaptive:
        given.update({k: v for k, v in (("rtol", rtol), ("atol", atol), ("rhs", rhs)) if v is not None})
    elif rtol is not None or atol is not None:
        raise ValueError(f"{cls.name} is not adaptive and takes no rtol/atol; "
                         "set its step options instead")
    elif rhs is not None and rhs != "numba":
        raise ValueError(f"{cls.name} is compiled with numba; rhs={rhs!r} does not apply")
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(given) - names)
    if unknown:
        raise ValueError(f"{cls.name} has no option(s) {unknown}; it takes {sorted(names)}")
    return cls(**given)


class Registry(Mapping):
    """Name → algorithm class, read-only but for :meth:`register`; names declared for a module
    are resolved by importing it."""

    def __init__(self):
        self._classes: dict[str, type[Algorithm]] = {}
        self._declared: dict[str, str] = {}      # name → module, until the module is imported
        self.origin: dict[str, str] = {}         # name → the module declared for it
        self.install: dict[str, str] = {}        # module → how to install what it needs

    def register(self, cls: type[Algorithm]) -> type[Algorithm]:
        """Enter ``cls`` under ``cls.name`` (the one way in: :func:`register` calls it), once,
        with one library and one kind among its tags."""
        if not cls.name:
            raise ValueError(f"{cls.__qualname__} has no name")
        if cls.name in self._classes:
            raise ValueError(f"integrator name {cls.name!r} registered twice")
        for fact, allowed in (("package", LIBRARIES), ("kind", KINDS), ("code", ("", *CODES))):
            if getattr(cls, fact) not in allowed:
                raise ValueError(f"{cls.name}: {fact} must be one of {allowed}, "
                                 f"got {getattr(cls, fact)!r}")
        self._declared.pop(cls.name, None)
        self._classes[cls.name] = cls
        return cls

    def declare(self, module: str, names, install: str = "") -> None:
        """``module`` registers ``names`` when imported; import it on first use only.
        ``install``: how to install what the module needs (said when it fails to import)."""
        if install:
            self.install[module] = install
        for name in names:
            self.origin[name] = module
            if name not in self._classes:
                self._declared[name] = module

    def _load(self, module: str) -> None:
        names = [n for n, m in self._declared.items() if m == module]
        try:
            importlib.import_module(module)
        except ImportError as exc:
            UNAVAILABLE[module] = f"{type(exc).__name__}: {exc}"
        finally:
            for name in names:
                self._declared.pop(name, None)
        missing = [n for n in names if module not in UNAVAILABLE and n not in self._classes]
        if missing:
            raise RuntimeError(f"{module} was declared to register {missing} but did not")

    def load_all(self) -> None:
        """Import every declared module (iteration and ``len`` do this first)."""
        for module in sorted(set(self._declared.values())):
            self._load(module)

    def __getitem__(self, name):
        if name in self._declared:
            self._load(self._declared[name])
        return self._classes[name]

    def __contains__(self, name):
        if name in self._declared:          # only the module that would register it
            self._load(self._declared[name])
        return name in self._classes

    def __iter__(self):
        self.load_all()
        return iter(self._classes)

    def __len__(self):
        self.load_all()
        return len(self._classes)

    def unavailable(self) -> list[dict]:
        """Every declared name whose module did not import: ``name``, ``module``, ``reason`` and
        ``install`` (how to get it); imports every declared module first."""
        self.load_all()
        return [{"name": name, "module": module, "reason": UNAVAILABLE[module],
                 "install": self.install.get(module, "")}
                for name, module in sorted(self.origin.items(), key=lambda kv: kv[0].lower())
                if module in UNAVAILABLE and name not in self._classes]

    def names(self) -> list[str]:
        """Every registered or declared name, importing nothing."""
        return sorted({*self._classes, *self._declared})

    def select(self, *tags: str, exclude=()) -> list[str]:
        """The names, sorted, of the algorithms carrying every one of ``tags`` and none of
        ``exclude`` (:func:`filter_by_tags`); imports every declared module."""
        return sorted(cls.name for cls in filter_by_tags(self.values(), *tags, exclude=exclude))


REGISTRY = Registry()
#: declared modules whose library did not import: module → the reason
UNAVAILABLE: dict[str, str] = {}
#: the smallest rtol an adaptive method accepts: 100 ulps of 1
RTOL_MIN = 100 * 2.0 ** -52


def register(cls: type[Algorithm]) -> type[Algorithm]:
    """Class decorator: enter ``cls`` in :data:`REGISTRY` under ``cls.name``
    (:meth:`Registry.register`).

    Parameters
    ----------
    cls : type
        A subclass of :class:`Algorithm` with its ``name``, ``package`` and ``kind`` set.

    Returns
    -------
    type
        ``cls`` itself.

    Raises
    ------
    ValueError
        For a class without a name, a name registered already, or a ``package``, ``kind`` or
        ``code`` outside :data:`LIBRARIES`, :data:`KINDS`, :data:`CODES`.
    """
    return REGISTRY.register(cls)


def filter_by_tags(algorithms, *tags: str, exclude=()) -> list:
    """The algorithms (classes or instances) carrying every one of ``tags`` and none of
    ``exclude``, in their order: DiffEqDevTools' ``filter_by_tags``. A tag outside :data:`TAGS`
    is a ValueError naming it and the known ones."""
    tags, exclude = frozenset(tags), frozenset(exclude)
    unknown = sorted((tags | exclude) - TAGS)
    if unknown:
        raise ValueError(f"unknown tag(s) {', '.join(map(repr, unknown))}; known: "
                         f"{', '.join(sorted(TAGS))}")
    return [a for a in algorithms if tags <= a.tags and not exclude & a.tags]


def algorithm_class(name: str) -> type[Algorithm]:
    """Registry lookup, case-insensitive, with the known names in the error; imports only the
    module that registers ``name``.

    Parameters
    ----------
    name : str
        The registry name, any case.

    Returns
    -------
    type
        The :class:`Algorithm` subclass.

    Raises
    ------
    ValueError
        For an unknown name (listing the known ones), or one whose library did not import
        (with the reason and how to install it).
    """
    for key in REGISTRY.names():
        if isinstance(name, str) and key.lower() == name.lower():
            try:
                return REGISTRY[key]
            except KeyError:
                module = REGISTRY.origin.get(key, "")
                how = REGISTRY.install.get(module)
                raise ValueError(f"integrator {key!r} is not available here: {module} did not "
                                 f"import ({UNAVAILABLE.get(module, 'unknown reason')})"
                                 + (f"; to install it: {how}" if how else "")) from None
    raise ValueError(f"unknown integrator {name!r}; known: {', '.join(sorted(REGISTRY))}")

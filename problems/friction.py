"""Rate-and-state friction laws: the slip (Ruina) law, the aging (Dieterich) law and the Nagata
law.

All share the direct effect ``A ln(v/v0)`` and differ in the state variable θ and its evolution
(Urata et al. 2017, Eqs. 6–9; SPEC §1; Nagata et al. 2012):

* slip law, θ in newtons:    Ft = F0 + A ln(v/v0) + θ,             dθ/dt = −(v/Lc)(θ + B ln(v/v0))
* aging law, θ in seconds:   Ft = F0 + A ln(v/v0) + B ln(v0 θ/Lc),  dθ/dt = 1 − v θ/Lc
* Nagata law, θ in seconds:  the aging law's friction,  dθ/dt = 1 − v θ/Lc − (c/b) θ dμ/dt

with A = a·Fn and B = b·Fn. In the Nagata law the state also weakens with the shear stress rate
dμ/dt (μ = shear force/Fn; c ≈ 2 in Nagata et al.'s fits to granite). Here the shear stress is the
spring's, the force the apparatus measures: dμ/dt = k (vL − v)/Fn. It is the friction's in the
quasi-static limit and the law's own definition (Nagata et al. 2012, Eq. 7; rsfmodel's
``NagataState``). A law object holds (a, b, Lc, v0) and its own parameters only; the normal force
Fn and the reference friction F0 belong to the spring-slider and are passed in.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from problems._validate import (check_finite, check_non_negative, check_positive,
                                check_possible)
from problems.formulations import LAW_CODES, check_law_code

__all__ = ["FrictionLaw", "SlipLaw", "AgingLaw", "NagataLaw", "LAWS", "law_from_name", "compiled_law_code",
           "law_parameters"]


@dataclass(frozen=True)
class FrictionLaw:
    """Common parameters of a rate-and-state law: a, b (dimensionless), Lc (m), v0 (m/s).

    Parameters
    ----------
    a : float
        The direct effect (dimensionless, 0 < a < 1).
    b : float
        The evolution effect (dimensionless, −1 < b < 1; negative: an evolution that
        strengthens with slip, as some clays show — the Nagata law needs b > 0).
    lc : float
        The critical slip distance Lc (m, positive).
    v0 : float
        The reference slip rate (m/s, positive).

    Raises
    ------
    ValueError
        Naming a parameter out of its range (a value of 1 or more for a or b is refused as a
        percentage).
    """

    a: float
    b: float
    lc: float
    v0: float = 1e-5

    #: short name used by the CLI and in result tables
    name: ClassVar[str] = ""
    #: integer code read by the compiled kernels (0 = slip law, 1 = aging law, 2 = Nagata law)
    code: ClassVar[int] = -1
    #: the unit of the state θ
    theta_unit: ClassVar[str] = ""

    def __post_init__(self) -> None:
        # a ≥ 1 or b ≥ 1 is refused (a percentage), a unit slip warned (problems._validate)
        for name, check in (("a", check_positive), ("b", check_finite),
                            ("lc", check_positive), ("v0", check_positive)):
            check_possible(name, check(name, getattr(self, name)))

    # --- the law itself -------------------------------------------------------------------
    def steady_state(self, v: float, fn: float) -> float:
        """State θss at steady sliding with slip rate ``v``."""
        raise NotImplementedError

    def state_rate(self, v, theta, fn: float, stress_rate=0.0):
        """dθ/dt of the law; ``stress_rate`` is dFs/dt (N/s), read by laws that depend on it."""
        raise NotImplementedError

    @property
    def stress_coefficient(self) -> float:
        """c of a state that weakens with the shear stress rate (Nagata law), else 0."""
        return 0.0

    def state_term(self, theta, fn: float):
        """The state's contribution to friction, Ft − F0 − A ln(v/v0), in newtons."""
        raise NotImplementedError

    def state_term_derivative(self, theta, fn: float):
        """d(state term)/dθ (N per unit of θ)."""
        raise NotImplementedError

    def friction(self, v, theta, fn: float, f0: float):
        """Friction force Ft (N) at slip rate ``v`` and state ``theta``."""
        return f0 + self.a * fn * np.log(v / self.v0) + self.state_term(theta, fn)

    def slip_rate(self, ft, theta, fn: float, f0: float):
        """The slip rate tied to friction ``ft`` and state ``theta`` (the law's constraint)."""
        return self.v0 * np.exp((ft - f0 - self.state_term(theta, fn)) / (self.a * fn))

    def steady_friction(self, v, fn: float, f0: float):
        """Ft,ss = F0 + (A − B) ln(v/v0), the same for both laws."""
        return f0 + (self.a - self.b) * fn * np.log(v / self.v0)

    # --- the nondimensional state Ψ of SPEC §2 --------------------------------------------
    def psi(self, theta, fn: float):
        """Nondimensional state Ψ from θ (slip law Ψ = θ/B, aging law Ψ = v0 θ/Lc)."""
        raise NotImplementedError

    def theta(self, psi, fn: float):
        """θ from the nondimensional state Ψ (inverse of :meth:`psi`)."""
        raise NotImplementedError


@dataclass(frozen=True)
class SlipLaw(FrictionLaw):
    """Slip (Ruina) law; the state θ is a force in newtons (Eqs. 6–7).

    Parameters
    ----------
    a, b : float
        The direct and evolution effects (dimensionless).
    lc : float
        The critical slip distance Lc (m).
    v0 : float
        The reference slip rate (m/s).

    Raises
    ------
    ValueError
        As :class:`FrictionLaw`.
    """

    name: ClassVar[str] = "slip"
    code: ClassVar[int] = 0
    theta_unit: ClassVar[str] = "N"

    def steady_state(self, v: float, fn: float) -> float:
        return -self.b * fn * math.log(v / self.v0)

    def state_rate(self, v, theta, fn: float, stress_rate=0.0):
        return -(v / self.lc) * (theta + self.b * fn * np.log(v / self.v0))

    def state_term(self, theta, fn: float):
        return theta

    def state_term_derivative(self, theta, fn: float):
        return np.ones_like(np.asarray(theta, dtype=float))[()]

    def psi(self, theta, fn: float):
        if self.b == 0:
            # Ψ = θ/B is undefined; with B = 0 the state only decays, so only θ = 0 maps.
            if np.any(np.asarray(theta) != 0):
                raise ValueError("slip law with b = 0 needs theta = 0 (Ψ = θ/B is undefined)")
            return np.zeros_like(np.asarray(theta, dtype=float))[()]
        return theta / (self.b * fn)

    def theta(self, psi, fn: float):
        return psi * (self.b * fn)


@dataclass(frozen=True)
class AgingLaw(FrictionLaw):
    """Aging (Dieterich) law; the state θ is a time in seconds (Eqs. 8–9).

    Parameters
    ----------
    a, b : float
        The direct and evolution effects (dimensionless).
    lc : float
        The critical slip distance Lc (m).
    v0 : float
        The reference slip rate (m/s).

    Raises
    ------
    ValueError
        As :class:`FrictionLaw`.
    """

    name: ClassVar[str] = "aging"
    code: ClassVar[int] = 1
    theta_unit: ClassVar[str] = "s"

    def steady_state(self, v: float, fn: float) -> float:
        return self.lc / v

    def state_rate(self, v, theta, fn: float, stress_rate=0.0):
        return 1.0 - v * theta / self.lc

    def state_term(self, theta, fn: float):
        return self.b * fn * np.log(self.v0 * theta / self.lc)

    def state_term_derivative(self, theta, fn: float):
        return self.b * fn / theta

    def psi(self, theta, fn: float):
        return self.v0 * theta / self.lc

    def theta(self, psi, fn: float):
        return psi * self.lc / self.v0


@dataclass(frozen=True)
class NagataLaw(AgingLaw):
    """Nagata et al. (2012): the aging law's friction and state, whose evolution also weakens
    with the shear stress rate, dθ/dt = 1 − vθ/Lc − (c/b) θ dμ/dt (c dimensionless, ≥ 0; c = 0
    is the aging law). Steady sliding is the aging law's (θ = Lc/v); the quasi-static critical
    stiffness is Fn (b − a)/(Lc (1 + c)) (:mod:`problems.stability`).

    Parameters
    ----------
    a, b : float
        The direct and evolution effects (dimensionless; b > 0).
    lc : float
        The critical slip distance Lc (m).
    v0 : float
        The reference slip rate (m/s).
    c : float
        The stress-rate coefficient (dimensionless, ≥ 0; default 2).

    Raises
    ------
    ValueError
        As :class:`FrictionLaw`, for a negative c, or for b = 0.
    """

    c: float = 2.0

    name: ClassVar[str] = "nagata"
    code: ClassVar[int] = 2

    def __post_init__(self) -> None:
        super().__post_init__()
        check_non_negative("c", self.c)
        if self.b <= 0:
            raise ValueError("the Nagata law needs b > 0 (its stress term is (c/b) θ dμ/dt), "
                             f"got b = {self.b:g}")

    def state_rate(self, v, theta, fn: float, stress_rate=0.0):
        return 1.0 - v * theta / self.lc - (self.c / self.b) * theta * stress_rate / fn

    @property
    def stress_coefficient(self) -> float:
        return self.c


#: each law by the short name :func:`law_from_name` takes
LAWS: dict[str, type[FrictionLaw]] = {"slip": SlipLaw, "aging": AgingLaw, "nagata": NagataLaw}


def law_from_name(name: str, **params) -> FrictionLaw:
    """Build a law by its short name (``"slip"``, ``"aging"`` or ``"nagata"``).

    Parameters
    ----------
    name : str
        The law's short name, any case (:data:`LAWS`).
    **params : float
        The law's parameters by name (``a``, ``b``, ``lc`` in m, ``v0`` in m/s; ``c`` for
        the Nagata law).

    Returns
    -------
    FrictionLaw
        An instance of the named law's class.

    Raises
    ------
    ValueError
        For an unknown name, a parameter the law does not have, or a value it refuses.
    """
    own = law_parameters(name)
    cls = LAWS[name.lower()]
    known = {f.name for f in dataclasses.fields(FrictionLaw)} | set(own)
    unknown = sorted(set(params) - known)
    if unknown:              # a TypeError from the constructor would be a traceback
        raise ValueError(f"{unknown[0]!r} is not a parameter of the {cls.name} law; its "
                         f"parameters are {', '.join(sorted(known))}")
    return cls(**params)


def law_parameters(name: str) -> tuple[str, ...]:
    """The parameters of the law called ``name`` beyond a, b, lc and v0 (the Nagata law's
    ``("c",)``); ValueError for a name not in :data:`LAWS`.

    Parameters
    ----------
    name : str
        A law's short name (a key of :data:`LAWS`, any case).

    Returns
    -------
    tuple of str
        The names of its own fields, in declaration order.

    Raises
    ------
    ValueError
        If no law has that name.
    """
    try:
        cls = LAWS[name.lower()]
    except (KeyError, AttributeError):
        raise ValueError(f"law must be one of {sorted(LAWS)}, got {name!r}") from None
    common = {f.name for f in dataclasses.fields(FrictionLaw)}
    return tuple(f.name for f in dataclasses.fields(cls) if f.name not in common)


def compiled_law_code(law: FrictionLaw) -> int:
    """The code under which the compiled forms (:mod:`problems.formulations`) know ``law``'s
    class; ValueError for any other class, a subclass included (its formulas may differ)."""
    code = getattr(type(law), "code", None)
    if LAWS.get(LAW_CODES.get(code, "")) is not type(law):
        raise ValueError(f"friction law {type(law).__name__} (code {code!r}) has no compiled "
                         f"form: the known laws are {sorted(LAWS)} (docs/adding-a-law.md says "
                         "how to add one)")
    return check_law_code(code)

"""Problems from Urata et al. (2017): the Appendix 1.4 speed-up example and windows W1–W4.

Parameters (SPEC §5): m = 1.1e3 kg, a = 0.008, v0 = 1e−5 m/s, Fn = 1.33 MPa × 1.5 m × 0.5 m.
Stiffness and the two-speed loading are Tables 2–3; the slip-law best fits are Sect. 4.1.

The aging-law best fits are published only as a figure. They are pinned down by two published
numbers per window: the normalized stiffness κ = k Lc/(Fn (b − a)) of Table 3 and the nucleation
length Lb = G Lc/((1 − ν) b σn) of the Discussion (0.31, 0.48, 2.8, 0.36 m; G = 39.3 GPa,
ν = 0.31). Solving the two for (b, Lc) gives :func:`aging_best_fit`.

The paper does not state its initial conditions (the limit cycle does not depend on them). Every
run starts sliding at the slow loading speed, with the state of steady sliding at a speed
``INITIAL_PERTURBATION`` times slower (a slightly healed fault) and the spring force equal to
friction. Starting in force balance puts the start on the slow manifold: a jump in slip rate
instead would open with a fast inertial layer (time scale m v/A) that fixed-step schemes cannot
resolve and that shifts the phase of the first events.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from problems._validate import check_positive, warn_implausible
from problems.friction import law_from_name
from problems.loading import ConstantLoading, TwoSpeedLoading
from problems.slider import BalancedStart, SpringSlider

__all__ = ["MASS", "A", "V0", "NORMAL_STRESS", "NORMAL_FORCE", "WINDOWS", "Window",
           "paper_example", "window", "aging_best_fit", "preset", "PRESET_NAMES",
           "SHEAR_MODULUS", "POISSON_RATIO", "LAB", "velocity_step_test",
           "slide_hold_slide_test", "fault_radiation_damping", "FAULT_AREA"]

MASS = 1.1e3                       # kg (Table 4)
A = 0.008                          # direct effect (Table 4)
V0 = 1e-5                          # m/s (Table 4)
NORMAL_STRESS = 1.33e6             # Pa
NORMAL_FORCE = NORMAL_STRESS * 1.5 * 0.5   # N, on the 1.5 m × 0.5 m fault (FAULT_AREA)
SHEAR_MODULUS = 39.3e9             # Pa, Indian metagabbro (Discussion)
POISSON_RATIO = 0.31
MU0 = 0.6                          # F0/Fn; only shifts the friction level
INITIAL_PERTURBATION = 1.1         # initial state: steady state of v_slow / 1.1
WINDOW_T_END = 40.0                # s, default simulated time of a window (~10–90 cycles)


@dataclass(frozen=True)
class Window:
    """One time window of the experiments (Tables 2–3, Sect. 4, SPEC §5)."""

    name: str
    experiment: str
    stiffness: float        # N/m
    vls: float              # m/s
    vlf: float              # m/s
    df: float               # s
    slip_b: float           # slip-law best fit
    slip_lc: float          # m
    kappa_slip: float       # Table 3
    kappa_aging: float      # Table 3
    nucleation_length: float  # m, aging law (Discussion)
    observed_recurrence: float  # s, mean ΔT
    observed_drop: float        # mean Δμ
    observed_slip: float        # m per event
    observed_peak_velocity: float  # m/s, approximate
    nominal_vl: float           # m/s


#: the paper's windows W1..W4 (Table 3), by name
WINDOWS: dict[str, Window] = {w.name: w for w in (
    Window("W1", "LB01-127 short disp.", 1.42e8, 0.0753e-3, 0.9622e-3, 0.039, 0.0085, 0.09e-6,
           2.6e-2, 2.4e-2, 0.31, 1.5, 0.022, 0.14e-3, 0.02, 0.1e-3),
    Window("W2", "LB01-127 long disp.", 1.48e8, 0.0750e-3, 1.9717e-3, 0.042, 0.0094, 0.3e-6,
           3.2e-2, 1.6e-2, 0.48, 3.1, 0.046, 0.32e-3, 0.04, 0.1e-3),
    Window("W3", "LB01-134 slow vL", 1.48e8, 0.0740e-3, 2.3608e-3, 0.036, 0.0098, 0.9e-6,
           7.4e-2, 7.4e-2, 2.8, 3.6, 0.052, 0.35e-3, 0.04, 0.1e-3),
    Window("W4", "LB01-142 fast vL", 1.48e8, 0.7356e-3, 3.3027e-3, 0.046, 0.0103, 0.1e-6,
           6.5e-3, 7.7e-3, 0.36, 0.44, 0.060, 0.39e-3, 0.05, 1.0e-3),
)}


def aging_best_fit(w: Window) -> tuple[float, float]:
    """(b, Lc) of the aging-law best fit, solved from Table 3's κ and the nucleation length Lb.

    Lc/b = Lb (1 − ν) σn / G and Lc/(b − a) = κ Fn / k give b = r2 a/(r2 − r1), Lc = r1 b.

    Parameters
    ----------
    w : Window
        One of :data:`WINDOWS`.

    Returns
    -------
    tuple of float
        b (dimensionless) and Lc (m).
    """
    r1 = w.nucleation_length * (1.0 - POISSON_RATIO) * NORMAL_STRESS / SHEAR_MODULUS
    r2 = w.kappa_aging * NORMAL_FORCE / w.stiffness
    b = r2 * A / (r2 - r1)
    return b, r1 * b


def _slider(law, loading, stiffness: float, t_end: float, name: str) -> SpringSlider:
    return SpringSlider(mass=MASS, stiffness=stiffness, normal_force=NORMAL_FORCE, law=law,
                        loading=loading, initial=BalancedStart(INITIAL_PERTURBATION),
                        t_end=t_end, mu0=MU0, name=name)


def paper_example(law: str = "slip", b: float = 0.0092, lc: float = 0.5e-6,
                  t_end: float = 20.0, vl: float = 0.1e-3,
                  stiffness: float | None = None) -> SpringSlider:
    """The speed-up example of Appendix 1.4: constant vL = 0.1 mm/s, b = 0.0092, Lc = 0.5 µm, 20 s.

    Parameters
    ----------
    law : str
        The friction law's short name: ``"slip"``, ``"aging"`` or ``"nagata"``.
    b : float
        The evolution effect (dimensionless).
    lc : float
        The characteristic slip distance Lc (m).
    t_end : float
        The simulated time (s).
    vl : float
        The constant load-point velocity (m/s).
    stiffness : float, optional
        k (N/m). The paper does not state it for this example; the default is W2's 1.48e8 N/m
        (the stiffness of the LB01-127 experiment it was drawn from, and that of W2–W4).

    Returns
    -------
    SpringSlider
        Named ``paper-example/<law>``.

    Raises
    ------
    ValueError
        For an unknown law or a parameter the problem refuses.
    """
    k = WINDOWS["W2"].stiffness if stiffness is None else stiffness
    friction = law_from_name(law, a=A, b=b, lc=lc, v0=V0)
    return _slider(friction, ConstantLoading(vl), k, t_end, f"paper-example/{law}")


def window(name: str, law: str = "slip", b: float | None = None, lc: float | None = None,
           t_end: float = WINDOW_T_END) -> SpringSlider:
    """Window ``W1``..``W4`` with its stiffness, two-speed loading and the law's best fit.

    Parameters
    ----------
    name : str
        ``W1``..``W4`` (any case).
    law : str
        The friction law's short name: ``"slip"``, ``"aging"`` or ``"nagata"``.
    b : float, optional
        The evolution effect (dimensionless), overriding the law's best fit.
    lc : float, optional
        The characteristic slip distance Lc (m), overriding the law's best fit.
    t_end : float
        The simulated time (s; default 40, ~10–90 cycles).

    Returns
    -------
    SpringSlider
        Named ``<window>/<law>``.

    Raises
    ------
    ValueError
        For an unknown window or law, or a parameter the problem refuses.
    """
    try:
        w = WINDOWS[name.upper()]
    except (KeyError, AttributeError):
        raise ValueError(f"window must be one of {sorted(WINDOWS)}, got {name!r}") from None
    law_from_name(law, a=A, b=0.01, lc=1e-6)          # the law's name, checked first
    b_fit, lc_fit = (w.slip_b, w.slip_lc) if law.lower() == "slip" else aging_best_fit(w)
    friction = law_from_name(law, a=A, b=b_fit if b is None else b, lc=lc_fit if lc is None else lc,
                             v0=V0)
    return _slider(friction, TwoSpeedLoading(w.vls, w.vlf, w.df), w.stiffness, t_end,
                   f"{w.name}/{law.lower()}")


#: the names :func:`preset` takes (the CLI's ``--preset``)
PRESET_NAMES = ("paper-example", "W1", "W2", "W3", "W4")


def preset(name: str, law: str = "slip", b: float | None = None, lc: float | None = None,
           t_end: float | None = None) -> SpringSlider:
    """A preset by its CLI name: :func:`paper_example` or :func:`window`.

    Parameters
    ----------
    name : str
        ``paper-example`` or ``W1``..``W4`` (:data:`PRESET_NAMES`).
    law : str
        The friction law's short name: ``"slip"``, ``"aging"`` or ``"nagata"``.
    b, lc, t_end : float, optional
        The evolution effect (dimensionless), Lc (m) and the simulated time (s); ``None``
        keeps the preset's own.

    Returns
    -------
    SpringSlider

    Raises
    ------
    ValueError
        For an unknown preset or law, or a parameter the problem refuses.
    """
    kw = {k: v for k, v in dict(b=b, lc=lc, t_end=t_end).items() if v is not None}
    if isinstance(name, str) and name.lower() == "paper-example":
        return paper_example(law=law, **kw)
    return window(name, law=law, **kw)


# --- laboratory tests: a velocity step and a slide-hold-slide sequence ----------------------------
#: Marone's rate-and-state code as distributed with rsfmodel (Leeman et al., github.com/jrleeman/
#: rsfmodel, cjm_model_comparison/): a = 0.005, b = 0.01, Dc = 10 µm, k = 0.001 per µm (friction
#: per displacement), V0 = 1 µm/s, μ0 = 0.6, quasi-static. In SI units with a normal force of
#: 10 kN (any Fn gives the same friction coefficient): k = 1e-3 µm⁻¹ · Fn = 1e7 N/m.
LAB = dict(a=0.005, b=0.01, lc=10e-6, v0=1e-6, normal_force=1e4, stiffness=1e7, mu0=0.6)


def _lab_slider(law: str, loading, t_end: float, name: str, mass: float,
                radiation_damping: float, c: float | None,
                stiffness: float | None) -> SpringSlider:
    params = {k: LAB[k] for k in ("a", "b", "lc", "v0")}
    if c is not None:
        params["c"] = c
    friction = law_from_name(law, **params)
    return SpringSlider(mass=mass, stiffness=LAB["stiffness"] if stiffness is None else stiffness,
                        normal_force=LAB["normal_force"], law=friction, loading=loading,
                        initial=BalancedStart(1.0), t_end=t_end, mu0=LAB["mu0"], name=name,
                        radiation_damping=radiation_damping)


def velocity_step_test(law: str = "aging", v1: float = 1e-6, v2: float = 1e-5,
                       t_step: float = 10.0, t_end: float = 40.0, mass: float = 0.0,
                       radiation_damping: float = 0.0, c: float | None = None,
                       stiffness: float | None = None) -> SpringSlider:
    """A velocity step on the laboratory apparatus of :data:`LAB`: steady sliding at ``v1`` (m/s)
    until ``t_step`` (s), then the load point at ``v2``; quasi-static by default (``mass`` 0),
    as in Marone's code and rsfmodel. ``c``: the Nagata law's stress coefficient.

    Parameters
    ----------
    law : str
        The friction law's short name: ``"slip"``, ``"aging"`` or ``"nagata"``.
    v1, v2 : float
        The load-point velocities before and after the step (m/s).
    t_step : float
        The time of the step (s).
    t_end : float
        The end of the run (s).
    mass : float
        The slider's mass (kg; 0 is quasi-static).
    radiation_damping : float
        ηr (N s/m).
    c : float, optional
        The Nagata law's stress coefficient (dimensionless); ``None`` keeps its default.
    stiffness : float, optional
        The spring's stiffness (N/m); ``None`` takes :data:`LAB`'s.

    Returns
    -------
    SpringSlider
        Started from :class:`BalancedStart` (1.0): steady sliding at ``v1``.

    Raises
    ------
    ValueError
        For an unknown law, or a value the loading or the problem refuses.
    """
    from problems.loading import velocity_step
    return _lab_slider(law, velocity_step(v1, v2, t_step), t_end,
                       f"velocity-step/{law}", mass, radiation_damping, c, stiffness)


def slide_hold_slide_test(law: str = "aging", holds=(1.0, 3.0, 10.0, 30.0, 100.0),
                          v: float = 1e-6, slide: float = 100.0, first_slide: float = 10.0,
                          mass: float = 0.0, radiation_damping: float = 0.0,
                          c: float | None = None,
                          stiffness: float | None = None) -> SpringSlider:
    """A slide-hold-slide sequence on the apparatus of :data:`LAB`: steady sliding at ``v``
    (m/s) for ``first_slide`` s, then each hold of ``holds`` (s) followed by ``slide`` s of
    sliding at ``v``. The run ends at the end of the last slide.

    Parameters
    ----------
    law : str
        The friction law's short name: ``"slip"``, ``"aging"`` or ``"nagata"``.
    holds : sequence of float
        The hold times (s).
    v : float
        The sliding velocity (m/s).
    slide, first_slide : float
        The duration of each slide after a hold, and of the first slide (s).
    mass : float
        The slider's mass (kg; 0 is quasi-static).
    radiation_damping : float
        ηr (N s/m).
    c : float, optional
        The Nagata law's stress coefficient (dimensionless); ``None`` keeps its default.
    stiffness : float, optional
        The spring's stiffness (N/m); ``None`` takes :data:`LAB`'s.

    Returns
    -------
    SpringSlider
        Started from :class:`BalancedStart` (1.0): steady sliding at ``v``.

    Raises
    ------
    ValueError
        For an unknown law, or a value the loading or the problem refuses.
    """
    from problems.loading import slide_hold_slide
    loading = slide_hold_slide(v, holds, slide, first_slide)
    t_end = first_slide + sum(holds) + slide * len(holds)
    return _lab_slider(law, loading, t_end, f"slide-hold-slide/{law}", mass, radiation_damping,
                       c, stiffness)


#: the paper's fault, 1.5 m × 0.5 m
FAULT_AREA = 1.5 * 0.5
#: kg/m³: not in the paper (metagabbro is about 2900–3100), for the shear-wave speed of
#: :func:`fault_radiation_damping` only
ASSUMED_DENSITY = 3000.0


def fault_radiation_damping(density: float = ASSUMED_DENSITY) -> float:
    """ηr = G S/(2 cs) (N s/m) of the paper's fault: the radiation damping of a fault of area S
    in an elastic medium of shear modulus G (Discussion: 39.3 GPa) and shear-wave speed
    cs = sqrt(G/ρ), the quasi-dynamic approximation of QDYN and Rice (1993). ≈ 4.1e6 N s/m.
    ``density`` in kg/m³ (a value in g/cm³ warns)."""
    warn_implausible("density", check_positive("density", density))
    return SHEAR_MODULUS * FAULT_AREA / (2.0 * math.sqrt(SHEAR_MODULUS / density))

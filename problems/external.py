"""Spring-sliders that someone else wrote down: problems nobody here chose, to check the
project's methods and advice beyond the paper's: Im et al.'s numerical comparison, and NIED's
4-m apparatus as its catalogue of stick–slips gives it (:func:`nied_4m`).

:func:`im_spring_slider` is the slider of Im, Elsworth, Marone & Leeman's solver comparison
(public repository ``limkjae/SpringSlider-RSF``, MIT licence; the scripts
``SolverComparison3_IMvsMatlabODE_SpringSlider.m`` and ``SolverComparison2_IMvsRK4_…``). Their
equations are the project's, per square metre of fault:

    m dv/dt = k (vL t + x0 − u) − σn (μ0 + a ln(v/V0) + b ln(V0 θ/Dc)),   dθ/dt = 1 − v θ/Dc

with m = 1000 kg/m², k = 1e9 Pa/m, σn = 1 MPa, μ0 = 0.6 at V0 = 1e−9 m/s, Dc = 1 µm,
vL = 1e−4 m/s, from v = V_init with θ = Dc/V_init (steady state at V_init, not at vL) and the
spring's force equal to friction (x0 = μ_I σn/k, so no initial acceleration), for 2 s. Here the
square metre is explicit in SI: mass 1000 kg, stiffness 1e9 N/m, normal force 1e6 N (the
per-area quantities times 1 m²; the motion does not depend on the area). Their two cases:

* ``"stick-slip"`` (their comparison with MATLAB's ode23s): a = 0.005, b = 0.007,
  V_init = 1e−6 m/s. k_c = σn (b − a)/Dc = 2e9 Pa/m > k: four stick–slip events in 2 s, the
  first larger, peak slip rates ~2–3 cm/s;
* ``"ringing"`` (their comparison with RK4): a = 0.005, b = 0.004, V_init = 1e−5 m/s:
  velocity-strengthening; one overshoot to ~2.5 vL, then oscillations that die out.

They solve it with their own implicit scheme at a fixed 1e−4 s (ωΔt = 0.1), classical RK4 at
1e−6 s and MATLAB's ode23s at its default tolerances (RelTol 1e−3, AbsTol 1e−6, MaxStep 1e−4);
they published no timings and compare V(t) by eye only.
"""

from __future__ import annotations

import math

from problems.friction import law_from_name
from problems.loading import ConstantLoading
from problems.slider import BalancedStart, InitialState, SpringSlider

__all__ = ["im_spring_slider", "IM_CASES", "nied_4m", "EXTERNAL_NAMES", "external"]

#: one square metre of fault: the per-area quantities in SI forces and masses
IM_AREA = 1.0
#: (a, b, V_init in m/s) of each of Im et al.'s cases
IM_CASES = {"stick-slip": (0.005, 0.007, 1e-6), "ringing": (0.005, 0.004, 1e-5)}
IM_MASS = 1000.0 * IM_AREA          # kg (1000 kg per m²)
IM_STIFFNESS = 1e9 * IM_AREA        # N/m (1e9 Pa/m per m²)
IM_NORMAL_FORCE = 1e6 * IM_AREA     # N (σn = 1 MPa)
IM_DC = 1e-6                        # m
IM_V0 = 1e-9                        # m/s, where μ = μ0 in steady sliding
IM_MU0 = 0.6
IM_VL = 1e-4                        # m/s
IM_T_END = 2.0                      # s


def im_spring_slider(case: str = "stick-slip", t_end: float = IM_T_END) -> SpringSlider:
    """Im et al.'s slider (module docstring) for ``case`` (:data:`IM_CASES`), ``t_end`` s.

    Named ``im/<case>``. ValueError for an unknown case."""
    if case not in IM_CASES:
        raise ValueError(f"case must be one of {', '.join(IM_CASES)}, got {case!r}")
    a, b, v_init = IM_CASES[case]
    law = law_from_name("aging", a=a, b=b, lc=IM_DC, v0=IM_V0)
    theta = IM_DC / v_init                          # steady state at V_init (s)
    mu = IM_MU0 + a * math.log(v_init / IM_V0) + b * math.log(IM_V0 * theta / IM_DC)
    return SpringSlider(mass=IM_MASS, stiffness=IM_STIFFNESS, normal_force=IM_NORMAL_FORCE,
                        law=law, loading=ConstantLoading(IM_VL),
                        initial=InitialState(v=v_init, theta=theta, fs=mu * IM_NORMAL_FORCE),
                        t_end=t_end, mu0=IM_MU0, name=f"im/{case}")


# NIED's 4-m biaxial apparatus, experiment fb03-087 (the catalogue of 56 stick–slips in
# tests/data/nied-4m-stick-slip, whose README says what its source states). Stated there: the
# fault, 4 m × 0.1 m, and a normal stress of about 2 MPa. Estimated from the catalogue by
# `rsfbench study nied-catalogue` (results/nied_catalogue_constants.csv): the stiffness, k/Fn
# the median of the events' drop/slip, and the load-point speed, the median interval's loading
# rate over k/Fn. Assumed there: the moving mass (a metagabbro block 0.1–1 m high, the geometric
# mean) and a (the paper's, Table 4). b and Lc: that study's least-squares fit of the catalogue's
# mean ΔT and Δμ with these constants (results/nied_catalogue.csv, the row "vl from the median
# interval's rate": its Lc is inside the box, where the base row's sits at the box's floor).
NIED_MASS = 376.9434970920708       # kg, assumed
NIED_STIFFNESS = 240477845.6543534  # N/m, estimated (± 1.2e6)
NIED_NORMAL_FORCE = 2e6 * 0.4       # N: 2 MPa on 0.4 m²
NIED_MU0 = 0.328                    # the catalogue's median friction before the events, at v0
NIED_V0 = 1e-5                      # m/s
NIED_VL = 9.57887639128662e-06      # m/s, estimated
NIED_A = 0.008                      # assumed
NIED_B = 0.008147193094730458       # fitted
NIED_LC = 2.840817365829046e-07     # m, fitted
NIED_T_END = 60.0                   # s: about 15 recurrence intervals (3.9 s), ~10 settling


def nied_4m(t_end: float = NIED_T_END) -> SpringSlider:
    """NIED's 4-m apparatus as the catalogue of experiment fb03-087 gives it (the comment
    above): slip law, the presets' balanced start at the load-point speed, ``t_end`` s. Named
    ``nied/fb03-087``. A stiff problem: Lc/vL ≈ 30 ms between events, Lc/v ≈ µs in them."""
    law = law_from_name("slip", a=NIED_A, b=NIED_B, lc=NIED_LC, v0=NIED_V0)
    return SpringSlider(mass=NIED_MASS, stiffness=NIED_STIFFNESS,
                        normal_force=NIED_NORMAL_FORCE, law=law,
                        loading=ConstantLoading(NIED_VL), initial=BalancedStart(),
                        t_end=t_end, mu0=NIED_MU0, name="nied/fb03-087")


#: the external problems by name
EXTERNAL_NAMES = tuple(f"im/{case}" for case in IM_CASES) + ("nied/fb03-087",)


def external(name: str) -> SpringSlider:
    """The external problem ``name`` (:data:`EXTERNAL_NAMES`); ValueError for another."""
    if name not in EXTERNAL_NAMES:
        raise ValueError(f"no external problem {name!r}; there are {', '.join(EXTERNAL_NAMES)}")
    return nied_4m() if name.startswith("nied/") else im_spring_slider(name.split("/", 1)[1])

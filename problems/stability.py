"""Linear stability of steady sliding for the spring-slider with mass (SPEC §7).

Both laws linearise to the same system about steady sliding at V (Rice & Ruina 1983; Gu et al.
1984). With λ = V/Lc, the characteristic polynomial of small perturbations is

    m V s³ + (m V λ + A) s² + (k V − (B − A) λ) s + k V λ = 0,

steady sliding is stable for k > kcr = Fn (b − a)/Lc · [1 + m V²/(A Lc)], and at k = kcr the
oscillation has angular frequency ω = (V/Lc) sqrt((b − a)/a), independent of the mass.
"""

from __future__ import annotations

import math

import numpy as np

from problems.slider import SpringSlider

__all__ = ["critical_stiffness", "neutral_frequency", "characteristic_roots", "growth_rate"]


def _velocity(problem: SpringSlider, v: float | None) -> float:
    return problem.loading.v_slow if v is None else v


def critical_stiffness(problem: SpringSlider, v: float | None = None) -> float:
    """kcr (N/m) at steady sliding speed ``v`` (default: the slow loading speed)."""
    law, fn, v = problem.law, problem.normal_force, _velocity(problem, v)
    return fn * (law.b - law.a) / law.lc * (1.0 + problem.mass * v * v / (law.a * fn * law.lc))


def neutral_frequency(problem: SpringSlider, v: float | None = None) -> float:
    """Angular frequency ω (rad/s) of the neutrally stable oscillation at k = kcr."""
    law, v = problem.law, _velocity(problem, v)
    if law.b <= law.a:
        raise ValueError(f"no neutral oscillation for velocity-strengthening friction (b={law.b} <= a={law.a})")
    return v / law.lc * math.sqrt((law.b - law.a) / law.a)


def characteristic_roots(problem: SpringSlider, v: float | None = None) -> np.ndarray:
    """Roots s (1/s) of the characteristic polynomial; Re s > 0 means unstable steady sliding."""
    law, fn, v = problem.law, problem.normal_force, _velocity(problem, v)
    m, k = problem.mass, problem.stiffness
    A, B, lam = law.a * fn, law.b * fn, v / law.lc
    return np.roots([m * v, m * v * lam + A, k * v - (B - A) * lam, k * v * lam])


def growth_rate(problem: SpringSlider, v: float | None = None) -> float:
    """The largest real part of the characteristic roots (1/s): steady sliding is linearly
    stable when it is negative."""
    return float(np.max(characteristic_roots(problem, v).real))

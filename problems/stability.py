"""Linear stability of steady sliding for the spring-slider (SPEC §7), with mass or without,
with radiation damping ηr, for the slip, aging and Nagata laws.

All three laws linearise alike about steady sliding at V (Rice & Ruina 1983; Gu et al. 1984);
the Nagata law's stress term adds c k V to one coefficient. With λ = V/Lc, A = a Fn, B = b Fn,
the characteristic polynomial of small perturbations is

    m V s³ + (m V λ + A + ηr V) s² + (k V (1 + c) − (B − A) λ + ηr V λ) s + k V λ = 0

(the derivation is in docs/problem-family.md). With ηr = c = 0: steady sliding is stable for
k > kcr = Fn (b − a)/Lc · [1 + m V²/(A Lc)], and at k = kcr the oscillation has angular frequency
ω = (V/Lc) sqrt((b − a)/a), independent of the mass. Without mass (quasi-static) the polynomial
is quadratic and kcr = (Fn (b − a) − ηr V)/(Lc (1 + c)): σ(b − a)/Lc for the aging and slip laws.
"""

from __future__ import annotations

import math

import numpy as np

from problems.slider import SpringSlider

__all__ = ["critical_stiffness", "neutral_frequency", "characteristic_roots", "growth_rate",
           "growth_rates", "characteristic_polynomial"]


def _velocity(problem: SpringSlider, v: float | None) -> float:
    return problem.steady_velocity if v is None else v


def characteristic_polynomial(problem: SpringSlider, v: float | None = None,
                              stiffness: float | None = None) -> np.ndarray:
    """Coefficients (highest power first) of the characteristic polynomial at steady sliding
    speed ``v`` (default: the load speed at the end of the run, ``steady_velocity``), at
    ``stiffness`` (default: the problem's).

    Parameters
    ----------
    problem : SpringSlider
        The problem linearised.
    v : float, optional
        The steady sliding speed (m/s); ``None`` takes ``problem.steady_velocity``.
    stiffness : float, optional
        The spring's stiffness (N/m); ``None`` takes the problem's.

    Returns
    -------
    numpy.ndarray
        Four coefficients, of s³ down to s⁰ (the s³ one is 0 without mass).
    """
    law, fn, v = problem.law, problem.normal_force, _velocity(problem, v)
    m, eta = problem.mass, problem.radiation_damping
    k = problem.stiffness if stiffness is None else stiffness
    A, B, lam, c = law.a * fn, law.b * fn, v / law.lc, law.stress_coefficient
    return np.array([m * v, m * v * lam + A + eta * v,
                     k * v * (1.0 + c) - (B - A) * lam + eta * v * lam, k * v * lam])


def critical_stiffness(problem: SpringSlider, v: float | None = None) -> float:
    """kcr (N/m) at steady sliding speed ``v`` (default: ``steady_velocity``): the stiffness
    at which the Routh–Hurwitz condition a2 a1 > a3 a0 of the polynomial turns.

    Parameters
    ----------
    problem : SpringSlider
        The problem linearised.
    v : float, optional
        The steady sliding speed (m/s); ``None`` takes ``problem.steady_velocity``.

    Returns
    -------
    float
        kcr (N/m); zero or negative when steady sliding is stable at every stiffness.
    """
    law, fn, v = problem.law, problem.normal_force, _velocity(problem, v)
    m, eta = problem.mass, problem.radiation_damping
    A, B, lam, c = law.a * fn, law.b * fn, v / law.lc, law.stress_coefficient
    a2 = m * v * lam + A + eta * v
    # a2 (k V (1 + c) − (B − A) λ + ηr V λ) = m V k V λ, linear in k
    return a2 * ((B - A) * lam - eta * v * lam) / (v * (1.0 + c) * a2 - m * v * v * lam)


def neutral_frequency(problem: SpringSlider, v: float | None = None) -> float:
    """Angular frequency ω (rad/s) of the neutrally stable oscillation at k = kcr: there the
    polynomial is (s² + ω²)(a3 s + a2), so ω² = a0/a2.

    Parameters
    ----------
    problem : SpringSlider
        The problem linearised.
    v : float, optional
        The steady sliding speed (m/s); ``None`` takes ``problem.steady_velocity``.

    Returns
    -------
    float
        ω (rad/s).

    Raises
    ------
    ValueError
        When kcr ≤ 0: steady sliding is stable at every stiffness.
    """
    v = _velocity(problem, v)
    kcr = critical_stiffness(problem, v)
    if not kcr > 0:
        raise ValueError(f"no neutral oscillation: steady sliding is stable at every stiffness "
                         f"(kcr = {kcr:g} N/m; b = {problem.law.b} ≤ a = {problem.law.a}, or "
                         "damping stabilises it)")
    a2, _, a0 = characteristic_polynomial(problem, v, stiffness=kcr)[1:]
    return math.sqrt(a0 / a2)


def characteristic_roots(problem: SpringSlider, v: float | None = None) -> np.ndarray:
    """Roots s (1/s) of the characteristic polynomial; Re s > 0 means unstable steady sliding.

    Parameters
    ----------
    problem : SpringSlider
        The problem linearised.
    v : float, optional
        The steady sliding speed (m/s); ``None`` takes ``problem.steady_velocity``.

    Returns
    -------
    numpy.ndarray
        Three complex roots with mass, two without (1/s).
    """
    coeffs = characteristic_polynomial(problem, v)
    return np.roots(coeffs if coeffs[0] != 0 else coeffs[1:])


def growth_rate(problem: SpringSlider, v: float | None = None) -> float:
    """The largest real part of the characteristic roots (1/s): steady sliding is linearly
    stable when it is negative; 0.0 when it is below what double precision resolves.

    The polynomial is taken in x = s/λ and divided by A λ² (coefficients μ = m V λ/A, 1, K =
    k Lc/A, ηr V/A: O(1) for the paper's parameters), so that no coefficient overflows for a
    mass or stiffness near the float limits; without its cubic term when μ is below the
    round-off of the next one (the inertial root −(μ + 1)/μ is then beyond any other). The
    complex pair's real part comes from the sum of the roots (−p2/p3 = r + 2 Re), with the real
    root r polished by Newton: np.roots rounds Re away beside a huge Im (k → ∞).

    Parameters
    ----------
    problem : SpringSlider
        The problem linearised.
    v : float, optional
        The steady sliding speed (m/s); ``None`` takes ``problem.steady_velocity``, and the
        rate is then computed once per problem (a problem is frozen) and kept on it.

    Returns
    -------
    float
        max Re s (1/s); NaN when the roots are not finite.
    """
    if v is not None:
        return _growth_rate_at(problem, v)
    kept = problem.__dict__.get(_KEPT)
    if kept is None:
        kept = _growth_rate_at(problem, problem.steady_velocity)
        object.__setattr__(problem, _KEPT, kept)    # not a field: equality and replace skip it
    return kept


_KEPT = "_steady_growth_rate"


def growth_rates(problems) -> np.ndarray:
    """:func:`growth_rate` of each of ``problems`` at its steady sliding speed, kept on each as
    :func:`growth_rate` keeps it: the same numbers to the last bit, the cubics' roots found by
    one stacked eigenvalue call (what a batch of hundreds of problems needs; a problem whose
    coefficients are not finite and nonzero takes :func:`growth_rate`'s own path).

    Parameters
    ----------
    problems : sequence of SpringSlider
        The problems linearised.

    Returns
    -------
    numpy.ndarray
        max Re s of each (1/s), in their order.

    Raises
    ------
    ValueError
        As :func:`growth_rate`, for a problem whose polynomial overflows double precision.
    """
    out, stack, at = np.empty(len(problems)), [], []
    with np.errstate(all="ignore"):
        for i, problem in enumerate(problems):
            kept = problem.__dict__.get(_KEPT)
            if kept is None:
                cubic, _ = _cubic(problem, problem.steady_velocity)
                if cubic is None or not (all(map(math.isfinite, cubic)) and cubic[3] != 0.0):
                    kept = growth_rate(problem)
                else:
                    stack.append(cubic)
                    at.append(i)
            out[i] = np.nan if kept is None else kept
        if stack:
            c = np.asarray(stack)
            companion = np.zeros((len(c), 3, 3))
            companion[:, 1, 0] = companion[:, 2, 1] = 1.0      # as np.roots builds it
            companion[:, 0, :] = -c[:, 1:] / 1.0
            roots = np.linalg.eigvals(companion)
    for j, i in enumerate(at):
        out[i] = _from_cubic_roots(roots[j], *stack[j])
        object.__setattr__(problems[i], _KEPT, float(out[i]))
    return out


def _cubic(problem: SpringSlider, v: float):
    """``(cubic, quadratic)``, one of them None: the characteristic polynomial in x = s/λ as
    cubic = (λ, a2, a1, a0) of x³ + a2 x² + a1 x + a0, or, when μ is below the round-off of
    p2, as quadratic = (λ, p2, p1, K) of p2 x² + p1 x + K."""
    law = problem.law
    A, lam = law.a * problem.normal_force, v / law.lc
    mu = problem.mass * v * lam / A
    g = problem.radiation_damping * v / A
    K = problem.stiffness * law.lc / A
    p2 = mu + 1.0 + g
    p1 = K * (1.0 + law.stress_coefficient) - (law.b / law.a - 1.0) + g
    if not mu > 1e-17 * p2:
        return None, (lam, p2, p1, K)
    return (lam, p2 / mu, p1 / mu, K / mu), None


def _growth_rate_at(problem: SpringSlider, v: float) -> float:
    """:func:`growth_rate` at the steady sliding speed ``v`` (m/s)."""
    with np.errstate(all="ignore"):
        cubic, quadratic = _cubic(problem, v)
        if not all(map(math.isfinite, (cubic or quadratic)[1:])):
            law = problem.law
            raise ValueError(
                f"the linear stability of steady sliding overflows double precision (mass = "
                f"{problem.mass:g} kg, stiffness = {problem.stiffness:g} N/m, Lc = {law.lc:g} m, "
                f"a * normal_force = {law.a * problem.normal_force:g} N): give the problem in "
                "other units")
        if cubic is None:
            lam, *coefficients = quadratic
            return lam * float(np.max(np.roots(coefficients).real))
        x = np.roots([1.0, *cubic[1:]])
    return _from_cubic_roots(x, *cubic)


def _from_cubic_roots(x, lam: float, a2: float, a1: float, a0: float) -> float:
    """λ max Re x over the roots ``x`` of x³ + a2 x² + a1 x + a0; the complex pair's real part
    from the sum of the roots, the real root polished by Newton."""
    if not np.all(np.isfinite(x)):
        return math.nan
    if not np.any(x.imag != 0.0):
        return lam * float(np.max(x.real))
    r = float(x[np.argmin(np.abs(x.imag))].real)
    for _ in range(3):
        d = (3.0 * r + 2.0 * a2) * r + a1
        if d == 0.0:
            break
        r -= (((r + a2) * r + a1) * r + a0) / d
    return lam * max(r, (-a2 - r) / 2.0)

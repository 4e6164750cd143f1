"""``rsfbench invert --nuisance NAME=SIGMA``: (b, Lc) with apparatus constants the record leaves
uncertain, each with a Gaussian prior about the problem's value
(:mod:`benchmarks.inversion.nuisance`).

    rsfbench invert --preset W2 --law slip --nuisance k=3% --nuisance vls=2% --out inv_W2
"""

from __future__ import annotations

import argparse
import json
import warnings

import numpy as np

from benchmarks.cli.args import say, sensitive_default, show_progress, stopped_by

#: effective samples under which the intervals are called rough (a warning, also in --json)
MIN_EFFECTIVE = 50

__all__ = ["nuisance_spec", "check_nuisance_options", "check_nuisance_observations",
           "nuisance_algorithm", "run_nuisance"]

#: what a prior's σ means, in --help and in nuisance.json
SPEC_HELP = ("NAME=SIGMA: free the constant NAME (stiffness or k, vl, vls, mass or m, "
             "normal_force or fn) with a Gaussian prior about the problem's value of σ SIGMA, "
             "in SI or as a percentage of the value (k=3%%); repeatable. The fit uses exact "
             "gradients (forward sensitivities: without --integrator, the fastest setting "
             "with them within --accuracy; --integrator Rodas5P or RadauIIA5 at rtol ≤ 1e-6), "
             "reports the Laplace covariance and "
             "its check, and samples the posterior (--nuisance-sampler) (default: no "
             "constant freed)")
SAMPLER_HELP = ("with --nuisance: nested (the constants drawn from their priors, (b, log10 Lc) "
                "fitted for each, the draws weighted by the Laplace evidence; --steps draws, "
                "default 200; it follows the thin sheet of a precise record) or metropolis "
                "(--steps random-walk steps on the Gauss–Newton metric, default 2000) "
                "(default: nested)")


def nuisance_spec(text: str):
    """``NAME=SIGMA`` or ``NAME=PERCENT%`` → (name, σ, relative)."""
    name, sep, sigma = text.partition("=")
    name, sigma = name.strip().lower(), sigma.strip()
    relative = sigma.endswith("%")
    try:
        value = float(sigma[:-1] if relative else sigma)
    except ValueError:
        value = float("nan")
    if not sep or not name or not (np.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected NAME=SIGMA or NAME=PERCENT% with a σ above "
                                         f"0 (k=3%, vls=1.5e-6), got {text!r}")
    return name, value / 100.0 if relative else value, relative


def check_nuisance_options(args, problem) -> None:
    """What --nuisance cannot go with, and its priors about ``problem``'s values, refused
    before any work."""
    from benchmarks.inversion.nuisance import priors_of
    priors_of(problem, args.nuisance)
    for flag, given in (("--method emcee", args.method == "emcee"),
                        ("--grid", args.grid is not None),
                        ("--walkers", args.walkers is not None),
                        ("--profile-points", args.profile_points != 21)):
        if given:
            raise ValueError(f"{flag} is not used with --nuisance: the fit is by exact "
                             "gradients, and the sampler takes --steps only")
    named = _named_class(args.integrator) if args.integrator else None
    if named is not None and not getattr(named, "sensitive", False):
        raise ValueError(f"--integrator {args.integrator}: --nuisance differentiates through "
                         "forward sensitivities; name Rodas5P or RadauIIA5, or drop "
                         "--integrator")


def _named_class(name: str):
    from integrators import algorithm_class
    try:
        return algorithm_class(name)
    except (KeyError, ValueError):
        return None             # an unknown name: refused where the integrator is made


def check_nuisance_observations(obs) -> None:
    """The curves are not differentiated: refused before any work."""
    if obs.curve_likelihood is not None:
        raise ValueError("--nuisance fits the means ΔT̄ and Δμ̄; the slip-weakening curves are "
                         "not differentiated: add --curve-noise none")


def nuisance_algorithm(args):
    """``(algorithm, why)`` as the nuisance fit solves: the named method (it has forward
    sensitivities) at its rtol and atol, each tightened to
    :data:`problems.directions.SENSITIVITY_RTOL` where looser (as the fit's
    :func:`benchmarks.inversion.misfit.sensitive_setting`); without --integrator,
    :func:`benchmarks.cli.args.sensitive_default` (not the plain recommendation, which is
    never used here: its warnings would be about another setting)."""
    from benchmarks.cli.args import check_no_tolerances, integrator_from_args
    from benchmarks.inversion.misfit import sensitive_setting
    from problems.directions import SENSITIVITY_RTOL
    if not args.integrator:
        check_no_tolerances(args)
        return sensitive_default(args.accuracy, "--nuisance")
    algorithm, why = integrator_from_args(args)
    used = sensitive_setting(algorithm)
    if used == algorithm:
        return algorithm, why
    return used, (f"{algorithm.name} at rtol {used.rtol:g}, atol {used.atol:g}, tightened from "
                  f"rtol {algorithm.rtol:g}, atol {algorithm.atol:g} (--nuisance: exact "
                  f"gradients need both ≤ {SENSITIVITY_RTOL:g})")


def run_nuisance(args, misfit, box, steps: int, out, record: dict) -> int:
    """The fit, its Laplace check and the sampler; files to ``out``; the summary said (or
    one JSON document). Exit status 1 when the fit did not converge (the sampler still runs
    from where it stopped on a limit cycle) or found none."""
    from benchmarks.inversion.invert import inversion_files
    from benchmarks.inversion.nuisance import priors_of, write_nuisance
    from benchmarks.records.files import remove_own
    priors = priors_of(misfit.problem, args.nuisance)
    if not args.json:
        say("… the fit of b, log10 Lc, " + ", ".join(priors) + " (exact gradients)")
    try:
        fitted, samples = _fit_and_sample(args, misfit, priors, box, steps)
    except KeyboardInterrupt:
        raise KeyboardInterrupt(f"invert --nuisance interrupted ({stopped_by()[0]}): nothing "
                                f"written to {out}") from None
    summary = {**write_nuisance(fitted, samples, out, record),   # where invert and sweep
               "integrator_choice": record["integrator_choice"], "out": str(out)}   # put them
    for path in inversion_files(out):        # an earlier run's, of the (b, Lc) posterior
        remove_own(path)
    if args.json:
        n = few_samples(summary.get("sampler") or {})
        if n:                                # on the standard error, beside the document
            warnings.warn(f"few effective samples ({n:.0f}, under {MIN_EFFECTIVE}): the "
                          "sampler's intervals are rough; raise --steps", stacklevel=1)
        say(_json(summary))
    else:
        _report(fitted, summary)
    return 0 if fitted.success else 1


def _fit_and_sample(args, misfit, priors: dict, box, steps: int):
    """``(fitted, samples or None)``: the fit, then the chosen sampler where it can start."""
    from benchmarks.inversion.nested_laplace import DRAWS, sample_nested
    from benchmarks.inversion.nuisance import fit_with_nuisance, sample_with_nuisance
    fitted = fit_with_nuisance(misfit, priors, *box)
    samples = None
    sampler = args.nuisance_sampler or "nested"
    draws = steps if args.steps is not None or sampler == "metropolis" else DRAWS
    bar = not args.json and show_progress(args)
    # the optimiser at its budget still ends on a cycle, a start for the chain
    usable = np.isfinite(fitted.chi2) and (sampler == "nested"
                                            or np.isfinite(fitted.covariance).all())
    if draws and not usable and not args.json:
        say(f"no {sampler} sample: the fit ended "
            + ("without a limit cycle" if not np.isfinite(fitted.chi2) else
               "with a singular JᵀJ (no metric to step with: try --nuisance-sampler nested)"))
    if usable and draws:
        if sampler == "nested":
            if not args.json:
                say(f"… {draws} draws of the constants, (b, log10 Lc) fitted for each")
            samples = sample_nested(misfit, fitted, draws=draws, seed=args.seed, progress=bar)
        else:
            if not args.json:
                say(f"… {draws} Metropolis steps on the Gauss–Newton metric")
            samples = sample_with_nuisance(misfit, fitted, steps=draws, seed=args.seed,
                                           progress=bar)
    return fitted, samples


def _json(summary: dict) -> str:
    from benchmarks.records.report import jsonable
    return json.dumps(jsonable(summary), indent=2)


def _report(fitted, summary: dict) -> None:
    if not np.isfinite(fitted.chi2):
        say(f"nuisance fit failed: {fitted.message}; written: "
            f"{', '.join(summary['files'].values())}")
        return
    if not fitted.success:
        say(f"the fit did not converge ({fitted.message}): where it stopped, on a cycle")
    for name, x, sd, lo, hi in zip(fitted.names, fitted.x, fitted.sd, *fitted.bounds):
        prior = fitted.priors.get(name)
        moved = "" if prior is None else (f" (prior {prior[0]:.5g} ± {prior[1]:.2g}: moved "
                                          f"{(x - prior[0]) / prior[1]:+.2f} σ)")
        wide = (" — wider than its search span: the data do not resolve it, read the sampler"
                if sd > hi - lo else "")
        if min(x - lo, hi - x) <= 1e-6 * (hi - lo):
            wide += " — at the edge of its search span: widen the box (or the prior)"
        say(f"{name} = {x:.5g} ± {sd:.2g} (Laplace){moved}{wide}")
    check = fitted.laplace_check
    say(f"χ² = {fitted.chi2:.3g}, {fitted.n_solves} solves; Laplace check "
        + ("(±1, ±2 sd along each principal axis): a step leaves the box or the cycles, so "
           "the Gaussian is not checked — read the sampler" if not np.isfinite(check) else
           f"(worst |Δχ²/k² − 1| at ±1, ±2 sd): {check:.2f}"
           + (" — not Gaussian: read the sampler" if check > 0.5 else "")))
    s = summary.get("sampler")
    if s:
        say((f"nested sampler ({s['draws']} draws, {s['effective_draws']:.0f} effective, "
             f"{s['inner_fits_not_converged']} of their fits of (b, log10 Lc) not converged)"
             if "draws" in s else
             f"sampler ({s['steps']} steps, the first {s['burn_in']} dropped, acceptance "
             f"{s['acceptance']:.2f}, τ {s['tau_steps']:.0f} steps: "
             f"{s['effective_steps']:.0f} effective)") + ": " + ", ".join(
                f"{n} 95 % {lo:.5g} to {hi:.5g}" for n, (lo, hi) in s["interval_95"].items()))
    if s and few_samples(s):
        say(f"few effective samples ({few_samples(s):.0f}, under {MIN_EFFECTIVE}): the "
            "intervals above are rough; raise --steps")
    say(f"written: {', '.join(summary['files'].values())}")


def few_samples(s: dict) -> float:
    """The sampler's effective sample size where it is under :data:`MIN_EFFECTIVE`, else 0
    (and 0 without a sampler)."""
    n = s.get("effective_draws", s.get("effective_steps"))
    return n if n is not None and n < MIN_EFFECTIVE else 0.0

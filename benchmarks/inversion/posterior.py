"""Posterior samples of (b, log10 Lc) with emcee (``rsfbench invert --method emcee``).

The model: the observed ΔT̄ and Δμ̄ are Gaussian about the limit cycle's metrics with the stated
σ, and the curves (when they are in the likelihood) as their noise model says, so
log L = −misfit/2 (:meth:`benchmarks.inversion.Misfit.log_likelihood`; −inf at a point without a
limit cycle). The prior is uniform on the box ``b_range`` × ``lc_range`` in (b, log10 Lc):
flat in b and in the logarithm of Lc, which spans decades. Both are stated in the result.

emcee's affine-invariant ensemble sampler runs with ``vectorize=True``: each step's walkers are
one ensemble batch (:func:`benchmarks.ensemble.ensemble`), one compiled call for the own methods.
Diagnostics reported: the mean acceptance fraction, the integrated autocorrelation time of each
parameter (emcee's estimate, with ``tol=0``, and whether the chain is at least 50 τ long, emcee's
rule of thumb for a reliable τ), and the effective number of samples, walkers × kept steps / τ.
A chain too short for a τ (a walker that never moved) has τ and the effective samples NaN and is
not reliable: it is not given a number it does not have.

A Ctrl-C during a step is held until the step ends and then raised as ``KeyboardInterrupt``
from :func:`sample`: emcee wraps the log-probability in a handler that prints a traceback for
any exception, an interruption included, so none may leave it (:class:`CtrlC`).
"""

from __future__ import annotations

import signal
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.inversion.misfit import Misfit
from benchmarks.records.interrupts import handled, note_sigterm

__all__ = ["sample", "Posterior", "check_sampler", "run_sampler", "CtrlC",
           "MAX_POSTERIOR_SOLVES"]

#: walkers × steps at most: each is a forward solve (hours at a few ms each on 2 cores), and
#: emcee keeps every sample in memory
MAX_POSTERIOR_SOLVES = 10_000_000


@dataclass
class Posterior:
    """Samples of (b, log10 Lc) after burn-in (flattened over walkers), their mean and standard
    deviation, and the chain's diagnostics.

    Parameters
    ----------
    samples : pandas.DataFrame
        Columns ``b`` (dimensionless), ``log10_lc`` (log10 of m) and ``log_likelihood``
        (−misfit/2 there), one row a kept sample.
    mean, std : dict of str to float
        The samples' mean and standard deviation, keyed ``"b"`` and ``"log10_lc"``.
    acceptance : float
        The mean acceptance fraction over the walkers (dimensionless).
    tau : dict of str to float
        Each parameter's integrated autocorrelation time (steps); NaN where it has none.
    tau_reliable : bool
        Whether the kept chain is at least 50 τ long.
    kept : int
        The chain's steps after burn-in (per walker).
    effective_samples : float
        Walkers × kept steps / the larger τ; NaN without a τ.
    n_solves : int
        Forward solves (the walkers' moves inside the prior box).
    wall_s : float
        The sampler's wall time (s).
    prior : str
        The prior in words: the box, uniform in b and log10 Lc.
    """

    samples: pd.DataFrame = field(repr=False)
    mean: dict
    std: dict
    acceptance: float
    tau: dict
    tau_reliable: bool
    kept: int
    effective_samples: float
    n_solves: int
    wall_s: float
    prior: str


def check_sampler(b_range, lc_range, walkers: int, steps: int, burn: int | None = None) -> int:
    """Refuse a bad prior box or chain shape (``ValueError`` naming it); return the burn-in
    (default: a quarter of the steps)."""
    (b_lo, b_hi), (lc_lo, lc_hi) = b_range, lc_range
    if not (0 <= b_lo < b_hi and 0 < lc_lo < lc_hi):
        raise ValueError(f"the prior box must have 0 ≤ b_lo < b_hi and 0 < lc_lo < lc_hi, got "
                         f"b_range = {b_range!r}, lc_range = {lc_range!r}")
    for name, n, least in (("walkers", walkers, 4), ("steps", steps, 2)):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < least:
            raise ValueError(f"walkers must be ≥ 4 and steps ≥ 2 (integers), got {name} = {n!r}")
    if walkers * steps > MAX_POSTERIOR_SOLVES:
        raise ValueError(f"walkers × steps = {walkers:,} × {steps:,} is over "
                         f"{MAX_POSTERIOR_SOLVES:,} forward solves (each one a sample emcee "
                         "keeps in memory): use fewer")
    burn = steps // 4 if burn is None else burn
    if isinstance(burn, bool) or not isinstance(burn, (int, np.integer)) or not 0 <= burn < steps:
        raise ValueError(f"burn must be in [0, steps), got {burn}")
    return burn


class CtrlC:
    """A Ctrl-C (or SIGTERM) while emcee samples, kept out of emcee's code. While
    :meth:`installed`, the signal only marks the run stopped, except inside :meth:`call` (the
    solves), where it interrupts at once and is caught there: an exception raised anywhere
    else in the log-probability, or in emcee between two calls, would reach emcee's handler,
    which prints its traceback (the test of it saw one when the Ctrl-C was caught around the
    solves alone). Truthy once stopped."""

    def __init__(self):
        self.stopped = False
        self._inside = False

    def __bool__(self) -> bool:
        return self.stopped

    def _handler(self, signum, frame):
        self.stopped = True
        if signum == signal.SIGTERM:
            note_sigterm()
        if self._inside:
            raise KeyboardInterrupt

    @contextmanager
    def installed(self):
        """SIGINT goes to this object for the block, and so does a SIGTERM that a Python
        handler takes (the command line's,
        :func:`~benchmarks.records.interrupts.stop_on_sigterm`; a SIGTERM left to kill the
        process still does). From the main thread (:func:`~benchmarks.records.interrupts.handled`);
        elsewhere Python's own handlers stay, and :meth:`call` still catches what they raise."""
        taken = [signal.SIGINT] + [signal.SIGTERM] * callable(signal.getsignal(signal.SIGTERM))
        with handled(taken, self._handler):
            yield self

    def call(self, fn, *args):
        """``fn(*args)``, or None once stopped (before or during it)."""
        if self.stopped:
            return None
        try:
            self._inside = True
            return fn(*args)
        except KeyboardInterrupt:
            self.stopped = True
            return None
        finally:
            self._inside = False


def run_sampler(sampler, p0, steps: int, progress: bool, stopped: CtrlC) -> None:
    """Run an emcee ``sampler`` from ``p0`` for ``steps`` steps with ``stopped`` installed (its
    log-probability solves through ``stopped.call``). A Ctrl-C is raised here, after the step
    it came in, as one ``KeyboardInterrupt`` naming that step."""
    done = 0
    with stopped.installed(), warnings.catch_warnings():
        # a walker at −inf (a point without a cycle) whose proposal is −inf too: emcee's
        # −inf − (−inf), a rejection, warned once a step (~800 lines in a probe's run)
        warnings.filterwarnings("ignore", "invalid value encountered in scalar subtract",
                                RuntimeWarning, "emcee")
        try:
            for done, _ in enumerate(sampler.sample(p0, iterations=steps, progress=progress),
                                     1):
                if stopped:
                    done -= 1                     # the step the Ctrl-C came in
                    break
        except KeyboardInterrupt:                 # Python's own handler, off the main thread
            stopped.stopped = True
    if stopped:
        raise KeyboardInterrupt(f"the posterior was interrupted at step {done + 1} of {steps}")


def sample(misfit: Misfit, b_range, lc_range, start, walkers: int = 32, steps: int = 2000,
           burn: int | None = None, seed: int = 0, progress: bool = False,
           cov=None) -> Posterior:
    """Sample the posterior (module docstring) with ``walkers`` walkers for ``steps`` steps,
    started from N(``start``, ``cov``) (a least-squares fit and its Gauss–Newton covariance:
    the ensemble's spread is the stretch move's scale), a draw outside the box drawn again and
    then clipped into it; without ``cov``, in a small ball (1e−4 relative in b, 1e−3 in log10
    Lc) around ``start``.

    Parameters
    ----------
    misfit : Misfit
        The log-likelihood's source (:meth:`~benchmarks.inversion.Misfit.evaluate`).
    b_range, lc_range : tuple of float
        The prior box: (low, high) of b (dimensionless) and of Lc (m).
    start : tuple of float
        (b, Lc in m) inside the box, e.g. a least-squares fit.
    walkers, steps : int
        At least 4 walkers and 2 steps; walkers × steps ≤ :data:`MAX_POSTERIOR_SOLVES`.
    burn : int, optional
        Steps dropped, in [0, ``steps``); default a quarter of them.
    seed : int
        Of the start ball and of emcee's generator.
    progress : bool
        Show emcee's progress bar.
    cov : array_like, optional
        The 2 × 2 covariance of (b, log10 Lc) the walkers start from (finite, positive
        definite); None: the small ball.

    Returns
    -------
    Posterior
        Its samples carry each one's ``log_likelihood`` too.

    Raises
    ------
    ValueError
        For a bad box, chain shape or burn-in, or ``start`` outside the box.
    """
    from benchmarks.records.optional import require
    require("emcee", "inversion", "a posterior sample")
    import emcee
    burn = check_sampler(b_range, lc_range, walkers, steps, burn)
    (b_lo, b_hi), (lc_lo, lc_hi) = b_range, lc_range
    lo, hi = np.array([b_lo, np.log10(lc_lo)]), np.array([b_hi, np.log10(lc_hi)])
    x0 = np.array([start[0], np.log10(start[1])])
    if not ((lo < x0) & (x0 < hi)).all():
        raise ValueError(f"start = {start!r} is outside the prior box")
    count = {"n": 0}
    stopped = CtrlC()

    def log_prob(x):                     # x: (walkers, 2); one ensemble batch a step
        inside = ((x > lo) & (x < hi)).all(axis=1)
        out = np.full(len(x), -np.inf)
        if inside.any():
            table = stopped.call(misfit.evaluate, x[inside, 0], 10.0 ** x[inside, 1])
            if table is None:            # a Ctrl-C: raised after the step (CtrlC)
                return out
            count["n"] += int(inside.sum())
            out[inside] = table.log_likelihood.to_numpy()
        return out

    rng = np.random.default_rng(seed)
    p0 = _start(rng, x0, cov, walkers, lo, hi)
    sampler = emcee.EnsembleSampler(walkers, 2, log_prob, vectorize=True)
    sampler.random_state = np.random.RandomState(int(rng.integers(2**31))).get_state()
    started = time.perf_counter()
    run_sampler(sampler, p0, steps, progress, stopped)
    wall = time.perf_counter() - started
    prior = (f"uniform in b on [{b_lo:g}, {b_hi:g}] and in log10 Lc on "
             f"[{np.log10(lc_lo):g}, {np.log10(lc_hi):g}] (Lc in m)")
    return _posterior(sampler, burn, steps - burn, count["n"], wall, prior)


def _posterior(sampler, burn: int, kept: int, n_solves: int, wall: float,
               prior: str) -> Posterior:
    """The :class:`Posterior` of an emcee ``sampler`` after ``burn`` steps dropped."""
    walkers = sampler.get_chain().shape[1]
    chain = sampler.get_chain(discard=burn, flat=True)
    log_l = sampler.get_log_prob(discard=burn, flat=True)
    with np.errstate(divide="ignore", invalid="ignore"):    # a walker that never moved
        tau = sampler.get_autocorr_time(discard=burn, tol=0)    # has no τ: NaN, said below
    samples = pd.DataFrame({"b": chain[:, 0], "log10_lc": chain[:, 1], "log_likelihood": log_l})
    xs = samples[["b", "log10_lc"]]
    return Posterior(
        samples=samples, mean=xs.mean().to_dict(), std=xs.std().to_dict(),
        acceptance=float(np.mean(sampler.acceptance_fraction)),
        tau={"b": float(tau[0]), "log10_lc": float(tau[1])},
        tau_reliable=bool(np.isfinite(tau).all() and kept >= 50 * np.max(tau)), kept=kept,
        effective_samples=(float(walkers * kept / np.max(tau)) if np.isfinite(tau).all()
                           else float("nan")), n_solves=n_solves, wall_s=wall, prior=prior)


def _start(rng, x0, cov, walkers: int, lo, hi) -> np.ndarray:
    """The walkers' start: N(x0, cov), a draw outside the box (lo, hi) drawn again up to ten
    times and then clipped into it; without a usable ``cov``, the small ball of :func:`sample`."""
    inner_lo, inner_hi = lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo)
    chol = None
    if cov is not None:
        try:
            chol = np.linalg.cholesky(np.asarray(cov, dtype=float))
        except np.linalg.LinAlgError:
            chol = None
    if chol is None or not np.isfinite(chol).all():
        p0 = x0 + rng.standard_normal((walkers, 2)) * np.array([1e-4 * x0[0], 1e-3])
        return np.clip(p0, lo + 1e-12, hi - 1e-12)
    p0 = x0 + rng.standard_normal((walkers, 2)) @ chol.T
    for _ in range(10):
        out = ~((p0 > inner_lo) & (p0 < inner_hi)).all(axis=1)
        if not out.any():
            break
        p0[out] = x0 + rng.standard_normal((int(out.sum()), 2)) @ chol.T
    return np.clip(p0, inner_lo, inner_hi)

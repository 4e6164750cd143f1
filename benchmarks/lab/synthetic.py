"""A laboratory recording made by the forward model: what ``rsfbench observe`` must read back.

:func:`synthetic_recording` solves a problem and writes what the apparatus's sensors would have
recorded: time; the load cell's force Fs; the slider's acceleration a = (Fs − Ft)/m (Eq. 4);
the slip u; the load point's position l (the table: vLs, and vLf for df after each event under
two-speed loading). The slip is exact, u = l − (Fs − Fs(0))/k (Eq. 5), not an integral of the
saved slip rate.

The sensor chain, in order: an anti-alias filter (a causal 4th-order Butterworth low-pass at
``anti_alias`` × the sampling rate, as a recorder's hardware filter is causal), white noise and a
slow drift. ``noise`` and ``drift`` are fractions of each channel's **per-event scale** — the
mean friction drop (in force) for Fs, the largest |a| for the acceleration, the mean slip per
event for the slip, the load point's travel over a mean recurrence interval for the table — so
that "1 % noise" means the same for every channel: σ = 0.01 × what one event changes. The drift
grows linearly from 0 at t = 0 to ``drift`` × that scale at the record's end (a record that
starts at ``t_skip`` starts with part of it).

``shake`` (m/s², rms) adds a lower specimen that vibrates (the table's own jitter), as its
accelerometer sees it, a2: a sum of sinusoids at ``SHAKE_HZ`` with random phases. The slip and
the spring force stay the model's (the upper specimen is carried along: a1 = ü + a2, the slip
accelerating at a1 − a2, and the displacement of the vibration, ∫∫a2 < a µm, is left out of the
spring), so the fault's friction is the model's less m·a2: Ft = Fs − m·a1 (Eq. 1). A reading
that put a1 − a2 into Eq. 3 would miss that m·a2.

Returns the table and the truth it was made from (:class:`Truth`): the model's own per-event
metrics of the recorded window (:func:`benchmarks.physics.metrics.event_metrics`) and the
apparatus (k, vLs, vLf, df, m, Fn).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import signal

from benchmarks.physics.metrics import event_metrics
from integrators import Rodas5P, solve

__all__ = ["synthetic_recording", "Truth", "load_point_position", "SHAKE_HZ"]

#: the frequencies (Hz) of the lower specimen's vibration (``shake``): inside the band the
#: analysis keeps of the force (400 Hz) and the accelerations (750 Hz)
SHAKE_HZ = (23.0, 61.0, 137.0)


@dataclass(frozen=True)
class Truth:
    """What a synthetic recording was made from: ``events`` (one row per event that starts in
    the recorded window: ``t_start`` and the four metrics) and the apparatus (SI units)."""

    events: pd.DataFrame = field(repr=False)
    stiffness: float
    mass: float
    normal_force: float
    vls: float
    vlf: float
    df: float


def load_point_position(loading, t: np.ndarray, event_ends) -> np.ndarray:
    """The load point's travel since t = 0 (m) at times ``t``: its history integrated exactly,
    plus the overshoot (``v_fast`` for ``fast_duration`` after each event end)."""
    hist = loading.history
    edges = np.concatenate(([0.0], np.asarray(hist.switch_times, dtype=float)))
    velocities = np.asarray(hist.velocities, dtype=float)
    x = np.zeros_like(t)
    for i, (start, v) in enumerate(zip(edges, velocities)):
        end = edges[i + 1] if i + 1 < len(edges) else np.inf
        x += v * np.clip(t - start, 0.0, end - start)
    if hist.two_speed:
        extra, span = hist.overshoot_velocity - velocities[-1], hist.overshoot_duration
        for te in event_ends:
            i0 = np.searchsorted(t, te)
            x[i0:] += extra * np.clip(t[i0:] - te, 0.0, span)
    return x


def synthetic_recording(problem, rate: float = 10_000.0, t_skip: float = 0.0,
                        noise: float = 0.0, drift: float = 0.0, anti_alias: float | None = 0.4,
                        seed: int = 0, shake: float = 0.0,
                        algorithm=None) -> tuple[pd.DataFrame, Truth]:
    """The recording of ``problem`` (with mass) from ``t_skip`` to ``t_end`` (module docstring).

    Parameters
    ----------
    problem : SpringSlider
    rate, t_skip, shake : float
        Samples per second (Hz); the start (s, in [0, t_end)); the lower specimen's vibration
        (m/s² rms, ≥ 0; then an ``acceleration_lower`` column).
    noise, drift : float
        White noise σ and the drift at the end, as fractions of each channel's per-event scale.
    anti_alias : float, optional
        The anti-alias filter's cutoff over the rate (dimensionless); ``None``: no filter.
    seed : int
        The random generator's seed.
    algorithm : Algorithm, optional
        The forward solver; ``None``: Rodas5P at rtol = atol = 1e−10.

    Returns
    -------
    table : pandas.DataFrame
        ``time`` (s), ``shear_force`` (N), ``acceleration`` (m/s²), ``slip`` and ``table`` (m).
    truth : Truth

    Raises
    ------
    ValueError
        Without mass, or ``t_skip`` or ``shake`` out of range; RuntimeError: a failed run."""
    if not problem.mass > 0:
        raise ValueError("a recording with accelerometers needs a slider with mass (mass > 0)")
    if not 0 <= t_skip < problem.t_end:
        raise ValueError(f"t_skip must be in [0, t_end = {problem.t_end:g}) s, got {t_skip!r}")
    if not (math.isfinite(shake) and shake >= 0):
        raise ValueError(f"shake must be a finite rms acceleration >= 0 in m/s², got {shake!r}")
    algorithm = algorithm or Rodas5P(rtol=1e-10, atol=1e-10)
    n = int(round(problem.t_end * rate))
    sol = solve(problem, algorithm, save_every=1.0 / rate, max_points=n + 2)
    if not sol.reached_end:
        raise RuntimeError(f"the forward run failed: {sol.retcode.value}: {sol.message}")
    t = sol.t
    table = load_point_position(problem.loading, t, sol.events.t_end.to_numpy())
    clean = {"shear_force": sol.fs, "acceleration": (sol.fs - sol.ft) / problem.mass,
             "slip": table - (sol.fs - sol.fs[0]) / problem.stiffness, "table": table}
    if shake > 0:                        # the module docstring
        phases = np.random.default_rng([seed, 1]).uniform(0.0, 2 * np.pi, len(SHAKE_HZ))
        a2 = sum(np.sin(2 * np.pi * f * t + p) for f, p in zip(SHAKE_HZ, phases))
        a2 *= shake / np.sqrt(np.mean(a2 ** 2))
        clean["acceleration"] = clean["acceleration"] + a2
        clean["acceleration_lower"] = a2
    metrics = event_metrics(sol.events, problem.normal_force)
    inside = metrics.t_start.to_numpy() >= t_skip
    complete = sol.events.t_end.to_numpy() < t[-1]
    truth_events = metrics[inside & complete].reset_index(drop=True)
    cycle = metrics[complete].iloc[1:]
    scale = {"shear_force": float(np.nanmean(cycle.friction_drop)) * problem.normal_force,
             "acceleration": float(np.max(np.abs(clean["acceleration"]))),
             "acceleration_lower": float(np.max(np.abs(clean["acceleration"]))),
             "slip": float(np.nanmean(cycle.slip_m)),
             "table": problem.loading.v_slow * float(np.nanmean(cycle.recurrence_s))}
    rng = np.random.default_rng(seed)
    sos = (signal.butter(4, anti_alias * rate, fs=rate, output="sos")
           if anti_alias else None)
    keep = t >= t_skip
    out = {"time": t[keep]}
    for name, x in clean.items():
        y = signal.sosfilt(sos, x - x[0]) + x[0] if sos is not None else x.copy()
        y = y + noise * scale[name] * rng.standard_normal(len(y))
        y = y + drift * scale[name] * (t - t[0]) / (t[-1] - t[0])
        out[name] = y[keep]
    loading = problem.loading
    return pd.DataFrame(out), Truth(truth_events, problem.stiffness, problem.mass,
                                    problem.normal_force, loading.v_slow, loading.v_fast,
                                    loading.fast_duration)

"""Start of steady-state locomotion, detected from the data (cycle-to-cycle consistency).

Komsuoglu et al. analyse "runs where the robot achieved steady-state behavior" (Section 2).
A run that enters the tracking volume while still settling into its gait (a start-up
transient: the body pitches and bounces differently from one clock cycle to the next, legs
make extra contacts) is cut where the motion starts repeating with the clock: for windows of
two clock periods ``T`` (stepping by ``T/2``), the RMS difference between the body pitch over
the first period and over the second is compared with the run's most repeatable window; the
steady part starts one period after the last window more than ``factor`` times that floor
(and more than ``min_diff_rad``, the measurement noise).

Core module: numpy only.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .errors import SlipDataError

__all__ = ['cycle_differences', 'steady_start_s']


def cycle_differences(t_s: ArrayLike, signal: ArrayLike, period_s: float, *,
                      step_frac: float = 0.5, n_grid: int = 60
                      ) -> tuple[np.ndarray, np.ndarray]:
    """RMS of ``signal(t) - signal(t + T)`` over windows ``[t0, t0 + T]``.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Sample times [s] (increasing; gaps longer than 2.5 median steps split the data).
    signal : array_like, shape (n,)
        E.g. body pitch [rad].
    period_s : float
        Gait clock period ``T`` [s].
    step_frac : float
        Window start step in periods.
    n_grid : int
        Points per period where the signal is interpolated (linear).

    Returns
    -------
    t0_s : ndarray, shape (w,)
        Window starts [s] (windows that cross a gap are left out).
    rms : ndarray, shape (w,)
        RMS cycle-to-cycle difference [signal units].
    """
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(signal, dtype=float)
    ok = np.isfinite(t) & np.isfinite(y)
    t, y = t[ok], y[ok]
    if not (math.isfinite(period_s) and period_s > 0):
        raise SlipDataError(f'period_s must be a positive number, got {period_s!r}')
    if t.size < 10 or t[-1] - t[0] < 2 * period_s:
        return np.zeros(0), np.zeros(0)
    dt = float(np.median(np.diff(t)))
    gap_starts = t[:-1][np.diff(t) > 2.5 * dt]
    gap_ends = t[1:][np.diff(t) > 2.5 * dt]
    starts = np.arange(t[0], t[-1] - 2 * period_s + 1e-9, step_frac * period_s)
    t0s, out = [], []
    u = np.linspace(0.0, period_s, n_grid, endpoint=False)
    for t0 in starts:
        if np.any((gap_ends > t0) & (gap_starts < t0 + 2 * period_s)):
            continue
        a = np.interp(t0 + u, t, y)
        b = np.interp(t0 + period_s + u, t, y)
        t0s.append(t0)
        out.append(math.sqrt(float(np.mean((a - b) ** 2))))
    return np.array(t0s), np.array(out)


def steady_start_s(t_s: ArrayLike, pitch_rad: ArrayLike, period_s: float, *,
                   factor: float = 3.0, min_diff_rad: float = math.radians(0.1)) -> float:
    """Time from which the run is in steady state (module docs) [s, the stamps' clock].

    Returns the first stamp when no window is transient, and ``inf`` when no two consecutive
    periods are covered (steadiness unknown: nothing is steady).
    """
    t0, d = cycle_differences(t_s, pitch_rad, period_s)
    if t0.size == 0:
        return math.inf
    thr = max(factor * float(np.min(d)), min_diff_rad)
    bad = np.flatnonzero(d > thr)
    t = np.asarray(t_s, dtype=float)
    first = float(np.min(t[np.isfinite(t)]))
    if bad.size == 0:
        return first
    return float(t0[bad[-1]] + period_s)

"""Start of steady-state locomotion, detected from the data (cycle-to-cycle consistency).

Komsuoglu et al. analyse "runs where the robot achieved steady-state behavior" (Section 2).
A run that enters the tracking volume while still settling into its gait (a start-up
transient: the body pitches and bounces differently from one clock cycle to the next, legs
make extra contacts) is cut where the motion starts repeating with the clock: for windows of
two clock periods ``T`` (stepping by ``T/2``), the RMS difference between the body pitch over
the first period and over the second is compared with the run's most repeatable window; the
steady part starts one period after the last window more than ``factor`` times that floor
(and more than ``min_diff_rad``, the measurement noise).

With ``check_floor`` that floor must itself look steady: its cycle-to-cycle difference
within the pitch's white noise (:func:`white_noise_std`, times ``3 sqrt 2``) or below the
pitch's own swing in the window (its standard deviation). A run recorded wholly inside a
transient has no such window (simulated EduBot pace, 1.5 s of motion capture still settling:
differences of 4.7-4.9 deg against 3.6-3.7 deg of swing, where steady windows differ by
0.05-0.08 deg against 0.3 deg); without the check its worst window is its own floor and the
run is called steady from its first sample. The geometric fit's helpers (ground slope from
whole strides, edge pooling) keep the plain rule: on slow custom clocks whose last windows
are still partly settling their slope from strides is still better than a fitted one.

Core module: numpy only.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from hexapod_common.series import robust_sigma

from .errors import SlipDataError
from .preprocess import max_mocap_gap_s

__all__ = ['cycle_differences', 'steady_start_s', 'steady_windows', 'white_noise_std']


def cycle_differences(t_s: ArrayLike, signal: ArrayLike, period_s: float, *,
                      step_frac: float = 0.5, n_grid: int = 60
                      ) -> tuple[np.ndarray, np.ndarray]:
    """RMS of ``signal(t) - signal(t + T)`` over windows ``[t0, t0 + T]``.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Sample times [s] (increasing; gaps over :func:`.preprocess.max_mocap_gap_s` split
        the data).
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
    gap_starts = t[:-1][np.diff(t) > max_mocap_gap_s(dt)]
    gap_ends = t[1:][np.diff(t) > max_mocap_gap_s(dt)]
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


def white_noise_std(signal: ArrayLike) -> float:
    """Standard deviation of white noise on a smooth sampled signal (a pitch [rad], a height
    [m]), from the median absolute deviation of its fourth differences (a smooth signal's
    fourth differences are small at 100 Hz and above: the simulated EduBot's pitch 0.01-0.15
    mrad, its height a few micrometres)."""
    b = np.asarray(signal, dtype=float)
    b = b[np.isfinite(b)]
    if b.size < 10:
        return 0.0
    d4 = np.diff(b, 4)
    return robust_sigma(d4) / math.sqrt(70.0)


def steady_windows(t_s: ArrayLike, pitch_rad: ArrayLike, period_s: float, *,
                   min_diff_rad: float = math.radians(0.1)
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cycle-to-cycle differences (:func:`cycle_differences`) with each window's pitch swing
    and whether it looks steady on its own (module docs).

    Returns
    -------
    t0_s, rms : ndarray, shape (w,)
        As :func:`cycle_differences` [s], [rad].
    swing : ndarray, shape (w,)
        Standard deviation of the pitch over the window's two periods [rad].
    steady : ndarray of bool, shape (w,)
        ``rms`` within ``max(min_diff_rad, 3 sqrt(2) noise)`` or below ``swing``.
    """
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(pitch_rad, dtype=float)
    t0, d = cycle_differences(t, y, period_s)
    ok = np.isfinite(t) & np.isfinite(y)
    t, y = t[ok], y[ok]
    swing = np.array([float(np.std(y[(t >= a) & (t < a + 2 * period_s)])) for a in t0])
    at_noise = max(min_diff_rad, 3.0 * math.sqrt(2.0) * white_noise_std(y))
    return t0, d, swing, (d <= at_noise) | (d < swing)


def steady_start_s(t_s: ArrayLike, pitch_rad: ArrayLike, period_s: float, *,
                   factor: float = 3.0, min_diff_rad: float = math.radians(0.1),
                   check_floor: bool = False) -> float:
    """Time from which the run is in steady state (module docs) [s, the stamps' clock].

    Returns the first stamp when no window is transient, and ``inf`` when no two consecutive
    periods are covered (steadiness unknown: nothing is steady) or, with ``check_floor``, when
    not even the most repeatable window looks steady (a run wholly inside a transient).
    """
    if check_floor:
        t0, d, _, steady = steady_windows(t_s, pitch_rad, period_s, min_diff_rad=min_diff_rad)
        if t0.size and not steady[int(np.argmin(d))]:
            return math.inf
    else:
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

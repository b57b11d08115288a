"""Input power over a run's time: the change the bench's short sessions cannot show.

A robot run is averaged into one ``P_in`` per schedule. Over minutes the windings heat (the
AX-18A's thermal time constant is about 8 min), a battery sags, a gearbox warms up or the
terrain changes, and the same schedule draws more (or less) power at the end than at the
start. The run mean, and its Eq. 1 prediction error, then mixes both ends without a word.

:func:`power_in_trend` splits a run's gait-cycle windows, in time order, into
:data:`TREND_BINS` bins of equal window count and takes each bin's median input power (an
isolated glitch or gap window moves no median). The change is the last bin's median less the
first's. It is called a drift when it is both

- at least :data:`TREND_NOTE_FRACTION` of the run's mean ``P_in``, and
- at least :data:`TREND_NOTE_SIGMAS` standard errors of that difference, the window-to-window
  noise taken from successive differences (robust: the median absolute deviation), which a
  slow trend does not inflate.

Runs shorter than :data:`TREND_MIN_WINDOWS` windows or :data:`TREND_MIN_SPAN_S` seconds get no
trend (None): too few cycles to tell a drift from the gait's cycle-to-cycle spread.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from hexapod_common.series import robust_sigma

__all__ = ['TREND_BINS', 'TREND_MIN_SPAN_S', 'TREND_MIN_WINDOWS', 'TREND_NOTE_FRACTION',
           'TREND_NOTE_SIGMAS', 'power_in_trend', 'trend_note']

#: time bins of equal window count
TREND_BINS = 10
#: fewest windows, and shortest run [s], given a trend
TREND_MIN_WINDOWS = 30
TREND_MIN_SPAN_S = 30.0
#: a drift: first-to-last change of at least this fraction of the mean P_in ...
TREND_NOTE_FRACTION = 0.02
#: ... and of at least this many standard errors of the change
TREND_NOTE_SIGMAS = 5.0


def power_in_trend(t_end_s: Sequence[float], window_s: Sequence[float],
                   power_in_w: Sequence[float]) -> dict[str, Any] | None:
    """The input power of a run's windows over time, binned.

    Parameters
    ----------
    t_end_s : sequence of float
        Each window's end [s] (bag time).
    window_s : sequence of float
        Each window's length [s].
    power_in_w : sequence of float
        Each window's mean input power [W]; non-finite windows are left out.

    Returns
    -------
    dict or None
        ``span_s`` (first window's start to last window's end), ``windows``,
        ``bin_time_s`` (each bin's median window centre, from the run's start),
        ``bin_power_in_w`` (each bin's median P_in), ``first_w`` and ``last_w`` (the first
        and last bins'), ``change_w`` (last - first), ``change_fraction`` (of the windows'
        time-weighted mean P_in), ``change_sigma_w`` (standard error of the change, from the
        window-to-window noise), ``drift`` (bool: see the module). None for a run of fewer
        than :data:`TREND_MIN_WINDOWS` windows or shorter than :data:`TREND_MIN_SPAN_S`.

    Raises
    ------
    ValueError
        When the three sequences differ in length.
    """
    t = np.asarray(t_end_s, dtype=float)
    w = np.asarray(window_s, dtype=float)
    p = np.asarray(power_in_w, dtype=float)
    if not t.shape == w.shape == p.shape or t.ndim != 1:
        raise ValueError(f'power_in_trend: t_end_s, window_s and power_in_w differ in shape '
                         f'({t.shape}, {w.shape}, {p.shape})')
    ok = np.isfinite(t) & np.isfinite(w) & np.isfinite(p) & (w > 0)
    t, w, p = t[ok], w[ok], p[ok]
    if t.size < TREND_MIN_WINDOWS:
        return None
    order = np.argsort(t, kind='stable')
    t, w, p = t[order], w[order], p[order]
    start = float(t[0] - w[0])
    span = float(t[-1] - start)
    if not span >= TREND_MIN_SPAN_S:
        return None
    centre = t - 0.5 * w - start
    bins = np.array_split(np.arange(t.size), TREND_BINS)
    med = np.array([float(np.median(p[i])) for i in bins])
    times = np.array([float(np.median(centre[i])) for i in bins])
    # window-to-window noise from successive differences: a slow trend adds only its (tiny)
    # per-window step, an isolated glitch only two outlying differences
    d = np.diff(p)
    sigma_w = robust_sigma(d) / math.sqrt(2.0)
    # a median's standard error is about 1.2533 sigma / sqrt(n); two bins' difference
    n_small = min(len(bins[0]), len(bins[-1]))
    sigma_change = math.sqrt(2.0) * 1.2533 * sigma_w / math.sqrt(n_small)
    mean = float(np.sum(w * p) / np.sum(w))
    change = float(med[-1] - med[0])
    frac = change / mean if mean != 0 else math.nan
    drift = bool(abs(change) >= TREND_NOTE_FRACTION * abs(mean)
                 and abs(change) >= TREND_NOTE_SIGMAS * sigma_change)
    return {'span_s': span, 'windows': int(t.size), 'bin_time_s': times.tolist(),
            'bin_power_in_w': med.tolist(), 'first_w': float(med[0]), 'last_w': float(med[-1]),
            'change_w': change, 'change_fraction': frac, 'change_sigma_w': sigma_change,
            'drift': drift}


def trend_note(trend: dict[str, Any] | None) -> str | None:
    """The run note for a drift found by :func:`power_in_trend`, else None."""
    if not trend or not trend['drift']:
        return None
    word = 'rose' if trend['change_w'] > 0 else 'fell'
    return (f"input power {word} over the run on one schedule: {trend['first_w']:.2f} W in its "
            f"first tenth, {trend['last_w']:.2f} W in its last "
            f"({100 * trend['change_fraction']:+.1f} %, over {trend['span_s'] / 60:.1f} min; "
            f"noise +-{trend['change_sigma_w']:.2g} W): a change with time that the bench's "
            'short sessions do not see (winding heating, which `residuals` models as '
            'thermal_drift; battery sag; terrain or wear); the run mean, and its prediction '
            'error, mixes both ends (plot power_in_over_time.png)')

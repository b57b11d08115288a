"""Time series helpers shared by the analyses (core, no ROS)."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ['MAD_TO_SIGMA', 'robust_sigma', 'span_mean']

#: a normal distribution's standard deviation over its median absolute deviation
MAD_TO_SIGMA = 1.4826


def span_mean(t_s: Any, y: Any, ta: float, tb: float) -> float:
    """Time-weighted mean of the piecewise-linear ``y(t)`` over ``[ta, tb]``: the trapezoidal
    integral of ``y`` over the span, interpolated at its bounds, divided by ``tb - ta``.

    ``t_s`` is sorted; it need only cover the span with one sample at or beyond each end
    (samples farther out do not change the mean; beyond the first or last sample ``y`` is
    held). A plain mean of the samples weights each sample equally, so samples that come
    irregularly or in bursts weight the moments they cluster at (up to 2.5 % on a run's power
    with 10 or more battery samples a cycle, an outside review of `slip`); this is the mean
    `energy` and the residual loop take over their windows.
    """
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(y, dtype=float)
    if not tb > ta:
        raise ValueError(f'span_mean needs tb > ta (got {ta!r}, {tb!r})')
    if t.size == 0 or t.shape != v.shape:
        raise ValueError('span_mean needs as many stamps as values, at least one')
    inner = (t > ta) & (t < tb)
    grid = np.concatenate(([ta], t[inner], [tb]))
    return float(np.trapezoid(np.interp(grid, t, v), grid) / (tb - ta))


def robust_sigma(x: Any, centre: float | None = None) -> float:
    """A robust standard deviation of ``x``: :data:`MAD_TO_SIGMA` times the median absolute
    deviation from ``centre`` (``x``'s median when not given; a caller whose values are
    already deviations passes 0). Equal to the standard deviation for normal samples, and
    moved by an outlier no more than by any other sample. The one definition the analyses
    share (they had written it inline in eight modules)."""
    v = np.asarray(x, dtype=float)
    if v.size == 0:
        raise ValueError('robust_sigma needs at least one value')
    mid = float(np.median(v)) if centre is None else float(centre)
    return MAD_TO_SIGMA * float(np.median(np.abs(v - mid)))

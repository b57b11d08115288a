"""Stance extraction from proprioception (Komsuoglu et al., Fig. 5 and Section 3).

For each tripod: the average measured hip speed ``w_a(t)`` of its three hips; the shift

    t_s = argmin_{tau >= 0} integral |w_a(t) - w_r(t - tau)| dt

of the target speed ``w_r`` (from the Buehler clock, or the logged target speeds) found on a
1 ms grid and refined to 0.05 ms; touchdown at the falling edges (fast -> slow) and lift-off at
the rising edges (slow -> fast) of the shifted target. A *single-tripod* stance is the part of
a tripod's stance during which the other tripod is not in stance (they overlap when
``dc > 0.5``); the longest such part is kept.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import SlipDataError

__all__ = [
    'StanceWindow',
    'best_shift',
    'edges_from_target',
    'longest_free_segment',
    'single_tripod_stances',
    'tripod_stance_windows',
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class StanceWindow:
    """One single-tripod stance: touchdown and lift-off [s], tripod, shift used [s]."""

    touchdown_s: float
    liftoff_s: float
    tripod: str
    shift_s: float


def best_shift(t_s: ArrayLike, measured_speed: ArrayLike,
               target_speed: Callable[[FloatArray], FloatArray], *,
               max_shift_s: float = 0.15, step_s: float = 1e-3) -> float:
    """Time shift ``tau in [0, max_shift_s]`` minimising mean |measured(t) - target(t - tau)|.

    Parameters
    ----------
    t_s : array_like, shape (n,)
    measured_speed : array_like, shape (n,)
        Tripod-average measured hip speed [rad/s].
    target_speed : callable
        ``target_speed(t) -> (n,)`` [rad/s], defined for ``t - tau``.
    """
    t = np.asarray(t_s, dtype=float)
    w = np.asarray(measured_speed, dtype=float)
    ok = np.isfinite(t) & np.isfinite(w)
    t, w = t[ok], w[ok]
    if t.size < 10:
        raise SlipDataError(f'best_shift needs >= 10 finite hip-speed samples, got {t.size}')

    def costs(taus: FloatArray) -> FloatArray:
        # all candidate shifts at once: (len(taus), n) target samples, in row blocks
        out = np.empty(taus.size)
        rows = max(1, 200_000 // max(t.size, 1))
        for a in range(0, taus.size, rows):
            tt = taus[a:a + rows]
            tgt = np.asarray(target_speed((t[None, :] - tt[:, None]).ravel()), dtype=float)
            out[a:a + rows] = np.mean(np.abs(w[None, :] - tgt.reshape(tt.size, t.size)), axis=1)
        return out

    taus = np.arange(0.0, max_shift_s + 0.5 * step_s, step_s)
    i = int(np.argmin(costs(taus)))
    lo, hi = taus[max(i - 1, 0)], taus[min(i + 1, taus.size - 1)]
    fine = np.arange(lo, hi + 1e-12, step_s / 20)
    fc = costs(fine)
    # the cost is piecewise linear and flat-bottomed between edges: take the middle of the
    # minimising set
    best = fine[fc <= fc.min() + 1e-12]
    return float(0.5 * (best.min() + best.max()))


def edges_from_target(t_s: ArrayLike, target_speed: ArrayLike, *,
                      threshold: float | None = None) -> tuple[FloatArray, FloatArray]:
    """Falling (touchdown) and rising (lift-off) edge times of a sampled two-speed target.

    Edges are located by linear interpolation of the crossing of ``threshold`` (default the
    middle of the slow and fast speeds).
    """
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(target_speed, dtype=float)
    thr = threshold if threshold is not None else 0.5 * (np.nanmin(v) + np.nanmax(v))
    s = v - thr
    cross = np.flatnonzero(np.sign(s[:-1]) != np.sign(s[1:]))
    tc = t[cross] + (t[cross + 1] - t[cross]) * s[cross] / (s[cross] - s[cross + 1])
    falling = tc[s[cross] > 0]
    rising = tc[s[cross] < 0]
    return falling, rising


def tripod_stance_windows(touchdown_s: ArrayLike, liftoff_s: ArrayLike) -> FloatArray:
    """Pair each touchdown with the next lift-off: (m, 2) windows."""
    td = np.sort(np.asarray(touchdown_s, dtype=float))
    lo = np.sort(np.asarray(liftoff_s, dtype=float))
    out = []
    for a in td:
        j = np.searchsorted(lo, a, side='right')
        if j < lo.size:
            nxt = np.searchsorted(td, a, side='right')
            if nxt >= td.size or lo[j] <= td[nxt]:
                out.append((a, lo[j]))
    return np.array(out, dtype=float).reshape(-1, 2)


def longest_free_segment(a: float, b: float, others: ArrayLike
                         ) -> tuple[float, float] | None:
    """Longest part of the interval ``[a, b]`` not covered by any of ``others`` (shape (k, 2)),
    or None when it is covered entirely (single support: this tripod down, the other not)."""
    segs = [(float(a), float(b))]
    for c, d in np.asarray(others, dtype=float).reshape(-1, 2):
        nxt = []
        for s0, s1 in segs:
            if d <= s0 or c >= s1:
                nxt.append((s0, s1))
                continue
            if c > s0:
                nxt.append((s0, c))
            if d < s1:
                nxt.append((d, s1))
        segs = nxt
    return max(segs, key=lambda x: x[1] - x[0]) if segs else None



def single_tripod_stances(windows: dict[str, FloatArray], shifts: dict[str, float] | None = None,
                          *, min_duration_s: float = 0.0) -> list[StanceWindow]:
    """Single-tripod parts of each tripod's stance windows (the other tripod off the ground).

    Parameters
    ----------
    windows : dict
        ``{'left': (m, 2), 'right': (k, 2)}`` stance windows [s].
    shifts : dict, optional
        Shift used per tripod (carried to the result).
    """
    shifts = shifts or {}
    out: list[StanceWindow] = []
    for tripod, w in windows.items():
        others = np.concatenate([v for k, v in windows.items() if k != tripod] or
                                [np.zeros((0, 2))])
        for a, b in np.asarray(w).reshape(-1, 2):
            longest = longest_free_segment(a, b, others)
            if longest is None:
                continue
            s0, s1 = longest
            if s1 - s0 > min_duration_s:
                out.append(StanceWindow(float(s0), float(s1), tripod, shifts.get(tripod, 0.0)))
    out.sort(key=lambda s: s.touchdown_s)
    return out

"""Touchdown from proprioception (hip effort onset) and the stream offset from contacts.

The paper's edges (Section 3) are those of the time-shifted Buehler target, where the
*controller* switches phase; physical contact differs from them by the hips' tracking dynamics.
Proprioception sees the physical touchdown directly: a leg in flight needs little hip torque,
and when it lands the load makes the effort jump. Per leg, the touchdown is the upward crossing
of ``low + threshold_frac * (high - low)`` by the measured effort (``low``/``high`` its 10th and
90th percentiles over the run), linearly interpolated between the 100 Hz samples; a tripod's
touchdown is the first of its legs' touchdowns in a cluster (the tripod's contact starts with its
first leg). Lift-off has no such signature in the effort (the hips keep pushing while they
accelerate away from the ground), so lift-off stays the paper's edge.

Stream offset (:func:`estimate_offset_contacts`): touchdowns of the same stances seen in both
clocks, proprioception (effort onset) and motion capture (body height leaves its ballistic
parabola, :func:`slip_identification.contact.refine_contact_edges`); the offset is the median
difference, iterated from 0 (so it must be below about a quarter of the gait period in
magnitude: touchdowns recur every half period). Accuracy is limited by the body-height edges
(0.2 mm noise: a few ms per stance), see the report figures in the tests.

Core module: numpy only.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .contact import refine_contact_edges
from .errors import SlipDataError

__all__ = [
    'effort_onsets',
    'estimate_offset_contacts',
    'refine_touchdowns',
    'tripod_touchdowns',
]

FloatArray = NDArray[np.float64]


def effort_onsets(t_s: ArrayLike, effort: ArrayLike, *, threshold_frac: float = 0.15
                  ) -> FloatArray:
    """Upward crossings of the effort threshold (one leg), interpolated [s], shape (m,).

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Sample times [s].
    effort : array_like, shape (n,)
        Hip effort [N m]. Oriented so that its larger tail (stance load) is positive; the
        opposite sign (e.g. braking spikes when the clock switches to its slow phase) is
        clipped to zero rather than taken as load.
    threshold_frac : float
        Threshold between the 10th and 90th percentile of ``|effort|``.
    """
    t = np.asarray(t_s, dtype=float)
    e = np.asarray(effort, dtype=float)
    ok = np.isfinite(t) & np.isfinite(e)
    t, e = t[ok], e[ok]
    if t.size < 10:
        return np.zeros(0)
    if abs(np.percentile(e, 5)) > abs(np.percentile(e, 95)):
        e = -e
    e = np.maximum(e, 0.0)
    lo, hi = np.percentile(e, 10), np.percentile(e, 90)
    if not hi > lo:
        return np.zeros(0)
    s = e - (lo + threshold_frac * (hi - lo))
    c = np.flatnonzero((s[:-1] < 0) & (s[1:] >= 0))
    return t[c] + (t[c + 1] - t[c]) * (-s[c]) / (s[c + 1] - s[c])


def tripod_touchdowns(names: tuple[str, ...], t_s: ArrayLike, effort: ArrayLike,
                      legs: tuple[str, ...], *, cluster_s: float = 0.04,
                      threshold_frac: float = 0.15) -> FloatArray:
    """Touchdowns of one tripod [s]: first leg onset of each cluster, shape (m,).

    ``names`` are joint names (``<leg>_hip``), ``effort`` (n, J) in that order, ``legs`` the
    tripod's legs. Onsets closer than ``cluster_s`` to the previous one belong to the same
    touchdown.
    """
    e = np.asarray(effort, dtype=float)
    if e.ndim != 2 or e.shape[1] != len(names):
        raise SlipDataError(f'effort must be (n, {len(names)}) for joints {names}, '
                            f'got shape {e.shape}')
    cols = [names.index(f'{leg}_hip') for leg in legs if f'{leg}_hip' in names]
    if not cols:
        raise SlipDataError(f'no hips of legs {legs} in {names}')
    x = np.sort(np.concatenate([effort_onsets(t_s, e[:, j], threshold_frac=threshold_frac)
                                for j in cols]))
    if x.size == 0:
        return x
    keep = np.concatenate([[True], np.diff(x) > cluster_s])
    return x[keep]


def refine_touchdowns(windows: ArrayLike, touchdowns_s: ArrayLike, *, max_move_s: float = 0.03,
                      min_stance_s: float = 0.02) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Replace each window's touchdown by the nearest proprioceptive touchdown.

    Parameters
    ----------
    windows : array_like, shape (m, 2)
        Touchdown / lift-off [s] (e.g. the paper's shifted clock edges) of one tripod.
    touchdowns_s : array_like, shape (k,)
        Touchdowns of that tripod from :func:`tripod_touchdowns` [s].
    max_move_s : float
        A touchdown farther than this from the window's is not used (window kept).

    Returns
    -------
    refined : ndarray, shape (m, 2)
    moved : ndarray of bool, shape (m,)
        Which windows got a proprioceptive touchdown.
    """
    w = np.asarray(windows, dtype=float).reshape(-1, 2).copy()
    td = np.sort(np.asarray(touchdowns_s, dtype=float))
    moved = np.zeros(w.shape[0], dtype=bool)
    if td.size == 0:
        return w, moved
    for i, (a, b) in enumerate(w):
        j = int(np.argmin(np.abs(td - a)))
        if abs(td[j] - a) <= max_move_s and b - td[j] >= min_stance_s:
            w[i, 0] = td[j]
            moved[i] = True
    return w, moved


def estimate_offset_contacts(touchdowns_s: ArrayLike, mocap_t_s: ArrayLike, height_m: ArrayLike,
                             *, stance_s: float = 0.12, search_s: float = 0.04,
                             iterations: int = 3, min_stances: int = 4
                             ) -> tuple[float, FloatArray]:
    """Mocap clock minus proprioception clock from touchdowns seen in both streams.

    Parameters
    ----------
    touchdowns_s : array_like, shape (k,)
        Touchdowns of both tripods in the proprioception clock [s] (effort onsets).
    mocap_t_s : array_like, shape (n,)
        Raw motion-capture stamps [s] (mocap clock).
    height_m : array_like, shape (n,)
        World-frame COM height at ``mocap_t_s`` [m].
    stance_s : float
        Nominal stance duration used as the initial lift-off [s].

    Returns
    -------
    offset_s : float
        Subtract from mocap stamps to express them in the proprioception clock.
    per_stance_s : ndarray, shape (m,)
        The per-touchdown differences the median was taken over (last iteration).
    """
    td = np.sort(np.asarray(touchdowns_s, dtype=float))
    tm = np.asarray(mocap_t_s, dtype=float)
    z = np.asarray(height_m, dtype=float)
    ok = np.isfinite(tm) & np.isfinite(z)
    tm, z = tm[ok], z[ok]
    if tm.size < 20:
        raise SlipDataError(f'offset from contacts needs >= 20 mocap samples, got {tm.size}')
    d = 0.0
    diffs = np.zeros(0)
    for _ in range(iterations):
        sel = td[(td + d > tm[0] + search_s) & (td + d + stance_s < tm[-1] - search_s)]
        if sel.size < min_stances:
            raise SlipDataError(f'offset from contacts needs >= {min_stances} touchdowns inside '
                                f'the motion-capture span, got {sel.size}')
        w = np.column_stack([sel + d, sel + d + stance_s])
        got, rms = refine_contact_edges(tm, z, w, search_s=search_s)
        good = np.isfinite(rms)
        if good.sum() < min_stances:
            raise SlipDataError(f'only {int(good.sum())} touchdowns refined from body height, '
                                f'need >= {min_stances}')
        diffs = got[good, 0] - sel[good]
        d = float(np.median(diffs))
    return d, diffs

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
(0.2 mm noise: a few ms per stance), see the report figures in the tests. The body-height edges
need an aerial phase between stances; a run where the body does not fall freely there (gravity
fitted free around the refined stances, :func:`slip_identification.contact.free_fall_gravity`,
below half of g in the median: simulated EduBot walk and pace) is refused, and with it the
joint offset started from it (on a walk the estimate was 63-75 ms off, clean, drifting by about
the search width with each iteration).

Joint offset (:func:`estimate_offset_joint`, offset method ``'joint'``): one offset for all
stances at once, see its docstring. On simulated RHex-class runs it is not yet within the
issue's 2 ms either (figures in test/unit/test_slip_edges_offset.py): the ground force of the
rolling legs starts with a small jump and a ramp, so under 0.2 mm noise at 120 Hz the
body-height trace fixes a touchdown to a few ms only, and a polynomial force model trades
timing against shape.

Core module: numpy only.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .contact import GRAVITY_M_S2, _sse, free_fall_gravity, refine_contact_edges
from .errors import SlipDataError
from .preprocess import max_mocap_gap_s

__all__ = [
    'effort_onsets',
    'estimate_offset_contacts',
    'alternating_touchdowns',
    'estimate_offset_joint',
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
                             iterations: int = 3, min_stances: int = 4,
                             min_free_fall: float = 0.5) -> tuple[float, FloatArray]:
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
    min_free_fall : float
        The run is refused (:class:`SlipDataError`) when the median downward acceleration
        fitted free around the refined stances (:func:`.contact.free_fall_gravity`) is below
        this fraction of g: no ballistic flight between stances, the model's assumption
        (simulated EduBot running and jogging 0.96-1.0, pace 0.15-0.27, walk 0.05).

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
    # the edges are breaks of a ballistic flight: without one they drift with the search
    fall = free_fall_gravity(tm, z, got, search_s=search_s)[good]
    fall = fall[np.isfinite(fall)]
    if fall.size == 0 or np.median(fall) < min_free_fall * GRAVITY_M_S2:
        seen = (f'{np.median(fall):.2f} m/s^2 in the median of {fall.size} stances' if fall.size
                else 'not measurable on any stance')
        raise SlipDataError(
            f'offset from contacts: the body does not fall freely between stances (its '
            f'vertical acceleration there, fitted free, {seen}; g = {GRAVITY_M_S2} m/s^2): '
            'a gait without an aerial phase, whose touchdowns the body height does not show')
    return d, diffs


def alternating_touchdowns(touchdowns: dict[str, ArrayLike]
                           ) -> tuple[FloatArray, NDArray[np.int_]]:
    """Merge per-tripod touchdowns, keeping the first of consecutive same-tripod onsets.

    Tripods alternate, so a second onset of a tripod before the other tripod's next one is a
    spurious onset within the stance (e.g. the load shifting near lift-off). Returns the kept
    times [s] (sorted) and the index of their tripod in ``touchdowns``' order.
    """
    t = np.concatenate([np.asarray(v, dtype=float) for v in touchdowns.values()])
    w = np.concatenate([np.full(np.size(v), i) for i, v in enumerate(touchdowns.values())])
    o = np.argsort(t)
    t, w = t[o], w[o]
    keep = np.concatenate([[True], w[1:] != w[:-1]]) if t.size else np.zeros(0, dtype=bool)
    return t[keep], w[keep]


def _parabola_min(d_grid: FloatArray, cost: FloatArray) -> float:
    i = int(np.argmin(cost))
    d = float(d_grid[i])
    if 0 < i < cost.size - 1:
        y0, y1, y2 = cost[i - 1], cost[i], cost[i + 1]
        den = y0 - 2 * y1 + y2
        if den > 0:
            d += 0.5 * (d_grid[1] - d_grid[0]) * (y0 - y2) / den
    return d


def _joint_cost(tm: FloatArray, z: FloatArray, td: FloatArray, d_grid: FloatArray,
                d_centre: float, *, pre_s: float, post_frac: float, lo_grid_s: FloatArray,
                degree: int) -> tuple[FloatArray, int]:
    """Sum over stances of the stance-model residual (min over lift-off), normalised per stance.

    Data windows are fixed by ``d_centre``: from ``pre_s`` before the shifted touchdown to
    ``post_frac`` of the way to the next touchdown (flight, stance, flight).
    """
    tot = np.zeros(d_grid.size)
    used = 0
    # a stance across a gap the SLIP track does not bridge is left out (was 2.5 intervals)
    longest = max_mocap_gap_s(float(np.median(np.diff(tm))))
    for i in range(td.size - 1):
        a = td[i] + d_centre - pre_s
        b = td[i] + d_centre + post_frac * (td[i + 1] - td[i])
        if a < tm[0] or b > tm[-1] or td[i + 1] - td[i] > 0.5:
            continue
        k = (tm >= a) & (tm <= b)
        if k.sum() < degree + 10 or np.any(np.diff(tm[k]) > longest):
            continue
        tdc, loc = (x.ravel() for x in np.meshgrid(td[i] + d_grid, td[i] + d_centre + lo_grid_s,
                                                   indexing='ij'))
        ok = loc - tdc >= 0.02
        sse = np.full(tdc.size, np.inf)
        sse[ok] = _sse(tm[k], z[k], tdc[ok], loc[ok], degree, GRAVITY_M_S2)
        c = sse.reshape(d_grid.size, lo_grid_s.size).min(axis=1)
        if not np.all(np.isfinite(c)):
            continue
        tot += c / max(float(c.min()), 1e-300)
        used += 1
    return tot, used


def estimate_offset_joint(touchdowns: dict[str, ArrayLike], mocap_t_s: ArrayLike,
                          height_m: ArrayLike, *, initial_offset_s: float | None = None,
                          half_range_s: float = 0.015, step_s: float = 5e-4,
                          pre_s: float = 0.03, post_frac: float = 0.8, degree: int = 3,
                          lift_off_s: tuple[float, float] = (0.05, 0.12),
                          iterations: int = 3, min_stances: int = 4) -> tuple[float, int]:
    """Mocap clock minus proprioception clock, one offset fitted over all stances.

    Every stance's body height over a fixed window (flight before it, the stance, most of the
    flight after it) is fitted by the ballistic-plus-force model of :mod:`.contact` with the
    touchdown fixed at the proprioceptive one plus the candidate offset and the lift-off free
    (``lift_off_s`` after the touchdown, 1 ms grid); each stance's residual curve is divided by
    its minimum (equal weight per stance) and the curves summed; the minimum on the ``step_s``
    grid is refined by a parabola, the windows re-centred on it and the search repeated.

    Parameters
    ----------
    touchdowns : dict of array_like
        Proprioceptive touchdowns per tripod [s] (:func:`tripod_touchdowns`).
    mocap_t_s, height_m : array_like, shape (n,)
        Raw motion-capture stamps [s] (mocap clock) and world-frame COM height [m].
    initial_offset_s : float, optional
        Start [s]; default :func:`estimate_offset_contacts`.

    Returns
    -------
    offset_s : float
        Subtract from mocap stamps to express them in the proprioception clock.
    n_stances : int
        Stances in the last sum.
    """
    td, _ = alternating_touchdowns(touchdowns)
    tm = np.asarray(mocap_t_s, dtype=float)
    z = np.asarray(height_m, dtype=float)
    ok = np.isfinite(tm) & np.isfinite(z)
    tm, z = tm[ok], z[ok]
    if tm.size < 20:
        raise SlipDataError(f'joint offset needs >= 20 mocap samples, got {tm.size}')
    o = np.argsort(tm)
    tm, z = tm[o], z[o]
    d = (estimate_offset_contacts(td, tm, z, min_stances=min_stances)[0]
         if initial_offset_s is None else float(initial_offset_s))
    lo_grid = np.arange(lift_off_s[0], lift_off_s[1] + 5e-4, 1e-3)
    used = 0
    for it in range(iterations):
        half = half_range_s if it == 0 else 0.5 * half_range_s
        grid = d + np.arange(-half, half + 0.5 * step_s, step_s)
        cost, used = _joint_cost(tm, z, td, grid, d, pre_s=pre_s, post_frac=post_frac,
                                 lo_grid_s=lo_grid, degree=degree)
        if used < min_stances:
            raise SlipDataError(f'joint offset: {used} stances with motion capture around '
                                f'them, need >= {min_stances}')
        d_new = _parabola_min(grid, cost)
        if abs(d_new - d) < 2.5e-4:
            d = d_new
            break
        d = d_new
    return float(d), used

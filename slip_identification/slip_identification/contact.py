"""Touchdown and lift-off refined from the body's vertical motion (flight is ballistic).

The paper's edges (Section 3) are those of the time-shifted Buehler target, i.e. where the
*controller* switches between its slow and fast phase; the physical contact differs from them
by the hip's tracking dynamics (on the EduBot simulator the clock lift-off comes 15 to 30 ms
before the foot leaves the ground). Between two stances of a gait with aerial phases
(duty factor below one half for each tripod) the COM is ballistic, ``z'' = -g``, and during a
stance ``z'' = -g + f(t)`` with ``f >= 0`` the vertical ground force over the mass. This module
fits, per stance, the raw motion-capture heights around the stance with

    z(t) = z0 + v0 (t - tc) - g (t - tc)^2 / 2 + sum_k c_k I2[(1 - s) s^k](t),
    s = (t - td) / (lo - td) clipped to [0, 1],

(``I2`` the double time integral; the force may jump at touchdown and falls to zero at lift-off
as the SLIP's spring force does), linear in ``z0, v0, c_k`` for given ``(td, lo)``; the edges
minimise the residual sum of squares on a coarse grid and then a fine one around its minimum.
Two passes: the fit interval of a stance runs from the previous lift-off to the next touchdown
(first pass: from the clock touchdown minus ``lead_s``).

The model holds only where the body falls freely between stances. :func:`free_fall_gravity`
checks it on the data: the same fits with gravity a free parameter give ``g`` on gaits with an
aerial phase (simulated EduBot running and jogging: 9.7 to 9.9 m/s^2 median over a run) and a
fraction of it where a tripod always carries the body (pace 1.5-2.6, walk 0.5 m/s^2). There
the refined edges mean nothing: on a walk the touchdowns move late by about the search width
each pass (the body height has no break to lock on to).

Windows bridge motion-capture gaps up to :func:`.preprocess.max_mocap_gap_s` (the SLIP
track's rule: 30 ms, two missing samples at 120 Hz); a longer gap leaves the stance's edges as
they were. Core module: numpy (and the shared gap rule).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .preprocess import max_mocap_gap_s

__all__ = ['GRAVITY_M_S2', 'free_fall_gravity', 'refine_contact_edges']

FloatArray = NDArray[np.float64]
GRAVITY_M_S2 = 9.81


def _basis(t: FloatArray, td: FloatArray, lo: FloatArray, degree: int) -> FloatArray:
    """Double integrals of (1 - s) s^k on [td, lo], shape (c, n, degree + 1) for c candidates.

    ``(1 - s) s^k = s^k - s^(k+1)`` and the double integral of ``s^m`` from td is
    ``D^2 S^(m+2) / ((m+1)(m+2))`` inside the stance, continued linearly with slope
    ``D / (m+1)`` after lift-off (``D = lo - td``, ``S = clip(s, 0, 1)``).
    """
    d = (lo - td)[:, None]
    s = np.clip((t[None, :] - td[:, None]) / d, 0.0, 1.0)
    after = np.maximum(t[None, :] - lo[:, None], 0.0)
    d2 = d * d
    power = s * s                  # s^(m+2), from m = 0 up
    terms = []                     # the double integral of s^m, m = 0 .. degree + 1
    for m in range(degree + 2):
        if m:
            power = power * s
        terms.append(d2 * power / ((m + 1) * (m + 2)) + d / (m + 1) * after)
    out = np.empty(s.shape + (degree + 1,))
    for k in range(degree + 1):
        np.subtract(terms[k], terms[k + 1], out=out[..., k])
    return out


def _sse(t: FloatArray, z: FloatArray, td: FloatArray, lo: FloatArray, degree: int,
         gravity: float) -> FloatArray:
    """Residual sum of squares of the linear fit for each candidate (td, lo), shape (c,)."""
    tc = t - t.mean()
    y = z + 0.5 * gravity * tc * tc
    b = _basis(t, td, lo, degree)
    x = np.empty(b.shape[:2] + (b.shape[2] + 2,))                    # (c, n, p)
    x[..., 0] = 1.0
    x[..., 1] = tc
    x[..., 2:] = b
    # scale columns for a well-conditioned normal system; batched products through matmul
    # (einsum's 'cnp,cnq->cpq' took twice the time of the whole rest)
    scale = np.sqrt(np.einsum('cnp,cnp->cp', x, x)) + 1e-300
    xs = x / scale[:, None, :]
    xt = xs.transpose(0, 2, 1)
    xtx = xt @ xs + 1e-12 * np.eye(x.shape[-1])
    beta = np.linalg.solve(xtx, (xt @ y)[..., None])
    r = y[None, :] - (xs @ beta)[..., 0]
    return np.einsum('cn,cn->c', r, r)


def _refine_one(t: FloatArray, z: FloatArray, td0: float, lo0: float, a: float, b: float, *,
                search_s: float, degree: int, gravity: float, min_stance_s: float
                ) -> tuple[float, float, float]:
    k = (t >= a) & (t <= b)
    tt, zz = t[k], z[k]
    if tt.size < degree + 6:
        return td0, lo0, float('nan')
    best = (td0, lo0, float('inf'))
    centre = (td0, lo0)
    for step, half in ((2e-3, search_s), (2.5e-4, 3e-3)):
        g_td = centre[0] + np.arange(-half, half + 0.5 * step, step)
        g_lo = centre[1] + np.arange(-half, half + 0.5 * step, step)
        td, lo = (x.ravel() for x in np.meshgrid(g_td, g_lo, indexing='ij'))
        ok = (td > tt[0]) & (lo < tt[-1]) & (lo - td >= min_stance_s)
        if not np.any(ok):
            return td0, lo0, float('nan')
        td, lo = td[ok], lo[ok]
        sse = _sse(tt, zz, td, lo, degree, gravity)
        i = int(np.argmin(sse))
        centre = (float(td[i]), float(lo[i]))
        best = (centre[0], centre[1], float(np.sqrt(sse[i] / tt.size)))
    return best


def _fit_interval(w: FloatArray, j: int, *, search_s: float, lead_s: float
                  ) -> tuple[float, float]:
    """Fit interval of stance ``j`` around the windows ``w`` (sorted): the second pass's."""
    a = w[j - 1, 1] + 1e-3 if j > 0 else w[j, 0] - 2 * lead_s
    b = w[j + 1, 0] - 1e-3 if j + 1 < w.shape[0] else w[j, 1] + 2 * lead_s
    return max(a, w[j, 0] - search_s), min(b, w[j, 1] + 2 * search_s)


def free_fall_gravity(t_s: ArrayLike, z_m: ArrayLike, windows: ArrayLike, *,
                      search_s: float = 0.04, lead_s: float = 0.015, degree: int = 2
                      ) -> FloatArray:
    """Vertical acceleration outside each stance fitted free [m/s^2] (``g`` if ballistic).

    The model of :func:`refine_contact_edges` with its ``-g t^2 / 2`` term replaced by a free
    ``t^2`` coefficient, fitted over the interval the refinement's second pass uses (the
    previous lift-off to the next touchdown) with the edges fixed at ``windows`` (e.g. the
    refined ones). Between stances with an aerial phase it returns ``g``; where another leg
    carries the body between the windows (no flight: walk, pace) a fraction of it.

    Returns
    -------
    ndarray, shape (m,)
        Fitted downward acceleration per window (in the windows' order) [m/s^2]; NaN where the
        interval has too few samples or a gap the track does not bridge.
    """
    t = np.asarray(t_s, dtype=float)
    z = np.asarray(z_m, dtype=float)
    ok = np.isfinite(t) & np.isfinite(z)
    t, z = t[ok], z[ok]
    w0 = np.asarray(windows, dtype=float).reshape(-1, 2)
    out = np.full(w0.shape[0], np.nan)
    if t.size < 10 or w0.shape[0] == 0:
        return out
    order = np.argsort(w0[:, 0])
    w = w0[order]
    longest = max_mocap_gap_s(float(np.median(np.diff(t))))
    for j in range(w.shape[0]):
        a, b = _fit_interval(w, j, search_s=search_s, lead_s=lead_s)
        k = (t >= a) & (t <= b)
        if (k.sum() < degree + 7 or np.any(np.diff(t[k]) > longest) or
                not t[k][0] < w[j, 0] < w[j, 1] < t[k][-1]):
            continue
        tc = t[k] - t[k].mean()
        x = np.column_stack([np.ones(tc.size), tc, tc * tc,
                             _basis(t[k], w[j:j + 1, 0], w[j:j + 1, 1], degree)[0]])
        scale = np.sqrt(np.sum(x * x, axis=0)) + 1e-300
        beta = np.linalg.lstsq(x / scale, z[k], rcond=None)[0] / scale
        out[order[j]] = -2.0 * beta[2]
    return out


def refine_contact_edges(t_s: ArrayLike, z_m: ArrayLike, windows: ArrayLike, *,
                         search_s: float = 0.04, lead_s: float = 0.015, degree: int = 2,
                         gravity_m_s2: float = GRAVITY_M_S2, min_stance_s: float = 0.02,
                         passes: int = 2) -> tuple[FloatArray, FloatArray]:
    """Refine stance windows on the COM height (gaits with an aerial phase between stances).

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Raw motion-capture times [s] (already in the proprioception clock).
    z_m : array_like, shape (n,)
        World-frame COM height [m] at ``t_s`` (raw samples, not splined).
    windows : array_like, shape (m, 2)
        Initial touchdown / lift-off of every stance of both tripods [s], e.g. the shifted
        clock edges; sorted by touchdown, not overlapping.
    search_s : float
        Half width of the coarse search around the initial edges [s].

    Returns
    -------
    refined : ndarray, shape (m, 2)
        Refined windows [s]; a window that cannot be refined (too few samples around it, a
        gap over :func:`.preprocess.max_mocap_gap_s`) keeps its initial edges.
    rms_m : ndarray, shape (m,)
        RMS residual of each fit [m] (NaN where not refined).
    """
    t = np.asarray(t_s, dtype=float)
    z = np.asarray(z_m, dtype=float)
    ok = np.isfinite(t) & np.isfinite(z)
    t, z = t[ok], z[ok]
    w0 = np.asarray(windows, dtype=float).reshape(-1, 2)
    order = np.argsort(w0[:, 0])
    w = w0[order].copy()
    rms = np.full(w.shape[0], np.nan)
    if t.size < 10 or w.shape[0] == 0:
        return w0.copy(), np.full(w0.shape[0], np.nan)
    init = w.copy()
    longest = max_mocap_gap_s(float(np.median(np.diff(t))))
    for p in range(passes):
        prev = w.copy()
        for j in range(w.shape[0]):
            if p == 0:
                a = init[j, 0] - lead_s
                b = init[j + 1, 0] - lead_s if j + 1 < w.shape[0] else init[j, 1] + 2 * search_s
                a = max(a, prev[j, 0] - search_s)
                b = min(b, prev[j, 1] + 2 * search_s)
            else:
                a, b = _fit_interval(prev, j, search_s=search_s, lead_s=lead_s)
            # no refinement across a motion-capture gap the track does not bridge (was 2.5
            # sample intervals: two missing samples at 120 Hz lost the stance)
            k = (t >= a) & (t <= b)
            if k.sum() < degree + 6 or np.any(np.diff(t[k]) > longest):
                continue
            td, lo, r = _refine_one(t, z, prev[j, 0], prev[j, 1], a, b,
                                    search_s=search_s if p == 0 else 0.5 * search_s,
                                    degree=degree, gravity=gravity_m_s2,
                                    min_stance_s=min_stance_s)
            w[j] = (td, lo)
            rms[j] = r
    out = np.empty_like(w)
    out[order] = w
    rms_out = np.empty_like(rms)
    rms_out[order] = rms
    return out, rms_out

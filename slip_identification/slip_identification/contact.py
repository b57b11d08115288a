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

Windows bridge motion-capture gaps up to :func:`.preprocess.max_mocap_gap_s` (the SLIP
track's rule: 30 ms, two missing samples at 120 Hz); a longer gap leaves the stance's edges as
they were. Core module: numpy (and the shared gap rule).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .preprocess import max_mocap_gap_s

__all__ = ['GRAVITY_M_S2', 'refine_contact_edges']

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
            else:
                a = prev[j - 1, 1] + 1e-3 if j > 0 else prev[j, 0] - 2 * lead_s
                b = prev[j + 1, 0] - 1e-3 if j + 1 < w.shape[0] else prev[j, 1] + 2 * lead_s
            a = max(a, prev[j, 0] - search_s)
            b = min(b, prev[j, 1] + 2 * search_s)
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

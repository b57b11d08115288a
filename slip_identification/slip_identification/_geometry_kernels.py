"""Compiled kernel of the geometric fit's output-error simulation (numba; optional).

:func:`simulate_windows` is the step loop of ``geometry._OutputError.simulate`` compiled: the
vertical body dynamics ``h'' = k sum_j max(0, p_j + tau p_j') - g0`` with ``p_j = Q_j - h``,
integrated by Heun's method on the 1 kHz grid, one window after the other (each window its own
stiffness, start height and velocity), with the exact derivatives of the discrete map by the
window's (k, h0, v0) when asked. Same operations as the numpy loop (which vectorises over
windows and steps in Python); without numba :data:`HAVE_NUMBA` is False and the caller keeps
the numpy loop.
"""

from __future__ import annotations

import numpy as np

__all__ = ['HAVE_NUMBA', 'simulate_windows']

try:
    from numba import njit
    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised when numba is absent
    HAVE_NUMBA = False


def _legs_force(q, qd, r, z, v, tau):  # type: ignore[no-untyped-def]
    """Sum over the legs in contact of ``p + tau p'`` at grid row ``r`` for height ``z`` and
    velocity ``v`` (``p = q - z`` and the force both positive), and their number."""
    ff = 0.0
    n_on = 0
    for j in range(q.shape[1]):
        p = q[r, j] - z
        f = p + tau * (qd[r, j] - v)
        if p > 0.0 and f > 0.0:
            ff += f
            n_on += 1
    return ff, n_on


if HAVE_NUMBA:
    _legs = njit(cache=True, inline='always')(_legs_force)
else:  # pragma: no cover
    _legs = _legs_force


def _simulate_windows(q, qd, i0, n_steps, k, h0, v0, tau, dt, g, sens,  # type: ignore
                      hh, vv, sh, sv):
    """Fill ``hh``, ``vv`` (n_steps, W) and, with ``sens``, ``sh``, ``sv`` (n_steps, 3, W).

    ``q``, ``qd`` (N, L): each leg's rest height plus the hip's height over the COM and its
    rate on the grid; window ``w`` starts at grid index ``i0[w]`` (indices past the grid's
    end are clamped to its last point, as the numpy loop's ``grid_i``)."""
    last = q.shape[0] - 1
    for w in range(i0.shape[0]):
        kw = k[w]
        z = h0[w]
        v = v0[w]
        dz0 = 0.0
        dz1 = 1.0
        dz2 = 0.0
        dv0 = 0.0
        dv1 = 0.0
        dv2 = 1.0
        # acceleration at step 0
        r = min(i0[w], last)
        ff, n_on = _legs(q, qd, r, z, v, tau)
        a = kw * ff - g
        kn = kw * n_on
        da0 = -kn * (dz0 + tau * dv0) + ff
        da1 = -kn * (dz1 + tau * dv1)
        da2 = -kn * (dz2 + tau * dv2)
        for s in range(n_steps):
            hh[s, w] = z
            vv[s, w] = v
            if sens:
                sh[s, 0, w] = dz0
                sh[s, 1, w] = dz1
                sh[s, 2, w] = dz2
                sv[s, 0, w] = dv0
                sv[s, 1, w] = dv1
                sv[s, 2, w] = dv2
            if s == n_steps - 1:
                break
            r = min(i0[w] + s + 1, last)
            zp = z + dt * v
            vp = v + dt * a
            ffp, n_on = _legs(q, qd, r, zp, vp, tau)
            ap = kw * ffp - g
            knp = kw * n_on
            z = z + 0.5 * dt * (v + vp)
            v = v + 0.5 * dt * (a + ap)
            if sens:
                dzp0 = dz0 + dt * dv0
                dzp1 = dz1 + dt * dv1
                dzp2 = dz2 + dt * dv2
                dvp0 = dv0 + dt * da0
                dvp1 = dv1 + dt * da1
                dvp2 = dv2 + dt * da2
                dap0 = -knp * (dzp0 + tau * dvp0) + ffp
                dap1 = -knp * (dzp1 + tau * dvp1)
                dap2 = -knp * (dzp2 + tau * dvp2)
                dz0 = dz0 + 0.5 * dt * (dv0 + dvp0)
                dz1 = dz1 + 0.5 * dt * (dv1 + dvp1)
                dz2 = dz2 + 0.5 * dt * (dv2 + dvp2)
                dv0 = dv0 + 0.5 * dt * (da0 + dap0)
                dv1 = dv1 + 0.5 * dt * (da1 + dap1)
                dv2 = dv2 + 0.5 * dt * (da2 + dap2)
            ff, n_on = _legs(q, qd, r, z, v, tau)
            a = kw * ff - g
            kn = kw * n_on
            if sens:
                da0 = -kn * (dz0 + tau * dv0) + ff
                da1 = -kn * (dz1 + tau * dv1)
                da2 = -kn * (dz2 + tau * dv2)


if HAVE_NUMBA:
    _compiled = njit(cache=True, nogil=True)(_simulate_windows)


def simulate_windows(q: np.ndarray, qd: np.ndarray, i0: np.ndarray, n_steps: int,
                     k: np.ndarray, h0: np.ndarray, v0: np.ndarray, tau: float, dt: float,
                     g: float, sens: bool) -> tuple[np.ndarray, ...]:
    """Heights and velocities above the ground, (n_steps, W) each; with ``sens`` also their
    derivatives by each window's (k, h0, v0), (n_steps, 3, W) each. Needs numba."""
    if not HAVE_NUMBA:  # pragma: no cover
        raise RuntimeError('simulate_windows needs numba')
    n_w = i0.shape[0]
    hh = np.empty((n_steps, n_w))
    vv = np.empty((n_steps, n_w))
    shape = (n_steps, 3, n_w) if sens else (1, 3, 1)
    sh = np.empty(shape)
    sv = np.empty(shape)
    _compiled(np.ascontiguousarray(q, dtype=np.float64),
              np.ascontiguousarray(qd, dtype=np.float64),
              np.ascontiguousarray(i0, dtype=np.int64), int(n_steps),
              np.ascontiguousarray(k, dtype=np.float64),
              np.ascontiguousarray(h0, dtype=np.float64),
              np.ascontiguousarray(v0, dtype=np.float64), float(tau), float(dt), float(g),
              bool(sens), hh, vv, sh, sv)
    if sens:
        return hh, vv, sh, sv
    return hh, vv

"""Compiled kernels of the geometric fit (numba; optional): its output-error simulation and
its equation-error cost.

:func:`simulate_windows` is the step loop of ``geometry._OutputError.simulate`` compiled: the
vertical body dynamics ``h'' = k sum_j max(0, p_j + tau p_j') - g0`` with ``p_j = Q_j - h``,
integrated by Heun's method on the 1 kHz grid, one window after the other (each window its own
stiffness, start height and velocity), with the exact derivatives of the discrete map by the
window's (k, h0, v0) when asked. Same operations as the numpy loop (which vectorises over
windows and steps in Python); without numba :data:`HAVE_NUMBA` is False and the caller keeps
the numpy loop.

:func:`cost_mse` is ``geometry._cost``'s scalar path (the mean squared residual of one
offset, ground and damping time, which the offset and ground searches evaluate thousands of
times) in one pass: the legs' force from the cached gaps, its two running integrals, their
values at the mocap samples and each window's 2 x 2 least squares in closed form. It gives the
numpy code's cost to rounding (its sums run in another order). :func:`leg_gaps` is the
legs' gaps above the ground (``geometry._Body.gaps_above_zero``) in one pass.
"""

from __future__ import annotations

import numpy as np

__all__ = ['HAVE_NUMBA', 'cost_mse', 'leg_gaps', 'simulate_windows']

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


def _quad2_py(a, b, c, x0, x1, y0, y1, rcond):  # type: ignore[no-untyped-def]
    """``x' pinv(G) y`` for the symmetric positive semi-definite ``G = [[a, b], [b, c]]``,
    with numpy's ``pinv`` cut-off: eigenvalues at most ``rcond`` times the largest count as
    zero."""
    h = 0.5 * (a + c)
    d = 0.5 * (a - c)
    disc = np.sqrt(d * d + b * b)
    lam1 = h + disc
    if not lam1 > 0.0:
        return 0.0
    det = a * c - b * b
    lam2 = det / lam1
    if abs(lam2) > rcond * lam1:
        return (c * x0 * y0 - b * (x0 * y1 + x1 * y0) + a * x1 * y1) / det
    # rank one: the eigenvector of lam1
    if d >= 0.0:
        v0, v1 = d + disc, b
    else:
        v0, v1 = b, disc - d
    nv = np.sqrt(v0 * v0 + v1 * v1)
    if nv == 0.0:
        v0, v1 = 1.0, 0.0
    else:
        v0 /= nv
        v1 /= nv
    return (v0 * x0 + v1 * x1) * (v0 * y0 + v1 * y1) / lam1


if HAVE_NUMBA:
    _quad2 = njit(cache=True, inline='always')(_quad2_py)
else:  # pragma: no cover
    _quad2 = _quad2_py


def _cost_mse(gap0, ground, clipped, tau, step, tf, tm_sel, offset, z_sel, bounds, sizes,
              gravity):  # type: ignore[no-untyped-def]
    """The scalar path of ``geometry._cost`` (see :func:`cost_mse`)."""
    linear = not clipped
    n, n_leg = gap0.shape
    pen = np.empty((n, n_leg))
    for i in range(n):
        for j in range(n_leg):
            p = ground - gap0[i, j]
            pen[i, j] = 0.0 if p < 0.0 else p
    force = np.zeros(n)
    if clipped:
        for i in range(n):
            s = 0.0
            for j in range(n_leg):
                p = pen[i, j]
                if p > 0.0:
                    if i == 0:
                        r = (pen[1, j] - pen[0, j]) / step
                    elif i == n - 1:
                        r = (pen[n - 1, j] - pen[n - 2, j]) / step
                    else:
                        r = (pen[i + 1, j] - pen[i - 1, j]) / (2.0 * step)
                    f = p + tau * r
                    s += 0.0 if f < 0.0 else f
            force[i] = s
    else:
        for i in range(n):
            s = 0.0
            for j in range(n_leg):
                s += pen[i, j]
            force[i] = s
    i1 = np.empty(n)
    i2 = np.empty(n)
    i1[0] = 0.0
    i2[0] = 0.0
    acc = 0.0
    for i in range(1, n):
        acc += 0.5 * (force[i] + force[i - 1])
        i1[i] = acc * step
    acc = 0.0
    for i in range(1, n):
        acc += 0.5 * (i1[i] + i1[i - 1])
        i2[i] = acc * step
    m = tm_sel.shape[0]
    ts = tm_sel - offset
    a2 = np.interp(ts, tf, i2)
    scale2 = 1e-300
    for k in range(m):
        v = abs(a2[k])
        if v > scale2:
            scale2 = v
    a1 = np.interp(ts, tf, i1) if linear else a2
    c_g = 0.5 * gravity
    sse = 0.0
    sum_sps = 0.0
    sum_spy = 0.0
    for w in range(bounds.shape[0]):
        lo = bounds[w]
        nw = sizes[w]
        hi = lo + nw
        t0 = ts[lo]
        my = 0.0
        mt = 0.0
        ma = 0.0
        ms = 0.0
        for k in range(lo, hi):
            dt = ts[k] - t0
            my += z_sel[k] + c_g * (dt * dt)
            mt += dt
            ma += a2[k] / scale2
            if linear:
                ms += a1[k]
        my /= nw
        mt /= nw
        ma /= nw
        ms /= nw
        g00 = 0.0
        g01 = 0.0
        g11 = 0.0
        x0y = 0.0
        x1y = 0.0
        yy = 0.0
        x0s = 0.0
        x1s = 0.0
        ss = 0.0
        sy = 0.0
        for k in range(lo, hi):
            dt = ts[k] - t0
            y = z_sel[k] + c_g * (dt * dt) - my
            c0 = dt - mt
            c1 = a2[k] / scale2 - ma
            g00 += c0 * c0
            g01 += c0 * c1
            g11 += c1 * c1
            x0y += c0 * y
            x1y += c1 * y
            yy += y * y
            if linear:
                sc = a1[k] - ms
                x0s += c0 * sc
                x1s += c1 * sc
                ss += sc * sc
                sy += sc * y
        sse += yy - _quad2(g00, g01, g11, x0y, x1y, x0y, x1y, 1e-12)
        if linear:
            sum_sps += ss - _quad2(g00, g01, g11, x0s, x1s, x0s, x1s, 1e-12)
            sum_spy += sy - _quad2(g00, g01, g11, x0s, x1s, x0y, x1y, 1e-12)
    if linear and sum_sps > 0.0:
        sse -= sum_spy / sum_sps * sum_spy
    if sse < 0.0:
        sse = 0.0
    return sse / max(m, 1)


if HAVE_NUMBA:
    _cost_mse_c = njit(cache=True, nogil=True)(_cost_mse)


def cost_mse(gap0: np.ndarray, ground: float, model: str, tau: float, step: float,
             tf: np.ndarray, tm_sel: np.ndarray, offset: float, z_sel: np.ndarray,
             bounds: np.ndarray, sizes: np.ndarray, gravity: float) -> float:
    """Mean squared residual of ``geometry._cost`` (its scalar path): ``gap0`` (N, L) the
    legs' gaps above ground 0 on the grid ``tf`` (step ``step``), ``tm_sel``/``z_sel`` the
    windows' mocap stamps and heights (windows contiguous, starting at ``bounds``, ``sizes``
    long). Needs numba."""
    if not HAVE_NUMBA:  # pragma: no cover
        raise RuntimeError('cost_mse needs numba')
    return float(_cost_mse_c(gap0, float(ground), model == 'clipped', float(tau), float(step),
                             tf, tm_sel, float(offset), z_sel, bounds, sizes, float(gravity)))


def _leg_gaps(z, b, phi, tt, hx, hip_z, hip_zero, radius, t_lo, t_hi):  # type: ignore
    n, n_leg = phi.shape
    out = np.empty((n, n_leg))
    two_pi = 2 * np.pi
    for i in range(n):
        if tt[i] < t_lo or tt[i] > t_hi:
            for j in range(n_leg):
                out[i, j] = np.inf
            continue
        sb = np.sin(b[i])
        cb = np.cos(b[i])
        for j in range(n_leg):
            hip = z[i] - hx[j] * sb + hip_z * cb
            psi = phi[i, j] + b[i] + hip_zero
            w = psi - two_pi * np.floor(psi / two_pi + 0.5)
            c = np.cos(w)
            if w >= 0 and w < np.pi:
                rest = radius * (1 + c)
            elif c > 0:
                rest = 2 * radius * c
            else:
                rest = -1.0
            out[i, j] = hip - rest
    return out


if HAVE_NUMBA:
    _leg_gaps_c = njit(cache=True, nogil=True)(_leg_gaps)


def leg_gaps(z: np.ndarray, b: np.ndarray, phi: np.ndarray, tt: np.ndarray, hx: np.ndarray,
             hip_z: float, hip_zero: float, radius: float, t_lo: float,
             t_hi: float) -> np.ndarray:
    """(n, L) hip height minus the leg's rest height below it [m]: body height ``z`` and
    pitch ``b`` (n,), hip angles ``phi`` (n, L) at mocap-clock times ``tt``; +inf outside
    ``[t_lo, t_hi]`` (``geometry.rest_height_m`` and ``_Body.gaps_above_zero``). Needs
    numba."""
    if not HAVE_NUMBA:  # pragma: no cover
        raise RuntimeError('leg_gaps needs numba')
    return _leg_gaps_c(np.ascontiguousarray(z, dtype=np.float64),
                       np.ascontiguousarray(b, dtype=np.float64),
                       np.ascontiguousarray(phi, dtype=np.float64),
                       np.ascontiguousarray(tt, dtype=np.float64),
                       np.ascontiguousarray(hx, dtype=np.float64), float(hip_z),
                       float(hip_zero), float(radius), float(t_lo), float(t_hi))

"""Compiled kernels of the fast SLIP fit (numba; optional).

One stance = one Nelder-Mead on nerr (scipy's algorithm, coefficients, initial simplex and
stopping rule), each function value an RK4 integration with cubic Hermite output on the 1 kHz
sample grid, accumulated on the fly (no trajectory stored). ``fit_many`` runs stances in
parallel (``prange``). Without numba, :data:`HAVE_NUMBA` is False and the caller falls back to
the lock-step numpy implementation in :mod:`slip_identification.fit`.

Gravity: ``g`` [m/s^2] along -z (into the ground) and ``gx`` along +x (the along-ground part of
gravity on a slope; 0 when gravity is normal to the ground).

Parameter vector layout (normalised ``q`` and physical ``p``): ``k, l0, fx, c, tau`` where
``c`` (leg damping) and ``tau`` (hip torque) are present when ``ext_idx[0/1] >= 0``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ['HAVE_NUMBA', 'fit_many', 'trajectory', 'trajectories']

try:
    from numba import njit, prange
    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised when numba is absent
    HAVE_NUMBA = False

if HAVE_NUMBA:

    @njit(cache=True, inline='always')
    def _acc(bx, vx, bz, vz, k, l0, fx, c, tau, inv_m, g, gx):  # type: ignore[no-untyped-def]
        dx = bx - fx
        r2 = dx * dx + bz * bz
        r = math.sqrt(r2)
        s = k * inv_m * (l0 / r - 1.0) - c * inv_m * (dx * vx + bz * vz) / r2
        t = tau * inv_m / r2
        return s * dx + t * bz + gx, s * bz - t * dx - g

    @njit(cache=True)
    def _run(p, x0, xe, n, dt, stride, inv_m, g, gx, out):  # type: ignore[no-untyped-def]
        """Integrate; if ``xe`` has rows, return sum ||x - xe||, else fill ``out`` (n, 4)."""
        k, l0, fx, c, tau = p[0], p[1], p[2], p[3], p[4]
        h = stride * dt
        y0, y1, y2, y3 = x0[0], x0[1], x0[2], x0[3]
        a0, a2 = _acc(y0, y1, y2, y3, k, l0, fx, c, tau, inv_m, g, gx)
        compare = xe.shape[0] > 0
        err = 0.0
        if not compare:
            out[0, 0] = y0
            out[0, 1] = y1
            out[0, 2] = y2
            out[0, 3] = y3
        i = 0
        while i < n - 1:
            # RK4 stages; derivative of (bx, vx, bz, vz) is (vx, ax, vz, az)
            k1 = (y1, a0, y3, a2)
            u0 = y0 + 0.5 * h * k1[0]
            u1 = y1 + 0.5 * h * k1[1]
            u2 = y2 + 0.5 * h * k1[2]
            u3 = y3 + 0.5 * h * k1[3]
            b0, b2 = _acc(u0, u1, u2, u3, k, l0, fx, c, tau, inv_m, g, gx)
            k2 = (u1, b0, u3, b2)
            u0 = y0 + 0.5 * h * k2[0]
            u1 = y1 + 0.5 * h * k2[1]
            u2 = y2 + 0.5 * h * k2[2]
            u3 = y3 + 0.5 * h * k2[3]
            b0, b2 = _acc(u0, u1, u2, u3, k, l0, fx, c, tau, inv_m, g, gx)
            k3 = (u1, b0, u3, b2)
            u0 = y0 + h * k3[0]
            u1 = y1 + h * k3[1]
            u2 = y2 + h * k3[2]
            u3 = y3 + h * k3[3]
            b0, b2 = _acc(u0, u1, u2, u3, k, l0, fx, c, tau, inv_m, g, gx)
            z0 = y0 + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + u1)
            z1 = y1 + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + b0)
            z2 = y2 + h / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + u3)
            z3 = y3 + h / 6.0 * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + b2)
            c0, c2 = _acc(z0, z1, z2, z3, k, l0, fx, c, tau, inv_m, g, gx)
            for j in range(1, stride + 1):
                idx = i + j
                if idx >= n:
                    break
                if j == stride:
                    s0, s1, s2, s3 = z0, z1, z2, z3
                else:
                    s = j / stride
                    h00 = 2 * s**3 - 3 * s**2 + 1
                    h10 = (s**3 - 2 * s**2 + s) * h
                    h01 = -2 * s**3 + 3 * s**2
                    h11 = (s**3 - s**2) * h
                    s0 = h00 * y0 + h10 * y1 + h01 * z0 + h11 * z1
                    s1 = h00 * y1 + h10 * a0 + h01 * z1 + h11 * c0
                    s2 = h00 * y2 + h10 * y3 + h01 * z2 + h11 * z3
                    s3 = h00 * y3 + h10 * a2 + h01 * z3 + h11 * c2
                if compare:
                    e0 = s0 - xe[idx, 0]
                    e1 = s1 - xe[idx, 1]
                    e2 = s2 - xe[idx, 2]
                    e3 = s3 - xe[idx, 3]
                    err += math.sqrt(e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)
                else:
                    out[idx, 0] = s0
                    out[idx, 1] = s1
                    out[idx, 2] = s2
                    out[idx, 3] = s3
            y0, y1, y2, y3, a0, a2 = z0, z1, z2, z3, c0, c2
            i += stride
        return err

    @njit(cache=True)
    def _nerr(q, x0, xe, n, den, fx0, dt, stride, inv_m, g, gx, scales, ext_idx, dummy):  # type: ignore[no-untyped-def]  # noqa: E501
        if not (q[0] > 0.0 and q[1] > 0.0):
            return np.inf
        p = np.zeros(5)
        p[0] = q[0] * scales[0]
        p[1] = q[1] * scales[1]
        p[2] = fx0 + (q[2] - 1.0) * scales[2]
        for e in range(2):
            if ext_idx[e] >= 0:
                p[3 + e] = (q[ext_idx[e]] - 1.0) * scales[ext_idx[e]]
        err = _run(p, x0, xe, n, dt, stride, inv_m, g, gx, dummy)
        if not math.isfinite(err):
            return np.inf
        return err / den

    @njit(cache=True)
    def _sort(sim, fsim):  # type: ignore[no-untyped-def]
        order = np.argsort(fsim)
        return sim[order].copy(), fsim[order].copy()

    @njit(cache=True)
    def _nelder_mead(x0, xe, n, den, fx0, dt, stride, inv_m, g, gx, scales, ext_idx, npar,
                     xatol, fatol, maxiter):  # type: ignore[no-untyped-def]
        dummy = np.zeros((0, 4))
        sim = np.ones((npar + 1, npar))
        for k in range(npar):
            sim[k + 1, k] = 1.05
        fsim = np.empty(npar + 1)
        for k in range(npar + 1):
            fsim[k] = _nerr(sim[k], x0, xe, n, den, fx0, dt, stride, inv_m, g, gx, scales,
                            ext_idx, dummy)
        fcalls = npar + 1
        sim, fsim = _sort(sim, fsim)
        it = 1
        converged = False
        while fcalls < maxiter and it < maxiter:
            dx = 0.0
            df = 0.0
            for a in range(1, npar + 1):
                df = max(df, abs(fsim[0] - fsim[a]))
                for b in range(npar):
                    dx = max(dx, abs(sim[a, b] - sim[0, b]))
            if dx <= xatol and df <= fatol:
                converged = True
                break
            xbar = np.zeros(npar)
            for a in range(npar):
                xbar += sim[a]
            xbar /= npar
            xr = 2.0 * xbar - sim[-1]
            fxr = _nerr(xr, x0, xe, n, den, fx0, dt, stride, inv_m, g, gx, scales, ext_idx,
                        dummy)
            fcalls += 1
            doshrink = False
            if fxr < fsim[0]:
                xe2 = 3.0 * xbar - 2.0 * sim[-1]
                fxe = _nerr(xe2, x0, xe, n, den, fx0, dt, stride, inv_m, g, gx, scales, ext_idx,
                            dummy)
                fcalls += 1
                if fxe < fxr:
                    sim[-1] = xe2
                    fsim[-1] = fxe
                else:
                    sim[-1] = xr
                    fsim[-1] = fxr
            elif fxr < fsim[-2]:
                sim[-1] = xr
                fsim[-1] = fxr
            else:
                if fxr < fsim[-1]:
                    xc = 1.5 * xbar - 0.5 * sim[-1]
                    fxc = _nerr(xc, x0, xe, n, den, fx0, dt, stride, inv_m, g, gx, scales,
                                ext_idx, dummy)
                    fcalls += 1
                    if fxc <= fxr:
                        sim[-1] = xc
                        fsim[-1] = fxc
                    else:
                        doshrink = True
                else:
                    xcc = 0.5 * xbar + 0.5 * sim[-1]
                    fxcc = _nerr(xcc, x0, xe, n, den, fx0, dt, stride, inv_m, g, gx, scales,
                                 ext_idx, dummy)
                    fcalls += 1
                    if fxcc < fsim[-1]:
                        sim[-1] = xcc
                        fsim[-1] = fxcc
                    else:
                        doshrink = True
                if doshrink:
                    for a in range(1, npar + 1):
                        sim[a] = sim[0] + 0.5 * (sim[a] - sim[0])
                        fsim[a] = _nerr(sim[a], x0, xe, n, den, fx0, dt, stride, inv_m, g, gx,
                                        scales, ext_idx, dummy)
                    fcalls += npar
            it += 1
            sim, fsim = _sort(sim, fsim)
        return sim[0].copy(), fsim[0], converged, it, fcalls

    def _make_fit_many(parallel):  # type: ignore[no-untyped-def]
        loop = prange if parallel else range

        @njit(cache=True, parallel=parallel)
        def fit_many_impl(x0s, xes, ns, dens, fx0s, dt, stride, inv_m, g, gx, scales, ext_idx,
                          npar, xatol, fatol, maxiter):  # type: ignore[no-untyped-def]
            b = x0s.shape[0]
            q = np.empty((b, npar))
            f = np.empty(b)
            conv = np.zeros(b, dtype=np.bool_)
            its = np.zeros(b, dtype=np.int64)
            calls = np.zeros(b, dtype=np.int64)
            for j in loop(b):
                qj, fj, cj, ij, nj = _nelder_mead(x0s[j], xes[j], ns[j], dens[j], fx0s[j], dt,
                                                  stride, inv_m, g, gx, scales[j], ext_idx, npar,
                                                  xatol, fatol, maxiter)
                q[j] = qj
                f[j] = fj
                conv[j] = cj
                its[j] = ij
                calls[j] = nj
            return q, f, conv, its, calls

        return fit_many_impl

    _fit_many_parallel = _make_fit_many(True)
    _fit_many_serial = _make_fit_many(False)

    def fit_many(x0s, xes, *args):  # type: ignore[no-untyped-def]
        """Nelder-Mead per stance. ``xes`` (B, Nmax, 4) padded, ``scales`` (B, P) per row (the
        start is ``q = 1``: a row's first two scales are its starting k and l0); returns q, f,
        conv, it, calls.

        Small batches (the online case) run serially: starting the thread pool costs more
        than a fit.
        """
        if x0s.shape[0] >= 16:
            return _fit_many_parallel(x0s, xes, *args)
        return _fit_many_serial(x0s, xes, *args)

    @njit(cache=True)
    def trajectory(p, x0, n, dt, stride, inv_m, g, gx):  # type: ignore[no-untyped-def]
        """States (n, 4) for physical ``p`` = (k, l0, fx, c, tau) from ``x0`` (4,)."""
        out = np.empty((n, 4))
        _run(p, x0, np.zeros((0, 4)), n, dt, stride, inv_m, g, gx, out)
        return out

    def _make_trajectories(parallel):  # type: ignore[no-untyped-def]
        loop = prange if parallel else range

        @njit(cache=True, parallel=parallel)
        def impl(p5s, x0s, n, dt, stride, inv_m, g, gx):  # type: ignore[no-untyped-def]
            m = p5s.shape[0]
            out = np.empty((m, n, 4))
            empty = np.zeros((0, 4))
            for j in loop(m):
                _run(p5s[j], x0s[j], empty, n, dt, stride, inv_m, g, gx, out[j])
            return out

        return impl

    _traj_parallel = _make_trajectories(True)
    _traj_serial = _make_trajectories(False)

    def trajectories(p5s, x0s, *args):  # type: ignore[no-untyped-def]
        """States (M, n, 4) for rows of ``p5s`` (M, 5) from ``x0s`` (M, 4)."""
        if p5s.shape[0] >= 64:
            return _traj_parallel(p5s, x0s, *args)
        return _traj_serial(p5s, x0s, *args)

else:  # pragma: no cover
    fit_many = None
    trajectory = None
    trajectories = None

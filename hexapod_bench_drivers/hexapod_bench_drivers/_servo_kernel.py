"""The servo model's sub-step loop, compiled (numba) when installed.

:meth:`hexapod_bench_drivers.servo_model.ServoModel.step` integrates every servo in sub-steps;
as numpy ufuncs over 18 servos each sub-step cost about 30 array calls (270 us a robot step:
half of a residual test's time). This is the same loop per servo, written with scalars in the
same order of operations (numpy's ``maximum``/``minimum``/``sign``/``clip`` semantics for
signed zeros and NaN), so that its results equal the numpy loop's to the bit
(``test/unit/test_servo_kernel.py`` compares them). Without numba, :data:`HAVE_NUMBA` is False
and the numpy loop runs.

Core module: numpy (and numba when installed), no ROS.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ['HAVE_NUMBA', 'substeps', 'warm']

try:
    from numba import njit
    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised when numba is absent
    HAVE_NUMBA = False

    def njit(*args: Any, **kwargs: Any) -> Any:
        """No numba: the functions stay Python (not called: the numpy loop runs)."""
        return lambda f: f


@njit(cache=True, inline='always')
def _max(a: float, b: float) -> float:
    """``np.maximum`` of two floats (NaN from ``a`` propagates; ``a`` kept on a tie)."""
    return a if (a >= b or a != a) else b


@njit(cache=True, inline='always')
def _min(a: float, b: float) -> float:
    """``np.minimum`` of two floats."""
    return a if (a <= b or a != a) else b


@njit(cache=True, inline='always')
def _sign(x: float) -> float:
    """``np.sign`` of a float (0.0 for both zeros, NaN for NaN)."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    if x == 0.0:
        return 0.0
    return x


@njit(cache=True)
def substeps(n_sub: int, h: float, goal: Any, setpoint: Any, limited: Any,
                speed_limit: Any, any_limited: bool, q: Any, w: Any, deflection: Any,
                margin: float, kp: float, umax: Any, volt_over_r: Any, ke_over_r: Any,
                all_drive: bool, drive_f: Any, ke: Any, coulomb: Any, mu: float,
                tau_ext: Any, visc: float, w_s: float, w_eps: float, h_inv_j: Any,
                rec: bool, u: Any, sums: Any) -> None:
    """Advance ``q``, ``w`` and ``setpoint`` (updated in place) by ``n_sub`` sub-steps of
    ``h`` seconds; ``u`` receives the last sub-step's duty; ``sums`` rows accumulate the
    bridge current, i^2 and (``rec``) the Coulomb, gear, viscous and braking powers."""
    for j in range(q.shape[0]):
        qj, wj, sp, uj = q[j], w[j], setpoint[j], u[j]
        for _ in range(n_sub):
            if any_limited:
                step = speed_limit[j] * h
                dq = goal[j] - sp
                if dq < -step:
                    dq = -step
                elif dq > step:
                    dq = step
                sp = sp + dq if limited[j] else goal[j]
            else:
                sp = goal[j]
            err = sp - qj - deflection[j]
            uj = math.copysign(_max(abs(err) - margin, 0.0) * kp, err)
            uj = _min(_max(uj, -umax[j]), umax[j])
            i = uj * volt_over_r[j] - ke_over_r[j] * wj
            if not all_drive:
                i = i * drive_f[j]
            gen = ke[j] * i
            f_max = coulomb[j] + mu * abs(gen)
            tau_free = gen + tau_ext[j] - visc * wj
            if w_s > 0.0:
                w_lin = (wj + h_inv_j[j] * tau_free) / (1.0 + h_inv_j[j] * f_max / w_s)
                w_new = wj + h_inv_j[j] * (tau_free - f_max * _sign(w_lin))
                if abs(w_lin) <= w_s or w_new * w_lin < 0.0:
                    w_new = w_lin
                    if w_new < -w_s:
                        w_new = -w_s
                    elif w_new > w_s:
                        w_new = w_s
                stick = False
            else:
                moving = abs(wj) > w_eps
                direction = _sign(wj if moving else tau_free)
                w_new = wj + h_inv_j[j] * (tau_free - f_max * direction)
                stick = (w_new * wj < 0.0) if moving else (abs(tau_free) <= f_max)
            if rec:
                w_abs = abs(0.0 if stick else w_new)
                f_frac = _min(w_abs / w_s, 1.0) if w_s > 0.0 else 1.0
                sums[2, j] += coulomb[j] * f_frac * w_abs
                sums[3, j] += mu * abs(gen) * f_frac * w_abs
                sums[4, j] += visc * abs(wj) * w_abs
                sums[5, j] += _max(-uj * i, 0.0)
            wj = 0.0 if stick else w_new
            qj += h * wj
            sums[0, j] += _max(uj * i, 0.0)
            sums[1, j] += i * i
        q[j], w[j], setpoint[j], u[j] = qj, wj, sp, uj


_WARM: list[bool] = []


def warm() -> None:
    """Load (or compile) :func:`substeps` now: its first call takes 0.6 s even from numba's
    disk cache, which inside a servo-bus emulator's first reply made a real driver read its
    servos as silent. :class:`~hexapod_bench_drivers.servo_model.ServoModel` calls this when
    built (once per process)."""
    if not HAVE_NUMBA or _WARM:
        return
    f = np.zeros(1)
    substeps(1, 1e-3, f.copy(), f.copy(), np.zeros(1, dtype=bool), f.copy(), False,
             f.copy(), f.copy(), f.copy(), 0.0, 1.0, f.copy(), f.copy(), f.copy(), True,
             f.copy(), f.copy(), f.copy(), 0.0, f.copy(), 0.0, 0.0, 0.0, f.copy(), False,
             f.copy(), np.zeros((6, 1)))
    _WARM.append(True)

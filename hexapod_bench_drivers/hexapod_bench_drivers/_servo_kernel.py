"""The servo model's step, compiled (numba) when installed.

:meth:`hexapod_bench_drivers.servo_model.ServoModel.step` integrates every servo in sub-steps
and then derives its currents, heat, losses and reports; as numpy ufuncs over 18 servos that
was about 80 array calls a step (220-340 us a robot step: half of a residual test's time).
:func:`step_all` is the same computation per servo, written with scalars in the same order of
operations (numpy's ``maximum``/``minimum``/``sign``/``clip`` semantics for signed zeros and
NaN, division by zero giving inf or NaN), so that its results equal the numpy code's to the
bit (``test/unit/test_servo_kernel.py`` compares them on every branch). The input checks,
the backlash's ``tanh`` and the result object stay in Python. Without numba,
:data:`HAVE_NUMBA` is False and the numpy code runs.

Core module: numpy (and numba when installed), no ROS.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ['HAVE_NUMBA', 'step_all', 'warm']

try:
    from numba import njit
    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised when numba is absent
    HAVE_NUMBA = False

    def njit(*args: Any, **kwargs: Any) -> Any:
        """No numba: the functions stay Python (not called: the numpy loop runs)."""
        return lambda f: f


@njit(cache=True, inline='always', error_model='numpy')
def _max(a: float, b: float) -> float:
    """``np.maximum`` of two floats (NaN from ``a`` propagates; ``a`` kept on a tie)."""
    return a if (a >= b or a != a) else b


@njit(cache=True, inline='always', error_model='numpy')
def _min(a: float, b: float) -> float:
    """``np.minimum`` of two floats."""
    return a if (a <= b or a != a) else b


@njit(cache=True, inline='always', error_model='numpy')
def _sign(x: float) -> float:
    """``np.sign`` of a float (0.0 for both zeros, NaN for NaN)."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    if x == 0.0:
        return 0.0
    return x


_WARM: list[bool] = []


def warm() -> None:
    """Load (or compile) :func:`step_all` now: its first call takes 0.6 s even from numba's
    disk cache, which inside a servo-bus emulator's first reply made a real driver read its
    servos as silent. :class:`~hexapod_bench_drivers.servo_model.ServoModel` calls this when
    built (once per process)."""
    if not HAVE_NUMBA or _WARM:
        return
    f = np.zeros(1)
    step_all(1e-3, 1, f, f.copy(), f.copy(), f.copy(), f.copy(), f.copy(), f.copy(), f.copy(),
             np.zeros(1, dtype=np.bool_), np.ones(1, dtype=np.bool_), f.copy(), f.copy(),
             f.copy(), f.copy(), np.ones(1), np.ones(22), True, np.empty((11, 1)),
             np.empty((3, 1), dtype=np.int64), np.empty((9, 1)))
    _WARM.append(True)


@njit(cache=True, error_model='numpy')   # x / 0 is inf or NaN, as numpy's, not an error
def step_all(dt: float, n_sub: int, goal_in: Any, tau_ext: Any, volts: Any, deflection: Any,
             q: Any, w: Any, temp: Any, setpoint: Any, overheated: Any, enabled: Any,
             torque_limit: Any, speed_limit: Any, extra_friction: Any, extra_power: Any,
             inertia: Any, prm: Any, rec: bool, out: Any, flags: Any, losses: Any) -> None:
    """A whole :meth:`ServoModel.step` after its input checks, per servo, in the numpy code's
    order of operations (``test/unit/test_servo_kernel.py``). State arrays (``q``, ``w``,
    ``temp``, ``setpoint``, ``overheated``) are updated in place. ``goal_in``: clipped to the
    mechanical range and checked finite by the caller. ``prm``: temperature limit, reference
    resistance, copper coefficient, reference temperature, back-EMF constant, magnet
    coefficient, compliance slope's inverse, margin, Coulomb and viscous friction, stick speed,
    1 - gear efficiency, friction smoothing, reflected inertia, standby current, ambient
    temperature, thermal drift, exp(-dt / tau_th), thermal resistance, minimum and maximum
    voltage, static friction ratio. ``out`` rows: position, velocity, torque, current,
    temperature, load fraction, power, mechanical power, winding loss, reported voltage, signed
    winding current;
    ``flags`` rows (int64): reported temperature, error bits, drive; ``losses`` rows
    (``rec``): standby, extra, copper, Coulomb, gear, viscous, kinetic, load, brake."""
    n = q.shape[0]
    h = dt / n_sub
    (t_limit, r_ref, cu, t_ref, ke0, mag, kp, margin, coulomb0, visc, w_eps, mu, w_s, refl,
     standby, ambient, drift, decay, r_th, v_min, v_max, ratio_s) = (
        prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8], prm[9],
        prm[10], prm[11], prm[12], prm[13], prm[14], prm[15], prm[16], prm[17], prm[18],
        prm[19], prm[20], prm[21])
    drive_all = True
    any_limited = False
    for j in range(n):
        powered = volts[j] >= 1.0
        overheated[j] = overheated[j] or temp[j] > t_limit
        drive = enabled[j] and powered and not overheated[j]
        flags[2, j] = 1 if drive else 0
        drive_all = drive_all and drive
        any_limited = any_limited or speed_limit[j] > 0.0
    for j in range(n):
        powered = volts[j] >= 1.0
        drive = flags[2, j] == 1
        goal = goal_in[j]
        resistance = r_ref * (1.0 + cu * (temp[j] - t_ref))
        if drive:
            tl = torque_limit[j]
            umax = 0.0 if tl < 0.0 else (1.0 if tl > 1.0 else tl)
        else:
            umax = 0.0
        ke = ke0 * (1.0 + mag * (temp[j] - t_ref))
        coulomb = coulomb0 + extra_friction[j]
        h_inv_j = h / inertia[j]
        volt_over_r = volts[j] / resistance
        ke_over_r = ke / resistance
        drive_f = 1.0 if drive else 0.0
        limited = speed_limit[j] > 0.0
        q0, w0 = q[j], w[j]
        qj, wj, sp, uj = q0, w0, setpoint[j], 0.0
        s_bridge = s_i2 = s_i = s_coulomb = s_gear = s_visc = s_brake = 0.0
        for _ in range(n_sub):
            if any_limited:
                step = speed_limit[j] * h
                dq = goal - sp
                if dq < -step:
                    dq = -step
                elif dq > step:
                    dq = step
                sp = sp + dq if limited else goal
            else:
                sp = goal
            err = sp - qj - deflection[j]
            uj = math.copysign(_max(abs(err) - margin, 0.0) * kp, err)
            uj = _min(_max(uj, -umax), umax)
            i = uj * volt_over_r - ke_over_r * wj
            if not drive_all:
                i = i * drive_f
            gen = ke * i
            f_max = coulomb + mu * abs(gen)
            tau_free = gen + tau_ext[j] - visc * wj
            if w_s > 0.0:
                w_lin = (wj + h_inv_j * tau_free) / (1.0 + h_inv_j * f_max / w_s)
                w_new = wj + h_inv_j * (tau_free - f_max * _sign(w_lin))
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
                w_new = wj + h_inv_j * (tau_free - f_max * direction)
                f_static = f_max if ratio_s == 1.0 else ratio_s * f_max
                stick = (w_new * wj < 0.0) if moving else (abs(tau_free) <= f_static)
            if rec:
                w_abs = abs(0.0 if stick else w_new)
                f_frac = _min(w_abs / w_s, 1.0) if w_s > 0.0 else 1.0
                s_coulomb += coulomb * f_frac * w_abs
                s_gear += mu * abs(gen) * f_frac * w_abs
                s_visc += visc * abs(wj) * w_abs
                s_brake += _max(-uj * i, 0.0)
            wj = 0.0 if stick else w_new
            qj += h * wj
            s_bridge += _max(uj * i, 0.0)
            s_i2 += i * i
            s_i += i
        load_j = inertia[j] - refl
        pmech = (-tau_ext[j] * (qj - q0) + 0.5 * load_j * (wj * wj - w0 * w0)) / h
        setpoint[j], q[j], w[j] = sp, qj, wj
        mean_bridge = s_bridge / n_sub
        winding_loss = s_i2 / n_sub * resistance
        rise = temp[j] - ambient
        extra_w = extra_power[j] + drift * _max(rise, 0.0) if powered else 0.0
        safe_v = volts[j] if powered else 1.0
        current = standby + mean_bridge + extra_w / safe_v if powered else 0.0
        t_inf = ambient + winding_loss * r_th
        temp[j] = t_inf + (temp[j] - t_inf) * decay
        error = 0
        if powered and (volts[j] < v_min or volts[j] > v_max):
            error |= 0x01
        if overheated[j]:
            error |= 0x04
        if drive and abs(uj) >= umax and abs(wj) < 0.05 and umax > 0:
            error |= 0x20
        out[0, j] = qj + deflection[j]
        out[1, j] = wj
        out[2, j] = -tau_ext[j] if (drive or wj == 0.0) else 0.0
        out[3, j] = current
        out[4, j] = temp[j]
        out[5, j] = uj if drive else 0.0
        out[6, j] = current * volts[j]
        out[7, j] = pmech / n_sub
        out[8, j] = winding_loss
        out[9, j] = np.rint(volts[j] * 10.0) / 10.0
        out[10, j] = s_i / n_sub
        flags[0, j] = np.int64(np.rint(temp[j]))
        flags[1, j] = error
        if rec:
            losses[0, j] = standby * volts[j] if powered else 0.0
            losses[1, j] = extra_w
            losses[2, j] = winding_loss
            losses[3, j] = s_coulomb / n_sub
            losses[4, j] = s_gear / n_sub
            losses[5, j] = s_visc / n_sub
            losses[6, j] = 0.5 * refl * (wj * wj - w0 * w0) / dt
            losses[7, j] = pmech / n_sub
            losses[8, j] = s_brake / n_sub * volts[j]

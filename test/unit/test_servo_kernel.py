"""The servo model's compiled step (numba) against its numpy code: the same numbers to the bit,
step after step, on every branch (Karnopp stick-slip with and without stiction and dithered
friction, speed limits, torque off, unpowered and overheated servos, torque limits, backlash,
extra power and thermal drift, heating and cooling, the loss breakdown), and on a whole
simulated robot run."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hexapod_bench_drivers import _servo_kernel
from hexapod_bench_drivers.servo_model import ServoModel, ServoParams

pytestmark = pytest.mark.skipif(not _servo_kernel.HAVE_NUMBA, reason='numba not installed')


def _outputs_equal(a, b) -> None:
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, dict):
            assert x.keys() == y.keys()
            for k in x:
                np.testing.assert_array_equal(x[k], y[k], err_msg=f'losses[{k}]')
        else:
            np.testing.assert_array_equal(x, y, err_msg=f.name)


@pytest.mark.parametrize('smoothing, stiction', [(0.0, 1.0), (1.0, 1.0), (0.0, 1.6)])
@pytest.mark.parametrize('params', ['ax18a', 'xm430'])
def test_compiled_loop_equals_the_numpy_loop(params, smoothing, stiction):
    p = ServoParams.by_name(params).with_changes(friction_smoothing_rad_s=smoothing,
                                                 static_friction_ratio=stiction,
                                                 backlash_rad=0.01)
    n = 12
    start = np.random.default_rng(7).uniform(-1, 1, n)
    models = []
    for compiled in (True, False):
        m = ServoModel(p, count=n, initial_position_rad=start,
                       extra_friction_nm=np.linspace(0.0, 0.05, n), max_substep_s=3.3e-3,
                       record_losses=True, load_inertia_kgm2=np.linspace(0, 1e-4, n),
                       extra_power_w=np.linspace(0.0, 0.5, n), thermal_drift_w_k=0.05,
                       initial_temperature_c=np.linspace(20.0, 60.0, n))
        m.compiled = compiled
        models.append(m)
    a, b = models
    assert a.compiled and not b.compiled
    for m in models:
        m.moving_speed_rad_s[::3] = 2.0          # goal-speed limits on a third of them
        m.torque_limit[1::4] = 0.3               # torque limits
        m.torque_enabled[5] = False              # one servo limp
    steps = np.random.default_rng(3)
    for k in range(400):
        goal = np.sin(0.05 * k + np.arange(n)) * 1.2 + steps.normal(0, 0.02, n)
        tau = steps.normal(0, 0.6, n)            # loads through and beyond the friction band
        tau[::5] = 0.0                           # unloaded: sticking at rest
        volts = np.full(n, 12.0)
        volts[7] = 0.0 if 100 <= k < 150 else 12.0   # a servo unpowered for a while
        volts[8] = 6.0                               # below its minimum voltage
        if k == 200:
            for m in models:
                m.temperature_c[9] = 90.0            # overheated: latched off
        dt = 0.01 if k % 7 else 0.0037
        _outputs_equal(a.step(dt, goal, tau, volts), b.step(dt, goal, tau, volts))
        for key, value in a.state().items():
            np.testing.assert_array_equal(value, b.state()[key], err_msg=key)


def test_simulated_robot_run_is_the_same_compiled_or_not(monkeypatch):
    from hexapod_bench_drivers.robot_sim import simulate_robot

    fast = simulate_robot(3.0, seed=2)
    monkeypatch.setattr(ServoModel, 'compiled', False)
    slow = simulate_robot(3.0, seed=2)
    for f in dataclasses.fields(fast):
        x, y = getattr(fast, f.name), getattr(slow, f.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=f.name)

"""The ground's slope from whole strides (slip_identification.geometry.stride_slope_rad) and
its use in the geometric ground and offset fit.

Without flight phases (pace, walk) the body-height dynamics pin the slope of the ground in the
run's frame weakly: on simulated runs the fitted slope was 0.5-0.7 mrad off on some (pace seeds
1-3, walk seed 10), and that bias put stance edges more than 5 ms off. In steady state the mean
body height over one gait period is the same every stride, so the means over one-period windows
against their mean x give the slope: 0.05-0.08 mrad median error on pace and walk seeds 1-12.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from slip_identification.geometry import fit_ground_offset, stride_slope_rad
from slip_sim_inputs import geometry_args


def _periodic(t, period, slope, speed=0.3, phase=0.0):
    x = speed * t
    z = 0.1 + 0.004 * np.sin(2 * np.pi * t / period + phase) \
        + 0.0015 * np.sin(4 * np.pi * t / period + 2 * phase) + slope * x
    pitch = 0.02 * np.sin(2 * np.pi * t / period + 0.3 + phase)
    return x, z, pitch


@pytest.mark.parametrize('phase', [0.0, 1.0, 2.5])
def test_slope_of_a_periodic_gait_on_a_slope(phase):
    t = np.arange(0.0, 4.5, 1 / 120)
    period = 1.047
    x, z, pitch = _periodic(t, period, slope=1.3e-3, phase=phase)
    assert stride_slope_rad(t, z, x, pitch, period) == pytest.approx(1.3e-3, abs=2e-5)
    # 0.2 mm of motion-capture noise
    rng = np.random.default_rng(1)
    noisy = z + rng.normal(0, 2e-4, t.size)
    assert stride_slope_rad(t, noisy, x, pitch, period) == pytest.approx(1.3e-3, abs=1e-4)


def test_no_slope_without_steady_strides_or_travel():
    t = np.arange(0.0, 1.4, 1 / 120)
    x, z, pitch = _periodic(t, 1.0, slope=1e-3)
    assert stride_slope_rad(t, z, x, pitch, 1.0) is None            # under 1.5 periods
    t = np.arange(0.0, 4.5, 1 / 120)
    x, z, pitch = _periodic(t, 1.0, slope=1e-3, speed=0.01)
    assert stride_slope_rad(t, z, x, pitch, 1.0) is None            # 4.5 cm of travel
    x, z, pitch = _periodic(t, 1.0, slope=1e-3)
    assert stride_slope_rad(t, z, x, pitch, math.nan) is None
    # a motion-capture gap in every one-period window
    keep = (np.abs(t - 1.5) > 0.1) & (np.abs(t - 2.5) > 0.1) & (np.abs(t - 3.5) > 0.1)
    assert stride_slope_rad(t[keep], z[keep], x[keep], pitch[keep], 1.0) is None


def test_fit_takes_the_strides_slope_on_simulated_pace():
    edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')
    run = edubot_sim.simulate_edubot('pace', duration_s=4.5, seed=1)
    args, pw, frame = geometry_args(run)
    kw = dict(initial_offset_s=0.0, offset_range_s=0.06, x_m=pw[:, 0])
    # the truth: the ground's normal in the mocap frame against the fitted frame's x axis
    normal = np.array(run.truth['frame']['mocap_from_ground_rotation'])[:, 2]
    true_tilt = -float(normal @ frame.rotation[0])
    strides = fit_ground_offset(*args, **kw)
    fitted = fit_ground_offset(*args, tilt_from_strides=False, **kw)
    print(f'\npace seed 1: slope from strides {1e3 * (strides.tilt_rad - true_tilt):+.2f} mrad '
          f'off, fitted {1e3 * (fitted.tilt_rad - true_tilt):+.2f} mrad off')
    assert strides.tilt_source == 'strides' and fitted.tilt_source == 'fitted'
    assert abs(strides.tilt_rad - true_tilt) < 2e-4            # 0.07 mrad
    assert abs(fitted.tilt_rad - true_tilt) > 4e-4             # 0.53 mrad
    off = run.truth['clock_offset_s']
    assert abs(strides.offset_s - off) < 2e-3
